//! The transport store: the baked sparse Haar transport, the dense SH transport and per-pixel data
//! of one fixed view, in memory and in a documented safetensors file.
//!
//! # Rows, tiles and columns
//! The image is cut into [`TILE`] x [`TILE`] pixel tiles, row-major over the tile grid. A *row* is
//! one transport vector over the 6 N² Haar coefficients together with the pixel it lights and an RGB
//! weight: a pixel's radiance is `Σ_rows weight ⊙ (row · L)`. A diffuse pixel that sees one material
//! has one row whose weight is the albedo; a pixel whose sub-samples see several materials has one
//! row per material, so the split stays exact. Rows are grouped by tile.
//!
//! Inside a tile the rows' nonzero coefficients are stored column by column (coefficient-major):
//! `col_ptr[t][j]..col_ptr[t][j + 1]` are tile t's entries of coefficient j, each a local row index
//! and a value, rows strictly increasing inside a column. So one worker owns a tile's rows with no
//! atomics, a column touches each row at most once, and relighting with K terms reads only K columns.
//!
//! # File
//! A safetensors file (readable from Python with `safetensors.numpy.load_file`); its one metadata
//! entry `meta` is JSON: `format = "wavelet-prt transport"`, `format_version`, `checksum` and the
//! fields of [`TransportMeta`].
//! Tensors: `tile_row_start` u32 [T+1], `row_pixel` u32 [R], `row_weight` f32 [R,3],
//! `tile_entry_start` u64 [T+1], `col_ptr` u32 [T, C+1] (relative to the tile's first entry),
//! `entry_row` u16 [nnz], `entry_value` f16 or f32 [nnz], `sh` f32 [R, n²], `albedo` f32 [H, W, 3],
//! `coverage` f32 [H, W], `transport_magnitude` f32 [C], `tile_stats` f64 [T, 3] (per tile: energy
//! dropped by thresholding, total energy, shadow rays). The `checksum` covers the tensors' bytes in
//! name order, so a flipped bit anywhere is caught. Loading checks the header, the sizes and
//! every index before it allocates anything or trusts any offset; writing goes to a temporary file
//! that is renamed into place.

use std::borrow::Cow;
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use half::f16;
use safetensors::tensor::{Dtype, View};
use serde::{Deserialize, Serialize};

use crate::error::{PrtError, Result};

/// Pixels on a side of a tile.
pub const TILE: usize = 16;
/// Name written in every transport file.
pub const FORMAT_NAME: &str = "wavelet-prt transport";
/// Version of the layout described in this module.
pub const FORMAT_VERSION: u32 = 2;
/// Largest safetensors header accepted (JSON text), checked before it is read.
const MAX_HEADER_BYTES: u64 = 1 << 24;

/// How stored coefficient values are quantised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Quantization {
    /// IEEE half floats (2 bytes).
    F16,
    /// 32-bit floats, for lossless bakes.
    F32,
}

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
    /// Sum over rows of the squared norm of what thresholding dropped, over the sum of squared
    /// norms: the relative L2 (squared) the sparsification removed from the transport.
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
    /// Relative L2 error allowed per row by thresholding (0 = keep every nonzero).
    pub threshold: f32,
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

/// Stored coefficient values.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    F16(Vec<f16>),
    F32(Vec<f32>),
}

impl Values {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Values::F16(v) => v.len(),
            Values::F32(v) => v.len(),
        }
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Bytes per value.
    pub fn value_bytes(&self) -> usize {
        match self {
            Values::F16(_) => 2,
            Values::F32(_) => 4,
        }
    }
    /// Value `i` as f32.
    #[inline]
    pub fn get(&self, i: usize) -> f32 {
        match self {
            Values::F16(v) => v[i].to_f32(),
            Values::F32(v) => v[i],
        }
    }
}

/// A baked view in memory, in the layout of this module.
#[derive(Clone, Debug, PartialEq)]
pub struct Transport {
    pub meta: TransportMeta,
    pub tile_row_start: Vec<u32>,
    pub row_pixel: Vec<u32>,
    pub row_weight: Vec<[f32; 3]>,
    pub tile_entry_start: Vec<u64>,
    pub col_ptr: Vec<u32>,
    pub entry_row: Vec<u16>,
    pub values: Values,
    pub sh: Vec<f32>,
    pub albedo: Vec<[f32; 3]>,
    pub coverage: Vec<f32>,
    pub transport_magnitude: Vec<f32>,
    /// Per tile: energy thresholding dropped, the rows' total energy, shadow rays traced.
    pub tile_stats: Vec<[f64; 3]>,
}

/// Tiles along x and y for an image.
pub fn tile_grid(width: usize, height: usize) -> (usize, usize) {
    (width.div_ceil(TILE), height.div_ceil(TILE))
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
    /// Pixels in the image.
    pub fn pixel_count(&self) -> usize {
        self.meta.width as usize * self.meta.height as usize
    }
    /// SH coefficients per row.
    pub fn sh_count(&self) -> usize {
        (self.meta.sh_order as usize).pow(2)
    }
    /// Entry range of coefficient `j` in tile `t`, as absolute entry indices.
    #[inline]
    pub fn column(&self, t: usize, j: usize) -> std::ops::Range<usize> {
        let c = self.coeff_count() + 1;
        let base = self.tile_entry_start[t] as usize;
        base + self.col_ptr[t * c + j] as usize..base + self.col_ptr[t * c + j + 1] as usize
    }
    /// Bytes of the sparse Haar matrix (entries and column pointers).
    pub fn haar_bytes(&self) -> usize {
        self.entry_row.len() * 2
            + self.values.len() * self.values.value_bytes()
            + self.col_ptr.len() * 4
    }

    /// Writes the file atomically: a temporary file beside `path`, then a rename.
    pub fn save(&self, path: &Path) -> Result<()> {
        let (w, h) = (self.meta.width as usize, self.meta.height as usize);
        let tiles = self.tile_count();
        let c = self.coeff_count();
        let r = self.row_pixel.len();
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
                "tile_entry_start",
                Tensor::new(Dtype::U64, vec![tiles + 1], &self.tile_entry_start),
            ),
            (
                "col_ptr",
                Tensor::new(Dtype::U32, vec![tiles, c + 1], &self.col_ptr),
            ),
            (
                "entry_row",
                Tensor::new(Dtype::U16, vec![self.entry_row.len()], &self.entry_row),
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
            Values::F16(v) => ("entry_value", Tensor::new(Dtype::F16, vec![v.len()], v)),
            Values::F32(v) => ("entry_value", Tensor::new(Dtype::F32, vec![v.len()], v)),
        });
        tensors.sort_by_key(|(name, _)| *name);
        debug_assert!(tensors.iter().map(|(n, _)| *n).eq(TENSOR_NAMES));
        let sum = checksum(tensors.iter().map(|(_, t)| t.bytes));
        // One metadata key, so the header is the same bytes for the same content (the
        // container keeps its metadata in a hash map, whose order varies between runs).
        let header = FileHeader {
            format: FORMAT_NAME.to_string(),
            format_version: FORMAT_VERSION,
            checksum: format!("{sum:016x}"),
            meta: self.meta.clone(),
        };
        let json = serde_json::to_string(&header)
            .map_err(|e| PrtError::file(path, format!("metadata: {e}")))?;
        let info: HashMap<String, String> = [("meta".to_string(), json)].into();
        crate::film::write_atomically(path, |tmp| {
            safetensors::serialize_to_file(tensors, Some(info), tmp)
                .map_err(|e| PrtError::file(tmp, format!("writing: {e}")))
        })
    }

    /// Reads and fully validates a transport file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with_progress(path, &|_, _| {})
    }

    /// [`Transport::load`], calling `progress(bytes read, file size)` as the file comes in (the
    /// viewer shows it; validation after the read is quick).
    pub fn load_with_progress(path: &Path, progress: &dyn Fn(u64, u64)) -> Result<Self> {
        let (meta, stored) = read_header(path)?;
        let buf = read_with_progress(path, progress)?;
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
        let (s, d) = get("tile_row_start", Dtype::U32)?;
        expect("tile_row_start", &s, &[tiles + 1])?;
        let tile_row_start: Vec<u32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("row_pixel", Dtype::U32)?;
        let r = s.first().copied().unwrap_or(0);
        expect("row_pixel", &s, &[r])?;
        let row_pixel: Vec<u32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("row_weight", Dtype::F32)?;
        expect("row_weight", &s, &[r, 3])?;
        let row_weight: Vec<[f32; 3]> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("tile_entry_start", Dtype::U64)?;
        expect("tile_entry_start", &s, &[tiles + 1])?;
        let tile_entry_start: Vec<u64> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("col_ptr", Dtype::U32)?;
        expect("col_ptr", &s, &[tiles, c + 1])?;
        let col_ptr: Vec<u32> = bytemuck::pod_collect_to_vec(d);
        let (s, d) = get("entry_row", Dtype::U16)?;
        let nnz = s.first().copied().unwrap_or(0);
        expect("entry_row", &s, &[nnz])?;
        let entry_row: Vec<u16> = bytemuck::pod_collect_to_vec(d);
        let values = match meta.quantization {
            Quantization::F16 => {
                let (s, d) = get("entry_value", Dtype::F16)?;
                expect("entry_value", &s, &[nnz])?;
                Values::F16(bytemuck::pod_collect_to_vec(d))
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
            tile_entry_start,
            col_ptr,
            entry_row,
            values,
            sh,
            albedo,
            coverage,
            transport_magnitude,
            tile_stats,
        };
        t.validate().map_err(|m| PrtError::file(path, m))?;
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
        if self.tile_row_start.len() != tiles + 1
            || self.tile_entry_start.len() != tiles + 1
            || self.col_ptr.len() != tiles * (c + 1)
        {
            return Err("tile tables do not match the image size".into());
        }
        if self.tile_row_start[0] != 0 || self.tile_row_start[tiles] as usize != r {
            return Err("tile_row_start does not span the rows".into());
        }
        if self.tile_entry_start[0] != 0
            || self.tile_entry_start[tiles] != self.entry_row.len() as u64
            || self.values.len() != self.entry_row.len()
        {
            return Err("tile_entry_start does not span the entries".into());
        }
        if self.row_weight.len() != r || self.sh.len() != r * self.sh_count() {
            return Err("row tables have different lengths".into());
        }
        for t in 0..tiles {
            let (r0, r1) = (
                self.tile_row_start[t] as usize,
                self.tile_row_start[t + 1] as usize,
            );
            let (e0, e1) = (self.tile_entry_start[t], self.tile_entry_start[t + 1]);
            if r1 < r0 || e1 < e0 {
                return Err(format!("tile {t}: offsets decrease"));
            }
            let rows = r1 - r0;
            if rows > u16::MAX as usize + 1 {
                return Err(format!(
                    "tile {t}: {rows} rows do not fit 16-bit row indices"
                ));
            }
            let (x0, y0) = ((t % tx) * TILE, (t / tx) * TILE);
            for &p in &self.row_pixel[r0..r1] {
                let (px, py) = (p as usize % w.max(1), p as usize / w.max(1));
                if p as usize >= w * h || px < x0 || px >= x0 + TILE || py < y0 || py >= y0 + TILE {
                    return Err(format!("tile {t}: row pixel {p} lies outside the tile"));
                }
            }
            let ptr = &self.col_ptr[t * (c + 1)..(t + 1) * (c + 1)];
            if ptr[0] != 0 || ptr[c] as u64 != e1 - e0 {
                return Err(format!("tile {t}: column pointers do not span its entries"));
            }
            for j in 0..c {
                if ptr[j + 1] < ptr[j] {
                    return Err(format!(
                        "tile {t}: column pointers decrease at coefficient {j}"
                    ));
                }
                let col = &self.entry_row
                    [(e0 as usize + ptr[j] as usize)..(e0 as usize + ptr[j + 1] as usize)];
                let mut last: i32 = -1;
                for &row in col {
                    if row as usize >= rows || row as i32 <= last {
                        return Err(format!(
                            "tile {t}, coefficient {j}: row index {row} out of range or not increasing"
                        ));
                    }
                    last = row as i32;
                }
            }
        }
        let finite = match &self.values {
            Values::F16(v) => v.iter().all(|x| x.is_finite()),
            Values::F32(v) => v.iter().all(|x| x.is_finite()),
        };
        if !finite || !self.sh.iter().all(|x| x.is_finite()) {
            return Err("non-finite transport values".into());
        }
        if self.albedo.len() != w * h
            || self.coverage.len() != w * h
            || self.transport_magnitude.len() != c
            || self.tile_stats.len() != tiles
        {
            return Err("per-pixel or per-coefficient tables have the wrong length".into());
        }
        Ok(())
    }
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

impl Transport {
    /// Lays out rows given tile by tile (tiles in row-major order of the tile grid, each tile's
    /// rows in the order they should keep) into the column-major tiled layout. Values are stored
    /// as `meta.quantization` says. Per-pixel and per-coefficient tables are taken as given.
    /// Checks the result, so a caller's mistake is an error, not a bad file.
    pub fn assemble(
        meta: TransportMeta,
        tiles: Vec<Vec<RowData>>,
        albedo: Vec<[f32; 3]>,
        coverage: Vec<f32>,
        tile_stats: Vec<[f64; 3]>,
    ) -> Result<Transport> {
        let c = 6 * (meta.cube_n as usize).pow(2);
        let nnz: usize = tiles.iter().flatten().map(|r| r.entries.len()).sum();
        let rows: usize = tiles.iter().map(|t| t.len()).sum();
        let shc = (meta.sh_order as usize).pow(2);
        let mut t = Transport {
            tile_row_start: Vec::with_capacity(tiles.len() + 1),
            row_pixel: Vec::with_capacity(rows),
            row_weight: Vec::with_capacity(rows),
            tile_entry_start: Vec::with_capacity(tiles.len() + 1),
            col_ptr: Vec::with_capacity(tiles.len() * (c + 1)),
            entry_row: vec![0; nnz],
            values: Values::F32(Vec::new()),
            sh: Vec::with_capacity(rows * shc),
            albedo,
            coverage,
            transport_magnitude: vec![0.0; c],
            tile_stats,
            meta,
        };
        let mut values = vec![0.0f32; nnz];
        t.tile_row_start.push(0);
        t.tile_entry_start.push(0);
        let mut base = 0usize;
        for tile in &tiles {
            // Counting sort by coefficient; rows are visited in order, so every column's rows
            // come out strictly increasing.
            let mut ptr = vec![0u32; c + 1];
            for row in tile {
                for &(j, _) in &row.entries {
                    if j as usize >= c {
                        return Err(PrtError::invalid(
                            "transport row",
                            format!("coefficient {j} >= {c}"),
                        ));
                    }
                    ptr[j as usize + 1] += 1;
                }
            }
            for j in 0..c {
                ptr[j + 1] += ptr[j];
            }
            let mut fill = ptr.clone();
            for (r, row) in tile.iter().enumerate() {
                for &(j, v) in &row.entries {
                    let e = base + fill[j as usize] as usize;
                    t.entry_row[e] = r as u16;
                    values[e] = v;
                    fill[j as usize] += 1;
                }
                if row.sh.len() != shc {
                    return Err(PrtError::invalid(
                        "transport row",
                        format!("{} SH values, expected {shc}", row.sh.len()),
                    ));
                }
                t.row_pixel.push(row.pixel);
                t.row_weight.push(row.weight);
                t.sh.extend_from_slice(&row.sh);
            }
            base += ptr[c] as usize;
            t.col_ptr.extend_from_slice(&ptr);
            t.tile_row_start.push(t.row_pixel.len() as u32);
            t.tile_entry_start.push(base as u64);
        }
        t.values = match t.meta.quantization {
            Quantization::F32 => Values::F32(values),
            Quantization::F16 => Values::F16(values.iter().map(|&v| f16::from_f32(v)).collect()),
        };
        t.validate()
            .map_err(|m| PrtError::invalid("transport", m))?;
        t.finish();
        Ok(t)
    }

    /// Derives the per-coefficient transport magnitudes and the statistics from the tables, in
    /// one fixed order (tile, coefficient, row), so a bake and a merge of its shards give the
    /// same bits.
    pub fn finish(&mut self) {
        let c = self.coeff_count();
        let mut magnitude = vec![0.0f64; c];
        for tile in 0..self.tile_count() {
            let r0 = self.tile_row_start[tile] as usize;
            for (j, m) in magnitude.iter_mut().enumerate() {
                for e in self.column(tile, j) {
                    let w = self.row_weight[r0 + self.entry_row[e] as usize];
                    *m += self.values.get(e).abs() as f64 * crate::light::rgb_magnitude(w) as f64;
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

    /// The rows of tile `tile` as [`RowData`], decoded from its columns.
    fn tile_rows(&self, tile: usize) -> Vec<RowData> {
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
        for j in 0..self.coeff_count() {
            for e in self.column(tile, j) {
                rows[self.entry_row[e] as usize]
                    .entries
                    .push((j as u32, self.values.get(e)));
            }
        }
        rows
    }

    /// Joins the shards of one bake (in any order) into the file a single bake would have
    /// written. The shards must come from the same scene and settings and cover every band once.
    pub fn merge(shards: &[Transport]) -> Result<Transport> {
        let first = shards
            .first()
            .ok_or_else(|| PrtError::invalid("merge", "no shard given"))?;
        let Some([_, count]) = first.meta.shard else {
            return Err(PrtError::invalid("merge", "the first file is not a shard"));
        };
        let same = |m: &TransportMeta| TransportMeta {
            shard: None,
            stats: BakeStats::default(),
            ..m.clone()
        };
        let mut owner = vec![usize::MAX; count as usize];
        for (k, s) in shards.iter().enumerate() {
            if same(&s.meta) != same(&first.meta) {
                return Err(PrtError::invalid(
                    "merge",
                    format!(
                        "file {} was baked from another scene or with other settings \
                         (scene hash {} vs {})",
                        k + 1,
                        s.meta.scene_hash,
                        first.meta.scene_hash
                    ),
                ));
            }
            match s.meta.shard {
                Some([i, n]) if n == count && i < n && owner[i as usize] == usize::MAX => {
                    owner[i as usize] = k
                }
                Some([i, n]) => {
                    return Err(PrtError::invalid(
                        "merge",
                        format!("shard {i}/{n} does not fit a set of {count} shards, or repeats"),
                    ));
                }
                None => {
                    return Err(PrtError::invalid(
                        "merge",
                        format!("file {} is not a shard", k + 1),
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
        let mut tiles = Vec::with_capacity(tx * ty);
        let mut albedo = vec![[0.0f32; 3]; w * h];
        let mut coverage = vec![0.0f32; w * h];
        let mut tile_stats = Vec::with_capacity(tx * ty);
        for band in 0..ty {
            let s = &shards[owner[shard_of_band(band, ty, count as usize)]];
            for tile in band * tx..(band + 1) * tx {
                tiles.push(s.tile_rows(tile));
                tile_stats.push(s.tile_stats[tile]);
            }
            let pixels = band * TILE * w..((band + 1) * TILE * w).min(w * h);
            albedo[pixels.clone()].copy_from_slice(&s.albedo[pixels.clone()]);
            coverage[pixels.clone()].copy_from_slice(&s.coverage[pixels]);
        }
        Transport::assemble(same(&first.meta), tiles, albedo, coverage, tile_stats)
    }
}

/// The shard that bakes band (tile row) `band` of `bands` when a bake is split into `count`.
pub fn shard_of_band(band: usize, bands: usize, count: usize) -> usize {
    (band * count) / bands.max(1)
}

/// Reads a whole file in 8 MiB pieces, reporting each.
fn read_with_progress(path: &Path, progress: &dyn Fn(u64, u64)) -> Result<Vec<u8>> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(|e| PrtError::io(path, e))?;
    let total = f.metadata().map_err(|e| PrtError::io(path, e))?.len();
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

/// Reads only the safetensors header and our metadata, checking that the declared tensors fill the
/// file exactly and that the format and version are ours; allocates nothing proportional to the
/// data.
pub fn read_header_meta(path: &Path) -> Result<TransportMeta> {
    read_header(path).map(|(meta, _)| meta)
}

/// [`read_header_meta`] and the stored checksum.
fn read_header(path: &Path) -> Result<(TransportMeta, String)> {
    let mut f = std::fs::File::open(path).map_err(|e| PrtError::io(path, e))?;
    let file_len = f.metadata().map_err(|e| PrtError::io(path, e))?.len();
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
    if format == Some(crate::volume::FORMAT_NAME) {
        return Err(PrtError::file(
            path,
            "a volume file (from `prt volume bake`), not a transport file: relight it with \
             `prt volume render` or `prt view`",
        ));
    }
    if format != Some(FORMAT_NAME) {
        return Err(PrtError::file(
            path,
            "not a wavelet-prt transport file (metadata `format`)",
        ));
    }
    let version = value.get("format_version").and_then(|v| v.as_u64());
    if version != Some(FORMAT_VERSION as u64) {
        return Err(PrtError::file(
            path,
            format!(
                "format_version {}; this build reads version {FORMAT_VERSION}",
                version.map(|v| v.to_string()).unwrap_or("?".into())
            ),
        ));
    }
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
    Ok((header.meta, header.checksum))
}

/// The one metadata entry of a file: format, version, checksum and the [`TransportMeta`].
#[derive(Serialize, Deserialize)]
struct FileHeader {
    format: String,
    format_version: u32,
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
    crate::cubemap::validate_n(m.cube_n as usize).map_err(|e| e.to_string())?;
    if m.sh_order == 0 || m.sh_order as usize > crate::sh::MAX_ORDER {
        return Err(format!("SH order {} out of range", m.sh_order));
    }
    Ok(())
}

/// Names of the tensors in a file, in the order the checksum covers them.
const TENSOR_NAMES: [&str; 12] = [
    "albedo",
    "col_ptr",
    "coverage",
    "entry_row",
    "entry_value",
    "row_pixel",
    "row_weight",
    "sh",
    "tile_entry_start",
    "tile_row_start",
    "tile_stats",
    "transport_magnitude",
];

/// A 64-bit checksum of byte slices taken in order: words mixed with the SplitMix64 finaliser,
/// position-dependent, so any flipped bit changes it. Fast enough to run on every load
/// (several GB/s).
pub(crate) fn checksum<'a>(parts: impl IntoIterator<Item = &'a [u8]>) -> u64 {
    let mut h = 0x51_7c_c1_b7_27_22_0a_95u64;
    for part in parts {
        let mut chunks = part.chunks_exact(8);
        for c in &mut chunks {
            let w = u64::from_le_bytes(c.try_into().unwrap_or([0; 8]));
            h = crate::sampling::mix64(h ^ w).wrapping_add(0x9e37_79b9_7f4a_7c15);
        }
        let mut tail = [0u8; 8];
        tail[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
        h = crate::sampling::mix64(h ^ u64::from_le_bytes(tail) ^ (part.len() as u64) << 3);
    }
    h
}

/// A borrowed tensor for safetensors serialisation.
pub(crate) struct Tensor<'a> {
    dtype: Dtype,
    shape: Vec<usize>,
    pub(crate) bytes: &'a [u8],
}

impl<'a> Tensor<'a> {
    pub(crate) fn new<T: bytemuck::NoUninit>(
        dtype: Dtype,
        shape: Vec<usize>,
        data: &'a [T],
    ) -> Self {
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
