//! Unturned weights kept on disk, so that a fresh process (`prt relight`, the viewer's first
//! light) reads the splat of its map size instead of recording it again: a 1024 x 512 map at
//! N = 32 takes about 25 ms to record and a few to read.
//!
//! Only pitch 0 is kept (the unturned SH light always needs it, and so does every wavelet light
//! that is not pitched), so the folder holds one file per map size and N. Files go to
//! `$PRT_CACHE_DIR`, else `$XDG_CACHE_HOME/wavelet-prt`, else `$HOME/.cache/wavelet-prt`; an empty
//! `PRT_CACHE_DIR` turns the disk off. They are written atomically. A file is input like any
//! other: its header must name the size asked for, its length must be the one the header implies
//! before anything is allocated, and every index, flag and count the gather relies on is checked
//! (every row of `width` cells, each closed by its last share; texels in range; the uneven
//! shares' tables as counted). What the gather derives (the solid angle each texel received, the
//! exact solid angles) is computed again, not read. A file that fails any check, or cannot be
//! read, is recorded again and written over; a folder that cannot be written only costs the
//! next process the recording.
//!
//! Layout (little-endian): the magic `PRTW`, the version, then `width`, `height`, `n`, the
//! sub-columns Q and the share and uneven-share counts S and B as u64, then `resolves_cuts` as a
//! u64 0 or 1; then the words (u32 x S), the weights (f32 x S), the row starts and row uneven
//! counts (u64 x (H + 1) each) and the tables (u16 x (Q − 1) B).

use std::io::Read;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::{LAST, LatLongWeights, MAX_SUBCOLUMNS, TAIL_SCALE, TEXEL_BITS, UNEVEN};
use crate::error::{PrtError, Result};
use crate::math::cubemap::texel_count;

const MAGIC: &[u8; 4] = b"PRTW";
/// Version of the layout; a file of another version is recorded again.
const VERSION: u32 = 1;
/// Bytes before the arrays: magic, version, seven u64.
const HEADER_BYTES: usize = 8 + 7 * 8;

/// The folder the weights are kept in, or `None` when the disk is off or no home is known.
pub fn folder() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("PRT_CACHE_DIR") {
        return (!dir.is_empty()).then(|| PathBuf::from(dir));
    }
    let base = match std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(std::env::var_os("HOME").filter(|d| !d.is_empty())?).join(".cache"),
    };
    Some(base.join("wavelet-prt"))
}

/// The file of the unturned weights of a `width` x `height` map at face size `n`.
pub fn path(dir: &Path, width: usize, height: usize, n: usize) -> PathBuf {
    dir.join(format!("latlong-{width}x{height}-n{n}.v{VERSION}.prtw"))
}

/// The bytes of `w` in the layout of the module notes.
pub fn encode(w: &LatLongWeights) -> Vec<u8> {
    let b_count = w.row_uneven[w.height];
    let mut out = Vec::with_capacity(file_bytes(w.word.len(), w.height, w.subcolumns, b_count));
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    for v in [
        w.width,
        w.height,
        w.n,
        w.subcolumns,
        w.word.len(),
        b_count,
        w.resolves_cuts as usize,
    ] {
        out.extend_from_slice(&(v as u64).to_le_bytes());
    }
    w.word.iter().for_each(|v| out.extend(v.to_le_bytes()));
    w.weight.iter().for_each(|v| out.extend(v.to_le_bytes()));
    for table in [&w.row_start, &w.row_uneven] {
        table
            .iter()
            .for_each(|&v| out.extend((v as u64).to_le_bytes()));
    }
    w.tail.iter().for_each(|v| out.extend(v.to_le_bytes()));
    out
}

/// Bytes of a file of `shares` shares, `height` rows, Q sub-columns and `uneven` uneven shares,
/// or `None` past usize.
fn checked_file_bytes(shares: u64, height: u64, q: u64, uneven: u64) -> Option<usize> {
    let arrays = shares
        .checked_mul(8)?
        .checked_add(height.checked_add(1)?.checked_mul(16)?)?
        .checked_add(q.checked_sub(1)?.checked_mul(uneven)?.checked_mul(2)?)?;
    usize::try_from(arrays.checked_add(HEADER_BYTES as u64)?).ok()
}

fn file_bytes(shares: usize, height: usize, q: usize, uneven: usize) -> usize {
    checked_file_bytes(shares as u64, height as u64, q as u64, uneven as u64).unwrap_or(0)
}

/// The unturned weights of a `width` x `height` map at face size `n` from `bytes`, checked as the
/// module notes say; `what` names the file in errors.
#[cfg(test)]
pub fn decode(
    bytes: &[u8],
    width: usize,
    height: usize,
    n: usize,
    what: &Path,
) -> Result<LatLongWeights> {
    read(
        &mut std::io::Cursor::new(bytes),
        bytes.len() as u64,
        [width, height, n],
        what,
    )
}

/// [`decode`] from a reader of `len` bytes, each array read straight into its own vector.
fn read(
    input: &mut impl Read,
    len: u64,
    [width, height, n]: [usize; 3],
    what: &Path,
) -> Result<LatLongWeights> {
    let bad = |why: String| PrtError::file(what, why);
    let io = |e: std::io::Error| PrtError::io(what, e);
    let mut header = [0u8; HEADER_BYTES];
    if len < HEADER_BYTES as u64 {
        return Err(bad(format!("{len} bytes: not a weights file")));
    }
    input.read_exact(&mut header).map_err(io)?;
    if &header[..4] != MAGIC {
        return Err(bad("not a weights file (no PRTW header)".into()));
    }
    let version = u32::from_le_bytes(header[4..8].try_into().expect("4 bytes"));
    if version != VERSION {
        return Err(bad(format!(
            "version {version}; this build reads {VERSION}"
        )));
    }
    let field =
        |i: usize| u64::from_le_bytes(header[8 + 8 * i..16 + 8 * i].try_into().expect("8 bytes"));
    let [w, h, nn, q, shares, uneven, resolves] = std::array::from_fn(field);
    if (w, h, nn) != (width as u64, height as u64, n as u64) {
        return Err(bad(format!(
            "header: a {w} x {h} map at N = {nn}, asked for {width} x {height} at N = {n}"
        )));
    }
    if !(q.is_power_of_two() && q as usize <= MAX_SUBCOLUMNS) || resolves > 1 {
        return Err(bad(format!(
            "header: {q} sub-columns, resolves_cuts {resolves}"
        )));
    }
    // Every cell has at least one share.
    let cells = (width * height) as u64;
    if shares < cells || shares > u32::MAX as u64 || uneven > shares || (q == 1 && uneven > 0) {
        return Err(bad(format!(
            "header: {shares} shares ({uneven} uneven, {q} sub-columns) for {cells} cells"
        )));
    }
    let want = checked_file_bytes(shares, h, q, uneven);
    if want.map(|b| b as u64) != Some(len) {
        return Err(bad(format!("{len} bytes; the header implies {want:?}")));
    }
    let (s, b_count, q) = (shares as usize, uneven as usize, q as usize);
    // Read in place as little-endian words: a no-op on little-endian machines.
    let mut word = vec![0u32; s];
    input
        .read_exact(bytemuck::cast_slice_mut(&mut word))
        .map_err(io)?;
    word.iter_mut().for_each(|v| *v = u32::from_le(*v));
    let mut bits = vec![0u32; s];
    input
        .read_exact(bytemuck::cast_slice_mut(&mut bits))
        .map_err(io)?;
    let weight: Vec<f32> = bits
        .iter()
        .map(|&v| f32::from_bits(u32::from_le(v)))
        .collect();
    let mut index = || -> Result<Vec<usize>> {
        let mut v = vec![0u64; height + 1];
        input
            .read_exact(bytemuck::cast_slice_mut(&mut v))
            .map_err(io)?;
        Ok(v.into_iter().map(|x| u64::from_le(x) as usize).collect())
    };
    let row_start = index()?;
    let row_uneven = index()?;
    let mut tail = vec![0u16; (q - 1) * b_count];
    input
        .read_exact(bytemuck::cast_slice_mut(&mut tail))
        .map_err(io)?;
    tail.iter_mut().for_each(|v| *v = u16::from_le(*v));
    let count = texel_count(n);
    if row_start[0] != 0
        || row_start[height] != s
        || row_uneven[0] != 0
        || row_uneven[height] != b_count
    {
        return Err(bad(
            "row tables: they must start at 0 and end at the share counts".into(),
        ));
    }
    if let Some(y) =
        (0..height).find(|&y| row_start[y + 1] < row_start[y] || row_uneven[y + 1] < row_uneven[y])
    {
        return Err(bad(format!("row {y}: its tables run backwards")));
    }
    // Each row, checked in parallel: texels in range, weights finite and not negative, `width`
    // cells each closed by its last share, the uneven shares as counted.
    (0..height).into_par_iter().try_for_each(|y| {
        let (s0, s1) = (row_start[y], row_start[y + 1]);
        let (mut closed, mut flagged) = (0, 0);
        for (k, (&v, &wt)) in word[s0..s1].iter().zip(&weight[s0..s1]).enumerate() {
            if (v & TEXEL_BITS) as usize >= count {
                return Err(bad(format!(
                    "share {}: texel {} of {count}",
                    s0 + k,
                    v & TEXEL_BITS
                )));
            }
            if !(wt.is_finite() && wt >= 0.0) {
                return Err(bad(format!("share {}: weight {wt}", s0 + k)));
            }
            closed += (v & LAST != 0) as usize;
            flagged += (v & UNEVEN != 0) as usize;
        }
        let uneven = row_uneven[y + 1] - row_uneven[y];
        if closed != width || word[s1 - 1] & LAST == 0 || flagged != uneven {
            return Err(bad(format!(
                "row {y}: {closed} cells closed of {width}, {flagged} uneven shares of {uneven}"
            )));
        }
        Ok(())
    })?;
    if let Some(&t) = tail.iter().find(|&&t| t as f64 > TAIL_SCALE) {
        return Err(bad(format!("a table holds {t}, past {TAIL_SCALE}")));
    }
    Ok(LatLongWeights::from_parts(
        [width, height, n],
        0.0,
        word,
        weight,
        [row_start, row_uneven],
        (q, resolves == 1),
        tail,
    ))
}

/// Largest weights file read: far above the 8192 x 4096 map's (see [`super::MAX_RECORDED_PIXELS`]).
const MAX_FILE_BYTES: u64 = 4 << 30;

/// The unturned weights of a `width` x `height` map at face size `n` from the folder, if a file
/// that passes every check is there.
pub fn load(dir: &Path, width: usize, height: usize, n: usize) -> Option<LatLongWeights> {
    let path = path(dir, width, height, n);
    let (file, len) = crate::files::open_regular(&path, MAX_FILE_BYTES, "weights file").ok()?;
    let mut input = std::io::BufReader::with_capacity(1 << 16, file);
    read(&mut input, len, [width, height, n], &path).ok()
}

/// Writes `w` (unturned) into the folder, made if missing, atomically.
pub fn store(dir: &Path, w: &LatLongWeights) -> Result<()> {
    crate::files::create_folder(dir)?;
    crate::files::write_bytes_atomically(&path(dir, w.width, w.height, w.n), &encode(w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::temp_dir;

    /// Small enough to record in a moment, with uneven shares (cells cut by texel borders).
    const W: usize = 64;
    const H: usize = 32;
    const N: usize = 8;

    fn weights() -> LatLongWeights {
        LatLongWeights::build(W, H, N, 0.0).unwrap()
    }

    #[test]
    fn a_file_reads_back_bit_equal_and_gathers_the_same_cube() {
        let w = weights();
        assert!(
            w.row_uneven[H] > 0 && w.subcolumns > 1,
            "uneven shares to carry"
        );
        let back = decode(&encode(&w), W, H, N, Path::new("w.prtw")).unwrap();
        assert_eq!(back.word, w.word);
        assert_eq!(
            back.weight.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            w.weight.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(
            (&back.row_start, &back.row_uneven, &back.tail),
            (&w.row_start, &w.row_uneven, &w.tail)
        );
        assert_eq!(back.received, w.received);
        assert_eq!(
            (back.subcolumns, back.resolves_cuts),
            (w.subcolumns, w.resolves_cuts)
        );
        let map: Vec<[f32; 3]> = (0..W * H)
            .map(|i| [1.0 + (i % 7) as f32, 0.5, (i % 3) as f32])
            .collect();
        for yaw in [0.0, 12.345] {
            assert_eq!(
                back.cube(&map, yaw).unwrap().texels,
                w.cube(&map, yaw).unwrap().texels
            );
        }
    }

    #[test]
    fn a_folder_keeps_the_weights_and_a_damaged_file_is_passed_over() {
        let dir = temp_dir("weights-disk");
        let w = weights();
        store(&dir, &w).unwrap();
        let back = load(&dir, W, H, N).expect("stored");
        assert_eq!(back.word, w.word);
        assert!(
            load(&dir, W, H, 2 * N).is_none(),
            "another N is another file"
        );
        let file = path(&dir, W, H, N);
        let mut bytes = std::fs::read(&file).unwrap();
        bytes.truncate(bytes.len() - 1);
        std::fs::write(&file, &bytes).unwrap();
        assert!(load(&dir, W, H, N).is_none());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Every damage the gather could trip on is refused with the file named, and no byte
    /// changed anywhere makes the reader panic.
    #[test]
    fn damaged_files_are_refused_not_read() {
        let w = weights();
        let good = encode(&w);
        let name = Path::new("cache/w.prtw");
        let refused = |bytes: &[u8], what: &str| {
            let e = decode(bytes, W, H, N, name)
                .err()
                .unwrap_or_else(|| panic!("{what}: read"));
            assert!(e.to_string().contains("w.prtw"), "{what}: {e}");
        };
        let words = HEADER_BYTES;
        let shares = w.word.len();
        let set_u32 = |at: usize, v: u32| {
            let mut b = good.clone();
            b[at..at + 4].copy_from_slice(&v.to_le_bytes());
            b
        };
        refused(&good[..good.len() - 2], "truncated");
        refused(&set_u32(4, VERSION + 1), "another version");
        refused(&set_u32(8, W as u32 + 1), "another width");
        // A texel past the cube, a cell left open, an uneven flag not counted.
        refused(
            &set_u32(words, (texel_count(N) as u32) | (w.word[0] & !TEXEL_BITS)),
            "texel",
        );
        let last = w.word.iter().position(|v| v & LAST != 0).unwrap();
        refused(
            &set_u32(words + 4 * last, w.word[last] & !LAST),
            "open cell",
        );
        let even = w.word.iter().position(|v| v & UNEVEN == 0).unwrap();
        refused(&set_u32(words + 4 * even, w.word[even] | UNEVEN), "uneven");
        refused(
            &set_u32(words + 4 * shares, f32::NAN.to_bits()),
            "NaN weight",
        );
        let uneven_table = words + 8 * shares + 8 * (H + 1) + 8 * (H / 2);
        refused(&set_u32(uneven_table, u32::MAX), "row table");
        let mut rng = crate::test_support::Rng::new(3);
        for _ in 0..300 {
            let mut b = good.clone();
            let at = (rng.next_u64() % b.len() as u64) as usize;
            b[at] ^= 1 << (rng.next_u64() % 8);
            let _ = decode(&b, W, H, N, name);
        }
    }
}
