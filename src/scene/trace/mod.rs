//! Ray queries against a loaded [`Scene`]: closest hit for camera rays and any-hit occlusion
//! for the visibility rays of the bake.
//!
//! Triangles go into a four-wide BVH with plain boxes and leaves of four triangles (`wide`,
//! collapsed from obvhs' binary BVH, built with spatial pre-splits so that large triangles such
//! as a ground quad do not bloat the nodes); rays from one point ([`Tracer::rays_from`]) share
//! its stack and try the last ray's occluder first, or walk the tree together in packets of up
//! to 64 directions (`packet`), such as a block of cube texels' centres. Spheres get a
//! compressed eight-wide BVH (obvhs' CWBVH) over their bounding boxes, and so do triangles where
//! the four-wide tree would come out deeper than its stack, and in the tests, where it is the
//! four-wide one's slow twin. All are traversed with SIMD tests. The tracer is immutable after
//! construction, so one instance is shared by all threads, and every query is deterministic.

use std::time::Duration;

use glam::{UVec2, Vec2, Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::{build_cwbvh, build_cwbvh_from_tris};
use obvhs::ray::Ray as BvhRay;
use obvhs::triangle::Triangle as BvhTriangle;

use crate::scene::{Scene, Sphere};

mod packet;
mod wide;

pub use packet::PACKET;

/// Self-intersection offset as a fraction of the scene's extent. Hit points computed in f32 are
/// off by a few ulps of the coordinates (about 1e-7 relative); 1e-5 clears that a hundredfold
/// while staying far below any feature worth resolving.
pub const SPAWN_OFFSET_RELATIVE: f32 = 1e-5;

/// Barycentric slack of the ray/triangle test. Möller–Trumbore in f32 is not watertight: on an
/// edge shared by two triangles rounding can put the ray just outside both. Accepting a hair
/// outside closes those cracks; the overlap it creates is harmless for visibility.
const BARYCENTRIC_SLACK: f32 = 1e-6;

/// How far the four-wide BVH's boxes reach past their triangles, as a fraction of the scene's
/// extent. The barycentric slack lets a hit lie up to twice the slack times an edge past its
/// triangle's box on an axis (a corner at u = -slack, v = 1 + 2 slack); twice that again covers
/// the slab test's rounding, about thirty f32 ulps of the scene's coordinates.
const BOX_PAD_RELATIVE: f32 = 4.0 * BARYCENTRIC_SLACK;

/// A ray's intersection with a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit: distance along the ray in units of the direction's length.
    pub t: f32,
    /// World-space hit point.
    pub point: Vec3,
    /// Unit shading normal (interpolated vertex normal, or exact sphere normal), on the side the
    /// ray came from: `dot(normal, dir) <= 0`. Where an interpolated normal would face away from
    /// the ray it is bent to lie just on the ray's side.
    pub normal: Vec3,
    /// Unit normal of the surface itself, flipped to the ray's side: `dot(geometric_normal, dir)
    /// <= 0`. Offset spawned rays along this one (see [`Tracer::offset_origin`]).
    pub geometric_normal: Vec3,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Texture coordinate at the hit (zero on spheres and shapes without coordinates).
    pub uv: Vec2,
}

/// Triangle in the form the intersection test wants, stored in BVH leaf order.
#[derive(Clone, Copy, Debug)]
struct PackedTriangle {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

impl PackedTriangle {
    fn new(vertices: [Vec3; 3]) -> Self {
        let [a, b, c] = vertices.map(Vec3A::from);
        PackedTriangle {
            v0: a,
            e1: b - a,
            e2: c - a,
        }
    }
}

/// What shading needs of a triangle once it has been hit, in scene order.
#[derive(Clone, Copy, Debug)]
struct TriangleShading {
    normals: [Vec3; 3],
    uvs: [Vec2; 3],
    geometric: Vec3,
    material: u32,
}

/// Möller–Trumbore: (t, u, v) of a hit with t in (0, t_max), where the point is
/// `(1-u-v) v0 + u v1 + v v2`.
#[inline(always)]
fn intersect_triangle(
    tri: &PackedTriangle,
    o: Vec3A,
    d: Vec3A,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let p = d.cross(tri.e2);
    let det = tri.e1.dot(p);
    // A ray parallel to the plane cannot hit it (and NaN means a degenerate query).
    if det == 0.0 || det.is_nan() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = o - tri.v0;
    let u = s.dot(p) * inv_det;
    if !(-BARYCENTRIC_SLACK..=1.0 + BARYCENTRIC_SLACK).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = d.dot(q) * inv_det;
    if !(v >= -BARYCENTRIC_SLACK && u + v <= 1.0 + BARYCENTRIC_SLACK) {
        return None;
    }
    let t = tri.e2.dot(q) * inv_det;
    (t > 0.0 && t < t_max).then_some((t, u, v))
}

/// Nearest root t in (0, t_max) of |o + t d - center| = radius, for any non-zero `d`.
#[inline(always)]
fn intersect_sphere(center: Vec3A, radius: f32, o: Vec3A, d: Vec3A, t_max: f32) -> Option<f32> {
    let oc = o - center;
    let a = d.dot(d);
    let b = oc.dot(d);
    // Distance² of the centre from the ray's line, found from the closest point rather than
    // as b² - ac, which cancels catastrophically for far or tiny spheres.
    let closest = oc - d * (b / a);
    let disc = radius * radius - closest.dot(closest);
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    // The stable pair of roots: q / a and c / q, with q taking the sign of -b.
    let q = -(b + (a * disc).sqrt().copysign(b));
    let c = oc.dot(oc) - radius * radius;
    let (mut t0, mut t1) = (q / a, c / q);
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    [t0, t1].into_iter().find(|&t| t > 0.0 && t < t_max)
}

/// Closest-hit traversal: `test(slot, t_max)` returns the hit distance of the primitive in BVH
/// slot `slot`, or infinity. Returns the slot of the nearest hit; `ray.tmax` ends as its t.
#[inline(always)]
fn traverse_closest(
    bvh: &CwBvh,
    ray: &mut BvhRay,
    mut test: impl FnMut(usize, f32) -> f32,
) -> Option<u32> {
    if bvh.nodes.is_empty() {
        return None;
    }
    let mut best = None;
    let mut state = bvh.new_traversal(ray.direction);
    let mut node;
    obvhs::traverse!(bvh, node, state, node.intersect_ray(ray, state.oct_inv4), {
        let t = test(state.primitive_id as usize, ray.tmax);
        if t < ray.tmax {
            // Shrinking tmax lets the node tests cull everything behind this hit.
            ray.tmax = t;
            best = Some(state.primitive_id);
        }
    });
    best
}

/// Any-hit traversal: stops at the first slot for which `test` says hit.
#[inline(always)]
fn traverse_any(bvh: &CwBvh, ray: &BvhRay, mut test: impl FnMut(usize) -> bool) -> bool {
    if bvh.nodes.is_empty() {
        return false;
    }
    let mut state = bvh.new_traversal(ray.direction);
    let mut node;
    let mut hit = false;
    'search: {
        obvhs::traverse!(bvh, node, state, node.intersect_ray(ray, state.oct_inv4), {
            if test(state.primitive_id as usize) {
                hit = true;
                break 'search;
            }
        });
    }
    hit
}

/// Up to [`PACKET`] directions prepared once to be traced together from any point
/// ([`RaysFrom::occluded_packet`]), such as a block of cube texels' centres.
#[derive(Clone, Debug)]
pub struct RayPacket {
    dirs: Vec<Vec3>,
    /// The directions a ray can take (finite and non-zero), a bit each.
    valid: u64,
    packet: packet::Packet,
}

impl RayPacket {
    /// The packet of the first [`PACKET`] of `dirs`, in order: bit i of a mask is `dirs[i]`.
    pub fn new(dirs: &[Vec3]) -> RayPacket {
        let dirs = &dirs[..dirs.len().min(PACKET)];
        let valid = dirs
            .iter()
            .enumerate()
            .filter(|(_, d)| d.is_finite() && **d != Vec3::ZERO)
            .fold(0u64, |m, (i, _)| m | 1 << i);
        // A direction no ray takes stands in the packet as +x, which its mask leaves out.
        let usable = dirs.iter().enumerate().map(|(i, d)| match valid >> i & 1 {
            1 => Vec3A::from(*d),
            _ => Vec3A::X,
        });
        RayPacket {
            dirs: dirs.to_vec(),
            valid,
            packet: packet::Packet::new(usable),
        }
    }

    /// The packet's directions.
    pub fn dirs(&self) -> &[Vec3] {
        &self.dirs
    }
}

/// Occlusion queries from one origin; see [`Tracer::rays_from`].
pub struct RaysFrom<'a> {
    tracer: &'a Tracer,
    origin: Vec3,
    scratch: wide::Scratch,
}

impl RaysFrom<'_> {
    /// Whether anything lies along `origin + t * dir` for t in (0, `t_max`), as
    /// [`Tracer::occluded`].
    pub fn occluded(&mut self, dir: Vec3, t_max: f32) -> bool {
        let tracer = self.tracer;
        if let (Some(wide), true) = (&tracer.wide, tracer.spheres.is_empty()) {
            // The common case, without the BVH ray the spheres' traversal needs; the same
            // refusals as `Tracer::bvh_ray`.
            let ok = self.origin.is_finite() && dir.is_finite() && dir != Vec3::ZERO && t_max > 0.0;
            return ok && wide.occluded(self.origin.into(), dir.into(), t_max, &mut self.scratch);
        }
        let Some(ray) = Tracer::bvh_ray(self.origin, dir, t_max) else {
            return false;
        };
        let (o, d) = (ray.origin, ray.direction);
        // Spheres first: there are few of them and they tend to be big occluders.
        traverse_any(&tracer.sphere_bvh, &ray, |slot| {
            let s = &tracer.spheres[slot];
            intersect_sphere(s.center.into(), s.radius, o, d, t_max).is_some()
        }) || match &tracer.wide {
            Some(wide) => wide.occluded(o, d, t_max, &mut self.scratch),
            None => traverse_any(&tracer.triangle_bvh, &ray, |slot| {
                intersect_triangle(&tracer.packed[slot], o, d, t_max).is_some()
            }),
        }
    }

    /// Which of the packet's rays with a bit in `active` are occluded along t in (0, `t_max`),
    /// a bit each: ray for ray the answers of [`RaysFrom::occluded`], traced together.
    pub fn occluded_packet(&mut self, packet: &RayPacket, active: u64, t_max: f32) -> u64 {
        let tracer = self.tracer;
        let active = active & packet.valid;
        if let (Some(wide), true) = (&tracer.wide, tracer.spheres.is_empty()) {
            let ok = self.origin.is_finite() && t_max > 0.0;
            return match ok {
                true => wide.occluded_packet(self.origin.into(), &packet.packet, active, t_max),
                false => 0,
            };
        }
        packet::bits(active)
            .filter(|&i| self.occluded(packet.dirs[i], t_max))
            .fold(0, |m, i| m | 1 << i)
    }
}

/// Ray-tracing acceleration structure over a scene. Build once with [`Tracer::new`], then
/// query from any number of threads (it is `Send + Sync`).
pub struct Tracer {
    triangle_bvh: CwBvh,
    /// Triangles in BVH slot order (a pre-split triangle occupies several slots).
    packed: Vec<PackedTriangle>,
    /// Scene triangle index of each BVH slot.
    packed_ids: Vec<u32>,
    /// Shading data in scene order.
    shading: Vec<TriangleShading>,
    sphere_bvh: CwBvh,
    /// Spheres in BVH slot order.
    spheres: Vec<Sphere>,
    /// The triangles' four-wide BVH, which answers both queries where it could be built (see
    /// [`wide::WideBvh::build`]); the compressed one answers them where it could not.
    wide: Option<wide::WideBvh>,
    spawn_offset: f32,
}

impl Tracer {
    /// Builds the BVHs over the scene's triangles and spheres. The scene's geometry must be
    /// finite, which [`Scene::load`] guarantees.
    pub fn new(scene: &Scene) -> Tracer {
        Self::build(scene, true)
    }

    /// The tracer, its triangles in the four-wide BVH where `wide` is set and it can be built,
    /// else in the compressed one.
    fn build(scene: &Scene, wide: bool) -> Tracer {
        let shading = scene
            .triangles
            .iter()
            .map(|t| TriangleShading {
                normals: t.normals,
                uvs: t.uvs,
                geometric: t.geometric_normal(),
                material: t.material,
            })
            .collect();

        let (lo, hi) = scene.bounds();
        let extent = lo
            .abs()
            .max(hi.abs())
            .max_element()
            .max((hi - lo).max_element());
        let corners: Vec<[Vec3; 3]> = scene.triangles.iter().map(|t| t.vertices).collect();
        let wide = wide
            .then(|| wide::WideBvh::build(&corners, BOX_PAD_RELATIVE * extent))
            .flatten();
        let (triangle_bvh, packed, packed_ids) = if scene.triangles.is_empty() || wide.is_some() {
            (CwBvh::default(), Vec::new(), Vec::new())
        } else {
            let bvh_tris: Vec<BvhTriangle> = scene
                .triangles
                .iter()
                .map(|t| {
                    let [v0, v1, v2] = t.vertices.map(Vec3A::from);
                    BvhTriangle { v0, v1, v2 }
                })
                .collect();
            // Pre-splitting costs a little build time and pays off in traversal: a scene's
            // few large triangles (ground quads) otherwise overlap every node.
            let bvh = build_cwbvh_from_tris(
                &bvh_tris,
                BvhBuildParams::slow_build(),
                &mut Duration::default(),
            );
            let packed = in_leaf_order(&bvh, |i| PackedTriangle::new(scene.triangles[i].vertices));
            let ids = bvh.primitive_indices.clone();
            (bvh, packed, ids)
        };

        let (sphere_bvh, spheres) = if scene.spheres.is_empty() {
            (CwBvh::default(), Vec::new())
        } else {
            let boxes: Vec<Aabb> = scene
                .spheres
                .iter()
                .map(|s| {
                    let c = Vec3A::from(s.center);
                    Aabb::new(c - s.radius, c + s.radius)
                })
                .collect();
            let bvh = build_cwbvh(
                &boxes,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            );
            let spheres = in_leaf_order(&bvh, |i| scene.spheres[i]);
            (bvh, spheres)
        };

        let spawn_offset = SPAWN_OFFSET_RELATIVE * extent.max(f32::MIN_POSITIVE);

        Tracer {
            triangle_bvh,
            packed,
            packed_ids,
            shading,
            sphere_bvh,
            spheres,
            wide,
            spawn_offset,
        }
    }

    /// The BVH ray, or `None` for a query that can hit nothing (zero or non-finite direction,
    /// non-finite origin, `t_max` not > 0).
    fn bvh_ray(origin: Vec3, dir: Vec3, t_max: f32) -> Option<BvhRay> {
        let ok = origin.is_finite() && dir.is_finite() && dir != Vec3::ZERO && t_max > 0.0;
        // obvhs picks a node's near planes from `dir < 0` but inverts -0.0 to a negative
        // number, so an axis-aligned ray such as -Y (which has -0.0 components) would see every
        // box inside out. Adding +0.0 turns -0.0 into +0.0 and leaves all else unchanged.
        let dir = Vec3A::from(dir) + Vec3A::ZERO;
        ok.then(|| BvhRay::new(origin.into(), dir, 0.0, t_max))
    }

    /// The nearest surface along `origin + t * dir` with t in (0, `t_max`), if any. `dir` need
    /// not be unit length (t is in units of it); `t_max` may be infinite.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<Hit> {
        let mut ray = Self::bvh_ray(origin, dir, t_max)?;
        let (o, d) = (ray.origin, ray.direction);

        // The triangle hit: its index in the scene and its barycentric u and v.
        let triangle = match &self.wide {
            Some(wide) => wide.closest(o, d, ray.tmax).map(|(t, u, v, id)| {
                ray.tmax = t;
                (id, u, v)
            }),
            None => {
                let slot = traverse_closest(&self.triangle_bvh, &mut ray, |slot, t_max| {
                    intersect_triangle(&self.packed[slot], o, d, t_max)
                        .map_or(f32::INFINITY, |h| h.0)
                });
                // Same inputs as during traversal, so this reproduces the winning test exactly.
                slot.and_then(|slot| {
                    let (_, u, v) =
                        intersect_triangle(&self.packed[slot as usize], o, d, f32::INFINITY)?;
                    Some((self.packed_ids[slot as usize], u, v))
                })
            }
        };
        let sphere_slot = traverse_closest(&self.sphere_bvh, &mut ray, |slot, t_max| {
            let s = &self.spheres[slot];
            intersect_sphere(s.center.into(), s.radius, o, d, t_max).unwrap_or(f32::INFINITY)
        });
        let t = ray.tmax;

        let (point, shading_normal, geometric, material, uv) = if let Some(slot) = sphere_slot {
            let s = &self.spheres[slot as usize];
            let n = (origin + t * dir - s.center).normalize();
            // Projecting onto the surface removes the root's rounding error from the point.
            (s.center + n * s.radius, n, n, s.material, Vec2::ZERO)
        } else {
            let (id, u, v) = triangle?;
            let sh = self.shading.get(id as usize)?;
            let n = sh.normals[0] * (1.0 - u - v) + sh.normals[1] * u + sh.normals[2] * v;
            let n = n.normalize_or_zero();
            let n = if n == Vec3::ZERO { sh.geometric } else { n };
            let uv = sh.uvs[0] * (1.0 - u - v) + sh.uvs[1] * u + sh.uvs[2] * v;
            (origin + t * dir, n, sh.geometric, sh.material, uv)
        };

        // Two-sided surfaces: the side the ray arrived on is the side we shade.
        let side = if geometric.dot(dir) > 0.0 { -1.0 } else { 1.0 };
        let geometric_normal = geometric * side;
        let mut normal = shading_normal * side;
        let along = normal.dot(dir);
        if along > 0.0 {
            // Interpolated normals can face away near silhouettes; tip them just past
            // perpendicular to the ray so callers can rely on the sign.
            let d = dir.normalize();
            let bent = (normal - d * (normal.dot(d) + 1e-3)).normalize_or_zero();
            normal = if bent == Vec3::ZERO {
                geometric_normal
            } else {
                bent
            };
        }

        Some(Hit {
            t,
            point,
            normal,
            geometric_normal,
            material,
            uv,
        })
    }

    /// Whether anything lies along `origin + t * dir` for t in (0, `t_max`). Stops at the first
    /// hit found, in no particular order, so it is cheaper than [`Tracer::closest_hit`]. Rays
    /// that share an origin are cheaper through [`Tracer::rays_from`].
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        self.rays_from(origin).occluded(dir, t_max)
    }

    /// Occlusion queries from one point, such as a shading point's shadow rays: they share a
    /// traversal stack and try the last ray's occluder first. Each answers as
    /// [`Tracer::occluded`] does.
    pub fn rays_from(&self, origin: Vec3) -> RaysFrom<'_> {
        RaysFrom {
            tracer: self,
            origin,
            scratch: wide::Scratch::default(),
        }
    }

    /// Distance by which to move a ray origin off a surface to avoid hitting that same surface
    /// again: [`SPAWN_OFFSET_RELATIVE`] times the scene's extent (the largest of its bounds'
    /// absolute coordinates and side lengths), so it tracks f32 rounding at the scene's scale.
    pub fn spawn_offset(&self) -> f32 {
        self.spawn_offset
    }

    /// Origin for a ray leaving `hit` in direction `dir`: the hit point moved by
    /// [`Tracer::spawn_offset`] along the geometric normal, to the side `dir` goes to (so
    /// reflected rays start above the surface and transmitted ones below it).
    pub fn offset_origin(&self, hit: &Hit, dir: Vec3) -> Vec3 {
        let side = if hit.geometric_normal.dot(dir) >= 0.0 {
            1.0
        } else {
            -1.0
        };
        hit.point + hit.geometric_normal * (side * self.spawn_offset)
    }
}

/// `f` of each primitive in the order `bvh`'s leaves hold them.
fn in_leaf_order<T>(bvh: &CwBvh, f: impl Fn(usize) -> T) -> Vec<T> {
    bvh.primitive_indices
        .iter()
        .map(|&i| f(i as usize))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::*;
    use std::fmt::Write as _;
    use std::path::Path;

    /// Hit distances and points in scenes a few units across.
    const T_TOL: f32 = 1e-5;
    /// Unit normals.
    const N_TOL: f32 = 1e-5;

    fn canonical() -> Scene {
        Scene::from_toml_str(CANONICAL, Path::new("/nonexistent/scene.toml")).unwrap()
    }

    fn material(scene: &Scene, name: &str) -> u32 {
        scene.material_names.iter().position(|n| n == name).unwrap() as u32
    }

    #[test]
    fn tracer_is_send_and_sync() {
        fn check<T: Send + Sync>() {}
        check::<Tracer>();
    }

    #[test]
    fn ray_hits_sphere_top() {
        let scene = canonical();
        let tracer = Tracer::new(&scene);
        let hit = tracer
            .closest_hit(Vec3::new(0.0, 3.0, 0.0), -Vec3::Y, f32::INFINITY)
            .expect("hits the sphere");
        assert_close("t", hit.t, 1.8, T_TOL);
        assert_vec_close("point", hit.point, Vec3::new(0.0, 1.2, 0.0), T_TOL);
        assert_vec_close("normal", hit.normal, Vec3::Y, N_TOL);
        assert_vec_close("geometric normal", hit.geometric_normal, Vec3::Y, N_TOL);
        assert_eq!(hit.material, material(&scene, "clay"));

        // Off-axis: a ray along -Z at height 0.6 + 0.3 hits where z = sqrt(0.6² - 0.3²).
        let hit = tracer
            .closest_hit(Vec3::new(0.0, 0.9, 5.0), -Vec3::Z, f32::INFINITY)
            .unwrap();
        let z = (0.36f32 - 0.09).sqrt();
        assert_close("t", hit.t, 5.0 - z, T_TOL);
        assert_vec_close("normal", hit.normal, Vec3::new(0.0, 0.3, z) / 0.6, N_TOL);

        // A non-unit direction measures t in its own units.
        let hit = tracer
            .closest_hit(Vec3::new(0.0, 3.0, 0.0), Vec3::new(0.0, -2.0, 0.0), 10.0)
            .unwrap();
        assert_close("t (|dir| = 2)", hit.t, 0.9, T_TOL);
    }

    #[test]
    fn ray_from_inside_sphere_sees_inner_side() {
        let tracer = Tracer::new(&canonical());
        let hit = tracer
            .closest_hit(Vec3::new(0.0, 0.6, 0.0), Vec3::X, f32::INFINITY)
            .unwrap();
        assert_close("t", hit.t, 0.6, T_TOL);
        assert_vec_close("normal faces the ray", hit.normal, -Vec3::X, N_TOL);
        assert_vec_close("geometric", hit.geometric_normal, -Vec3::X, N_TOL);
    }

    #[test]
    fn ray_hits_both_quad_triangles_and_misses_outside() {
        let scene = canonical();
        let tracer = Tracer::new(&scene);
        for (x, z) in [(1.5, 1.0), (1.0, 1.5), (-1.5, 1.9), (1.9, -1.5)] {
            let hit = tracer
                .closest_hit(Vec3::new(x, 1.0, z), -Vec3::Y, f32::INFINITY)
                .unwrap_or_else(|| panic!("ground at ({x}, {z})"));
            assert_close("t", hit.t, 1.0, T_TOL);
            assert_vec_close("point", hit.point, Vec3::new(x, 0.0, z), T_TOL);
            assert_vec_close("normal", hit.normal, Vec3::Y, N_TOL);
            assert_eq!(hit.material, material(&scene, "ground"));
        }
        assert!(
            tracer
                .closest_hit(Vec3::new(2.5, 1.0, 0.0), -Vec3::Y, f32::INFINITY)
                .is_none()
        );
        // t_max shorter than the distance: no hit.
        assert!(
            tracer
                .closest_hit(Vec3::new(1.5, 1.0, 1.5), -Vec3::Y, 0.99)
                .is_none()
        );
    }

    #[test]
    fn quad_is_two_sided() {
        let tracer = Tracer::new(&canonical());
        let hit = tracer
            .closest_hit(Vec3::new(1.5, -1.0, 1.5), Vec3::Y, f32::INFINITY)
            .expect("hits the ground from below");
        assert_close("t", hit.t, 1.0, T_TOL);
        assert_vec_close("normal", hit.normal, -Vec3::Y, N_TOL);
        assert_vec_close("geometric", hit.geometric_normal, -Vec3::Y, N_TOL);
        // Spawning back downwards stays below; upwards crosses to above.
        let below = tracer.offset_origin(&hit, -Vec3::Y);
        assert!(below.y < 0.0 && below.y >= -2.0 * tracer.spawn_offset());
        assert!(tracer.offset_origin(&hit, Vec3::Y).y > 0.0);
    }

    #[test]
    fn shading_normal_is_interpolated_and_faces_the_ray() {
        let dir = temp_dir("trace-vn");
        // A flat triangle whose vertex normals lean towards +X by different amounts.
        std::fs::write(
            dir.join("m.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 0 -1\nvn 0 1 0\nvn 1 1 0\nvn 0 1 0\nf 1//1 2//2 3//3\n",
        )
        .unwrap();
        let text = CANONICAL.replace(
            "[[shape]]\ntype = \"quad\"",
            "[[shape]]\ntype = \"mesh\"\npath = \"m.obj\"\ntranslate = [0.0, 5.0, 0.0]\nmaterial = \"clay\"\n\n[[shape]]\ntype = \"quad\"",
        );
        let scene = Scene::from_toml_str(&text, &dir.join("scene.toml")).unwrap();
        let tracer = Tracer::new(&scene);
        // At barycentric u = 0.5, v = 0.25 the normal is 0.25 (0,1,0) + 0.5 (1,1,0)/√2 + 0.25 (0,1,0).
        let p = Vec3::new(0.5, 5.0, -0.25);
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let expected = (Vec3::new(0.0, 0.5, 0.0) + 0.5 * Vec3::new(s, s, 0.0)).normalize();
        let down = tracer
            .closest_hit(p + Vec3::Y, -Vec3::Y, f32::INFINITY)
            .unwrap();
        assert_vec_close("point", down.point, p, T_TOL);
        assert_vec_close("from above", down.normal, expected, N_TOL);
        assert_vec_close("geometric", down.geometric_normal, Vec3::Y, N_TOL);
        let up = tracer
            .closest_hit(p - Vec3::Y, Vec3::Y, f32::INFINITY)
            .unwrap();
        assert_vec_close("from below", up.normal, -expected, N_TOL);

        // A grazing ray that sees the front while the interpolated normal leans away.
        let grazing = Vec3::new(1.0, -0.2, 0.0).normalize();
        let hit = tracer
            .closest_hit(p - grazing, grazing, f32::INFINITY)
            .unwrap();
        assert!(
            hit.normal.dot(grazing) <= 0.0,
            "{} · {grazing} > 0",
            hit.normal
        );
        assert!(hit.geometric_normal.dot(grazing) <= 0.0);
        assert_close("|normal|", hit.normal.length(), 1.0, N_TOL);
    }

    /// Rays that graze the ground quad's edges and corners within the barycentric slack, with
    /// directions from unit length down to 1e-18: the boxes' padding and the slab test's guard
    /// against tiny components must keep every hit the triangle test makes.
    #[test]
    fn rays_at_the_edges_answer_as_brute_force_at_any_direction_length() {
        let scene = canonical();
        let tracer = Tracer::new(&scene);
        assert!(tracer.wide.is_some());
        let mut hits = 0;
        for (x, z) in [
            (2.0f32, 0.7f32),
            (-2.0, -1.3),
            (0.4, 2.0),
            (-0.9, -2.0),
            (2.0, 2.0),
            (-2.0, 2.0),
        ] {
            for k in -6..=6 {
                // Past (or short of) the edge by k millionths of the ground's side.
                let step = k as f32 * 1e-6 * 4.0;
                let at = Vec3::new(x + x.signum() * step, 1.0, z + z.signum() * step * 0.5);
                for scale in [1.0f32, 1e-6, 1e-12, 2e-18] {
                    let dir = Vec3::new(0.0, -scale, 0.0);
                    let want = brute_force_t(&scene, at, dir, f32::INFINITY).is_some();
                    assert_eq!(
                        tracer.occluded(at, dir, f32::INFINITY),
                        want,
                        "from {at} along {dir}"
                    );
                    let mut from = tracer.rays_from(at);
                    assert_eq!(
                        from.occluded(dir, f32::INFINITY),
                        want,
                        "rays_from {at} along {dir}"
                    );
                    assert_eq!(
                        tracer.closest_hit(at, dir, f32::INFINITY).is_some(),
                        want,
                        "closest from {at} along {dir}"
                    );
                    hits += usize::from(want);
                }
            }
        }
        // Both sides of every edge are tried.
        assert!(hits > 40 && hits < 6 * 13 * 4 - 40, "{hits} hits");
    }

    #[test]
    fn ground_under_sphere_is_occluded() {
        let scene = canonical();
        let tracer = Tracer::new(&scene);
        let hit = tracer
            .closest_hit(Vec3::new(0.1, -1.0, 0.0), Vec3::Y, f32::INFINITY)
            .unwrap();
        assert_eq!(hit.material, material(&scene, "ground"));
        // The hit came from below; flip to the top side as the bake would for a visible point.
        let top = Hit {
            normal: Vec3::Y,
            geometric_normal: Vec3::Y,
            ..hit
        };
        let origin = tracer.offset_origin(&top, Vec3::Y);
        assert!(tracer.occluded(origin, Vec3::Y, f32::INFINITY));
        // The sphere's underside is 0.0084 above this point: a shorter ray does not reach it.
        let origin_under = Vec3::new(0.1, 1e-3, 0.0);
        assert!(!tracer.occluded(origin_under, Vec3::Y, 1e-3));
        let far = Vec3::new(1.8, tracer.spawn_offset(), 1.8);
        assert!(!tracer.occluded(far, Vec3::Y, f32::INFINITY));
        assert!(tracer.occluded(far, Vec3::new(-1.8, 0.6, -1.8), f32::INFINITY));
    }

    #[test]
    fn degenerate_queries_hit_nothing() {
        let tracer = Tracer::new(&canonical());
        let o = Vec3::new(0.0, 3.0, 0.0);
        for (origin, dir, t_max) in [
            (o, Vec3::ZERO, 10.0),
            (o, Vec3::new(f32::NAN, -1.0, 0.0), 10.0),
            (Vec3::splat(f32::INFINITY), -Vec3::Y, 10.0),
            (o, -Vec3::Y, 0.0),
            (o, -Vec3::Y, f32::NAN),
        ] {
            assert!(tracer.closest_hit(origin, dir, t_max).is_none());
            assert!(!tracer.occluded(origin, dir, t_max));
        }
    }

    #[test]
    fn tiny_and_empty_scenes_work() {
        let mut scene = canonical();
        // One triangle only, no spheres: the smallest BVH.
        scene.triangles.truncate(1);
        scene.spheres.clear();
        let tracer = Tracer::new(&scene);
        let hit = tracer
            .closest_hit(Vec3::new(-1.5, 1.0, 1.0), -Vec3::Y, f32::INFINITY)
            .expect("the remaining triangle");
        assert_close("t", hit.t, 1.0, T_TOL);
        assert!(tracer.occluded(Vec3::new(-1.5, 1.0, 1.0), -Vec3::Y, 2.0));
        // The other half of the quad is gone.
        assert!(
            tracer
                .closest_hit(Vec3::new(1.5, 1.0, -1.0), -Vec3::Y, f32::INFINITY)
                .is_none()
        );

        scene.triangles.clear();
        let tracer = Tracer::new(&scene);
        assert!(
            tracer
                .closest_hit(Vec3::ZERO, Vec3::Y, f32::INFINITY)
                .is_none()
        );
        assert!(!tracer.occluded(Vec3::ZERO, Vec3::Y, f32::INFINITY));
        assert!(tracer.spawn_offset() > 0.0);
    }

    /// An icosphere of `subdivisions` levels as OBJ text (unwelded is fine: vertices are
    /// shared by index).
    fn icosphere_obj(subdivisions: u32) -> (String, usize) {
        use crate::scene::tessellate::{ICOSAHEDRON_FACES, icosahedron_directions};
        let mut verts: Vec<Vec3> = icosahedron_directions().to_vec();
        let mut faces: Vec<[usize; 3]> = ICOSAHEDRON_FACES
            .iter()
            .map(|f| f.map(|i| i as usize))
            .collect();
        for _ in 0..subdivisions {
            let mut midpoints = std::collections::HashMap::new();
            let mut mid = |a: usize, b: usize, verts: &mut Vec<Vec3>| {
                *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    verts.push(((verts[a] + verts[b]) * 0.5).normalize());
                    verts.len() - 1
                })
            };
            let mut next = Vec::with_capacity(faces.len() * 4);
            for [a, b, c] in faces {
                let ab = mid(a, b, &mut verts);
                let bc = mid(b, c, &mut verts);
                let ca = mid(c, a, &mut verts);
                next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
            faces = next;
        }
        let mut text = String::new();
        for v in &verts {
            writeln!(text, "v {} {} {}", v.x, v.y, v.z).unwrap();
        }
        for [a, b, c] in &faces {
            writeln!(text, "f {} {} {}", a + 1, b + 1, c + 1).unwrap();
        }
        (text, faces.len())
    }

    /// Slow twin of `closest_hit`: every primitive, no BVH.
    fn brute_force_t(scene: &Scene, origin: Vec3, dir: Vec3, t_max: f32) -> Option<f32> {
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let tris = scene.triangles.iter().filter_map(|t| {
            intersect_triangle(&PackedTriangle::new(t.vertices), o, d, t_max).map(|h| h.0)
        });
        let spheres = scene
            .spheres
            .iter()
            .filter_map(|s| intersect_sphere(s.center.into(), s.radius, o, d, t_max));
        tris.chain(spheres).min_by(f32::total_cmp)
    }

    #[test]
    fn bvh_agrees_with_brute_force_on_random_rays() {
        let dir = temp_dir("trace-random");
        let (obj, faces) = icosphere_obj(3);
        std::fs::write(dir.join("ico.obj"), obj).unwrap();
        let text = format!(
            "{CANONICAL}
[[shape]]
type = \"mesh\"
path = \"ico.obj\"
scale = 0.5
translate = [1.2, 0.5, -0.4]
material = \"clay\"

[[shape]]
type = \"mesh\"
path = \"ico.obj\"
scale = 0.3
rotate_y_deg = 17.0
translate = [-1.0, 0.3, 0.9]
material = \"ground\"

[[shape]]
type = \"sphere\"
center = [-1.2, 0.25, -1.0]
radius = 0.25
material = \"clay\"
"
        );
        let scene = Scene::from_toml_str(&text, &dir.join("scene.toml")).unwrap();
        assert_eq!(scene.triangle_count(), 2 + 2 * faces);
        let tracer = Tracer::new(&scene);

        let mut rng = Rng(0x5eed_1234);
        let (mut hits, mut occluded) = (0, 0);
        const RAYS: usize = 20_000;
        for i in 0..RAYS {
            let origin = Vec3::new(
                rng.range_f32(-2.5, 2.5),
                rng.range_f32(-0.5, 2.0),
                rng.range_f32(-2.5, 2.5),
            );
            // Every seventh ray is axis-aligned: their zero (and -0.0) components are the
            // edge case of the BVH's slab tests.
            let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
            let unit = if i % 7 == 0 {
                axes[(rng.next_u64() % 6) as usize]
            } else {
                rng.unit_vector()
            };
            let dir = unit * if i % 4 == 0 { 2.5 } else { 1.0 };
            let t_max = if i % 3 == 0 {
                f32::INFINITY
            } else {
                rng.range_f32(0.05, 3.0)
            };
            let expected = brute_force_t(&scene, origin, dir, t_max);
            let got = tracer.closest_hit(origin, dir, t_max);
            match (got, expected) {
                (Some(h), Some(t)) => {
                    assert_close(format!("ray {i} t"), h.t, t, T_TOL * t.max(1.0));
                    assert_vec_close(&format!("ray {i} point"), h.point, origin + dir * t, 1e-4);
                    assert!(h.normal.dot(dir) <= 0.0 && h.geometric_normal.dot(dir) <= 0.0);
                    hits += 1;
                }
                (None, None) => {}
                _ => panic!(
                    "ray {i} from {origin} along {dir} (t_max {t_max}): bvh {got:?}, brute force {expected:?}"
                ),
            }
            let blocked = tracer.occluded(origin, dir, t_max);
            assert_eq!(
                blocked,
                got.is_some(),
                "ray {i} from {origin} along {dir} (t_max {t_max}): occluded disagrees with closest_hit"
            );
            occluded += usize::from(blocked);
        }
        // The test only means something if both outcomes are common.
        assert!(hits > RAYS / 10 && hits < RAYS * 9 / 10, "{hits} hits");
        assert_eq!(hits, occluded);
    }

    /// The four-wide BVH, and the stack and occluder that rays from one point share, against
    /// the compressed BVH's traversals (its slow twin) and brute force, on the demo's teapot
    /// scene from shading points of a camera grid.
    #[test]
    fn rays_from_a_point_agree_with_the_compressed_bvh_and_brute_force() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/demo.toml");
        let scene = Scene::load(&path).unwrap();
        assert!(
            scene.spheres.is_empty(),
            "the fast path is for triangles only"
        );
        let tracer = Tracer::new(&scene);
        assert!(tracer.wide.is_some());
        let twin = Tracer::build(&scene, false);
        let mut rng = Rng(0xfeed_5eed);
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let dirs: Vec<Vec3> = (0..1500)
            .map(|i| if i < 6 { axes[i] } else { rng.unit_vector() })
            .collect();
        let cam = &scene.camera;
        let (mut rays, mut blocked) = (0usize, 0usize);
        for y in 0..6 {
            for x in 0..6 {
                let ray = cam.ray(
                    (x as f32 + 0.5) * cam.width as f32 / 6.0,
                    (y as f32 + 0.5) * cam.height as f32 / 6.0,
                );
                let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
                    continue;
                };
                let origin = hit.point + hit.geometric_normal * tracer.spawn_offset();
                let mut from = tracer.rays_from(origin);
                let forward: Vec<bool> = dirs
                    .iter()
                    .map(|d| from.occluded(*d, f32::INFINITY))
                    .collect();
                let mut from = tracer.rays_from(origin);
                let backward: Vec<bool> = dirs
                    .iter()
                    .rev()
                    .map(|d| from.occluded(*d, f32::INFINITY))
                    .collect();
                for (i, d) in dirs.iter().enumerate() {
                    let expected = twin.occluded(origin, *d, f32::INFINITY);
                    assert_eq!(forward[i], expected, "from {origin} along {d}");
                    assert_eq!(
                        backward[dirs.len() - 1 - i],
                        expected,
                        "reversed, along {d}"
                    );
                    // Rays that end early, through the same scratch.
                    let t_max = rng.range_f32(0.0, 2.0);
                    assert_eq!(
                        from.occluded(*d, t_max),
                        twin.occluded(origin, *d, t_max),
                        "from {origin} along {d} to t = {t_max}"
                    );
                    if i % 16 == 0 {
                        let brute = brute_force_t(&scene, origin, *d, f32::INFINITY);
                        assert_eq!(
                            expected,
                            brute.is_some(),
                            "brute force from {origin} along {d}"
                        );
                    }
                    // The nearest hit, against the compressed BVH's.
                    if i % 4 == 0 {
                        let (got, want) = (
                            tracer.closest_hit(origin, *d, f32::INFINITY),
                            twin.closest_hit(origin, *d, f32::INFINITY),
                        );
                        assert_eq!(got.is_some(), expected, "closest hit along {d}");
                        if let (Some(g), Some(w)) = (got, want) {
                            assert_close(format!("t along {d}"), g.t, w.t, T_TOL * w.t.max(1.0));
                            assert_vec_close(
                                "normal",
                                g.geometric_normal,
                                w.geometric_normal,
                                1e-3,
                            );
                            assert_vec_close("shading normal", g.normal, w.normal, 1e-3);
                            assert!((g.uv - w.uv).abs().max_element() < 1e-3, "uv along {d}");
                            assert_eq!(g.material, w.material, "material along {d}");
                        }
                    }
                    rays += 1;
                    blocked += usize::from(expected);
                }
            }
        }
        assert!(rays > 40_000, "{rays} rays");
        assert!(
            blocked > rays / 20 && blocked < rays * 19 / 20,
            "{blocked} of {rays} occluded"
        );
    }

    #[test]
    fn offset_origin_escapes_curved_and_flat_surfaces() {
        let scene = canonical();
        let tracer = Tracer::new(&scene);
        let mut rng = Rng(99);
        // Camera-like rays onto sphere and ground, then shadow rays leaving the hit point on its
        // own side: none may re-hit the surface it starts on at t ≈ 0.
        for _ in 0..2000 {
            let origin = Vec3::new(rng.range_f32(-3.0, 3.0), 3.0, rng.range_f32(-3.0, 3.0));
            let target = Vec3::new(rng.range_f32(-1.0, 1.0), 0.0, rng.range_f32(-1.0, 1.0));
            let Some(hit) = tracer.closest_hit(origin, target - origin, f32::INFINITY) else {
                continue;
            };
            // Where sphere and ground touch, the other surface is legitimately that close.
            if hit.point.length() < 0.1 {
                continue;
            }
            let mut out = rng.unit_vector();
            if out.dot(hit.geometric_normal) < 0.0 {
                out = -out;
            }
            let start = tracer.offset_origin(&hit, out);
            if let Some(again) = tracer.closest_hit(start, out, f32::INFINITY) {
                assert!(
                    again.t > 10.0 * tracer.spawn_offset(),
                    "self-hit at t = {} from {}",
                    again.t,
                    hit.point
                );
            }
        }
    }
}
