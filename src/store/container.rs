//! The container both of the engine's files use: a safetensors file whose one metadata entry
//! `meta` is JSON naming the format and its version, with a checksum over the tensors and a seal
//! over the metadata text. Writing is atomic ([`crate::files::write_atomically`]); reading knows
//! every format by name, so a file of the other kind is refused with what to do with it.
//!
//! The transport file ([`crate::store::transport`]) and the volume file
//! ([`crate::volume::VolumeTransfer`]) each add their tensors and their own metadata fields.

use std::collections::HashMap;
use std::path::Path;

use safetensors::tensor::Dtype;

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

/// What a file given where one of `want` was expected is, when its first bytes tell, and what
/// to do with it: a scene file to bake first, an image or map to give with `--env`, a mesh or a
/// grid to name in a scene. `None` when they do not tell.
pub fn what_else(path: &Path, want: Format) -> Option<String> {
    use std::io::Read;
    let (f, _) = crate::files::open_regular(path, u64::MAX, "file").ok()?;
    let mut head = Vec::new();
    f.take(1 << 20).read_to_end(&mut head).ok()?;
    let (is, then) = match head.as_slice() {
        [0x76, 0x2f, 0x31, 0x01, ..] => (
            "an OpenEXR image",
            "give an environment map with --env; `prt compare` compares two images".to_string(),
        ),
        [b'#', b'?', ..] => (
            "a Radiance HDR image",
            "give an environment map with --env".to_string(),
        ),
        [0x89, b'P', b'N', b'G', ..] => ("a PNG image", "no command reads one".to_string()),
        [0x93, b'N', b'U', b'M', b'P', b'Y', ..] => (
            "a NumPy array",
            "a density grid is named in a scene file's [[medium]]".to_string(),
        ),
        _ => {
            let text = std::str::from_utf8(&head).ok()?;
            let table = text.parse::<toml::Table>().ok();
            if table.is_some_and(|t| {
                ["camera", "shape", "material", "medium"]
                    .iter()
                    .any(|k| t.contains_key(*k))
            }) {
                let (bake, ext) = if want == VOLUME {
                    ("prt volume bake", "prtv")
                } else {
                    ("prt bake", "prt")
                };
                (
                    "a scene file",
                    format!(
                        "bake it first with `{bake} {} -o OUT.{ext}`",
                        path.display()
                    ),
                )
            } else if text
                .lines()
                .any(|l| l.starts_with("v ") || l.starts_with("f "))
            {
                (
                    "an OBJ mesh",
                    "name it in a scene file's [[shape]] of type \"mesh\"".to_string(),
                )
            } else {
                return None;
            }
        }
    };
    Some(format!("this is {is}, not a {}: {then}", want.noun))
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
/// ([`seal_meta`]), atomically at `path`. Spilled tensors are read twice (for the checksum,
/// then into the file), a piece at a time.
pub fn save(
    path: &Path,
    tensors: Vec<(&str, Tensor)>,
    header: impl FnOnce(String) -> serde_json::Result<String>,
) -> Result<()> {
    let mut sum = Checksum::new();
    for (_, t) in &tensors {
        t.for_each_piece(&mut |piece| {
            sum.update(piece);
            Ok(())
        })?;
        sum.end_part();
    }
    let json = header(format!("{:016x}", sum.value()))
        .map_err(|e| PrtError::file(path, format!("metadata: {e}")))?;
    crate::files::write_atomically(path, |file| {
        write_tensors(file, path, tensors, seal_meta(json))
    })
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

/// Checks the `meta_checksum` of a `meta` text written by [`seal_meta`]. Every file of the
/// current versions is sealed, so a text without the seal is refused: switching the seal off
/// (by renaming its key, say) must not let an edited value through.
pub fn check_meta_seal(text: &str) -> std::result::Result<(), String> {
    if !text.contains("\"meta_checksum\"") {
        return Err(
            "metadata has no `meta_checksum`, which every file of this version carries: the \
             header is corrupted or was edited"
                .into(),
        );
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

/// Checks that the metadata of a file holds the one entry `meta` and nothing else.
pub fn check_metadata_entries<'a>(
    mut keys: impl Iterator<Item = &'a String>,
) -> std::result::Result<(), String> {
    match keys.find(|k| *k != "meta") {
        Some(k) => Err(format!(
            "unknown metadata entry `{}`: a file holds only `meta`",
            crate::files::printable(k)
        )),
        None => Ok(()),
    }
}

/// Checks that every key of the JSON object `text` (a `meta` text, its seal aside) is one that
/// `parsed`, the value read from it, writes back: an unknown key, or a field this build never
/// writes with that value (null for an absent one), is an edit the reader would silently drop.
/// Keys `parsed` writes that the text lacks are fields of older files, read with defaults.
pub fn check_known_keys(
    text: &str,
    parsed: &impl serde::Serialize,
) -> std::result::Result<(), String> {
    let mut read: serde_json::Value =
        serde_json::from_str(text).map_err(|e| format!("metadata is not JSON: {e}"))?;
    if let Some(o) = read.as_object_mut() {
        o.remove("meta_checksum");
    }
    let written = serde_json::to_value(parsed).map_err(|e| format!("metadata: {e}"))?;
    match unknown_key(&read, &written) {
        Some(key) => Err(format!(
            "metadata key `{}` is not one this build writes: the header was edited",
            crate::files::printable(&key)
        )),
        None => Ok(()),
    }
}

/// The first key path of `read` that `written` lacks.
fn unknown_key(read: &serde_json::Value, written: &serde_json::Value) -> Option<String> {
    use serde_json::Value;
    match (read, written) {
        (Value::Object(r), Value::Object(w)) => r.iter().find_map(|(k, v)| match w.get(k) {
            None => Some(k.clone()),
            Some(wv) => unknown_key(v, wv).map(|inner| format!("{k}.{inner}")),
        }),
        (Value::Array(r), Value::Array(w)) => r
            .iter()
            .zip(w)
            .enumerate()
            .find_map(|(i, (a, b))| unknown_key(a, b).map(|inner| format!("{i}.{inner}"))),
        _ => None,
    }
}

/// A 64-bit checksum of byte slices taken in order: words mixed with the SplitMix64 finaliser,
/// position-dependent, so any flipped bit changes it. Fast enough to run on every load
/// (several GB/s).
pub fn checksum<'a>(parts: impl IntoIterator<Item = &'a [u8]>) -> u64 {
    let mut sum = Checksum::new();
    for part in parts {
        sum.update(part);
        sum.end_part();
    }
    sum.value()
}

/// [`checksum`] taken as the bytes arrive: a part may come in pieces of any length, and gives
/// the same value as when it comes whole.
#[derive(Clone, Debug)]
pub struct Checksum {
    h: u64,
    /// The bytes of the part's unfinished word.
    word: [u8; 8],
    word_len: usize,
    part_len: u64,
}

impl Default for Checksum {
    fn default() -> Self {
        Self::new()
    }
}

impl Checksum {
    /// A checksum before any part.
    pub fn new() -> Self {
        Checksum {
            h: 0x51_7c_c1_b7_27_22_0a_95,
            word: [0; 8],
            word_len: 0,
            part_len: 0,
        }
    }

    fn mix_word(&mut self, w: u64) {
        self.h = crate::math::sampling::mix64(self.h ^ w).wrapping_add(0x9e37_79b9_7f4a_7c15);
    }

    /// Adds the next bytes of the current part.
    pub fn update(&mut self, mut bytes: &[u8]) {
        self.part_len += bytes.len() as u64;
        if self.word_len > 0 {
            let take = (8 - self.word_len).min(bytes.len());
            self.word[self.word_len..self.word_len + take].copy_from_slice(&bytes[..take]);
            self.word_len += take;
            bytes = &bytes[take..];
            if self.word_len < 8 {
                return;
            }
            self.mix_word(u64::from_le_bytes(self.word));
            self.word_len = 0;
        }
        let mut words = bytes.chunks_exact(8);
        for c in &mut words {
            self.mix_word(u64::from_le_bytes(c.try_into().unwrap_or([0; 8])));
        }
        let rest = words.remainder();
        self.word[..rest.len()].copy_from_slice(rest);
        self.word_len = rest.len();
    }

    /// Ends the current part: its last bytes, zero-padded, are mixed with its length.
    pub fn end_part(&mut self) {
        let mut tail = [0u8; 8];
        tail[..self.word_len].copy_from_slice(&self.word[..self.word_len]);
        self.h =
            crate::math::sampling::mix64(self.h ^ u64::from_le_bytes(tail) ^ (self.part_len << 3));
        self.word_len = 0;
        self.part_len = 0;
    }

    /// The checksum of the parts ended so far.
    pub fn value(&self) -> u64 {
        self.h
    }
}

/// Writes a safetensors file into `file` (the temporary file of the output `path`, which errors
/// name) with one metadata entry `meta` holding `meta_json`: the header as the `safetensors`
/// crate lays it out (tensors by descending dtype alignment, then name; the header padded to 8
/// bytes), then each tensor's bytes.
fn write_tensors(
    file: std::fs::File,
    path: &Path,
    mut tensors: Vec<(&str, Tensor)>,
    meta_json: String,
) -> Result<()> {
    use std::io::Write;
    tensors.sort_by(|(ln, l), (rn, r)| r.dtype.cmp(&l.dtype).then(ln.cmp(rn)));
    let mut offset = 0;
    let mut infos = Vec::with_capacity(tensors.len());
    for (name, t) in &tensors {
        let info = safetensors::tensor::TensorInfo {
            dtype: t.dtype,
            shape: t.shape.clone(),
            data_offsets: (offset, offset + t.len()),
        };
        offset += t.len();
        infos.push((name.to_string(), info));
    }
    let info: HashMap<String, String> = [("meta".to_string(), meta_json)].into();
    let metadata = safetensors::tensor::Metadata::new(Some(info), infos)
        .map_err(|e| PrtError::file(path, format!("tensor layout: {e}")))?;
    let mut header = serde_json::to_string(&metadata)
        .map_err(|e| PrtError::file(path, format!("header: {e}")))?
        .into_bytes();
    header.resize(header.len().next_multiple_of(8), b' ');
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    let io = |e| PrtError::io(path, e);
    w.write_all(&(header.len() as u64).to_le_bytes())
        .map_err(io)?;
    w.write_all(&header).map_err(io)?;
    for (_, t) in &tensors {
        t.for_each_piece(&mut |piece| w.write_all(piece).map_err(io))?;
    }
    w.flush().map_err(io)?;
    Ok(())
}

/// A tensor to write: borrowed bytes, or a [`Spill`] written earlier.
pub struct Tensor<'a> {
    dtype: Dtype,
    shape: Vec<usize>,
    bytes: Source<'a>,
}

enum Source<'a> {
    Slice(&'a [u8]),
    Spill(&'a Spill),
}

impl<'a> Tensor<'a> {
    /// The bytes of `data` as a tensor of `dtype` and `shape`, which must describe them.
    pub fn new<T: bytemuck::NoUninit>(dtype: Dtype, shape: Vec<usize>, data: &'a [T]) -> Self {
        Tensor {
            dtype,
            shape,
            bytes: Source::Slice(bytemuck::cast_slice(data)),
        }
    }

    /// The bytes of `spill`, which must be `shape`'s elements of `dtype`.
    pub fn spilled(dtype: Dtype, shape: Vec<usize>, spill: &'a Spill) -> Result<Self> {
        let want = (shape.iter().product::<usize>() as u64 * dtype.bitsize() as u64).div_ceil(8);
        if want != spill.len {
            return Err(PrtError::file(
                &spill.output,
                format!(
                    "tensor `{}`: {} bytes spilled where a {dtype:?} tensor of shape {shape:?} \
                     takes {want}",
                    spill.tensor, spill.len
                ),
            ));
        }
        Ok(Tensor {
            dtype,
            shape,
            bytes: Source::Spill(spill),
        })
    }

    fn len(&self) -> usize {
        match &self.bytes {
            Source::Slice(b) => b.len(),
            Source::Spill(s) => s.len as usize,
        }
    }

    /// Calls `f` with the bytes in order, a piece at a time.
    fn for_each_piece(&self, f: &mut dyn FnMut(&[u8]) -> Result<()>) -> Result<()> {
        match &self.bytes {
            Source::Slice(b) => f(b),
            Source::Spill(s) => s.for_each_piece(f),
        }
    }
}

/// A temporary file beside an output that holds one tensor's bytes while they are produced, so
/// a writer keeps none of them in memory. It is opened as [`crate::files::create_spill`] does:
/// exclusively, and gone from the folder at once where the platform allows, so nothing is left
/// of it whatever ends the process; elsewhere it is removed when dropped. Errors name the output.
pub struct Spill {
    /// The output it is part of, for messages, and the tensor it holds.
    output: std::path::PathBuf,
    tensor: String,
    /// The file's name where it stays in the folder while open.
    path: Option<std::path::PathBuf>,
    file: std::io::BufWriter<std::fs::File>,
    len: u64,
}

impl Spill {
    /// An empty spill for tensor `name` of the output `output`.
    pub fn create(output: &Path, name: &str) -> Result<Self> {
        let (path, file) = crate::files::create_spill(output, name)?;
        Ok(Spill {
            output: output.to_path_buf(),
            tensor: name.to_string(),
            path,
            file: std::io::BufWriter::with_capacity(1 << 20, file),
            len: 0,
        })
    }

    /// An I/O error while spilling, naming the output and the tensor.
    fn io(&self, e: std::io::Error) -> PrtError {
        PrtError::file(
            &self.output,
            format!(
                "writing the temporary data of tensor `{}` beside it: {e}",
                self.tensor
            ),
        )
    }

    /// Appends `data`'s bytes.
    pub fn append<T: bytemuck::NoUninit>(&mut self, data: &[T]) -> Result<()> {
        use std::io::Write;
        let bytes: &[u8] = bytemuck::cast_slice(data);
        self.file.write_all(bytes).map_err(|e| self.io(e))?;
        self.len += bytes.len() as u64;
        Ok(())
    }

    /// Bytes appended so far.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// True when nothing was appended.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Flushes what was appended, so that it can be read back.
    pub fn flush(&mut self) -> Result<()> {
        use std::io::Write;
        self.file.flush().map_err(|e| self.io(e))
    }

    /// Reads the spill from its start in 8 MiB pieces (flushed first by [`Spill::flush`]); a
    /// file cut short is an error, not a short tensor.
    fn for_each_piece(&self, f: &mut dyn FnMut(&[u8]) -> Result<()>) -> Result<()> {
        use std::io::{Read, Seek};
        let io = |e| self.io(e);
        let mut file = self.file.get_ref();
        file.seek(std::io::SeekFrom::Start(0)).map_err(io)?;
        let mut piece = vec![0u8; (8 << 20).min(self.len as usize)];
        let mut left = self.len;
        while left > 0 {
            let n = (piece.len() as u64).min(left) as usize;
            file.read_exact(&mut piece[..n]).map_err(io)?;
            f(&piece[..n])?;
            left -= n as u64;
        }
        Ok(())
    }
}

impl Drop for Spill {
    fn drop(&mut self) {
        if let Some(path) = &self.path {
            let _ = std::fs::remove_file(path);
        }
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
        // A text without the seal is refused, as is one whose seal was renamed.
        assert!(
            check_meta_seal(r#"{"a":1}"#)
                .unwrap_err()
                .contains("no `meta_checksum`")
        );
        let renamed = sealed.replace("meta_checksum", "meta_checksun");
        assert!(
            check_meta_seal(&renamed)
                .unwrap_err()
                .contains("no `meta_checksum`")
        );
    }

    #[test]
    fn keys_a_reader_would_drop_are_found() {
        #[derive(serde::Serialize)]
        struct Inner {
            x: u32,
        }
        #[derive(serde::Serialize)]
        struct Outer {
            a: u32,
            inner: Inner,
            #[serde(skip_serializing_if = "Option::is_none")]
            maybe: Option<u32>,
        }
        let v = Outer {
            a: 1,
            inner: Inner { x: 2 },
            maybe: None,
        };
        let ok = r#"{"a":1,"inner":{"x":2},"meta_checksum":"00"}"#;
        assert!(check_known_keys(ok, &v).is_ok());
        // An older file without a field is fine.
        assert!(check_known_keys(r#"{"a":1}"#, &v).is_ok());
        let e = check_known_keys(r#"{"a":1,"inner":{"x":2,"y":3}}"#, &v).unwrap_err();
        assert!(e.contains("`inner.y`"), "{e}");
        let e = check_known_keys(r#"{"a":1,"maybe":null}"#, &v).unwrap_err();
        assert!(e.contains("`maybe`"), "{e}");
        let e = check_known_keys(r#"{"a":1,"\u001b]0;x\u0007":0}"#, &v).unwrap_err();
        assert!(!e.contains('\u{1b}') && e.contains("\\u{1b}"), "{e}");
        assert!(check_metadata_entries(["meta".to_string()].iter()).is_ok());
        let e = check_metadata_entries(["meta".into(), "x".into()].iter()).unwrap_err();
        assert!(e.contains("unknown metadata entry `x`"), "{e}");
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
    fn a_checksum_taken_in_pieces_equals_the_whole() {
        let parts: Vec<Vec<u8>> = [0usize, 1, 7, 8, 9, 37, 1000]
            .iter()
            .map(|&n| (0..n).map(|i| (i * 31 + n) as u8).collect())
            .collect();
        let whole = checksum(parts.iter().map(Vec::as_slice));
        for piece in [1, 3, 8, 13, 64] {
            let mut sum = Checksum::new();
            for part in &parts {
                for p in part.chunks(piece) {
                    sum.update(p);
                }
                sum.end_part();
            }
            assert_eq!(sum.value(), whole, "pieces of {piece}");
        }
    }

    #[test]
    fn a_spilled_tensor_is_written_as_its_bytes_and_leaves_no_file() {
        let dir = std::env::temp_dir().join(format!("prt-spill-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("t.prt");
        let data: Vec<u32> = (0..5000).collect();
        let mut spill = Spill::create(&out, "x").unwrap();
        spill.append(&data[..1234]).unwrap();
        spill.append(&data[1234..]).unwrap();
        spill.flush().unwrap();
        let e = Tensor::spilled(Dtype::U32, vec![4999], &spill)
            .err()
            .unwrap();
        assert!(e.to_string().contains("t.prt: tensor `x`"), "{e}");
        let read = |tensor: Tensor| {
            let mut sum = Checksum::new();
            let mut bytes = Vec::new();
            tensor
                .for_each_piece(&mut |p| {
                    sum.update(p);
                    bytes.extend_from_slice(p);
                    Ok(())
                })
                .unwrap();
            sum.end_part();
            (bytes, sum.value())
        };
        let spilled = read(Tensor::spilled(Dtype::U32, vec![5000], &spill).unwrap());
        let direct = read(Tensor::new(Dtype::U32, vec![5000], &data));
        assert_eq!(spilled, direct);
        drop(spill);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        std::fs::remove_dir_all(&dir).unwrap();
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
