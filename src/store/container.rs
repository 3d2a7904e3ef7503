//! The container both of the engine's files use: a safetensors file whose one metadata entry
//! `meta` is JSON naming the format and its version, with a checksum over the tensors and a seal
//! over the metadata text. Writing is atomic ([`crate::files::write_atomically`]); reading knows
//! every format by name, so a file of the other kind is refused with what to do with it.
//!
//! The transport file ([`crate::store::transport`]) and the volume file
//! ([`crate::volume::VolumeTransfer`]) each add their tensors and their own metadata fields.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

use safetensors::tensor::{Dtype, View};

use crate::error::{PrtError, Result};

/// A file format of the engine: its name in the metadata and how to speak of it in messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Format {
    /// The `format` field of the metadata.
    pub name: &'static str,
    /// What a user calls it ("transport file").
    pub noun: &'static str,
    /// The command that writes it.
    pub made_by: &'static str,
    /// The commands that read it.
    pub read_by: &'static str,
}

/// The per-pixel transport of a fixed view (`.prt`, [`crate::store::transport`]).
pub const TRANSPORT: Format = Format {
    name: "wavelet-prt transport",
    noun: "transport file",
    made_by: "prt bake",
    read_by: "`prt relight` or `prt view`",
};

/// The SH self-transfer of a medium (`.prtv`, [`crate::volume`]).
pub const VOLUME: Format = Format {
    name: "wavelet-prt volume",
    noun: "volume file",
    made_by: "prt volume bake",
    read_by: "`prt volume render` or `prt view`",
};

const FORMATS: [Format; 2] = [TRANSPORT, VOLUME];

/// The error for a file of another known format where `want` was expected, naming what the
/// file is and what reads it; `None` when `found` is not one of ours (the caller says what it
/// expected).
pub fn other_format(path: &Path, found: Option<&str>, want: Format) -> Option<PrtError> {
    let other = FORMATS
        .iter()
        .find(|f| Some(f.name) == found && f.name != want.name)?;
    Some(PrtError::file(
        path,
        format!(
            "a {} (from `{}`), not a {}: relight it with {}",
            other.noun, other.made_by, want.noun, other.read_by
        ),
    ))
}

/// The format a file names in its metadata, read from at most the first MiB of its header;
/// `None` when it is no safetensors file of ours or cannot be read.
pub fn sniff(path: &Path) -> Option<Format> {
    use std::io::Read;
    let (mut f, _) = crate::files::open_regular(path, u64::MAX, "file").ok()?;
    let mut len = [0u8; 8];
    f.read_exact(&mut len).ok()?;
    let n = u64::from_le_bytes(len).min(1 << 20) as usize;
    let mut header = vec![0u8; n];
    f.read_exact(&mut header).ok()?;
    let text = String::from_utf8_lossy(&header);
    FORMATS.into_iter().find(|f| text.contains(f.name))
}

/// Writes `tensors` (in the order their checksum covers them) and the metadata that
/// `header(checksum)` makes from the tensors' checksum (16 hex digits), sealed
/// ([`seal_meta`]), atomically at `path`.
pub fn save(
    path: &Path,
    tensors: Vec<(&str, Tensor)>,
    header: impl FnOnce(String) -> serde_json::Result<String>,
) -> Result<()> {
    let sum = checksum(tensors.iter().map(|(_, t)| t.bytes));
    let json = header(format!("{sum:016x}"))
        .map_err(|e| PrtError::file(path, format!("metadata: {e}")))?;
    crate::files::write_atomically(path, |tmp| write_tensors(tmp, tensors, seal_meta(json)))
}

/// Reads a whole file of at most `max_bytes` in 8 MiB pieces, calling `progress(bytes read,
/// file size)` after each.
pub fn read_with_progress(
    path: &Path,
    max_bytes: u64,
    what: &str,
    progress: &dyn Fn(u64, u64),
) -> Result<Vec<u8>> {
    use std::io::Read;
    let (f, total) = crate::files::open_regular(path, max_bytes, what)?;
    // The size was read before the data: a file that grows meanwhile is not read past it.
    let mut f = f.take(total);
    let mut buf = Vec::new();
    buf.try_reserve_exact(total as usize)
        .map_err(|_| PrtError::file(path, format!("{total} bytes do not fit in memory")))?;
    let mut piece = vec![0u8; 8 << 20];
    loop {
        let n = f.read(&mut piece).map_err(|e| PrtError::io(path, e))?;
        if n == 0 {
            break;
        }
        buf.extend_from_slice(&piece[..n]);
        progress(buf.len() as u64, total);
    }
    Ok(buf)
}

/// The last member of a sealed `meta` text, before its 16 hex digits and the closing `"}`.
const META_CHECKSUM_KEY: &str = ",\"meta_checksum\":\"";

/// Appends `"meta_checksum": "HEX"` to a JSON object's text as its last member: the
/// [`checksum`] of the text before it, closed by `}`. So a reader in any language checks the
/// metadata by cutting the member off, closing the brace and hashing the bytes.
pub fn seal_meta(mut json: String) -> String {
    let sum = checksum([json.as_bytes()]);
    json.pop();
    json.push_str(&format!("{META_CHECKSUM_KEY}{sum:016x}\"}}"));
    json
}

/// Checks the `meta_checksum` of a `meta` text written by [`seal_meta`]. A text without one
/// (written before it existed) passes; its fields are checked one by one all the same.
pub fn check_meta_seal(text: &str) -> std::result::Result<(), String> {
    if !text.contains("\"meta_checksum\"") {
        return Ok(());
    }
    let sealed = text.strip_suffix("\"}").and_then(|body| {
        let stored = body.get(body.len().checked_sub(16)?..)?;
        let covered = body
            .get(..body.len() - 16)?
            .strip_suffix(META_CHECKSUM_KEY)?;
        Some((stored, covered))
    });
    let Some((stored, covered)) = sealed else {
        return Err(
            "metadata `meta_checksum` is not the last member of `meta`: the header \
                    is corrupted or was edited"
                .into(),
        );
    };
    let sum = format!("{:016x}", checksum([format!("{covered}}}").as_bytes()]));
    if sum != stored {
        return Err(format!(
            "metadata checksum mismatch (stored {stored}, computed {sum}): the header is \
             corrupted or was edited"
        ));
    }
    Ok(())
}

/// A 64-bit checksum of byte slices taken in order: words mixed with the SplitMix64 finaliser,
/// position-dependent, so any flipped bit changes it. Fast enough to run on every load
/// (several GB/s).
pub fn checksum<'a>(parts: impl IntoIterator<Item = &'a [u8]>) -> u64 {
    let mut h = 0x51_7c_c1_b7_27_22_0a_95u64;
    for part in parts {
        let mut chunks = part.chunks_exact(8);
        for c in &mut chunks {
            let w = u64::from_le_bytes(c.try_into().unwrap_or([0; 8]));
            h = crate::math::sampling::mix64(h ^ w).wrapping_add(0x9e37_79b9_7f4a_7c15);
        }
        let mut tail = [0u8; 8];
        tail[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
        h = crate::math::sampling::mix64(h ^ u64::from_le_bytes(tail) ^ (part.len() as u64) << 3);
    }
    h
}

/// Writes a safetensors file at `path` with one metadata entry `meta` holding `meta_json`:
/// the header as the `safetensors` crate lays it out (tensors by descending dtype alignment, then
/// name; the header padded to 8 bytes), then each tensor's bytes, straight into `path` (the
/// caller's temporary file, which gets the umask's permissions).
fn write_tensors(path: &Path, mut tensors: Vec<(&str, Tensor)>, meta_json: String) -> Result<()> {
    use std::io::Write;
    tensors.sort_by(|(ln, l), (rn, r)| r.dtype.cmp(&l.dtype).then(ln.cmp(rn)));
    let mut offset = 0;
    let mut infos = Vec::with_capacity(tensors.len());
    for (name, t) in &tensors {
        let info = safetensors::tensor::TensorInfo {
            dtype: t.dtype,
            shape: t.shape.clone(),
            data_offsets: (offset, offset + t.bytes.len()),
        };
        offset += t.bytes.len();
        infos.push((name.to_string(), info));
    }
    let info: HashMap<String, String> = [("meta".to_string(), meta_json)].into();
    let metadata = safetensors::tensor::Metadata::new(Some(info), infos)
        .map_err(|e| PrtError::file(path, format!("tensor layout: {e}")))?;
    let mut header = serde_json::to_string(&metadata)
        .map_err(|e| PrtError::file(path, format!("header: {e}")))?
        .into_bytes();
    header.resize(header.len().next_multiple_of(8), b' ');
    let file = std::fs::File::create(path).map_err(|e| PrtError::io(path, e))?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    let io = |e| PrtError::io(path, e);
    w.write_all(&(header.len() as u64).to_le_bytes())
        .map_err(io)?;
    w.write_all(&header).map_err(io)?;
    for (_, t) in &tensors {
        w.write_all(t.bytes).map_err(io)?;
    }
    w.flush().map_err(io)?;
    Ok(())
}

/// A borrowed tensor to write.
pub struct Tensor<'a> {
    dtype: Dtype,
    shape: Vec<usize>,
    bytes: &'a [u8],
}

impl<'a> Tensor<'a> {
    pub fn new<T: bytemuck::NoUninit>(dtype: Dtype, shape: Vec<usize>, data: &'a [T]) -> Self {
        Tensor {
            dtype,
            shape,
            bytes: bytemuck::cast_slice(data),
        }
    }
}

impl View for Tensor<'_> {
    fn dtype(&self) -> Dtype {
        self.dtype
    }
    fn shape(&self) -> &[usize] {
        &self.shape
    }
    fn data(&self) -> Cow<'_, [u8]> {
        Cow::Borrowed(self.bytes)
    }
    fn data_len(&self) -> usize {
        self.bytes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sealed_text_passes_and_any_changed_byte_fails() {
        let sealed = seal_meta(r#"{"a":1,"b":"x"}"#.to_string());
        assert!(check_meta_seal(&sealed).is_ok());
        let edited = sealed.replace("\"a\":1", "\"a\":2");
        assert!(check_meta_seal(&edited).unwrap_err().contains("mismatch"));
        // A text written before the seal existed is read as before.
        assert!(check_meta_seal(r#"{"a":1}"#).is_ok());
    }

    #[test]
    fn checksum_depends_on_every_bit_and_on_where_parts_end() {
        let data = vec![7u8; 37];
        let base = checksum([data.as_slice()]);
        for bit in [0, 9, 8 * 36 + 7] {
            let mut d = data.clone();
            d[bit / 8] ^= 1 << (bit % 8);
            assert_ne!(checksum([d.as_slice()]), base, "bit {bit}");
        }
        assert_ne!(checksum([&data[..8], &data[8..]]), base);
    }

    #[test]
    fn a_file_of_the_other_kind_is_named_with_what_reads_it() {
        let p = Path::new("x.prtv");
        let e = other_format(p, Some(VOLUME.name), TRANSPORT).unwrap();
        assert!(
            e.to_string()
                .contains("a volume file (from `prt volume bake`)")
        );
        assert!(other_format(p, Some(TRANSPORT.name), TRANSPORT).is_none());
        assert!(other_format(p, Some("something else"), TRANSPORT).is_none());
    }
}
