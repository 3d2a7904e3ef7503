//! Every tensor of a transport file read straight into its table, in name order (the order the
//! checksum covers them), with its shape: the tables a file of its kind and version lacks are
//! `None`. Shapes are checked by the loader once the checksum has passed.

use safetensors::tensor::Dtype;

use super::reader::TensorReader;
use super::{Quantization, TransportMeta, Values};
use crate::error::Result;

/// A tensor as read: its shape and its values.
pub(super) type Tensor<T> = (Vec<usize>, Vec<T>);
/// The visibility's bits, lobes and vertices, as read.
pub(super) type VisibilityTensors = (Tensor<u32>, Tensor<[f32; 4]>, Tensor<u32>);
/// A mesh's vertex materials, normals and positions, and its triangles, as read.
pub(super) type MeshTensors = (
    Tensor<u32>,
    Tensor<glam::Vec3>,
    Tensor<glam::Vec3>,
    Tensor<[u32; 3]>,
);
/// The albedo maps' table, their materials and their texels, as read.
pub(super) type MapTensors = (Tensor<[u32; 5]>, Tensor<[u32; 2]>, Tensor<[u16; 3]>);

/// Stored values as read: their shape and values.
pub(super) type ValueTensor = (Vec<usize>, Values);

/// Every tensor of a transport file, as read (see the module's notes).
pub(super) struct FileTensors {
    pub(super) albedo: Tensor<[f32; 3]>,
    pub(super) map_tables: Option<MapTensors>,
    /// Versions 3 to 6: the columns' entry counts.
    pub(super) col_count: Option<Tensor<u16>>,
    pub(super) col_scale: Tensor<u8>,
    pub(super) coverage: Tensor<f32>,
    /// Versions 3 to 6: the columns' entries' rows and values.
    pub(super) entries: Option<(Tensor<u8>, ValueTensor)>,
    pub(super) light_tables: Option<(Tensor<f32>, Tensor<u16>)>,
    pub(super) mesh: Option<MeshTensors>,
    pub(super) mesh_uv: Option<Tensor<glam::Vec2>>,
    pub(super) row_pixel: Tensor<u32>,
    pub(super) row_scale: Tensor<f32>,
    pub(super) row_weight: Tensor<[f32; 3]>,
    pub(super) sh: Tensor<f32>,
    /// Versions 7 to 9: the strips' counts, places and values.
    pub(super) strip_tables: Option<(Tensor<u8>, Tensor<u8>, ValueTensor)>,
    pub(super) tile_row_start: Tensor<u32>,
    pub(super) tile_stats: Tensor<[f64; 3]>,
    pub(super) transport_magnitude: Tensor<f32>,
    pub(super) visibility: Option<VisibilityTensors>,
}

/// Reads every tensor that a file of format `version` with metadata `meta` holds, in name order.
pub(super) fn read_all(
    reader: &mut TensorReader,
    meta: &TransportMeta,
    version: u32,
) -> Result<FileTensors> {
    let albedo = reader.read::<[f32; 3]>("albedo", Dtype::F32)?;
    let map_count = meta
        .per_vertex
        .as_ref()
        .map_or(0, |p| p.albedo_maps as usize);
    let map_tables = if map_count > 0 {
        Some((
            reader.read::<[u32; 5]>("albedo_map", Dtype::U32)?,
            reader.read::<[u32; 2]>("albedo_map_material", Dtype::U32)?,
            reader.read::<[u16; 3]>("albedo_texel", Dtype::U16)?,
        ))
    } else {
        None
    };
    // Versions 3 to 6 store columns (`col_count`, `entry_row`, `entry_value`), versions 7 to 9
    // strips; `col_scale` is in both.
    let legacy = version < 7;
    let col_count = if legacy {
        Some(reader.read::<u16>("col_count", Dtype::U16)?)
    } else {
        None
    };
    let col_scale = reader.read::<u8>("col_scale", Dtype::U8)?;
    let coverage = reader.read::<f32>("coverage", Dtype::F32)?;
    let entries = if legacy {
        Some((
            reader.read::<u8>("entry_row", Dtype::U8)?,
            read_values(reader, "entry_value", meta.identity.quantization)?,
        ))
    } else {
        None
    };
    let columns = meta.light_columns();
    let light_tables = if columns > 0 {
        Some((
            reader.read::<f32>("light_scale", Dtype::F32)?,
            reader.read::<u16>("light_value", Dtype::U16)?,
        ))
    } else {
        None
    };
    let mesh = match &meta.per_vertex {
        None => None,
        Some(_) => Some((
            reader.read::<u32>("mesh_material", Dtype::U32)?,
            reader.read::<glam::Vec3>("mesh_normal", Dtype::F32)?,
            reader.read::<glam::Vec3>("mesh_position", Dtype::F32)?,
            reader.read::<[u32; 3]>("mesh_triangle", Dtype::U32)?,
        )),
    };
    let mesh_uv = if map_count > 0 {
        Some(reader.read::<glam::Vec2>("mesh_uv", Dtype::F32)?)
    } else {
        None
    };
    let row_pixel = reader.read::<u32>("row_pixel", Dtype::U32)?;
    let row_scale = reader.read::<f32>("row_scale", Dtype::F32)?;
    let row_weight = reader.read::<[f32; 3]>("row_weight", Dtype::F32)?;
    let sh = reader.read::<f32>("sh", Dtype::F32)?;
    let strip_tables = if legacy {
        None
    } else {
        Some((
            reader.read::<u8>("strip_count", Dtype::U8)?,
            reader.read::<u8>("strip_place", Dtype::U8)?,
            read_values(reader, "strip_value", meta.identity.quantization)?,
        ))
    };
    let tile_row_start = reader.read::<u32>("tile_row_start", Dtype::U32)?;
    let tile_stats = reader.read::<[f64; 3]>("tile_stats", Dtype::F64)?;
    let transport_magnitude = reader.read::<f32>("transport_magnitude", Dtype::F32)?;
    let visibility = if meta.identity.visibility {
        Some((
            reader.read::<u32>("visibility_bits", Dtype::U32)?,
            reader.read::<[f32; 4]>("visibility_lobe", Dtype::F32)?,
            reader.read::<u32>("visibility_vertex", Dtype::U32)?,
        ))
    } else {
        None
    };
    Ok(FileTensors {
        albedo,
        map_tables,
        col_count,
        col_scale,
        coverage,
        entries,
        light_tables,
        mesh,
        mesh_uv,
        row_pixel,
        row_scale,
        row_weight,
        sh,
        strip_tables,
        tile_row_start,
        tile_stats,
        transport_magnitude,
        visibility,
    })
}

/// Tensor `name` of stored values in quantisation `q`: its shape and values.
pub(super) fn read_values(
    reader: &mut TensorReader,
    name: &str,
    q: Quantization,
) -> Result<ValueTensor> {
    Ok(match q {
        Quantization::Q8 => {
            let (s, v) = reader.read(name, Dtype::I8)?;
            (s, Values::Q8(v))
        }
        Quantization::Q16 => {
            let (s, v) = reader.read(name, Dtype::I16)?;
            (s, Values::Q16(v))
        }
        Quantization::F32 => {
            let (s, v) = reader.read(name, Dtype::F32)?;
            (s, Values::F32(v))
        }
    })
}
