//! The medium through the per-pixel wavelet bake: for every pixel, the single-scattered radiance
//! along its camera ray from each cube texel light,
//! `row_t = Σ_k T_cam(x_k) sigma_t(x_k) dt · Σ_m p(w_m·d) Ω_m · exp(−tau(x_k, w_t)) V(x_k, w_t)`
//! (the medium's albedo is the row's RGB weight), up to the surface the ray hits; V is whether a
//! surface blocks the texel, from the lattice of [`MediumLight`].
//!
//! The rows are computed texel by texel: one [`Sweeper`] pass gives the transmittance towards
//! the texel's centre direction at every voxel, and every pixel's march samples (located in the
//! grid once, up front) read it trilinearly. That is one sweep per texel instead of one shadow march per (sample, texel). The
//! rows are held texel-major (6 N² × pixels floats) until the tiles take them.

use glam::Vec3;
use rayon::prelude::*;

use crate::bake::medium_light::{LatticePoint, MediumLight, Seen};
use crate::error::{PrtError, Result};
use crate::math::cubemap::{texel_count, texel_dirs};
use crate::math::sampling::{TexelSamples, pixel_samples};
use crate::medium::sweep::{Located, Sweeper};
use crate::medium::{Medium, henyey_greenstein};
use crate::scene::Scene;
use crate::scene::trace::Tracer;

/// Most bytes the texel-major medium rows may take.
pub const MAX_MEDIUM_ROW_BYTES: u64 = 4 << 30;

/// One camera sub-sample's march: its direction and its samples' range.
struct SubRay {
    dir: Vec3,
    samples: std::ops::Range<usize>,
}

/// A pixel's camera sub-rays and their march samples (located, weighted).
/// A pixel's camera sub-rays and their march samples: located in the sweeps with their weights,
/// and apart (read only for texels some surface hides) located in the visibility lattice.
type PixelMarch = (Vec<SubRay>, Vec<([Located; 3], f32)>, Vec<LatticePoint>);

/// The medium rows of every pixel, texel-major.
pub struct MediumRows {
    pixels: usize,
    texels: usize,
    cols: Vec<f32>,
    /// Whether a pixel's rays meet the medium at all.
    touched: Vec<bool>,
    /// A pixel's opacity: `Σ_k T_cam sigma_t dt`, about `1 − T_cam`, averaged over sub-samples.
    opacity: Vec<f32>,
    /// Squared norm of the row of an unshadowed isotropic medium of opacity 1:
    /// `Σ_t (Ω_t / 4π)²`.
    unshadowed_energy: f64,
}

impl MediumRows {
    /// Bakes the rows of the pixels `wanted(pixel)` of `scene`'s view through `medium` (sub-samples
    /// as the bake's: `[spp, seed]`), texel lights of `samples`, surfaces' visibility of `light`.
    /// Calls `progress(texels done, texels)`.
    pub fn bake(
        (medium, light): (&Medium, &MediumLight),
        scene: &Scene,
        tracer: &Tracer,
        samples: &TexelSamples,
        [spp, seed]: [u64; 2],
        wanted: &(dyn Fn(usize) -> bool + Sync),
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<MediumRows> {
        let spp = spp as u32;
        let cam = &scene.camera;
        let (w, h) = (cam.width as usize, cam.height as usize);
        let n = samples.n;
        let texels = texel_count(n);
        let bytes = (texels * w * h * 4) as u64;
        if bytes > MAX_MEDIUM_ROW_BYTES {
            return Err(PrtError::invalid(
                "medium",
                format!(
                    "the medium rows of {w}x{h} pixels at N = {n} need {} MiB (at most {} MiB): \
                     bake a smaller image or cube",
                    bytes >> 20,
                    MAX_MEDIUM_ROW_BYTES >> 20
                ),
            ));
        }
        // Every pixel's sub-rays and march samples, weights already divided by the sub-samples.
        let sweeper = Sweeper::new(medium);
        let per_pixel: Vec<PixelMarch> = (0..w * h)
            .into_par_iter()
            .map(|p| {
                let (mut rays, mut marks, mut points) = (Vec::new(), Vec::new(), Vec::new());
                if !wanted(p) {
                    return (rays, marks, points);
                }
                let (x, y) = (p % w, p / w);
                let subs = pixel_samples(x as u32, y as u32, w as u32, spp, seed);
                let inv = 1.0 / subs.len() as f32;
                let mut march = Vec::new();
                for (fx, fy) in subs {
                    let ray = cam.ray(fx, fy);
                    let t_max = tracer
                        .closest_hit(ray.origin, ray.dir, f32::INFINITY)
                        .map_or(f32::INFINITY, |hit| hit.t);
                    medium.march_camera(ray.origin, ray.dir, t_max, &mut march);
                    let start = marks.len();
                    marks.extend(
                        march
                            .iter()
                            .map(|s| (sweeper.locate(s.pos), s.weight * inv)),
                    );
                    points.extend(march.iter().map(|s| light.locate(s.pos)));
                    if marks.len() > start {
                        rays.push(SubRay {
                            dir: ray.dir,
                            samples: start..marks.len(),
                        });
                    }
                }
                (rays, marks, points)
            })
            .collect();
        let touched: Vec<bool> = per_pixel.iter().map(|(r, _, _)| !r.is_empty()).collect();
        let opacity: Vec<f32> = per_pixel
            .iter()
            .map(|(_, marks, _)| marks.iter().map(|(_, w)| w).sum())
            .collect();
        let unshadowed_energy: f64 = (0..texels)
            .map(|t| {
                let o: f64 = samples.weights[t * samples.per_texel..(t + 1) * samples.per_texel]
                    .iter()
                    .map(|w| *w as f64)
                    .sum();
                (o / (4.0 * std::f64::consts::PI)).powi(2)
            })
            .sum();
        let centres: Vec<Vec3> = texel_dirs(n).iter().map(|d| d.as_vec3()).collect();
        let pixels = w * h;
        let mut cols = vec![0.0f32; texels * pixels];
        let done = std::sync::atomic::AtomicUsize::new(0);
        cols.par_chunks_mut(pixels)
            .enumerate()
            .for_each(|(t, col)| {
                let seen_from = light.seen(t);
                // Where surfaces hide the texel from the whole medium, its column stays 0.
                if seen_from != Seen::Nowhere {
                    let column = Column {
                        medium,
                        light,
                        sweeper: &sweeper,
                        samples,
                        per_pixel: &per_pixel,
                    };
                    column.fill(t, centres[t], col);
                }
                let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                if d.is_multiple_of(64) || d == texels {
                    progress(d, texels);
                }
            });
        Ok(MediumRows {
            pixels,
            texels,
            cols,
            touched,
            opacity,
            unshadowed_energy,
        })
    }

    /// The scale of `pixel`'s thresholding budget: the energy of the row of an unshadowed
    /// isotropic medium of the pixel's opacity. A surface row's budget is absolute (shadowed
    /// surfaces are dark); a thin fringe of medium is faint everywhere, and an absolute budget
    /// would drop it whole.
    pub fn reference_energy(&self, pixel: usize) -> f64 {
        self.unshadowed_energy * (self.opacity[pixel] as f64).powi(2)
    }

    /// The dense row of `pixel` (texel order), or `None` when its rays miss the medium.
    pub fn row(&self, pixel: usize) -> Option<Vec<f32>> {
        self.touched[pixel].then(|| {
            (0..self.texels)
                .map(|t| self.cols[t * self.pixels + pixel])
                .collect()
        })
    }
}

/// What every texel's column of the medium rows reads.
struct Column<'a> {
    medium: &'a Medium,
    light: &'a MediumLight,
    sweeper: &'a Sweeper,
    samples: &'a TexelSamples,
    /// Every pixel's sub-rays and march samples.
    per_pixel: &'a [PixelMarch],
}

impl Column<'_> {
    /// The medium rows' column of texel `t` (centre direction `centre`) for every pixel, into `col`.
    fn fill(&self, t: usize, centre: Vec3, col: &mut [f32]) {
        let Column {
            medium,
            light,
            sweeper,
            samples,
            per_pixel,
        } = *self;
        let m = samples.per_texel;
        let open = sweeper.transmittance(centre);
        let dirs = &samples.dirs[t * m..(t + 1) * m];
        let omegas = &samples.weights[t * m..(t + 1) * m];
        let partly = light.seen(t) == Seen::Partly;
        for (p, (rays, marks, points)) in per_pixel.iter().enumerate() {
            let mut sum = 0.0f32;
            for ray in rays {
                let phase: f32 = dirs
                    .iter()
                    .zip(omegas)
                    .map(|(wd, o)| henyey_greenstein(medium.g, wd.dot(ray.dir)) * o)
                    .sum();
                let mut s = 0.0f32;
                let range = ray.samples.clone();
                if partly {
                    for ((loc, weight), at) in marks[range.clone()].iter().zip(&points[range]) {
                        let seen = light.visibility(t, at);
                        if seen > 0.0 {
                            s += weight * open.at_located(loc) * seen;
                        }
                    }
                } else {
                    for (loc, weight) in &marks[range] {
                        s += weight * open.at_located(loc);
                    }
                }
                sum += phase * s;
            }
            col[p] = sum;
        }
    }
}
