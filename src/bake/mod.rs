//! The bake: for every pixel of the fixed view, its transport row over all 6 N² cube texel lights
//! (visibility x BRDF x cosine integrated over each texel), the SH projection of the same row,
//! then per-face Haar, thresholding and quantisation into the tiled layout of
//! [`crate::store::transport`]. Parallel over pixel tiles with rayon, taken in order; each tile is
//! finished and compressed before the next is taken and handed on in tile order, either kept
//! ([`bake`]) or written out at once ([`bake_to_file`]), so a bake to a file holds only the tiles
//! under way, whatever the size of its output. A [`Cancel`] token stops either between tiles.

pub mod bounce;
mod direct;
mod gloss;
mod in_order;
pub mod lights;
pub mod medium_light;
pub mod medium_rows;
pub mod path_tracer;
mod pixels;
pub mod reference;
mod settings;
mod slot;
mod tint;

use crate::store::transport::BakeDomain;
pub use direct::{accumulate_direct_rows, direct_texels};
pub use in_order::Cancel;
use in_order::in_tile_order;
pub use lights::LightSampler;
use pixels::visits;
pub use pixels::{EdgeMap, pixel_subsamples, sample_stride};
pub use settings::{
    BakeSettings, load_if_baked_with, load_or_bake, load_or_bake_logged, worst_case_bytes,
};
use slot::Slot;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

use glam::Vec3;

use crate::bake::medium_light::MediumLight;
use crate::bake::medium_rows::MediumRows;
use crate::error::{PrtError, Result};
use crate::math::cubemap::{texel_count, validate_n};
use crate::math::haar;
use crate::math::sampling::TexelSamples;
use crate::math::texel_sh::TexelShBasis;
use crate::medium::Medium;
use crate::scene::Scene;
use crate::scene::brdf;
use crate::scene::tessellate::VertexMesh;
use crate::scene::trace::{Hit, Tracer};
use crate::store::budget::{Budget, Thresholder};
use crate::store::transport::{
    BakeStats, CameraMeta, EncodedTile, KeptTiles, LightColumns, PerVertexMeta, Quantization,
    RowData, TILE, Transport, TransportMeta, TransportWriter, Untiled, shard_of_band, tile_grid,
};

/// Progress of a running bake.
#[derive(Clone, Copy, Debug)]
pub struct BakeProgress {
    /// Pixels (or vertices) whose rows are done.
    pub pixels_done: usize,
    /// Pixels (or vertices) this bake makes rows for: those of its shard's tiles.
    pub pixels_total: usize,
    /// Shadow rays traced so far.
    pub shadow_rays: u64,
    /// Pixels of the view that take `edge_spp` sub-samples ([`EdgeMap`]), found before the first
    /// stage.
    pub edge_pixels: usize,
    /// Passes done and in all over the texels for what a medium's points see of them: the
    /// surfaces' visibility, then with bounces the transmittance table (the first stage; `[0, 0]`
    /// without a medium).
    pub medium_light: [usize; 2],
    /// Texel lights done and in all for a scene's medium rows (the next stage; `[0, 0]` without
    /// a medium).
    pub medium_texels: [usize; 2],
    /// Surface cache points traced and in all for the interreflections (a first stage; `[0, 0]`
    /// without it).
    pub cache_points: [usize; 2],
}

/// Where the shading of one camera sub-sample happens: a hit point and its diffuse material.
#[derive(Clone, Copy, Debug)]
pub struct ShadingPoint {
    /// Origin for shadow rays, offset off the surface.
    pub origin: Vec3,
    /// Shading normal, facing the camera ray.
    pub normal: Vec3,
    /// Unit direction from the surface towards the viewer.
    pub view: Vec3,
    /// Material index.
    pub material: u32,
    /// Texture coordinate of the point.
    pub uv: glam::Vec2,
    /// Whether the point's light is taken for a white diffuse surface, its albedo applied after
    /// relighting: a textured vertex of a per-vertex bake, whose raster multiplies by its albedo
    /// map per pixel.
    pub unit_albedo: bool,
}

impl ShadingPoint {
    /// The lobes the point reflects with: its material's at its texture coordinate, or a white
    /// diffuse lobe for a [`ShadingPoint::unit_albedo`] point.
    #[inline]
    pub fn lobes(&self, scene: &Scene) -> brdf::Lobes {
        if self.unit_albedo {
            brdf::Lobes::of(&crate::scene::Material::Diffuse { albedo: Vec3::ONE })
        } else {
            scene.lobes_at(self.material, self.uv)
        }
    }
}

/// Shades a camera hit seen along `ray_dir`: the offset origin for shadow rays, the normal and
/// the direction back to the viewer.
pub fn shading_point(tracer: &Tracer, hit: &Hit, ray_dir: Vec3) -> ShadingPoint {
    ShadingPoint {
        origin: tracer.offset_origin(hit, hit.normal),
        normal: hit.normal,
        view: -ray_dir,
        material: hit.material,
        uv: hit.uv,
        unit_albedo: false,
    }
}

/// The random stream of a camera sub-sample's interreflection paths.
pub fn path_stream(pixel: u64, sub: usize, spp: u32) -> u64 {
    pixel * spp.max(1) as u64 + sub as u64
}

/// What one tile of the bake produces.
struct TileOutput {
    rows: Vec<RowData>,
    /// (pixel, mean albedo over hit sub-samples, coverage).
    pixels: Vec<(u32, [f32; 3], f32)>,
    dropped_energy: f64,
    total_energy: f64,
    rays: u64,
    /// (pixel, its response to every light column), for pixels with a visit.
    lights: Vec<(u32, Vec<Vec3>)>,
}

/// Bakes `scene` with `settings` in memory, calling `progress` after each tile.
pub fn bake(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<Transport> {
    bake_with(scene, settings, progress, &Cancel::new())
}

/// [`bake`], stopped between tiles with [`PrtError::Cancelled`] once `cancel` is cancelled.
pub fn bake_with(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &(dyn Fn(BakeProgress) + Sync),
    cancel: &Cancel,
) -> Result<Transport> {
    cancel.check()?;
    let mut kept = KeptTiles::default();
    let mesh = bake_mesh(scene, settings)?;
    let mut keep = |tile: EncodedTile, stats: TileStats| kept.push(tile, stats);
    let untiled = bake_tiles(scene, settings, mesh, progress, cancel, &mut keep)?;
    kept.into_transport(untiled)
}

/// Bakes `scene` with `settings` into the transport file `path`, each tile written out as soon
/// as the tiles before it are: memory holds the tiles under way and the per-pixel tables, not
/// the transport. Writes the file [`bake`] and [`Transport::save`] would, byte for byte, and
/// returns its metadata.
pub fn bake_to_file(
    scene: &Scene,
    settings: &BakeSettings,
    path: &std::path::Path,
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<TransportMeta> {
    bake_to_file_with(scene, settings, path, progress, &Cancel::new())
}

/// [`bake_to_file`], stopped between tiles with [`PrtError::Cancelled`] once `cancel` is
/// cancelled: nothing is then written at `path` and the spills are removed.
pub fn bake_to_file_with(
    scene: &Scene,
    settings: &BakeSettings,
    path: &std::path::Path,
    progress: &(dyn Fn(BakeProgress) + Sync),
    cancel: &Cancel,
) -> Result<TransportMeta> {
    cancel.check()?;
    let mesh = bake_mesh(scene, settings)?;
    let mut writer = TransportWriter::create(
        path,
        image_size(scene, mesh.as_ref()),
        settings.cube_n,
        settings.sh_order,
        settings.storage().2,
    )?;
    let mut write = |tile: EncodedTile, stats: TileStats| writer.push(&tile, stats);
    let untiled = bake_tiles(scene, settings, mesh, progress, cancel, &mut write)?;
    writer.finish(untiled)
}

/// A tile's statistics: energy dropped by thresholding and quantisation, total energy, rays.
type TileStats = [f64; 3];

/// The mesh a per-vertex bake's rows belong to (refined at shadow edges where the settings say
/// so, [`BakeSettings::refines_shadows`]), with its in-out BRDF terms; `None` for a view. The
/// settings are checked against the scene first, so what a scene cannot be baked with is said
/// before any work.
pub fn bake_mesh(scene: &Scene, settings: &BakeSettings) -> Result<Option<VertexMesh>> {
    settings.validate_for(scene)?;
    Ok(match settings.domain {
        BakeDomain::Vertices { edge_length } => {
            let mut m = if settings.refines_shadows() {
                VertexMesh::tessellate_refined(scene, edge_length)?
            } else {
                VertexMesh::tessellate(scene, edge_length)?
            };
            m.factors = crate::scene::brdf_factor::BrdfFactors::for_materials(
                &scene.materials,
                settings.brdf_terms as usize,
                settings.brdf_error as f64,
            )
            .map(Box::new);
            Some(m)
        }
        BakeDomain::View => None,
    })
}

/// The size of the image the rows belong to: the view's, or for a mesh one tile wide, vertex
/// v's terms pixels v · stride + k.
fn image_size(scene: &Scene, mesh: Option<&VertexMesh>) -> (usize, usize) {
    match mesh {
        Some(m) => (TILE, m.pixel_count().div_ceil(TILE)),
        None => (scene.camera.width as usize, scene.camera.height as usize),
    }
}

/// The bake of `mesh` (from [`bake_mesh`]), handing each encoded tile and its statistics to
/// `deliver` in tile order; `cancel` is checked before the tiles and before each tile.
fn bake_tiles(
    scene: &Scene,
    settings: &BakeSettings,
    mesh: Option<VertexMesh>,
    progress: &(dyn Fn(BakeProgress) + Sync),
    cancel: &Cancel,
    deliver: &mut (dyn FnMut(EncodedTile, TileStats) -> Result<()> + Send),
) -> Result<Untiled> {
    let identity = settings.identity(scene)?;
    let tracer = Tracer::new(scene);
    let cam = &scene.camera;
    let (w, h) = image_size(scene, mesh.as_ref());
    let n = settings.cube_n;
    let samples = TexelSamples::new(n, settings.texel_samples as usize, settings.seed)
        .refined(settings.stored_edge_texel_samples() as usize);
    let basis = TexelShBasis::new(n, settings.sh_order)?;
    let (tx, ty) = tile_grid(w, h);
    if let Some([_, count]) = settings.shard
        && count as usize > ty
    {
        return Err(PrtError::invalid(
            "shard",
            format!("{count} shards for an image of only {ty} tile rows"),
        ));
    }
    // A shard bakes only its band of tile rows; the other tiles stay empty.
    let mine = |tile: usize| match settings.shard {
        None => true,
        Some([i, count]) => shard_of_band(tile / tx, ty, count as usize) == i as usize,
    };
    let pixels_total: usize = (0..tx * ty)
        .filter(|&t| mine(t))
        .map(|t| match &mesh {
            Some(m) => m
                .pixel_count()
                .saturating_sub(t * TILE * TILE)
                .min(TILE * TILE),
            None => tile_pixels(w, h, t % tx, t / tx),
        })
        .sum();
    let medium = match &scene.medium {
        Some(spec) => Some(spec.build(None)?),
        None => None,
    };
    // The pixels that take more sub-samples (none per vertex); the cache's paths start at the
    // same ones as the rows.
    let edges = EdgeMap::new(scene, &tracer, settings);
    let edge_pixels = edges.count();
    // Whether a pixel is this bake's (its tile is), and the progress of a first stage.
    let mine_pixel = |p: usize| mine((p / w / TILE) * tx + (p % w) / TILE);
    let stage = |medium_light: [usize; 2], medium_texels: [usize; 2], cache_points: [usize; 2]| {
        progress(BakeProgress {
            pixels_done: 0,
            pixels_total,
            shadow_rays: 0,
            edge_pixels,
            medium_light,
            medium_texels,
            cache_points,
        })
    };
    // What the medium's points see of the texels; the transmittance table for bounces.
    let medium_light = match &medium {
        Some(m) => Some(MediumLight::build(
            m,
            &tracer,
            n,
            settings.bounces > 0,
            &|done, total| stage([done, total], [0, 0], [0, 0]),
        )?),
        None => None,
    };
    let medium_rows = match medium.as_ref().zip(medium_light.as_ref()) {
        Some((m, light)) => Some(MediumRows::bake(
            m,
            light,
            scene,
            &tracer,
            &samples,
            settings.spp,
            settings.seed,
            &mine_pixel,
            &|done, total| stage([0, 0], [done, total], [0, 0]),
        )?),
        None => None,
    };
    let through = medium.as_ref().zip(medium_light.as_ref());
    let bounces = bounce::Bounces::new(scene, &tracer, settings, &samples)
        .with_medium(through.filter(|_| settings.bounces > 0))
        .with_cache(&edges, &mine_pixel, &|done, total| {
            stage([0, 0], [0, 0], [done, total])
        })?;
    let light_sampler = LightSampler::new(scene, settings);
    let mut reference_haar = unoccluded_row(&samples);
    let reference_energy: f64 = reference_haar.iter().map(|&v| (v as f64).powi(2)).sum();
    haar::forward_face_all(&mut reference_haar, n, &mut Vec::new());
    // The thresholding budget of each glossy term's rows (material-major, as the factors): the
    // diffuse row's, divided by the square of the largest g_k the term's response is multiplied
    // by, so that its error once drawn is at most the diffuse row's.
    let term_budgets: Vec<f64> = match mesh.as_ref().and_then(|m| m.factors.as_deref()) {
        Some(f) => (0..f.terms.len() as u32)
            .flat_map(|m| (1..f.stride).map(move |k| (m, k)))
            .map(|(m, k)| reference_energy / (f.view_peak(m, k).max(1e-6) as f64).powi(2))
            .collect(),
        None => Vec::new(),
    };
    let ctx = TileContext {
        scene,
        width: w,
        height: h,
        mesh: mesh.as_ref(),
        tracer: &tracer,
        edges: &edges,
        settings,
        reference_energy,
        term_budgets,
        thresholder: Thresholder::new(identity.budget, identity.threshold, n, &reference_haar),
        samples: &samples,
        basis: &basis,
        medium: medium.as_ref(),
        medium_rows: medium_rows.as_ref(),
        bounces: &bounces,
        lights: &light_sampler,
    };
    let done = AtomicUsize::new(0);
    let rays = AtomicU64::new(0);
    let (c, shc, quantization) = (
        texel_count(n),
        settings.sh_order.pow(2),
        identity.quantization,
    );
    let mut albedo = vec![[0.0f32; 3]; w * h];
    let mut coverage = vec![0.0f32; w * h];
    // The light columns of one band of tile rows, `[L, 3, TILE, W]`, encoded once the band's
    // last tile is in (each image row against its own scale, see `LightColumns`).
    let columns = light_sampler.columns();
    let mut light_columns = LightColumns::zeros(columns, w, h);
    let mut band = vec![0.0f32; columns * 3 * TILE * w];
    cancel.check()?;
    in_tile_order(
        tx * ty,
        |t| {
            cancel.check()?;
            if !mine(t) {
                return Ok((t, None));
            }
            let mut out = bake_tile(&ctx, t % tx, t / tx);
            // Quantised here, in parallel, so the rows' floats are freed tile by tile.
            let encoded = EncodedTile::encode(&out.rows, c, shc, quantization)?;
            out.rows = Vec::new();
            let px = out.pixels.len();
            progress(BakeProgress {
                pixels_done: done.fetch_add(px, Ordering::Relaxed) + px,
                pixels_total,
                shadow_rays: rays.fetch_add(out.rays, Ordering::Relaxed) + out.rays,
                edge_pixels,
                medium_light: [0, 0],
                medium_texels: [0, 0],
                cache_points: [0, 0],
            });
            Ok((t, Some((out, encoded))))
        },
        |(t, tile)| {
            let band_done = |band: &mut Vec<f32>, cols: &mut LightColumns| {
                if t % tx == tx - 1 && columns > 0 {
                    cols.set_rows((t / tx) * TILE, band);
                    band.fill(0.0);
                }
            };
            let Some((out, encoded)) = tile else {
                band_done(&mut band, &mut light_columns);
                return deliver(EncodedTile::encode(&[], c, shc, quantization)?, [0.0; 3]);
            };
            for (p, a, cov) in out.pixels {
                albedo[p as usize] = a;
                coverage[p as usize] = cov;
            }
            for (p, values) in &out.lights {
                let (x, y) = (*p as usize % w, *p as usize / w);
                let r = y % TILE;
                for (col, v) in values.iter().enumerate() {
                    if !v.is_finite() {
                        return Err(PrtError::invalid(
                            "lights",
                            format!(
                                "light column {col} gives {v} at pixel ({x}, {y}): is a light \
                                 on a surface?"
                            ),
                        ));
                    }
                    for k in 0..3 {
                        band[((col * 3 + k) * TILE + r) * w + x] = v[k];
                    }
                }
            }
            band_done(&mut band, &mut light_columns);
            let stats = [
                out.dropped_energy + encoded.quantization_energy,
                out.total_energy,
                out.rays as f64,
            ];
            deliver(encoded, stats)
        },
    )?;
    debug_assert_eq!(identity.texel_samples as usize, samples.per_texel);
    let meta = TransportMeta {
        width: w as u32,
        height: h as u32,
        tile: TILE as u32,
        scene_path: scene.source_path.display().to_string(),
        camera: CameraMeta {
            eye: cam.eye.to_array(),
            target: cam.target.to_array(),
            up: cam.up.to_array(),
            fov_y_deg: cam.fov_y_deg,
        },
        identity,
        cache_points: bounces.cache().map_or(0, |c| c.points as u64),
        per_vertex: mesh.as_ref().map(|m| PerVertexMeta {
            vertices: m.vertex_count() as u32,
            triangles: m.triangles.len() as u32,
            image: [cam.width, cam.height],
            materials: scene.materials.len() as u32,
            albedo_maps: m.albedo_maps.len() as u32,
            brdf_stride: m.stride() as u32,
            brdf_map: m.factors.as_ref().map_or(0, |f| f.map.res as u32),
        }),
        stats: BakeStats::default(),
        lights: scene.lights.clone(),
    };
    Ok(Untiled {
        meta,
        albedo,
        coverage,
        mesh,
        lights: light_columns,
    })
}

fn tile_pixels(w: usize, h: usize, tx: usize, ty: usize) -> usize {
    (w - tx * TILE).min(TILE) * (h - ty * TILE).min(TILE)
}

/// What every tile of a bake shares.
struct TileContext<'a> {
    scene: &'a Scene,
    /// Size of the image the rows belong to: the view's, or one tile wide for a mesh.
    width: usize,
    height: usize,
    /// The mesh of a per-vertex bake: pixel `v · stride` is vertex v (its terms after it).
    mesh: Option<&'a VertexMesh>,
    tracer: &'a Tracer,
    /// The pixels that take `edge_spp` sub-samples.
    edges: &'a EdgeMap,
    settings: &'a BakeSettings,
    samples: &'a TexelSamples,
    basis: &'a TexelShBasis,
    /// Energy of an unshadowed row, the scale of the thresholding budget.
    reference_energy: f64,
    /// The scale of each glossy term's thresholding budget, `[m · (stride − 1) + k − 1]`.
    term_budgets: Vec<f64>,
    /// The thresholding budget.
    thresholder: Thresholder,
    /// The scene's medium and its rows, if it has one.
    medium: Option<&'a Medium>,
    medium_rows: Option<&'a MediumRows>,
    /// The interreflections' paths and vertex rows.
    bounces: &'a bounce::Bounces<'a>,
    /// The local lights' columns.
    lights: &'a LightSampler,
}

/// Bakes one tile: dense rows per (pixel, material), SH projection, Haar and thresholding.
fn bake_tile(ctx: &TileContext, tile_x: usize, tile_y: usize) -> TileOutput {
    let TileContext {
        scene,
        width: w,
        height: h,
        mesh,
        tracer,
        edges: _,
        settings,
        samples,
        basis,
        reference_energy,
        ref term_budgets,
        ref thresholder,
        medium,
        medium_rows,
        bounces,
        lights,
    } = *ctx;
    let n = settings.cube_n;
    let c = texel_count(n);
    let shc = settings.sh_order * settings.sh_order;
    let mut out = TileOutput {
        rows: Vec::new(),
        pixels: Vec::new(),
        dropped_energy: 0.0,
        total_energy: 0.0,
        rays: 0,
        lights: Vec::new(),
    };
    let mut order: Vec<(f32, u32)> = Vec::with_capacity(c);
    // The tile's rows, each with its kind ([`RowKind`]), laid out kind by kind at the end.
    let mut rows: Vec<(RowKind, RowData)> = Vec::new();
    let mut scratch = Vec::new();
    // One sub-sample's rows of a textured material, before its colour weighs them.
    let mut scratch_rows = [vec![0.0f32; c], vec![0.0f32; c]];
    for y in tile_y * TILE..((tile_y + 1) * TILE).min(h) {
        for x in tile_x * TILE..((tile_x + 1) * TILE).min(w) {
            let visits = visits(ctx, x, y);
            if visits.is_empty() {
                continue;
            }
            let inv_spp = 1.0 / visits.len() as f32;
            // Dense rows of this pixel per material seen: the diffuse lobe's and, for glossy
            // materials, the GGX lobe's; tinted per sub-sample for a textured material.
            let mut dense: Vec<Slot> = Vec::new();
            // Interreflected light, one row per colour channel (colour bleeding mixes them).
            let mut indirect: Option<[Vec<f32>; 3]> = None;
            let mut hits = 0usize;
            let mut covered = 0.0f32;
            let mut albedo_sum = Vec3::ZERO;
            let pixel_index = (y * w + x) as u64;
            let mut light_columns = vec![Vec3::ZERO; lights.columns()];
            // A textured vertex, whose rows are a white surface's.
            let mut white = false;
            // A glossy vertex's in-out BRDF terms 1.., and the material they belong to.
            let mut terms: Option<(u32, Vec<Vec<f32>>)> = None;
            for (sub, visit) in visits.into_iter().enumerate() {
                covered += visit.covered;
                let stream = path_stream(pixel_index, sub, sample_stride(settings));
                if settings.bounces > 0
                    && let Some(ray) = visit.ray
                    && medium.is_some()
                {
                    // Paths that start at collisions along the camera ray.
                    let rows =
                        indirect.get_or_insert_with(|| std::array::from_fn(|_| vec![0.0; c]));
                    let scale = inv_spp / settings.paths as f32;
                    out.rays += bounces.add_camera_rows(ray, stream, scale, rows);
                }
                let Some(sp) = visit.point else {
                    continue;
                };
                let seen = visit.seen;
                hits += 1;
                // A vertex is seen from every side: only the diffuse lobe holds for all.
                let mut here = sp.lobes(scene);
                if mesh.is_some() {
                    here.specular = Vec3::ZERO;
                }
                albedo_sum += here.albedo;
                let glossy = scene.materials[sp.material as usize]
                    .glossy_lobe()
                    .is_some()
                    && mesh.is_none();
                // A vertex has one visit, and a textured one is baked white: no tinting.
                let textured = !sp.unit_albedo
                    && scene
                        .material_maps
                        .get(sp.material as usize)
                        .is_some_and(Option::is_some);
                white |= sp.unit_albedo;
                let slot = match dense.iter().position(|d| d.material == sp.material) {
                    Some(i) => i,
                    None => {
                        dense.push(Slot::new(sp.material, c, glossy, textured));
                        dense.len() - 1
                    }
                };
                if lights.columns() > 0 {
                    let lobes = match mesh {
                        // A vertex is seen from every side: its diffuse lobe.
                        Some(_) => LightSampler::diffuse(here.albedo),
                        None => here,
                    };
                    out.rays += lights.add(
                        tracer,
                        &sp,
                        &lobes,
                        settings.unshadowed,
                        stream,
                        None,
                        true,
                        Vec3::splat(inv_spp * seen),
                        &mut light_columns,
                    );
                }
                let slot = &mut dense[slot];
                let (diffuse, glossy_row) = slot.rows_for_sample(&mut scratch_rows);
                let factors = gloss::factors_of(mesh.and_then(|m| m.factors.as_deref()), &sp);
                out.rays += match factors {
                    Some(f) => {
                        let count = f.terms_of(sp.material) - 1;
                        let (_, rows) =
                            terms.get_or_insert_with(|| (sp.material, vec![vec![0.0; c]; count]));
                        gloss::accumulate_term_rows(
                            tracer,
                            samples,
                            &sp,
                            settings.unshadowed,
                            f,
                            inv_spp * seen,
                            diffuse,
                            rows,
                        )
                    }
                    None => accumulate_direct_rows(
                        tracer,
                        samples,
                        &sp,
                        settings.unshadowed,
                        medium,
                        inv_spp * seen,
                        diffuse,
                        glossy_row.map(|row| (here.alpha, row)),
                    ),
                };
                slot.fold_sample(&here, &scratch_rows);
                if settings.bounces > 0 {
                    let rows =
                        indirect.get_or_insert_with(|| std::array::from_fn(|_| vec![0.0; c]));
                    // What the camera sees of the surface is attenuated by a medium in between.
                    let scale = inv_spp * seen / settings.paths as f32;
                    let lit = (lights.columns() > 0).then_some((lights, &mut light_columns[..]));
                    out.rays += bounces.add_rows(&sp, stream, scale, rows, lit);
                }
            }
            let pixel = (y * w + x) as u32;
            let mean_albedo = if hits > 0 {
                (albedo_sum / hits as f32).to_array()
            } else {
                [0.0; 3]
            };
            out.pixels.push((pixel, mean_albedo, covered * inv_spp));
            // A vertex's term pixels are its own: covered as it is, so that masks keep them.
            for k in 1..mesh.map_or(1, VertexMesh::stride) as u32 {
                out.pixels.push((pixel + k, [0.0; 3], covered * inv_spp));
            }
            if !light_columns.is_empty() {
                out.lights.push((pixel, light_columns));
            }
            let lobes = dense
                .into_iter()
                .flat_map(|slot| {
                    let white_surface = crate::scene::Material::Diffuse { albedo: Vec3::ONE };
                    let material = match white {
                        true => &white_surface,
                        false => &scene.materials[slot.material as usize],
                    };
                    slot.finish(material)
                })
                .enumerate()
                .map(|(i, (weight, row))| (RowKind::Lobe(i), weight, row));
            let channels = indirect.into_iter().flat_map(|rows| {
                rows.into_iter().enumerate().map(|(k, row)| {
                    let weight = std::array::from_fn(|i| (i == k) as u8 as f32);
                    (RowKind::Channels, weight, row)
                })
            });
            // Every row with its kind, its pixel and the scale of its thresholding budget.
            let lobes = lobes
                .chain(channels)
                .map(|(kind, weight, row)| (kind, pixel, weight, row, reference_energy));
            let scattered = medium.zip(medium_rows).and_then(|(m, rows)| {
                let p = pixel as usize;
                Some((
                    RowKind::Medium,
                    pixel,
                    m.albedo.to_array(),
                    rows.row(p)?,
                    rows.reference_energy(p),
                ))
            });
            // A glossy vertex's terms, each with its budget.
            let per = mesh.map_or(1, VertexMesh::stride) - 1;
            let terms = terms.into_iter().flat_map(|(m, rows)| {
                let specular = scene.materials[m as usize]
                    .glossy_lobe()
                    .map_or([0.0; 3], |(s, _)| s.to_array());
                let first = m as usize * per;
                rows.into_iter().enumerate().map(move |(i, row)| {
                    let budget = term_budgets[first + i];
                    (
                        RowKind::Term(i),
                        pixel + i as u32 + 1,
                        specular,
                        row,
                        budget,
                    )
                })
            });
            for (kind, pixel, weight, mut row, budget_scale) in lobes.chain(scattered).chain(terms)
            {
                let mut sh = vec![0.0f32; shc];
                basis.project_row(&row, &mut sh);
                haar::forward_face_all(&mut row, n, &mut scratch);
                let (entries, dropped, total) =
                    thresholder.sparsify(&row, budget_scale, &mut order);
                out.dropped_energy += dropped;
                out.total_energy += total;
                rows.push((
                    kind,
                    RowData {
                        pixel,
                        weight,
                        entries,
                        sh,
                    },
                ));
            }
        }
    }
    // Stable: inside a kind, rows keep their pixels' order (and a pixel's channels theirs).
    rows.sort_by_key(|(kind, _)| *kind);
    out.rows = rows.into_iter().map(|(_, row)| row).collect();
    out
}

/// What a row of a tile holds, in the order a tile lays its rows out. A block's column is cut into
/// strips of 8 rows, kept whole when one of them has an entry, so rows that keep the same
/// coefficients belong side by side: the first lobe of every pixel, then the second, and so on;
/// then each pixel's three interreflection rows together (their paths are the same, and so are
/// the coefficients they keep); then the medium's rows; then a per-vertex bake's BRDF terms,
/// term by term. Laid out pixel by pixel, the sparse interreflection rows shared strips with the
/// dense direct rows: on a 128² one-bounce demo bake 29% of strip values were entries, and 76%
/// this way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum RowKind {
    /// The i-th lobe row of a pixel (a material's diffuse lobe, then its GGX lobe, per material).
    Lobe(usize),
    /// A pixel's interreflection rows, one per colour channel.
    Channels,
    /// A pixel's single-scattering row through the medium.
    Medium,
    /// A vertex's i-th in-out BRDF term.
    Term(usize),
}

/// The row of an unshadowed surface facing +Y with unit albedo, in texel order: the row the
/// thresholding budget is relative to (the same energy for every normal up to texel
/// discretisation).
fn unoccluded_row(samples: &TexelSamples) -> Vec<f32> {
    let m = samples.per_texel;
    (0..samples.dirs.len() / m)
        .map(|j| {
            ((j * m..(j + 1) * m)
                .map(|k| samples.dirs[k].y.max(0.0) as f64 * samples.weights[k] as f64)
                .sum::<f64>()
                * std::f64::consts::FRAC_1_PI) as f32
        })
        .collect()
}
