//! The centres of a cube's texels in blocks that a shading point traces together: squares of up
//! to 8 x 8 texels of a face, each on one side of the face's middle lines, so that every
//! direction of a block enters each axis's slabs by the same side, which the packets' interval
//! test needs ([`crate::scene::trace::RayPacket`]). The bake's texel centres, the surface
//! cache's points and the glossy vertices' visibility bits are all traced this way.

use glam::Vec3;

use super::{ShadingPoint, Shadows};
use crate::math::sampling::TexelSamples;
use crate::scene::trace::{PACKET, RayPacket, RaysFrom};

/// A cube's texel centres in blocks, each prepared as a packet.
pub struct CentrePackets {
    /// Each block's texels (linear indices), and its centres as a packet in that order.
    blocks: Vec<(Vec<u32>, RayPacket)>,
}

impl CentrePackets {
    /// The blocks of an N-cube whose texel centres are `centres` (unit directions, `6 N²` in
    /// the cube's linear order).
    pub fn new(n: usize, centres: &[Vec3]) -> CentrePackets {
        // A side of 8 fills a packet; no block straddles a face's middle (N is a power of 2).
        let side = (n / 2).clamp(1, 8);
        debug_assert!(side * side <= PACKET);
        let mut blocks = Vec::new();
        for face in 0..6 {
            for r0 in (0..n).step_by(side) {
                for c0 in (0..n).step_by(side) {
                    let texels: Vec<u32> = (r0..(r0 + side).min(n))
                        .flat_map(|r| (c0..(c0 + side).min(n)).map(move |c| (r, c)))
                        .map(|(r, c)| (face * n * n + r * n + c) as u32)
                        .filter(|&j| (j as usize) < centres.len())
                        .collect();
                    let dirs: Vec<Vec3> = texels.iter().map(|&j| centres[j as usize]).collect();
                    blocks.push((texels, RayPacket::new(&dirs)));
                }
            }
        }
        CentrePackets { blocks }
    }

    /// Each block's texels (linear indices) and its packet of their centres, in that order.
    pub fn blocks(&self) -> impl Iterator<Item = (&[u32], &RayPacket)> {
        self.blocks.iter().map(|(t, p)| (&t[..], p))
    }

    /// Traces from `from` the centre of every texel j with `traced(j)`, block by block, and sets
    /// bit j of `open` (`j / 64`-th word) for each one that escapes; other bits are left as
    /// they are. Returns the rays traced.
    pub fn open_bits(
        &self,
        from: &mut RaysFrom,
        traced: impl Fn(usize) -> bool,
        open: &mut [u64],
    ) -> u64 {
        let mut rays = 0;
        for (texels, packet) in &self.blocks {
            let above = (texels.iter().enumerate())
                .filter(|(_, j)| traced(**j as usize))
                .fold(0u64, |m, (i, _)| m | 1 << i);
            rays += above.count_ones() as u64;
            let mut seen = above & !from.occluded_packet(packet, above, f32::INFINITY);
            while seen != 0 {
                let j = texels[seen.trailing_zeros() as usize] as usize;
                seen &= seen - 1;
                open[j / 64] |= 1 << (j % 64);
            }
        }
        rays
    }
}

/// A shading point's shadow rays towards a set of texel samples, counted: with one sample a
/// texel and packets of the samples' own centres, every sample above the surface traced
/// beforehand in blocks; otherwise each traced when asked. Either way a sample's answer is the
/// same.
pub struct SampleRays<'a> {
    from: RaysFrom<'a>,
    unshadowed: bool,
    /// The samples found open in blocks, a bit each; empty where they are traced when asked.
    open: Vec<u64>,
    /// The rays traced.
    pub rays: u64,
}

impl<'a> SampleRays<'a> {
    /// The rays from `sp` towards `samples`, shadowed by `shadows`.
    pub fn new(shadows: &Shadows<'a>, samples: &TexelSamples, sp: &ShadingPoint) -> Self {
        let mut rays = Self::one_by_one(shadows, sp);
        // With a quadrature the packets hold its centres, not these samples.
        let own = samples.per_texel == 1 && samples.refine.is_none();
        if let Some(p) = shadows.packets.filter(|_| own && !shadows.unshadowed) {
            let mut open = vec![0u64; samples.dirs.len().div_ceil(64)];
            let above = |s: usize| sp.normal.dot(samples.dirs[s]) > 0.0;
            rays.trace_blocks(p, above, &mut open);
            rays.open = open;
        }
        rays
    }

    /// The rays from `sp`, each traced when asked ([`SampleRays::open_along`]).
    pub fn one_by_one(shadows: &Shadows<'a>, sp: &ShadingPoint) -> Self {
        SampleRays {
            from: shadows.tracer.rays_from(sp.origin),
            unshadowed: shadows.unshadowed,
            open: Vec::new(),
            rays: 0,
        }
    }

    /// The samples found open in blocks, a bit each, where they were traced so
    /// ([`SampleRays::new`]); `None` where each is traced when asked, or none is.
    pub fn open_bits(&self) -> Option<&[u64]> {
        (!self.open.is_empty() && !self.unshadowed).then_some(&self.open[..])
    }

    /// Whether every direction is open (no ray is traced).
    pub fn unshadowed(&self) -> bool {
        self.unshadowed
    }

    /// Traces the centres of `packets` whose texel j has `traced(j)` and sets bit j of `open`
    /// for each one that escapes ([`CentrePackets::open_bits`]), counting the rays.
    pub fn trace_blocks(
        &mut self,
        packets: &CentrePackets,
        traced: impl Fn(usize) -> bool,
        open: &mut [u64],
    ) {
        self.rays += packets.open_bits(&mut self.from, traced, open);
    }

    /// Whether sample `s`, direction `d` (above the surface), is open.
    pub fn open(&mut self, s: usize, d: Vec3) -> bool {
        if !self.open.is_empty() && !self.unshadowed {
            return self.open[s / 64] >> (s % 64) & 1 == 1;
        }
        self.open_along(d)
    }

    /// Whether direction `d` is open, traced now (unless every direction is).
    pub fn open_along(&mut self, d: Vec3) -> bool {
        if self.unshadowed {
            return true;
        }
        self.rays += 1;
        !self.from.occluded(d, f32::INFINITY)
    }
}
