//! The independent reference for media: a volumetric path tracer that uses no transfer data.
//!
//! Free paths are drawn by delta tracking and shadow rays by ratio tracking
//! ([`crate::medium::tracking`]), so the heterogeneous density leaves no step bias. At every
//! real collision the path's weight takes the albedo (the share that scatters), the light is
//! sampled twice and the two are weighed by the power heuristic (Veach 1997):
//! - **next-event estimation:** a direction drawn from the cube map by importance
//!   ([`CubeSampler`], the sampling of `prt reference`), its transmittance out of the medium
//!   estimated by ratio tracking;
//! - **phase sampling:** a direction drawn from the Henyey–Greenstein lobe ([`sample_hg`]), whose
//!   path either scatters again or leaves the medium and then sees the map.
//!
//! Scattering order k is the number of real collisions on the path; `max_order` stops paths
//! after that many, so order 1 is single scattering. Like `prt volume render`, the image holds
//! the light scattered by the medium only: a camera ray that leaves without a collision counts 0
//! (the environment behind the medium is not part of the image). The map is the same
//! piecewise-constant cube of texels the SH light is projected from, and pixels are sampled at
//! their centres, as the ray march does, so that both see the same medium along the same rays.

use glam::Vec3;

use crate::bake::path_tracer::{PathTraced, PixelPaths};
use crate::env::importance::CubeSampler;
use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;
use crate::math::sampling::{Estimate, Rng, power_heuristic};
use crate::medium::tracking::{Tracker, sample_hg};
use crate::medium::{Medium, henyey_greenstein};
use crate::output::film::Image;
use crate::scene::Camera;

/// Most paths per pixel a reference may ask for.
pub const MAX_SAMPLES: u32 = 1 << 20;
/// Scattering order after which a path's weight goes to Russian roulette.
const ROULETTE_ORDER: u32 = 8;
/// Bytes a pixel of a reference takes: its radiance and standard error (12 bytes each) and its
/// coverage (4).
pub const TRACE_BYTES_PER_PIXEL: u64 = 28;

/// Settings of a volumetric reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VolumeTraceSettings {
    /// Paths per pixel.
    pub samples: u32,
    /// Most real collisions on a path (1 is single scattering); `None` follows every path out.
    pub max_order: Option<u32>,
    /// Seed of every pixel's random stream.
    pub seed: u64,
}

impl Default for VolumeTraceSettings {
    fn default() -> Self {
        VolumeTraceSettings {
            samples: 256,
            max_order: None,
            seed: 1,
        }
    }
}

/// One path's radiance scattered towards the camera along `dir` from `origin`.
fn trace_path(
    tracker: &Tracker,
    cube: &CubeMap,
    sampler: &CubeSampler,
    max_order: u32,
    origin: Vec3,
    dir: Vec3,
    rng: &mut Rng,
) -> Vec3 {
    let medium = tracker.medium();
    let g = medium.g;
    let env = |w: Vec3| Vec3::from_array(cube.lookup(w.as_dvec3()));
    let mut radiance = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let (mut o, mut d) = (origin, dir);
    let Some(t) = tracker.collide(o, d, f32::INFINITY, rng) else {
        return radiance;
    };
    o += d * t;
    let mut order = 1u32;
    loop {
        beta *= medium.albedo;
        // Next-event estimation towards the map.
        let (w, pdf_light) = sampler.sample([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
        if pdf_light > 0.0 {
            let phase = henyey_greenstein(g, w.dot(d));
            let tr = tracker.transmittance(o, w, f32::INFINITY, rng);
            if tr > 0.0 {
                radiance +=
                    beta * env(w) * (tr * phase / pdf_light) * power_heuristic(pdf_light, phase);
            }
        }
        // Phase sampling: the weight phase / pdf is 1.
        let w = sample_hg(g, d, [rng.next_f32(), rng.next_f32()]);
        match tracker.collide(o, w, f32::INFINITY, rng) {
            None => {
                let phase = henyey_greenstein(g, w.dot(d));
                radiance += beta * env(w) * power_heuristic(phase, sampler.pdf(w));
                return radiance;
            }
            Some(t) => {
                if order >= max_order {
                    return radiance;
                }
                o += w * t;
                d = w;
                order += 1;
            }
        }
        if order > ROULETTE_ORDER {
            let q = beta.max_element().min(1.0);
            if rng.next_f32() >= q {
                return radiance;
            }
            beta /= q;
        }
    }
}

/// Path traces `medium` lit by `cube` through `camera` (see the module docs), calling
/// `progress(rows done, rows)`.
pub fn path_trace_volume(
    medium: &Medium,
    cube: &CubeMap,
    camera: &Camera,
    settings: &VolumeTraceSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<PathTraced> {
    medium.validate()?;
    camera.validate()?;
    if !(1..=MAX_SAMPLES).contains(&settings.samples) {
        return Err(PrtError::invalid(
            "samples",
            format!("{}; it must be from 1 to {MAX_SAMPLES}", settings.samples),
        ));
    }
    if settings.max_order == Some(0) {
        return Err(PrtError::invalid(
            "max order",
            "0; a path must scatter at least once (1 is single scattering)",
        ));
    }
    let max_order = settings.max_order.unwrap_or(u32::MAX);
    let (w, h) = (camera.width as usize, camera.height as usize);
    let field = "camera.width/height";
    let what = format!("a {w} x {h} volume reference ({TRACE_BYTES_PER_PIXEL} bytes a pixel)");
    let pixels = w as u64 * h as u64;
    crate::files::check_memory(field, &what, pixels * TRACE_BYTES_PER_PIXEL)?;
    let image = Image {
        width: w,
        height: h,
        pixels: crate::files::try_filled(field, &what, w * h, [0.0f32; 3])?,
    };
    let std_error = crate::files::try_filled(field, &what, w * h, [0.0f32; 3])?;
    let coverage = crate::files::try_filled(field, &what, w * h, 0.0f32)?;
    let samples = settings.samples;
    let Some(sampler) = CubeSampler::new(cube) else {
        // A black map lights nothing.
        return Ok(PathTraced {
            image,
            coverage,
            std_error,
            samples,
        });
    };
    let tracker = Tracker::new(medium);
    let pixel = |x: usize, y: usize| {
        let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
        let mut rng = Rng::new(settings.seed, (y * w + x) as u64);
        let mut estimate = Estimate::default();
        let mut scattered = 0u32;
        for _ in 0..samples {
            let l = trace_path(
                &tracker, cube, &sampler, max_order, ray.origin, ray.dir, &mut rng,
            );
            if l != Vec3::ZERO {
                scattered += 1;
            }
            estimate.add(l);
        }
        PixelPaths {
            estimate,
            count: samples as usize,
            coverage: scattered as f32 / samples as f32,
        }
    };
    Ok(PathTraced::fill(
        image, coverage, std_error, samples, progress, pixel,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::DensitySource;
    use crate::medium::tracking::tests::medium;

    /// Standard errors an estimate may stray: a true failure (a wrong free-path law, a lobe
    /// turned the wrong way) is off by tens of them.
    const SIGMAS: f64 = 4.5;

    /// A ball of radius 0.8 at the origin whose density falls off over `falloff`, on a 16³ grid
    /// of this extinction and albedo.
    fn ball(falloff: f32, extinction: f32, albedo: f32) -> Medium {
        let src = DensitySource::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::splat(0.8),
            falloff,
        };
        medium([16; 3], |p| src.density(p), extinction, albedo)
    }

    fn camera(size: u32) -> Camera {
        Camera {
            eye: Vec3::new(0.0, 0.4, 4.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 40.0,
            width: size,
            height: size,
        }
    }

    #[test]
    fn albedo_one_under_a_white_sky_is_the_medium_white_furnace() {
        // With no absorption and radiance 1 from every direction, radiance is 1 everywhere in the
        // medium, so what it scatters to the camera is 1 − T along the camera ray.
        let m = ball(0.4, 6.0, 1.0);
        let cube = CubeMap::constant(8, [1.0; 3]).unwrap();
        let cam = camera(12);
        let settings = VolumeTraceSettings {
            samples: 48,
            ..Default::default()
        };
        let traced = path_trace_volume(&m, &cube, &cam, &settings, &|_, _| {}).unwrap();
        let mut checked = 0;
        for (i, (p, e)) in traced
            .image
            .pixels
            .iter()
            .zip(&traced.std_error)
            .enumerate()
        {
            let ray = cam.ray((i % 12) as f32 + 0.5, (i / 12) as f32 + 0.5);
            let want =
                1.0 - (-crate::medium::tracking::tests::fine_depth(&m, ray.origin, ray.dir)).exp();
            for c in 0..3 {
                // The reported error, or the Bernoulli spread of meeting the medium at all (the
                // report is 0 where no path of a faint fringe happened to scatter).
                let bernoulli = (want * (1.0 - want) / settings.samples as f64).sqrt();
                let tol = SIGMAS * (e[c] as f64).max(bernoulli) + 1e-3;
                assert!(
                    (p[c] as f64 - want).abs() < tol,
                    "pixel {i}: {} vs 1 − T = {want} (± {})",
                    p[c],
                    e[c]
                );
            }
            checked += usize::from(want > 0.5);
        }
        assert!(checked > 10, "the camera must see the thick middle");
    }

    #[test]
    fn order_one_is_single_scattering_and_thin_media_barely_scatter_twice() {
        use crate::volume::{TransferSettings, VolumeLight, VolumeTransfer, bake_transfer};
        // An optically thin sphere (depth about 0.15 across) lit by a sky with a bright patch.
        let m = ball(0.3, 0.1, 0.8);
        let n = 8;
        let patch = glam::DVec3::new(0.5, 0.7, 0.5).normalize();
        let cube = CubeMap::from_fn(n, |d| {
            let sun = 20.0 * (d.dot(patch) > 0.9) as u8 as f32;
            let sky = 0.5 + 0.4 * d.y as f32;
            [sky + sun, sky + 0.5 * sun, sky]
        })
        .unwrap();
        let cam = camera(12);
        let single = VolumeTraceSettings {
            samples: 256,
            max_order: Some(1),
            seed: 2,
        };
        let traced = path_trace_volume(&m, &cube, &cam, &single, &|_, _| {}).unwrap();
        let settings = TransferSettings::default();
        let vt = VolumeTransfer {
            meta: crate::volume::tests::meta_for(&m, 3, settings.directions),
            density: m.grid.data.clone(),
            transfer: bake_transfer(&m, &settings, &|_, _| {}).unwrap(),
            scatter: None,
        };
        let light = VolumeLight::single(&cube, 3, m.albedo, m.g);
        let marched = crate::volume::render_volume(&vt, &light, &cam, Default::default());
        let err = crate::output::metrics::relative_l2(&marched, &traced.image, None).unwrap();
        let noise = traced.relative_noise(None);
        // The march's half-voxel steps and the transfer's SH truncation of a nearly constant
        // transmittance leave well under 1%; the rest is the tracer's noise.
        assert!(
            err < 0.01 + 3.0 * noise,
            "single scattering {err} (noise {noise})"
        );
        // All orders: a depth of 0.15 scatters a second time about 0.15 · 0.8 as often.
        let all = VolumeTraceSettings {
            max_order: None,
            ..single
        };
        let every = path_trace_volume(&m, &cube, &cam, &all, &|_, _| {}).unwrap();
        let total = |i: &Image| i.pixels.iter().flatten().map(|&v| v as f64).sum::<f64>();
        let gain = total(&every.image) / total(&traced.image) - 1.0;
        assert!(gain > 0.0 && gain < 0.15, "higher orders add {gain}");
    }
}
