//! The brute-force reference: the scene ray traced under a cube map whose texels are
//! piecewise-constant lights, with no transport matrix. It is the ground truth for tests and
//! benchmarks, so it is written to be obviously right: for every camera sub-sample and every texel
//! sample direction, visibility x BRDF x cos x solid angle x radiance, summed; with bounces, the
//! same seeded paths and surface cache as the bake, each vertex bringing its throughput times its
//! own direct light (so this checks the matrix's bookkeeping; the independent check of the
//! interreflections is [`crate::bake::path_tracer`]).
//! A medium attenuates what the camera sees and every shadow ray, and adds single scattering along
//! the camera ray: at every march sample and texel sample direction, a shadow ray is traced
//! against the surfaces and its transmittance marched through the medium directly (no sweep, no
//! SH, no matrix). With bounces, the bake's own paths through the medium, those from the camera
//! hit and those from collisions along the camera ray, with its transmittance table.

use rayon::prelude::*;

use glam::Vec3;

use crate::bake::LightSampler;
use crate::bake::bounce::Bounces;
use crate::bake::lights::Draw;
use crate::bake::medium_light::MediumLight;
use crate::bake::{
    BakeSettings, EdgeMap, Shadows, direct_texels, path_stream, pixel_subsamples, sample_stride,
    shading_point,
};
use crate::error::Result;
use crate::math::cubemap::CubeMap;
use crate::math::sampling::TexelSamples;
use crate::medium::henyey_greenstein;
use crate::output::film::Image;
use crate::scene::Scene;
use crate::scene::light_mix::LightMix;
use crate::scene::trace::Tracer;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Renders `scene` lit by `cube` with the sampling of `settings` (spp, texel samples, seed,
/// unshadowed); the cube's N is the texel-light resolution.
pub fn render_reference(scene: &Scene, cube: &CubeMap, settings: &BakeSettings) -> Result<Image> {
    Ok(render_reference_with(scene, cube, settings, &|_, _| {})?.image)
}

/// A reference image and, per pixel, the fraction of its camera sub-samples that hit geometry
/// (as a bake's `coverage`).
pub struct Reference {
    /// The rendered image.
    pub image: Image,
    /// Fraction of each pixel's camera sub-samples that hit geometry, in [0, 1].
    pub coverage: Vec<f32>,
}

/// [`render_reference`], with the coverage, calling `progress(rows done, rows)` as rows finish.
pub fn render_reference_with(
    scene: &Scene,
    cube: &CubeMap,
    settings: &BakeSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Reference> {
    render_reference_lit(scene, cube, &LightMix::none(), settings, progress)
}

/// [`render_reference_with`] plus the scene's local lights weighted by `lights` (one RGB weight
/// per light column, or none), sampled as the bake samples them ([`LightSampler`]): with the
/// same seed, the same samples, so this checks the bake's light columns' bookkeeping.
pub fn render_reference_lit(
    scene: &Scene,
    cube: &CubeMap,
    lights: &LightMix,
    settings: &BakeSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Reference> {
    cube.expect_n(settings.cube_n, "the settings ask for")?;
    settings.validate_for(scene)?;
    let tracer = Tracer::new(scene);
    let cam = &scene.camera;
    let (w, h) = (cam.width as usize, cam.height as usize);
    let samples = TexelSamples::new(cube.n, settings.texel_samples as usize, settings.seed)
        .refined(settings.stored_edge_texel_samples() as usize);
    let medium = match &scene.medium {
        Some(spec) => Some(spec.build(None)?),
        None => None,
    };
    let medium = medium.as_ref();
    let shadows = Shadows {
        tracer: &tracer,
        unshadowed: settings.unshadowed,
        medium,
        packets: None, // ray by ray: the slow twin of the bake's packets
    };
    // The bake's own paths and surface cache, so that this checks the matrix's bookkeeping.
    let edges = EdgeMap::new(scene, &tracer, settings);
    let light = match medium {
        Some(m) if settings.bounces > 0 => {
            Some(MediumLight::build(m, &tracer, cube.n, true, &|_, _| {})?)
        }
        _ => None,
    };
    let bounces = Bounces::new(scene, &tracer, settings, &samples)
        .with_medium(medium.zip(light.as_ref()))
        .with_cache(&edges, &|_| true, &|_, _| {})?;
    let sampler = LightSampler::new(scene, settings);
    let weights = light_weights(lights, sampler.columns())?;
    let mut image = Image::new(w, h);
    let mut coverage = vec![0.0f32; w * h];
    let rows_done = AtomicUsize::new(0);
    image
        .pixels
        .par_chunks_mut(w)
        .zip(coverage.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (line, line_coverage))| {
            for (x, (px, cov)) in line.iter_mut().zip(line_coverage).enumerate() {
                let subs = pixel_subsamples(&edges, cam, settings, x as u32, y as u32);
                let inv_spp = 1.0 / subs.len() as f64;
                let mut sum = [0.0f64; 3];
                let mut march = Vec::new();
                for (sub, (fx, fy)) in subs.into_iter().enumerate() {
                    let ray = cam.ray(fx, fy);
                    let found = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY);
                    let t_hit = found.map_or(f32::INFINITY, |h| h.t);
                    let mut seen = 1.0f64;
                    if let Some(m) = medium {
                        seen = m.transmittance(ray.origin, ray.dir, t_hit) as f64;
                        m.march_camera(ray.origin, ray.dir, t_hit, &mut march);
                        for s in &march {
                            let mut shadow = tracer.rays_from(s.pos);
                            for (d, w) in samples.dirs.iter().zip(&samples.weights) {
                                if shadow.occluded(*d, f32::INFINITY) {
                                    continue;
                                }
                                let tau = m.optical_depth(s.pos, *d, f32::INFINITY);
                                let f = s.weight as f64
                                    * henyey_greenstein(m.g, d.dot(ray.dir)) as f64
                                    * *w as f64
                                    * (-tau as f64).exp()
                                    * inv_spp;
                                let l = cube.lookup(d.as_dvec3());
                                for k in 0..3 {
                                    sum[k] += f * m.albedo[k] as f64 * l[k] as f64;
                                }
                            }
                        }
                    }
                    let stream = path_stream((y * w + x) as u64, sub, sample_stride(settings));
                    if settings.bounces > 0 && medium.is_some() {
                        let l = bounces.camera_radiance((ray.origin, ray.dir, t_hit), stream, cube);
                        for k in 0..3 {
                            sum[k] += l[k] * inv_spp;
                        }
                    }
                    let Some(hit) = found else {
                        // A medium alone veils the environment by its opacity, as in the bake.
                        if seen < 0.999 {
                            *cov += (inv_spp * (1.0 - seen)) as f32;
                        }
                        continue;
                    };
                    *cov += inv_spp as f32;
                    let sp = shading_point(&tracer, &hit, ray.dir);
                    let lobes = sp.lobes(scene);
                    let albedo = lobes.albedo;
                    let glossy = (lobes.specular != glam::Vec3::ZERO)
                        .then_some((lobes.specular, lobes.alpha));
                    // f(ω, view) · cos: albedo / π · cos, plus the specular GGX lobe, over
                    // each texel as the bake integrates it.
                    let (specular, alpha) =
                        glossy.map_or((glam::Vec3::ZERO, None), |(s, a)| (s, Some(a)));
                    direct_texels(&shadows, &samples, &sp, alpha, |j, diffuse, ggx| {
                        let l = cube.texels[j];
                        for k in 0..3 {
                            let f = albedo[k] * diffuse + specular[k] * ggx;
                            sum[k] += f as f64 * inv_spp * l[k] as f64 * seen;
                        }
                    });
                    // Interreflections: every vertex of the bake's paths brings its throughput
                    // times its own direct light, seen through the medium.
                    if settings.bounces > 0 {
                        let l = bounces.radiance(&sp, stream, cube);
                        for k in 0..3 {
                            sum[k] += l[k] * inv_spp * seen;
                        }
                    }
                    if !weights.is_empty() {
                        let mut columns = vec![Vec3::ZERO; weights.len()];
                        let draw = Draw {
                            stream,
                            samples: None,
                            mis: true,
                        };
                        sampler.add(
                            &shadows,
                            &sp,
                            &lobes,
                            draw,
                            Vec3::splat(seen as f32),
                            &mut columns,
                        );
                        if settings.bounces > 0 {
                            let scale = 1.0 / settings.paths as f32;
                            bounces.add_light_columns(&sp, stream, scale, &sampler, &mut columns);
                        }
                        for (c, wt) in columns.iter().zip(&weights) {
                            for k in 0..3 {
                                sum[k] += (c[k] * wt[k]) as f64 * inv_spp;
                            }
                        }
                    }
                }
                *px = sum.map(|v| v as f32);
            }
            progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1, h);
        });
    Ok(Reference { image, coverage })
}

/// The weights of `lights` for `columns` light columns: one each, or none when no light is on.
pub fn light_weights(lights: &LightMix, columns: usize) -> Result<Vec<[f32; 3]>> {
    if lights.is_dark() {
        return Ok(Vec::new());
    }
    if lights.weights.len() != columns {
        return Err(crate::error::PrtError::invalid(
            "lights",
            format!(
                "{} light weights for a scene with {columns} light columns",
                lights.weights.len()
            ),
        ));
    }
    Ok(lights.weights.clone())
}
