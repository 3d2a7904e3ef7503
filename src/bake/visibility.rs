//! The visibility bits of a per-vertex bake's glossy vertices ([`Visibility`]): from each such
//! vertex (its shadow-ray origin, as its rows take it), one ray through the centre of every
//! texel above its horizon; a bit is set where the ray escapes. Texels below the horizon stay
//! shut.

use rayon::prelude::*;

use super::CentrePackets;
use crate::math::cube_pyramid::morton_of_linear;
use crate::math::cubemap::texel_dirs;
use crate::scene::Scene;
use crate::scene::tessellate::VertexMesh;
use crate::scene::trace::Tracer;
use crate::scene::visibility::Visibility;

/// The bits of every vertex of `mesh` whose material has a glossy lobe, over an N-cube (every
/// texel above the horizon open when `unshadowed`, no ray traced).
pub fn glossy_vertices(
    scene: &Scene,
    tracer: &Tracer,
    mesh: &VertexMesh,
    n: usize,
    unshadowed: bool,
) -> crate::error::Result<Visibility> {
    let vertices: Vec<u32> = (0..mesh.vertex_count() as u32)
        .filter(|&v| {
            scene
                .materials
                .get(mesh.materials[v as usize] as usize)
                .is_some_and(|m| m.glossy_lobe().is_some())
        })
        .collect();
    let dirs: Vec<glam::Vec3> = texel_dirs(n).iter().map(|d| d.as_vec3()).collect();
    let morton = morton_of_linear(n);
    let words = Visibility::words(n);
    let packets = CentrePackets::new(n, &dirs);
    let rows: Vec<Vec<u32>> = vertices
        .par_iter()
        .map(|&v| {
            let normal = mesh.normals[v as usize];
            let origin = mesh.positions[v as usize] + normal * tracer.spawn_offset();
            // The open texels in linear order, then in Morton order.
            let mut open = vec![0u64; dirs.len().div_ceil(64)];
            let above = |j: usize| normal.dot(dirs[j]) > 0.0;
            if unshadowed {
                (0..dirs.len())
                    .filter(|&j| above(j))
                    .for_each(|j| open[j / 64] |= 1 << (j % 64));
            } else {
                packets.open_bits(&mut tracer.rays_from(origin), above, &mut open);
            }
            let mut bits = vec![0u32; words];
            for (j, &m) in morton.iter().enumerate() {
                if open[j / 64] >> (j % 64) & 1 == 1 {
                    bits[m as usize / 32] |= 1 << (m % 32);
                }
            }
            bits
        })
        .collect();
    let bits = rows.into_iter().flatten().collect();
    Visibility::new(
        n,
        mesh.vertex_count(),
        vertices,
        bits,
        Visibility::lobes_of(&scene.materials),
    )
}
