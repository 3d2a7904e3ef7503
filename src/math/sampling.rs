//! Deterministic, seeded sampling shared by the bake and the brute-force reference: a small
//! counter-based generator (every pixel and texel draws from its own stream, so results do not
//! depend on thread scheduling), sub-pixel positions and stratified directions inside cube texels.

use glam::Vec3;

use crate::math::cubemap::{face_st_to_dir, patch_solid_angle, texel_count};
use crate::math::texel_quadrature::TexelQuadrature;

/// SplitMix64 finaliser: a good 64-bit mix, so nearby stream ids give unrelated sequences.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A pixel's Monte Carlo estimate, as its samples come in: their sums and the sums of their
/// squares per colour channel, in f64. What the path tracers report for a pixel, its mean and
/// the standard error of that mean, is worked out here once.
#[derive(Clone, Copy, Debug, Default)]
pub struct Estimate {
    sum: [f64; 3],
    squares: [f64; 3],
}

impl Estimate {
    /// Adds a sample.
    pub fn add(&mut self, l: Vec3) {
        for k in 0..3 {
            let v = l[k] as f64;
            self.sum[k] += v;
            self.squares[k] += v * v;
        }
    }

    /// The mean of `n` samples, those not added being zero.
    pub fn mean(&self, n: usize) -> [f32; 3] {
        self.sum.map(|s| (s / n as f64) as f32)
    }

    /// The standard error of [`Estimate::mean`]: the samples' unbiased standard deviation over
    /// √n, which is √(σ² / (n − 1)) for their variance σ² about the mean; 0 for one sample.
    pub fn std_error(&self, n: usize) -> [f32; 3] {
        let n = n as f64;
        std::array::from_fn(|k| {
            let mean = self.sum[k] / n;
            let var = (self.squares[k] / n - mean * mean).max(0.0);
            if n > 1.0 {
                (var / (n - 1.0)).sqrt() as f32
            } else {
                0.0
            }
        })
    }
}

/// A tiny generator for one stream: (seed, stream id) fully determine the sequence.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// The stream `stream` of generator `seed`.
    pub fn new(seed: u64, stream: u64) -> Self {
        Rng {
            state: mix64(seed ^ mix64(stream.wrapping_add(0x9e37_79b9_7f4a_7c15))),
        }
    }
    /// Next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }
    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
    /// Uniform in [0, 1), double precision.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Film positions (in pixels) of the `spp` sub-pixel samples of pixel (x, y). One sample is the
/// pixel centre; a square count is a jittered grid; any other count is uniform jitter.
pub fn pixel_samples(x: u32, y: u32, width: u32, spp: u32, seed: u64) -> Vec<(f32, f32)> {
    if spp <= 1 {
        return vec![(x as f32 + 0.5, y as f32 + 0.5)];
    }
    let mut rng = Rng::new(seed, (y as u64) * width as u64 + x as u64);
    let side = (spp as f64).sqrt().round() as u32;
    if side * side == spp {
        let mut out = Vec::with_capacity(spp as usize);
        for sy in 0..side {
            for sx in 0..side {
                out.push((
                    x as f32 + (sx as f32 + rng.next_f32()) / side as f32,
                    y as f32 + (sy as f32 + rng.next_f32()) / side as f32,
                ));
            }
        }
        out
    } else {
        (0..spp)
            .map(|_| (x as f32 + rng.next_f32(), y as f32 + rng.next_f32()))
            .collect()
    }
}

/// For every cube texel, `m` directions inside it with weights that sum to the texel's exact solid
/// angle. One sample is the texel centre with the whole solid angle; a square count splits the
/// texel into a grid of sub-texels, each with a jittered direction and its own exact solid angle;
/// any other count rounds up to the next square.
#[derive(Clone, Debug)]
pub struct TexelSamples {
    /// Face size N.
    pub n: usize,
    /// Samples per texel.
    pub per_texel: usize,
    /// Unit directions, texel-major.
    pub dirs: Vec<Vec3>,
    /// Solid-angle weights, texel-major.
    pub weights: Vec<f32>,
    /// With one sample a texel, the quadrature that integrates the texels that need more than
    /// their centre (see [`TexelSamples::refined`]); `None` takes every texel's samples as
    /// they are.
    pub refine: Option<TexelQuadrature>,
}

impl TexelSamples {
    /// The side of the square grid of samples a texel takes when `m` are asked for: `m` rounds
    /// up to `side²` (at least 1).
    pub fn grid_side(m: usize) -> usize {
        ((m.max(1) as f64).sqrt().ceil() as usize).max(1)
    }

    /// Samples for a cube of face size `n`, `m` per texel (rounded up to a square), seeded.
    pub fn new(n: usize, m: usize, seed: u64) -> Self {
        let side = Self::grid_side(m);
        let per_texel = side * side;
        let count = texel_count(n);
        let mut dirs = Vec::with_capacity(count * per_texel);
        let mut weights = Vec::with_capacity(count * per_texel);
        let sub = n * side;
        for j in 0..count {
            let (face, row, col) = (j / (n * n), (j / n) % n, j % n);
            let mut rng = Rng::new(seed ^ 0x7e8e_15a3, j as u64);
            for a in 0..side {
                for b in 0..side {
                    let (r, c) = (row * side + a, col * side + b);
                    let inv = 2.0 / sub as f64;
                    let (s0, t0) = (c as f64 * inv - 1.0, r as f64 * inv - 1.0);
                    let (s1, t1) = (s0 + inv, t0 + inv);
                    let w = patch_solid_angle(s0, t0, s1, t1);
                    let (js, jt) = if per_texel == 1 {
                        (0.5, 0.5)
                    } else {
                        (rng.next_f64(), rng.next_f64())
                    };
                    let d = face_st_to_dir(face, s0 + js * inv, t0 + jt * inv).normalize();
                    dirs.push(d.as_vec3());
                    weights.push(w as f32);
                }
            }
        }
        TexelSamples {
            n,
            per_texel,
            dirs,
            weights,
            refine: None,
        }
    }

    /// These samples, with texels integrated where one centre direction is not enough: with
    /// one sample a texel and `edge_samples` > 1, a texel on a shadow border traces those of a
    /// grid of `edge_samples` sub-texels (rounded up to a square) that lie towards the border
    /// (see the `bake::direct` module), one the horizon crosses or inside a
    /// narrow glossy lobe sums its lobe over them, and the cosine over any other texel is exact.
    /// More samples a texel integrate every texel alike, so this leaves them as they are.
    pub fn refined(mut self, edge_samples: usize) -> Self {
        if self.per_texel == 1 && edge_samples > 1 {
            self.refine = Some(TexelQuadrature::new(self.n, Self::grid_side(edge_samples)));
        }
        self
    }
}

/// Power heuristic weight of a strategy with density `a` against one with density `b` (one
/// sample of each).
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A texel's sample weights, each an exact f64 sub-area stored as f32, summed against the
    /// texel's f64 solid angle: at most 9 roundings of 2^-24 relative on values below 0.4.
    const F32_WEIGHT_SUM: f64 = 1e-6;

    #[test]
    fn an_estimate_gives_the_mean_and_its_standard_error() {
        // Samples 1, 2, 3 and 4 (in the red channel; twice that in green), then four more that
        // are zero and not added: over 4 the mean is 2.5 and the unbiased variance 5/3, so the
        // standard error is √(5/12); over 8, the mean is 1.25, the variance (30 − 8 · 1.25²) / 7
        // = 5/2, and the error √(5/16).
        let mut e = Estimate::default();
        for v in [1.0f32, 2.0, 3.0, 4.0] {
            e.add(Vec3::new(v, 2.0 * v, 0.0));
        }
        let close = |a: f32, b: f64| (a as f64 - b).abs() <= 1e-6 * b.max(1.0);
        let (mean, error) = (e.mean(4), e.std_error(4));
        assert!(
            close(mean[0], 2.5) && close(mean[1], 5.0) && mean[2] == 0.0,
            "{mean:?}"
        );
        let want = (5.0f64 / 12.0).sqrt();
        assert!(
            close(error[0], want) && close(error[1], 2.0 * want),
            "{error:?}"
        );
        assert_eq!(error[2], 0.0);
        assert!(close(e.mean(8)[0], 1.25), "{:?}", e.mean(8));
        assert!(close(e.std_error(8)[0], (5.0f64 / 16.0).sqrt()));
        // One sample has no spread to measure.
        let mut one = Estimate::default();
        one.add(Vec3::splat(3.0));
        assert_eq!((one.mean(1), one.std_error(1)), ([3.0; 3], [0.0; 3]));
    }

    #[test]
    fn texel_sample_weights_sum_to_the_texel_solid_angle() {
        let n = 4;
        let omega = crate::math::cubemap::solid_angles(n);
        for m in [1, 4, 9] {
            let s = TexelSamples::new(n, m, 7);
            for (j, texel_omega) in omega.iter().enumerate() {
                let sum: f64 = s.weights[j * s.per_texel..(j + 1) * s.per_texel]
                    .iter()
                    .map(|&w| w as f64)
                    .sum();
                assert!(
                    (sum - texel_omega).abs() < F32_WEIGHT_SUM,
                    "m = {m}, texel {j}"
                );
                for d in &s.dirs[j * s.per_texel..(j + 1) * s.per_texel] {
                    assert_eq!(crate::math::cubemap::dir_to_texel(n, d.as_dvec3()), j);
                }
            }
        }
    }

    #[test]
    fn pixel_samples_stay_inside_the_pixel_and_are_reproducible() {
        let a = pixel_samples(3, 5, 10, 16, 42);
        assert_eq!(a, pixel_samples(3, 5, 10, 16, 42));
        assert_ne!(a, pixel_samples(3, 5, 10, 16, 43));
        for (x, y) in a {
            assert!((3.0..4.0).contains(&x) && (5.0..6.0).contains(&y));
        }
        assert_eq!(pixel_samples(3, 5, 10, 1, 42), vec![(3.5, 5.5)]);
    }
}
