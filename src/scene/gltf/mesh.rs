//! A glTF mesh's primitives placed in the world: triangles with shading normals (through the
//! inverse transpose of the node's matrix) and texture coordinates, every index checked.

use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::DataType;
use gltf::mesh::Mode;

use super::{MAX_TRIANGLES, Reader, printable};
use crate::error::Result;
use crate::scene::{MAX_COORDINATE, Triangle};

/// A primitive's vertex attributes as read and checked: positions, normals and texture
/// coordinates (as many of each), and the corner indices, each below the vertex count.
struct Attributes {
    positions: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    indices: Vec<u32>,
}

impl Reader<'_> {
    pub(super) fn place_mesh(&mut self, mesh: &gltf::Mesh, node: usize, world: Mat4) -> Result<()> {
        for prim in mesh.primitives() {
            let field = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
            let corners = match prim.mode() {
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan => prim.mode(),
                other => {
                    self.out
                        .ignored
                        .insert(format!("{other:?} primitives (only triangles are drawn)"));
                    continue;
                }
            };
            let attributes = self.read_attributes(&prim, &field)?;
            let corner_lists = triangle_corners(&attributes.indices, corners);
            let material = self.material(prim.material().index())?;
            let first = self.out.triangles.len();
            self.reserve_triangles(&field, first + corner_lists.len())?;
            self.push_triangles(&field, &attributes, (world, material), corner_lists)?;
            let end = self.out.triangles.len();
            if end > first {
                let name = mesh
                    .name()
                    .map(|n| format!(" ({})", printable(n)))
                    .unwrap_or_default();
                self.out.surfaces.push((
                    first..end,
                    format!(
                        "mesh {}{name} primitive {} at node {node}",
                        mesh.index(),
                        prim.index()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The primitive's attributes, counted against the scene's budget of vertices and corners
    /// before anything is read, and every size and index checked.
    fn read_attributes(&mut self, prim: &gltf::Primitive, field: &str) -> Result<Attributes> {
        let Some(pos) = prim.get(&gltf::Semantic::Positions) else {
            return Err(self.error(format!("{field}.attributes"), "has no POSITION"));
        };
        // Every instance of a primitive is read again: its vertices and corners count
        // against one budget for the whole scene, before anything is read.
        let work = pos.count() as u64 + prim.indices().map_or(pos.count(), |a| a.count()) as u64;
        if work > self.limits.corners_left {
            return Err(self.error(
                field,
                format!(
                    "the scene's glTF primitives, every instance counted, hold more than \
                     {} vertices and corners",
                    3 * MAX_TRIANGLES
                ),
            ));
        }
        self.limits.corners_left -= work;
        let positions: Vec<[f32; 3]> = self.read_floats(
            &pos,
            &format!("{field}.attributes.POSITION"),
            &[DataType::F32],
        )?;
        let normals: Option<Vec<[f32; 3]>> = self.read_optional(
            prim,
            (
                gltf::Semantic::Normals,
                &format!("{field}.attributes.NORMAL"),
            ),
            &[DataType::F32, DataType::I8, DataType::I16],
        )?;
        let uvs: Option<Vec<[f32; 2]>> = self.read_optional(
            prim,
            (
                gltf::Semantic::TexCoords(0),
                &format!("{field}.attributes.TEXCOORD_0"),
            ),
            &[DataType::F32, DataType::U8, DataType::U16],
        )?;
        let n = positions.len();
        for (what, len) in [
            ("NORMAL", normals.as_ref().map(Vec::len)),
            ("TEXCOORD_0", uvs.as_ref().map(Vec::len)),
        ] {
            if let Some(len) = len.filter(|&l| l != n) {
                return Err(self.error(
                    format!("{field}.attributes.{what}"),
                    format!("has {len} elements for {n} positions"),
                ));
            }
        }
        let indices = match prim.indices() {
            Some(a) => self.read_indices(&a, &format!("{field}.indices"))?,
            None => (0..n as u32).collect(),
        };
        if let Some((k, &bad)) = indices.iter().enumerate().find(|(_, v)| **v as usize >= n) {
            return Err(self.error(
                format!("{field}.indices"),
                format!("index {k} is {bad}, but there are {n} vertices"),
            ));
        }
        Ok(Attributes {
            positions,
            normals,
            uvs,
            indices,
        })
    }

    /// The primitive's attribute `semantic` (its field `field`) as [`Reader::read_floats`]
    /// reads it, where the primitive has it.
    fn read_optional<const N: usize>(
        &self,
        prim: &gltf::Primitive,
        (semantic, field): (gltf::Semantic, &str),
        types: &[DataType],
    ) -> Result<Option<Vec<[f32; N]>>> {
        let read = |a| self.read_floats(&a, field, types);
        prim.get(&semantic).map(read).transpose()
    }

    /// Room in the scene's triangle list for `total` triangles, refused with an error (not an
    /// abort) past the scene's limit or this process's memory.
    fn reserve_triangles(&mut self, field: &str, total: usize) -> Result<()> {
        if total > MAX_TRIANGLES {
            return Err(self.error(
                field,
                format!("the file places more than {MAX_TRIANGLES} triangles"),
            ));
        }
        // The triangle list's memory, before it grows: a model instanced many times must
        // be refused, not abort. It grows by doubling, so twice what it will hold is asked.
        let size = std::mem::size_of::<Triangle>() as u64;
        crate::files::check_memory(
            field,
            "placing the scene's glTF triangles",
            2 * total as u64 * size,
        )
        .map_err(|e| match e {
            crate::error::PrtError::Invalid { message, .. } => self.error(field, message),
            e => e,
        })?;
        let more = total - self.out.triangles.len();
        self.out.triangles.try_reserve(more).map_err(|_| {
            self.error(
                field,
                format!("{total} triangles do not fit in this process's memory"),
            )
        })
    }

    /// The primitive's triangles placed by `world` with `material`: shading normals through the
    /// inverse transpose, winding kept under a mirroring matrix, degenerate triangles and exact
    /// repeats left out.
    fn push_triangles(
        &mut self,
        field: &str,
        attributes: &Attributes,
        (world, material): (Mat4, u32),
        corner_lists: Vec<[u32; 3]>,
    ) -> Result<()> {
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        let mirrored = Mat3::from_mat4(world).determinant() < 0.0;
        let world_pos: Vec<Vec3> = attributes
            .positions
            .iter()
            .map(|p| world.transform_point3(Vec3::from(*p)))
            .collect();
        if let Some(v) = world_pos
            .iter()
            .find(|v| !(v.is_finite() && v.abs().max_element() <= MAX_COORDINATE))
        {
            return Err(self.error(
                format!("{field}.attributes.POSITION"),
                format!("a vertex lands at {v}, beyond ±{MAX_COORDINATE:e} scene units"),
            ));
        }
        for mut c in corner_lists {
            if mirrored {
                c.swap(1, 2);
            }
            let vertices = c.map(|i| world_pos[i as usize]);
            let [a, b, d] = vertices;
            let geometric = (b - a).cross(d - a).normalize_or_zero();
            if geometric == Vec3::ZERO {
                continue;
            }
            let normals = match &attributes.normals {
                Some(ns) => c.map(|i| {
                    let s = (normal_matrix * Vec3::from(ns[i as usize])).normalize_or_zero();
                    if s.is_finite() && s != Vec3::ZERO {
                        s
                    } else {
                        geometric
                    }
                }),
                None => [geometric; 3],
            };
            let uvs = match &attributes.uvs {
                Some(t) => c.map(|i| {
                    let uv = Vec2::from(t[i as usize]);
                    if uv.is_finite() { uv } else { Vec2::ZERO }
                }),
                None => [Vec2::ZERO; 3],
            };
            let triangle = Triangle {
                vertices,
                normals,
                uvs,
                material,
            };
            if self.is_duplicate(&triangle) {
                continue;
            }
            self.out.triangles.push(triangle);
        }
        Ok(())
    }
}

impl Reader<'_> {
    /// Whether `t` repeats, bit for bit, a triangle this placement has already made. Stacked
    /// copies change no ray's hit but multiply every trace's work, so each is made once (and
    /// counted, for the note of what the file holds).
    fn is_duplicate(&mut self, t: &Triangle) -> bool {
        let mut h = crate::scene::hash::Fnv1a::new();
        for v in t.vertices.iter().chain(&t.normals) {
            for x in v.to_array() {
                h.write(&x.to_bits().to_le_bytes());
            }
        }
        for uv in &t.uvs {
            for x in uv.to_array() {
                h.write(&x.to_bits().to_le_bytes());
            }
        }
        h.write(&t.material.to_le_bytes());
        let next = self.out.triangles.len();
        let same = |i: usize, t: &Triangle, all: &[Triangle]| {
            let o = &all[i];
            let bits = |v: &[Vec3; 3]| v.map(|p| p.to_array().map(f32::to_bits));
            let uv_bits = |v: &[Vec2; 3]| v.map(|p| p.to_array().map(f32::to_bits));
            bits(&o.vertices) == bits(&t.vertices)
                && bits(&o.normals) == bits(&t.normals)
                && uv_bits(&o.uvs) == uv_bits(&t.uvs)
                && o.material == t.material
        };
        match self.seen_triangles.entry(h.0) {
            std::collections::hash_map::Entry::Occupied(e) => {
                if same(*e.get(), t, &self.out.triangles) {
                    self.duplicates += 1;
                    return true;
                }
                false
            }
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(next);
                false
            }
        }
    }
}

/// The corners of each triangle of a primitive's index list.
fn triangle_corners(indices: &[u32], mode: Mode) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                let (a, b, c) = (indices[i - 2], indices[i - 1], indices[i]);
                // Every other triangle of a strip is wound the other way round.
                if i % 2 == 0 { [a, b, c] } else { [b, a, c] }
            })
            .collect(),
        Mode::TriangleFan => (2..indices.len())
            .map(|i| [indices[i - 1], indices[i], indices[0]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_keep_their_winding() {
        let strip = triangle_corners(&[0, 1, 2, 3], Mode::TriangleStrip);
        assert_eq!(strip, vec![[0, 1, 2], [2, 1, 3]]);
        let fan = triangle_corners(&[0, 1, 2, 3], Mode::TriangleFan);
        assert_eq!(fan, vec![[1, 2, 0], [2, 3, 0]]);
        assert_eq!(
            triangle_corners(&[0, 1, 2, 3], Mode::Triangles),
            vec![[0, 1, 2]]
        );
    }
}
