//! The triangles' BVH for both queries: four children a node with their boxes stored
//! uncompressed, component by component, so that one ray tests all four in a few SIMD
//! instructions, and leaves of four triangles stored the same way, tested against the ray
//! together.
//!
//! It is built from obvhs' binary BVH (SAH-quality PLOC with spatial pre-splits) by pulling the
//! largest of a node's inner descendants up until it has four children. obvhs' compressed
//! eight-wide BVH, which the tracer used before (and keeps for spheres, and as this one's slow
//! twin in tests), is made for GPU memory traffic; on the CPU, decoding its quantised boxes costs
//! more than reading plain ones: occlusion runs 2.1 times as fast through this one.

use std::time::Duration;

use glam::{BVec4A, Vec3, Vec3A, Vec4};
use obvhs::BvhBuildParams;
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::triangle::Triangle as BvhTriangle;

use super::BARYCENTRIC_SLACK;

/// A child slot's tag for a leaf: the rest holds its first triangle group and group count.
pub(super) const LEAF: u32 = 1 << 31;
/// Bits of a leaf's group count (minus one).
const COUNT_BITS: u32 = 3;
/// Most triangles the binary BVH puts in a leaf: one group of four (eight timed the same).
const MAX_LEAF_TRIANGLES: u32 = 4;
/// A child slot that holds nothing (its box is empty, so no ray reaches it).
pub(super) const EMPTY: u32 = LEAF - 1;
/// Traversal stack size. A pop pushes at most four, so depth D needs at most 3 D + 1 entries.
pub(super) const STACK: usize = 128;
/// Deepest tree the stack can hold; a deeper one is not used (see [`WideBvh::build`]).
const MAX_DEPTH: usize = (STACK - 1) / 3;
/// Smallest magnitude of a direction component whose reciprocal is taken, as a fraction of its
/// largest component. Smaller ones (and zeros) take this with their sign, so that no slab test
/// multiplies zero by infinity; the ray then drifts by 2^-60 of its length along that axis, far
/// inside the boxes' padding.
const MIN_COMPONENT_RELATIVE: f32 = 1.0 / (1u64 << 60) as f32;

/// Four children's boxes, each coordinate in a lane of its own.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct Node {
    /// The low corners, then the high ones. An empty slot's box runs from +inf to -inf.
    pub(super) bounds: [[Vec4; 3]; 2],
    pub(super) child: [u32; 4],
}

impl Node {
    const EMPTY: Node = Node {
        bounds: [[Vec4::INFINITY; 3], [Vec4::NEG_INFINITY; 3]],
        child: [EMPTY; 4],
    };
}

/// Four triangles as Möller–Trumbore wants them (a corner and two edges), lane by lane. Lanes
/// without a triangle hold NaN, which fails every comparison.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(super) struct Triangles4 {
    v0: [Vec4; 3],
    e1: [Vec4; 3],
    e2: [Vec4; 3],
}

impl Triangles4 {
    fn new(corners: &[[Vec3; 3]]) -> Triangles4 {
        let mut group = Triangles4 {
            v0: [Vec4::NAN; 3],
            e1: [Vec4::NAN; 3],
            e2: [Vec4::NAN; 3],
        };
        for (lane, [a, b, c]) in corners.iter().enumerate().take(4) {
            let (e1, e2) = (*b - *a, *c - *a);
            for axis in 0..3 {
                group.v0[axis][lane] = a[axis];
                group.e1[axis][lane] = e1[axis];
                group.e2[axis][lane] = e2[axis];
            }
        }
        group
    }

    /// The scalar test of [`super::intersect_triangle`], four lanes at a time: which lanes hit
    /// with t in (0, t_max), and their t, u and v.
    #[inline(always)]
    fn test(&self, o: [Vec4; 3], d: [Vec4; 3], t_max: Vec4) -> (BVec4A, Vec4, Vec4, Vec4) {
        let [e1x, e1y, e1z] = self.e1;
        let [e2x, e2y, e2z] = self.e2;
        let [dx, dy, dz] = d;
        let px = dy * e2z - dz * e2y;
        let py = dz * e2x - dx * e2z;
        let pz = dx * e2y - dy * e2x;
        let det = e1x * px + e1y * py + e1z * pz;
        let inv_det = Vec4::ONE / det;
        let sx = o[0] - self.v0[0];
        let sy = o[1] - self.v0[1];
        let sz = o[2] - self.v0[2];
        let u = (sx * px + sy * py + sz * pz) * inv_det;
        let qx = sy * e1z - sz * e1y;
        let qy = sz * e1x - sx * e1z;
        let qz = sx * e1y - sy * e1x;
        let v = (dx * qx + dy * qy + dz * qz) * inv_det;
        let t = (e2x * qx + e2y * qy + e2z * qz) * inv_det;
        // A zero determinant makes u infinite or NaN, which the range test refuses.
        let lo = Vec4::splat(-BARYCENTRIC_SLACK);
        let hi = Vec4::splat(1.0 + BARYCENTRIC_SLACK);
        let hit = u.cmpge(lo)
            & u.cmple(hi)
            & v.cmpge(lo)
            & (u + v).cmple(hi)
            & t.cmpgt(Vec4::ZERO)
            & t.cmplt(t_max);
        (hit, t, u, v)
    }

    /// Whether the ray hits any of the four with t in (0, t_max).
    #[inline(always)]
    pub(super) fn any_hit(&self, o: [Vec4; 3], d: [Vec4; 3], t_max: Vec4) -> bool {
        self.test(o, d, t_max).0.any()
    }

    /// The nearest of the four the ray hits with t in (0, t_max): its lane, t, u and v (the
    /// first lane of a tie).
    #[inline(always)]
    fn nearest(&self, o: [Vec4; 3], d: [Vec4; 3], t_max: Vec4) -> Option<(usize, f32, f32, f32)> {
        let (hit, t, u, v) = self.test(o, d, t_max);
        let mut lanes = hit.bitmask();
        let mut best: Option<usize> = None;
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            if best.is_none_or(|b| t[lane] < t[b]) {
                best = Some(lane);
            }
        }
        best.map(|lane| (lane, t[lane], u[lane], v[lane]))
    }
}

/// A direction as the box and triangle tests take it: the direction and its reciprocal in every
/// lane, and the side of each slab a ray along it enters by.
#[derive(Clone, Copy, Debug)]
pub(super) struct Dir4 {
    pub(super) d: [Vec4; 3],
    pub(super) inv: [Vec4; 3],
    /// 0 where the ray enters the axis's slab at its low side, 1 at its high side.
    pub(super) near: [usize; 3],
    far: [usize; 3],
}

impl Dir4 {
    #[inline(always)]
    pub(super) fn new(d: Vec3A) -> Dir4 {
        // Relative to the direction's largest component, so the test does not depend on its
        // length; the reciprocals stay finite (their products may overflow to a signed
        // infinity, which the slab test takes as it should).
        let floor = (d.abs().max_element() * MIN_COMPONENT_RELATIVE).max(f32::MIN_POSITIVE);
        let d_safe = d.to_array().map(|c| {
            if c.abs() < floor {
                floor.copysign(c)
            } else {
                c
            }
        });
        Dir4 {
            d: d.to_array().map(Vec4::splat),
            inv: d_safe.map(|c| Vec4::splat(1.0 / c)),
            near: d_safe.map(|c| (c < 0.0) as usize),
            far: d_safe.map(|c| (c >= 0.0) as usize),
        }
    }

    /// Where a ray from `o` (in every lane) enters each of the node's four boxes, and a bit for
    /// each it passes through with t in [0, t_max].
    #[inline(always)]
    pub(super) fn boxes(&self, n: &Node, o: &[Vec4; 3], t_max: Vec4) -> (Vec4, u32) {
        let (b, inv) = (&n.bounds, &self.inv);
        let (near, far) = (self.near, self.far);
        let enter = ((b[near[0]][0] - o[0]) * inv[0])
            .max((b[near[1]][1] - o[1]) * inv[1])
            .max(((b[near[2]][2] - o[2]) * inv[2]).max(Vec4::ZERO));
        let leave = ((b[far[0]][0] - o[0]) * inv[0])
            .min((b[far[1]][1] - o[1]) * inv[1])
            .min(((b[far[2]][2] - o[2]) * inv[2]).min(t_max));
        (enter, enter.cmple(leave).bitmask())
    }
}

/// A ray: its origin in every lane, and its direction.
struct Ray4 {
    o: [Vec4; 3],
    dir: Dir4,
}

impl Ray4 {
    #[inline(always)]
    fn new(o: Vec3A, d: Vec3A) -> Ray4 {
        Ray4 {
            o: o.to_array().map(Vec4::splat),
            dir: Dir4::new(d),
        }
    }

    /// [`Dir4::boxes`] from the ray's origin.
    #[inline(always)]
    fn boxes(&self, n: &Node, t_max: Vec4) -> (Vec4, u32) {
        self.dir.boxes(n, &self.o, t_max)
    }
}

/// A leaf's groups, from its child code.
#[inline(always)]
pub(super) fn leaf_groups(code: u32) -> std::ops::Range<usize> {
    let first = ((code & !LEAF) >> COUNT_BITS) as usize;
    let count = (code & ((1 << COUNT_BITS) - 1)) as usize + 1;
    first..first + count
}

/// No occluder remembered.
const NO_OCCLUDER: u32 = u32::MAX;

/// What a run of queries reuses: the traversal stack, and the triangle group that answered the
/// last occluded ray, which a neighbouring ray from the same point is likely to hit too.
#[derive(Clone, Debug)]
pub(super) struct Scratch {
    stack: [u32; STACK],
    last_occluder: u32,
}

impl Default for Scratch {
    fn default() -> Self {
        Scratch {
            stack: [0; STACK],
            last_occluder: NO_OCCLUDER,
        }
    }
}

/// The four-wide occlusion BVH over a scene's triangles.
#[derive(Debug, Default)]
pub(super) struct WideBvh {
    pub(super) nodes: Vec<Node>,
    pub(super) groups: Vec<Triangles4>,
    /// Each group's triangles, as indices into the triangles it was built from (`u32::MAX` in
    /// a lane without one).
    ids: Vec<[u32; 4]>,
}

impl WideBvh {
    /// Builds the BVH over triangles given by their corners, or `None` where the tree comes out
    /// deeper than the traversal stack holds (the caller then keeps its other BVH for these
    /// rays). `pad` widens every box on each side, to cover the rounding of the slab test and
    /// the triangle test's barycentric slack.
    pub(super) fn build(triangles: &[[Vec3; 3]], pad: f32) -> Option<WideBvh> {
        if triangles.is_empty() {
            return Some(WideBvh::default());
        }
        let bvh_tris: Vec<BvhTriangle> = triangles
            .iter()
            .map(|t| {
                let [v0, v1, v2] = t.map(Vec3A::from);
                BvhTriangle { v0, v1, v2 }
            })
            .collect();
        let params = BvhBuildParams {
            max_prims_per_leaf: MAX_LEAF_TRIANGLES,
            ..BvhBuildParams::slow_build()
        };
        let bvh2 = build_bvh2_from_tris(&bvh_tris, params, &mut Duration::default());
        let pad = Vec3::splat(pad.max(0.0));

        let mut wide = WideBvh {
            nodes: vec![Node::EMPTY],
            groups: Vec::new(),
            ids: Vec::new(),
        };
        // (binary node whose subtree fills it, wide node, depth)
        let mut work = vec![(0usize, 0usize, 1usize)];
        while let Some((root, slot, depth)) = work.pop() {
            if depth > MAX_DEPTH {
                return None;
            }
            let mut kids = Vec::with_capacity(4);
            let node = bvh2.nodes.get(root)?;
            if node.prim_count > 0 {
                kids.push(root);
            } else {
                let first = node.first_index as usize;
                kids.extend([first, first + 1]);
            }
            // Open the largest inner child until there are four.
            while kids.len() < 4 {
                let widest = kids
                    .iter()
                    .enumerate()
                    .filter(|(_, k)| bvh2.nodes.get(**k).is_some_and(|n| n.prim_count == 0))
                    .max_by(|a, b| {
                        let area = |k: usize| bvh2.nodes[k].aabb.half_area();
                        area(*a.1).total_cmp(&area(*b.1))
                    })
                    .map(|(i, _)| i);
                let Some(i) = widest else { break };
                let first = bvh2.nodes[kids[i]].first_index as usize;
                kids[i] = first;
                kids.push(first + 1);
            }
            for (lane, &k) in kids.iter().enumerate() {
                let child = bvh2.nodes.get(k)?;
                let (lo, hi) = (
                    Vec3::from(child.aabb.min) - pad,
                    Vec3::from(child.aabb.max) + pad,
                );
                let code = if child.prim_count > 0 {
                    let first = child.first_index as usize;
                    let ids = bvh2
                        .primitive_indices
                        .get(first..first + child.prim_count as usize)?;
                    let start = wide.groups.len();
                    for chunk in ids.chunks(4) {
                        let corners: Vec<[Vec3; 3]> = chunk
                            .iter()
                            .map(|&i| triangles.get(i as usize).copied())
                            .collect::<Option<_>>()?;
                        wide.groups.push(Triangles4::new(&corners));
                        let mut lanes = [u32::MAX; 4];
                        lanes[..chunk.len()].copy_from_slice(chunk);
                        wide.ids.push(lanes);
                    }
                    let count = (wide.groups.len() - start) as u32;
                    if count == 0
                        || count > 1 << COUNT_BITS
                        || start >= (EMPTY >> COUNT_BITS) as usize
                    {
                        return None;
                    }
                    LEAF | (start as u32) << COUNT_BITS | (count - 1)
                } else {
                    let index = wide.nodes.len();
                    if index >= EMPTY as usize {
                        return None;
                    }
                    wide.nodes.push(Node::EMPTY);
                    work.push((k, index, depth + 1));
                    index as u32
                };
                let n = &mut wide.nodes[slot];
                for axis in 0..3 {
                    n.bounds[0][axis][lane] = lo[axis];
                    n.bounds[1][axis][lane] = hi[axis];
                }
                n.child[lane] = code;
            }
        }
        Some(wide)
    }

    /// Whether a triangle lies along `o + t d` for t in (0, `t_max`). `d` must be finite and
    /// non-zero, `o` finite. The scratch's last occluder is tried first and updated; the answer
    /// does not depend on it.
    pub(super) fn occluded(&self, o: Vec3A, d: Vec3A, t_max: f32, scratch: &mut Scratch) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let ray = Ray4::new(o, d);
        let t_max4 = Vec4::splat(t_max);
        if let Some(group) = self.groups.get(scratch.last_occluder as usize) {
            if group.any_hit(ray.o, ray.dir.d, t_max4) {
                return true;
            }
            scratch.last_occluder = NO_OCCLUDER;
        }
        let stack = &mut scratch.stack;
        stack[0] = 0;
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            let (_, mut hits) = ray.boxes(n, t_max4);
            while hits != 0 {
                let lane = hits.trailing_zeros() as usize;
                hits &= hits - 1;
                let code = n.child[lane];
                if code & LEAF == 0 {
                    stack[top] = code;
                    top += 1;
                    continue;
                }
                let range = leaf_groups(code);
                let first = range.start;
                if let Some(i) = self.groups[range]
                    .iter()
                    .position(|g| g.any_hit(ray.o, ray.dir.d, t_max4))
                {
                    scratch.last_occluder = (first + i) as u32;
                    return true;
                }
            }
        }
        false
    }

    /// The nearest triangle along `o + t d` with t in (0, `t_max`): its t, barycentric u and v,
    /// and its index in the triangles the BVH was built from. Children are visited nearest
    /// first, and a box entered beyond the nearest hit so far is skipped.
    pub(super) fn closest(&self, o: Vec3A, d: Vec3A, t_max: f32) -> Option<(f32, f32, f32, u32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let ray = Ray4::new(o, d);
        let mut best_t = t_max;
        let mut best = None;
        let mut stack = [(0u32, 0.0f32); STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (node, entered) = stack[top];
            if entered > best_t {
                continue;
            }
            let n = &self.nodes[node as usize];
            let (enter, mut hits) = ray.boxes(n, Vec4::splat(best_t));
            let mut inner = [(0u32, 0.0f32); 4];
            let mut count = 0;
            while hits != 0 {
                let lane = hits.trailing_zeros() as usize;
                hits &= hits - 1;
                let code = n.child[lane];
                if code & LEAF == 0 {
                    inner[count] = (code, enter[lane]);
                    count += 1;
                    continue;
                }
                for g in leaf_groups(code) {
                    if let Some((lane, t, u, v)) =
                        self.groups[g].nearest(ray.o, ray.dir.d, Vec4::splat(best_t))
                    {
                        best_t = t;
                        best = Some((t, u, v, self.ids[g][lane]));
                    }
                }
            }
            // Farthest pushed first, so the nearest is taken next.
            let inner = &mut inner[..count];
            inner.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
            for &child in inner.iter() {
                stack[top] = child;
                top += 1;
            }
        }
        best
    }
}
