//! The fast cases of a surface vertex's row ([`Bounces::vertex_row`]): one sample a texel and
//! visibility from the surface cache, in loops without branches over the 64 texels of each word
//! of bits, compiled for every vector instruction set `pulp` dispatches to. The same arithmetic
//! as the general row, value by value.

use glam::Vec3;

use super::Bounces;
use crate::bake::ShadingPoint;
use crate::scene::brdf::{GgxAt, Lobes};

/// The row of a surface vertex with one sample a texel and visibility from the cache, added
/// to `rows` by the fast cases of [`Bounces::vertex_row`], as a [`pulp::WithSimd`] so that
/// their loops are compiled for every vector instruction set `pulp` dispatches to.
pub(super) struct CachedRow<'a, 'b> {
    pub(super) bounces: &'b Bounces<'a>,
    /// The cache point's bits, the vertex, its lobes and its path's throughput.
    pub(super) vertex: (&'b [u64], &'b ShadingPoint, &'b Lobes, Vec3),
    pub(super) transmittance: Option<&'b [u8]>,
    pub(super) rows: &'b mut [Vec<f32>; 3],
}

impl pulp::WithSimd for CachedRow<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let CachedRow {
            bounces,
            vertex,
            transmittance,
            rows,
        } = self;
        let (bits, at, lobes, throughput) = vertex;
        if lobes.specular == Vec3::ZERO {
            let c = throughput * lobes.albedo * std::f32::consts::FRAC_1_PI;
            bounces.add_lambertian(bits, at.normal, c, transmittance, rows);
            return;
        }
        bounces.add_glossy(vertex, transmittance, rows);
    }
}

impl Bounces<'_> {
    /// The fast case of [`Bounces::vertex_row`]: a Lambertian vertex, one sample a texel,
    /// visibility from the cache. Adds `c max(0, n·ω) Ω` to the rows at every visible texel, 64
    /// texels a word, without branches, so that the loop vectorises; times the transmittance
    /// through a medium towards each texel, given one.
    #[inline(always)]
    fn add_lambertian(
        &self,
        bits: &[u64],
        n: Vec3,
        c: Vec3,
        transmittance: Option<&[u8]>,
        rows: &mut [Vec<f32>; 3],
    ) {
        if let Some(t) = transmittance {
            let [wx, wy, wz] = &self.weighted;
            for (wi, &word) in bits.iter().enumerate() {
                let mut word = word;
                while word != 0 {
                    let j = wi * 64 + word.trailing_zeros() as usize;
                    word &= word - 1;
                    let through = t[j] as f32 / 255.0;
                    let cos = (n.x * wx[j] + n.y * wy[j] + n.z * wz[j]).max(0.0) * through;
                    rows[0][j] += c.x * cos;
                    rows[1][j] += c.y * cos;
                    rows[2][j] += c.z * cos;
                }
            }
            return;
        }
        let [wx, wy, wz] = &self.weighted;
        let [r0, r1, r2] = rows;
        let chunks = wx.chunks(64).zip(wy.chunks(64)).zip(wz.chunks(64)).zip(
            r0.chunks_mut(64)
                .zip(r1.chunks_mut(64))
                .zip(r2.chunks_mut(64)),
        );
        for (&word, (((x, y), z), ((o0, o1), o2))) in bits.iter().zip(chunks) {
            if word == 0 {
                continue;
            }
            let len = x
                .len()
                .min(y.len())
                .min(z.len())
                .min(o0.len())
                .min(o1.len())
                .min(o2.len());
            for j in 0..len {
                let bit = ((word >> j) & 1) as f32;
                let cos = (n.x * x[j] + n.y * y[j] + n.z * z[j]).max(0.0) * bit;
                o0[j] += c.x * cos;
                o1[j] += c.y * cos;
                o2[j] += c.z * cos;
            }
        }
    }

    /// The fast case of [`Bounces::vertex_row`] for a glossy vertex: one sample a texel,
    /// visibility from the cache, each texel weighed by its solid angle (and its transmittance,
    /// given one). Each word of bits with any texel in sight has its 64 GGX values worked out
    /// together ([`GgxAt::cosines`]), then its rows' multiply-adds run without branches: the
    /// same arithmetic as the vertex row, so the same numbers to the bit (a test holds them
    /// equal).
    #[inline(always)]
    fn add_glossy(
        &self,
        (bits, at, lobes, throughput): (&[u64], &ShadingPoint, &Lobes, Vec3),
        transmittance: Option<&[u8]>,
        rows: &mut [Vec<f32>; 3],
    ) {
        let n = at.normal;
        let ggx = GgxAt::new(n, at.view, lobes.alpha);
        let [dx, dy, dz] = &self.dirs;
        let w = &self.samples.weights;
        let [r0, r1, r2] = rows;
        let (mut lobe, mut weight) = ([0.0f32; 64], [0.0f32; 64]);
        let mut value = [[0.0f32; 64]; 3];
        for (wi, &word) in bits.iter().enumerate() {
            if word == 0 {
                continue;
            }
            let (start, end) = (wi * 64, (wi * 64 + 64).min(dx.len()));
            let (x, y, z) = (&dx[start..end], &dy[start..end], &dz[start..end]);
            let lobe = &mut lobe[..end - start];
            ggx.cosines([x, y, z], lobe);
            let weight = &mut weight[..end - start];
            weight.copy_from_slice(&w[start..end]);
            if let Some(t) = transmittance {
                for (w, &t) in weight.iter_mut().zip(&t[start..end]) {
                    *w *= t as f32 / 255.0;
                }
            }
            // As `vertex_row`: n·ω in f32, the lobes' sum, times the throughput and the
            // texel's weight; nothing where the bit is clear or ω is below the surface. Into
            // the word's own values first, which alias nothing, so the loop vectorises.
            for j in 0..end - start {
                let cos = n.x * x[j] + n.y * y[j] + n.z * z[j];
                let f = lobes.albedo * (cos.max(0.0) * std::f32::consts::FRAC_1_PI)
                    + lobes.specular * lobe[j];
                let v = throughput * f * weight[j];
                let on = ((word >> j) & 1 == 1) & (cos > 0.0);
                for (value, v) in value.iter_mut().zip(v.to_array()) {
                    value[j] = if on { v } else { 0.0 };
                }
            }
            for (row, value) in [&mut *r0, &mut *r1, &mut *r2].into_iter().zip(&value) {
                for (o, v) in row[start..end].iter_mut().zip(value) {
                    *o += v;
                }
            }
        }
    }
}
