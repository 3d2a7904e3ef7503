//! Rays from one point traced together through the four-wide BVH: a packet of up to 64
//! directions (a block of cube texels, say) walks the tree once. A node's boxes are first tested
//! against the whole packet by interval arithmetic over its reciprocal directions, which culls
//! the boxes no ray of it reaches; then only the first and the last ray that enter each box are
//! found, and the rays between them go on together. At the nodes above leaves every ray is
//! tested on its own, so a ray meets the triangles of exactly the leaves whose boxes it passes
//! through, as when it is traced alone: the packet's answers are the single rays', ray for ray.
//!
//! The interval test is exact, not approximate: for a fixed box plane the rounded product
//! `(plane − o) · inv` is monotone in `inv`, so its smallest and largest values over the packet
//! lie at the ends of the packet's range of `inv`, and a box the interval test refuses is refused
//! by every ray's own slab test.

use glam::{Vec3A, Vec4};

use super::wide::{Dir4, EMPTY, LEAF, Node, STACK, WideBvh, leaf_groups};

/// Most directions in a packet: one bit each of a `u64`.
pub const PACKET: usize = 64;

/// Below this many rays a node's rays are tested one by one rather than by first and last.
const FEW: u32 = 4;

/// Up to [`PACKET`] directions prepared for tracing together from any origin.
#[derive(Clone, Debug)]
pub(super) struct Packet {
    pub(super) dirs: Vec<Dir4>,
    /// Per axis, the smallest and largest reciprocal component over the packet, where every
    /// direction enters that axis's slabs by the same side; `None` otherwise.
    span: Option<[[Vec4; 3]; 2]>,
}

impl Packet {
    /// The packet of `dirs` (at most [`PACKET`], each finite and non-zero).
    pub(super) fn new(dirs: impl Iterator<Item = Vec3A>) -> Packet {
        let dirs: Vec<Dir4> = dirs.take(PACKET).map(Dir4::new).collect();
        let span = dirs.first().and_then(|first| {
            dirs.iter().all(|d| d.near == first.near).then(|| {
                let mut lo = first.inv;
                let mut hi = first.inv;
                for d in &dirs[1..] {
                    for axis in 0..3 {
                        lo[axis] = lo[axis].min(d.inv[axis]);
                        hi[axis] = hi[axis].max(d.inv[axis]);
                    }
                }
                [lo, hi]
            })
        });
        Packet { dirs, span }
    }

    /// The node's children that some ray of the packet may enter with t in [0, t_max] (all of
    /// them without a span): a superset of the union of the rays' own [`Dir4::boxes`].
    #[inline(always)]
    fn reached(&self, n: &Node, o: &[Vec4; 3], t_max: Vec4) -> u32 {
        let Some([lo, hi]) = &self.span else {
            return 0b1111;
        };
        let (b, near) = (&n.bounds, self.dirs[0].near);
        let mut enter = Vec4::ZERO;
        let mut leave = t_max;
        for axis in 0..3 {
            let (low, high) = (lo[axis], hi[axis]);
            let entry = b[near[axis]][axis] - o[axis];
            let exit = b[1 - near[axis]][axis] - o[axis];
            enter = enter.max((entry * low).min(entry * high));
            leave = leave.min((exit * low).max(exit * high));
        }
        enter.cmple(leave).bitmask()
    }
}

impl WideBvh {
    /// Which rays of the packet, among those with a bit in `active`, have a triangle along
    /// `o + t d` for t in (0, `t_max`): the answers of [`WideBvh::occluded`] ray by ray. `o`
    /// must be finite.
    pub(super) fn occluded_packet(
        &self,
        o: Vec3A,
        packet: &Packet,
        active: u64,
        t_max: f32,
    ) -> u64 {
        let rays = &packet.dirs;
        let active = active & mask_below(rays.len());
        if self.nodes.is_empty() || active == 0 {
            return 0;
        }
        let o4 = o.to_array().map(Vec4::splat);
        let t4 = Vec4::splat(t_max);
        let mut blocked = 0u64;
        // A pop pushes at most four, as in the single-ray traversal, which the tree's depth
        // was built for.
        let mut stack = [(0u32, 0u64); STACK];
        stack[0] = (0, active);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (node, mask) = stack[top];
            let mask = mask & !blocked;
            if mask == 0 {
                continue;
            }
            let n = &self.nodes[node as usize];
            let filled = n.child.map(|c| c != EMPTY);
            let filled = (0..4).filter(|&l| filled[l]).fold(0u32, |m, l| m | 1 << l);
            let lanes = packet.reached(n, &o4, t4) & filled;
            if lanes == 0 {
                continue;
            }
            let leaves = (0..4)
                .filter(|&l| lanes & 1 << l != 0 && n.child[l] & LEAF != 0)
                .fold(0u32, |m, l| m | 1 << l);
            let at = AtNode {
                rays,
                n,
                o: &o4,
                t_max: t4,
            };
            let masks = if leaves != 0 || mask.count_ones() <= FEW {
                at.each_ray(mask, lanes)
            } else {
                at.first_to_last(mask, lanes)
            };
            for (lane, &m) in masks.iter().enumerate() {
                if m == 0 {
                    continue;
                }
                let code = n.child[lane];
                if code & LEAF == 0 {
                    stack[top] = (code, m);
                    top += 1;
                    continue;
                }
                for group in &self.groups[leaf_groups(code)] {
                    for i in bits(m & !blocked) {
                        if group.any_hit(o4, rays[i].d, t4) {
                            blocked |= 1 << i;
                        }
                    }
                }
                if blocked == active {
                    return blocked;
                }
            }
        }
        blocked
    }
}

/// The low `len` bits.
fn mask_below(len: usize) -> u64 {
    if len >= 64 { u64::MAX } else { (1 << len) - 1 }
}

/// The set bits of `mask`, lowest first.
#[inline(always)]
pub(super) fn bits(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            i
        })
    })
}

/// The set bits of `mask`, highest first.
#[inline(always)]
fn bits_down(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let i = 63 - mask.leading_zeros() as usize;
            mask &= !(1 << i);
            i
        })
    })
}

/// The rays of a packet at one node, from one origin.
struct AtNode<'a> {
    rays: &'a [Dir4],
    n: &'a Node,
    o: &'a [Vec4; 3],
    t_max: Vec4,
}

impl AtNode<'_> {
    /// Which of the lanes `among` ray `i`'s own slab test enters.
    #[inline(always)]
    fn entered(&self, i: usize, among: u32) -> u32 {
        self.rays[i].boxes(self.n, self.o, self.t_max).1 & among
    }

    /// For each of the node's `lanes`, the rays of `mask` whose own slab test enters its box.
    #[inline(always)]
    fn each_ray(&self, mask: u64, lanes: u32) -> [u64; 4] {
        let mut masks = [0u64; 4];
        for i in bits(mask) {
            for lane in bits(self.entered(i, lanes) as u64) {
                masks[lane] |= 1 << i;
            }
        }
        masks
    }

    /// For each of the node's `lanes`, the rays of `mask` from the first whose own slab test
    /// enters its box to the last: a superset of [`AtNode::each_ray`]'s, found with few tests.
    #[inline(always)]
    fn first_to_last(&self, mask: u64, lanes: u32) -> [u64; 4] {
        // From the lowest ray up until every lane has its first, then from the highest down;
        // lanes no ray enters are dropped.
        let ends = |order: &mut dyn Iterator<Item = usize>, lanes: u32| {
            let (mut end, mut pending) = ([0usize; 4], lanes);
            for i in order {
                let hits = self.entered(i, pending);
                pending &= !hits;
                for lane in bits(hits as u64) {
                    end[lane] = i;
                }
                if pending == 0 {
                    break;
                }
            }
            (end, lanes & !pending)
        };
        let (first, lanes) = ends(&mut bits(mask), lanes);
        let (last, _) = ends(&mut bits_down(mask), lanes);
        let mut masks = [0u64; 4];
        for lane in bits(lanes as u64) {
            masks[lane] = mask & mask_below(last[lane] + 1) & !mask_below(first[lane]);
        }
        masks
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::super::wide::Scratch;
    use super::*;
    use crate::math::cubemap::texel_dirs;
    use crate::math::sampling::Rng;

    /// `count` random triangles in the box [-2, 2]³, most small, some as large as the box (a
    /// ground or a wall), a few needle-thin.
    fn soup(rng: &mut Rng, count: usize) -> Vec<[Vec3; 3]> {
        let mut at = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
        (0..count)
            .map(|i| {
                let c = Vec3::new(at(-2.0, 2.0), at(-2.0, 2.0), at(-2.0, 2.0));
                let size = match i % 10 {
                    0 => 2.0,
                    1 => 0.02,
                    _ => 0.3,
                };
                let mut corner =
                    || c + Vec3::new(at(-1.0, 1.0), at(-1.0, 1.0), at(-1.0, 1.0)) * size;
                let (a, b) = (corner(), corner());
                // A needle: its third corner on the line through the other two.
                let third = if i % 37 == 0 {
                    a + (b - a) * 0.5
                } else {
                    corner()
                };
                [a, b, third]
            })
            .collect()
    }

    fn unit(rng: &mut Rng) -> Vec3 {
        loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// Packets of every kind a caller makes: 8 x 8 blocks of a cube's texel centres (one side
    /// of every axis, the interval test at work), random directions (mixed sides, no interval
    /// test), a narrow cone, the six axes and lengths other than one.
    fn packets(rng: &mut Rng) -> Vec<Vec<Vec3>> {
        let n = 32;
        let centres: Vec<Vec3> = texel_dirs(n).iter().map(|d| d.as_vec3()).collect();
        let mut out = Vec::new();
        for face in 0..6 {
            for block in 0..16 {
                let (r0, c0) = (block / 4 * 8, block % 4 * 8);
                let texels = (0..64).map(|i| face * n * n + (r0 + i / 8) * n + c0 + i % 8);
                out.push(texels.map(|t| centres[t]).collect());
            }
        }
        for _ in 0..40 {
            out.push((0..64).map(|_| unit(rng)).collect());
            let axis = unit(rng);
            out.push(
                (0..37)
                    .map(|_| (axis + unit(rng) * 0.05).normalize() * 3.0)
                    .collect(),
            );
        }
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        out.push(axes.to_vec());
        out
    }

    /// Every packet, from random points among random triangles, answers ray for ray as the rays
    /// traced alone do, to the end of the rays and to random distances along them.
    #[test]
    fn packets_answer_as_single_rays_on_random_scenes() {
        let mut rng = Rng::new(7, 0);
        let (mut blocked, mut open) = (0usize, 0usize);
        for scene in 0..3 {
            let triangles = soup(&mut rng, [300, 2000, 6000][scene]);
            let bvh = WideBvh::build(&triangles, 1e-5).expect("a tree the stack holds");
            let dirs = packets(&mut rng);
            for _ in 0..12 {
                let o = Vec3::new(
                    rng.next_f32() * 5.0 - 2.5,
                    rng.next_f32() * 5.0 - 2.5,
                    rng.next_f32() * 5.0 - 2.5,
                );
                for d in &dirs {
                    let packet = Packet::new(d.iter().map(|&v| Vec3A::from(v)));
                    let t_max = match rng.next_u64() % 3 {
                        0 => rng.next_f32() * 3.0,
                        _ => f32::INFINITY,
                    };
                    let active = rng.next_u64() | rng.next_u64();
                    let got = bvh.occluded_packet(o.into(), &packet, active, t_max);
                    for (i, v) in d.iter().enumerate() {
                        let mut scratch = Scratch::default();
                        let alone = bvh.occluded(o.into(), (*v).into(), t_max, &mut scratch);
                        let want = alone && active >> i & 1 == 1;
                        assert_eq!(
                            got >> i & 1 == 1,
                            want,
                            "scene {scene}: ray {i} from {o} along {v} to {t_max}"
                        );
                        if active >> i & 1 == 1 {
                            blocked += usize::from(alone);
                            open += usize::from(!alone);
                        }
                    }
                    assert_eq!(got & !mask_below(d.len()), 0);
                }
            }
        }
        // The comparison means something only if both answers are common.
        assert!(
            blocked > 20_000 && open > 20_000,
            "{blocked} blocked, {open} open"
        );
    }

    /// The interval test refuses no box that a ray of the packet enters, and does refuse boxes
    /// away from a narrow packet (else the packet is traced as single rays).
    #[test]
    fn the_interval_test_keeps_every_box_a_ray_enters_and_culls_others() {
        let mut rng = Rng::new(11, 0);
        let triangles = soup(&mut rng, 2000);
        let bvh = WideBvh::build(&triangles, 1e-5).unwrap();
        let (mut culled, mut kept) = (0usize, 0usize);
        for d in packets(&mut rng) {
            let packet = Packet::new(d.iter().map(|&v| Vec3A::from(v)));
            let o = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
            let o4 = o.to_array().map(Vec4::splat);
            for n in &bvh.nodes {
                let reached = packet.reached(n, &o4, Vec4::INFINITY);
                let entered = packet
                    .dirs
                    .iter()
                    .fold(0, |m, r| m | r.boxes(n, &o4, Vec4::INFINITY).1);
                assert_eq!(entered & !reached, 0, "a box a ray enters was refused");
                let filled = n.child.iter().filter(|&&c| c != EMPTY).count();
                culled += filled - (reached & 0b1111).count_ones().min(filled as u32) as usize;
                kept += reached.count_ones() as usize;
            }
        }
        assert!(culled > kept, "{culled} culled, {kept} kept");
    }
}
