//! The parts of a transport file, each a group of tensors stored together or not at all: the
//! pixel tables, the rows, their SH, the Haar matrix (strips, or columns before version 7), a
//! per-vertex bake's mesh, its albedo maps and its visibility, and the local lights' columns.
//! Each group names its tensors once, says when a file holds it, reads them and, where its
//! shapes need nothing of the other groups, checks and writes them. A load reads every group's
//! tensors interleaved, in the name order the checksum covers ([`plan`]).

use std::path::Path;

use safetensors::tensor::Dtype;

/// A group's [`ReadGroup`] that reads each of its tensors, by name, into its own field, as
/// stored: `read_group!(Group { NAME => field: Dtype, ... })`.
macro_rules! read_group {
    ($group:ty { $($name:ident => $field:ident: $dtype:ident),+ $(,)? }) => {
        impl ReadGroup for $group {
            fn read(
                &mut self,
                name: &str,
                reader: &mut TensorReader,
                _: &TransportMeta,
            ) -> Result<()> {
                match name {
                    $(Self::$name => self.$field = Some(reader.read(name, Dtype::$dtype)?),)+
                    _ => return Err(not_mine(name)),
                }
                Ok(())
            }
        }
    };
}

mod matrix;
mod mesh;

pub(super) use matrix::MatrixTensors;
pub(super) use mesh::mesh_values_problem;
use mesh::{MapTensors, MeshTensors, VisibilityTensors};

use super::reader::TensorReader;
use super::{Attached, Domain, LightColumns, TransportMeta, Values};
use crate::error::{PrtError, Result};
use crate::store::container::Tensor as Out;

/// A tensor as read: its shape and its values.
pub(super) type Tensor<T> = (Vec<usize>, Vec<T>);
/// Stored values as read: their shape and values.
pub(super) type ValueTensor = (Vec<usize>, Values);
/// Checks a tensor's shape against what it must be: (name, shape, expected).
pub(super) type ShapeCheck<'a> = &'a dyn Fn(&str, &[usize], &[usize]) -> Result<()>;

/// The groups of a transport file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Group {
    Pixels,
    Rows,
    Sh,
    Matrix,
    Mesh,
    Maps,
    Visibility,
    Lights,
}

impl Group {
    const ALL: [Group; 8] = [
        Group::Pixels,
        Group::Rows,
        Group::Sh,
        Group::Matrix,
        Group::Mesh,
        Group::Maps,
        Group::Visibility,
        Group::Lights,
    ];

    /// The group's tensors in a file of `version` with `meta`: none where the file has no such
    /// part.
    fn names(self, meta: &TransportMeta, version: u32) -> &'static [&'static str] {
        let pv = meta.per_vertex.as_ref();
        let stored = match self {
            Group::Pixels | Group::Rows | Group::Sh | Group::Matrix => true,
            Group::Mesh => pv.is_some(),
            Group::Maps => pv.is_some_and(|p| p.albedo_maps > 0),
            Group::Visibility => pv.is_some() && meta.identity.visibility,
            Group::Lights => meta.light_columns() > 0,
        };
        match (stored, self) {
            (false, _) => &[],
            (_, Group::Pixels) => &PixelTensors::NAMES,
            (_, Group::Rows) => &RowTensors::NAMES,
            (_, Group::Sh) => &[ShTensor::NAME],
            (_, Group::Matrix) if version < 7 => &MatrixTensors::COLUMN_NAMES,
            (_, Group::Matrix) => &MatrixTensors::STRIP_NAMES,
            (_, Group::Mesh) => &MeshTensors::NAMES,
            (_, Group::Maps) => &MapTensors::NAMES,
            (_, Group::Visibility) if version >= 10 && meta.light_columns() > 0 => {
                &VisibilityTensors::LIT_NAMES
            }
            (_, Group::Visibility) => &VisibilityTensors::NAMES,
            (_, Group::Lights) => &LightTensors::NAMES,
        }
    }
}

/// Every tensor of a file of `version` with `meta` and its group, in name order: the order the
/// checksum covers them, and so the order a load reads them.
pub(super) fn plan(meta: &TransportMeta, version: u32) -> Vec<(&'static str, Group)> {
    let mut plan: Vec<(&'static str, Group)> = Group::ALL
        .iter()
        .flat_map(|&g| g.names(meta, version).iter().map(move |&n| (n, g)))
        .collect();
    plan.sort();
    plan
}

/// The names of [`plan`].
pub(super) fn tensor_names(version: u32, meta: &TransportMeta) -> Vec<&'static str> {
    plan(meta, version).into_iter().map(|(n, _)| n).collect()
}

/// A group's tensors as they are read, one by one.
trait ReadGroup {
    /// Reads tensor `name`, one of the group's, from `reader`.
    fn read(&mut self, name: &str, reader: &mut TensorReader, meta: &TransportMeta) -> Result<()>;
}

/// An error for a tensor a group does not hold (the plan and the group disagree).
fn not_mine(name: &str) -> PrtError {
    PrtError::invalid("transport file", format!("tensor `{name}` of no group"))
}

/// `t`, which the plan read, or an error naming it.
pub(super) fn taken<T>(t: Option<T>, name: &str) -> Result<T> {
    t.ok_or_else(|| PrtError::invalid("transport file", format!("tensor `{name}` was not read")))
}

/// Every tensor of a transport file, as read, by group.
#[derive(Default)]
pub(super) struct FileTensors {
    pub(super) pixels: PixelTensors,
    pub(super) rows: RowTensors,
    pub(super) sh: ShTensor,
    pub(super) matrix: MatrixTensors,
    /// The groups of the parts stored beside the rows ([`Attached`]).
    pub(super) attached: AttachedTensors,
}

impl FileTensors {
    fn group(&mut self, g: Group) -> &mut dyn ReadGroup {
        let a = &mut self.attached;
        match g {
            Group::Pixels => &mut self.pixels,
            Group::Rows => &mut self.rows,
            Group::Sh => &mut self.sh,
            Group::Matrix => &mut self.matrix,
            Group::Mesh => &mut a.mesh,
            Group::Maps => &mut a.maps,
            Group::Visibility => &mut a.visibility,
            Group::Lights => &mut a.lights,
        }
    }
}

/// The tensors of the parts a file stores beside its rows and per-pixel tables, as read.
#[derive(Default)]
pub(super) struct AttachedTensors {
    mesh: MeshTensors,
    maps: MapTensors,
    visibility: VisibilityTensors,
    lights: LightTensors,
}

impl AttachedTensors {
    /// The parts these tensors hold, for a file with `meta` (each shape checked by `expect`,
    /// other errors by `bad`).
    pub(super) fn into_attached(
        self,
        meta: &TransportMeta,
        expect: ShapeCheck,
        bad: &dyn Fn(String) -> PrtError,
    ) -> Result<Attached> {
        let (w, h) = (meta.width as usize, meta.height as usize);
        let columns = meta.light_columns();
        let lights = self.lights.into_columns((columns, w, h), expect)?;
        let mesh = match &meta.per_vertex {
            Some(pv) => {
                let maps = (pv, pv.albedo_maps as usize);
                self.mesh.into_mesh(self.maps, maps, expect, bad)?
            }
            None => None,
        };
        let mesh = self
            .visibility
            .attach(mesh, (meta.identity.cube_n as usize, columns), expect)
            .map_err(|e| bad(e.to_string()))?;
        Ok(Attached {
            domain: Domain::from_mesh(mesh),
            lights,
        })
    }
}

/// The attached parts to write, with what their tensors are written from beyond the parts
/// themselves: a textured mesh's maps as one table. The tensors borrow it, so it lives in the
/// writer's call.
pub(super) struct AttachedTables<'a> {
    attached: &'a Attached,
    maps: Option<crate::scene::albedo_map::FileTables>,
}

impl<'a> AttachedTables<'a> {
    /// The tables `attached` is written with.
    pub(super) fn of(attached: &'a Attached) -> Self {
        let textured = attached.domain.mesh().filter(|m| !m.albedo_maps.is_empty());
        AttachedTables {
            attached,
            maps: textured.map(|m| crate::scene::albedo_map::to_table(&m.albedo_maps)),
        }
    }

    /// The parts' tensors to write into the file `path` with header `meta` (read by this file's
    /// reader as [`AttachedTensors::into_attached`] reads them), or an error where the parts and
    /// the header disagree.
    pub(super) fn write(
        &'a self,
        meta: &TransportMeta,
        path: &Path,
    ) -> Result<Vec<(&'static str, Out<'a>)>> {
        let mut tensors = Vec::new();
        let attached = self.attached;
        let mesh = attached.domain.mesh();
        if let Some((mesh, maps)) = mesh.zip(self.maps.as_ref()) {
            tensors.extend(MapTensors::write(mesh, maps));
        }
        if let Some(vis) = mesh.and_then(|m| m.visibility.as_ref()) {
            if vis.columns != meta.light_columns() {
                return Err(PrtError::file(
                    path,
                    format!(
                        "the glossy vertices keep shares of {} light columns, the header has {}: \
                         a glossy bake with lights from before format version 10 is drawn as it \
                         loads, but is written only when baked again",
                        vis.columns,
                        meta.light_columns()
                    ),
                ));
            }
            tensors.extend(VisibilityTensors::write(vis));
        }
        if let Some(mesh) = mesh {
            tensors.extend(MeshTensors::write(mesh));
        }
        let columns = meta.light_columns();
        if attached.lights.problem(columns).is_some() {
            return Err(PrtError::file(
                path,
                "the light columns to write do not match the header's lights",
            ));
        }
        if columns > 0 {
            let (w, h) = (meta.width as usize, meta.height as usize);
            tensors.extend(LightTensors::write(&attached.lights, (columns, w, h)));
        }
        Ok(tensors)
    }
}

/// Reads every tensor that a file of format `version` with metadata `meta` holds, in name order,
/// each into its group.
pub(super) fn read_all(
    reader: &mut TensorReader,
    meta: &TransportMeta,
    version: u32,
) -> Result<FileTensors> {
    let mut t = FileTensors::default();
    for (name, g) in plan(meta, version) {
        t.group(g).read(name, reader, meta)?;
    }
    Ok(t)
}

/// The per-pixel tables: the albedo seen, the coverage, and each coefficient's mean magnitude.
#[derive(Default)]
pub(super) struct PixelTensors {
    pub(super) albedo: Option<Tensor<[f32; 3]>>,
    pub(super) coverage: Option<Tensor<f32>>,
    pub(super) magnitude: Option<Tensor<f32>>,
}

impl PixelTensors {
    pub(super) const ALBEDO: &str = "albedo";
    pub(super) const COVERAGE: &str = "coverage";
    pub(super) const MAGNITUDE: &str = "transport_magnitude";
    const NAMES: [&str; 3] = [Self::ALBEDO, Self::COVERAGE, Self::MAGNITUDE];

    /// The tables of a `w` x `h` image of `c` coefficients, to write.
    pub(super) fn write<'a>(
        [w, h, c]: [usize; 3],
        albedo: &'a [[f32; 3]],
        coverage: &'a [f32],
        magnitude: &'a [f32],
    ) -> [(&'static str, Out<'a>); 3] {
        [
            (Self::ALBEDO, Out::new(Dtype::F32, vec![h, w, 3], albedo)),
            (Self::COVERAGE, Out::new(Dtype::F32, vec![h, w], coverage)),
            (Self::MAGNITUDE, Out::new(Dtype::F32, vec![c], magnitude)),
        ]
    }
}

read_group!(PixelTensors {
    ALBEDO => albedo: F32,
    COVERAGE => coverage: F32,
    MAGNITUDE => magnitude: F32,
});

/// The rows: each row's pixel, weight and scale, where each tile's rows start, and each tile's
/// statistics.
#[derive(Default)]
pub(super) struct RowTensors {
    pub(super) pixel: Option<Tensor<u32>>,
    pub(super) scale: Option<Tensor<f32>>,
    pub(super) weight: Option<Tensor<[f32; 3]>>,
    pub(super) tile_start: Option<Tensor<u32>>,
    pub(super) tile_stats: Option<Tensor<[f64; 3]>>,
}

impl RowTensors {
    pub(super) const PIXEL: &str = "row_pixel";
    pub(super) const SCALE: &str = "row_scale";
    pub(super) const WEIGHT: &str = "row_weight";
    pub(super) const TILE_START: &str = "tile_row_start";
    pub(super) const TILE_STATS: &str = "tile_stats";
    const NAMES: [&str; 5] = [
        Self::PIXEL,
        Self::SCALE,
        Self::WEIGHT,
        Self::TILE_START,
        Self::TILE_STATS,
    ];

    /// The tiles' tables to write: where each tile's rows start, and its statistics.
    pub(super) fn write_tiles<'a>(
        tile_start: &'a [u32],
        tile_stats: &'a [[f64; 3]],
    ) -> [(&'static str, Out<'a>); 2] {
        let tiles = tile_stats.len();
        [
            (
                Self::TILE_START,
                Out::new(Dtype::U32, vec![tiles + 1], tile_start),
            ),
            (
                Self::TILE_STATS,
                Out::new(Dtype::F64, vec![tiles, 3], tile_stats),
            ),
        ]
    }
}

read_group!(RowTensors {
    PIXEL => pixel: U32,
    SCALE => scale: F32,
    WEIGHT => weight: F32,
    TILE_START => tile_start: U32,
    TILE_STATS => tile_stats: F64,
});

/// Each row's SH transport.
#[derive(Default)]
pub(super) struct ShTensor {
    pub(super) sh: Option<Tensor<f32>>,
}

impl ShTensor {
    pub(super) const NAME: &str = "sh";
}

read_group!(ShTensor {
    NAME => sh: F32,
});

/// The local lights' columns: a scale per (column, pixel row) and each column's RGB response.
#[derive(Default)]
pub(super) struct LightTensors {
    scale: Option<Tensor<f32>>,
    value: Option<Tensor<u16>>,
}

impl LightTensors {
    pub(super) const SCALE: &str = "light_scale";
    const VALUE: &str = "light_value";
    const NAMES: [&str; 2] = [Self::SCALE, Self::VALUE];

    /// The columns of `columns` lights over a `w` x `h` image (their shapes checked by
    /// `expect`); none without tables.
    pub(super) fn into_columns(
        self,
        (columns, w, h): (usize, usize, usize),
        expect: ShapeCheck,
    ) -> Result<LightColumns> {
        let (Some((ss, scale)), Some((vs, values))) = (self.scale, self.value) else {
            return Ok(LightColumns::empty(w, h));
        };
        expect(Self::SCALE, &ss, &[columns, h])?;
        expect(Self::VALUE, &vs, &[columns, 3, h, w])?;
        Ok(LightColumns {
            width: w,
            height: h,
            scale,
            values,
        })
    }

    /// The tensors of `columns` light columns over a `w` x `h` image, to write.
    pub(super) fn write(
        lights: &LightColumns,
        (columns, w, h): (usize, usize, usize),
    ) -> [(&'static str, Out<'_>); 2] {
        [
            (
                Self::SCALE,
                Out::new(Dtype::F32, vec![columns, h], &lights.scale),
            ),
            (
                Self::VALUE,
                Out::new(Dtype::U16, vec![columns, 3, h, w], &lights.values),
            ),
        ]
    }
}

read_group!(LightTensors {
    SCALE => scale: F32,
    VALUE => value: U16,
});
