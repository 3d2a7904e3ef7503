//! The visibility bits of a per-vertex bake's glossy vertices ([`Visibility`]): from each such
//! vertex (its shadow-ray origin, as its rows take it), one ray through the centre of every
//! texel above its horizon; a bit is set where the ray escapes. Texels below the horizon stay
//! shut. Beside the bits, each vertex's visible share of every local light column: one shadow
//! ray for a delta light, the light's own stratified samples for a sized one, each weighed by
//! the light it brings.

use rayon::prelude::*;

use super::{BakeSettings, CentrePackets};
use crate::math::cube_pyramid::morton_of_linear;
use crate::math::cubemap::texel_dirs;
use crate::math::sampling::Rng;
use crate::scene::Scene;
use crate::scene::light::{Emitter, emitters, stratified};
use crate::scene::tessellate::VertexMesh;
use crate::scene::trace::Tracer;
use crate::scene::visibility::Visibility;

/// Salt of the light shares' random streams, apart from every other stream of the bake.
const SHARE_STREAM: u64 = 0x5a4e_11d7_0b1e_0002;

/// The bits of every vertex of `mesh` whose material has a glossy lobe, over the settings'
/// N-cube, and its share of each light column (every texel above the horizon open and every
/// light whole when the settings are unshadowed, no ray traced).
pub fn glossy_vertices(
    scene: &Scene,
    tracer: &Tracer,
    mesh: &VertexMesh,
    settings: &BakeSettings,
) -> crate::error::Result<Visibility> {
    let (n, unshadowed) = (settings.cube_n, settings.unshadowed);
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
    let lights = emitters(&scene.lights);
    let shares: Vec<f32> = vertices
        .par_iter()
        .flat_map_iter(|&v| {
            let normal = mesh.normals[v as usize];
            let origin = mesh.positions[v as usize] + normal * tracer.spawn_offset();
            let mut rng = Rng::new(settings.seed ^ SHARE_STREAM, v as u64);
            let samples = settings.light_samples as usize;
            lights
                .iter()
                .map(|e| match unshadowed {
                    true => 1.0,
                    false => light_share(tracer, e, origin, samples, &mut rng),
                })
                .collect::<Vec<f32>>()
        })
        .collect();
    Visibility::new(
        n,
        mesh.vertex_count(),
        vertices,
        bits,
        Visibility::lobes_of(&scene.materials),
    )?
    .with_light_shares(lights.len(), shares)
}

/// The share of emitter `e`'s light that reaches `origin`: its samples (one for a delta light,
/// `samples` stratified for a sized one) weighed by the light each brings, over those not
/// blocked. 1 where no sample reaches the point (outside a spot's cone, behind a quad): a
/// highlight is then dark for want of light, not of sight.
fn light_share(
    tracer: &Tracer,
    e: &Emitter,
    origin: glam::Vec3,
    samples: usize,
    rng: &mut Rng,
) -> f32 {
    let (mut open, mut all) = (0.0f64, 0.0f64);
    let mut add = |u: [f32; 2]| {
        if let Some(s) = e.sample(origin, u) {
            all += s.weight as f64;
            if !tracer.occluded(origin, s.dir, s.dist) {
                open += s.weight as f64;
            }
        }
    };
    if e.is_delta() {
        add([0.5, 0.5]);
    } else {
        for u in stratified(samples, || rng.next_f32()) {
            add(u);
        }
    }
    if all > 0.0 {
        (open / all).clamp(0.0, 1.0) as f32
    } else {
        1.0
    }
}
