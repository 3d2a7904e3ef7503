//! Reading the transport file (format version 9, laid out in the [module docs](super); versions
//! 3 to 6, which stored columns, into strips; version 7, whose slots are whole only when full, as
//! stored): reading and validating all of it, and reading only its header and small tables for
//! `prt info`. Every size and index is checked before anything is sliced or allocated.

use std::io::Read;
use std::path::Path;

use safetensors::tensor::Dtype;
use serde::{Deserialize, Serialize};

use super::groups::{
    FileTensors, MatrixTensors, PixelTensors, RowTensors, ShTensor, read_all, taken, tensor_names,
};
use super::reader::TensorReader;
use super::strips::Layout;
use super::*;
use crate::error::{PrtError, Result};
use crate::store::container::{self, check_meta_seal};

impl Transport {
    /// Reads and fully validates a transport file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with_progress(path, &|_, _| {})
    }

    /// [`Transport::load`], calling `progress(bytes read, file size)` as the file comes in (the
    /// viewer shows it; validation after the read is quick).
    pub fn load_with_progress(path: &Path, progress: &dyn Fn(u64, u64)) -> Result<Self> {
        let Header {
            meta,
            version,
            checksum: stored,
            tensors,
            data_start,
            file,
        } = read_header(path)?;
        // One pass over the tensors in name order (the order the checksum covers them), each
        // read straight into its table: memory holds the transport once and no copy of the file.
        // Shapes are checked once the checksum has passed.
        let mut reader = TensorReader::new(path, &tensors, data_start, file, progress)?;
        let (w, h) = (meta.width as usize, meta.height as usize);
        let (tx, ty) = tile_grid(w, h);
        let tiles = tx * ty;
        let c = 6 * (meta.identity.cube_n as usize).pow(2);
        let FileTensors {
            pixels,
            rows,
            sh,
            matrix,
            attached,
        } = read_all(&mut reader, &meta, version)?;
        check_checksum(path, &stored, reader.checksum())?;
        let expect = |name: &str, shape: &[usize], want: &[usize]| -> Result<()> {
            if shape != want {
                return Err(PrtError::file(
                    path,
                    format!("tensor `{name}` has shape {shape:?}, expected {want:?}"),
                ));
            }
            Ok(())
        };
        let bad = |m: String| PrtError::file(path, m);
        let (start_shape, tile_row_start) = taken(rows.tile_start, RowTensors::TILE_START)?;
        expect(RowTensors::TILE_START, &start_shape, &[tiles + 1])?;
        let (pixel_shape, row_pixel) = taken(rows.pixel, RowTensors::PIXEL)?;
        let r = pixel_shape.first().copied().unwrap_or(0);
        expect(RowTensors::PIXEL, &pixel_shape, &[r])?;
        // The block tables follow from the tiles' row counts, checked before anything is sized
        // by them.
        let (tile_block_start, block_row_start) = block_tables(&tile_row_start, r).map_err(bad)?;
        let (weight_shape, row_weight) = taken(rows.weight, RowTensors::WEIGHT)?;
        expect(RowTensors::WEIGHT, &weight_shape, &[r, 3])?;
        let (row_scale_shape, row_scale) = taken(rows.scale, RowTensors::SCALE)?;
        expect(RowTensors::SCALE, &row_scale_shape, &[r])?;
        let layout = Layout::of(&tile_block_start, tx);
        let strips = matrix.into_strips(layout, (&block_row_start, c), &expect, &bad)?;
        let (sh_shape, sh) = taken(sh.sh, ShTensor::NAME)?;
        expect(
            ShTensor::NAME,
            &sh_shape,
            &[r, (meta.identity.sh_order as usize).pow(2)],
        )?;
        let (albedo_shape, albedo) = taken(pixels.albedo, PixelTensors::ALBEDO)?;
        expect(PixelTensors::ALBEDO, &albedo_shape, &[h, w, 3])?;
        let (coverage_shape, coverage) = taken(pixels.coverage, PixelTensors::COVERAGE)?;
        expect(PixelTensors::COVERAGE, &coverage_shape, &[h, w])?;
        let (magnitude_shape, transport_magnitude) =
            taken(pixels.magnitude, PixelTensors::MAGNITUDE)?;
        expect(PixelTensors::MAGNITUDE, &magnitude_shape, &[c])?;
        let (stats_shape, tile_stats) = taken(rows.tile_stats, RowTensors::TILE_STATS)?;
        expect(RowTensors::TILE_STATS, &stats_shape, &[tiles, 3])?;
        let attached = attached.into_attached(&meta, &expect, &bad)?;
        // A twin by design of the merge's literal (`assemble.rs`): the struct built whole,
        // where a load and a merge of shards each make one.
        let t = Transport {
            meta,
            tile_row_start,
            row_pixel,
            row_weight,
            row_scale,
            tile_block_start,
            block_row_start,
            strips,
            sh,
            albedo,
            coverage,
            transport_magnitude,
            tile_stats,
            attached,
        };
        t.validate().map_err(bad)?;
        Ok(t)
    }
}

/// Reads only the safetensors header and our metadata, checking that the declared tensors fill the
/// file exactly and that the format and version are ours; allocates nothing proportional to the
/// data.
pub fn read_header_meta(path: &Path) -> Result<TransportMeta> {
    read_header(path).map(|h| h.meta)
}

/// The format version of the transport file `path`, its header checked as [`read_header_meta`]
/// checks it.
pub fn read_format_version(path: &Path) -> Result<u32> {
    read_header(path).map(|h| h.version)
}

/// The header and the small tables, for `prt info`: the metadata, checked as
/// [`read_header_meta`] does, and the tile and strip-count tables (column counts before version
/// 7), checked against each other and against the strips (entries) the header declares. The
/// strips, nearly all of the file, are neither read nor checked (their checksum needs them all).
pub fn read_summary(path: &Path) -> Result<TransportMeta> {
    let Header {
        meta,
        version,
        tensors,
        data_start,
        file,
        ..
    } = read_header(path)?;
    let mut reader = TensorReader::new(path, &tensors, data_start, file, &|_, _| {})?;
    let legacy = version < 7;
    // Read in name order: `col_count` (versions 3 to 6) before `strip_count` before
    // `tile_row_start`.
    let col_counts: Option<(_, Vec<u16>)> = if legacy {
        Some(reader.read(MatrixTensors::COL_COUNT, Dtype::U16)?)
    } else {
        None
    };
    let strip_counts: Option<(_, Vec<u8>)> = if legacy {
        None
    } else {
        Some(reader.read(MatrixTensors::STRIP_COUNT, Dtype::U8)?)
    };
    let (_, starts): (_, Vec<u32>) = reader.read(RowTensors::TILE_START, Dtype::U32)?;
    // The large tensors are only counted; their bytes need the whole file's checksum.
    let count = |name: &str, bytes_each: u64| -> Result<usize> {
        let (_, shape, start, end) = reader.locate(name)?;
        let elements = shape.iter().try_fold(1u64, |n, &d| n.checked_mul(d as u64));
        match shape[..] {
            [n, ..] if elements.and_then(|e| e.checked_mul(bytes_each)) == Some(end - start) => {
                Ok(n)
            }
            _ => Err(PrtError::file(
                path,
                format!("tensor `{name}` of shape {shape:?} does not fill its bytes"),
            )),
        }
    };
    let rows = count(RowTensors::PIXEL, 4)?;
    let (tx, ty) = tile_grid(meta.width as usize, meta.height as usize);
    if starts.len() != tx * ty + 1 {
        return Err(PrtError::file(
            path,
            "tile tables do not match the image size",
        ));
    }
    let (_, block_rows) = block_tables(&starts, rows).map_err(|m| PrtError::file(path, m))?;
    let c = 6 * meta.identity.cube_n as usize * meta.identity.cube_n as usize;
    let blocks = block_rows.len() - 1;
    match (col_counts, strip_counts) {
        (Some((_, counts)), _) => {
            let nnz = count(MatrixTensors::ENTRY_ROW, 1)?;
            if counts.len() != blocks * c {
                return Err(PrtError::file(
                    path,
                    "column counts do not match the blocks and coefficients",
                ));
            }
            column_pointers(&counts, &block_rows, c, nnz).map_err(|m| PrtError::file(path, m))?;
        }
        (_, Some((_, counts))) => {
            let strips = count(MatrixTensors::STRIP_PLACE, 1)?;
            let counted: u64 = counts.iter().map(|&n| n as u64).sum();
            if counts.len() != blocks * c {
                return Err(PrtError::file(
                    path,
                    "strip counts do not match the blocks and coefficients",
                ));
            }
            if counted != strips as u64 {
                return Err(PrtError::file(
                    path,
                    format!("strip counts add up to {counted} strips but the file stores {strips}"),
                ));
            }
        }
        _ => {}
    }
    Ok(meta)
}

/// What [`read_header`] gives: the checked metadata, the stored tensor checksum, the header's
/// tensor entries (name to dtype, shape and offsets), where the tensor data starts, and the open
/// file.
struct Header {
    meta: TransportMeta,
    version: u32,
    checksum: String,
    tensors: serde_json::Map<String, serde_json::Value>,
    data_start: u64,
    file: std::fs::File,
}

/// The error for a file that is no transport at all: what it is when its first bytes tell
/// ([`container::what_else`]), else `why`.
fn not_a_transport(path: &Path, why: String) -> PrtError {
    PrtError::file(
        path,
        container::what_else(path, container::TRANSPORT).unwrap_or(why),
    )
}

/// [`read_header_meta`], with what the rest of a reader needs (see [`Header`]).
fn read_header(path: &Path) -> Result<Header> {
    let (mut f, file_len) = crate::files::open_regular(path, u64::MAX, "transport")?;
    let mut len8 = [0u8; 8];
    f.read_exact(&mut len8)
        .map_err(|_| not_a_transport(path, "too short to be a transport file".into()))?;
    let header_len = u64::from_le_bytes(len8);
    if header_len > MAX_HEADER_BYTES || header_len + 8 > file_len {
        return Err(not_a_transport(
            path,
            format!("header length {header_len} does not fit a file of {file_len} bytes"),
        ));
    }
    let mut header = vec![0u8; header_len as usize];
    f.read_exact(&mut header)
        .map_err(|e| PrtError::file(path, format!("reading header: {e}")))?;
    let json: serde_json::Value = serde_json::from_slice(&header)
        .map_err(|e| not_a_transport(path, format!("header is not JSON: {e}")))?;
    let obj = json
        .as_object()
        .ok_or_else(|| PrtError::file(path, "header is not a JSON object"))?;
    let info = obj
        .get("__metadata__")
        .and_then(|m| m.as_object())
        .ok_or_else(|| PrtError::file(path, "no metadata: not a wavelet-prt transport file"))?;
    let text = info
        .get("meta")
        .and_then(|v| v.as_str())
        .ok_or_else(|| PrtError::file(path, "not a wavelet-prt transport file (no `meta`)"))?;
    container::check_metadata_entries(info.keys()).map_err(|m| PrtError::file(path, m))?;
    let value: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| PrtError::file(path, format!("metadata `meta` is not JSON: {e}")))?;
    let format = value.get("format").and_then(|v| v.as_str());
    if let Some(e) = container::other_format(path, format, container::TRANSPORT) {
        return Err(e);
    }
    if format != Some(FORMAT_NAME) {
        return Err(PrtError::file(
            path,
            "not a wavelet-prt transport file (metadata `format`)",
        ));
    }
    let version = value.get("format_version").and_then(|v| v.as_u64());
    match version {
        Some(v) if (OLDEST_VERSION as u64..=FORMAT_VERSION as u64).contains(&v) => {}
        Some(v) if v < OLDEST_VERSION as u64 => {
            return Err(PrtError::file(
                path,
                format!(
                    "format_version {v} was written by an older build (16-bit float values); \
                     this build reads versions {OLDEST_VERSION} to {FORMAT_VERSION}: bake the scene again with \
                     `prt bake`"
                ),
            ));
        }
        _ => {
            return Err(PrtError::file(
                path,
                format!(
                    "format_version {}; this build reads versions {OLDEST_VERSION} to \
                     {FORMAT_VERSION}",
                    version.map(|v| v.to_string()).unwrap_or("?".into())
                ),
            ));
        }
    }
    check_meta_seal(text).map_err(|m| PrtError::file(path, m))?;
    let header: FileHeader = serde_json::from_value(value)
        .map_err(|e| PrtError::file(path, format!("metadata `meta`: {e}")))?;
    container::check_known_keys(text, &header).map_err(|m| PrtError::file(path, m))?;
    let known = tensor_names(header.format_version, &header.meta);
    if let Some(name) = obj
        .keys()
        .find(|k| *k != "__metadata__" && !known.contains(&k.as_str()))
    {
        return Err(PrtError::file(
            path,
            format!(
                "unknown tensor `{}`: a transport file holds {}",
                crate::files::printable(name),
                known.join(", ")
            ),
        ));
    }
    let mut data_end = 0u64;
    for (name, t) in obj.iter().filter(|(k, _)| *k != "__metadata__") {
        let end = t
            .get("data_offsets")
            .and_then(|o| o.get(1))
            .and_then(|e| e.as_u64())
            .ok_or_else(|| PrtError::file(path, format!("tensor `{name}` has no data_offsets")))?;
        data_end = data_end.max(end);
    }
    if 8 + header_len + data_end != file_len {
        return Err(PrtError::file(
            path,
            format!(
                "tensors need {} bytes but the file has {file_len}: truncated or padded",
                8 + header_len + data_end
            ),
        ));
    }
    check_meta(&header.meta).map_err(|m| PrtError::file(path, m))?;
    Ok(Header {
        meta: header.meta,
        version: header.format_version,
        checksum: header.checksum,
        tensors: obj.clone(),
        data_start: 8 + header_len,
        file: f,
    })
}

/// The one metadata entry of a file: format, version, checksum and the [`TransportMeta`]
/// (`meta_checksum` follows them in the text, see [`container::seal_meta`]).
#[derive(Serialize, Deserialize)]
pub(super) struct FileHeader {
    pub format: String,
    pub format_version: u32,
    /// Of the tensors (see [`container::checksum`]).
    pub checksum: String,
    #[serde(flatten)]
    pub meta: TransportMeta,
}

fn check_meta(m: &TransportMeta) -> std::result::Result<(), String> {
    // A per-vertex bake's image is one tile wide and as tall as its vertices need.
    let tallest = match m.per_vertex {
        Some(_) => crate::scene::tessellate::MAX_VERTICES.div_ceil(TILE) as u32,
        None => 16384,
    };
    if m.width == 0 || m.height == 0 || m.width > 16384 || m.height > tallest {
        return Err(format!(
            "image size {} x {} out of range",
            m.width, m.height
        ));
    }
    if m.tile as usize != TILE {
        return Err(format!("tile size {}; this build uses {TILE}", m.tile));
    }
    crate::math::cubemap::validate_n(m.identity.cube_n as usize).map_err(|e| e.to_string())?;
    if m.identity.sh_order == 0 || m.identity.sh_order as usize > crate::math::sh::MAX_ORDER {
        return Err(format!("SH order {} out of range", m.identity.sh_order));
    }
    if let Some([i, n]) = m.identity.shard {
        // A bake cuts at most one shard per band of tile rows.
        let (_, bands) = tile_grid(m.width as usize, m.height as usize);
        if n == 0 || i >= n || n as usize > bands {
            return Err(format!(
                "shard {i}/{n}: a shard is I/COUNT with I < COUNT <= {bands} (the image's \
                 bands of tile rows)"
            ));
        }
    }
    if !(m.identity.threshold.is_finite() && m.identity.threshold >= 0.0) {
        return Err(format!(
            "threshold {} must be finite and >= 0",
            m.identity.threshold
        ));
    }
    let columns = m.light_columns();
    if columns > crate::scene::light::MAX_LIGHT_COLUMNS {
        return Err(format!(
            "{columns} light columns; a transport holds at most {}",
            crate::scene::light::MAX_LIGHT_COLUMNS
        ));
    }
    if let Some(i) =
        (0..m.lights.len()).find(|&i| m.lights[..i].iter().any(|o| o.name == m.lights[i].name))
    {
        return Err(format!("two lights are called `{}`", m.lights[i].name));
    }
    let c = &m.camera;
    if !c
        .eye
        .iter()
        .chain(&c.target)
        .chain(&c.up)
        .all(|v| v.is_finite())
        || !c.fov_y_deg.is_finite()
    {
        return Err("camera: every number must be finite".into());
    }
    Ok(())
}

/// An error unless the checksum computed over the tensors, `computed`, is the one stored.
fn check_checksum(path: &Path, stored: &str, computed: u64) -> Result<()> {
    let sum = format!("{computed:016x}");
    if sum != stored {
        return Err(PrtError::file(
            path,
            format!("checksum mismatch (stored {stored}, computed {sum}): the file is corrupted"),
        ));
    }
    Ok(())
}
