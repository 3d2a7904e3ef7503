//! Unbiased free paths and transmittance through a medium, for the path tracers.
//!
//! Free paths are drawn by delta (Woodcock) tracking against the grid's majorant, the largest
//! extinction anywhere in it: a tentative collision at distance `−ln(1 − u) / sigma_max` is real
//! with probability `sigma_t(x) / sigma_max` and otherwise null, so the heterogeneous density
//! needs no ray marching and leaves no step bias (Woodcock et al. 1965; pbrt-v4's volumetric path
//! integrator uses the same scheme). Shadow rays take ratio tracking (Novák et al. 2014): an
//! unbiased product of `1 − sigma_t / sigma_max` over tentative collisions. New directions at a
//! collision are drawn from the Henyey–Greenstein lobe ([`sample_hg`]). A segment takes at most
//! [`MAX_TRACKING_STEPS`] tentative collisions; the rest of a longer one is marched.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;

use crate::math::sampling::Rng;
use crate::medium::{Medium, ray_box};

/// Most tentative collisions one tracked segment takes before the rest of it is marched. Under
/// [`crate::medium::MAX_VOXEL_DEPTH`] a segment expects at most 100 a voxel it crosses, ~89,000
/// across a 512³ grid's diagonal (Poisson, standard deviation ~300), so a medium a scene file
/// accepts reaches this only with voxels far longer than their shortest edge. There, and for a
/// step that stalls below f32's resolution of the distance, the rest of the segment is marched
/// ([`Tracker::marched`] counts them): delta tracking forgets the null collisions behind it, so
/// the rest of a free path is a new one's from where it stands, exact but for the march's
/// quadrature.
pub const MAX_TRACKING_STEPS: u32 = 1 << 18;
/// Most steps of that march (half a voxel each, longer across a box far longer than its voxels).
const MAX_MARCH_STEPS: f32 = 65536.0;

/// A direction from the Henyey–Greenstein lobe of asymmetry `g` around `d` (the direction of
/// travel before the collision; `g > 0` keeps going forward), from two uniform numbers. Its
/// density over solid angle is `henyey_greenstein(g, result · d)`.
pub fn sample_hg(g: f32, d: Vec3, u: [f32; 2]) -> Vec3 {
    let cos = if g.abs() < 1e-3 {
        1.0 - 2.0 * u[0]
    } else {
        // Inverting the lobe's distribution of cos θ (pbrt-v4, section 11.3.1, with θ measured
        // from the direction of travel).
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u[0]);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 2.0 * std::f32::consts::PI * u[1];
    let (t, b) = d.any_orthonormal_pair();
    (d * cos + (t * phi.cos() + b * phi.sin()) * sin).normalize()
}

/// The medium as the trackers see it: its box of support and majorant.
pub struct Tracker<'a> {
    medium: &'a Medium,
    lo: Vec3,
    hi: Vec3,
    majorant: f32,
    /// Tentative collisions a segment takes before its rest is marched.
    max_steps: u32,
    /// Segments whose rest was marched.
    marched: AtomicU64,
}

impl<'a> Tracker<'a> {
    /// The trackers of `medium`.
    pub fn new(medium: &'a Medium) -> Tracker<'a> {
        Self::with_max_steps(medium, MAX_TRACKING_STEPS)
    }

    /// The trackers of `medium`, marching the rest of a segment after `max_steps` tentative
    /// collisions.
    fn with_max_steps(medium: &'a Medium, max_steps: u32) -> Tracker<'a> {
        let (lo, hi) = medium.grid.support();
        let max_density = medium.grid.data.iter().fold(0.0f32, |a, &b| a.max(b));
        Tracker {
            medium,
            lo,
            hi,
            majorant: medium.extinction * max_density,
            max_steps,
            marched: AtomicU64::new(0),
        }
    }

    /// The medium tracked.
    pub fn medium(&self) -> &'a Medium {
        self.medium
    }

    /// Segments so far that reached [`MAX_TRACKING_STEPS`] and were marched to their end.
    pub fn marched(&self) -> u64 {
        self.marched.load(Ordering::Relaxed)
    }

    /// The march of `o + s d` for `s` in `[t, t1]`: its steps and their length, `None` when
    /// the span is empty.
    fn march_steps(&self, t: f32, t1: f32) -> Option<(usize, f32)> {
        let span = t1 - t;
        if !(span.is_finite() && span > 0.0) {
            return None;
        }
        let steps = (span / self.medium.camera_step())
            .ceil()
            .clamp(1.0, MAX_MARCH_STEPS);
        Some((steps as usize, span / steps))
    }

    /// The rest of a free path from `t`, marched: the distance where the optical depth from
    /// `t` reaches `−ln(1 − u)` (midpoint rule, linear within a step), `None` past `t1`.
    fn march_collision(&self, o: Vec3, d: Vec3, t: f32, t1: f32, u: f32) -> Option<f32> {
        self.marched.fetch_add(1, Ordering::Relaxed);
        let target = -(1.0 - u).ln();
        let (steps, dt) = self.march_steps(t, t1)?;
        let mut depth = 0.0f32;
        for i in 0..steps {
            let s = t + i as f32 * dt;
            let step = self.medium.sigma_t(o + d * (s + 0.5 * dt)) * dt;
            if step > 0.0 && depth + step >= target {
                return Some(s + (target - depth) / step * dt);
            }
            depth += step;
        }
        None
    }

    /// The transmittance of `o + s d` for `s` in `[t, t1]`, marched.
    fn march_transmittance(&self, o: Vec3, d: Vec3, t: f32, t1: f32) -> f32 {
        self.marched.fetch_add(1, Ordering::Relaxed);
        let Some((steps, dt)) = self.march_steps(t, t1) else {
            return 1.0;
        };
        let depth: f32 = (0..steps)
            .map(|i| self.medium.sigma_t(o + d * (t + (i as f32 + 0.5) * dt)))
            .sum();
        (-depth * dt).exp()
    }

    /// Delta tracking from `o` along `d` (unit) up to distance `t_max`: the distance to the first
    /// real collision, or `None` when the ray leaves the medium or reaches `t_max` first.
    pub fn collide(&self, o: Vec3, d: Vec3, t_max: f32, rng: &mut Rng) -> Option<f32> {
        if self.majorant <= 0.0 {
            return None;
        }
        let (t0, t1) = ray_box(o, d, self.lo, self.hi)?;
        let t1 = t1.min(t_max);
        let mut t = t0;
        for _ in 0..self.max_steps {
            t -= (1.0 - rng.next_f32()).ln() / self.majorant;
            if t >= t1 {
                return None;
            }
            if rng.next_f32() * self.majorant < self.medium.sigma_t(o + d * t) {
                return Some(t);
            }
        }
        self.march_collision(o, d, t, t1, rng.next_f32())
    }

    /// Ratio tracking from `o` along `d` (unit) up to distance `t_max` or out of the medium: an
    /// unbiased estimate of the transmittance.
    pub fn transmittance(&self, o: Vec3, d: Vec3, t_max: f32, rng: &mut Rng) -> f32 {
        if self.majorant <= 0.0 {
            return 1.0;
        }
        let Some((t0, t1)) = ray_box(o, d, self.lo, self.hi) else {
            return 1.0;
        };
        let t1 = t1.min(t_max);
        let mut t = t0;
        let mut tr = 1.0f32;
        for _ in 0..self.max_steps {
            t -= (1.0 - rng.next_f32()).ln() / self.majorant;
            if t >= t1 {
                return tr;
            }
            tr *= 1.0 - self.medium.sigma_t(o + d * t) / self.majorant;
            if tr <= 0.0 {
                return 0.0;
            }
            // Deep in the medium the estimate is tiny; end it without bias by roulette.
            if tr < 0.1 {
                if rng.next_f32() >= tr {
                    return 0.0;
                }
                tr = 1.0;
            }
        }
        tr * self.march_transmittance(o, d, t, t1)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::medium::henyey_greenstein;
    use crate::medium::{DensityGrid, DensitySource};

    /// Draws per test of a tracker or a sampler: the binomial standard error of an estimate near
    /// 0.14 is then 8e-4.
    const DRAWS: u32 = 200_000;
    /// Standard errors an estimate may stray: a true failure (a wrong free-path law, a lobe
    /// turned the wrong way) is off by tens of them.
    const SIGMAS: f64 = 4.5;
    /// A transmittance whose segments end in the march against the fine quadrature: half-voxel
    /// midpoint steps of the smooth sphere miss its depth by a few thousandths, T by less; a
    /// march that stopped paths or let them through would be off by tenths.
    const MARCHED_REST: f64 = 0.01;

    /// A medium over [-1, 1]³ of density `f` on a grid of `dims`, g = 0.3.
    pub(crate) fn medium(
        dims: [usize; 3],
        f: impl Fn(Vec3) -> f32,
        extinction: f32,
        albedo: f32,
    ) -> Medium {
        Medium {
            grid: DensityGrid::from_fn(dims, Vec3::splat(-1.0), Vec3::splat(1.0), f),
            extinction,
            albedo: Vec3::splat(albedo),
            g: 0.3,
        }
    }

    /// Ratio-tracked transmittance along `o + t d` out of `medium`, averaged over `count` estimates
    /// (against closed forms).
    fn estimate_transmittance(medium: &Medium, o: Vec3, d: Vec3, count: u32, seed: u64) -> f64 {
        let tracker = Tracker::new(medium);
        let mut rng = Rng::new(seed, 0);
        (0..count)
            .map(|_| tracker.transmittance(o, d, f32::INFINITY, &mut rng) as f64)
            .sum::<f64>()
            / count as f64
    }

    /// The fraction of `count` delta-tracked rays along `o + t d` that leave `medium` without a real
    /// collision: an estimate of the same transmittance by the other tracker.
    fn estimate_escape(medium: &Medium, o: Vec3, d: Vec3, count: u32, seed: u64) -> f64 {
        let tracker = Tracker::new(medium);
        let mut rng = Rng::new(seed, 0);
        (0..count)
            .filter(|_| tracker.collide(o, d, f32::INFINITY, &mut rng).is_none())
            .count() as f64
            / count as f64
    }

    /// The optical depth of the trilinear density along a ray, by a fine midpoint rule (1,000
    /// steps across the support), independent of the tracker.
    pub(crate) fn fine_depth(m: &Medium, o: Vec3, d: Vec3) -> f64 {
        let (lo, hi) = m.grid.support();
        let Some((t0, t1)) = ray_box(o, d, lo, hi) else {
            return 0.0;
        };
        let steps = 1000;
        let dt = (t1 - t0) as f64 / steps as f64;
        (0..steps)
            .map(|i| m.sigma_t(o + d * (t0 + ((i as f64 + 0.5) * dt) as f32)) as f64)
            .sum::<f64>()
            * dt
    }

    #[test]
    fn hg_draws_follow_the_lobe_in_cos_theta_and_are_even_in_azimuth() {
        let d = Vec3::new(0.3, -0.5, 0.8).normalize();
        let (t, _) = d.any_orthonormal_pair();
        for g in [-0.6f32, 0.0, 0.3, 0.85] {
            let bins = 20;
            let mut count = vec![0u32; bins];
            let mut side = 0.0f64;
            let mut rng = Rng::new(9, (g * 100.0) as u64);
            for _ in 0..DRAWS {
                let w = sample_hg(g, d, [rng.next_f32(), rng.next_f32()]);
                assert!((w.length() - 1.0).abs() < 1e-5);
                let c = w.dot(d).clamp(-1.0, 1.0 - 1e-7);
                count[((c + 1.0) * 0.5 * bins as f32) as usize] += 1;
                side += w.dot(t) as f64;
            }
            for (b, &k) in count.iter().enumerate() {
                // The bin's probability: 2π ∫ p(cos) dcos by a fine midpoint rule.
                let (a, z) = (-1.0 + 2.0 * b as f64 / bins as f64, 2.0 / bins as f64);
                let p: f64 = (0..200)
                    .map(|i| {
                        let c = a + (i as f64 + 0.5) * z / 200.0;
                        henyey_greenstein(g, c as f32) as f64
                    })
                    .sum::<f64>()
                    * 2.0
                    * std::f64::consts::PI
                    * z
                    / 200.0;
                let want = p * DRAWS as f64;
                let sigma = (want * (1.0 - p)).sqrt().max(1.0);
                assert!(
                    (k as f64 - want).abs() < SIGMAS * sigma,
                    "g {g}, bin {b}: {k} draws, {want:.0} expected"
                );
            }
            // Azimuth uniform: the mean along a perpendicular is 0 (its spread is below 1/√2).
            let mean = side / DRAWS as f64;
            assert!(
                mean.abs() < SIGMAS * (0.5 / DRAWS as f64).sqrt(),
                "g {g}: mean {mean}"
            );
        }
    }

    #[test]
    fn both_trackers_see_a_homogeneous_slabs_transmittance() {
        // Density 1 at every voxel centre of a 4³ grid over [-1, 1]³: 1 over [-0.75, 0.75] and a
        // linear ramp to 0 half a voxel beyond, so the depth across is exactly 2 · extinction.
        let m = medium([4; 3], |_| 1.0, 1.0, 0.5);
        let o = Vec3::new(-3.0, 0.1, -0.2);
        for d in [Vec3::X, Vec3::new(1.0, 0.15, 0.1).normalize()] {
            let want = (-fine_depth(&m, o, d)).exp();
            if d == Vec3::X {
                assert!((want - (-2.0f64).exp()).abs() < 1e-4, "{want}");
            }
            let sigma = (want * (1.0 - want) / DRAWS as f64).sqrt();
            let ratio = estimate_transmittance(&m, o, d, DRAWS, 3);
            let escape = estimate_escape(&m, o, d, DRAWS, 4);
            assert!((ratio - want).abs() < SIGMAS * sigma, "{ratio} vs {want}");
            assert!((escape - want).abs() < SIGMAS * sigma, "{escape} vs {want}");
        }
    }

    /// A soft sphere whose density varies 0..1 on a 12³ grid, at `extinction`, and a ray through
    /// it: its origin and direction.
    fn soft_sphere(extinction: f32) -> (Medium, Vec3, Vec3) {
        let src = DensitySource::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::splat(0.9),
            falloff: 0.5,
        };
        let m = medium([12; 3], |p| src.density(p), extinction, 0.5);
        let o = Vec3::new(-0.3, -3.0, 0.2);
        (m, o, Vec3::new(0.1, 1.0, -0.05).normalize())
    }

    #[test]
    fn a_segment_past_its_step_limit_is_marched_to_the_same_transmittance() {
        let (m, o, d) = soft_sphere(2.0);
        let want = (-fine_depth(&m, o, d)).exp();
        let sigma = (want * (1.0 - want) / DRAWS as f64).sqrt();
        // About 4 tentative collisions across: most segments go on past the first 2.
        let tracker = Tracker::with_max_steps(&m, 2);
        let mut rng = Rng::new(7, 0);
        let escape = (0..DRAWS)
            .filter(|_| tracker.collide(o, d, f32::INFINITY, &mut rng).is_none())
            .count() as f64
            / DRAWS as f64;
        let ratio = (0..DRAWS)
            .map(|_| tracker.transmittance(o, d, f32::INFINITY, &mut rng) as f64)
            .sum::<f64>()
            / DRAWS as f64;
        let marched = tracker.marched();
        assert!(marched > DRAWS as u64 / 2, "{marched}");
        let tol = SIGMAS * sigma + MARCHED_REST;
        assert!((escape - want).abs() < tol, "{escape} vs {want}");
        assert!((ratio - want).abs() < tol, "{ratio} vs {want}");
        // At the depth limit a segment is nowhere near the step limit.
        let (dense, _, _) = soft_sphere(crate::medium::MAX_VOXEL_DEPTH * 6.0);
        let tracker = Tracker::new(&dense);
        for _ in 0..1000 {
            tracker.collide(o, d, f32::INFINITY, &mut rng);
            tracker.transmittance(o, d, f32::INFINITY, &mut rng);
        }
        assert_eq!(tracker.marched(), 0);
    }

    #[test]
    fn a_huge_extinction_ends_every_segment() {
        // Far past MAX_VOXEL_DEPTH (no scene file takes it): steps of 1e-8 stall below the
        // resolution of distances near 3, and a ray that misses the ball sees only null
        // collisions, so every segment reaches the limit and is marched.
        let m = medium([8; 3], |p| (p.length() < 0.5) as u8 as f32, 1e8, 0.5);
        let tracker = Tracker::new(&m);
        let mut rng = Rng::new(11, 0);
        let o = Vec3::new(-3.0, 0.9, 0.9);
        for _ in 0..2 {
            let tr = tracker.transmittance(o, Vec3::X, f32::INFINITY, &mut rng);
            assert_eq!(tr, 1.0);
            assert_eq!(tracker.collide(o, Vec3::X, f32::INFINITY, &mut rng), None);
        }
        assert_eq!(tracker.marched(), 4);
    }

    #[test]
    fn a_heterogeneous_medium_is_tracked_without_bias() {
        // A soft sphere whose density varies 0..1: ratio and delta tracking against the fine
        // quadrature of the same trilinear density.
        let (m, o, d) = soft_sphere(2.0);
        let want = (-fine_depth(&m, o, d)).exp();
        assert!(want > 0.05 && want < 0.8, "{want}");
        let sigma = (want * (1.0 - want) / DRAWS as f64).sqrt();
        let ratio = estimate_transmittance(&m, o, d, DRAWS, 5);
        let escape = estimate_escape(&m, o, d, DRAWS, 6);
        assert!((ratio - want).abs() < SIGMAS * sigma, "{ratio} vs {want}");
        assert!((escape - want).abs() < SIGMAS * sigma, "{escape} vs {want}");
    }
}
