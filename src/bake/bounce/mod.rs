//! Interreflections by next-event estimation into the row.
//!
//! From every camera hit, `paths` paths of up to `bounces` bounces are drawn by importance
//! ([`Lobes::sample`]: cosine and GGX mixed by multiple importance sampling). At every vertex a
//! path reaches, the path's throughput times that vertex's own direct row (visibility x f x cos x
//! solid angle to every texel sample) is added to the pixel's three colour rows: the interreflected
//! transfer of Sloan et al. 2002, per pixel. A path that leaves the scene adds nothing, since the
//! row of the vertex it left from already holds that light. Every vertex thus sends light to every
//! texel, and a light concentrated in a few texels (a small sun) costs no more noise than a smooth
//! sky; binning each path into the one texel it leaves through, as a plain path tracer would, turns
//! such a light into fireflies and missing light.
//!
//! The visibility of a vertex comes from a surface cache ([`VisibilityCache`]) by default: one bit
//! per texel sample at cache points, one point per cell of a grid a few pixel footprints wide, per
//! normal direction and material. Cosine and BRDF are evaluated exactly at the vertex itself. With
//! [`BounceVisibility::Exact`] every vertex traces its own 6 N² shadow rays instead.

use glam::Vec3;

mod cache;

use crate::bake::{BakeSettings, EdgeMap, ShadingPoint, shading_point};
use crate::error::Result;
use crate::math::cubemap::CubeMap;
use crate::math::sampling::{Rng, TexelSamples};
use crate::scene::Scene;
use crate::scene::trace::Tracer;
pub use crate::store::transport::BounceVisibility;
pub use cache::VisibilityCache;

use super::lights::LightSampler;

/// Where the visibility of one vertex comes from.
#[derive(Clone, Copy)]
enum Visibility<'a> {
    /// Every direction above the surface sees the light (an unshadowed bake).
    All,
    /// One bit per texel sample, from the cache.
    Bits(&'a [u64]),
    /// Shadow rays traced from the vertex.
    Trace,
}

/// What the interreflections of a bake (or of its reference with the same paths) share.
pub struct Bounces<'a> {
    scene: &'a Scene,
    tracer: &'a Tracer,
    settings: &'a BakeSettings,
    samples: &'a TexelSamples,
    cache: Option<VisibilityCache>,
    /// The texel sample directions times their solid angles, by coordinate: `max(0, n·ω) Ω` is
    /// `max(0, n·(ω Ω))`, which a loop over these vectorises.
    weighted: [Vec<f32>; 3],
}

impl<'a> Bounces<'a> {
    /// The paths of a bake with `settings`, without a cache yet.
    pub fn new(
        scene: &'a Scene,
        tracer: &'a Tracer,
        settings: &'a BakeSettings,
        samples: &'a TexelSamples,
    ) -> Self {
        let weighted = std::array::from_fn(|k| {
            samples
                .dirs
                .iter()
                .zip(&samples.weights)
                .map(|(d, w)| d[k] * w)
                .collect()
        });
        Bounces {
            scene,
            tracer,
            settings,
            samples,
            cache: None,
            weighted,
        }
    }

    /// Builds the surface cache when the settings call for one (bounces, shadows, cache
    /// visibility), tracing the points that pixels with `mine(pixel)` reach.
    pub fn with_cache(
        mut self,
        edges: &EdgeMap,
        mine: &(dyn Fn(usize) -> bool + Sync),
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        let s = self.settings;
        if s.bounces > 0 && !s.unshadowed && s.bounce_visibility == BounceVisibility::Cache {
            self.cache = VisibilityCache::build(&self, edges, mine, progress)?;
        }
        Ok(self)
    }

    /// The surface cache, if the bake has one.
    pub fn cache(&self) -> Option<&VisibilityCache> {
        self.cache.as_ref()
    }

    /// Walks the `paths` paths of one camera sub-sample from `start` and calls
    /// `visit(path, bounce, vertex, throughput)` at every vertex reached (bounce 1 to `bounces`);
    /// the throughput is the product of `f cos / pdf` along the way. The first bounce is
    /// stratified over the paths (a jittered grid of ⌊√P⌋² cells). Seeded per stream; returns the
    /// rays traced.
    pub fn walk(
        &self,
        start: &ShadingPoint,
        stream: u64,
        visit: &mut dyn FnMut(u32, u32, &ShadingPoint, Vec3),
    ) -> u64 {
        let mut rays = 0;
        let mut rng = Rng::new(self.settings.seed ^ 0x5eed_ba11, stream);
        let strata = (self.settings.paths as f64).sqrt() as u32;
        for path in 0..self.settings.paths {
            let mut throughput = Vec3::ONE;
            let mut at = *start;
            for bounce in 1..=self.settings.bounces {
                let lobes = at.lobes(self.scene);
                let mut u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                if bounce == 1 && path < strata * strata {
                    // The first bounce's directions on a jittered grid: the paths of a sample
                    // cover its hemisphere evenly.
                    u[1] = ((path % strata) as f32 + u[1]) / strata as f32;
                    u[2] = ((path / strata) as f32 + u[2]) / strata as f32;
                }
                let Some(s) = lobes.sample(at.normal, at.view, u) else {
                    break;
                };
                throughput *= s.weight;
                rays += 1;
                let Some(hit) = self.tracer.closest_hit(at.origin, s.dir, f32::INFINITY) else {
                    break;
                };
                at = shading_point(self.tracer, &hit, s.dir);
                visit(path, bounce, &at, throughput);
            }
        }
        rays
    }

    fn visibility(&self, at: &ShadingPoint) -> Visibility<'_> {
        if self.settings.unshadowed {
            return Visibility::All;
        }
        match self.cache.as_ref().and_then(|c| c.lookup(at)) {
            Some(bits) => Visibility::Bits(bits),
            None => Visibility::Trace,
        }
    }

    /// The direct row of a vertex seeing the light as `visibility` says, times `throughput`: for
    /// every visible texel sample ω, `out(texel, throughput ⊙ f(ω, view) cos Ω_ω)`. Returns the
    /// shadow rays traced.
    fn vertex_row(
        &self,
        at: &ShadingPoint,
        visibility: Visibility,
        throughput: Vec3,
        out: &mut impl FnMut(usize, Vec3),
    ) -> u64 {
        let lobes = at.lobes(self.scene);
        let (dirs, weights) = (&self.samples.dirs, &self.samples.weights);
        let m = self.samples.per_texel;
        let diffuse = throughput * lobes.albedo * std::f32::consts::FRAC_1_PI;
        let glossy = lobes.specular != Vec3::ZERO;
        let mut emit = |s: usize, cos: f32| {
            let value = if glossy {
                throughput * lobes.eval_cosine(at.normal, at.view, dirs[s])
            } else {
                diffuse * cos
            };
            out(s / m, value * weights[s]);
        };
        let mut rays = 0;
        match visibility {
            Visibility::Bits(bits) => {
                for (wi, &word) in bits.iter().enumerate() {
                    let mut word = word;
                    while word != 0 {
                        let s = wi * 64 + word.trailing_zeros() as usize;
                        word &= word - 1;
                        let cos = at.normal.dot(dirs[s]);
                        if cos > 0.0 {
                            emit(s, cos);
                        }
                    }
                }
            }
            vis => {
                for (s, d) in dirs.iter().enumerate() {
                    let cos = at.normal.dot(*d);
                    if cos <= 0.0 {
                        continue;
                    }
                    if matches!(vis, Visibility::Trace) {
                        rays += 1;
                        if self.tracer.occluded(at.origin, *d, f32::INFINITY) {
                            continue;
                        }
                    }
                    emit(s, cos);
                }
            }
        }
        rays
    }

    /// Adds `scale` times the interreflected rows of a camera sub-sample to `rows` (one per colour
    /// channel, texel order). Returns the rays traced.
    /// With `lights`, adds the local lights' columns through the same paths: one sample of
    /// each column at every vertex ([`LightSampler::add`]).
    pub fn add_rows(
        &self,
        start: &ShadingPoint,
        stream: u64,
        scale: f32,
        rows: &mut [Vec<f32>; 3],
        mut lights: Option<(&LightSampler, &mut [Vec3])>,
    ) -> u64 {
        let mut shadow = 0;
        let rays = self.walk(start, stream, &mut |path, bounce, at, throughput| {
            let lobes = at.lobes(self.scene);
            if let Some((sampler, columns)) = lights.as_mut() {
                shadow += self.light_vertex(
                    stream,
                    [path, bounce],
                    at,
                    throughput * scale,
                    sampler,
                    columns,
                );
            }
            match self.visibility(at) {
                Visibility::Bits(bits)
                    if lobes.specular == Vec3::ZERO && self.samples.per_texel == 1 =>
                {
                    let c = throughput * scale * lobes.albedo * std::f32::consts::FRAC_1_PI;
                    self.add_lambertian(bits, at.normal, c, rows);
                }
                visibility => {
                    shadow += self.vertex_row(at, visibility, throughput * scale, &mut |j, v| {
                        rows[0][j] += v.x;
                        rows[1][j] += v.y;
                        rows[2][j] += v.z;
                    });
                }
            }
        });
        rays + shadow
    }

    /// At path vertex `at` (path and bounce `index` of the sub-sample's `stream`), adds
    /// `throughput ⊙` one sample of every light column to `columns`. Returns the shadow rays.
    fn light_vertex(
        &self,
        stream: u64,
        index: [u32; 2],
        at: &ShadingPoint,
        throughput: Vec3,
        sampler: &LightSampler,
        columns: &mut [Vec3],
    ) -> u64 {
        let lobes = at.lobes(self.scene);
        // A stream of its own for every vertex, apart from the camera hits' (top bit).
        let vertex = Rng::new(stream, ((index[0] as u64) << 8) | index[1] as u64).next_u64();
        sampler.add(
            self.tracer,
            at,
            &lobes,
            self.settings.unshadowed,
            vertex | 1 << 63,
            Some(1),
            false,
            throughput,
            columns,
        )
    }

    /// The local lights' part of [`Bounces::add_rows`] alone: `scale ⊙` the interreflected
    /// light of every column, through the same paths and samples, added to `columns`. The
    /// reference's bookkeeping check.
    pub fn add_light_columns(
        &self,
        start: &ShadingPoint,
        stream: u64,
        scale: f32,
        sampler: &LightSampler,
        columns: &mut [Vec3],
    ) {
        self.walk(start, stream, &mut |path, bounce, at, throughput| {
            self.light_vertex(
                stream,
                [path, bounce],
                at,
                throughput * scale,
                sampler,
                columns,
            );
        });
    }

    /// The fast case of [`Bounces::vertex_row`]: a Lambertian vertex, one sample a texel,
    /// visibility from the cache. Adds `c max(0, n·ω) Ω` to the rows at every visible texel, 64
    /// texels a word, without branches, so that the loop vectorises.
    fn add_lambertian(&self, bits: &[u64], n: Vec3, c: Vec3, rows: &mut [Vec<f32>; 3]) {
        let [wx, wy, wz] = &self.weighted;
        let [r0, r1, r2] = rows;
        let chunks = wx.chunks(64).zip(wy.chunks(64)).zip(wz.chunks(64)).zip(
            r0.chunks_mut(64)
                .zip(r1.chunks_mut(64))
                .zip(r2.chunks_mut(64)),
        );
        for (&word, (((x, y), z), ((o0, o1), o2))) in bits.iter().zip(chunks) {
            if word == 0 {
                continue;
            }
            let len = x
                .len()
                .min(y.len())
                .min(z.len())
                .min(o0.len())
                .min(o1.len())
                .min(o2.len());
            for j in 0..len {
                let bit = ((word >> j) & 1) as f32;
                let cos = (n.x * x[j] + n.y * y[j] + n.z * z[j]).max(0.0) * bit;
                o0[j] += c.x * cos;
                o1[j] += c.y * cos;
                o2[j] += c.z * cos;
            }
        }
    }

    /// The interreflected radiance of a camera sub-sample lit by `cube`, through the same paths
    /// and vertex rows as [`Bounces::add_rows`] but with no matrix: the bookkeeping check of the
    /// brute-force reference.
    pub fn radiance(&self, start: &ShadingPoint, stream: u64, cube: &CubeMap) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        self.walk(start, stream, &mut |_, _, at, throughput| {
            self.vertex_row(at, self.visibility(at), throughput, &mut |j, v| {
                let l = cube.texels[j];
                for k in 0..3 {
                    sum[k] += v[k] as f64 * l[k] as f64;
                }
            });
        });
        sum.map(|v| v / self.settings.paths as f64)
    }
}
