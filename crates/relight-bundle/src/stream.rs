//! Writing a bundle whose tensors do not fit in memory together: the tensors' names, types and
//! shapes are known first, their bytes are produced one tensor at a time (e.g. the rows of
//! every part of a sharded bake in turn), and the file is byte-identical to
//! [`crate::Bundle::to_bytes`] of the same contents.
//!
//! The header holds the data's CRC-32, known only at the end, in 8 hex digits: it is written
//! with a placeholder of the same length, the data streamed behind it, and the header
//! rewritten in place. All of it goes to a temporary file renamed at the end
//! ([`crate::write_atomic_with`]), so a reader never sees a partial bundle.

use crate::{header_text, BundleError, Crc32, DType};
use std::collections::BTreeMap;
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

/// A tensor of a streamed bundle, before its data.
#[derive(Clone, Debug, PartialEq)]
pub struct TensorSpec {
    /// Name.
    pub name: String,
    /// Element type.
    pub dtype: DType,
    /// Shape.
    pub shape: Vec<usize>,
}

impl TensorSpec {
    /// Bytes of its data.
    pub fn bytes(&self) -> u64 {
        self.shape.iter().map(|&d| d as u64).product::<u64>() * self.dtype.size() as u64
    }
}

/// Where [`write_streamed`]'s `fill` writes a tensor's bytes: buffered, checksummed and counted.
pub struct Sink<'a> {
    out: std::io::BufWriter<&'a mut std::fs::File>,
    crc: Crc32,
    written: u64,
}

impl Sink<'_> {
    /// Append bytes of the current tensor.
    ///
    /// # Errors
    /// The OS error of the write.
    pub fn write(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.crc.update(bytes);
        self.written += bytes.len() as u64;
        self.out.write_all(bytes)
    }
}

/// Write the bundle of `metadata` and the tensors `specs` (any order; laid out by name) to
/// `path` atomically, asking `fill(spec, sink)` for each tensor's bytes in name order.
///
/// # Errors
/// [`BundleError::Invalid`] if two tensors share a name or `fill` writes another number of
/// bytes than its spec holds; the error `fill` returns; [`BundleError::Io`] naming `path`. On
/// any error `path` is untouched.
pub fn write_streamed(
    path: &Path,
    metadata: &BTreeMap<String, String>,
    specs: &[TensorSpec],
    mut fill: impl FnMut(&TensorSpec, &mut Sink) -> Result<(), BundleError>,
) -> Result<(), BundleError> {
    let mut sorted: Vec<&TensorSpec> = specs.iter().collect();
    sorted.sort_by(|a, b| a.name.cmp(&b.name));
    if let Some(w) = sorted.windows(2).find(|w| w[0].name == w[1].name) {
        return Err(BundleError::Invalid {
            path: path.to_path_buf(),
            msg: format!("two tensors named '{}'", w[0].name),
        });
    }
    let header = |crc: u32| {
        let it = sorted
            .iter()
            .map(|s| (s.name.as_str(), s.dtype, &s.shape[..]));
        header_text(metadata, it, crc)
    };
    let placeholder = header(0);
    // The error of `fill` or of a size check, kept apart from IO errors to be returned as is.
    let mut failure: Option<BundleError> = None;
    let result = crate::write_atomic_with(path, |f| {
        f.write_all(&(placeholder.len() as u64).to_le_bytes())?;
        f.write_all(placeholder.as_bytes())?;
        let mut sink = Sink {
            out: std::io::BufWriter::with_capacity(1 << 20, &mut *f),
            crc: Crc32::new(),
            written: 0,
        };
        for spec in &sorted {
            let before = sink.written;
            if let Err(e) = fill(spec, &mut sink) {
                failure = Some(e);
                return Err(std::io::Error::other("fill failed"));
            }
            if sink.written - before != spec.bytes() {
                failure = Some(BundleError::Invalid {
                    path: path.to_path_buf(),
                    msg: format!(
                        "tensor '{}' got {} bytes, its shape {:?} of {} holds {}",
                        spec.name,
                        sink.written - before,
                        spec.shape,
                        spec.dtype.name(),
                        spec.bytes()
                    ),
                });
                return Err(std::io::Error::other("size mismatch"));
            }
        }
        sink.out.flush()?;
        let crc = sink.crc.finish();
        drop(sink);
        let h = header(crc);
        debug_assert_eq!(h.len(), placeholder.len());
        f.seek(SeekFrom::Start(8))?;
        f.write_all(h.as_bytes())
    });
    match failure {
        Some(e) => Err(e),
        None => result,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Bundle, Tensor};

    fn sample() -> Bundle {
        let mut b = Bundle::new();
        b.metadata.insert("method".into(), "sh".into());
        b.insert(
            "zeta",
            Tensor::from_f32(vec![3, 2], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
        );
        b.insert("alpha", Tensor::from_u32(vec![2], &[7, 8]));
        b.insert(
            "mid",
            Tensor::from_f32_as_f16(vec![1, 3], &[0.5, 1.0, -2.0]),
        );
        b
    }

    fn specs(b: &Bundle) -> Vec<TensorSpec> {
        // Given out of name order on purpose.
        b.tensors
            .iter()
            .rev()
            .map(|(n, t)| TensorSpec {
                name: n.clone(),
                dtype: t.dtype,
                shape: t.shape.clone(),
            })
            .collect()
    }

    fn dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("relight-stream-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_streamed_bundle_is_the_in_memory_one_byte_for_byte() {
        let b = sample();
        let d = dir("same");
        let path = d.join("s.relight");
        write_streamed(&path, &b.metadata, &specs(&b), |s, sink| {
            // In two pieces, as rows of parts come.
            let bytes = &b.tensors[&s.name].bytes;
            let (x, y) = bytes.split_at(bytes.len() / 2);
            sink.write(x)
                .and_then(|_| sink.write(y))
                .map_err(|error| BundleError::Io {
                    path: path.clone(),
                    error,
                })
        })
        .unwrap();
        assert!(std::fs::read(&path).unwrap() == b.to_bytes());
        assert_eq!(Bundle::read(&path).unwrap(), b);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn short_data_or_a_failing_fill_leaves_nothing() {
        let b = sample();
        let d = dir("fail");
        let path = d.join("s.relight");
        let e = write_streamed(&path, &b.metadata, &specs(&b), |s, sink| {
            sink.write(&b.tensors[&s.name].bytes[1..]).unwrap();
            Ok(())
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("s.relight") && e.contains("bytes"), "{e}");
        let e = write_streamed(&path, &b.metadata, &specs(&b), |_, _| {
            Err(BundleError::Invalid {
                path: "part-3.relight".into(),
                msg: "corrupt".into(),
            })
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("part-3.relight: corrupt"), "{e}");
        let mut twice = specs(&b);
        twice.push(twice[0].clone());
        assert!(write_streamed(&path, &b.metadata, &twice, |_, _| Ok(())).is_err());
        // Neither the output nor a temporary is left.
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
