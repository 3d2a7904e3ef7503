//! The independent reference for interreflections: a path tracer that lights the scene with the
//! cube map directly, with no rows, no surface cache and none of the bake's paths.
//!
//! At every path vertex it draws one light direction from the map by importance
//! ([`crate::env::importance::CubeSampler`]) and one direction from the material ([`crate::scene::brdf::Lobes::sample`]), and weighs the two
//! by multiple importance sampling with the power heuristic (Veach 1997), as pbrt-v4's path
//! integrator does. The map is the same piecewise-constant cube of texels the bake is lit by, so
//! a converged image differs from the bake's with every term only by the bake's own errors (its
//! per-texel quadrature, its surface cache, its path noise). Each pixel's estimate comes with its
//! standard error, so agreement can be judged against the reference's own noise.
//!
//! Local lights join in the same way ([`path_trace_env`], each light column weighted by a
//! [`LightMix`]): at every vertex each light that is on is sampled once (a quad by area,
//! converted to solid angle; a sun disc uniformly over its cone; points and spots as deltas),
//! and a material-sampled direction that reaches a quad or a disc before any surface brings its
//! light too, the two weighed by the power heuristic, so small lights and glossy surfaces both
//! converge. It uses none of the bake's light samples.
//!
//! A medium ([`path_trace`] of a scene with a `[medium]`) is tracked, not marched: every segment,
//! the camera ray's included, draws its free path by delta tracking ([`Tracker`]), so it either
//! reaches the next surface or collides in the medium. A collision is a vertex like a surface's:
//! it takes the albedo, samples the map (its transmittance by ratio tracking, and the surfaces by
//! a shadow ray) and the Henyey–Greenstein lobe, weighed by the power heuristic, and counts as a
//! bounce. Shadow rays from surfaces take the medium's ratio-tracked transmittance. It uses none
//! of the bake's tables: no sweep, no lattice, no transmittance table.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};

use glam::Vec3;
use rayon::prelude::*;

use crate::bake::bounce::Vertex;
use crate::bake::{BakeSettings, EdgeMap, pixel_subsamples, shading_point};
use crate::env::importance::{CubeLight, EnvLight};
use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;
use crate::math::sampling::{Estimate, Rng};
use crate::medium::henyey_greenstein;
use crate::medium::tracking::{Tracker, sample_hg};
use crate::output::film::Image;
use crate::scene::light::{Emitter, emitters};
use crate::scene::light_mix::LightMix;
use crate::scene::trace::Tracer;
use crate::scene::{Material, Scene};

use super::lights::power_heuristic;
use super::reference::light_weights;
use super::settings::MAX_SPP;

/// A path-traced image with its per-pixel standard error.
pub struct PathTraced {
    /// Linear radiance of each pixel: the mean of its paths (a camera ray that misses the scene
    /// counts as 0).
    pub image: Image,
    /// Fraction of each pixel's camera sub-samples that hit geometry.
    pub coverage: Vec<f32>,
    /// Standard error of each pixel's mean, per channel.
    pub std_error: Vec<[f32; 3]>,
    /// Samples asked for per pixel (a pixel takes a multiple of its sub-samples at least as large).
    pub samples: u32,
}

/// One pixel's paths: their estimate, how many were taken (those that found nothing count as
/// zero), and the share of them that found something to light.
pub(crate) struct PixelPaths {
    /// The sums of the paths' radiance.
    pub(crate) estimate: Estimate,
    /// Paths taken (at least one).
    pub(crate) count: usize,
    /// Fraction of the paths that met geometry (or the medium).
    pub(crate) coverage: f32,
}

impl PathTraced {
    /// Fills every pixel of `image`, `coverage` and `std_error` (sized alike, `samples` paths
    /// asked for a pixel) by `pixel(x, y)`, rows in parallel, calling `progress(rows done,
    /// rows)` after each. The loop both path tracers share: what a pixel's paths are is theirs.
    pub(crate) fn fill(
        mut image: Image,
        mut coverage: Vec<f32>,
        mut std_error: Vec<[f32; 3]>,
        samples: u32,
        progress: &(dyn Fn(usize, usize) + Sync),
        pixel: impl Fn(usize, usize) -> PixelPaths + Sync,
    ) -> PathTraced {
        let (w, h) = (image.width, image.height);
        debug_assert!(coverage.len() == w * h && std_error.len() == w * h);
        // Chunks of at least one (an empty image has no rows to fill).
        let row = w.max(1);
        let rows_done = AtomicUsize::new(0);
        image
            .pixels
            .par_chunks_mut(row)
            .zip(coverage.par_chunks_mut(row))
            .zip(std_error.par_chunks_mut(row))
            .enumerate()
            .for_each(|(y, ((line, line_coverage), line_error))| {
                for x in 0..w {
                    let p = pixel(x, y);
                    line[x] = p.estimate.mean(p.count);
                    line_coverage[x] = p.coverage;
                    line_error[x] = p.estimate.std_error(p.count);
                }
                progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1, h);
            });
        PathTraced {
            image,
            coverage,
            std_error,
            samples,
        }
    }

    /// The image's noise as a relative L2: the root sum of squared standard errors over the root
    /// sum of squared values, over the pixels `mask` keeps (all when `None`).
    pub fn relative_noise(&self, mask: Option<&[bool]>) -> f64 {
        let (mut noise, mut value) = (0.0f64, 0.0f64);
        for (i, (p, e)) in self.image.pixels.iter().zip(&self.std_error).enumerate() {
            if mask.is_some_and(|m| !m[i]) {
                continue;
            }
            for k in 0..3 {
                noise += (e[k] as f64).powi(2);
                value += (p[k] as f64).powi(2);
            }
        }
        if value > 0.0 {
            (noise / value).sqrt()
        } else {
            0.0
        }
    }
}

/// Path traces `scene` under `cube` with `samples` paths per pixel (rounded up to a multiple of
/// the pixel's camera sub-samples, which it cycles through), up to `settings.bounces` bounces
/// after the camera hit. Uses the bake's camera sub-samples, seed and `unshadowed`; calls
/// `progress(rows done, rows)`. A material whose lobe gives a value that is not finite is an
/// error that names it and a pixel where a path met it.
pub fn path_trace(
    scene: &Scene,
    cube: &CubeMap,
    settings: &BakeSettings,
    samples: u32,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<PathTraced> {
    path_trace_env(
        scene,
        &CubeLight::new(cube),
        &LightMix::none(),
        settings,
        samples,
        progress,
    )
}

/// `scene` seen from `camera`, path traced under the environment `env` alone (no local lights)
/// with `samples` paths a pixel, as the reference of a drawing: an image that is not finite is
/// an error.
///
/// A drawn pixel is the mean over its area (its samples spread over it), so each path here
/// passes through a point of its own in the pixel (the first 4,096 paths; then again):
/// stratified on a grid when `samples` is a square such as 1,024, uniform otherwise, whatever
/// `settings` asks of a baked pixel (its centre, and more only on edges). A
/// highlight smaller than a pixel is far from its pixel's mean at the pixel's centre: the glossy
/// sphere at 64² was 35% apart in the two (measured).
pub fn path_trace_from(
    scene: &Scene,
    camera: &crate::scene::Camera,
    env: &dyn EnvLight,
    settings: &BakeSettings,
    samples: u32,
) -> Result<PathTraced> {
    path_trace_from_lit(scene, camera, (env, &LightMix::none()), settings, samples)
}

/// [`path_trace_from`] with the scene's local lights too, each column weighted by `lights`:
/// the reference of a drawing of a bake relit with them.
pub fn path_trace_from_lit(
    scene: &Scene,
    camera: &crate::scene::Camera,
    (env, lights): (&dyn EnvLight, &LightMix),
    settings: &BakeSettings,
    samples: u32,
) -> Result<PathTraced> {
    let mut seen = scene.clone();
    seen.camera = camera.clone();
    let spread = samples.clamp(1, MAX_SPP);
    let settings = BakeSettings {
        spp: spread,
        edge_spp: spread,
        ..settings.clone()
    };
    let traced = path_trace_env(&seen, env, lights, &settings, samples, &|_, _| {})?;
    traced.image.check_finite("path-traced image")?;
    Ok(traced)
}

/// [`path_trace`] plus the scene's local lights, each column weighted by `lights` (one RGB weight
/// per light column, or none), under any environment light: a cube ([`CubeLight`]), or a
/// lat-long map's own pixels ([`crate::env::importance::MapLight`]), the true lighting with no
/// cube's resolution in between.
pub fn path_trace_env(
    scene: &Scene,
    env: &dyn EnvLight,
    lights: &LightMix,
    settings: &BakeSettings,
    samples: u32,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<PathTraced> {
    settings.validate()?;
    let weights = light_weights(lights, emitters(&scene.lights).len())?;
    let lit: Vec<(Emitter, Vec3)> = emitters(&scene.lights)
        .into_iter()
        .zip(&weights)
        .map(|(e, w)| (e, Vec3::from_array(*w)))
        .filter(|(_, w)| *w != Vec3::ZERO)
        .collect();
    if scene.medium.is_some() && !lit.is_empty() {
        return Err(PrtError::invalid(
            "lights",
            "local lights are not traced through a medium yet; light a scene with a [medium] by \
             its environment only",
        ));
    }
    let medium = match &scene.medium {
        Some(spec) => Some(spec.build(None)?),
        None => None,
    };
    let tracker = medium.as_ref().map(Tracker::new);
    if !(1..=1 << 20).contains(&samples) {
        return Err(PrtError::invalid(
            "samples",
            format!("{samples}; it must be from 1 to 1048576"),
        ));
    }
    let tracer = Tracer::new(scene);
    let cam = &scene.camera;
    let edges = EdgeMap::new(scene, &tracer, settings);
    let (w, h) = (cam.width as usize, cam.height as usize);
    // The first pixel (in reading order) whose paths met a material gone non-finite, and it.
    let blamed: Mutex<Option<(usize, usize, u32)>> = Mutex::new(None);
    let pixel = |x: usize, y: usize| {
        let subs = pixel_subsamples(&edges, cam, settings, x as u32, y as u32);
        let count = samples.div_ceil(subs.len() as u32) as usize * subs.len();
        let mut rng = Rng::new(settings.seed ^ 0x9a7b_7ace, (y * w + x) as u64);
        let mut estimate = Estimate::default();
        let mut hits = 0usize;
        for i in 0..count {
            let (fx, fy) = subs[i % subs.len()];
            let ray = cam.ray(fx, fy);
            let hit = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY);
            let t_hit = hit.map_or(f32::INFINITY, |h| h.t);
            let collision = tracker
                .as_ref()
                .and_then(|t| Some((t.collide(ray.origin, ray.dir, t_hit, &mut rng)?, t)));
            let (first, throughput) = match (collision, hit) {
                (Some((t, tracker)), _) => (
                    Vertex::Medium {
                        pos: ray.origin + ray.dir * t,
                        dir: ray.dir,
                    },
                    tracker.medium().albedo,
                ),
                (None, Some(hit)) => (
                    Vertex::Surface(shading_point(&tracer, &hit, ray.dir)),
                    Vec3::ONE,
                ),
                (None, None) => continue,
            };
            hits += 1;
            let lighting = Lighting {
                env,
                lights: &lit,
                tracker: tracker.as_ref(),
            };
            match radiance(
                scene,
                &tracer,
                &lighting,
                settings,
                (first, throughput),
                &mut rng,
            ) {
                Ok(l) => estimate.add(l),
                Err(material) => {
                    let mut b = blamed.lock().unwrap_or_else(PoisonError::into_inner);
                    if b.as_ref().is_none_or(|&(bx, by, _)| (y, x) < (by, bx)) {
                        *b = Some((x, y, material));
                    }
                }
            }
        }
        PixelPaths {
            estimate,
            count,
            coverage: hits as f32 / count as f32,
        }
    };
    let (coverage, std_error) = (vec![0.0f32; w * h], vec![[0.0f32; 3]; w * h]);
    let traced = PathTraced::fill(
        Image::new(w, h),
        coverage,
        std_error,
        samples,
        progress,
        pixel,
    );
    if let Some((x, y, m)) = blamed.into_inner().unwrap_or_else(PoisonError::into_inner) {
        return Err(non_finite_material(scene, x, y, m));
    }
    Ok(traced)
}

/// The error of a material whose lobe gave a NaN or infinite value on a path through pixel
/// (x, y): it names the material, since neither the environment nor the lights are to blame.
fn non_finite_material(scene: &Scene, x: usize, y: usize, m: u32) -> PrtError {
    let name = scene
        .material_names
        .get(m as usize)
        .map_or("?", String::as_str);
    let lobe = match scene.materials.get(m as usize) {
        Some(Material::Glossy { roughness, .. }) => {
            format!("its glossy lobe, roughness {roughness}")
        }
        _ => "its lobe".to_string(),
    };
    PrtError::invalid(
        format!("material `{name}`"),
        format!(
            "pixel (x = {x}, y = {y}) of the path-traced image is NaN: {lobe}, evaluated or \
             sampled where a path met it, is not finite in 32-bit floats (the material is to \
             blame, not the environment or the lights)"
        ),
    )
}

/// What lights a path: the environment, and the local lights that are on, each with its RGB
/// weight.
struct Lighting<'a> {
    env: &'a dyn EnvLight,
    lights: &'a [(Emitter, Vec3)],
    /// The medium's trackers, with a medium.
    tracker: Option<&'a Tracker<'a>>,
}

/// Radiance leaving the first vertex (a camera hit, or a collision along the camera ray with
/// its albedo as the throughput) towards the camera, by one path; or the index of a material
/// whose lobe gave a value that is not finite at a vertex of the path.
fn radiance(
    scene: &Scene,
    tracer: &Tracer,
    lighting: &Lighting,
    settings: &BakeSettings,
    (first, mut throughput): (Vertex, Vec3),
    rng: &mut Rng,
) -> std::result::Result<Vec3, u32> {
    let Lighting {
        env: light,
        lights,
        tracker,
    } = *lighting;
    let env = |d: Vec3| light.radiance(d);
    let mut total = Vec3::ZERO;
    let mut at = first;
    // The medium's transmittance along a shadow ray, by ratio tracking.
    let through = |o: Vec3, d: Vec3, rng: &mut Rng| match tracker {
        Some(t) if !settings.unshadowed => t.transmittance(o, d, f32::INFINITY, rng),
        _ => 1.0,
    };
    for depth in 0..=settings.bounces {
        // Light sampling, then the next direction with its weight and density.
        let (origin, dir, weight, pdf) = match &at {
            Vertex::Surface(sp) => {
                let lobes = sp.lobes(scene);
                let (n, v) = (sp.normal, sp.view);
                // The lobe's value and density towards `d`, or the material to blame.
                let lobe = |d: Vec3| {
                    let (f, p) = (lobes.eval_cosine(n, v, d), lobes.pdf(n, v, d));
                    if f.is_finite() && p.is_finite() {
                        Ok((f, p))
                    } else {
                        Err(sp.material)
                    }
                };
                if light.drawable() {
                    let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                    let (d, p_light) = light.sample(u);
                    if p_light > 0.0
                        && n.dot(d) > 0.0
                        && (settings.unshadowed || !tracer.occluded(sp.origin, d, f32::INFINITY))
                    {
                        let (f, p_brdf) = lobe(d)?;
                        let w = power_heuristic(p_light, p_brdf);
                        let tr = through(sp.origin, d, rng);
                        total += throughput * f * env(d) * (tr * w / p_light);
                    }
                }
                // Local lights: one sample of each.
                for (e, rgb) in lights {
                    let u = [rng.next_f32(), rng.next_f32()];
                    let Some(ls) = e.sample(sp.origin, u) else {
                        continue;
                    };
                    if n.dot(ls.dir) <= 0.0
                        || (!settings.unshadowed && tracer.occluded(sp.origin, ls.dir, ls.dist))
                    {
                        continue;
                    }
                    let (f, p_brdf) = lobe(ls.dir)?;
                    let w = if ls.pdf > 0.0 {
                        power_heuristic(ls.pdf, p_brdf)
                    } else {
                        1.0
                    };
                    total += throughput * f * *rgb * (ls.weight * w);
                }
                let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                let Some(s) = lobes.sample(n, v, u) else {
                    break;
                };
                if !(s.weight.is_finite() && s.pdf.is_finite()) {
                    return Err(sp.material);
                }
                (sp.origin, s.dir, s.weight, s.pdf)
            }
            Vertex::Medium { pos, dir } => {
                let g = tracker.map_or(0.0, |t| t.medium().g);
                if light.drawable() {
                    let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                    let (d, p_light) = light.sample(u);
                    if p_light > 0.0
                        && (settings.unshadowed || !tracer.occluded(*pos, d, f32::INFINITY))
                    {
                        let phase = henyey_greenstein(g, d.dot(*dir));
                        let tr = through(*pos, d, rng);
                        let w = power_heuristic(p_light, phase);
                        total += throughput * env(d) * (tr * phase * w / p_light);
                    }
                }
                let d = sample_hg(g, *dir, [rng.next_f32(), rng.next_f32()]);
                (*pos, d, Vec3::ONE, henyey_greenstein(g, d.dot(*dir)))
            }
        };
        // The next segment: a collision in the medium, a surface, or the map.
        let hit = tracer.closest_hit(origin, dir, f32::INFINITY);
        let t_hit = match &hit {
            Some(h) if !settings.unshadowed => h.t,
            _ => f32::INFINITY,
        };
        let collision = match tracker {
            Some(t) if !settings.unshadowed => t.collide(origin, dir, t_hit, rng),
            _ => None,
        };
        if collision.is_none() && (hit.is_none() || settings.unshadowed) {
            let p_light = light.pdf(dir);
            total += throughput * weight * env(dir) * power_heuristic(pdf, p_light);
        }
        if collision.is_none() {
            for (e, rgb) in lights {
                if let Some((t, radiance, p_light)) = e.hit(origin, dir)
                    && t <= t_hit
                {
                    total +=
                        throughput * weight * *rgb * (radiance * power_heuristic(pdf, p_light));
                }
            }
        }
        throughput *= weight;
        if depth == settings.bounces {
            break;
        }
        at = match (collision, hit, tracker) {
            (Some(t), _, Some(tracker)) => {
                throughput *= tracker.medium().albedo;
                Vertex::Medium {
                    pos: origin + dir * t,
                    dir,
                }
            }
            (None, Some(hit), _) => Vertex::Surface(shading_point(tracer, &hit, dir)),
            _ => break,
        };
    }
    Ok(total)
}
