//! The local lights' columns of a bake: at every shading point, its response to each light
//! column (a light at one of its positions) at unit colour and intensity, visibility, BRDF and
//! cosine included.
//!
//! A delta light (point, spot, sun without a disc) takes one shadow ray. A sized light (a quad,
//! a sun disc) takes `light_samples` stratified samples (a jittered square grid over the light),
//! so penumbrae are smooth rather than noisy; the quad is sampled by area and converted to solid
//! angle. On a glossy surface as many directions are drawn from the BRDF too, and the two are
//! weighed by the power heuristic (Veach 1997), so that a sharp highlight of a large light
//! converges as fast as a diffuse penumbra. The samples are seeded per camera sub-sample, so a
//! shard bakes exactly what the whole bake does. Interreflections reach the lights through the
//! same paths as the environment's (`bake::bounce`), with one light sample of each column at
//! every path vertex.

use glam::Vec3;

use super::{BakeSettings, ShadingPoint, Shadows};
pub use crate::math::sampling::power_heuristic;
use crate::math::sampling::{Rng, TexelSamples};
use crate::scene::Scene;
use crate::scene::brdf::Lobes;
use crate::scene::light::{Emitter, emitters, strata, stratified};

/// Salt of the light samples' random streams, apart from every other stream of the bake.
const LIGHT_STREAM: u64 = 0x11a7_5a3d_c0de_0001;

/// How one shading point draws its light samples.
#[derive(Clone, Copy, Debug)]
pub struct Draw {
    /// The random stream the samples come from.
    pub stream: u64,
    /// Samples of a sized light (`None`: the bake's count).
    pub samples: Option<usize>,
    /// On a glossy surface, as many BRDF samples too, weighed by multiple importance sampling.
    pub mis: bool,
}

/// The light columns of a bake and how each is sampled.
pub struct LightSampler {
    emitters: Vec<Emitter>,
    /// Samples of a sized light per shading point (a square).
    samples: usize,
    seed: u64,
}

impl LightSampler {
    /// The columns of `scene`'s lights, sampled as `settings` say.
    pub fn new(scene: &Scene, settings: &BakeSettings) -> LightSampler {
        let side = TexelSamples::grid_side(settings.light_samples as usize);
        LightSampler {
            emitters: emitters(&scene.lights),
            samples: side * side,
            seed: settings.seed ^ LIGHT_STREAM,
        }
    }

    /// Number of columns.
    pub fn columns(&self) -> usize {
        self.emitters.len()
    }

    /// Adds `scale ⊙ ∫ f cos L dω` over every column to `out` (one RGB sum per column),
    /// estimated at `at` with the BRDF `lobes` towards `at.view`, its samples drawn as `draw`
    /// says; shadow rays stop at the light (a medium's transmittance is not taken). Returns the
    /// rays traced.
    pub fn add(
        &self,
        shadows: &Shadows,
        at: &ShadingPoint,
        lobes: &Lobes,
        draw: Draw,
        scale: Vec3,
        out: &mut [Vec3],
    ) -> u64 {
        let Draw {
            stream,
            samples,
            mis,
        } = draw;
        let Shadows {
            tracer, unshadowed, ..
        } = *shadows;
        let mut rng = Rng::new(self.seed, stream);
        let mut rays = 0;
        let (n, v) = (at.normal, at.view);
        let glossy = mis && lobes.specular != Vec3::ZERO;
        let lobes_at = lobes.at(n, v);
        let visible = |dir: Vec3, dist: f32, rays: &mut u64| {
            unshadowed || {
                *rays += 1;
                !tracer.occluded(at.origin, dir, dist)
            }
        };
        for (e, sum) in self.emitters.iter().zip(out.iter_mut()) {
            let delta = e.is_delta();
            let both = glossy && !delta;
            // One light sample's `f cos L / pdf`, weighed against the BRDF's density under MIS.
            let light = |u: [f32; 2], rays: &mut u64| -> Vec3 {
                let Some(s) = e.sample(at.origin, u) else {
                    return Vec3::ZERO;
                };
                if n.dot(s.dir) <= 0.0 {
                    return Vec3::ZERO;
                }
                let f = lobes_at.eval_cosine(s.dir);
                if f == Vec3::ZERO || !visible(s.dir, s.dist, rays) {
                    return Vec3::ZERO;
                }
                let w = if both {
                    power_heuristic(s.pdf, lobes.pdf(n, v, s.dir))
                } else {
                    1.0
                };
                f * (s.weight * w)
            };
            if delta {
                *sum += scale * light([0.5, 0.5], &mut rays);
                continue;
            }
            // The strata are drawn as they are used, nothing kept; the BRDF's pass replays them
            // from a copy of the stream.
            let count = samples.unwrap_or(self.samples);
            let replay = rng.clone();
            let mut acc = Vec3::ZERO;
            for u in stratified(count, || rng.next_f32()) {
                acc += light(u, &mut rays);
            }
            if both {
                // The BRDF's directions, stratified as the light's, that reach the light.
                let mut again = replay;
                for u in stratified(count, || again.next_f32()) {
                    let Some(b) = lobes.sample(n, v, [rng.next_f32(), u[0], u[1]]) else {
                        continue;
                    };
                    let Some((t, radiance, pdf)) = e.hit(at.origin, b.dir) else {
                        continue;
                    };
                    if visible(b.dir, t, &mut rays) {
                        acc += b.weight * (radiance * power_heuristic(b.pdf, pdf));
                    }
                }
            }
            *sum += scale * acc / strata(count) as f32;
        }
        rays
    }
}

impl LightSampler {
    /// The diffuse lobe alone of a material of albedo `albedo`: what a vertex, seen from every
    /// side, reflects.
    pub fn diffuse(albedo: Vec3) -> Lobes {
        Lobes {
            albedo,
            specular: Vec3::ZERO,
            alpha: 1.0,
        }
    }
}
