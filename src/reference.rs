//! The brute-force reference: the scene ray traced under a cube map whose texels are
//! piecewise-constant lights, with no transport matrix. It is the ground truth for tests and
//! benchmarks, so it is written to be obviously right: for every camera sub-sample and every texel
//! sample direction, visibility x BRDF x cos x solid angle x radiance, summed; with bounces, the
//! same seeded paths as the bake, each bringing its throughput times its exit texel's radiance.

use rayon::prelude::*;

use crate::bake::{BakeSettings, indirect_paths, path_stream, shading_point};
use crate::brdf;
use crate::cubemap::CubeMap;
use crate::error::{PrtError, Result};
use crate::film::Image;
use crate::sampling::{TexelSamples, pixel_samples};
use crate::scene::Scene;
use crate::trace::Tracer;

/// Renders `scene` lit by `cube` with the sampling of `settings` (spp, texel samples, seed,
/// unshadowed); the cube's N is the texel-light resolution.
pub fn render_reference(scene: &Scene, cube: &CubeMap, settings: &BakeSettings) -> Result<Image> {
    if cube.n != settings.cube_n {
        return Err(PrtError::invalid(
            "cube map",
            format!(
                "N = {} but the settings ask for N = {}",
                cube.n, settings.cube_n
            ),
        ));
    }
    settings.validate()?;
    let tracer = Tracer::new(scene);
    let cam = &scene.camera;
    let (w, h) = (cam.width as usize, cam.height as usize);
    let samples = TexelSamples::new(cube.n, settings.texel_samples as usize, settings.seed);
    let mut image = Image::new(w, h);
    image
        .pixels
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, line)| {
            for (x, px) in line.iter_mut().enumerate() {
                let subs = pixel_samples(x as u32, y as u32, w as u32, settings.spp, settings.seed);
                let inv_spp = 1.0 / subs.len() as f64;
                let mut sum = [0.0f64; 3];
                for (sub, (fx, fy)) in subs.into_iter().enumerate() {
                    let ray = cam.ray(fx, fy);
                    let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
                        continue;
                    };
                    let sp = shading_point(&tracer, &hit, ray.dir);
                    let material = &scene.materials[sp.material as usize];
                    let albedo = material.albedo();
                    let glossy = material.glossy_lobe();
                    for (d, w) in samples.dirs.iter().zip(&samples.weights) {
                        if sp.normal.dot(*d) <= 0.0 {
                            continue;
                        }
                        if !settings.unshadowed && tracer.occluded(sp.origin, *d, f32::INFINITY) {
                            continue;
                        }
                        // f(ω, view) · cos: albedo / π · cos, plus the specular GGX lobe.
                        let diffuse = brdf::diffuse_cosine(sp.normal, *d);
                        let (specular, ggx) = match glossy {
                            Some((s, alpha)) => {
                                (s, brdf::ggx_cosine(sp.normal, sp.view, *d, alpha))
                            }
                            None => (glam::Vec3::ZERO, 0.0),
                        };
                        let l = cube.lookup(d.as_dvec3());
                        for k in 0..3 {
                            let f = albedo[k] * diffuse + specular[k] * ggx;
                            sum[k] += f as f64 * *w as f64 * inv_spp * l[k] as f64;
                        }
                    }
                    // Interreflections: every path that leaves the scene after a bounce brings
                    // its throughput times the radiance of the texel it leaves through.
                    if settings.bounces > 0 {
                        let scale = inv_spp / settings.paths as f64;
                        let stream = path_stream((y * w + x) as u64, sub, settings.spp);
                        indirect_paths(&tracer, scene, &sp, settings, stream, &mut |d, tp| {
                            let l = cube.lookup(d.as_dvec3());
                            for k in 0..3 {
                                sum[k] += tp[k] as f64 * l[k] as f64 * scale;
                            }
                        });
                    }
                }
                *px = sum.map(|v| v as f32);
            }
        });
    Ok(image)
}
