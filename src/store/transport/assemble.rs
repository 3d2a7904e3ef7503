//! Assembling a transport: rows encoded tile by tile into the blocked column layout (bakes encode
//! tiles in parallel), the per-coefficient tables finished from them, and a tile's rows decoded
//! back (shards are merged by `merge`).

use super::strips::{BlockColumns, Layout, Stored};
use super::*;
use crate::error::{PrtError, Result};
use crate::store::quant::{UNIT_SCALE_CODE, code_for, quantize, scale_of};

/// One transport row before assembly: its pixel, RGB weight, sparse Haar entries (ascending by
/// coefficient) and SH transport.
#[derive(Clone, Debug, PartialEq)]
pub struct RowData {
    /// The pixel the row lights, `y · width + x` (the vertex in a per-vertex bake).
    pub pixel: u32,
    /// RGB weight: the pixel gains `weight ⊙ (row · L)`.
    pub weight: [f32; 3],
    /// Kept Haar coefficients as (coefficient index, value), ascending by index.
    pub entries: Vec<(u32, f32)>,
    /// SH transport, n² coefficients.
    pub sh: Vec<f32>,
}

/// One tile in the stored layout: its rows' pixels, weights and SH, and its blocks' counts,
/// scale codes and entries. Bakes encode tiles in parallel; a merge copies them from shards.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedTile {
    /// The pixel of each row.
    pub row_pixel: Vec<u32>,
    /// The RGB weight of each row.
    pub row_weight: Vec<[f32; 3]>,
    /// Each row's largest magnitude; its stored values are relative to it.
    pub row_scale: Vec<f32>,
    /// `[rows, n²]` SH transport.
    pub sh: Vec<f32>,
    /// `[blocks, C]` entry counts.
    pub col_count: Vec<u16>,
    /// `[blocks, C]` scale codes.
    pub col_scale: Vec<u8>,
    /// Row inside its block of each entry, in (block, coefficient) order.
    pub entry_row: Vec<u8>,
    /// Stored value of each entry (the integer, or the float when lossless), in the order of
    /// `entry_row`.
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

impl EncodedTile {
    /// Checks that the tile's tables fit one another, `c` coefficients and the quantisation
    /// `q`; a message when they do not.
    pub(super) fn check(&self, c: usize, q: Quantization) -> std::result::Result<(), String> {
        let rows = self.row_pixel.len();
        let nnz = self.entry_row.len();
        let counted: usize = self.col_count.iter().map(|&n| n as usize).sum();
        if self.values.quantization() != q
            || self.row_weight.len() != rows
            || self.row_scale.len() != rows
            || self.col_count.len() != blocks_of(rows) * c
            || self.col_scale.len() != blocks_of(rows) * c
            || self.values.len() != nnz
            || counted != nnz
        {
            return Err("its tables do not fit one another or the quantisation".into());
        }
        // Every column's rows inside its block and strictly increasing.
        let mut e = 0;
        for (k, &n) in self.col_count.iter().enumerate() {
            let block_rows = (rows - (k / c.max(1)) * BLOCK_ROWS).min(BLOCK_ROWS);
            let col = &self.entry_row[e..e + n as usize];
            if col.iter().any(|&r| r as usize >= block_rows) || col.windows(2).any(|w| w[1] <= w[0])
            {
                return Err(format!(
                    "block {}, coefficient {}: rows outside the block or not increasing",
                    k / c.max(1),
                    k % c.max(1)
                ));
            }
            e += n as usize;
        }
        Ok(())
    }

    /// Its blocks' columns, each block's in the form [`Strips::of_blocks`] reads.
    fn block_columns<'a, V: Stored>(&'a self, c: usize, out: &mut Vec<BlockColumns<'a, V>>) {
        let values = V::slice(&self.values).unwrap_or(&[]);
        let mut e = 0;
        for b in 0..self.col_count.len() / c.max(1) {
            let counts = &self.col_count[b * c..(b + 1) * c];
            let n: usize = counts.iter().map(|&n| n as usize).sum();
            out.push(BlockColumns {
                counts,
                codes: &self.col_scale[b * c..(b + 1) * c],
                rows: &self.entry_row[e..e + n],
                values: &values[e..e + n],
                block_rows: self
                    .row_pixel
                    .len()
                    .saturating_sub(b * BLOCK_ROWS)
                    .min(BLOCK_ROWS),
            });
            e += n;
        }
    }
}

/// The strips of checked tiles (row-major over a grid `tiles_x` wide) whose blocks
/// `tile_block_start` gives, in `c` coefficients of quantisation `q`.
pub(super) fn strips_of_tiles(
    tiles: &[EncodedTile],
    tile_block_start: &[u32],
    tiles_x: usize,
    c: usize,
    q: Quantization,
) -> std::result::Result<Strips, String> {
    fn of<V: Stored>(
        tiles: &[EncodedTile],
        layout: Layout,
        c: usize,
    ) -> std::result::Result<Strips, String> {
        let mut blocks: Vec<BlockColumns<V>> = Vec::new();
        for t in tiles {
            t.block_columns(c, &mut blocks);
        }
        Strips::of_blocks(layout, &blocks, c)
    }
    let layout = Layout::of(tile_block_start, tiles_x);
    match q {
        Quantization::Q8 => of::<i8>(tiles, layout, c),
        Quantization::Q16 => of::<i16>(tiles, layout, c),
        Quantization::F32 => of::<f32>(tiles, layout, c),
    }
}

impl Transport {
    /// Lays out rows given tile by tile (tiles in row-major order of the tile grid, each tile's
    /// rows in the order they should keep) into blocks and strips, quantised as
    /// `meta.identity.quantization` says. Per-pixel and per-coefficient tables are taken as given; the
    /// energy quantisation drops is added to each tile's first statistic. Checks the result, so a
    /// caller's mistake is an error, not a bad file.
    pub fn assemble(
        meta: TransportMeta,
        tiles: Vec<Vec<RowData>>,
        albedo: Vec<[f32; 3]>,
        coverage: Vec<f32>,
        mut tile_stats: Vec<[f64; 3]>,
    ) -> Result<Transport> {
        let c = 6 * (meta.identity.cube_n as usize).pow(2);
        let shc = (meta.identity.sh_order as usize).pow(2);
        let encoded = tiles
            .iter()
            .map(|rows| EncodedTile::encode(rows, c, shc, meta.identity.quantization))
            .collect::<Result<Vec<_>>>()?;
        for (s, e) in tile_stats.iter_mut().zip(&encoded) {
            s[0] += e.quantization_energy;
        }
        let attached = Attached {
            domain: Domain::View,
            lights: LightColumns::empty(meta.width as usize, meta.height as usize),
        };
        Self::assemble_encoded(meta, &encoded, albedo, coverage, tile_stats, attached)
    }

    /// Joins encoded tiles (row-major over the tile grid) into a transport and derives its
    /// statistics: the per-coefficient magnitudes in the order (tile, block, coefficient, row)
    /// that [`super::TransportWriter`] sums them in, so both give the same bits.
    pub fn assemble_encoded(
        mut meta: TransportMeta,
        tiles: &[EncodedTile],
        albedo: Vec<[f32; 3]>,
        coverage: Vec<f32>,
        tile_stats: Vec<[f64; 3]>,
        attached: Attached,
    ) -> Result<Transport> {
        let c = 6 * (meta.identity.cube_n as usize).pow(2);
        let q = meta.identity.quantization;
        let rows: usize = tiles.iter().map(|t| t.row_pixel.len()).sum();
        let nnz: usize = tiles.iter().map(|t| t.entry_row.len()).sum();
        let mut tile_row_start = Vec::with_capacity(tiles.len() + 1);
        let mut row_pixel = Vec::with_capacity(rows);
        let mut row_weight = Vec::with_capacity(rows);
        let mut row_scale = Vec::with_capacity(rows);
        let mut sh = Vec::new();
        let mut magnitude = vec![0.0f64; c];
        tile_row_start.push(0u32);
        for t in tiles {
            t.check(c, q)
                .map_err(|m| PrtError::invalid("transport tile", m))?;
            row_pixel.extend_from_slice(&t.row_pixel);
            row_weight.extend_from_slice(&t.row_weight);
            row_scale.extend_from_slice(&t.row_scale);
            sh.extend_from_slice(&t.sh);
            add_magnitudes(&t.slices(), &mut magnitude);
            tile_row_start.push(row_pixel.len() as u32);
        }
        let invalid = |m: String| PrtError::invalid("transport", m);
        let (tile_block_start, block_row_start) =
            block_tables(&tile_row_start, rows).map_err(invalid)?;
        let (tx, _) = tile_grid(meta.width as usize, meta.height as usize);
        if !tiles.len().is_multiple_of(tx.max(1)) {
            return Err(invalid(
                "the tiles do not fill the image's tile rows".into(),
            ));
        }
        let strips = strips_of_tiles(tiles, &tile_block_start, tx, c, q).map_err(invalid)?;
        meta.stats = bake_stats(rows, nnz, c, &tile_stats);
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
            transport_magnitude: mean_magnitudes(&magnitude, rows),
            tile_stats,
            attached,
        };
        t.validate().map_err(invalid)?;
        Ok(t)
    }

    /// Stores whole every slot that this build stores whole from half full
    /// ([`super::strips::stored_whole`]), which a product adds faster: a file of version 7 kept
    /// only the strips that hold entries. The values and what they mean are unchanged.
    pub fn make_slots_whole(&mut self) -> Result<()> {
        self.strips = self
            .strips
            .with_slots_made_whole(&self.block_rows(), self.coeff_count())
            .map_err(|m| PrtError::invalid("transport", m))?;
        Ok(())
    }

    /// Tile `tile` in the stored layout, read back from the strips (for a merge).
    pub(super) fn encoded_tile(&self, tile: usize) -> EncodedTile {
        let c = self.coeff_count();
        let (r0, r1) = (
            self.tile_row_start[tile] as usize,
            self.tile_row_start[tile + 1] as usize,
        );
        let shc = self.sh_count();
        let blocks = self.blocks(tile);
        let mut t = EncodedTile {
            row_pixel: self.row_pixel[r0..r1].to_vec(),
            row_weight: self.row_weight[r0..r1].to_vec(),
            row_scale: self.row_scale[r0..r1].to_vec(),
            sh: self.sh[r0 * shc..r1 * shc].to_vec(),
            col_count: Vec::with_capacity(blocks.len() * c),
            col_scale: Vec::with_capacity(blocks.len() * c),
            entry_row: Vec::new(),
            values: Values::empty(self.quantization()),
            quantization_energy: 0.0,
        };
        for b in blocks {
            for slot in self.strips.block_slots(b, c) {
                t.col_count.push(slot.entries);
                t.col_scale.push(slot.code);
                for (r, v) in self.strips.column(*slot) {
                    t.entry_row.push(r);
                    t.values.push(v);
                }
            }
        }
        t
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
            for j in 0..self.coeff_count() {
                for (row, v) in self.column(b, j) {
                    rows[row - r0].entries.push((j as u32, v));
                }
            }
        }
        rows
    }
}

/// What a transport holds besides its tiles: the header (its statistics are filled in when the
/// tiles are joined), the per-pixel tables and the attached parts. A bake and a merge make
/// it while they hand their tiles on, in tile order, to [`KeptTiles`] or a
/// [`super::TransportWriter`].
pub struct Untiled {
    /// The header; its statistics are filled in when the tiles are joined.
    pub meta: TransportMeta,
    /// Per pixel: the mean diffuse albedo its sub-samples hit.
    pub albedo: Vec<[f32; 3]>,
    /// Per pixel: the fraction of its sub-samples that hit geometry.
    pub coverage: Vec<f32>,
    /// What the rows belong to and the local lights' columns.
    pub attached: Attached,
}

/// Encoded tiles kept in memory in tile order, with their statistics (energy dropped by
/// thresholding and quantisation, total energy, shadow rays), to be joined into a transport.
#[derive(Default)]
pub struct KeptTiles {
    tiles: Vec<EncodedTile>,
    stats: Vec<[f64; 3]>,
}

impl KeptTiles {
    /// Keeps the next tile.
    pub fn push(&mut self, tile: EncodedTile, stats: [f64; 3]) -> Result<()> {
        self.tiles.push(tile);
        self.stats.push(stats);
        Ok(())
    }

    /// The transport of these tiles and `rest`.
    pub fn into_transport(self, rest: Untiled) -> Result<Transport> {
        Transport::assemble_encoded(
            rest.meta,
            &self.tiles,
            rest.albedo,
            rest.coverage,
            self.stats,
            rest.attached,
        )
    }
}

/// One tile's blocks as the magnitudes read them.
pub(super) struct TileSlices<'a> {
    pub row_weight: &'a [[f32; 3]],
    pub row_scale: &'a [f32],
    /// `[blocks, C]`.
    pub col_count: &'a [u16],
    /// `[blocks, C]`.
    pub col_scale: &'a [u8],
    pub entry_row: &'a [u8],
    /// Values from which the tile's entries start at `first_value`.
    pub values: &'a Values,
    pub first_value: usize,
}

impl EncodedTile {
    /// This tile as [`add_magnitudes`] reads it.
    pub(super) fn slices(&self) -> TileSlices<'_> {
        TileSlices {
            row_weight: &self.row_weight,
            row_scale: &self.row_scale,
            col_count: &self.col_count,
            col_scale: &self.col_scale,
            entry_row: &self.entry_row,
            values: &self.values,
            first_value: 0,
        }
    }
}

/// Adds a tile's `|value| · |weight|` to the per-coefficient sums `magnitude` (C of them), in
/// the order (block, coefficient, row) that makes the bits independent of how tiles are held.
pub(super) fn add_magnitudes(t: &TileSlices, magnitude: &mut [f64]) {
    let c = magnitude.len();
    let mut e = t.first_value;
    for (block, counts) in t.col_count.chunks_exact(c.max(1)).enumerate() {
        let r0 = block * BLOCK_ROWS;
        for (j, (&count, m)) in counts.iter().zip(magnitude.iter_mut()).enumerate() {
            let s = scale_of(t.col_scale[block * c + j]) as f64;
            for _ in 0..count {
                let r = r0 + t.entry_row[e - t.first_value] as usize;
                *m += (t.values.raw(e).abs() as f64 * s * t.row_scale[r] as f64)
                    * crate::math::rgb_magnitude(t.row_weight[r]) as f64;
                e += 1;
            }
        }
    }
}

/// The mean magnitude of each coefficient over `rows` rows, from [`add_magnitudes`]' sums.
pub(super) fn mean_magnitudes(sums: &[f64], rows: usize) -> Vec<f32> {
    sums.iter()
        .map(|m| (m / rows.max(1) as f64) as f32)
        .collect()
}

/// A bake's statistics from its counts and its tiles' (dropped energy, total energy, rays).
pub(super) fn bake_stats(rows: usize, nonzeros: usize, c: usize, tiles: &[[f64; 3]]) -> BakeStats {
    let (mut dropped, mut total, mut rays) = (0.0f64, 0.0f64, 0.0f64);
    for s in tiles {
        dropped += s[0];
        total += s[1];
        rays += s[2];
    }
    BakeStats {
        rows: rows as u64,
        nonzeros: nonzeros as u64,
        dense_entries: (rows * c) as u64,
        dropped_energy_fraction: if total > 0.0 { dropped / total } else { 0.0 },
        shadow_rays: rays as u64,
    }
}
