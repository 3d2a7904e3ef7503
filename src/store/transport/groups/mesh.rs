//! A per-vertex bake's groups: its mesh, its albedo maps (with each vertex's texture
//! coordinate) and its glossy vertices' visibility.

use safetensors::tensor::Dtype;

use super::{ReadGroup, ShapeCheck, Tensor, not_mine};
use crate::error::{PrtError, Result};
use crate::scene::albedo_map::from_table;
use crate::scene::tessellate::VertexMesh;
use crate::scene::visibility::Visibility;
use crate::store::container::Tensor as Out;
use crate::store::transport::reader::TensorReader;
use crate::store::transport::{PerVertexMeta, TransportMeta};

/// A per-vertex bake's mesh: each vertex's material, normal and position, and the triangles.
#[derive(Default)]
pub(in crate::store::transport) struct MeshTensors {
    material: Option<Tensor<u32>>,
    normal: Option<Tensor<glam::Vec3>>,
    position: Option<Tensor<glam::Vec3>>,
    triangle: Option<Tensor<[u32; 3]>>,
}

impl MeshTensors {
    const MATERIAL: &str = "mesh_material";
    const NORMAL: &str = "mesh_normal";
    const POSITION: &str = "mesh_position";
    const TRIANGLE: &str = "mesh_triangle";
    pub(super) const NAMES: [&str; 4] =
        [Self::MATERIAL, Self::NORMAL, Self::POSITION, Self::TRIANGLE];

    /// The mesh of `pv`'s vertices and triangles with its albedo maps, if any (`map_count` of
    /// them), every tensor's shape checked by `expect` and the maps' tables by their reader
    /// (errors by `bad`); `None` for a file without a mesh.
    pub(in crate::store::transport) fn into_mesh(
        self,
        maps: MapTensors,
        (pv, map_count): (&PerVertexMeta, usize),
        expect: ShapeCheck,
        bad: &dyn Fn(String) -> PrtError,
    ) -> Result<Option<VertexMesh>> {
        let (
            Some((ms, materials)),
            Some((ns, normals)),
            Some((ps, positions)),
            Some((ts, triangles)),
        ) = (self.material, self.normal, self.position, self.triangle)
        else {
            return Ok(None);
        };
        let (v, t) = (pv.vertices as usize, pv.triangles as usize);
        expect(Self::POSITION, &ps, &[v, 3])?;
        expect(Self::NORMAL, &ns, &[v, 3])?;
        expect(Self::MATERIAL, &ms, &[v])?;
        expect(Self::TRIANGLE, &ts, &[t, 3])?;
        let (uvs, albedo_maps) = match maps {
            MapTensors {
                uv: Some((us, uvs)),
                table: Some((ms, table)),
                owners: Some((os, owners)),
                texels: Some((xs, texels)),
            } => {
                expect(MapTensors::UV, &us, &[v, 2])?;
                expect(MapTensors::TABLE, &ms, &[map_count, 5])?;
                let n = os.first().copied().unwrap_or(0);
                expect(MapTensors::OWNERS, &os, &[n, 2])?;
                let n = xs.first().copied().unwrap_or(0);
                expect(MapTensors::TEXELS, &xs, &[n, 3])?;
                (uvs, from_table(&table, &owners, texels).map_err(bad)?)
            }
            _ => (vec![glam::Vec2::ZERO; v], Vec::new()),
        };
        Ok(Some(VertexMesh {
            positions,
            normals,
            materials,
            uvs,
            triangles,
            albedo_maps,
            visibility: None,
        }))
    }

    /// The mesh's tensors to write.
    pub(in crate::store::transport) fn write(mesh: &VertexMesh) -> [(&'static str, Out<'_>); 4] {
        let (v, t) = (mesh.vertex_count(), mesh.triangles.len());
        [
            (
                Self::POSITION,
                Out::new(Dtype::F32, vec![v, 3], &mesh.positions),
            ),
            (
                Self::NORMAL,
                Out::new(Dtype::F32, vec![v, 3], &mesh.normals),
            ),
            (
                Self::MATERIAL,
                Out::new(Dtype::U32, vec![v], &mesh.materials),
            ),
            (
                Self::TRIANGLE,
                Out::new(Dtype::U32, vec![t, 3], &mesh.triangles),
            ),
        ]
    }
}

read_group!(MeshTensors {
    MATERIAL => material: U32,
    NORMAL => normal: F32,
    POSITION => position: F32,
    TRIANGLE => triangle: U32,
});

/// A textured mesh's albedo maps: their table, their materials, their texels, and each vertex's
/// texture coordinate.
#[derive(Default)]
pub(in crate::store::transport) struct MapTensors {
    table: Option<Tensor<[u32; 5]>>,
    owners: Option<Tensor<[u32; 2]>>,
    texels: Option<Tensor<[u16; 3]>>,
    uv: Option<Tensor<glam::Vec2>>,
}

impl MapTensors {
    const TABLE: &str = "albedo_map";
    const OWNERS: &str = "albedo_map_material";
    const TEXELS: &str = "albedo_texel";
    const UV: &str = "mesh_uv";
    pub(super) const NAMES: [&str; 4] = [Self::TABLE, Self::OWNERS, Self::TEXELS, Self::UV];

    /// The tensors of `mesh`'s albedo maps, to write with `tables` (the maps as
    /// [`crate::scene::albedo_map::to_table`] lays them out).
    pub(in crate::store::transport) fn write<'a>(
        mesh: &'a VertexMesh,
        (table, owners, texels): &'a crate::scene::albedo_map::FileTables,
    ) -> [(&'static str, Out<'a>); 4] {
        [
            (
                Self::TABLE,
                Out::new(Dtype::U32, vec![table.len(), 5], table),
            ),
            (
                Self::OWNERS,
                Out::new(Dtype::U32, vec![owners.len(), 2], owners),
            ),
            (
                Self::TEXELS,
                Out::new(Dtype::U16, vec![texels.len(), 3], texels),
            ),
            (
                Self::UV,
                Out::new(Dtype::F32, vec![mesh.vertex_count(), 2], &mesh.uvs),
            ),
        ]
    }
}

read_group!(MapTensors {
    TABLE => table: U32,
    OWNERS => owners: U32,
    TEXELS => texels: U16,
    UV => uv: F32,
});

/// The glossy vertices' visibility: their bits, the materials' lobes and the vertices, and with
/// local lights (from version 10) each vertex's share of each light column.
#[derive(Default)]
pub(in crate::store::transport) struct VisibilityTensors {
    bits: Option<Tensor<u32>>,
    lobe: Option<Tensor<[f32; 4]>>,
    vertex: Option<Tensor<u32>>,
    light: Option<Tensor<f32>>,
}

impl VisibilityTensors {
    const BITS: &str = "visibility_bits";
    const LIGHT: &str = "visibility_light";
    const LOBE: &str = "visibility_lobe";
    const VERTEX: &str = "visibility_vertex";
    pub(super) const NAMES: [&str; 3] = [Self::BITS, Self::LOBE, Self::VERTEX];
    pub(super) const LIT_NAMES: [&str; 4] = [Self::BITS, Self::LIGHT, Self::LOBE, Self::VERTEX];

    /// `mesh` with the visibility read over an `n`-cube, with its share of each of the header's
    /// `columns` light columns where stored (its shapes checked by `expect`), if any: an error
    /// for a visibility without a per-vertex mesh.
    pub(in crate::store::transport) fn attach(
        self,
        mesh: Option<VertexMesh>,
        (n, columns): (usize, usize),
        expect: ShapeCheck,
    ) -> Result<Option<VertexMesh>> {
        let (Some((bs, bits)), Some((ls, lobes)), Some((vs, vertices))) =
            (self.bits, self.lobe, self.vertex)
        else {
            return Ok(mesh);
        };
        let light = self.light;
        let mut mesh = mesh.ok_or_else(|| {
            PrtError::invalid("visibility", "stored for a bake that is not per vertex")
        })?;
        let g = vs.first().copied().unwrap_or(0);
        expect(Self::VERTEX, &vs, &[g])?;
        expect(Self::BITS, &bs, &[g, Visibility::words(n)])?;
        let m = ls.first().copied().unwrap_or(0);
        expect(Self::LOBE, &ls, &[m, 4])?;
        let mut vis = Visibility::new(n, mesh.vertex_count(), vertices, bits, lobes)?;
        if let Some((shape, shares)) = light {
            expect(Self::LIGHT, &shape, &[g, columns])?;
            vis = vis.with_light_shares(columns, shares)?;
        }
        mesh.visibility = Some(Box::new(vis));
        Ok(Some(mesh))
    }

    /// The tensors of a glossy mesh's visibility, to write: the light shares where it has light
    /// columns.
    pub(in crate::store::transport) fn write(vis: &Visibility) -> Vec<(&'static str, Out<'_>)> {
        let rows = vis.vertices.len();
        let shares = (vis.columns > 0).then(|| {
            (
                Self::LIGHT,
                Out::new(Dtype::F32, vec![rows, vis.columns], &vis.light_shares),
            )
        });
        [
            (
                Self::BITS,
                Out::new(Dtype::U32, vec![rows, Visibility::words(vis.n)], &vis.bits),
            ),
            (
                Self::LOBE,
                Out::new(Dtype::F32, vec![vis.lobes.len(), 4], &vis.lobes),
            ),
            (
                Self::VERTEX,
                Out::new(Dtype::U32, vec![rows], &vis.vertices),
            ),
        ]
        .into_iter()
        .chain(shares)
        .collect()
    }
}

read_group!(VisibilityTensors {
    BITS => bits: U32,
    LIGHT => light: F32,
    LOBE => lobe: F32,
    VERTEX => vertex: U32,
});

/// Checks a per-vertex mesh's stored values, each error naming its tensor: finite positions,
/// texture coordinates, finite unit normals, and material indices below the header's material
/// count, a map's materials also used by a vertex. Returns the material count when the file
/// gives one.
pub(in crate::store::transport) fn mesh_values_problem(
    pv: &PerVertexMeta,
    mesh: &VertexMesh,
) -> std::result::Result<Option<usize>, String> {
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!(
            "tensor `{}`: vertex {i} is at {}",
            MeshTensors::POSITION,
            mesh.positions[i]
        ));
    }
    let unit = |n: &glam::Vec3| n.is_finite() && (n.length() - 1.0).abs() <= 1e-3;
    if let Some(i) = mesh.normals.iter().position(|n| !unit(n)) {
        return Err(format!(
            "tensor `{}`: vertex {i} has normal {}, not a finite unit vector",
            MeshTensors::NORMAL,
            mesh.normals[i]
        ));
    }
    if let Some(i) = mesh.uvs.iter().position(|t| !t.is_finite()) {
        return Err(format!(
            "tensor `{}`: vertex {i} has texture coordinate {}",
            MapTensors::UV,
            mesh.uvs[i]
        ));
    }
    let count = match pv.materials as usize {
        0 => None,
        n => Some(n),
    };
    if let Some(n) = count
        && let Some(i) = mesh.materials.iter().position(|&m| m as usize >= n)
    {
        return Err(format!(
            "tensor `{}`: vertex {i} has material {}, but the bake has {n} materials",
            MeshTensors::MATERIAL,
            mesh.materials[i]
        ));
    }
    if !mesh.albedo_maps.is_empty() {
        let used: std::collections::HashSet<u32> = mesh.materials.iter().copied().collect();
        let maps = mesh.albedo_maps.iter().flat_map(|a| &a.materials);
        for &m in maps {
            match count {
                Some(n) if m as usize >= n => {
                    return Err(format!(
                        "tensor `{}`: a map of material {m}, but the bake has {n} materials",
                        MapTensors::OWNERS
                    ));
                }
                _ if !used.contains(&m) => {
                    return Err(format!(
                        "tensor `{}`: a map of material {m}, which no vertex has",
                        MapTensors::OWNERS
                    ));
                }
                _ => {}
            }
        }
    }
    Ok(count)
}
