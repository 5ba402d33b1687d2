//! glTF containers and bytes: the GLB chunks, buffers (GLB BIN chunk, base64 `data:` URIs,
//! files under the path policy of [`crate::io::files`]) and the URIs of images.

use crate::error::SceneError;
use crate::io::files::{self, LoadOptions};
use std::path::Path;

/// Split a GLB container into its JSON chunk and optional BIN chunk.
pub(super) fn split_glb<'a>(
    path: &Path,
    b: &'a [u8],
) -> Result<(&'a [u8], Option<&'a [u8]>), SceneError> {
    let u32_at = |o: usize| {
        b.get(o..o + 4)
            .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]) as usize)
    };
    if !b.starts_with(b"glTF") {
        return Err(SceneError::malformed(path, "not a GLB file (bad magic)"));
    }
    let (Some(version), Some(total)) = (u32_at(4), u32_at(8)) else {
        return Err(SceneError::malformed(path, "truncated GLB header"));
    };
    if version != 2 {
        return Err(SceneError::unsupported(
            path,
            format!("GLB version {version}"),
        ));
    }
    if total > b.len() {
        return Err(SceneError::malformed(
            path,
            format!(
                "truncated: GLB announces {total} bytes, file has {}",
                b.len()
            ),
        ));
    }
    let mut chunks = Vec::new();
    let mut o = 12;
    while o + 8 <= total {
        let (Some(len), Some(kind)) = (u32_at(o), u32_at(o + 4)) else {
            break;
        };
        let data = b
            .get(o + 8..o + 8 + len)
            .filter(|_| o + 8 + len <= total)
            .ok_or_else(|| {
                SceneError::malformed(
                    path,
                    format!("truncated: GLB chunk at byte {o} overruns the file"),
                )
            })?;
        chunks.push((kind, data));
        o += 8 + len.div_ceil(4) * 4;
    }
    match chunks.first() {
        Some(&(0x4E4F_534A, json)) => Ok((
            json,
            chunks.get(1).filter(|c| c.0 == 0x004E_4942).map(|c| c.1),
        )),
        _ => Err(SceneError::malformed(
            path,
            "GLB does not start with a JSON chunk",
        )),
    }
}

pub(super) fn load_buffers(
    path: &Path,
    doc: &gltf::Document,
    bin: Option<&[u8]>,
    opts: &LoadOptions,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut out = Vec::with_capacity(doc.buffers().len());
    for b in doc.buffers() {
        let (i, byte_length) = (b.index(), b.length());
        if byte_length as u64 > files::MAX_FILE_BYTES {
            return Err(SceneError::too_large(
                path,
                format!(
                    "buffer {i}: byteLength {byte_length} exceeds the limit of {} bytes",
                    files::MAX_FILE_BYTES
                ),
            ));
        }
        let data = match b.source() {
            gltf::buffer::Source::Bin if i == 0 => bin
                .ok_or_else(|| {
                    SceneError::malformed(path, "buffer 0 has no uri and there is no GLB BIN chunk")
                })?
                .to_vec(),
            gltf::buffer::Source::Bin => {
                return Err(SceneError::malformed(
                    path,
                    format!("buffer {i} has no uri"),
                ))
            }
            gltf::buffer::Source::Uri(uri) => {
                read_uri(path, uri, &format!("buffer {i}"), byte_length as u64, opts)?
            }
        };
        if data.len() < byte_length {
            return Err(SceneError::malformed(
                path,
                format!(
                    "buffer {i} holds {} bytes, byteLength says {byte_length}",
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// The bytes a buffer or image `uri` names: a base64 `data:` URI, or a relative file path
/// resolved under the path policy and read up to `max_bytes`. `what` names it in errors.
pub(crate) fn read_uri(
    path: &Path,
    uri: &str,
    what: &str,
    max_bytes: u64,
    opts: &LoadOptions,
) -> Result<Vec<u8>, SceneError> {
    if uri.starts_with("data:") {
        let (_, payload) = uri.split_once(";base64,").ok_or_else(|| {
            SceneError::unsupported(path, format!("{what}: data URI that is not base64"))
        })?;
        return base64_decode(payload)
            .map_err(|m| SceneError::malformed(path, format!("{what}: {m}")));
    }
    if has_scheme(uri) {
        return Err(SceneError::unsupported(
            path,
            format!("{what}: uri '{uri}' (only relative file paths and data: URIs)"),
        ));
    }
    let rel = files::percent_decode(uri);
    let file = files::resolve_model_ref(path, &rel, &opts.paths, &format!("{what} uri"))?;
    files::read_prefix(&file, max_bytes)
}

/// Whether a URI reference starts with a scheme (`file:`, `http:`, `data:`; RFC 3986: a
/// letter, then letters, digits, `+`, `-`, `.`, then `:`).
fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            scheme.starts_with(|c: char| c.is_ascii_alphabetic())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        }
        None => false,
    }
}

/// Decode standard base64 (padding optional, whitespace ignored).
pub(super) fn base64_decode(s: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return Err(format!("invalid base64 character '{}'", c as char)),
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Ok(out)
}
