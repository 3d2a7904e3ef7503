//! Writing the transport file (format version 9, laid out in the [module docs](super)): a whole
//! transport in memory, or the tensors a streamed bake spilled ([`super::TransportWriter`]),
//! both through [`save_file`], so the same content gives the same bytes.

use std::path::Path;

use safetensors::tensor::Dtype;

use super::file::FileHeader;
use super::groups::{
    AttachedTables, MatrixTensors, PixelTensors, RowTensors, ShTensor, tensor_names,
};
use super::*;
use crate::error::{PrtError, Result};
use crate::store::container::{self, Tensor};

impl Transport {
    /// Writes the file atomically: a temporary file beside `path`, then a rename.
    pub fn save(&self, path: &Path) -> Result<()> {
        let r = self.row_pixel.len();
        let (counts, codes) = self.strips.slot_tables();
        let mut grown = vec![
            (
                RowTensors::PIXEL,
                Tensor::new(Dtype::U32, vec![r], &self.row_pixel),
            ),
            (
                RowTensors::WEIGHT,
                Tensor::new(Dtype::F32, vec![r, 3], &self.row_weight),
            ),
            (
                RowTensors::SCALE,
                Tensor::new(Dtype::F32, vec![r], &self.row_scale),
            ),
            (
                ShTensor::NAME,
                Tensor::new(Dtype::F32, vec![r, self.sh_count()], &self.sh),
            ),
        ];
        grown.extend(MatrixTensors::write(
            [self.block_count(), self.coeff_count()],
            &counts,
            &codes,
            &self.strips.index,
            &self.strips.values,
        ));
        save_file(
            path,
            &self.meta,
            grown,
            &FileTables {
                tile_row_start: &self.tile_row_start,
                albedo: &self.albedo,
                coverage: &self.coverage,
                transport_magnitude: &self.transport_magnitude,
                tile_stats: &self.tile_stats,
                attached: &self.attached,
            },
        )
    }
}

/// The tensors of a file that are one table for the whole image (or mesh), whichever way the
/// tiles' tensors are held.
pub(super) struct FileTables<'a> {
    pub tile_row_start: &'a [u32],
    pub albedo: &'a [[f32; 3]],
    pub coverage: &'a [f32],
    pub transport_magnitude: &'a [f32],
    pub tile_stats: &'a [[f64; 3]],
    pub attached: &'a Attached,
}

/// Writes a transport file atomically from `grown`, the eight tensors that grow tile by tile
/// (`row_*`, `sh`, `strip_*` and `col_scale`, in memory or spilled), and the whole-image
/// `tables`.
/// [`Transport::save`] and the streamed bake ([`super::TransportWriter`]) both come here, so
/// the same content gives the same bytes.
pub(super) fn save_file<'a>(
    path: &Path,
    meta: &TransportMeta,
    mut tensors: Vec<(&'a str, Tensor<'a>)>,
    tables: &FileTables<'a>,
) -> Result<()> {
    let (w, h) = (meta.width as usize, meta.height as usize);
    let c = tables.transport_magnitude.len();
    tensors.extend(RowTensors::write_tiles(
        tables.tile_row_start,
        tables.tile_stats,
    ));
    tensors.extend(PixelTensors::write(
        [w, h, c],
        tables.albedo,
        tables.coverage,
        tables.transport_magnitude,
    ));
    // What the attached parts are written from lives in this call: the tensors borrow it.
    let attached = AttachedTables::of(tables.attached);
    let mut tensors: Vec<(&str, Tensor)> = tensors;
    tensors.extend(attached.write(meta, path)?);
    tensors.sort_by_key(|(name, _)| *name);
    if !tensors
        .iter()
        .map(|(n, _)| *n)
        .eq(tensor_names(FORMAT_VERSION, meta))
    {
        return Err(PrtError::file(
            path,
            "the tensors to write are not those of a transport file",
        ));
    }
    // One metadata key, so the header is the same bytes for the same content (the
    // container keeps its metadata in a hash map, whose order varies between runs).
    container::save(path, tensors, |checksum| {
        serde_json::to_string(&FileHeader {
            format: FORMAT_NAME.to_string(),
            format_version: FORMAT_VERSION,
            checksum,
            meta: meta.clone(),
        })
    })
}
