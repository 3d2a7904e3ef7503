//! The surface cache of the interreflections: visibility bits at surface points, shared by the
//! path vertices near them (see [`VisibilityCache`]).

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::Bounces;
use super::Vertex;
use super::kept::{KeptWalks, Start, Visit};
use crate::bake::{
    EdgeMap, ShadingPoint, path_stream, pixel_subsamples, sample_stride, shading_point,
};
use crate::error::{PrtError, Result};
use crate::scene::Scene;
use crate::scene::trace::Tracer;

/// A cache cell: grid cell, octahedral normal bin and material.
#[derive(Clone, Copy, Debug, Hash, PartialEq, Eq)]
struct CellKey {
    cell: [i64; 3],
    normal: u8,
    material: u32,
}

/// Normal bins per side of the octahedral map (8 x 8 bins, about 25° wide).
const NORMAL_BINS: f32 = 8.0;

fn normal_bin(n: Vec3) -> u8 {
    let p = n / (n.x.abs() + n.y.abs() + n.z.abs()).max(1e-20);
    let (mut u, mut v) = (p.x, p.y);
    if p.z < 0.0 {
        (u, v) = (
            (1.0 - p.y.abs()) * p.x.signum(),
            (1.0 - p.x.abs()) * p.y.signum(),
        );
    }
    let bin = |x: f32| (((x + 1.0) * 0.5 * NORMAL_BINS) as i32).clamp(0, NORMAL_BINS as i32 - 1);
    (bin(u) * NORMAL_BINS as i32 + bin(v)) as u8
}

/// Visibility bits at surface points, shared by the bounce vertices near them.
///
/// The points are chosen before the bake: every path the bake will trace is walked once (the
/// paths are seeded per pixel, so the walk is the bake's own), and each occupied cell keeps the
/// first vertex that fell in it, first in (pixel, sub-sample, path, bounce) order. The choice is
/// therefore the same for a whole bake and for each of its shards, which keeps shards identical to
/// the whole; a shard traces the bits of the cells its own pixels reach. The bake keeps the paths
/// this walk finds ([`KeptWalks`]), so that its tiles replay them rather than walk them again.
pub struct VisibilityCache {
    cell: f32,
    index: HashMap<CellKey, u32>,
    bits: Vec<u64>,
    words: usize,
    /// With a medium, the transmittance towards every texel per point, in 255ths.
    transmittance: Vec<u8>,
    texels: usize,
    /// Cache points of the whole image.
    pub points: usize,
    /// Points whose bits this bake traced (all of them, or a shard's).
    pub traced: usize,
    /// Shadow rays the cache traced.
    pub rays: u64,
    /// The paths of the bake's camera sub-samples as the cache's walk found them, for the tiles
    /// to replay, where the bake keeps them and they fit ([`Bounces::keeping_walks`]).
    pub walks: Option<KeptWalks>,
}

/// First vertex found in a cell.
#[derive(Clone, Copy)]
struct Candidate {
    order: u128,
    origin: Vec3,
    normal: Vec3,
    mine: bool,
}

impl VisibilityCache {
    /// Width of a cache cell: `spacing` pixel footprints at the median depth of the view, and at
    /// most `spacing` / 512 of the scene's diagonal (so that a small image does not get a coarse
    /// cache).
    pub fn cell_size(scene: &Scene, tracer: &Tracer, spacing: f32) -> Option<f32> {
        let cam = &scene.camera;
        let per_unit = 2.0 * (cam.fov_y_deg.to_radians() * 0.5).tan() / cam.height as f32;
        let mut depths: Vec<f32> = (0..cam.height)
            .step_by(4)
            .flat_map(|y| (0..cam.width).step_by(4).map(move |x| (x, y)))
            .filter_map(|(x, y)| {
                let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
                tracer
                    .closest_hit(ray.origin, ray.dir, f32::INFINITY)
                    .map(|h| h.t)
            })
            .collect();
        if depths.is_empty() {
            return None;
        }
        let mid = depths.len() / 2;
        let (_, median, _) = depths.select_nth_unstable_by(mid, f32::total_cmp);
        let (lo, hi) = scene.bounds();
        let cap = (hi - lo).length() * spacing / 512.0;
        Some(
            (*median * per_unit * spacing)
                .min(cap)
                .max(tracer.spawn_offset() * 16.0),
        )
    }

    fn key(&self, at: &ShadingPoint) -> CellKey {
        let c = (at.origin / self.cell).floor();
        CellKey {
            cell: [c.x as i64, c.y as i64, c.z as i64],
            normal: normal_bin(at.normal),
            material: at.material,
        }
    }

    /// Walks every path of the bake, picks the cache points, and traces the bits of those that
    /// pixels with `mine(pixel)` reach. `progress(done, total)` follows the tracing.
    pub fn build(
        bounces: &Bounces,
        edges: &EdgeMap,
        mine: &(dyn Fn(usize) -> bool + Sync),
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Option<VisibilityCache>> {
        let Bounces {
            scene,
            tracer,
            settings,
            samples,
            ref packets,
            ..
        } = *bounces;
        let Some(cell) = Self::cell_size(scene, tracer, settings.cache_spacing) else {
            return Ok(None);
        };
        let mut cache = VisibilityCache {
            cell,
            index: HashMap::new(),
            bits: Vec::new(),
            words: samples.dirs.len().div_ceil(64),
            transmittance: Vec::new(),
            texels: samples.dirs.len() / samples.per_texel,
            points: 0,
            traced: 0,
            rays: 0,
            walks: None,
        };
        let walker = Walker {
            bounces,
            edges,
            mine,
            cache: &cache,
            limit: bounces.keep_walks,
            kept_bytes: AtomicUsize::new(0),
        };
        let found = (0..scene.camera.height as usize)
            .into_par_iter()
            .fold(Found::default, |mut found, y| {
                walker.row(y, &mut found);
                found
            })
            .reduce(Found::default, Found::merge);
        // Kept whole or not at all: past the limit, the tiles walk every path again.
        let kept = walker.kept_bytes.into_inner();
        cache.walks = walker
            .limit
            .filter(|&l| kept <= l)
            .map(|_| found.walks.shrink());
        let found = found.cells;
        cache.points = found.len();
        let mut chosen: Vec<(CellKey, Candidate)> =
            found.into_iter().filter(|(_, c)| c.mine).collect();
        chosen.sort_by_key(|(_, c)| c.order);
        cache.traced = chosen.len();
        let total_bytes = chosen.len() as u64 * cache.words as u64 * 8;
        if total_bytes > 16 << 30 {
            return Err(PrtError::invalid(
                "cache spacing",
                format!(
                    "the surface cache would take {:.1} GiB ({} points); raise --cache-spacing",
                    total_bytes as f64 / (1u64 << 30) as f64,
                    chosen.len()
                ),
            ));
        }
        let done = AtomicUsize::new(0);
        let light = bounces.medium.as_ref().map(|(_, light)| *light);
        let traced: Vec<(Vec<u64>, u64, Vec<u8>)> = chosen
            .par_iter()
            .map(|(_, c)| {
                let transmittance = light.map_or(Vec::new(), |l| l.surface_transmittance(c.origin));
                let mut bits = vec![0u64; cache.words];
                let mut shadow = tracer.rays_from(c.origin);
                let above = |s: usize| c.normal.dot(samples.dirs[s]) > 0.0;
                let rays = match packets {
                    Some(p) => p.open_bits(&mut shadow, above, &mut bits),
                    None => (0..samples.dirs.len())
                        .filter(|&s| above(s))
                        .fold(0, |rays, s| {
                            if !shadow.occluded(samples.dirs[s], f32::INFINITY) {
                                bits[s / 64] |= 1 << (s % 64);
                            }
                            rays + 1
                        }),
                };
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_multiple_of(256) || n == chosen.len() {
                    progress(n, chosen.len());
                }
                (bits, rays, transmittance)
            })
            .collect();
        cache.bits.reserve_exact(chosen.len() * cache.words);
        for (i, ((key, _), (bits, rays, transmittance))) in chosen.iter().zip(traced).enumerate() {
            cache.index.insert(*key, i as u32);
            cache.bits.extend_from_slice(&bits);
            cache.transmittance.extend_from_slice(&transmittance);
            cache.rays += rays;
        }
        Ok(Some(cache))
    }

    /// The bits of the cache point for a vertex, if the vertex's cell has one.
    pub(super) fn lookup(&self, at: &ShadingPoint) -> Option<&[u64]> {
        let i = *self.index.get(&self.key(at))? as usize;
        Some(&self.bits[i * self.words..(i + 1) * self.words])
    }

    /// The transmittance through the medium towards every texel at the cache point for a
    /// vertex, if the vertex's cell has one and the bake a medium.
    pub(super) fn transmittance(&self, at: &ShadingPoint) -> Option<&[u8]> {
        let i = *self.index.get(&self.key(at))? as usize;
        self.transmittance
            .get(i * self.texels..(i + 1) * self.texels)
    }

    /// Bytes the cache holds.
    pub fn bytes(&self) -> usize {
        self.bits.len() * 8
            + self.transmittance.len()
            + self.index.len() * (std::mem::size_of::<CellKey>() + 8)
    }
}

/// What the walk over part of the image found: the first vertex in each cell, and the walks it
/// keeps.
#[derive(Default)]
struct Found {
    cells: HashMap<CellKey, Candidate>,
    walks: KeptWalks,
}

impl Found {
    /// Takes `c` as the candidate of `cells`' cell `key` if it comes first; the cell is `mine`
    /// if either is.
    fn offer(cells: &mut HashMap<CellKey, Candidate>, key: CellKey, c: Candidate) {
        cells
            .entry(key)
            .and_modify(|e| {
                let mine = e.mine | c.mine;
                if c.order < e.order {
                    *e = c;
                }
                e.mine = mine;
            })
            .or_insert(c);
    }

    /// What both parts found.
    fn merge(mut self, other: Found) -> Found {
        for (key, c) in other.cells {
            Found::offer(&mut self.cells, key, c);
        }
        self.walks = self.walks.merge(other.walks);
        self
    }
}

/// The cache's walk over the image: every path of every camera sub-sample, as the tiles will
/// walk it.
struct Walker<'c, 'a> {
    bounces: &'c Bounces<'a>,
    edges: &'c EdgeMap,
    mine: &'c (dyn Fn(usize) -> bool + Sync),
    /// The cache being built, for its cells.
    cache: &'c VisibilityCache,
    /// The most bytes of walks kept (see [`Bounces::keeping_walks`]); `None` keeps none.
    limit: Option<usize>,
    /// The bytes of the walks kept so far, by every part.
    kept_bytes: AtomicUsize,
}

impl Walker<'_, '_> {
    /// Walks the paths of the pixels of image row `y` into `found`.
    fn row(&self, y: usize, found: &mut Found) {
        let Bounces {
            scene,
            tracer,
            settings,
            ..
        } = *self.bounces;
        let cam = &scene.camera;
        let w = cam.width as usize;
        let stride = sample_stride(settings);
        let limit = self.limit.unwrap_or(0);
        // A walk's vertices, until they are kept.
        let mut visits = Vec::new();
        for x in 0..w {
            let pixel = y * w + x;
            let is_mine = (self.mine)(pixel);
            // The pixel's walks are kept until the kept walks outgrow their limit.
            let keeping =
                self.limit.is_some() && is_mine && self.kept_bytes.load(Ordering::Relaxed) <= limit;
            let subs = pixel_subsamples(self.edges, cam, settings, x as u32, y as u32);
            for (sub, (fx, fy)) in subs.into_iter().enumerate() {
                let ray = cam.ray(fx, fy);
                let hit = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY);
                let stream = path_stream(pixel as u64, sub, stride);
                // The paths from the hit, then those from collisions along the camera ray.
                for start in [Start::Surface, Start::Camera] {
                    visits.clear();
                    let cells = &mut found.cells;
                    let mut visit = |path: u32, bounce: u32, at: &Vertex, throughput: Vec3| {
                        if keeping {
                            let step = [path, bounce];
                            let vertex = *at;
                            visits.push(Visit {
                                step,
                                vertex,
                                throughput,
                            });
                        }
                        let Vertex::Surface(at) = at else {
                            return;
                        };
                        let order = ((pixel as u128) << 64)
                            | (u128::from(start == Start::Camera) << 63)
                            | ((sub as u128) << 40)
                            | ((path as u128) << 8)
                            | bounce as u128;
                        let candidate = Candidate {
                            order,
                            origin: at.origin,
                            normal: at.normal,
                            mine: is_mine,
                        };
                        Found::offer(cells, self.cache.key(at), candidate);
                    };
                    // The rays of a walk there is to keep: none from a missed hit, nor along
                    // the camera ray without a medium.
                    let rays = match start {
                        Start::Surface => hit.map(|hit| {
                            let from = shading_point(tracer, &hit, ray.dir);
                            self.bounces.walk(&from, stream, &mut visit)
                        }),
                        Start::Camera => {
                            let t_hit = hit.map_or(f32::INFINITY, |h| h.t);
                            let b = self.bounces;
                            let rays =
                                b.walk_camera(ray.origin, ray.dir, t_hit, stream, &mut visit);
                            b.medium.is_some().then_some(rays)
                        }
                    };
                    if let (Some(rays), true) = (rays, keeping) {
                        let bytes = KeptWalks::bytes_of(visits.len());
                        if self.kept_bytes.fetch_add(bytes, Ordering::Relaxed) + bytes <= limit {
                            found.walks.keep((stream, start), rays, &mut visits);
                        }
                    }
                }
            }
        }
    }
}
