//! Interreflections by next-event estimation into the row.
//!
//! From every camera hit, `paths` paths of up to `bounces` bounces are drawn by importance
//! ([`crate::scene::brdf::Lobes::sample`]: cosine and GGX mixed by multiple importance sampling). At every vertex a
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
//!
//! With a medium, paths are tracked through it ([`Tracker`]): a segment either reaches the next
//! surface (with the probability of its transmittance) or collides in the medium, and a
//! collision is a vertex that takes the albedo, sends its own light to every texel
//! ([`MediumLight::vertex_weights`]) and goes on in a direction drawn from the phase function.
//! Paths also start at collisions along camera rays ([`Bounces::add_camera_rows`]), whose own
//! light is the single scattering of [`super::medium_rows`]. A surface vertex's row is
//! attenuated by the transmittance towards each texel, kept per cache point with its bits.

use std::borrow::Cow;

use glam::Vec3;

mod cache;
mod kept;
mod rows;

use crate::bake::{BakeSettings, CentrePackets, EdgeMap, ShadingPoint, Shadows, shading_point};
use crate::error::Result;
use crate::math::cubemap::CubeMap;
use crate::math::sampling::{Rng, TexelSamples};
use crate::medium::Medium;
use crate::medium::tracking::{Tracker, sample_hg};
use crate::scene::Scene;
use crate::scene::trace::Tracer;
pub use crate::store::transport::BounceVisibility;
pub use cache::VisibilityCache;
use kept::Start;
pub use kept::{KEPT_BYTES, KeptWalks};

use super::lights::{Draw, LightSampler};
use super::medium_light::MediumLight;

/// A vertex of an interreflection path.
#[derive(Clone, Copy, Debug)]
pub enum Vertex {
    /// On a surface.
    Surface(ShadingPoint),
    /// A collision in the medium at `pos`, reached travelling along `dir`.
    Medium {
        /// Where the path collided.
        pos: Vec3,
        /// The direction it was travelling in.
        dir: Vec3,
    },
}

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
    /// With one sample a texel, its centres in blocks traced together.
    packets: Option<CentrePackets>,
    cache: Option<VisibilityCache>,
    /// The most bytes of paths the cache's walk keeps for the tiles to replay; `None` keeps
    /// none.
    keep_walks: Option<usize>,
    /// The medium's trackers and what its points see, with a medium.
    medium: Option<(Tracker<'a>, &'a MediumLight)>,
    /// The texel sample directions times their solid angles, by coordinate: `max(0, n·ω) Ω` is
    /// `max(0, n·(ω Ω))`, which a loop over these vectorises.
    weighted: [Vec<f32>; 3],
    /// The texel sample directions by coordinate, for the GGX lobe's loop.
    dirs: [Vec<f32>; 3],
    /// The vector instructions this machine has, found once.
    arch: pulp::Arch,
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
        let dirs = std::array::from_fn(|k| samples.dirs.iter().map(|d| d[k]).collect());
        let packets =
            (samples.per_texel == 1).then(|| CentrePackets::new(samples.n, &samples.dirs));
        Bounces {
            scene,
            tracer,
            settings,
            samples,
            packets,
            cache: None,
            keep_walks: None,
            medium: None,
            weighted,
            dirs,
            arch: pulp::Arch::new(),
        }
    }

    /// Tracks the paths through `medium`, whose points see the texels as `light` says (built
    /// with its table). Before [`Bounces::with_cache`], whose points then keep their
    /// transmittance.
    pub fn with_medium(mut self, medium: Option<(&'a Medium, &'a MediumLight)>) -> Self {
        self.medium = medium.map(|(m, light)| (Tracker::new(m), light));
        self
    }

    /// Has the surface cache keep the paths its walk finds, if they take at most `limit` bytes
    /// (the bake's is [`KEPT_BYTES`]), so that [`Bounces::walk`] and [`Bounces::walk_camera`]
    /// replay them rather than walk them again. Before [`Bounces::with_cache`]; the reference
    /// walks its paths anew.
    pub fn keeping_walks(mut self, limit: usize) -> Self {
        self.keep_walks = Some(limit);
        self
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
    /// the throughput is the product of `f cos / pdf` along the way, and of the albedo at
    /// collisions in a medium. The first bounce is stratified over the paths (a jittered grid of
    /// ⌊√P⌋² cells). Seeded per stream; returns the rays traced.
    pub fn walk(
        &self,
        start: &ShadingPoint,
        stream: u64,
        visit: &mut dyn FnMut(u32, u32, &Vertex, Vec3),
    ) -> u64 {
        if let Some(rays) = self.replay((stream, Start::Surface), visit) {
            return rays;
        }
        let mut rng = Rng::new(self.settings.seed ^ 0x5eed_ba11, stream);
        (0..self.settings.paths)
            .map(|path| self.follow(Vertex::Surface(*start), Vec3::ONE, path, &mut rng, visit))
            .sum()
    }

    /// The paths of one camera sub-sample that start in the medium: each tracks the camera ray
    /// (from `origin` along `dir` up to `t_max`, the surface it hits) and, where it collides,
    /// goes on from there as [`Bounces::walk`] does (its first vertex, the collision itself,
    /// is not visited: its light is the medium's single-scattering row). Nothing without a
    /// medium.
    pub fn walk_camera(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        stream: u64,
        visit: &mut dyn FnMut(u32, u32, &Vertex, Vec3),
    ) -> u64 {
        let Some((tracker, _)) = &self.medium else {
            return 0;
        };
        if let Some(rays) = self.replay((stream, Start::Camera), visit) {
            return rays;
        }
        let mut rng = Rng::new(self.settings.seed ^ 0xc10d_5eed, stream);
        let albedo = tracker.medium().albedo;
        let mut rays = 0;
        for path in 0..self.settings.paths {
            if let Some(t) = tracker.collide(origin, dir, t_max, &mut rng) {
                let first = Vertex::Medium {
                    pos: origin + dir * t,
                    dir,
                };
                rays += self.follow(first, albedo, path, &mut rng, visit);
            }
        }
        rays
    }

    /// The kept walk `key` visited again, if the cache kept it: its rays.
    fn replay(
        &self,
        key: (u64, Start),
        visit: &mut dyn FnMut(u32, u32, &Vertex, Vec3),
    ) -> Option<u64> {
        let walks = self.cache.as_ref()?.walks.as_ref()?;
        walks.replay(key, visit)
    }

    /// One path from `first` with `throughput` (see [`Bounces::walk`]).
    fn follow(
        &self,
        first: Vertex,
        mut throughput: Vec3,
        path: u32,
        rng: &mut Rng,
        visit: &mut dyn FnMut(u32, u32, &Vertex, Vec3),
    ) -> u64 {
        let strata = (self.settings.paths as f64).sqrt() as u32;
        let mut at = first;
        let mut rays = 0;
        for bounce in 1..=self.settings.bounces {
            let mut u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            if bounce == 1 && path < strata * strata {
                // The first bounce's directions on a jittered grid: the paths of a sample
                // cover its hemisphere (or sphere) evenly.
                u[1] = ((path % strata) as f32 + u[1]) / strata as f32;
                u[2] = ((path / strata) as f32 + u[2]) / strata as f32;
            }
            let (origin, dir) = match &at {
                Vertex::Surface(sp) => {
                    let lobes = sp.lobes(self.scene);
                    let Some(s) = lobes.sample(sp.normal, sp.view, u) else {
                        break;
                    };
                    throughput *= s.weight;
                    (sp.origin, s.dir)
                }
                // The phase function's draw weighs 1.
                Vertex::Medium { pos, dir } => {
                    let g = self.medium.as_ref().map_or(0.0, |(t, _)| t.medium().g);
                    (*pos, sample_hg(g, *dir, [u[1], u[2]]))
                }
            };
            rays += 1;
            let hit = self.tracer.closest_hit(origin, dir, f32::INFINITY);
            let t_hit = hit.as_ref().map_or(f32::INFINITY, |h| h.t);
            let collision = self.medium.as_ref().and_then(|(tracker, _)| {
                Some((tracker.collide(origin, dir, t_hit, rng)?, tracker))
            });
            at = match (collision, hit) {
                (Some((t, tracker)), _) => {
                    throughput *= tracker.medium().albedo;
                    Vertex::Medium {
                        pos: origin + dir * t,
                        dir,
                    }
                }
                (None, Some(hit)) => Vertex::Surface(shading_point(self.tracer, &hit, dir)),
                (None, None) => break,
            };
            visit(path, bounce, &at, throughput);
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
        let transmittance = self.surface_transmittance(at);
        let lobes = at.lobes(self.scene);
        let (dirs, weights) = (&self.samples.dirs, &self.samples.weights);
        let m = self.samples.per_texel;
        let diffuse = throughput * lobes.albedo * std::f32::consts::FRAC_1_PI;
        let glossy = lobes.specular != Vec3::ZERO;
        let lobes_at = lobes.at(at.normal, at.view);
        let mut emit = |s: usize, cos: f32| {
            let value = if glossy {
                throughput * lobes_at.eval_cosine(dirs[s])
            } else {
                diffuse * cos
            };
            // The sample's texel, without a division where a texel has one sample.
            let j = if m == 1 { s } else { s / m };
            let through = transmittance.as_ref().map_or(1.0, |t| t[j] as f32 / 255.0);
            out(j, value * (weights[s] * through));
        };
        let mut rays = 0;
        let mut traced: Vec<u64>;
        let visibility = match (visibility, &self.packets) {
            (Visibility::Trace, Some(p)) => {
                // The same rays in blocks: their bits, then as the cache's.
                traced = vec![0u64; dirs.len().div_ceil(64)];
                let mut from = self.tracer.rays_from(at.origin);
                let above = |s: usize| at.normal.dot(dirs[s]) > 0.0;
                rays += p.open_bits(&mut from, above, &mut traced);
                Visibility::Bits(&traced)
            }
            (visibility, _) => visibility,
        };
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
                let mut shadow = self.tracer.rays_from(at.origin);
                for (s, d) in dirs.iter().enumerate() {
                    let cos = at.normal.dot(*d);
                    if cos <= 0.0 {
                        continue;
                    }
                    if matches!(vis, Visibility::Trace) {
                        rays += 1;
                        if shadow.occluded(*d, f32::INFINITY) {
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
        lights: Option<(&LightSampler, &mut [Vec3])>,
    ) -> u64 {
        self.add_along_paths(start, (stream, scale), Some(rows), lights)
    }

    /// Walks the paths of a camera sub-sample and adds `scale` times what each vertex sends:
    /// its rows to `rows`, and (at surface vertices; local lights are not baked through a
    /// medium, the settings refuse them) one sample of each local light's column to `lights`'
    /// columns. Returns the rays traced.
    fn add_along_paths(
        &self,
        start: &ShadingPoint,
        (stream, scale): (u64, f32),
        mut rows: Option<&mut [Vec<f32>; 3]>,
        mut lights: Option<(&LightSampler, &mut [Vec3])>,
    ) -> u64 {
        let mut shadow = 0;
        let rays = self.walk(start, stream, &mut |path, bounce, at, throughput| {
            if let (Some((sampler, columns)), Vertex::Surface(at)) = (lights.as_mut(), at) {
                shadow += self.light_vertex(
                    stream,
                    [path, bounce],
                    at,
                    throughput * scale,
                    sampler,
                    columns,
                );
            }
            if let Some(rows) = rows.as_deref_mut() {
                shadow += self.vertex_rows(at, throughput * scale, rows);
            }
        });
        rays + shadow
    }

    /// Adds `scale` times the rows of the paths that start in the medium along a camera
    /// sub-sample's ray (from `origin` along `dir` up to `t_max`; see [`Bounces::walk_camera`]) to
    /// `rows`. Returns the rays traced.
    pub fn add_camera_rows(
        &self,
        (origin, dir, t_max): (Vec3, Vec3, f32),
        stream: u64,
        scale: f32,
        rows: &mut [Vec<f32>; 3],
    ) -> u64 {
        let mut shadow = 0;
        let rays = self.walk_camera(origin, dir, t_max, stream, &mut |_, _, at, throughput| {
            shadow += self.vertex_rows(at, throughput * scale, rows);
        });
        rays + shadow
    }

    /// Adds the row of any vertex, times `throughput`, to `rows`. Returns the shadow rays.
    fn vertex_rows(&self, at: &Vertex, throughput: Vec3, rows: &mut [Vec<f32>; 3]) -> u64 {
        match at {
            Vertex::Medium { pos, dir } => {
                self.medium_vertex(*pos, *dir, throughput, &mut |j, v| {
                    rows[0][j] += v.x;
                    rows[1][j] += v.y;
                    rows[2][j] += v.z;
                });
                0
            }
            Vertex::Surface(at) => {
                let lobes = at.lobes(self.scene);
                match self.visibility(at) {
                    Visibility::Bits(bits) if self.samples.per_texel == 1 => {
                        let transmittance = self.surface_transmittance(at);
                        let transmittance = transmittance.as_deref();
                        // In the widest vector instructions the machine has.
                        self.arch.dispatch(rows::CachedRow {
                            bounces: self,
                            vertex: (bits, at, &lobes, throughput),
                            transmittance,
                            rows,
                        });
                        0
                    }
                    visibility => self.vertex_row(at, visibility, throughput, &mut |j, v| {
                        rows[0][j] += v.x;
                        rows[1][j] += v.y;
                        rows[2][j] += v.z;
                    }),
                }
            }
        }
    }

    /// The row of a vertex in the medium at `pos`, reached along `dir`, times `throughput` (the
    /// albedo of the collision included): `out(texel, value)` for every texel it sees.
    fn medium_vertex(
        &self,
        pos: Vec3,
        dir: Vec3,
        throughput: Vec3,
        out: &mut impl FnMut(usize, Vec3),
    ) {
        let Some((tracker, light)) = &self.medium else {
            return;
        };
        let weights = light.vertex_weights(pos, dir, tracker.medium().g, self.samples);
        for (j, w) in weights.iter().enumerate() {
            if *w != 0.0 {
                out(j, throughput * *w);
            }
        }
    }

    /// The transmittance through the medium from a surface vertex towards every texel, in
    /// 255ths: the cache point's where the vertex has one, else read at the vertex. `None`
    /// without a medium or in an unshadowed bake.
    fn surface_transmittance(&self, at: &ShadingPoint) -> Option<Cow<'_, [u8]>> {
        let (_, light) = self.medium.as_ref()?;
        if self.settings.unshadowed {
            return None;
        }
        Some(
            match self.cache.as_ref().and_then(|c| c.transmittance(at)) {
                Some(t) => Cow::Borrowed(t),
                None => Cow::Owned(light.surface_transmittance(at.origin)),
            },
        )
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
        let shadows = Shadows {
            tracer: self.tracer,
            unshadowed: self.settings.unshadowed,
            medium: None,
            packets: None,
        };
        let draw = Draw {
            stream: vertex | 1 << 63,
            samples: Some(1),
            mis: false,
        };
        sampler.add(&shadows, at, &lobes, draw, throughput, columns)
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
        self.add_along_paths(start, (stream, scale), None, Some((sampler, columns)));
    }

    /// The interreflected radiance of a camera sub-sample lit by `cube`, through the same paths
    /// and vertex rows as [`Bounces::add_rows`] but with no matrix: the bookkeeping check of the
    /// brute-force reference.
    pub fn radiance(&self, start: &ShadingPoint, stream: u64, cube: &CubeMap) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        self.walk(start, stream, &mut |_, _, at, throughput| {
            self.vertex_radiance(at, throughput, cube, &mut sum);
        });
        sum.map(|v| v / self.settings.paths as f64)
    }

    /// [`Bounces::radiance`] for the paths that start in the medium along a camera ray (see
    /// [`Bounces::add_camera_rows`]).
    pub fn camera_radiance(
        &self,
        (origin, dir, t_max): (Vec3, Vec3, f32),
        stream: u64,
        cube: &CubeMap,
    ) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        self.walk_camera(origin, dir, t_max, stream, &mut |_, _, at, throughput| {
            self.vertex_radiance(at, throughput, cube, &mut sum);
        });
        sum.map(|v| v / self.settings.paths as f64)
    }

    /// Adds the light a vertex sends on lit by `cube`, times `throughput`, to `sum`.
    fn vertex_radiance(&self, at: &Vertex, throughput: Vec3, cube: &CubeMap, sum: &mut [f64; 3]) {
        let mut add = |j: usize, v: Vec3| {
            let l = cube.texels[j];
            for k in 0..3 {
                sum[k] += v[k] as f64 * l[k] as f64;
            }
        };
        match at {
            Vertex::Surface(at) => {
                self.vertex_row(at, self.visibility(at), throughput, &mut add);
            }
            Vertex::Medium { pos, dir } => self.medium_vertex(*pos, *dir, throughput, &mut add),
        }
    }
}

#[cfg(test)]
mod tests;
