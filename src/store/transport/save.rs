//! Writing the transport file (format version 9, laid out in the [module docs](super)): a whole
//! transport in memory, or the tensors a streamed bake spilled ([`super::TransportWriter`]),
//! both through [`save_file`], so the same content gives the same bytes.

use std::path::Path;

use safetensors::tensor::Dtype;

use super::file::{FileHeader, tensor_names};
use super::strips::STRIP_ROWS;
use super::*;
use crate::error::{PrtError, Result};
use crate::scene::visibility::Visibility;
use crate::store::container::{self, Tensor};

impl Transport {
    /// Writes the file atomically: a temporary file beside `path`, then a rename.
    pub fn save(&self, path: &Path) -> Result<()> {
        let r = self.row_pixel.len();
        let (counts, codes) = self.strips.slot_tables();
        let mut grown = vec![
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
            (
                "sh",
                Tensor::new(Dtype::F32, vec![r, self.sh_count()], &self.sh),
            ),
        ];
        grown.extend(strip_tensors(
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
                mesh: self.domain.mesh(),
                lights: &self.lights,
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
    pub mesh: Option<&'a VertexMesh>,
    pub lights: &'a LightColumns,
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
    let tiles = tables.tile_stats.len();
    let c = tables.transport_magnitude.len();
    tensors.extend([
        (
            "tile_row_start",
            Tensor::new(Dtype::U32, vec![tiles + 1], tables.tile_row_start),
        ),
        (
            "albedo",
            Tensor::new(Dtype::F32, vec![h, w, 3], tables.albedo),
        ),
        (
            "coverage",
            Tensor::new(Dtype::F32, vec![h, w], tables.coverage),
        ),
        (
            "transport_magnitude",
            Tensor::new(Dtype::F32, vec![c], tables.transport_magnitude),
        ),
        (
            "tile_stats",
            Tensor::new(Dtype::F64, vec![tiles, 3], tables.tile_stats),
        ),
    ]);
    // A textured mesh's maps: their table and level-0 texels.
    let textured = tables.mesh.filter(|m| !m.albedo_maps.is_empty());
    let (map_table, map_materials, map_texels) = textured
        .map_or((Vec::new(), Vec::new(), Vec::new()), |m| {
            crate::scene::albedo_map::to_table(&m.albedo_maps)
        });
    let mut tensors: Vec<(&str, Tensor)> = tensors;
    if let Some(mesh) = textured {
        tensors.extend([
            (
                "albedo_map",
                Tensor::new(Dtype::U32, vec![map_table.len(), 5], &map_table),
            ),
            (
                "albedo_map_material",
                Tensor::new(Dtype::U32, vec![map_materials.len(), 2], &map_materials),
            ),
            (
                "albedo_texel",
                Tensor::new(Dtype::U16, vec![map_texels.len(), 3], &map_texels),
            ),
            (
                "mesh_uv",
                Tensor::new(Dtype::F32, vec![mesh.vertex_count(), 2], &mesh.uvs),
            ),
        ]);
    }
    if let Some(vis) = tables.mesh.and_then(|m| m.visibility.as_ref()) {
        tensors.extend(visibility_tensors(vis));
    }
    if let Some(mesh) = tables.mesh {
        let (v, t) = (mesh.vertex_count(), mesh.triangles.len());
        tensors.extend([
            (
                "mesh_position",
                Tensor::new(Dtype::F32, vec![v, 3], &mesh.positions),
            ),
            (
                "mesh_normal",
                Tensor::new(Dtype::F32, vec![v, 3], &mesh.normals),
            ),
            (
                "mesh_material",
                Tensor::new(Dtype::U32, vec![v], &mesh.materials),
            ),
            (
                "mesh_triangle",
                Tensor::new(Dtype::U32, vec![t, 3], &mesh.triangles),
            ),
        ]);
    }
    let columns = meta.light_columns();
    if tables.lights.problem(columns).is_some() {
        return Err(PrtError::file(
            path,
            "the light columns to write do not match the header's lights",
        ));
    }
    if columns > 0 {
        tensors.extend([
            (
                "light_scale",
                Tensor::new(Dtype::F32, vec![columns, h], &tables.lights.scale),
            ),
            (
                "light_value",
                Tensor::new(Dtype::U16, vec![columns, 3, h, w], &tables.lights.values),
            ),
        ]);
    }
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

/// The tensors of a glossy mesh's visibility: its bits, the materials' lobes and the vertices.
fn visibility_tensors(vis: &Visibility) -> [(&'static str, Tensor<'_>); 3] {
    let rows = vis.vertices.len();
    [
        (
            "visibility_bits",
            Tensor::new(Dtype::U32, vec![rows, Visibility::words(vis.n)], &vis.bits),
        ),
        (
            "visibility_lobe",
            Tensor::new(Dtype::F32, vec![vis.lobes.len(), 4], &vis.lobes),
        ),
        (
            "visibility_vertex",
            Tensor::new(Dtype::U32, vec![rows], &vis.vertices),
        ),
    ]
}

/// The tensors of a Haar matrix in strips: `strip_count` and `col_scale` of shape `slots`
/// ([B, C]), the strips' places and their values.
pub(super) fn strip_tensors<'a>(
    slots: [usize; 2],
    counts: &'a [u8],
    codes: &'a [u8],
    index: &'a [u8],
    values: &'a Values,
) -> [(&'static str, Tensor<'a>); 4] {
    let s = index.len();
    [
        (
            "strip_count",
            Tensor::new(Dtype::U8, slots.to_vec(), counts),
        ),
        ("col_scale", Tensor::new(Dtype::U8, slots.to_vec(), codes)),
        ("strip_place", Tensor::new(Dtype::U8, vec![s], index)),
        match values {
            Values::Q8(v) => (
                "strip_value",
                Tensor::new(Dtype::I8, vec![s, STRIP_ROWS], v),
            ),
            Values::Q16(v) => (
                "strip_value",
                Tensor::new(Dtype::I16, vec![s, STRIP_ROWS], v),
            ),
            Values::F32(v) => (
                "strip_value",
                Tensor::new(Dtype::F32, vec![s, STRIP_ROWS], v),
            ),
        },
    ]
}
