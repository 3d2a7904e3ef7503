//! The transport store: the baked sparse Haar transport, the dense SH transport and per-pixel data
//! of one fixed view, in memory and in a documented safetensors file.
//!
//! # Rows, tiles, blocks and columns
//! The image is cut into [`TILE`] x [`TILE`] pixel tiles, row-major over the tile grid. A *row* is
//! one transport vector over the 6 N² Haar coefficients together with the pixel it lights and an RGB
//! weight: a pixel's radiance is `Σ_rows weight ⊙ (row · L)`. A diffuse pixel that sees one material
//! has one row whose weight is the albedo; a pixel whose sub-samples see several materials has one
//! row per material, so the split stays exact. Rows are grouped by tile.
//!
//! A tile's rows are cut into *blocks* of at most [`BLOCK_ROWS`] (256) consecutive rows, so a row
//! index inside a block is one byte; a tile of one row per pixel is one block. Inside a block the
//! rows' nonzero coefficients are stored column by column (coefficient-major): the entries of
//! coefficient j, each a row index and an integer, rows strictly increasing, with the value
//! `integer · scale(code[block, j]) · row_scale[row]` (see [`crate::store::quant`]). The row scale (the
//! row's largest magnitude) puts rows of very different brightness, such as a glossy lobe beside a
//! diffuse row, on one footing before a block's columns share a scale; the kernels apply it once per
//! row, with the weight. So one worker owns a tile's rows
//! with no atomics, a column touches each row at most once, and relighting with K terms reads only
//! K columns of each block.
//!
//! # File (format version 3)
//! A safetensors file (readable from Python with `safetensors.numpy.load_file`); its one metadata
//! entry `meta` is JSON: `format = "wavelet-prt transport"`, `format_version`, `checksum` and the
//! fields of [`TransportMeta`]. Tensors (T tiles, R rows, B blocks, C = 6 N² coefficients):
//!
//! | tensor | dtype, shape | what |
//! |---|---|---|
//! | `tile_row_start` | u32 [T+1] | tile t holds rows `tile_row_start[t] .. tile_row_start[t+1]`; its blocks are those rows in runs of 256 |
//! | `row_pixel`, `row_weight` | u32 [R], f32 [R, 3] | the pixel (y · width + x) and RGB weight of each row |
//! | `row_scale` | f32 [R] | each row's stored values are relative to this (its largest magnitude) |
//! | `col_count` | u16 [B, C] | entries of coefficient j in block b; blocks in tile order, entries in (block, j) order |
//! | `col_scale` | u8 [B, C] | the scale code of (b, j): `scale = 2^((code − 192) / 4)` |
//! | `entry_row` | u8 [nnz] | the row inside its block |
//! | `entry_value` | i8, i16 or f32 [nnz] | the integer (`quantization` q8, q16) or the value (f32, scale 1) |
//! | `sh` | f32 [R, n²] | SH transport of each row |
//! | `albedo`, `coverage` | f32 [H, W, 3], f32 [H, W] | per pixel: albedo seen, fraction of sub-samples that hit |
//! | `transport_magnitude` | f32 [C] | mean magnitude of each coefficient over the rows (transport weighting) |
//! | `tile_stats` | f64 [T, 3] | per tile: energy dropped by thresholding and quantisation, total energy, shadow rays |
//!
//! The `checksum` covers the tensors' bytes in name order and `meta_checksum` the metadata's
//! fields (the JSON of `meta` without `meta_checksum`, as this build writes it), so a flipped bit
//! anywhere is caught; files written before `meta_checksum` existed have none and are read as
//! before. A checksum guards against accidents, not edits: loading checks the header, the sizes
//! and every count, index and value (NaN or infinite floats included) before it allocates
//! anything or trusts any offset, and allocates no more than the file's own tensors hold. Writing
//! goes to a temporary file that is renamed into place ([`crate::files`]).

use std::io::{Read, Seek};
use std::ops::Range;
use std::path::Path;

use safetensors::tensor::Dtype;
use serde::{Deserialize, Serialize};

use crate::error::{PrtError, Result};
use crate::store::container::{self, Tensor, check_meta_seal, checksum};
pub use crate::store::quant::{BLOCK_ROWS, Quantization};
use crate::store::quant::{UNIT_SCALE_CODE, code_for, quantize, scale_of};

/// Pixels on a side of a tile.
pub const TILE: usize = 16;
/// Name written in every transport file.
pub const FORMAT_NAME: &str = container::TRANSPORT.name;
/// Version of the layout described in this module.
pub const FORMAT_VERSION: u32 = 3;
/// Largest safetensors header accepted (JSON text), checked before it is read.
const MAX_HEADER_BYTES: u64 = 1 << 24;

/// Camera of the baked view, as written in the file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraMeta {
    pub eye: [f32; 3],
    pub target: [f32; 3],
    pub up: [f32; 3],
    pub fov_y_deg: f32,
}

/// Figures of a bake.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BakeStats {
    /// Transport rows.
    pub rows: u64,
    /// Stored nonzero Haar coefficients.
    pub nonzeros: u64,
    /// rows x 6 N², what a dense matrix would hold.
    pub dense_entries: u64,
    /// Sum over rows of the squared norm of what thresholding and quantisation changed, over the
    /// sum of squared norms: the relative L2 (squared) the storage removed from the transport.
    pub dropped_energy_fraction: f64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
}

/// Everything about a transport file but its arrays.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransportMeta {
    pub width: u32,
    pub height: u32,
    pub tile: u32,
    pub cube_n: u32,
    pub sh_order: u32,
    /// FNV-1a hash of the scene text and its meshes, hex.
    pub scene_hash: String,
    /// The scene file as given to the bake.
    pub scene_path: String,
    pub camera: CameraMeta,
    pub spp: u32,
    pub texel_samples: u32,
    pub unshadowed: bool,
    pub seed: u64,
    /// Thresholding parameter (0 = keep every nonzero); its meaning is `budget`'s.
    pub threshold: f32,
    /// How the thresholding budget weighs coefficients.
    #[serde(default)]
    pub budget: crate::store::budget::Budget,
    pub quantization: Quantization,
    /// `[index, count]` for one shard of a sharded bake (it holds only its band of tile rows);
    /// absent for a whole bake or a merge of all shards.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<[u32; 2]>,
    /// Interreflection bounces baked in (0: direct light only).
    #[serde(default)]
    pub bounces: u32,
    /// Paths per camera sub-sample for the interreflections (0 without them).
    #[serde(default)]
    pub paths: u32,
    /// Derived from the tables (see [`Transport::finish`]): the same for a bake and a merge.
    pub stats: BakeStats,
}

/// Stored coefficient values: integers against their column's scale, or lossless floats.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    Q8(Vec<i8>),
    Q16(Vec<i16>),
    F32(Vec<f32>),
}

impl Values {
    /// Empty values of a quantisation.
    pub fn empty(q: Quantization) -> Self {
        match q {
            Quantization::Q8 => Values::Q8(Vec::new()),
            Quantization::Q16 => Values::Q16(Vec::new()),
            Quantization::F32 => Values::F32(Vec::new()),
        }
    }
    /// The quantisation these values are in.
    pub fn quantization(&self) -> Quantization {
        match self {
            Values::Q8(_) => Quantization::Q8,
            Values::Q16(_) => Quantization::Q16,
            Values::F32(_) => Quantization::F32,
        }
    }
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Values::Q8(v) => v.len(),
            Values::Q16(v) => v.len(),
            Values::F32(v) => v.len(),
        }
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Bytes per value.
    pub fn value_bytes(&self) -> usize {
        self.quantization().value_bytes()
    }
    /// Stored value `i` (the integer, or the float) as f32, before its column's scale.
    #[inline]
    pub fn raw(&self, i: usize) -> f32 {
        match self {
            Values::Q8(v) => v[i] as f32,
            Values::Q16(v) => v[i] as f32,
            Values::F32(v) => v[i],
        }
    }
    /// Appends the stored values `range` of `other` (same quantisation).
    fn extend_from(&mut self, other: &Values, range: Range<usize>) {
        match (self, other) {
            (Values::Q8(a), Values::Q8(b)) => a.extend_from_slice(&b[range]),
            (Values::Q16(a), Values::Q16(b)) => a.extend_from_slice(&b[range]),
            (Values::F32(a), Values::F32(b)) => a.extend_from_slice(&b[range]),
            _ => debug_assert!(false, "mixed quantisations"),
        }
    }
    /// Appends one quantised value.
    fn push(&mut self, q: f32) {
        match self {
            Values::Q8(a) => a.push(q as i8),
            Values::Q16(a) => a.push(q as i16),
            Values::F32(a) => a.push(q),
        }
    }
}

/// A baked view in memory, in the layout of this module. The block tables (`tile_block_start`,
/// `block_row_start`, `block_entry_start`, `col_ptr`) are derived from `tile_row_start` and the
/// file's `col_count`.
#[derive(Clone, Debug, PartialEq)]
pub struct Transport {
    pub meta: TransportMeta,
    pub tile_row_start: Vec<u32>,
    pub row_pixel: Vec<u32>,
    pub row_weight: Vec<[f32; 3]>,
    /// Each row's values are stored relative to this.
    pub row_scale: Vec<f32>,
    /// Tile t holds blocks `tile_block_start[t] .. tile_block_start[t + 1]`.
    pub tile_block_start: Vec<u32>,
    /// Block b holds rows `block_row_start[b] .. block_row_start[b + 1]` (global row indices).
    pub block_row_start: Vec<u32>,
    /// Block b holds entries `block_entry_start[b] .. block_entry_start[b + 1]`.
    pub block_entry_start: Vec<u64>,
    /// `col_ptr[b (C + 1) + j] .. col_ptr[b (C + 1) + j + 1]`: block b's entries of coefficient j,
    /// relative to the block's first entry.
    pub col_ptr: Vec<u32>,
    /// Scale code of every (block, coefficient).
    pub col_scale: Vec<u8>,
    /// Row of each entry inside its block.
    pub entry_row: Vec<u8>,
    pub values: Values,
    pub sh: Vec<f32>,
    pub albedo: Vec<[f32; 3]>,
    pub coverage: Vec<f32>,
    pub transport_magnitude: Vec<f32>,
    /// Per tile: energy thresholding and quantisation dropped, the rows' total energy, shadow
    /// rays traced.
    pub tile_stats: Vec<[f64; 3]>,
}

/// Tiles along x and y for an image.
pub fn tile_grid(width: usize, height: usize) -> (usize, usize) {
    (width.div_ceil(TILE), height.div_ceil(TILE))
}

/// Blocks a tile of `rows` rows is cut into.
pub fn blocks_of(rows: usize) -> usize {
    rows.div_ceil(BLOCK_ROWS)
}

impl Transport {
    /// Haar coefficients per row, 6 N².
    pub fn coeff_count(&self) -> usize {
        6 * (self.meta.cube_n as usize).pow(2)
    }
    /// Number of pixel tiles.
    pub fn tile_count(&self) -> usize {
        self.tile_row_start.len() - 1
    }
    /// Number of row blocks.
    pub fn block_count(&self) -> usize {
        self.block_row_start.len() - 1
    }
    /// Pixels in the image.
    pub fn pixel_count(&self) -> usize {
        self.meta.width as usize * self.meta.height as usize
    }
    /// SH coefficients per row.
    pub fn sh_count(&self) -> usize {
        (self.meta.sh_order as usize).pow(2)
    }
    /// The blocks of tile `t`.
    #[inline]
    pub fn blocks(&self, t: usize) -> Range<usize> {
        self.tile_block_start[t] as usize..self.tile_block_start[t + 1] as usize
    }
    /// Entry range of coefficient `j` in block `b`, as absolute entry indices.
    #[inline]
    pub fn block_column(&self, b: usize, j: usize) -> Range<usize> {
        let c = self.coeff_count() + 1;
        let base = self.block_entry_start[b] as usize;
        base + self.col_ptr[b * c + j] as usize..base + self.col_ptr[b * c + j + 1] as usize
    }
    /// The scale of coefficient `j` in block `b`.
    #[inline]
    pub fn scale(&self, b: usize, j: usize) -> f32 {
        scale_of(self.col_scale[b * self.coeff_count() + j])
    }
    /// Stored value of entry `e` of block `b`, coefficient `j`, decoded.
    #[inline]
    pub fn value(&self, b: usize, j: usize, e: usize) -> f32 {
        let row = self.block_row_start[b] as usize + self.entry_row[e] as usize;
        self.values.raw(e) * self.scale(b, j) * self.row_scale[row]
    }
    /// Bytes of the sparse Haar matrix as stored in the file: entries (row and value), column
    /// counts and scale codes.
    pub fn haar_bytes(&self) -> usize {
        self.entry_row.len() * (1 + self.values.value_bytes())
            + self.block_count() * self.coeff_count() * 3
    }
    /// The per-column entry counts of `blocks`, as the file stores them, derived from the column
    /// pointers.
    fn col_counts(&self, blocks: Range<usize>) -> Vec<u16> {
        let c = self.coeff_count();
        let mut counts = Vec::with_capacity(blocks.len() * c);
        for b in blocks {
            let ptr = &self.col_ptr[b * (c + 1)..(b + 1) * (c + 1)];
            counts.extend(ptr.windows(2).map(|w| (w[1] - w[0]) as u16));
        }
        counts
    }

    /// Writes the file atomically: a temporary file beside `path`, then a rename.
    pub fn save(&self, path: &Path) -> Result<()> {
        let (w, h) = (self.meta.width as usize, self.meta.height as usize);
        let tiles = self.tile_count();
        let c = self.coeff_count();
        let r = self.row_pixel.len();
        let b = self.block_count();
        let nnz = self.entry_row.len();
        let counts = self.col_counts(0..self.block_count());
        let mut tensors: Vec<(&str, Tensor)> = vec![
            (
                "tile_row_start",
                Tensor::new(Dtype::U32, vec![tiles + 1], &self.tile_row_start),
            ),
            (
                "row_pixel",
                Tensor::new(Dtype::U32, vec![r], &self.row_pixel),
            ),
            (
                "row_weight",
                Tensor::new(Dtype::F32, vec![r, 3], &self.row_weight),
            ),
            (
                "row_scale",
                Tensor::new(Dtype::F32, vec![r], &self.row_scale),
            ),
            ("col_count", Tensor::new(Dtype::U16, vec![b, c], &counts)),
            (
                "col_scale",
                Tensor::new(Dtype::U8, vec![b, c], &self.col_scale),
            ),
            (
                "entry_row",
                Tensor::new(Dtype::U8, vec![nnz], &self.entry_row),
            ),
            (
                "sh",
                Tensor::new(Dtype::F32, vec![r, self.sh_count()], &self.sh),
            ),
            (
                "albedo",
                Tensor::new(Dtype::F32, vec![h, w, 3], &self.albedo),
            ),
            (
                "coverage",
                Tensor::new(Dtype::F32, vec![h, w], &self.coverage),
            ),
            (
                "transport_magnitude",
                Tensor::new(Dtype::F32, vec![c], &self.transport_magnitude),
            ),
            (
                "tile_stats",
                Tensor::new(Dtype::F64, vec![tiles, 3], &self.tile_stats),
            ),
        ];
        tensors.push(match &self.values {
            Values::Q8(v) => ("entry_value", Tensor::new(Dtype::I8, vec![nnz], v)),
            Values::Q16(v) => ("entry_value", Tensor::new(Dtype::I16, vec![nnz], v)),
            Values::F32(v) => ("entry_value", Tensor::new(Dtype::F32, vec![nnz], v)),
        });
        tensors.sort_by_key(|(name, _)| *name);
        debug_assert!(tensors.iter().map(|(n, _)| *n).eq(TENSOR_NAMES));
        // One metadata key, so the header is the same bytes for the same content (the
        // container keeps its metadata in a hash map, whose order varies between runs).
        container::save(path, tensors, |checksum| {
            serde_json::to_string(&FileHeader {
                format: FORMAT_NAME.to_string(),
                format_version: FORMAT_VERSION,
                checksum,
                meta: self.meta.clone(),
            })
        })
    }

    /// Reads and fully validates a transport file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with_progress(path, &|_, _| {})
    }

    /// [`Transport::load`], calling `progress(bytes read, file size)` as the file comes in (the
    /// viewer shows it; validation after the read is quick).
    pub fn load_with_progress(path: &Path, progress: &dyn Fn(u64, u64)) -> Result<Self> {
        let Header {
            meta,
            checksum: stored,
            ..
        } = read_header(path)?;
        let buf = container::read_with_progress(path, u64::MAX, "transport", progress)?;
        let st = safetensors::SafeTensors::deserialize(&buf)
            .map_err(|e| PrtError::file(path, format!("not a valid safetensors file: {e}")))?;
        let mut parts = Vec::with_capacity(TENSOR_NAMES.len());
        for name in TENSOR_NAMES {
            let t = st
                .tensor(name)
                .map_err(|_| PrtError::file(path, format!("tensor `{name}` is missing")))?;
            parts.push(t.data());
        }
        let sum = format!("{:016x}", checksum(parts));
        if sum != stored {
            return Err(PrtError::file(
                path,
                format!(
                    "checksum mismatch (stored {stored}, computed {sum}): the file is corrupted"
                ),
            ));
        }
        let (w, h) = (meta.width as usize, meta.height as usize);
        let (tx, ty) = tile_grid(w, h);
        let tiles = tx * ty;
        let c = 6 * (meta.cube_n as usize).pow(2);
        let get = |name: &str, dtype: Dtype| -> Result<(Vec<usize>, &[u8])> {
            let t = st
                .tensor(name)
                .map_err(|_| PrtError::file(path, format!("tensor `{name}` is missing")))?;
            if t.dtype() != dtype {
                return Err(PrtError::file(
                    path,
                    format!(
                        "tensor `{name}` has dtype {:?}, expected {dtype:?}",
                        t.dtype()
                    ),
                ));
            }
            Ok((t.shape().to_vec(), t.data()))
        };
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
        let (s, d) = get("tile_row_start", Dtype::U32)?;
        expect("tile_row_start", &s, &[tiles + 1])?;
        let tile_row_start: Vec<u32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("row_pixel", Dtype::U32)?;
        let r = s.first().copied().unwrap_or(0);
        expect("row_pixel", &s, &[r])?;
        let row_pixel: Vec<u32> = bytemuck::pod_collect_to_vec(d);
        // The block tables follow from the tiles' row counts, checked before anything is sized
        // by them.
        let (tile_block_start, block_row_start) = block_tables(&tile_row_start, r).map_err(bad)?;
        let blocks = block_row_start.len() - 1;
        let (s, d) = get("row_weight", Dtype::F32)?;
        expect("row_weight", &s, &[r, 3])?;
        let row_weight: Vec<[f32; 3]> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("row_scale", Dtype::F32)?;
        expect("row_scale", &s, &[r])?;
        let row_scale: Vec<f32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("col_count", Dtype::U16)?;
        expect("col_count", &s, &[blocks, c])?;
        let counts: Vec<u16> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("col_scale", Dtype::U8)?;
        expect("col_scale", &s, &[blocks, c])?;
        let col_scale: Vec<u8> = d.to_vec();
        let (s, d) = get("entry_row", Dtype::U8)?;
        let nnz = s.first().copied().unwrap_or(0);
        expect("entry_row", &s, &[nnz])?;
        let entry_row: Vec<u8> = d.to_vec();
        let (col_ptr, block_entry_start) =
            column_pointers(&counts, &block_row_start, c, nnz).map_err(bad)?;
        let values = match meta.quantization {
            Quantization::Q8 => {
                let (s, d) = get("entry_value", Dtype::I8)?;
                expect("entry_value", &s, &[nnz])?;
                Values::Q8(bytemuck::pod_collect_to_vec(d))
            }
            Quantization::Q16 => {
                let (s, d) = get("entry_value", Dtype::I16)?;
                expect("entry_value", &s, &[nnz])?;
                Values::Q16(bytemuck::pod_collect_to_vec(d))
            }
            Quantization::F32 => {
                let (s, d) = get("entry_value", Dtype::F32)?;
                expect("entry_value", &s, &[nnz])?;
                Values::F32(bytemuck::pod_collect_to_vec(d))
            }
        };
        let shc = (meta.sh_order as usize).pow(2);
        let (s, d) = get("sh", Dtype::F32)?;
        expect("sh", &s, &[r, shc])?;
        let sh: Vec<f32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("albedo", Dtype::F32)?;
        expect("albedo", &s, &[h, w, 3])?;
        let albedo: Vec<[f32; 3]> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("coverage", Dtype::F32)?;
        expect("coverage", &s, &[h, w])?;
        let coverage: Vec<f32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("transport_magnitude", Dtype::F32)?;
        expect("transport_magnitude", &s, &[c])?;
        let transport_magnitude: Vec<f32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("tile_stats", Dtype::F64)?;
        expect("tile_stats", &s, &[tiles, 3])?;
        let tile_stats: Vec<[f64; 3]> = bytemuck::pod_collect_to_vec(d);
        let t = Transport {
            meta,
            tile_row_start,
            row_pixel,
            row_weight,
            row_scale,
            tile_block_start,
            block_row_start,
            block_entry_start,
            col_ptr,
            col_scale,
            entry_row,
            values,
            sh,
            albedo,
            coverage,
            transport_magnitude,
            tile_stats,
        };
        t.validate().map_err(bad)?;
        Ok(t)
    }

    /// Checks every index and offset, so kernels may index without further checks. Returns a
    /// message naming the first inconsistency.
    pub fn validate(&self) -> std::result::Result<(), String> {
        let m = &self.meta;
        let (w, h) = (m.width as usize, m.height as usize);
        let (tx, ty) = tile_grid(w, h);
        let tiles = tx * ty;
        let c = self.coeff_count();
        let r = self.row_pixel.len();
        if self.tile_row_start.len() != tiles + 1 || self.tile_block_start.len() != tiles + 1 {
            return Err("tile tables do not match the image size".into());
        }
        let (tile_blocks, block_rows) = block_tables(&self.tile_row_start, r)?;
        if tile_blocks != self.tile_block_start || block_rows != self.block_row_start {
            return Err("block tables do not follow from the tiles' rows".into());
        }
        let blocks = self.block_count();
        if self.col_ptr.len() != blocks * (c + 1)
            || self.col_scale.len() != blocks * c
            || self.block_entry_start.len() != blocks + 1
        {
            return Err("block tables have the wrong length".into());
        }
        if self.block_entry_start[0] != 0
            || self.block_entry_start[blocks] != self.entry_row.len() as u64
            || self.values.len() != self.entry_row.len()
        {
            return Err("block_entry_start does not span the entries".into());
        }
        if self.values.quantization() != m.quantization {
            return Err(format!(
                "values are {} but the header says {}",
                self.values.quantization(),
                m.quantization
            ));
        }
        if self.row_weight.len() != r
            || self.row_scale.len() != r
            || self.sh.len() != r * self.sh_count()
        {
            return Err("row tables have different lengths".into());
        }
        for t in 0..tiles {
            let (r0, r1) = (
                self.tile_row_start[t] as usize,
                self.tile_row_start[t + 1] as usize,
            );
            let (x0, y0) = ((t % tx) * TILE, (t / tx) * TILE);
            for &p in &self.row_pixel[r0..r1] {
                let (px, py) = (p as usize % w.max(1), p as usize / w.max(1));
                if p as usize >= w * h || px < x0 || px >= x0 + TILE || py < y0 || py >= y0 + TILE {
                    return Err(format!("tile {t}: row pixel {p} lies outside the tile"));
                }
            }
        }
        for b in 0..blocks {
            let rows = (self.block_row_start[b + 1] - self.block_row_start[b]) as usize;
            let (e0, e1) = (self.block_entry_start[b], self.block_entry_start[b + 1]);
            let ptr = &self.col_ptr[b * (c + 1)..(b + 1) * (c + 1)];
            if e1 < e0 || ptr[0] != 0 || ptr[c] as u64 != e1 - e0 {
                return Err(format!(
                    "block {b}: column pointers do not span its entries"
                ));
            }
            // Every pointer is checked against the next before either slices anything.
            if let Some(j) = (0..c).find(|&j| ptr[j + 1] < ptr[j]) {
                return Err(format!(
                    "block {b}: column pointers decrease at coefficient {j}"
                ));
            }
            for j in 0..c {
                let col = &self.entry_row
                    [(e0 as usize + ptr[j] as usize)..(e0 as usize + ptr[j + 1] as usize)];
                let mut last: i32 = -1;
                for &row in col {
                    if row as usize >= rows || row as i32 <= last {
                        return Err(format!(
                            "block {b}, coefficient {j}: row index {row} out of range or not increasing"
                        ));
                    }
                    last = row as i32;
                }
            }
        }
        if let Values::F32(v) = &self.values
            && !v.iter().all(|x| x.is_finite())
        {
            return Err("tensor `entry_value` holds NaN or infinite values".into());
        }
        if !self.sh.iter().all(|x| x.is_finite()) {
            return Err("tensor `sh` holds NaN or infinite values".into());
        }
        if !self.row_weight.iter().flatten().all(|x| x.is_finite()) {
            return Err("tensor `row_weight` holds NaN or infinite values".into());
        }
        if !self.row_scale.iter().all(|x| x.is_finite() && *x > 0.0) {
            return Err("tensor `row_scale`: every row scale must be finite and positive".into());
        }
        if self.albedo.len() != w * h
            || self.coverage.len() != w * h
            || self.transport_magnitude.len() != c
            || self.tile_stats.len() != tiles
        {
            return Err("per-pixel or per-coefficient tables have the wrong length".into());
        }
        for (name, finite) in [
            (
                "albedo",
                self.albedo.iter().flatten().all(|x| x.is_finite()),
            ),
            ("coverage", self.coverage.iter().all(|x| x.is_finite())),
            (
                "transport_magnitude",
                self.transport_magnitude.iter().all(|x| x.is_finite()),
            ),
            (
                "tile_stats",
                self.tile_stats.iter().flatten().all(|x| x.is_finite()),
            ),
        ] {
            if !finite {
                return Err(format!("tensor `{name}` holds NaN or infinite values"));
            }
        }
        Ok(())
    }
}

/// The blocks of every tile and the rows of every block, from the tiles' row starts; checks that
/// the starts begin at 0, never decrease and end at `rows`.
fn block_tables(
    tile_row_start: &[u32],
    rows: usize,
) -> std::result::Result<(Vec<u32>, Vec<u32>), String> {
    if tile_row_start.first() != Some(&0) || *tile_row_start.last().unwrap_or(&0) as usize != rows {
        return Err("tile_row_start does not span the rows".into());
    }
    if let Some(t) = tile_row_start.windows(2).position(|w| w[1] < w[0]) {
        return Err(format!("tile {t}: row offsets decrease"));
    }
    let mut tile_blocks = Vec::with_capacity(tile_row_start.len());
    let mut block_rows = vec![0u32];
    tile_blocks.push(0u32);
    for w in tile_row_start.windows(2) {
        let mut start = w[0];
        while start < w[1] {
            start = (start + BLOCK_ROWS as u32).min(w[1]);
            block_rows.push(start);
        }
        tile_blocks.push(block_rows.len() as u32 - 1);
    }
    Ok((tile_blocks, block_rows))
}

/// Column pointers and block entry starts from the file's per-(block, coefficient) counts;
/// checks each count against its block's rows and the total against the entries.
fn column_pointers(
    counts: &[u16],
    block_row_start: &[u32],
    c: usize,
    nnz: usize,
) -> std::result::Result<(Vec<u32>, Vec<u64>), String> {
    let blocks = block_row_start.len() - 1;
    let mut col_ptr = Vec::with_capacity(blocks * (c + 1));
    let mut starts = Vec::with_capacity(blocks + 1);
    starts.push(0u64);
    let mut total = 0u64;
    for b in 0..blocks {
        let rows = (block_row_start[b + 1] - block_row_start[b]) as u16;
        let mut p = 0u32;
        col_ptr.push(0);
        for (j, &n) in counts[b * c..(b + 1) * c].iter().enumerate() {
            if n > rows {
                return Err(format!(
                    "block {b}, coefficient {j}: {n} entries in a block of {rows} rows"
                ));
            }
            p += n as u32;
            col_ptr.push(p);
        }
        total += p as u64;
        starts.push(total);
    }
    if total != nnz as u64 {
        return Err(format!(
            "column counts add up to {total} entries but the file stores {nnz}"
        ));
    }
    Ok((col_ptr, starts))
}

/// One transport row before assembly: its pixel, RGB weight, sparse Haar entries (ascending by
/// coefficient) and SH transport.
#[derive(Clone, Debug, PartialEq)]
pub struct RowData {
    pub pixel: u32,
    pub weight: [f32; 3],
    pub entries: Vec<(u32, f32)>,
    pub sh: Vec<f32>,
}

/// One tile in the stored layout: its rows' pixels, weights and SH, and its blocks' counts,
/// scale codes and entries. Bakes encode tiles in parallel; a merge copies them from shards.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedTile {
    pub row_pixel: Vec<u32>,
    pub row_weight: Vec<[f32; 3]>,
    pub row_scale: Vec<f32>,
    pub sh: Vec<f32>,
    /// `[blocks, C]` entry counts.
    pub col_count: Vec<u16>,
    /// `[blocks, C]` scale codes.
    pub col_scale: Vec<u8>,
    pub entry_row: Vec<u8>,
    pub values: Values,
    /// Squared error quantisation added (dropped values included).
    pub quantization_energy: f64,
}

impl EncodedTile {
    /// Lays out a tile's rows (in the order they should keep) in blocks and columns, quantising
    /// each (block, coefficient) column against the smallest scale that holds its largest value.
    /// Values that round to zero are dropped.
    pub fn encode(rows: &[RowData], c: usize, shc: usize, q: Quantization) -> Result<Self> {
        let mut tile = EncodedTile {
            row_pixel: Vec::with_capacity(rows.len()),
            row_weight: Vec::with_capacity(rows.len()),
            row_scale: Vec::with_capacity(rows.len()),
            sh: Vec::with_capacity(rows.len() * shc),
            col_count: Vec::with_capacity(blocks_of(rows.len()) * c),
            col_scale: Vec::with_capacity(blocks_of(rows.len()) * c),
            entry_row: Vec::new(),
            values: Values::empty(q),
            quantization_energy: 0.0,
        };
        let q_max = q.q_max();
        let mut ptr = vec![0u32; c + 1];
        let mut col: Vec<(u8, f32)> = Vec::new();
        for block in rows.chunks(BLOCK_ROWS) {
            // Counting sort by coefficient; rows are visited in order, so every column's rows
            // come out strictly increasing.
            ptr.iter_mut().for_each(|p| *p = 0);
            // Lossless rows keep scale 1, so their values stay bit-exact.
            let row_scales: Vec<f32> = block
                .iter()
                .map(|row| {
                    let m = row.entries.iter().fold(0.0f32, |m, e| m.max(e.1.abs()));
                    if q == Quantization::F32 || !m.is_normal() {
                        1.0
                    } else {
                        m
                    }
                })
                .collect();
            for row in block {
                if row.sh.len() != shc {
                    return Err(PrtError::invalid(
                        "transport row",
                        format!("{} SH values, expected {shc}", row.sh.len()),
                    ));
                }
                for &(j, v) in &row.entries {
                    if j as usize >= c {
                        return Err(PrtError::invalid(
                            "transport row",
                            format!("coefficient {j} >= {c}"),
                        ));
                    }
                    if !v.is_finite() {
                        return Err(PrtError::invalid(
                            "transport row",
                            format!("non-finite value at coefficient {j}"),
                        ));
                    }
                    ptr[j as usize + 1] += 1;
                }
            }
            for j in 0..c {
                ptr[j + 1] += ptr[j];
            }
            col.clear();
            col.resize(ptr[c] as usize, (0, 0.0));
            let mut fill = ptr.clone();
            for (r, row) in block.iter().enumerate() {
                for &(j, v) in &row.entries {
                    col[fill[j as usize] as usize] = (r as u8, v / row_scales[r]);
                    fill[j as usize] += 1;
                }
            }
            for j in 0..c {
                let entries = &col[ptr[j] as usize..ptr[j + 1] as usize];
                let before = tile.entry_row.len();
                if q == Quantization::F32 {
                    tile.col_scale.push(UNIT_SCALE_CODE);
                    for &(r, v) in entries.iter().filter(|(_, v)| *v != 0.0) {
                        tile.entry_row.push(r);
                        tile.values.push(v);
                    }
                } else {
                    let max = entries.iter().fold(0.0f32, |m, e| m.max(e.1.abs()));
                    let code = code_for(max, q_max).ok_or_else(|| {
                        PrtError::invalid(
                            "transport row",
                            format!("coefficient {j}: {max} is too large to quantise"),
                        )
                    })?;
                    let s = scale_of(code);
                    tile.col_scale.push(code);
                    for &(r, v) in entries {
                        let k = quantize(v, s, q_max);
                        let sr = row_scales[r as usize] as f64;
                        tile.quantization_energy += ((v - k * s) as f64 * sr).powi(2);
                        if k != 0.0 {
                            tile.entry_row.push(r);
                            tile.values.push(k);
                        }
                    }
                }
                tile.col_count.push((tile.entry_row.len() - before) as u16);
            }
            for (row, &sr) in block.iter().zip(&row_scales) {
                tile.row_pixel.push(row.pixel);
                tile.row_weight.push(row.weight);
                tile.row_scale.push(sr);
                tile.sh.extend_from_slice(&row.sh);
            }
        }
        Ok(tile)
    }
}

impl Transport {
    /// Lays out rows given tile by tile (tiles in row-major order of the tile grid, each tile's
    /// rows in the order they should keep) into the blocked column layout, quantised as
    /// `meta.quantization` says. Per-pixel and per-coefficient tables are taken as given; the
    /// energy quantisation drops is added to each tile's first statistic. Checks the result, so a
    /// caller's mistake is an error, not a bad file.
    pub fn assemble(
        meta: TransportMeta,
        tiles: Vec<Vec<RowData>>,
        albedo: Vec<[f32; 3]>,
        coverage: Vec<f32>,
        mut tile_stats: Vec<[f64; 3]>,
    ) -> Result<Transport> {
        let c = 6 * (meta.cube_n as usize).pow(2);
        let shc = (meta.sh_order as usize).pow(2);
        let encoded = tiles
            .iter()
            .map(|rows| EncodedTile::encode(rows, c, shc, meta.quantization))
            .collect::<Result<Vec<_>>>()?;
        for (s, e) in tile_stats.iter_mut().zip(&encoded) {
            s[0] += e.quantization_energy;
        }
        Self::assemble_encoded(meta, &encoded, albedo, coverage, tile_stats)
    }

    /// Joins encoded tiles (row-major over the tile grid) into a transport and derives its
    /// statistics.
    pub fn assemble_encoded(
        meta: TransportMeta,
        tiles: &[EncodedTile],
        albedo: Vec<[f32; 3]>,
        coverage: Vec<f32>,
        tile_stats: Vec<[f64; 3]>,
    ) -> Result<Transport> {
        let c = 6 * (meta.cube_n as usize).pow(2);
        let rows: usize = tiles.iter().map(|t| t.row_pixel.len()).sum();
        let nnz: usize = tiles.iter().map(|t| t.entry_row.len()).sum();
        let blocks: usize = tiles.iter().map(|t| t.col_count.len() / c.max(1)).sum();
        let mut tile_row_start = Vec::with_capacity(tiles.len() + 1);
        let mut row_pixel = Vec::with_capacity(rows);
        let mut row_weight = Vec::with_capacity(rows);
        let mut row_scale = Vec::with_capacity(rows);
        let mut sh = Vec::new();
        let mut counts = Vec::with_capacity(blocks * c);
        let mut col_scale = Vec::with_capacity(blocks * c);
        let mut entry_row = Vec::with_capacity(nnz);
        let mut values = Values::empty(meta.quantization);
        tile_row_start.push(0u32);
        for t in tiles {
            if t.values.quantization() != meta.quantization
                || t.row_scale.len() != t.row_pixel.len()
                || t.col_count.len() != blocks_of(t.row_pixel.len()) * c
                || t.col_scale.len() != t.col_count.len()
            {
                return Err(PrtError::invalid(
                    "transport tile",
                    "its blocks do not match its rows or the quantisation",
                ));
            }
            row_pixel.extend_from_slice(&t.row_pixel);
            row_weight.extend_from_slice(&t.row_weight);
            row_scale.extend_from_slice(&t.row_scale);
            sh.extend_from_slice(&t.sh);
            counts.extend_from_slice(&t.col_count);
            col_scale.extend_from_slice(&t.col_scale);
            entry_row.extend_from_slice(&t.entry_row);
            values.extend_from(&t.values, 0..t.values.len());
            tile_row_start.push(row_pixel.len() as u32);
        }
        let invalid = |m: String| PrtError::invalid("transport", m);
        let (tile_block_start, block_row_start) =
            block_tables(&tile_row_start, rows).map_err(invalid)?;
        let (col_ptr, block_entry_start) =
            column_pointers(&counts, &block_row_start, c, nnz).map_err(invalid)?;
        let mut t = Transport {
            meta,
            tile_row_start,
            row_pixel,
            row_weight,
            row_scale,
            tile_block_start,
            block_row_start,
            block_entry_start,
            col_ptr,
            col_scale,
            entry_row,
            values,
            sh,
            albedo,
            coverage,
            transport_magnitude: vec![0.0; c],
            tile_stats,
        };
        t.validate().map_err(invalid)?;
        t.finish();
        Ok(t)
    }

    /// Derives the per-coefficient transport magnitudes and the statistics from the tables, in
    /// one fixed order (block, coefficient, row), so a bake and a merge of its shards give the
    /// same bits.
    pub fn finish(&mut self) {
        let c = self.coeff_count();
        let mut magnitude = vec![0.0f64; c];
        for b in 0..self.block_count() {
            let r0 = self.block_row_start[b] as usize;
            for (j, m) in magnitude.iter_mut().enumerate() {
                let s = self.scale(b, j) as f64;
                for e in self.block_column(b, j) {
                    let r = r0 + self.entry_row[e] as usize;
                    *m += (self.values.raw(e).abs() as f64 * s * self.row_scale[r] as f64)
                        * crate::light::select::rgb_magnitude(self.row_weight[r]) as f64;
                }
            }
        }
        let rows = self.row_pixel.len();
        self.transport_magnitude = magnitude
            .iter()
            .map(|m| (m / rows.max(1) as f64) as f32)
            .collect();
        let (mut dropped, mut total, mut rays) = (0.0f64, 0.0f64, 0.0f64);
        for s in &self.tile_stats {
            dropped += s[0];
            total += s[1];
            rays += s[2];
        }
        self.meta.stats = BakeStats {
            rows: rows as u64,
            nonzeros: self.entry_row.len() as u64,
            dense_entries: (rows * c) as u64,
            dropped_energy_fraction: if total > 0.0 { dropped / total } else { 0.0 },
            shadow_rays: rays as u64,
        };
    }

    /// Tile `tile` in the stored layout, copied (for a merge).
    fn encoded_tile(&self, tile: usize) -> EncodedTile {
        let c = self.coeff_count();
        let (r0, r1) = (
            self.tile_row_start[tile] as usize,
            self.tile_row_start[tile + 1] as usize,
        );
        let blocks = self.blocks(tile);
        let (e0, e1) = (
            self.block_entry_start[blocks.start] as usize,
            self.block_entry_start[blocks.end] as usize,
        );
        let shc = self.sh_count();
        let mut values = Values::empty(self.values.quantization());
        values.extend_from(&self.values, e0..e1);
        let counts = self.col_counts(blocks.clone());
        EncodedTile {
            row_pixel: self.row_pixel[r0..r1].to_vec(),
            row_weight: self.row_weight[r0..r1].to_vec(),
            row_scale: self.row_scale[r0..r1].to_vec(),
            sh: self.sh[r0 * shc..r1 * shc].to_vec(),
            col_count: counts,
            col_scale: self.col_scale[blocks.start * c..blocks.end * c].to_vec(),
            entry_row: self.entry_row[e0..e1].to_vec(),
            values,
            quantization_energy: 0.0,
        }
    }

    /// The rows of tile `tile` as [`RowData`] with decoded values (for tests and tools).
    pub fn tile_rows(&self, tile: usize) -> Vec<RowData> {
        let (r0, r1) = (
            self.tile_row_start[tile] as usize,
            self.tile_row_start[tile + 1] as usize,
        );
        let shc = self.sh_count();
        let mut rows: Vec<RowData> = (r0..r1)
            .map(|r| RowData {
                pixel: self.row_pixel[r],
                weight: self.row_weight[r],
                entries: Vec::new(),
                sh: self.sh[r * shc..(r + 1) * shc].to_vec(),
            })
            .collect();
        for b in self.blocks(tile) {
            let local = self.block_row_start[b] as usize - r0;
            for j in 0..self.coeff_count() {
                for e in self.block_column(b, j) {
                    rows[local + self.entry_row[e] as usize]
                        .entries
                        .push((j as u32, self.value(b, j, e)));
                }
            }
        }
        rows
    }

    /// Joins the shards of one bake (in any order) into the file a single bake would have
    /// written. The shards must come from the same scene and settings and cover every band once.
    /// Errors name a shard as "file K" (its place in `shards`, from 1).
    pub fn merge(shards: &[Transport]) -> Result<Transport> {
        let names: Vec<String> = (1..=shards.len()).map(|k| format!("file {k}")).collect();
        Self::merge_named(shards, &names)
    }

    /// [`Transport::merge`], naming shard k as `names[k]` in errors (a path, say).
    pub fn merge_named(shards: &[Transport], names: &[String]) -> Result<Transport> {
        let name = |k: usize| {
            names
                .get(k)
                .cloned()
                .unwrap_or_else(|| format!("file {}", k + 1))
        };
        let first = shards
            .first()
            .ok_or_else(|| PrtError::invalid("merge", "no shard given"))?;
        let Some([_, count]) = first.meta.shard else {
            return Err(PrtError::invalid(
                "merge",
                format!("{} is not a shard", name(0)),
            ));
        };
        let same = |m: &TransportMeta| TransportMeta {
            shard: None,
            stats: BakeStats::default(),
            ..m.clone()
        };
        // Loading checked count <= the image's bands, so this is small.
        let mut owner = vec![usize::MAX; count as usize];
        for (k, s) in shards.iter().enumerate() {
            if same(&s.meta) != same(&first.meta) {
                return Err(PrtError::invalid(
                    "merge",
                    meta_difference(&same(&s.meta), &name(k), &same(&first.meta), &name(0)),
                ));
            }
            match s.meta.shard {
                Some([i, n]) if n == count && i < n && owner[i as usize] == usize::MAX => {
                    owner[i as usize] = k
                }
                Some([i, n]) if n == count && i < n => {
                    return Err(PrtError::invalid(
                        "merge",
                        format!(
                            "shard {i}/{n} repeats: {} and {} are both shard {i}/{n}",
                            name(owner[i as usize]),
                            name(k)
                        ),
                    ));
                }
                Some([i, n]) => {
                    return Err(PrtError::invalid(
                        "merge",
                        format!(
                            "{} is shard {i}/{n}, which does not fit a set of {count} shards",
                            name(k)
                        ),
                    ));
                }
                None => {
                    return Err(PrtError::invalid(
                        "merge",
                        format!("{} is not a shard", name(k)),
                    ));
                }
            }
        }
        if let Some(i) = owner.iter().position(|&o| o == usize::MAX) {
            return Err(PrtError::invalid(
                "merge",
                format!("shard {i}/{count} is missing"),
            ));
        }
        let (w, h) = (first.meta.width as usize, first.meta.height as usize);
        let (tx, ty) = tile_grid(w, h);
        // A shard holds nothing outside its own bands: a label that does not match the content
        // (two shards' labels swapped, say) would otherwise merge into a mostly black image.
        for (i, &k) in owner.iter().enumerate() {
            let s = &shards[k];
            for band in (0..ty).filter(|&b| shard_of_band(b, ty, count as usize) != i) {
                let tiles = band * tx..(band + 1) * tx;
                let pixels = band * TILE * w..((band + 1) * TILE * w).min(w * h);
                let rows = s.tile_row_start[tiles.end] - s.tile_row_start[tiles.start];
                let stats = s.tile_stats[tiles].iter().flatten().any(|v| *v != 0.0);
                let seen = s.coverage[pixels.clone()].iter().any(|v| *v != 0.0)
                    || s.albedo[pixels].iter().flatten().any(|v| *v != 0.0);
                if rows > 0 || stats || seen {
                    return Err(PrtError::invalid(
                        "merge",
                        format!(
                            "{} is labelled shard {i}/{count} but holds data in tile row {band}, \
                             which shard {}/{count} bakes: its `shard` label does not match its \
                             content",
                            name(k),
                            shard_of_band(band, ty, count as usize)
                        ),
                    ));
                }
            }
        }
        let mut tiles = Vec::with_capacity(tx * ty);
        let mut albedo = vec![[0.0f32; 3]; w * h];
        let mut coverage = vec![0.0f32; w * h];
        let mut tile_stats = Vec::with_capacity(tx * ty);
        for band in 0..ty {
            let s = &shards[owner[shard_of_band(band, ty, count as usize)]];
            for tile in band * tx..(band + 1) * tx {
                tiles.push(s.encoded_tile(tile));
                tile_stats.push(s.tile_stats[tile]);
            }
            let pixels = band * TILE * w..((band + 1) * TILE * w).min(w * h);
            albedo[pixels.clone()].copy_from_slice(&s.albedo[pixels.clone()]);
            coverage[pixels.clone()].copy_from_slice(&s.coverage[pixels]);
        }
        Transport::assemble_encoded(same(&first.meta), &tiles, albedo, coverage, tile_stats)
    }
}

/// How shard `a` (named `na`) differs from shard `b` (named `nb`): "A was baked from another
/// scene than B (scene hash X against Y)", or the first setting that differs, "A was baked with
/// seed 7, B with seed 1".
fn meta_difference(a: &TransportMeta, na: &str, b: &TransportMeta, nb: &str) -> String {
    if a.scene_hash != b.scene_hash {
        return format!(
            "{na} was baked from another scene than {nb} (scene hash {} against {})",
            a.scene_hash, b.scene_hash
        );
    }
    if let (Ok(serde_json::Value::Object(x)), Ok(serde_json::Value::Object(y))) =
        (serde_json::to_value(a), serde_json::to_value(b))
    {
        for (key, va) in &x {
            let vb = y.get(key).unwrap_or(&serde_json::Value::Null);
            if va != vb {
                return format!("{na} was baked with {key} {va}, {nb} with {key} {vb}");
            }
        }
    }
    format!("{na} was baked with other settings than {nb}")
}

/// The shard that bakes band (tile row) `band` of `bands` when a bake is split into `count`.
pub fn shard_of_band(band: usize, bands: usize, count: usize) -> usize {
    (band * count) / bands.max(1)
}

/// Reads only the safetensors header and our metadata, checking that the declared tensors fill the
/// file exactly and that the format and version are ours; allocates nothing proportional to the
/// data.
pub fn read_header_meta(path: &Path) -> Result<TransportMeta> {
    read_header(path).map(|h| h.meta)
}

/// The header and the small tables, for `prt info`: the metadata, checked as
/// [`read_header_meta`] does, and the tile and column-count tables, checked against each other and
/// against the entry count the header declares. The entries and values, nearly all of the file,
/// are neither read nor checked (their checksum needs them all).
pub fn read_summary(path: &Path) -> Result<TransportMeta> {
    let Header {
        meta,
        tensors,
        data_start,
        mut file,
        ..
    } = read_header(path)?;
    // A tensor's element count and, when `read`, its bytes (the header's offsets were checked
    // against the file's length, so the read is bounded by the file).
    let mut tensor = |name: &str, dtype: &str, read: bool| -> Result<(usize, Vec<u8>)> {
        let bad = |why: &str| PrtError::file(path, format!("tensor `{name}`: {why}"));
        let t = tensors.get(name).ok_or_else(|| bad("missing"))?;
        if t.get("dtype").and_then(|d| d.as_str()) != Some(dtype) {
            return Err(bad(&format!("dtype is not {dtype}")));
        }
        let count = t
            .get("shape")
            .and_then(|s| s.as_array())
            .and_then(|a| {
                a.iter()
                    .try_fold(1usize, |n, d| n.checked_mul(d.as_u64()? as usize))
            })
            .ok_or_else(|| bad("bad shape"))?;
        let offsets = t.get("data_offsets").and_then(|o| o.as_array());
        let (start, end) =
            match offsets.and_then(|o| Some((o.first()?.as_u64()?, o.get(1)?.as_u64()?))) {
                Some((a, b)) if a <= b => (a, b),
                _ => return Err(bad("bad data_offsets")),
            };
        let width = match dtype {
            "U32" => 4,
            "U16" => 2,
            _ => 1,
        };
        if count.checked_mul(width) != Some((end - start) as usize) {
            return Err(bad(&format!(
                "{count} values do not fill {} bytes",
                end - start
            )));
        }
        if !read {
            return Ok((count, Vec::new()));
        }
        let mut bytes = vec![0u8; (end - start) as usize];
        file.seek(std::io::SeekFrom::Start(data_start + start))
            .and_then(|_| file.read_exact(&mut bytes))
            .map_err(|e| bad(&format!("reading: {e}")))?;
        Ok((count, bytes))
    };
    let (tiles, starts) = tensor("tile_row_start", "U32", true)?;
    let (rows, _) = tensor("row_pixel", "U32", false)?;
    let (nnz, _) = tensor("entry_row", "U8", false)?;
    let (_, counts) = tensor("col_count", "U16", true)?;
    let (tx, ty) = tile_grid(meta.width as usize, meta.height as usize);
    let starts: Vec<u32> = bytemuck::pod_collect_to_vec(&starts);
    if tiles != tx * ty + 1 || starts.len() != tiles {
        return Err(PrtError::file(
            path,
            "tile tables do not match the image size",
        ));
    }
    let (_, block_rows) = block_tables(&starts, rows).map_err(|m| PrtError::file(path, m))?;
    let c = 6 * meta.cube_n as usize * meta.cube_n as usize;
    let counts: Vec<u16> = bytemuck::pod_collect_to_vec(&counts);
    if counts.len() != (block_rows.len() - 1) * c {
        return Err(PrtError::file(
            path,
            "column counts do not match the blocks and coefficients",
        ));
    }
    column_pointers(&counts, &block_rows, c, nnz).map_err(|m| PrtError::file(path, m))?;
    Ok(meta)
}

/// What [`read_header`] gives: the checked metadata, the stored tensor checksum, the header's
/// tensor entries (name to dtype, shape and offsets), where the tensor data starts, and the open
/// file.
struct Header {
    meta: TransportMeta,
    checksum: String,
    tensors: serde_json::Map<String, serde_json::Value>,
    data_start: u64,
    file: std::fs::File,
}

/// [`read_header_meta`], with what the rest of a reader needs (see [`Header`]).
fn read_header(path: &Path) -> Result<Header> {
    let (mut f, file_len) = crate::files::open_regular(path, u64::MAX, "transport")?;
    let mut len8 = [0u8; 8];
    f.read_exact(&mut len8)
        .map_err(|_| PrtError::file(path, "too short to be a transport file"))?;
    let header_len = u64::from_le_bytes(len8);
    if header_len > MAX_HEADER_BYTES || header_len + 8 > file_len {
        return Err(PrtError::file(
            path,
            format!("header length {header_len} does not fit a file of {file_len} bytes"),
        ));
    }
    let mut header = vec![0u8; header_len as usize];
    f.read_exact(&mut header)
        .map_err(|e| PrtError::file(path, format!("reading header: {e}")))?;
    let json: serde_json::Value = serde_json::from_slice(&header)
        .map_err(|e| PrtError::file(path, format!("header is not JSON: {e}")))?;
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
        Some(v) if v == FORMAT_VERSION as u64 => {}
        Some(v) if v < FORMAT_VERSION as u64 => {
            return Err(PrtError::file(
                path,
                format!(
                    "format_version {v} was written by an older build (16-bit float values); \
                     this build reads version {FORMAT_VERSION}: bake the scene again with \
                     `prt bake`"
                ),
            ));
        }
        _ => {
            return Err(PrtError::file(
                path,
                format!(
                    "format_version {}; this build reads version {FORMAT_VERSION}",
                    version.map(|v| v.to_string()).unwrap_or("?".into())
                ),
            ));
        }
    }
    check_meta_seal(text).map_err(|m| PrtError::file(path, m))?;
    let header: FileHeader = serde_json::from_value(value)
        .map_err(|e| PrtError::file(path, format!("metadata `meta`: {e}")))?;
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
        checksum: header.checksum,
        tensors: obj.clone(),
        data_start: 8 + header_len,
        file: f,
    })
}

/// The one metadata entry of a file: format, version, checksum and the [`TransportMeta`]
/// (`meta_checksum` follows them in the text, see [`seal_meta`]).
#[derive(Serialize, Deserialize)]
struct FileHeader {
    format: String,
    format_version: u32,
    /// Of the tensors (see [`checksum`]).
    checksum: String,
    #[serde(flatten)]
    meta: TransportMeta,
}

fn check_meta(m: &TransportMeta) -> std::result::Result<(), String> {
    if m.width == 0 || m.height == 0 || m.width > 16384 || m.height > 16384 {
        return Err(format!(
            "image size {} x {} out of range",
            m.width, m.height
        ));
    }
    if m.tile as usize != TILE {
        return Err(format!("tile size {}; this build uses {TILE}", m.tile));
    }
    crate::math::cubemap::validate_n(m.cube_n as usize).map_err(|e| e.to_string())?;
    if m.sh_order == 0 || m.sh_order as usize > crate::math::sh::MAX_ORDER {
        return Err(format!("SH order {} out of range", m.sh_order));
    }
    if let Some([i, n]) = m.shard {
        // A bake cuts at most one shard per band of tile rows.
        let (_, bands) = tile_grid(m.width as usize, m.height as usize);
        if n == 0 || i >= n || n as usize > bands {
            return Err(format!(
                "shard {i}/{n}: a shard is I/COUNT with I < COUNT <= {bands} (the image's \
                 bands of tile rows)"
            ));
        }
    }
    if !(m.threshold.is_finite() && m.threshold >= 0.0) {
        return Err(format!("threshold {} must be finite and >= 0", m.threshold));
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

/// Names of the tensors in a file, in the order the checksum covers them.
const TENSOR_NAMES: [&str; 13] = [
    "albedo",
    "col_count",
    "col_scale",
    "coverage",
    "entry_row",
    "entry_value",
    "row_pixel",
    "row_scale",
    "row_weight",
    "sh",
    "tile_row_start",
    "tile_stats",
    "transport_magnitude",
];
