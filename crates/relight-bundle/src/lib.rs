//! # relight-bundle: the baked file format
//!
//! A bundle is one [safetensors](https://huggingface.co/docs/safetensors) file, so Python reads
//! it with `safetensors.numpy.load_file` (or 20 lines of plain Python), plus two checksums and a
//! version that relight checks before using anything:
//!
//! ```text
//! u64 little-endian  N                    header length in bytes
//! N bytes            JSON header          {"__metadata__": {...strings...},
//!                                          "<tensor>": {"dtype": "F32"|"F16"|"U32"|"U8",
//!                                                       "shape": [...],
//!                                                       "data_offsets": [begin, end]}, ...}
//!                                         padded with spaces to a multiple of 8
//! rest               data section         tensors, little-endian, at their offsets
//! ```
//!
//! `__metadata__` always holds `format = "relight-bundle"`, `format_version` (decimal),
//! `data_crc32` (8 lowercase hex digits: CRC-32 as Python's `zlib.crc32` of the whole data
//! section) and `header_crc32` (CRC-32 of the header bytes in which the 8 hex digits of
//! `header_crc32` itself are replaced by `00000000`). Everything else (method, settings, scene
//! description, materials) is stored as strings, JSON where structured.
//!
//! The tensors' `data_offsets` must tile the data section exactly, in any order: no two
//! overlap, no byte belongs to no tensor, nothing trails the last one (the safetensors rule).
//! A file whose checksums are right but whose layout is not is refused.
//!
//! Only regular files are read (a FIFO or `/dev/zero` is refused before reading), up to the
//! size their metadata states.
//!
//! Files are written atomically ([`write_atomic`]): to a hidden temporary
//! `.<name>.relight-tmp.<host>.<pid>.<random>` in the same folder, flushed, then renamed over
//! `path`, so a reader never sees a partial bundle. A process killed while writing leaves its
//! temporary behind; the next write into that folder removes every such temporary whose host
//! is this machine and whose process no longer runs (`/proc/<pid>` absent), and says so on
//! stderr, one line per file. Where `/proc` is not mounted nothing is removed. Temporaries of
//! the former naming (`<name>.tmp-<pid>`) are removed by the next write of the same `<name>`
//! under the same condition. relight-scene's image and mesh writers follow the same rule and
//! naming.

mod crc32;
pub mod output;
pub mod stream;
pub mod tmpfile;

pub use crc32::{crc32, Crc32};

use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The bundle layout version this build writes and the only one it reads.
pub const FORMAT_VERSION: u32 = 1;
/// Value of the `format` metadata key.
pub const FORMAT_NAME: &str = "relight-bundle";
/// Largest header accepted (a guard against absurd sizes in corrupt files).
pub const MAX_HEADER_BYTES: u64 = 64 << 20;

/// Errors reading or writing a bundle. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum BundleError {
    /// The file could not be read or written.
    ///
    /// The OS error is part of the message and deliberately *not* a `source()`, so that
    /// error chains (`anyhow`'s `{:#}`) print it once.
    #[error("{path}: {error}")]
    Io {
        /// The file (the output, never the temporary, for writes).
        path: PathBuf,
        /// The OS error (shown in the message).
        error: std::io::Error,
    },
    /// The file is not a valid bundle (corrupt, truncated, wrong version...).
    #[error("{path}: {msg}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        msg: String,
    },
    /// A tensor is missing or has an unexpected type or shape.
    #[error("{path}: tensor '{name}': {msg}")]
    Tensor {
        /// The file.
        path: PathBuf,
        /// Tensor name.
        name: String,
        /// What is wrong.
        msg: String,
    },
}

/// Element type of a tensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DType {
    /// IEEE binary32.
    F32,
    /// IEEE binary16.
    F16,
    /// Unsigned 32-bit integer.
    U32,
    /// Byte.
    U8,
}

impl DType {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            DType::F32 | DType::U32 => 4,
            DType::F16 => 2,
            DType::U8 => 1,
        }
    }

    /// The safetensors name.
    pub fn name(self) -> &'static str {
        match self {
            DType::F32 => "F32",
            DType::F16 => "F16",
            DType::U32 => "U32",
            DType::U8 => "U8",
        }
    }

    fn parse(s: &str) -> Option<DType> {
        Some(match s {
            "F32" => DType::F32,
            "F16" => DType::F16,
            "U32" => DType::U32,
            "U8" => DType::U8,
            _ => return None,
        })
    }
}

impl fmt::Display for DType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One named array: element type, shape and little-endian bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// Element type.
    pub dtype: DType,
    /// Shape (row-major).
    pub shape: Vec<usize>,
    /// Little-endian element bytes, `product(shape) * dtype.size()` long.
    pub bytes: Vec<u8>,
}

impl Tensor {
    /// An f32 tensor.
    pub fn from_f32(shape: Vec<usize>, values: &[f32]) -> Self {
        debug_assert_eq!(shape.iter().product::<usize>(), values.len());
        let bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        Tensor {
            dtype: DType::F32,
            shape,
            bytes,
        }
    }

    /// An f16 tensor rounded from f32 values (round to nearest even).
    pub fn from_f32_as_f16(shape: Vec<usize>, values: &[f32]) -> Self {
        debug_assert_eq!(shape.iter().product::<usize>(), values.len());
        let bytes = values
            .iter()
            .flat_map(|v| half::f16::from_f32(*v).to_le_bytes())
            .collect();
        Tensor {
            dtype: DType::F16,
            shape,
            bytes,
        }
    }

    /// A u32 tensor.
    pub fn from_u32(shape: Vec<usize>, values: &[u32]) -> Self {
        debug_assert_eq!(shape.iter().product::<usize>(), values.len());
        let bytes = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        Tensor {
            dtype: DType::U32,
            shape,
            bytes,
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// Whether the tensor has no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Values as f32 (F16 widened); `None` for integer tensors.
    pub fn to_f32(&self) -> Option<Vec<f32>> {
        match self.dtype {
            DType::F32 => Some(
                self.bytes
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect(),
            ),
            DType::F16 => Some(
                self.bytes
                    .chunks_exact(2)
                    .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
                    .collect(),
            ),
            DType::U32 | DType::U8 => None,
        }
    }

    /// Values as u32; `None` for other types.
    pub fn to_u32(&self) -> Option<Vec<u32>> {
        (self.dtype == DType::U32).then(|| {
            self.bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        })
    }
}

/// A bundle in memory: string metadata and named tensors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bundle {
    /// User metadata (the format keys are added on write and removed on read).
    pub metadata: BTreeMap<String, String>,
    /// Tensors by name.
    pub tensors: BTreeMap<String, Tensor>,
}

const RESERVED: [&str; 4] = ["format", "format_version", "data_crc32", "header_crc32"];
const HEADER_CRC_KEY: &str = "\"header_crc32\":\"";

impl Bundle {
    /// An empty bundle.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add a tensor (replacing any of the same name).
    pub fn insert(&mut self, name: &str, t: Tensor) {
        self.tensors.insert(name.to_string(), t);
    }

    /// A required tensor, with an error naming `path` when missing.
    pub fn tensor(&self, path: &Path, name: &str) -> Result<&Tensor, BundleError> {
        self.tensors.get(name).ok_or_else(|| BundleError::Tensor {
            path: path.to_path_buf(),
            name: name.to_string(),
            msg: "missing".into(),
        })
    }

    /// A required metadata string, with an error naming `path` when missing.
    pub fn meta(&self, path: &Path, key: &str) -> Result<&str, BundleError> {
        self.metadata
            .get(key)
            .map(String::as_str)
            .ok_or_else(|| BundleError::Invalid {
                path: path.to_path_buf(),
                msg: format!("metadata key '{key}' missing"),
            })
    }

    /// Serialise to bytes (header with checksums, then data). The data section is checksummed
    /// tensor by tensor and copied once, into the result: a bundle of `n` bytes of tensors
    /// peaks at twice that while it is written, not three times.
    pub fn to_bytes(&self) -> Vec<u8> {
        // The data section is the tensors in name order.
        let mut crc = Crc32::new();
        let mut data_len = 0;
        for t in self.tensors.values() {
            debug_assert_eq!(t.bytes.len(), t.len() * t.dtype.size());
            crc.update(&t.bytes);
            data_len += t.bytes.len();
        }
        let specs = self
            .tensors
            .iter()
            .map(|(n, t)| (n.as_str(), t.dtype, &t.shape[..]));
        let h = header_text(&self.metadata, specs, crc.finish());
        let mut out = Vec::with_capacity(8 + h.len() + data_len);
        out.extend_from_slice(&(h.len() as u64).to_le_bytes());
        out.extend_from_slice(h.as_bytes());
        for t in self.tensors.values() {
            out.extend_from_slice(&t.bytes);
        }
        out
    }

    /// Parse and verify bytes read from `path` (used in error messages only).
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Bundle, BundleError> {
        let bad = |msg: String| BundleError::Invalid {
            path: path.to_path_buf(),
            msg,
        };
        if bytes.len() < 8 {
            return Err(bad(format!(
                "truncated: {} bytes, too short for a bundle header",
                bytes.len()
            )));
        }
        let n = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes"));
        if n > MAX_HEADER_BYTES || n > (bytes.len() - 8) as u64 {
            return Err(bad(format!(
                "header length {n} is absurd or beyond the end of the file ({} bytes): not a relight bundle, or truncated",
                bytes.len()
            )));
        }
        let hbytes = &bytes[8..8 + n as usize];
        let hstr = std::str::from_utf8(hbytes)
            .map_err(|_| bad("header is not UTF-8: not a relight bundle".into()))?;
        let header: Value = serde_json::from_str(hstr).map_err(|e| {
            bad(format!(
                "header is not valid JSON ({e}): not a relight bundle or corrupt"
            ))
        })?;
        let Value::Object(mut header) = header else {
            return Err(bad("header is not a JSON object".into()));
        };
        let Some(Value::Object(meta)) = header.remove("__metadata__") else {
            return Err(bad(
                "no __metadata__: a safetensors file but not a relight bundle".into(),
            ));
        };
        let get = |k: &str| meta.get(k).and_then(Value::as_str);
        if get("format") != Some(FORMAT_NAME) {
            return Err(bad(
                "metadata 'format' is not 'relight-bundle': not a relight bundle".into(),
            ));
        }
        match get("format_version").map(str::parse::<u32>) {
            Some(Ok(FORMAT_VERSION)) => {}
            Some(Ok(v)) => {
                return Err(bad(format!(
                    "bundle format version {v}, but this relight reads only version {FORMAT_VERSION}: re-bake it with this version"
                )))
            }
            _ => return Err(bad("metadata 'format_version' missing or not a number".into())),
        }
        // Header checksum: over the header with its own 8 digits zeroed.
        let stored = get("header_crc32").ok_or_else(|| bad("header_crc32 missing".into()))?;
        let at = hstr
            .find(HEADER_CRC_KEY)
            .ok_or_else(|| bad("header_crc32 not found in header text".into()))?
            + HEADER_CRC_KEY.len();
        let mut zeroed = hbytes.to_vec();
        if at + 8 > zeroed.len() {
            return Err(bad("header_crc32 malformed".into()));
        }
        zeroed[at..at + 8].copy_from_slice(b"00000000");
        if format!("{:08x}", crc32(&zeroed)) != stored {
            return Err(bad("header checksum mismatch: the file is corrupt".into()));
        }
        let data = &bytes[8 + n as usize..];
        let data_crc = get("data_crc32").ok_or_else(|| bad("data_crc32 missing".into()))?;
        if format!("{:08x}", crc32(data)) != data_crc {
            return Err(bad(format!(
                "data checksum mismatch: the file is corrupt or truncated ({} data bytes)",
                data.len()
            )));
        }
        let mut out = Bundle::new();
        for (k, v) in meta.iter() {
            if !RESERVED.contains(&k.as_str()) {
                let s = v
                    .as_str()
                    .ok_or_else(|| bad(format!("metadata '{k}' is not a string")))?;
                out.metadata.insert(k.clone(), s.to_string());
            }
        }
        let mut spans: Vec<(u64, u64, String)> = Vec::with_capacity(header.len());
        for (name, desc) in header {
            let tbad = |msg: String| BundleError::Tensor {
                path: path.to_path_buf(),
                name: name.clone(),
                msg,
            };
            let dtype = desc
                .get("dtype")
                .and_then(Value::as_str)
                .and_then(DType::parse)
                .ok_or_else(|| tbad("unknown or missing dtype".into()))?;
            let shape: Vec<usize> = desc
                .get("shape")
                .and_then(Value::as_array)
                .ok_or_else(|| tbad("missing shape".into()))?
                .iter()
                .map(|d| d.as_u64().map(|d| d as usize))
                .collect::<Option<_>>()
                .ok_or_else(|| tbad("shape is not a list of integers".into()))?;
            let offs: Vec<u64> = desc
                .get("data_offsets")
                .and_then(Value::as_array)
                .map(|a| a.iter().filter_map(Value::as_u64).collect())
                .unwrap_or_default();
            let [b, e] = offs[..] else {
                return Err(tbad("data_offsets must be [begin, end]".into()));
            };
            let count = shape
                .iter()
                .try_fold(1usize, |a, &d| a.checked_mul(d))
                .and_then(|c| c.checked_mul(dtype.size()))
                .ok_or_else(|| tbad("absurd shape".into()))?;
            if b > e || e > data.len() as u64 || (e - b) as usize != count {
                return Err(tbad(format!(
                    "data_offsets [{b}, {e}] do not match shape {shape:?} x {dtype} or exceed the data ({} bytes)",
                    data.len()
                )));
            }
            out.tensors.insert(
                name.clone(),
                Tensor {
                    dtype,
                    shape,
                    bytes: data[b as usize..e as usize].to_vec(),
                },
            );
            spans.push((b, e, name));
        }
        check_tiling(&mut spans, data.len() as u64).map_err(bad)?;
        Ok(out)
    }

    /// Write atomically to `path` (temporary file in the same folder, then rename).
    pub fn write(&self, path: &Path) -> Result<(), BundleError> {
        write_atomic(path, &self.to_bytes())
    }

    /// Read and verify a bundle: a regular file (checked before opening and on the opened
    /// file), read up to the size its metadata states.
    pub fn read(path: &Path) -> Result<Bundle, BundleError> {
        let bytes = read_regular_file(path)?;
        Bundle::from_bytes(path, &bytes)
    }
}

/// The header of a bundle (padded, with both checksums): `metadata`, and the tensors `specs`
/// (name, type, shape) laid out in the order given, which must be name order; `data_crc` is
/// the CRC-32 of the data section. Its length does not depend on `data_crc`.
fn header_text<'a>(
    metadata: &BTreeMap<String, String>,
    specs: impl Iterator<Item = (&'a str, DType, &'a [usize])>,
    data_crc: u32,
) -> String {
    let mut header = Map::new();
    let mut end = 0;
    for (name, dtype, shape) in specs {
        let begin = end;
        end += shape.iter().product::<usize>() * dtype.size();
        let mut e = Map::new();
        e.insert("dtype".into(), Value::from(dtype.name()));
        e.insert("shape".into(), Value::from(shape.to_vec()));
        e.insert("data_offsets".into(), Value::from(vec![begin, end]));
        header.insert(name.to_string(), Value::Object(e));
    }
    let mut meta = Map::new();
    for (k, v) in metadata {
        if !RESERVED.contains(&k.as_str()) {
            meta.insert(k.clone(), Value::from(v.clone()));
        }
    }
    meta.insert("format".into(), Value::from(FORMAT_NAME));
    meta.insert(
        "format_version".into(),
        Value::from(FORMAT_VERSION.to_string()),
    );
    meta.insert("data_crc32".into(), Value::from(format!("{data_crc:08x}")));
    meta.insert("header_crc32".into(), Value::from("00000000"));
    header.insert("__metadata__".into(), Value::Object(meta));
    let mut h = serde_json::to_string(&Value::Object(header)).expect("JSON of strings");
    while !h.len().is_multiple_of(8) {
        h.push(' ');
    }
    // Fill in the header checksum over the header with the placeholder in place.
    let crc = crc32(h.as_bytes());
    let at = h.find(HEADER_CRC_KEY).expect("placeholder present") + HEADER_CRC_KEY.len();
    h.replace_range(at..at + 8, &format!("{crc:08x}"));
    h
}

/// Check that the `(begin, end, name)` spans tile `0..len` exactly (sorts `spans`).
fn check_tiling(spans: &mut [(u64, u64, String)], len: u64) -> Result<(), String> {
    spans.sort();
    let mut end = 0u64;
    let mut last: Option<&(u64, u64, String)> = None;
    for s in spans.iter() {
        if s.0 < end {
            let prev = last.map_or("", |p| p.2.as_str());
            return Err(format!(
                "tensors '{prev}' and '{}' overlap (data_offsets end {end} and begin {}): corrupt or forged",
                s.2, s.0
            ));
        }
        if s.0 > end {
            return Err(format!(
                "data bytes [{end}, {}) belong to no tensor: corrupt or forged",
                s.0
            ));
        }
        end = s.1;
        last = Some(s);
    }
    if end != len {
        return Err(format!(
            "{} bytes of trailing data after the last tensor (data section {len} bytes, tensors end at {end}): corrupt or forged",
            len - end
        ));
    }
    Ok(())
}

/// Read a whole regular file: its metadata is checked before opening (a FIFO is never
/// opened) and again on the opened file; at most the size it states is read.
fn read_regular_file(path: &Path) -> Result<Vec<u8>, BundleError> {
    use std::io::Read;
    let io = |error| BundleError::Io {
        path: path.to_path_buf(),
        error,
    };
    let not_regular = |meta: &std::fs::Metadata| BundleError::Invalid {
        path: path.to_path_buf(),
        msg: format!(
            "not a regular file ({}): relight reads bundles only from regular files",
            if meta.is_dir() {
                "a directory"
            } else {
                "a device, FIFO or socket"
            }
        ),
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(meta.len()).read_to_end(&mut bytes).map_err(io)?;
    Ok(bytes)
}

/// Write `bytes` to `path` atomically: a temporary sibling file, flushed and synced, then
/// renamed over `path`. On error the temporary file is removed and `path` is untouched; the
/// error names `path`. Stale temporaries of killed processes in the folder are removed first
/// (see the crate docs).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), BundleError> {
    write_atomic_with(path, |f| f.write_all(bytes))
}

/// [`write_atomic`] of what `write` writes into the temporary file (which it may also seek
/// and rewrite); on error of `write` nothing is renamed and the temporary is removed.
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> Result<(), BundleError> {
    let io = |error| BundleError::Io {
        path: path.to_path_buf(),
        error,
    };
    let file_name = path.file_name().ok_or_else(|| BundleError::Invalid {
        path: path.to_path_buf(),
        msg: "not a file path".into(),
    })?;
    let name = file_name.to_string_lossy();
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    tmpfile::remove_stale_temporaries(dir, &name);
    let tmp = dir.join(tmpfile::temporary_name(&name));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        write(&mut f)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Bundle {
        let mut b = Bundle::new();
        b.metadata.insert("method".into(), "sh".into());
        b.metadata
            .insert("settings".into(), r#"{"order":5}"#.into());
        b.insert(
            "positions",
            Tensor::from_f32(vec![2, 3], &[0.0, 1.0, 2.0, 3.0, 4.0, 5.5]),
        );
        b.insert("indices", Tensor::from_u32(vec![1, 3], &[0, 1, 1]));
        b.insert(
            "transfer",
            Tensor::from_f32_as_f16(vec![4], &[0.5, -1.0, 1e-3, 65504.0]),
        );
        b
    }

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("relight-bundle-test-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    #[test]
    fn round_trip_through_a_file() {
        let p = tmp("rt.relight");
        let b = sample();
        b.write(&p).unwrap();
        let r = Bundle::read(&p).unwrap();
        assert_eq!(r, b);
        let f16 = r.tensors["transfer"].to_f32().unwrap();
        assert_eq!(
            f16,
            vec![0.5, -1.0, half::f16::from_f32(1e-3).to_f32(), 65504.0]
        );
        // No temporary file is left behind.
        let leftovers: Vec<_> = std::fs::read_dir(p.parent().unwrap())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| {
                let n = e.file_name().to_string_lossy().to_string();
                n.contains(".tmp-") || n.contains(tmpfile::TMP_MARKER)
            })
            .collect();
        assert!(leftovers.is_empty());
    }

    #[test]
    fn header_is_aligned_and_safetensors_shaped() {
        let bytes = sample().to_bytes();
        let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        assert_eq!(n % 8, 0);
        let h: Value = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
        assert_eq!(h["positions"]["dtype"], "F32");
        assert_eq!(h["positions"]["shape"], serde_json::json!([2, 3]));
        assert_eq!(h["__metadata__"]["format"], FORMAT_NAME);
    }

    #[test]
    fn every_single_byte_corruption_is_detected() {
        let good = sample().to_bytes();
        let p = Path::new("corrupt.relight");
        for i in 0..good.len() {
            let mut bad = good.clone();
            bad[i] ^= 0x20;
            assert!(
                Bundle::from_bytes(p, &bad).is_err(),
                "flip at byte {i} not detected"
            );
        }
    }

    #[test]
    fn truncation_is_detected_at_every_length() {
        let good = sample().to_bytes();
        for len in 0..good.len() {
            let e = Bundle::from_bytes(Path::new("t.relight"), &good[..len]).unwrap_err();
            assert!(e.to_string().starts_with("t.relight: "), "{e}");
        }
    }

    #[test]
    fn wrong_version_is_refused_with_a_clear_message() {
        let mut bytes = sample().to_bytes();
        let s = String::from_utf8_lossy(&bytes).to_string();
        let at = s.find("\"format_version\":\"1\"").unwrap() + "\"format_version\":\"".len();
        bytes[at] = b'9';
        // Recompute the header checksum so only the version is wrong.
        let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        let h = std::str::from_utf8(&bytes[8..8 + n]).unwrap().to_string();
        let c = h.find(HEADER_CRC_KEY).unwrap() + HEADER_CRC_KEY.len();
        let mut z = h.clone().into_bytes();
        z[c..c + 8].copy_from_slice(b"00000000");
        let crc = format!("{:08x}", crc32(&z));
        bytes[8 + c..8 + c + 8].copy_from_slice(crc.as_bytes());
        let e = Bundle::from_bytes(Path::new("v.relight"), &bytes)
            .unwrap_err()
            .to_string();
        assert!(e.contains("version 9") && e.contains("re-bake"), "{e}");
    }

    #[test]
    fn missing_file_and_absurd_header_are_errors() {
        let e = Bundle::read(Path::new("/nonexistent/x.relight"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/x.relight"));
        let mut bytes = vec![0u8; 16];
        bytes[..8].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = Bundle::from_bytes(Path::new("a.relight"), &bytes)
            .unwrap_err()
            .to_string();
        assert!(e.contains("absurd"), "{e}");
    }

    /// Header JSON and data assembled into bytes with valid checksums, however wrong the
    /// layout: `tensors` are (name, shape of F32, data_offsets).
    fn forge(tensors: &[(&str, Vec<usize>, [u64; 2])], data: &[u8]) -> Vec<u8> {
        let mut header = Map::new();
        for (name, shape, offs) in tensors {
            header.insert(
                name.to_string(),
                serde_json::json!({"dtype": "F32", "shape": shape, "data_offsets": offs}),
            );
        }
        header.insert(
            "__metadata__".into(),
            serde_json::json!({"format": FORMAT_NAME, "format_version": FORMAT_VERSION.to_string(),
                "data_crc32": format!("{:08x}", crc32(data)), "header_crc32": "00000000"}),
        );
        let mut h = serde_json::to_string(&Value::Object(header)).unwrap();
        while !h.len().is_multiple_of(8) {
            h.push(' ');
        }
        let crc = crc32(h.as_bytes());
        let at = h.find(HEADER_CRC_KEY).unwrap() + HEADER_CRC_KEY.len();
        h.replace_range(at..at + 8, &format!("{crc:08x}"));
        let mut out = (h.len() as u64).to_le_bytes().to_vec();
        out.extend_from_slice(h.as_bytes());
        out.extend_from_slice(data);
        out
    }

    #[test]
    fn valid_checksums_with_a_bad_layout_are_refused() {
        let p = Path::new("forged.relight");
        let data = [0u8; 32];
        // The forgery helper itself makes readable bundles.
        let good = forge(&[("a", vec![4], [0, 16]), ("b", vec![4], [16, 32])], &data);
        assert_eq!(Bundle::from_bytes(p, &good).unwrap().tensors.len(), 2);
        for (tensors, data_len, want) in [
            (
                vec![("a", vec![4], [0, 16]), ("b", vec![4], [8, 24])],
                24,
                "overlap",
            ),
            (
                vec![("a", vec![4], [0, 16]), ("b", vec![4], [0, 16])],
                16,
                "overlap",
            ),
            (
                vec![("a", vec![4], [0, 16])],
                20,
                "4 bytes of trailing data",
            ),
            (
                vec![("a", vec![2], [0, 8]), ("b", vec![2], [16, 24])],
                24,
                "belong to no tensor",
            ),
            (
                vec![("a", vec![2], [8, 16])],
                16,
                "[0, 8) belong to no tensor",
            ),
        ] {
            let bytes = forge(&tensors, &data[..data_len]);
            let e = Bundle::from_bytes(p, &bytes).unwrap_err().to_string();
            assert!(
                e.starts_with("forged.relight: ") && e.contains(want),
                "{want}: {e}"
            );
        }
    }

    /// The error and its sources joined by ": ", as `anyhow` prints `{:#}`.
    fn chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut cur = e.source();
        while let Some(c) = cur {
            s += &format!(": {c}");
            cur = c.source();
        }
        s
    }

    #[test]
    fn os_errors_print_once_in_an_error_chain() {
        let e = Bundle::read(Path::new("/nonexistent/x.relight")).unwrap_err();
        let s = chain(&e);
        assert_eq!(s.matches("os error 2").count(), 1, "{s}");
        let e = sample()
            .write(Path::new("/nonexistent-dir/x.relight"))
            .unwrap_err();
        let s = chain(&e);
        assert_eq!(s.matches("os error 2").count(), 1, "{s}");
        // A write error names the output, not the temporary.
        assert!(s.starts_with("/nonexistent-dir/x.relight: "), "{s}");
    }

    #[test]
    fn special_files_are_refused_without_blocking() {
        let d = tmp("fifo").with_file_name("fifo-dir");
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let fifo = d.join("b.relight");
        match std::process::Command::new("mkfifo").arg(&fifo).status() {
            Ok(s) if s.success() => {}
            other => {
                relight_testdata::skip_platform("fifo", &format!("mkfifo unavailable ({other:?})"));
                return;
            }
        }
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let r = (Bundle::read(&fifo), Bundle::read(Path::new("/dev/zero")));
            let _ = tx.send(r);
        });
        let (a, b) = rx
            .recv_timeout(std::time::Duration::from_secs(10))
            .expect("reading a FIFO or /dev/zero did not return within 10 s");
        for e in [a.unwrap_err(), b.unwrap_err()] {
            assert!(e.to_string().contains("not a regular file"), "{e}");
        }
    }

    #[test]
    fn stale_temporaries_of_dead_processes_are_removed_by_the_next_write() {
        if !Path::new("/proc/self").exists() {
            relight_testdata::skip_platform(
                "proc",
                "no /proc: stale temporaries cannot be recognised here",
            );
            return;
        }
        let dead = {
            let mut c = std::process::Command::new("true").spawn().unwrap();
            let pid = c.id();
            c.wait().unwrap();
            pid
        };
        let d = tmp("x").with_file_name("stale-dir");
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let out = d.join("scene.relight");
        let host = tmpfile::host_name();
        let stale = d.join(format!(
            ".scene.relight{}{host}.{dead}.{:016x}",
            tmpfile::TMP_MARKER,
            42
        ));
        let stale_other = d.join(format!(
            ".other.relight{}{host}.{dead}.{:016x}",
            tmpfile::TMP_MARKER,
            43
        ));
        let legacy = d.join(format!("scene.relight.tmp-{dead}"));
        let live = d.join(tmpfile::temporary_name("scene.relight"));
        let foreign = d.join(format!(
            ".scene.relight{}another-host.{dead}.{:016x}",
            tmpfile::TMP_MARKER,
            44
        ));
        for f in [&stale, &stale_other, &legacy, &live, &foreign] {
            std::fs::write(f, b"partial bundle").unwrap();
        }
        sample().write(&out).unwrap();
        assert!(!stale.exists() && !stale_other.exists() && !legacy.exists());
        // This process's own temporaries and other hosts' are kept.
        assert!(live.exists() && foreign.exists());
        assert_eq!(Bundle::read(&out).unwrap(), sample());
    }

    #[test]
    fn failed_write_leaves_no_file() {
        let p = Path::new("/nonexistent-dir/x.relight");
        assert!(sample().write(p).is_err());
        assert!(!p.exists());
    }
}
