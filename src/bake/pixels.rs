//! The camera sub-samples of a pixel, shared by the bake and the reference: `spp` of them, or
//! `edge_spp` where the pixel's corners see different things (adaptive antialiasing); and what one
//! row of the bake is made from: those sub-samples, or in a per-vertex bake one vertex.

use rayon::prelude::*;

use super::{BakeSettings, ShadingPoint, TileContext, shading_point};
use crate::math::sampling::pixel_samples;
use crate::scene::trace::Tracer;
use crate::scene::{Camera, Scene};

/// Cosine of the largest angle between the normals two corners of a pixel may see and the pixel
/// still count as smooth (25°).
const EDGE_COS: f32 = 0.906;
/// Largest distance of one corner's hit from the tangent plane of another's, as a fraction of its
/// depth, for the pixel to count as one surface (beyond it: an occluding edge).
const EDGE_DEPTH: f32 = 0.02;

/// Whether the four corners of pixel (x, y) see different things: a hit beside a miss, two
/// materials, normals more than 25° apart, or a hit off the other's tangent plane (an occluding
/// edge over the same material). Such a pixel straddles a silhouette, a material edge or a
/// crease, where one sample aliases; elsewhere the image varies smoothly across the pixel.
pub fn is_edge_pixel(tracer: &Tracer, cam: &Camera, x: u32, y: u32) -> bool {
    let see = |dx: u32, dy: u32| {
        let ray = cam.ray((x + dx) as f32, (y + dy) as f32);
        tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY)
    };
    let corners = [see(0, 0), see(1, 0), see(0, 1), see(1, 1)];
    corners.iter().enumerate().any(|(i, a)| {
        corners[i + 1..].iter().any(|b| match (a, b) {
            (None, None) => false,
            (Some(a), Some(b)) => {
                a.material != b.material
                    || a.normal.dot(b.normal) < EDGE_COS
                    || (b.point - a.point).dot(a.normal).abs() > EDGE_DEPTH * a.t.min(b.t)
            }
            _ => true,
        })
    })
}

/// How many pixels of `scene`'s view are edge pixels ([`is_edge_pixel`]).
pub fn edge_pixel_count(scene: &Scene) -> usize {
    let tracer = Tracer::new(scene);
    let cam = &scene.camera;
    (0..cam.height)
        .into_par_iter()
        .map(|y| {
            (0..cam.width)
                .filter(|&x| is_edge_pixel(&tracer, cam, x, y))
                .count()
        })
        .sum()
}

/// The camera sub-samples of pixel (x, y): `spp` of them, or `edge_spp` where the pixel is an
/// edge pixel ([`is_edge_pixel`]). The bake and the reference take the same ones.
pub fn pixel_subsamples(
    tracer: &Tracer,
    cam: &Camera,
    settings: &BakeSettings,
    x: u32,
    y: u32,
) -> Vec<(f32, f32)> {
    let spp = if settings.edge_spp > settings.spp && is_edge_pixel(tracer, cam, x, y) {
        settings.edge_spp
    } else {
        settings.spp
    };
    pixel_samples(x, y, cam.width, spp, settings.seed)
}

/// Sub-samples a pixel may take at most: the stride of [`super::path_stream`].
pub fn sample_stride(settings: &BakeSettings) -> u32 {
    settings.spp.max(settings.edge_spp)
}

/// One camera sub-sample of a pixel, or a mesh vertex: where it shades (`None` where it sees no
/// surface), the fraction of its light that reaches the camera, and whether it counts towards
/// the pixel's coverage.
pub(super) struct Visit {
    pub(super) point: Option<ShadingPoint>,
    pub(super) seen: f32,
    pub(super) covered: bool,
}

/// The visits of pixel (x, y): its camera sub-samples, or for a per-vertex bake its vertex
/// (none past the last vertex).
pub(super) fn visits(ctx: &TileContext, x: usize, y: usize) -> Vec<Visit> {
    let (tracer, medium) = (ctx.tracer, ctx.medium);
    if let Some(mesh) = ctx.mesh {
        let v = y * ctx.width + x;
        if v >= mesh.vertex_count() {
            return Vec::new();
        }
        let normal = mesh.normals[v];
        let point = ShadingPoint {
            origin: mesh.positions[v] + normal * tracer.spawn_offset(),
            normal,
            view: normal,
            material: mesh.materials[v],
        };
        return vec![Visit {
            point: Some(point),
            seen: 1.0,
            covered: true,
        }];
    }
    let cam = &ctx.scene.camera;
    pixel_subsamples(tracer, cam, ctx.settings, x as u32, y as u32)
        .into_iter()
        .map(|(fx, fy)| {
            let ray = cam.ray(fx, fy);
            let found = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY);
            // Through a medium, what the camera sees of the surface is attenuated.
            let (seen, in_medium) = match medium {
                Some(m) => {
                    let t =
                        m.transmittance(ray.origin, ray.dir, found.map_or(f32::INFINITY, |h| h.t));
                    (t, t < 0.999)
                }
                None => (1.0, false),
            };
            Visit {
                point: found.map(|hit| shading_point(tracer, &hit, ray.dir)),
                seen,
                covered: found.is_some() || in_medium,
            }
        })
        .collect()
}
