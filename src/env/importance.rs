//! Importance sampling of a cube map: a texel drawn with probability proportional to its
//! radiance (largest channel) times its solid angle, then a point uniform over the texel's square
//! on the cube face. This is the light sampling of the path-traced reference
//! ([`crate::bake::path_tracer`]), in the manner of pbrt-v4's image infinite light, which
//! samples a map's pixels by their luminance.

use glam::{DVec3, Vec3};

use crate::math::cubemap::{CubeMap, dir_to_face_st, dir_to_texel, face_st_to_dir, solid_angles};

/// A cube map's texel distribution.
pub struct CubeSampler {
    n: usize,
    /// Cumulative texel probabilities, ending at 1.
    cdf: Vec<f64>,
    /// Probability of each texel.
    prob: Vec<f64>,
}

impl CubeSampler {
    /// The distribution of `cube`; `None` when the map is black.
    pub fn new(cube: &CubeMap) -> Option<CubeSampler> {
        let weights: Vec<f64> = cube
            .texels
            .iter()
            .zip(solid_angles(cube.n))
            .map(|(l, w)| l.iter().fold(0.0f32, |a, &b| a.max(b)) as f64 * w)
            .collect();
        let total: f64 = weights.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let prob: Vec<f64> = weights.iter().map(|w| w / total).collect();
        let mut acc = 0.0;
        let mut cdf: Vec<f64> = prob
            .iter()
            .map(|p| {
                acc += p;
                acc
            })
            .collect();
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Some(CubeSampler {
            n: cube.n,
            cdf,
            prob,
        })
    }

    /// Area of one texel on its face, in face coordinates of [-1, 1]².
    fn texel_area(&self) -> f64 {
        (2.0 / self.n as f64).powi(2)
    }

    /// A direction and its density over solid angle, from three uniform numbers.
    pub fn sample(&self, u: [f64; 3]) -> (Vec3, f32) {
        let j = self
            .cdf
            .partition_point(|&c| c <= u[0])
            .min(self.cdf.len() - 1);
        let n = self.n;
        let (face, row, col) = (j / (n * n), (j / n) % n, j % n);
        let step = 2.0 / n as f64;
        // Kept a hair inside the texel, so that rounding the direction to f32 cannot carry it into
        // a neighbour with another density (a bias of 4e-5 of the texel's area).
        let inside = |x: f64| x.clamp(1e-5, 1.0 - 1e-5);
        let s = -1.0 + (col as f64 + inside(u[1])) * step;
        let t = -1.0 + (row as f64 + inside(u[2])) * step;
        let d = face_st_to_dir(face, s, t);
        let r = d.length();
        let pdf = self.prob[j] / self.texel_area() * r * r * r;
        ((d / r).as_vec3(), pdf as f32)
    }

    /// Density over solid angle of drawing `d` (unit).
    pub fn pdf(&self, d: Vec3) -> f32 {
        let d = d.as_dvec3();
        let (_, s, t) = dir_to_face_st(d);
        let j = dir_to_texel(self.n, d);
        let r = DVec3::new(s, t, 1.0).length();
        (self.prob[j] / self.texel_area() * r * r * r) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::sampling::Rng;

    /// A drawn direction's length against 1: normalised in f32, a few ulps.
    const UNIT_LENGTH_F32: f32 = 1e-5;
    /// The density evaluated at a drawn direction against the density the draw reported,
    /// relative: both are the texel's probability times r³ over its area, from the direction
    /// before and after its rounding to f32, so they differ by a few f32 ulps of r³.
    const DRAWN_PDF_ROUNDING: f32 = 1e-4;
    /// The mean of L / pdf over 200,000 draws against the map's power, per channel, relative: the
    /// draws follow the largest channel, so the spread comes from the other channels' ratios to
    /// it and from r³ across a texel, and the inset at texel borders moves 4e-5 of a texel's
    /// area; 0.1% asks for an unbiased estimate at this count.
    const SAMPLED_POWER: f64 = 1e-3;

    #[test]
    fn sampled_estimate_of_the_power_is_unbiased_and_the_pdf_matches_the_draw() {
        // E[L(ω) / pdf(ω)] = ∫ L dω, the map's power; and pdf(ω) evaluated at a drawn direction
        // equals the density the draw reported.
        let n = 8;
        let mut cube = CubeMap::constant(n, [0.05, 0.1, 0.02]).unwrap();
        cube.texels[17] = [400.0, 300.0, 200.0];
        cube.texels[300] = [0.0, 9.0, 0.0];
        let sampler = CubeSampler::new(&cube).unwrap();
        let power = cube.power();
        let mut rng = Rng::new(9, 0);
        let count = 200_000;
        let mut sum = [0.0f64; 3];
        for _ in 0..count {
            let (d, pdf) = sampler.sample([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
            assert!((d.length() - 1.0).abs() < UNIT_LENGTH_F32);
            let back = sampler.pdf(d);
            assert!(
                (back - pdf).abs() <= DRAWN_PDF_ROUNDING * pdf,
                "{back} vs {pdf}"
            );
            let l = cube.lookup(d.as_dvec3());
            for k in 0..3 {
                sum[k] += l[k] as f64 / pdf as f64;
            }
        }
        for k in 0..3 {
            let got = sum[k] / count as f64;
            assert!(
                (got - power[k]).abs() < SAMPLED_POWER * power[k],
                "channel {k}: {got} vs {}",
                power[k]
            );
        }
        assert!(CubeSampler::new(&CubeMap::constant(n, [0.0; 3]).unwrap()).is_none());
    }
}
