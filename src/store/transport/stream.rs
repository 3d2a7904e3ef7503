//! Writing a transport file tile by tile, so that a bake holds no more of its rows than one
//! group of tile rows: the tensors that grow with the tiles go to spill files beside the output
//! ([`container::Spill`]), a tile's rows as it arrives and a group's strips once its last tile
//! row is in ([`super::strips`]); the per-coefficient magnitudes and the statistics are summed
//! as the tiles arrive, and [`TransportWriter::finish`] writes the file from the spills. The
//! file is the one [`Transport::save`] writes for the same tiles, byte for byte.

use std::path::{Path, PathBuf};

use safetensors::tensor::Dtype;

use super::assemble::{self, add_magnitudes, bake_stats, mean_magnitudes};
use super::groups::{MatrixTensors, RowTensors, ShTensor};
use super::save::{FileTables, save_file};
use super::*;
use crate::error::{PrtError, Result};
use crate::store::container::{Spill, Tensor};

/// A transport file being written tile by tile, in tile order.
pub struct TransportWriter {
    path: PathBuf,
    c: usize,
    shc: usize,
    quantization: Quantization,
    image: (usize, usize),
    tiles_x: usize,
    tile_row_start: Vec<u32>,
    tile_stats: Vec<[f64; 3]>,
    magnitude: Vec<f64>,
    blocks: usize,
    nonzeros: usize,
    strips: usize,
    /// The tiles of the group of tile rows under way, and their blocks.
    group: Vec<EncodedTile>,
    group_blocks: usize,
    row_pixel: Spill,
    row_weight: Spill,
    row_scale: Spill,
    sh: Spill,
    strip_count: Spill,
    col_scale: Spill,
    strip_place: Spill,
    strip_value: Spill,
}

impl TransportWriter {
    /// A writer of the file `path` for an image of `image` (width, height) pixels, whose tiles
    /// hold rows over 6 `cube_n`² coefficients with `sh_order`² SH values, quantised as
    /// `quantization` says. Nothing is at `path` until [`TransportWriter::finish`]; the spills
    /// are removed when the writer is dropped.
    pub fn create(
        path: &Path,
        image: (usize, usize),
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
            image,
            tiles_x: tile_grid(image.0, image.1).0,
            tile_row_start: vec![0],
            tile_stats: Vec::new(),
            magnitude: vec![0.0; c],
            blocks: 0,
            nonzeros: 0,
            strips: 0,
            group: Vec::new(),
            group_blocks: 0,
            row_pixel: spill(RowTensors::PIXEL)?,
            row_weight: spill(RowTensors::WEIGHT)?,
            row_scale: spill(RowTensors::SCALE)?,
            sh: spill(ShTensor::NAME)?,
            strip_count: spill(MatrixTensors::STRIP_COUNT)?,
            col_scale: spill(MatrixTensors::COL_SCALE)?,
            strip_place: spill(MatrixTensors::STRIP_PLACE)?,
            strip_value: spill(MatrixTensors::STRIP_VALUE)?,
        })
    }

    /// Tiles written so far.
    pub fn tiles_written(&self) -> usize {
        self.tile_stats.len()
    }

    /// Appends the next tile and its statistics (energy dropped by thresholding and
    /// quantisation, total energy, shadow rays). Checks that its tables fit one another before
    /// anything is written, so that a mistake is an error rather than a file that fails to load.
    pub fn push(&mut self, tile: &EncodedTile, stats: [f64; 3]) -> Result<()> {
        let rows = tile.row_pixel.len();
        let (tx, ty) = tile_grid(self.image.0, self.image.1);
        let refuse = |why: String| {
            PrtError::file(&self.path, format!("tile {}: {why}", self.tiles_written()))
        };
        if tile.sh.len() != rows * self.shc {
            return Err(refuse("its SH table does not fit its rows".into()));
        }
        tile.check(self.c, self.quantization).map_err(refuse)?;
        if self.tiles_written() >= tx * ty {
            return Err(refuse(format!(
                "a {} x {} image has only {} tiles",
                self.image.0,
                self.image.1,
                tx * ty
            )));
        }
        let total_rows = *self.tile_row_start.last().unwrap_or(&0) as usize + rows;
        let total_rows = u32::try_from(total_rows)
            .map_err(|_| PrtError::file(&self.path, "more than 2^32 rows"))?;
        self.row_pixel.append(&tile.row_pixel)?;
        self.row_weight.append(&tile.row_weight)?;
        self.row_scale.append(&tile.row_scale)?;
        self.sh.append(&tile.sh)?;
        add_magnitudes(&tile.slices(), &mut self.magnitude);
        self.tile_row_start.push(total_rows);
        self.tile_stats.push(stats);
        self.blocks += blocks_of(rows);
        self.group_blocks += blocks_of(rows);
        self.nonzeros += tile.entry_row.len();
        self.group.push(tile.clone());
        // A group closes at the end of a tile row once it holds a band's blocks, and at the
        // image's end ([`strips::Layout::of`]).
        let written = self.tiles_written();
        if written.is_multiple_of(self.tiles_x)
            && (self.group_blocks >= strips::BAND_BLOCKS || written == tx * ty)
        {
            self.write_group()?;
        }
        Ok(())
    }

    /// Lays out the group's strips and appends them to the spills.
    fn write_group(&mut self) -> Result<()> {
        let group = std::mem::take(&mut self.group);
        let mut tile_block_start = vec![0u32];
        for t in &group {
            let last = *tile_block_start.last().unwrap_or(&0);
            tile_block_start.push(last + blocks_of(t.row_pixel.len()) as u32);
        }
        let strips = assemble::strips_of_tiles(
            &group,
            &tile_block_start,
            self.tiles_x,
            self.c,
            self.quantization,
        )
        .map_err(|m| PrtError::file(&self.path, m))?;
        let (counts, codes) = strips.slot_tables();
        self.strip_count.append(&counts)?;
        self.col_scale.append(&codes)?;
        self.strip_place.append(&strips.index)?;
        match &strips.values {
            Values::Q8(v) => self.strip_value.append(v)?,
            Values::Q16(v) => self.strip_value.append(v)?,
            Values::F32(v) => self.strip_value.append(v)?,
        }
        self.strips += strips.strip_count();
        self.group_blocks = 0;
        Ok(())
    }

    /// Writes the file (atomically) once every tile is in, with `rest` (the header's statistics
    /// are filled in here); returns the metadata written.
    pub fn finish(mut self, rest: Untiled) -> Result<TransportMeta> {
        let Untiled {
            mut meta,
            albedo,
            coverage,
            attached,
        } = rest;
        let (w, h) = (meta.width as usize, meta.height as usize);
        let (tx, ty) = tile_grid(w, h);
        if self.tiles_written() != tx * ty
            || (w, h) != self.image
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
        let (c, b, s) = (self.c, self.blocks, self.strips);
        for spill in [
            &mut self.row_pixel,
            &mut self.row_weight,
            &mut self.row_scale,
            &mut self.sh,
            &mut self.strip_count,
            &mut self.col_scale,
            &mut self.strip_place,
            &mut self.strip_value,
        ] {
            spill.flush()?;
        }
        let value_type = match self.quantization {
            Quantization::Q8 => Dtype::I8,
            Quantization::Q16 => Dtype::I16,
            Quantization::F32 => Dtype::F32,
        };
        let grown = vec![
            (
                RowTensors::PIXEL,
                Tensor::spilled(Dtype::U32, vec![rows], &self.row_pixel)?,
            ),
            (
                RowTensors::WEIGHT,
                Tensor::spilled(Dtype::F32, vec![rows, 3], &self.row_weight)?,
            ),
            (
                RowTensors::SCALE,
                Tensor::spilled(Dtype::F32, vec![rows], &self.row_scale)?,
            ),
            (
                ShTensor::NAME,
                Tensor::spilled(Dtype::F32, vec![rows, self.shc], &self.sh)?,
            ),
            (
                MatrixTensors::STRIP_COUNT,
                Tensor::spilled(Dtype::U8, vec![b, c], &self.strip_count)?,
            ),
            (
                MatrixTensors::COL_SCALE,
                Tensor::spilled(Dtype::U8, vec![b, c], &self.col_scale)?,
            ),
            (
                MatrixTensors::STRIP_PLACE,
                Tensor::spilled(Dtype::U8, vec![s], &self.strip_place)?,
            ),
            (
                MatrixTensors::STRIP_VALUE,
                Tensor::spilled(value_type, vec![s, strips::STRIP_ROWS], &self.strip_value)?,
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
                attached: &attached,
            },
        )?;
        Ok(meta)
    }
}
