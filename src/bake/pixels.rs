//! The camera sub-samples of a pixel, shared by the bake and the reference: `spp` of them, or
//! `edge_spp` where the pixel's corners see different things (adaptive antialiasing); and what one
//! row of the bake is made from: those sub-samples, or in a per-vertex bake one vertex.

use rayon::prelude::*;

use super::{BakeSettings, ShadingPoint, TileContext, shading_point};
use crate::math::cubemap::Directions;
use crate::math::sampling::pixel_samples;
use crate::scene::trace::Tracer;
use crate::scene::{Camera, Scene};
use glam::Vec3;

/// Cosine of the largest angle between the normals two corners of a pixel may see and the pixel
/// still count as smooth (25°).
const EDGE_COS: f32 = 0.906;
/// Largest distance of one corner's hit from the tangent plane of another's, as a fraction of its
/// depth, for the pixel to count as one surface (beyond it: an occluding edge).
const EDGE_DEPTH: f32 = 0.02;
/// Face size of the cube of directions in which the corners' shadows are compared: its 6 x 8²
/// texel centres, about 11° apart.
const SHADOW_CUBE: usize = 8;
/// Words of one corner's visibility bits (one per direction of the shadow cube).
const SHADOW_WORDS: usize = (6 * SHADOW_CUBE * SHADOW_CUBE).div_ceil(64);
/// Least fraction of a corner's unshadowed diffuse light (its cosine-weighted hemisphere) whose
/// visibility must change between two corners for a shadow border to count.
const SHADOW_FRACTION: f32 = 0.01;
/// Pixel rows whose corners are found together (one parallel task).
const EDGE_BAND: usize = 16;

/// The directions of the shadow cube and their solid angles over π, so that `max(0, n·ω)` times
/// one is that direction's share of an unshadowed diffuse row.
type ShadowCube = Directions;

impl ShadowCube {
    /// The diffuse share of the directions whose bits are set in `bits`, seen with `normal`.
    fn share(&self, bits: &[u64; SHADOW_WORDS], normal: Vec3) -> f32 {
        let mut sum = 0.0;
        for (k, word) in bits.iter().enumerate() {
            let mut word = *word;
            while word != 0 {
                let i = k * 64 + word.trailing_zeros() as usize;
                word &= word - 1;
                sum += normal.dot(self.dirs[i]).max(0.0) * self.weights[i];
            }
        }
        sum
    }
}

/// What the camera ray through a pixel corner sees: the surface it hits and, for each direction
/// of the shadow cube above it, whether it is unoccluded there (`open`).
struct Corner {
    hit: Option<CornerHit>,
    front: [u64; SHADOW_WORDS],
    open: [u64; SHADOW_WORDS],
    /// The diffuse share of the `front` directions: what an unshadowed row sums to.
    unshadowed: f32,
}

struct CornerHit {
    material: u32,
    normal: Vec3,
    point: Vec3,
    t: f32,
}

impl Corner {
    fn see(
        tracer: &Tracer,
        cam: &Camera,
        shadows: Option<&ShadowCube>,
        cx: u32,
        cy: u32,
    ) -> Corner {
        let ray = cam.ray(cx as f32, cy as f32);
        let mut corner = Corner {
            hit: None,
            front: [0; SHADOW_WORDS],
            open: [0; SHADOW_WORDS],
            unshadowed: 0.0,
        };
        let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
            return corner;
        };
        if let Some(cube) = shadows {
            let sp = shading_point(tracer, &hit, ray.dir);
            let mut rays = tracer.rays_from(sp.origin);
            for (i, d) in cube.dirs.iter().enumerate() {
                if sp.normal.dot(*d) <= 0.0 {
                    continue;
                }
                let bit = 1u64 << (i % 64);
                corner.front[i / 64] |= bit;
                if !rays.occluded(*d, f32::INFINITY) {
                    corner.open[i / 64] |= bit;
                }
            }
            corner.unshadowed = cube.share(&corner.front, sp.normal);
        }
        corner.hit = Some(CornerHit {
            material: hit.material,
            normal: hit.normal,
            point: hit.point,
            t: hit.t,
        });
        corner
    }

    /// Whether a pixel with corners `self` and `other` straddles an edge between them.
    fn differs(&self, other: &Corner, shadows: Option<&ShadowCube>) -> bool {
        match (&self.hit, &other.hit) {
            (None, None) => false,
            (Some(a), Some(b)) => {
                if a.material != b.material
                    || a.normal.dot(b.normal) < EDGE_COS
                    || (b.point - a.point).dot(a.normal).abs() > EDGE_DEPTH * a.t.min(b.t)
                {
                    return true;
                }
                let Some(cube) = shadows else {
                    return false;
                };
                let changed: [u64; SHADOW_WORDS] = std::array::from_fn(|k| {
                    (self.open[k] ^ other.open[k]) & self.front[k] & other.front[k]
                });
                cube.share(&changed, a.normal) > SHADOW_FRACTION * self.unshadowed
            }
            _ => true,
        }
    }
}

/// Which pixels of a view are edge pixels, whose four corners see different things:
/// - a hit beside a miss (a silhouette against the sky);
/// - two materials;
/// - normals more than 25° apart (a crease);
/// - a hit off the other's tangent plane (an occluding edge over the same material);
/// - in a shadowed bake, a shadow border: the directions of a coarse cube (6 x 8²) open from one
///   corner and occluded from another hold more than 1% of the corner's unshadowed diffuse
///   light.
///
/// Such a pixel straddles an outline, where one sample aliases; elsewhere the image varies
/// smoothly across the pixel. The test does not depend on the light, so one bake serves every
/// environment. Any pixel that sees an occluder may hold a shadow border for a light small
/// enough, so the 1% keeps the borders of occluders that fill much of the sky, as near a
/// contact, where shadows are sharp under every light; it is the order of the error the
/// thresholding of a row is allowed.
///
/// Empty (no edge pixels) where the settings take no more samples at edges than elsewhere.
#[derive(Clone, Debug, Default)]
pub struct EdgeMap {
    width: usize,
    edges: Vec<bool>,
}

impl EdgeMap {
    /// The edge pixels of `scene`'s view, found when the settings record edge samples
    /// ([`BakeSettings::stored_edge_spp`]: more than `spp`, in a per-pixel bake).
    pub fn new(scene: &Scene, tracer: &Tracer, settings: &BakeSettings) -> EdgeMap {
        if settings.stored_edge_spp() == 0 {
            return EdgeMap::default();
        }
        Self::find(scene, tracer, !settings.unshadowed)
    }

    /// The edge pixels of `scene`'s view, with shadow borders or without.
    fn find(scene: &Scene, tracer: &Tracer, shadows: bool) -> EdgeMap {
        let cam = &scene.camera;
        let (w, h) = (cam.width as usize, cam.height as usize);
        let cube = ShadowCube::diffuse(SHADOW_CUBE);
        let shadows = shadows.then_some(&cube);
        let mut edges = vec![false; w * h];
        edges
            .par_chunks_mut(w * EDGE_BAND)
            .enumerate()
            .for_each(|(band, flags)| {
                let y0 = band * EDGE_BAND;
                let rows = flags.len() / w;
                // The band's rows of corners, one more than its rows of pixels.
                let corners: Vec<Corner> = (y0..=y0 + rows)
                    .flat_map(|cy| (0..=w).map(move |cx| (cx, cy)))
                    .map(|(cx, cy)| Corner::see(tracer, cam, shadows, cx as u32, cy as u32))
                    .collect();
                let at = |cx: usize, cy: usize| &corners[(cy - y0) * (w + 1) + cx];
                for (i, flag) in flags.iter_mut().enumerate() {
                    let (x, y) = (i % w, y0 + i / w);
                    let four = [at(x, y), at(x + 1, y), at(x, y + 1), at(x + 1, y + 1)];
                    *flag = four
                        .iter()
                        .enumerate()
                        .any(|(k, a)| four[k + 1..].iter().any(|b| a.differs(b, shadows)));
                }
            });
        EdgeMap { width: w, edges }
    }

    /// Whether pixel (x, y) is an edge pixel.
    pub fn is_edge(&self, x: u32, y: u32) -> bool {
        self.edges
            .get(y as usize * self.width + x as usize)
            .copied()
            .unwrap_or(false)
    }

    /// How many pixels are edge pixels.
    pub fn count(&self) -> usize {
        self.edges.iter().filter(|e| **e).count()
    }
}

/// The camera sub-samples of pixel (x, y): `spp` of them, or `edge_spp` where the pixel is an
/// edge pixel of `edges`, which has none unless `edge_spp` exceeds `spp`. The bake and the
/// reference take the same ones.
pub fn pixel_subsamples(
    edges: &EdgeMap,
    cam: &Camera,
    settings: &BakeSettings,
    x: u32,
    y: u32,
) -> Vec<(f32, f32)> {
    let spp = if edges.is_edge(x, y) {
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
    /// The camera ray (origin, direction, distance to the surface it hits or infinity); `None`
    /// for a vertex.
    pub(super) ray: Option<(Vec3, Vec3, f32)>,
    /// How much of the environment behind the sub-sample is hidden: 1 behind a surface, the
    /// opacity 1 − T of a medium the ray only crosses, 0 for a clear miss.
    pub(super) covered: f32,
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
            uv: mesh.uvs[v],
            unit_albedo: mesh.is_textured(v),
        };
        return vec![Visit {
            point: Some(point),
            seen: 1.0,
            ray: None,
            covered: 1.0,
        }];
    }
    let cam = &ctx.scene.camera;
    pixel_subsamples(ctx.edges, cam, ctx.settings, x as u32, y as u32)
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
            // A surface hides the environment; a medium alone veils it by its opacity, so the
            // environment behind is seen through the transmittance and the medium's box never
            // shows as a slab.
            let covered = if found.is_some() {
                1.0
            } else if in_medium {
                1.0 - seen
            } else {
                0.0
            };
            Visit {
                point: found.map(|hit| shading_point(tracer, &hit, ray.dir)),
                seen,
                ray: Some((ray.origin, ray.dir, found.map_or(f32::INFINITY, |h| h.t))),
                covered,
            }
        })
        .collect()
}
