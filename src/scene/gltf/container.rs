//! The file around the glTF document: splitting a `.glb` into its JSON and BIN chunks,
//! parsing the JSON, and fetching buffers from the BIN chunk, `data:` URIs or files next
//! to the scene. Everything after this works on [`Doc`], whose buffers are loaded and
//! whose byte ranges are checked on access.

use std::path::PathBuf;

use ::gltf::json;

use super::SUPPORTED_REQUIRED;
use crate::scene::{
    error::{GlbError, UriError},
    SceneError,
};

/// Split a file into its JSON document and, for `.glb`, the binary chunk.
pub(super) fn parse_container(
    file: &str,
    bytes: &[u8],
) -> Result<(json::Root, Option<Vec<u8>>), SceneError> {
    let (json_bytes, blob, where_) = if bytes.starts_with(b"glTF") {
        let (j, b) = parse_glb(bytes).map_err(|source| SceneError::Glb {
            file: file.to_string(),
            source,
        })?;
        (j, b, " (in the .glb JSON chunk)")
    } else {
        // A UTF-8 byte order mark is not allowed, but harmless.
        (
            bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes),
            None,
            "",
        )
    };
    let root: json::Root = serde_json::from_slice(json_bytes).map_err(|e| {
        let text = e.to_string();
        let message = match text.rfind(" at line ") {
            Some(i) => text[..i].to_string(),
            None => text,
        };
        SceneError::Parse {
            file: file.to_string(),
            line: e.line().max(1),
            column: e.column().max(1),
            message: format!("{message}{where_}"),
        }
    })?;
    if !root.asset.version.starts_with("2.") {
        return Err(SceneError::Invalid {
            name: file.to_string(),
            message: format!(
                "glTF version {} is not supported (2.x expected)",
                root.asset.version
            ),
        });
    }
    Ok((root, blob.map(<[u8]>::to_vec)))
}

fn le_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// The JSON and BIN chunks of a binary glTF file.
fn parse_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), GlbError> {
    const JSON: u32 = 0x4E4F_534A;
    const BIN: u32 = 0x004E_4942;
    if bytes.len() < 12 {
        return Err(GlbError::ShortHeader(bytes.len()));
    }
    let version = le_u32(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(GlbError::Version(version));
    }
    let length = le_u32(bytes, 8).unwrap_or(0) as usize;
    if length > bytes.len() {
        return Err(GlbError::ShortFile {
            declared: length,
            actual: bytes.len(),
        });
    }
    if length < 12 {
        return Err(GlbError::TinyLength(length));
    }
    let data = &bytes[..length];
    let mut pos = 12usize;
    let mut json_chunk = None;
    let mut bin_chunk = None;
    while pos < data.len() {
        let (Some(len), Some(kind)) = (le_u32(data, pos), le_u32(data, pos + 4)) else {
            return Err(GlbError::ChunkHeader(pos));
        };
        let start = pos + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| GlbError::ShortChunk {
                at: pos,
                len,
                remain: data.len() - start.min(data.len()),
            })?;
        let chunk = &data[start..end];
        match kind {
            JSON if json_chunk.is_none() && pos == 12 => json_chunk = Some(chunk),
            JSON => return Err(GlbError::SecondJson(pos)),
            _ if json_chunk.is_none() => return Err(GlbError::FirstNotJson),
            BIN if bin_chunk.is_none() => bin_chunk = Some(chunk),
            // Unknown chunk types must be ignored.
            _ => {}
        }
        // Chunks are 4-byte aligned; tolerate writers that forgot the padding at the end.
        pos = end.saturating_add(3) & !3;
    }
    let json_chunk = json_chunk.ok_or(GlbError::NoJson)?;
    Ok((json_chunk, bin_chunk))
}

/// Decode standard or URL-safe base64, with or without padding.
fn base64_decode(text: &str) -> Result<Vec<u8>, UriError> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    let mut padding = false;
    for (i, c) in text.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => {
                padding = true;
                continue;
            }
            c if c.is_ascii_whitespace() => continue,
            _ => return Err(UriError::Base64Character(i)),
        };
        if padding {
            return Err(UriError::Base64AfterPadding(i));
        }
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// Decode `%XX` escapes of a relative URI into a path string.
pub(super) fn percent_decode(uri: &str) -> Result<String, UriError> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or(UriError::PercentEscape(i))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| UriError::PercentNotUtf8)
}

/// The parsed file: JSON model and buffer contents, with checked access to both.
pub(super) struct Doc {
    /// The scene file as shown in messages.
    pub(super) file: String,
    /// Where relative URIs start.
    pub(super) dir: PathBuf,
    pub(super) root: json::Root,
    /// Buffer contents, cut to their declared `byteLength`; filled by
    /// [`Doc::load_buffers`].
    pub(super) buffers: Vec<Vec<u8>>,
}

impl Doc {
    pub(super) fn invalid(&self, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            name: self.file.clone(),
            message: message.into(),
        }
    }

    pub(super) fn check_required_extensions(&self) -> Result<(), SceneError> {
        for e in &self.root.extensions_required {
            if !SUPPORTED_REQUIRED.contains(&e.as_str()) {
                return Err(self.invalid(format!(
                    "requires extension {e}, which this loader does not support (supported: {})",
                    SUPPORTED_REQUIRED.join(", ")
                )));
            }
        }
        Ok(())
    }

    /// Bytes behind a URI: `data:` (base64), `file:` or a path relative to the file.
    pub(super) fn read_uri(&self, uri: &str, what: &str) -> Result<Vec<u8>, SceneError> {
        let bad_uri = |source| SceneError::Uri {
            file: self.file.clone(),
            what: what.to_string(),
            source,
        };
        if let Some(rest) = uri.strip_prefix("data:") {
            let (_, payload) = rest
                .split_once(";base64,")
                .ok_or_else(|| bad_uri(UriError::DataNotBase64))?;
            return base64_decode(payload).map_err(bad_uri);
        }
        let path = if let Some(rest) = uri.strip_prefix("file:") {
            let rest = rest.strip_prefix("//").unwrap_or(rest);
            PathBuf::from(percent_decode(rest).map_err(bad_uri)?)
        } else if uri.split('/').next().is_some_and(|s| s.contains(':')) {
            return Err(bad_uri(UriError::Scheme(uri.to_string())));
        } else {
            self.dir.join(percent_decode(uri).map_err(bad_uri)?)
        };
        crate::scene::limits::read_bounded(&path).map_err(|e| SceneError::Io {
            path: path.clone(),
            message: format!("{e} ({what} of {})", self.file),
        })
    }

    pub(super) fn load_buffers(&mut self, mut blob: Option<Vec<u8>>) -> Result<(), SceneError> {
        let mut buffers = Vec::with_capacity(self.root.buffers.len());
        for (i, b) in self.root.buffers.iter().enumerate() {
            let what = format!("buffer {i}");
            let mut data = match &b.uri {
                Some(uri) => self.read_uri(uri, &what)?,
                None => blob.take().ok_or_else(|| {
                    self.invalid(format!(
                        "{what} has no uri, and the file has no (unclaimed) binary chunk"
                    ))
                })?,
            };
            let len = b.byte_length.0;
            if (data.len() as u64) < len {
                return Err(self.invalid(format!(
                    "{what} holds {} bytes, but its byteLength is {len} (truncated file?)",
                    data.len()
                )));
            }
            data.truncate(len as usize);
            buffers.push(data);
        }
        self.buffers = buffers;
        Ok(())
    }

    /// The bytes of a buffer view, checked against its buffer.
    pub(super) fn view_bytes(&self, index: usize, ctx: &str) -> Result<&[u8], SceneError> {
        let v = self.root.buffer_views.get(index).ok_or_else(|| {
            self.invalid(format!(
                "{ctx}: bufferView {index} does not exist ({} defined)",
                self.root.buffer_views.len()
            ))
        })?;
        let bi = v.buffer.value();
        let buf = self.buffers.get(bi).ok_or_else(|| {
            self.invalid(format!(
                "{ctx}: bufferView {index} refers to buffer {bi}, which does not exist ({} defined)",
                self.buffers.len()
            ))
        })?;
        let off = v.byte_offset.map_or(0, |o| o.0);
        let len = v.byte_length.0;
        let end = off
            .checked_add(len)
            .filter(|&e| e <= buf.len() as u64)
            .ok_or_else(|| {
                self.invalid(format!(
                "{ctx}: bufferView {index} (bytes {off}..{}) lies outside buffer {bi} ({} bytes)",
                off.saturating_add(len),
                buf.len()
            ))
            })?;
        Ok(&buf[off as usize..end as usize])
    }

    /// The glTF node's name, or `node N` when it has none.
    pub(super) fn node_name(&self, index: usize) -> String {
        self.root
            .nodes
            .get(index)
            .and_then(|n| n.name.clone())
            .unwrap_or_else(|| format!("node {index}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trip() {
        assert_eq!(base64_decode("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(base64_decode("aGVsbG8").unwrap(), b"hello");
        assert_eq!(base64_decode("AAEC/w==").unwrap(), [0, 1, 2, 255]);
        assert!(base64_decode("a$b").is_err());
    }

    #[test]
    fn percent_escapes() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert!(percent_decode("%FF").is_err());
        assert!(percent_decode("%G0").is_err());
        assert!(percent_decode("%2").is_err());
    }

    #[test]
    fn glb_container_errors() {
        assert!(parse_glb(b"glTF").is_err());
        let mut v = b"glTF".to_vec();
        v.extend_from_slice(&2u32.to_le_bytes());
        v.extend_from_slice(&100u32.to_le_bytes());
        assert_eq!(
            parse_glb(&v).unwrap_err(),
            GlbError::ShortFile {
                declared: 100,
                actual: 12
            }
        );
    }
}
