//! Writing a transport file tile by tile, so that a bake holds none of its rows once a tile is
//! encoded: the tensors that grow with the tiles go to spill files beside the output
//! ([`container::Spill`]), the per-coefficient magnitudes and the statistics are summed as the
//! tiles arrive, and [`TransportWriter::finish`] writes the file from the spills. The file is the
//! one [`Transport::save`] writes for the same tiles, byte for byte.

use std::path::{Path, PathBuf};

use safetensors::tensor::Dtype;

use super::assemble::{add_magnitudes, bake_stats, mean_magnitudes};
use super::file::{FileTables, save_file};
use super::*;
use crate::error::{PrtError, Result};
use crate::store::container::{Spill, Tensor};

/// A transport file being written tile by tile, in tile order.
pub struct TransportWriter {
    path: PathBuf,
    c: usize,
    shc: usize,
    quantization: Quantization,
    tile_row_start: Vec<u32>,
    tile_stats: Vec<[f64; 3]>,
    magnitude: Vec<f64>,
    blocks: usize,
    nonzeros: usize,
    row_pixel: Spill,
    row_weight: Spill,
    row_scale: Spill,
    sh: Spill,
    col_count: Spill,
    col_scale: Spill,
    entry_row: Spill,
    entry_value: Spill,
}

impl TransportWriter {
    /// A writer of the file `path` for tiles of rows over 6 `cube_n`² coefficients with
    /// `sh_order`² SH values, quantised as `quantization` says. Nothing is at `path` until
    /// [`TransportWriter::finish`]; the spills are removed when the writer is dropped.
    pub fn create(
        path: &Path,
        cube_n: usize,
        sh_order: usize,
        quantization: Quantization,
    ) -> Result<Self> {
        crate::files::remove_stale_partials(path);
        let spill = |name: &str| Spill::create(path, name);
        let c = 6 * cube_n * cube_n;
        Ok(TransportWriter {
            path: path.to_path_buf(),
            c,
            shc: sh_order * sh_order,
            quantization,
            tile_row_start: vec![0],
            tile_stats: Vec::new(),
            magnitude: vec![0.0; c],
            blocks: 0,
            nonzeros: 0,
            row_pixel: spill("row_pixel")?,
            row_weight: spill("row_weight")?,
            row_scale: spill("row_scale")?,
            sh: spill("sh")?,
            col_count: spill("col_count")?,
            col_scale: spill("col_scale")?,
            entry_row: spill("entry_row")?,
            entry_value: spill("entry_value")?,
        })
    }

    /// Tiles written so far.
    pub fn tiles_written(&self) -> usize {
        self.tile_stats.len()
    }

    /// Appends the next tile and its statistics (energy dropped by thresholding and
    /// quantisation, total energy, shadow rays). Checks that its tables fit one another before anything is
    /// written, so that a mistake is an error rather than a file that fails to load.
    pub fn push(&mut self, tile: &EncodedTile, stats: [f64; 3]) -> Result<()> {
        let rows = tile.row_pixel.len();
        let blocks = blocks_of(rows);
        let nnz = tile.entry_row.len();
        let counted: usize = tile.col_count.iter().map(|&n| n as usize).sum();
        if tile.values.quantization() != self.quantization
            || tile.row_weight.len() != rows
            || tile.row_scale.len() != rows
            || tile.sh.len() != rows * self.shc
            || tile.col_count.len() != blocks * self.c
            || tile.col_scale.len() != blocks * self.c
            || tile.values.len() != nnz
            || counted != nnz
        {
            return Err(PrtError::file(
                &self.path,
                format!(
                    "tile {}: its tables do not fit one another or the quantisation",
                    self.tiles_written()
                ),
            ));
        }
        let total_rows = *self.tile_row_start.last().unwrap_or(&0) as usize + rows;
        let total_rows = u32::try_from(total_rows)
            .map_err(|_| PrtError::file(&self.path, "more than 2^32 rows"))?;
        self.row_pixel.append(&tile.row_pixel)?;
        self.row_weight.append(&tile.row_weight)?;
        self.row_scale.append(&tile.row_scale)?;
        self.sh.append(&tile.sh)?;
        self.col_count.append(&tile.col_count)?;
        self.col_scale.append(&tile.col_scale)?;
        self.entry_row.append(&tile.entry_row)?;
        match &tile.values {
            Values::Q8(v) => self.entry_value.append(v)?,
            Values::Q16(v) => self.entry_value.append(v)?,
            Values::F32(v) => self.entry_value.append(v)?,
        }
        add_magnitudes(&tile.slices(), &mut self.magnitude);
        self.tile_row_start.push(total_rows);
        self.tile_stats.push(stats);
        self.blocks += blocks;
        self.nonzeros += nnz;
        Ok(())
    }

    /// Writes the file (atomically) once every tile is in, with `rest` (the header's statistics
    /// are filled in here); returns the metadata written.
    pub fn finish(mut self, rest: Untiled) -> Result<TransportMeta> {
        let Untiled {
            mut meta,
            albedo,
            coverage,
            mesh,
            lights,
        } = rest;
        let (w, h) = (meta.width as usize, meta.height as usize);
        let (tx, ty) = tile_grid(w, h);
        if self.tiles_written() != tx * ty
            || albedo.len() != w * h
            || coverage.len() != w * h
            || 6 * (meta.identity.cube_n as usize).pow(2) != self.c
            || (meta.identity.sh_order as usize).pow(2) != self.shc
            || meta.identity.quantization != self.quantization
        {
            return Err(PrtError::file(
                &self.path,
                format!(
                    "{} of the {} tiles of a {w} x {h} image were written, or the header does \
                     not match them",
                    self.tiles_written(),
                    tx * ty
                ),
            ));
        }
        let rows = *self.tile_row_start.last().unwrap_or(&0) as usize;
        meta.stats = bake_stats(rows, self.nonzeros, self.c, &self.tile_stats);
        let magnitude = mean_magnitudes(&self.magnitude, rows);
        let (c, b, nnz) = (self.c, self.blocks, self.nonzeros);
        for s in [
            &mut self.row_pixel,
            &mut self.row_weight,
            &mut self.row_scale,
            &mut self.sh,
            &mut self.col_count,
            &mut self.col_scale,
            &mut self.entry_row,
            &mut self.entry_value,
        ] {
            s.flush()?;
        }
        let value_type = match self.quantization {
            Quantization::Q8 => Dtype::I8,
            Quantization::Q16 => Dtype::I16,
            Quantization::F32 => Dtype::F32,
        };
        let grown = vec![
            (
                "row_pixel",
                Tensor::spilled(Dtype::U32, vec![rows], &self.row_pixel)?,
            ),
            (
                "row_weight",
                Tensor::spilled(Dtype::F32, vec![rows, 3], &self.row_weight)?,
            ),
            (
                "row_scale",
                Tensor::spilled(Dtype::F32, vec![rows], &self.row_scale)?,
            ),
            (
                "col_count",
                Tensor::spilled(Dtype::U16, vec![b, c], &self.col_count)?,
            ),
            (
                "col_scale",
                Tensor::spilled(Dtype::U8, vec![b, c], &self.col_scale)?,
            ),
            (
                "entry_row",
                Tensor::spilled(Dtype::U8, vec![nnz], &self.entry_row)?,
            ),
            (
                "sh",
                Tensor::spilled(Dtype::F32, vec![rows, self.shc], &self.sh)?,
            ),
            (
                "entry_value",
                Tensor::spilled(value_type, vec![nnz], &self.entry_value)?,
            ),
        ];
        save_file(
            &self.path,
            &meta,
            grown,
            &FileTables {
                tile_row_start: &self.tile_row_start,
                albedo: &albedo,
                coverage: &coverage,
                transport_magnitude: &magnitude,
                tile_stats: &self.tile_stats,
                mesh: mesh.as_ref(),
                lights: &lights,
            },
        )?;
        Ok(meta)
    }
}
