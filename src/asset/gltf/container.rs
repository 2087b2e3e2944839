//! The file containers: a `.gltf`'s JSON or a `.glb`'s chunks, buffer URIs (relative paths
//! and base64 data URIs), and writing a GLB.

use std::io::Read;

use super::*;

/// A file's bytes, with where its JSON and (for a `.glb`) its BIN chunk are.
pub(super) struct Source {
    pub(super) bytes: Vec<u8>,
    pub(super) json: Range<usize>,
    pub(super) bin: Option<Range<usize>>,
    pub(super) is_glb: bool,
}

impl Source {
    pub(super) fn json(&self) -> &[u8] {
        self.bytes.get(self.json.clone()).unwrap_or_default()
    }

    pub(super) fn bin(&self) -> Option<&[u8]> {
        self.bin.clone().and_then(|r| self.bytes.get(r))
    }
}

pub(super) fn read_source(file: &Path) -> Result<Source, GltfError> {
    let bytes = fs::read(file).map_err(|source| GltfError::Read {
        file: file.to_owned(),
        what: "the file".to_owned(),
        source,
    })?;
    let glb_extension = file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    if bytes.starts_with(b"glTF") || glb_extension {
        let (json, bin) = split_glb(file, &bytes)?;
        Ok(Source {
            bytes,
            json,
            bin,
            is_glb: true,
        })
    } else {
        Ok(Source {
            json: 0..bytes.len(),
            bytes,
            bin: None,
            is_glb: false,
        })
    }
}

pub(super) fn le_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b: [u8; 4] = bytes.get(at..at.checked_add(4)?)?.try_into().ok()?;
    Some(u32::from_le_bytes(b))
}

/// Where the JSON chunk and the BIN chunk (if any) of a GLB file are, every length checked.
pub(super) fn split_glb(
    file: &Path,
    bytes: &[u8],
) -> Result<(Range<usize>, Option<Range<usize>>), GltfError> {
    let err = |reason: String| GltfError::Glb {
        file: file.to_owned(),
        reason,
    };
    if bytes.len() < 12 {
        return Err(err(format!(
            "the file is {} bytes, shorter than the 12-byte GLB header",
            bytes.len()
        )));
    }
    if !bytes.starts_with(b"glTF") {
        return Err(err("it does not start with the magic \"glTF\"".to_owned()));
    }
    let version = le_u32(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(err(format!(
            "GLB version {version} is not supported (only 2)"
        )));
    }
    let declared = le_u32(bytes, 8).unwrap_or(0) as usize;
    if declared > bytes.len() {
        return Err(err(format!(
            "the header declares {declared} bytes but the file has {} (truncated?)",
            bytes.len()
        )));
    }
    let Some(body) = bytes.get(12..declared) else {
        return Err(err(format!(
            "the header declares {declared} bytes, fewer than the header itself"
        )));
    };
    let (mut offset, mut chunk) = (0usize, 0usize);
    let (mut json, mut bin) = (None, None);
    while offset < body.len() {
        let (Some(length), Some(kind)) = (le_u32(body, offset), body.get(offset + 4..offset + 8))
        else {
            return Err(err(format!(
                "chunk {chunk}'s header at byte {} is cut off (truncated?)",
                12 + offset
            )));
        };
        let start = offset + 8;
        let Some(end) = start
            .checked_add(length as usize)
            .filter(|&end| end <= body.len())
        else {
            return Err(err(format!(
                "chunk {chunk} declares {length} bytes but only {} remain (truncated?)",
                body.len().saturating_sub(start)
            )));
        };
        // Ranges in the whole file, after its 12-byte header.
        let range = 12 + start..12 + end;
        match (chunk, kind) {
            (0, b"JSON") => json = Some(range),
            (0, _) => return Err(err("its first chunk is not JSON".to_owned())),
            (_, b"BIN\0") if bin.is_none() => bin = Some(range),
            // The spec asks readers to skip chunks they do not know.
            _ => {}
        }
        offset = end;
        chunk += 1;
    }
    let Some(json) = json else {
        return Err(err("it has no JSON chunk".to_owned()));
    };
    Ok((json, bin))
}

/// The bytes `uri` names, at most `limit` of them: a buffer needs no more than its
/// `byteLength`, and a file is read only if it is a regular file (never a device or a pipe
/// that might not end).
pub(super) fn read_uri(
    file: &Path,
    base: &Path,
    at: &str,
    uri: &str,
    limit: u64,
) -> Result<Vec<u8>, GltfError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((_, payload)) = rest.split_once(";base64,") else {
            return Err(invalid(
                file,
                at,
                "its data URI is not base64 (data:…;base64,…)",
            ));
        };
        // Standard base64, as RFC 2397 says; some writers use the URL-safe alphabet.
        return base64::decode(payload)
            .or_else(|_| base64::decode_config(payload, base64::URL_SAFE))
            .map_err(|e| invalid(file, at, format!("its data URI holds invalid base64: {e}")));
    }
    if has_scheme(uri) {
        return Err(invalid(
            file,
            at,
            format!("URI \"{uri}\" is neither a relative path nor a data URI"),
        ));
    }
    let Ok(relative) = percent_encoding::percent_decode_str(uri).decode_utf8() else {
        return Err(invalid(
            file,
            at,
            format!("URI \"{uri}\" is badly percent-encoded"),
        ));
    };
    let target = base.join(&*relative);
    let read_error = |source| GltfError::Read {
        file: file.to_owned(),
        what: format!("{at} from \"{}\"", target.display()),
        source,
    };
    let external = fs::File::open(&target).map_err(read_error)?;
    if !external.metadata().map_err(read_error)?.is_file() {
        return Err(invalid(
            file,
            at,
            format!("\"{}\" is not a regular file", target.display()),
        ));
    }
    let mut bytes = Vec::new();
    external
        .take(limit)
        .read_to_end(&mut bytes)
        .map_err(read_error)?;
    Ok(bytes)
}

/// Whether `uri` starts with a scheme such as `http:` (two letters or more, so that a Windows
/// drive letter is not one).
pub(super) fn has_scheme(uri: &str) -> bool {
    uri.split_once(':').is_some_and(|(scheme, _)| {
        scheme.len() > 1
            && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
            && scheme
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "+.-".contains(c))
    })
}

/// `data` as standard base64 with padding, for data URIs.
pub(super) fn base64_encode(data: &[u8]) -> String {
    base64::encode(data)
}

pub(super) fn glb_bytes(
    file: &Path,
    json: Vec<u8>,
    bin: Option<Vec<u8>>,
) -> Result<Vec<u8>, GltfError> {
    let total = 12 + 8 + json.len() + 3 + bin.as_ref().map_or(0, |b| 8 + b.len() + 3);
    if u32::try_from(total).is_err() {
        return Err(invalid(
            file,
            "GLB",
            "would exceed the format's 4 GiB limit",
        ));
    }
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // `to_vec` computes it
        },
        json: Cow::Owned(json),
        bin: bin.map(Cow::Owned),
    };
    glb.to_vec().map_err(|e| internal(file, e))
}
