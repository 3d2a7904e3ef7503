//! Importance sampling of an environment, for the path-traced reference
//! ([`crate::bake::path_tracer`]), in the manner of pbrt-v4's image infinite light, which samples
//! a map's pixels by their luminance:
//! - a cube map ([`CubeLight`]): a texel drawn with probability proportional to its radiance
//!   (largest channel) times its solid angle, then a point uniform over the texel's square on the
//!   cube face; the light the bake itself is lit by;
//! - a lat-long map's own pixels ([`MapLight`]), its radiance constant over each pixel (the
//!   function the cube's resampling integrates, so a cube of growing N tends to it): a pixel
//!   drawn the same way, then a direction uniform in solid angle over the pixel. The true
//!   lighting, with no cube's resolution between it and the image.

use glam::{DMat3, DVec3, Vec3};

use crate::env::envmap::EnvMap;
use crate::env::latlong::{EnvRotation, latlong_dir, latlong_uv, pixel_solid_angle};
use crate::math::cubemap::{CubeMap, dir_to_face_st, dir_to_texel, face_st_to_dir, solid_angles};

/// An environment lighting a path tracer's scene: its radiance along any direction and, where it
/// is not black, directions drawn by importance with their density over solid angle.
pub trait EnvLight: Sync {
    /// Radiance arriving from the unit world direction `d`.
    fn radiance(&self, d: Vec3) -> Vec3;
    /// Whether directions can be drawn: the light is not black (nor its power infinite).
    fn drawable(&self) -> bool;
    /// A unit direction and its density over solid angle, from three uniform numbers (where
    /// [`EnvLight::drawable`]).
    fn sample(&self, u: [f64; 3]) -> (Vec3, f32);
    /// Density over solid angle of drawing `d` (unit); 0 where not drawable.
    fn pdf(&self, d: Vec3) -> f32;
}

/// A discrete distribution over cells, proportional to their weights.
struct Distribution {
    /// Cumulative probabilities, ending at 1.
    cdf: Vec<f64>,
    /// Probability of each cell.
    prob: Vec<f64>,
}

impl Distribution {
    /// The distribution of `weights`; `None` where they sum to 0 or to no finite number.
    fn new(weights: Vec<f64>) -> Option<Distribution> {
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
        Some(Distribution { cdf, prob })
    }

    /// The cell drawn by the uniform number `u`.
    fn draw(&self, u: f64) -> usize {
        self.cdf
            .partition_point(|&c| c <= u)
            .min(self.cdf.len() - 1)
    }
}

/// A cell's importance: its largest channel times its solid angle.
fn importance(l: &[f32; 3], omega: f64) -> f64 {
    l.iter().fold(0.0f32, |a, &b| a.max(b)) as f64 * omega
}

/// A uniform number kept a hair inside its cell, so that rounding the direction to f32 cannot
/// carry it into a neighbour with another density (a bias of 4e-5 of the cell's size).
fn inside(x: f64) -> f64 {
    x.clamp(1e-5, 1.0 - 1e-5)
}

/// A cube map's texel distribution.
pub struct CubeSampler {
    n: usize,
    texels: Distribution,
}

impl CubeSampler {
    /// The distribution of `cube`; `None` when the map is black.
    pub fn new(cube: &CubeMap) -> Option<CubeSampler> {
        let weights = cube
            .texels
            .iter()
            .zip(solid_angles(cube.n))
            .map(|(l, w)| importance(l, w))
            .collect();
        Some(CubeSampler {
            n: cube.n,
            texels: Distribution::new(weights)?,
        })
    }

    /// Area of one texel on its face, in face coordinates of [-1, 1]².
    fn texel_area(&self) -> f64 {
        (2.0 / self.n as f64).powi(2)
    }

    /// A direction and its density over solid angle, from three uniform numbers.
    pub fn sample(&self, u: [f64; 3]) -> (Vec3, f32) {
        let j = self.texels.draw(u[0]);
        let n = self.n;
        let (face, row, col) = (j / (n * n), (j / n) % n, j % n);
        let step = 2.0 / n as f64;
        let s = -1.0 + (col as f64 + inside(u[1])) * step;
        let t = -1.0 + (row as f64 + inside(u[2])) * step;
        let d = face_st_to_dir(face, s, t);
        let r = d.length();
        let pdf = self.texels.prob[j] / self.texel_area() * r * r * r;
        ((d / r).as_vec3(), pdf as f32)
    }

    /// Density over solid angle of drawing `d` (unit).
    pub fn pdf(&self, d: Vec3) -> f32 {
        let d = d.as_dvec3();
        let (_, s, t) = dir_to_face_st(d);
        let j = dir_to_texel(self.n, d);
        let r = DVec3::new(s, t, 1.0).length();
        (self.texels.prob[j] / self.texel_area() * r * r * r) as f32
    }
}

/// A cube map as a path tracer's light: its texels' radiance, drawn by [`CubeSampler`].
pub struct CubeLight<'a> {
    cube: &'a CubeMap,
    sampler: Option<CubeSampler>,
}

impl CubeLight<'_> {
    /// The light of `cube`.
    pub fn new(cube: &CubeMap) -> CubeLight<'_> {
        CubeLight {
            cube,
            sampler: CubeSampler::new(cube),
        }
    }
}

impl EnvLight for CubeLight<'_> {
    fn radiance(&self, d: Vec3) -> Vec3 {
        Vec3::from(self.cube.lookup(d.as_dvec3()))
    }

    fn drawable(&self) -> bool {
        self.sampler.is_some()
    }

    fn sample(&self, u: [f64; 3]) -> (Vec3, f32) {
        match &self.sampler {
            Some(s) => s.sample(u),
            None => (Vec3::Y, 0.0),
        }
    }

    fn pdf(&self, d: Vec3) -> f32 {
        self.sampler.as_ref().map_or(0.0, |s| s.pdf(d))
    }
}

/// A lat-long map's own pixels as a path tracer's light, turned by a rotation: radiance constant
/// over each pixel, pixels drawn by their largest channel times their solid angle.
pub struct MapLight<'a> {
    map: &'a EnvMap,
    world_from_map: DMat3,
    pixels: Option<Distribution>,
}

impl MapLight<'_> {
    /// The light of `map` turned by `rotation`.
    pub fn new(map: &EnvMap, rotation: EnvRotation) -> MapLight<'_> {
        let (w, h) = (map.width, map.height);
        let weights = (0..w * h)
            .map(|j| importance(&map.pixels[j], pixel_solid_angle(w, h, j / w)))
            .collect();
        MapLight {
            map,
            world_from_map: rotation.world_from_map(),
            pixels: Distribution::new(weights),
        }
    }

    /// The pixel that map direction `d` falls in.
    fn pixel_of(&self, d: DVec3) -> usize {
        let (w, h) = (self.map.width, self.map.height);
        let (u, v) = latlong_uv(d);
        let x = ((u * w as f64) as usize).min(w - 1);
        let y = ((v * h as f64) as usize).min(h - 1);
        y * w + x
    }

    /// The pixel of world direction `d`.
    fn pixel_towards(&self, d: Vec3) -> usize {
        self.pixel_of(self.world_from_map.transpose() * d.as_dvec3())
    }
}

impl EnvLight for MapLight<'_> {
    fn radiance(&self, d: Vec3) -> Vec3 {
        Vec3::from(self.map.pixels[self.pixel_towards(d)])
    }

    fn drawable(&self) -> bool {
        self.pixels.is_some()
    }

    fn sample(&self, u: [f64; 3]) -> (Vec3, f32) {
        let Some(pixels) = &self.pixels else {
            return (Vec3::Y, 0.0);
        };
        let (w, h) = (self.map.width, self.map.height);
        let j = pixels.draw(u[0]);
        let (x, y) = (j % w, j / w);
        // Uniform in solid angle over the pixel: uniform in longitude and in cos θ.
        let along = (x as f64 + inside(u[1])) / w as f64;
        let (c0, c1) = (
            (std::f64::consts::PI * y as f64 / h as f64).cos(),
            (std::f64::consts::PI * (y + 1) as f64 / h as f64).cos(),
        );
        let cos_theta = c0 + (c1 - c0) * inside(u[2]);
        let d = latlong_dir(
            along,
            cos_theta.clamp(-1.0, 1.0).acos() / std::f64::consts::PI,
        );
        let pdf = pixels.prob[j] / pixel_solid_angle(w, h, y);
        ((self.world_from_map * d).normalize().as_vec3(), pdf as f32)
    }

    fn pdf(&self, d: Vec3) -> f32 {
        let Some(pixels) = &self.pixels else {
            return 0.0;
        };
        let j = self.pixel_towards(d);
        let (w, h) = (self.map.width, self.map.height);
        (pixels.prob[j] / pixel_solid_angle(w, h, j / w)) as f32
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

    /// E[L(ω) / pdf(ω)] over 200,000 draws of `light` against `power`, and pdf(ω) evaluated at
    /// each drawn direction against the density the draw reported.
    fn assert_unbiased(light: &dyn EnvLight, power: [f64; 3], seed: u64) {
        assert!(light.drawable());
        let mut rng = Rng::new(seed, 0);
        let count = 200_000;
        let mut sum = [0.0f64; 3];
        for _ in 0..count {
            let (d, pdf) = light.sample([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
            assert!((d.length() - 1.0).abs() < UNIT_LENGTH_F32);
            let back = light.pdf(d);
            assert!(
                (back - pdf).abs() <= DRAWN_PDF_ROUNDING * pdf,
                "{back} vs {pdf}"
            );
            let l = light.radiance(d);
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
    }

    #[test]
    fn sampled_estimate_of_the_power_is_unbiased_and_the_pdf_matches_the_draw() {
        let n = 8;
        let mut cube = CubeMap::constant(n, [0.05, 0.1, 0.02]).unwrap();
        cube.texels[17] = [400.0, 300.0, 200.0];
        cube.texels[300] = [0.0, 9.0, 0.0];
        assert_unbiased(&CubeLight::new(&cube), cube.power(), 9);
        assert!(CubeSampler::new(&CubeMap::constant(n, [0.0; 3]).unwrap()).is_none());
    }

    /// A lat-long map's own pixels, turned: the mean of L / pdf over many draws is the map's
    /// power, the density at a drawn direction is the one reported, and the radiance there is
    /// the drawn pixel's (the draw stays inside its pixel, turned and back).
    #[test]
    fn map_light_draws_its_pixels_without_bias() {
        let (w, h) = (16, 8);
        let mut pixels = vec![[0.02f32, 0.05, 0.1]; w * h];
        pixels[3 * w + 5] = [300.0, 200.0, 100.0];
        pixels[7 * w] = [0.0, 4.0, 0.0];
        let map = EnvMap {
            width: w,
            height: h,
            pixels,
            source: "test".into(),
            negatives_clamped: 0,
            lowest_negative: 0.0,
            negative_power: 0.0,
        };
        let rotation = EnvRotation::new(40.0, -25.0);
        assert_unbiased(&MapLight::new(&map, rotation), map.power(), 11);
        let black = EnvMap {
            pixels: vec![[0.0; 3]; w * h],
            ..map.clone()
        };
        let dark = MapLight::new(&black, EnvRotation::default());
        assert!(!dark.drawable() && dark.pdf(Vec3::Y) == 0.0);
    }
}
