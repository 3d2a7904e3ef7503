//! The bake: for every pixel of the fixed view, its transport row over all 6 N² cube texel lights
//! (visibility x BRDF x cosine integrated over each texel), the SH projection of the same row,
//! then per-face Haar, thresholding and quantisation into the tiled layout of
//! [`crate::store::transport`]. Parallel over pixel tiles with rayon, taken in order; each tile is
//! finished and compressed before the next is taken and handed on in tile order, either kept
//! ([`bake`]) or written out at once ([`bake_to_file`]), so a bake to a file holds only the tiles
//! under way, whatever the size of its output. A [`Cancel`] token stops either between tiles.

pub mod bounce;
mod direct;
mod in_order;
pub mod lights;
pub mod medium_light;
pub mod medium_rows;
mod packets;
pub mod path_tracer;
mod pixels;
pub mod reference;
mod settings;
mod setup;
mod slot;
mod tile;
mod tint;
mod visibility;

use crate::store::transport::{Attached, BakeDomain, BakeIdentity, Domain};
pub use direct::{accumulate_direct_rows, direct_texels};
pub use in_order::Cancel;
use in_order::in_tile_order;
pub use lights::LightSampler;
pub use packets::CentrePackets;
pub use pixels::{EdgeMap, pixel_subsamples, sample_stride};
pub use settings::{
    BakeSettings, load_if_baked_with, load_or_bake, load_or_bake_logged, worst_case_bytes,
};
use setup::{TileParts, with_tile_context};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use tile::{TileContext, bake_tile};

use glam::Vec3;

use crate::error::{PrtError, Result};
use crate::math::cubemap::{texel_count, validate_n};
use crate::math::sampling::TexelSamples;
use crate::medium::Medium;
use crate::scene::Scene;
use crate::scene::brdf;
use crate::scene::tessellate::VertexMesh;
use crate::scene::trace::{Hit, Tracer};
use crate::store::budget::Budget;
use crate::store::transport::{
    BakeStats, CameraMeta, EncodedTile, KeptTiles, LightColumns, PerVertexMeta, Quantization, TILE,
    Transport, TransportMeta, TransportWriter, Untiled, shard_of_band, tile_grid,
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

/// What a shading point's samples are shadowed by, which every source of its light (the direct
/// rows, a vertex's BRDF terms, the light columns) takes: the scene's tracer, unless shadows are
/// off, and the medium in between, if any.
#[derive(Clone, Copy)]
pub struct Shadows<'a> {
    /// The scene's occluders.
    pub tracer: &'a Tracer,
    /// Every direction open and no ray traced.
    pub unshadowed: bool,
    /// The scene's medium, whose transmittance a visible direction takes (where shadows are on).
    pub medium: Option<&'a Medium>,
    /// The texel centres the shading points trace (the quadrature's, or the samples' at one a
    /// texel) in blocks traced together; `None` traces them one by one (the same answers).
    pub packets: Option<&'a CentrePackets>,
}

/// The random stream of a camera sub-sample's interreflection paths.
pub fn path_stream(pixel: u64, sub: usize, spp: u32) -> u64 {
    pixel * spp.max(1) as u64 + sub as u64
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
/// so, [`BakeSettings::refines_shadows`]); `None` for a view. The
/// settings are checked against the scene first, so what a scene cannot be baked with is said
/// before any work.
pub fn bake_mesh(scene: &Scene, settings: &BakeSettings) -> Result<Option<VertexMesh>> {
    settings.validate_for(scene)?;
    Ok(match settings.domain {
        BakeDomain::Vertices { edge_length } => Some(if settings.refines_shadows() {
            VertexMesh::tessellate_refined(scene, edge_length)?
        } else {
            VertexMesh::tessellate(scene, edge_length)?
        }),
        BakeDomain::View => None,
    })
}

/// The size of the image the rows belong to: the view's, or for a mesh one tile wide, vertex v
/// pixel v.
fn image_size(scene: &Scene, mesh: Option<&VertexMesh>) -> (usize, usize) {
    match mesh {
        Some(m) => (TILE, m.vertex_count().div_ceil(TILE)),
        None => (scene.camera.width as usize, scene.camera.height as usize),
    }
}

/// What a bake's tiles are made with: its identity, the scene's tracer, its mesh (with its
/// glossy vertices' visibility where the settings keep it) and the size of its image.
struct Prepared {
    identity: BakeIdentity,
    tracer: Tracer,
    mesh: Option<VertexMesh>,
    size: [usize; 2],
}

impl Prepared {
    fn new(scene: &Scene, settings: &BakeSettings, mut mesh: Option<VertexMesh>) -> Result<Self> {
        let identity = settings.identity(scene)?;
        let tracer = Tracer::new(scene);
        if let Some(m) = mesh.as_mut().filter(|_| identity.visibility) {
            let bits = visibility::glossy_vertices(scene, &tracer, m, settings)?;
            m.visibility = Some(Box::new(bits));
        }
        let (w, h) = image_size(scene, mesh.as_ref());
        Ok(Prepared {
            identity,
            tracer,
            mesh,
            size: [w, h],
        })
    }

    /// What the tiles' context is built from, for a bake of `pixels_total` pixels.
    fn parts<'a>(
        &'a self,
        scene: &'a Scene,
        settings: &'a BakeSettings,
        pixels_total: usize,
    ) -> TileParts<'a> {
        TileParts {
            scene,
            settings,
            identity: &self.identity,
            tracer: &self.tracer,
            mesh: self.mesh.as_ref(),
            size: self.size,
            pixels_total,
        }
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
    let prepared = Prepared::new(scene, settings, mesh)?;
    let [w, h] = prepared.size;
    let (tx, ty) = tile_grid(w, h);
    let mine = shard_tiles(settings, [tx, ty])?;
    let pixels_total: usize = (0..tx * ty)
        .filter(|&t| mine(t))
        .map(|t| tile_pixels(w, h, prepared.mesh.as_ref(), [tx, t]))
        .sum();
    // Whether a pixel is this bake's (its tile is).
    let mine_pixel = |p: usize| mine((p / w / TILE) * tx + (p % w) / TILE);
    let parts = prepared.parts(scene, settings, pixels_total);
    let (c, shc, quantization) = (
        texel_count(settings.cube_n),
        settings.sh_order.pow(2),
        prepared.identity.quantization,
    );
    let (tables, cache_points) = with_tile_context(&parts, &mine_pixel, progress, |ctx| {
        let edge_pixels = ctx.edges.count();
        let done = AtomicUsize::new(0);
        let rays = AtomicU64::new(0);
        let mut tables = PixelTables::new(ctx.lights.columns(), w, h);
        cancel.check()?;
        in_tile_order(
            tx * ty,
            |t| {
                cancel.check()?;
                if !mine(t) {
                    return Ok((t, None));
                }
                let mut out = bake_tile(ctx, t % tx, t / tx);
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
                let band_done = t % tx == tx - 1;
                let Some((out, encoded)) = tile else {
                    tables.band_done(t / tx, band_done);
                    return deliver(EncodedTile::encode(&[], c, shc, quantization)?, [0.0; 3]);
                };
                tables.take(&out)?;
                tables.band_done(t / tx, band_done);
                let stats = [
                    out.dropped_energy + encoded.quantization_energy,
                    out.total_energy,
                    out.rays as f64,
                ];
                deliver(encoded, stats)
            },
        )?;
        debug_assert_eq!(
            prepared.identity.texel_samples as usize,
            ctx.samples.per_texel
        );
        Ok((tables, ctx.bounces.cache().map_or(0, |c| c.points as u64)))
    })?;
    let Prepared { identity, mesh, .. } = prepared;
    let meta = meta_of(scene, [w, h], identity, cache_points, mesh.as_ref());
    Ok(Untiled {
        meta,
        albedo: tables.albedo,
        coverage: tables.coverage,
        attached: Attached {
            domain: Domain::from_mesh(mesh),
            lights: tables.light_columns,
        },
    })
}

/// Bakes the tiles of `scene` one at a time, for benchmarks and profilers: what every tile
/// reads (the tracer, the texel samples, the edge map, a medium's and the bounces' stages) is
/// built once, then `f` is handed the number of tiles and a function that bakes and encodes
/// tile `t` (row-major over the image's tiles, as a bake takes them) and returns its shadow
/// rays, or an error for a tile past the last.
pub fn with_tile_baker<R>(
    scene: &Scene,
    settings: &BakeSettings,
    f: impl FnOnce(usize, &(dyn Fn(usize) -> Result<u64> + Sync)) -> R,
) -> Result<R> {
    let prepared = Prepared::new(scene, settings, bake_mesh(scene, settings)?)?;
    let [w, h] = prepared.size;
    let (tx, ty) = tile_grid(w, h);
    let parts = prepared.parts(scene, settings, w * h);
    let (c, shc) = (texel_count(settings.cube_n), settings.sh_order.pow(2));
    with_tile_context(&parts, &|_| true, &|_| {}, |ctx| {
        let one = |t: usize| {
            if t >= tx * ty {
                return Err(PrtError::invalid(
                    "tile",
                    format!("tile {t} of an image of {} tiles", tx * ty),
                ));
            }
            let out = bake_tile(ctx, t % tx, t / tx);
            EncodedTile::encode(&out.rows, c, shc, prepared.identity.quantization)?;
            Ok(out.rays)
        };
        Ok(f(tx * ty, &one))
    })
}

/// A bake's metadata: its image of `[w, h]` pixels, the camera and the mesh, the identity.
fn meta_of(
    scene: &Scene,
    [w, h]: [usize; 2],
    identity: crate::store::transport::BakeIdentity,
    cache_points: u64,
    mesh: Option<&VertexMesh>,
) -> TransportMeta {
    let cam = &scene.camera;
    TransportMeta {
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
        cache_points,
        per_vertex: mesh.map(|m| PerVertexMeta {
            vertices: m.vertex_count() as u32,
            triangles: m.triangles.len() as u32,
            image: [cam.width, cam.height],
            materials: scene.materials.len() as u32,
            albedo_maps: m.albedo_maps.len() as u32,
        }),
        stats: BakeStats::default(),
        lights: scene.lights.clone(),
    }
}

/// The per-pixel tables a bake fills as its tiles come in: albedo, coverage and the light
/// columns.
struct PixelTables {
    width: usize,
    albedo: Vec<[f32; 3]>,
    coverage: Vec<f32>,
    light_columns: LightColumns,
    /// The light columns of one band of tile rows, `[L, 3, TILE, W]`, encoded once the band's
    /// last tile is in (each image row against its own scale, see `LightColumns`).
    band: Vec<f32>,
}

impl PixelTables {
    fn new(columns: usize, w: usize, h: usize) -> PixelTables {
        PixelTables {
            width: w,
            albedo: vec![[0.0f32; 3]; w * h],
            coverage: vec![0.0f32; w * h],
            light_columns: LightColumns::zeros(columns, w, h),
            band: vec![0.0f32; columns * 3 * TILE * w],
        }
    }

    /// A tile's pixels' albedo, coverage and light columns.
    fn take(&mut self, out: &tile::TileOutput) -> Result<()> {
        let w = self.width;
        for &(p, a, cov) in &out.pixels {
            self.albedo[p as usize] = a;
            self.coverage[p as usize] = cov;
        }
        for (p, values) in &out.lights {
            let (x, y) = (*p as usize % w, *p as usize / w);
            let r = y % TILE;
            for (col, v) in values.iter().enumerate() {
                if !v.is_finite() {
                    return Err(PrtError::invalid(
                        "lights",
                        format!(
                            "light column {col} gives {v} at pixel ({x}, {y}): is a light on a \
                             surface?"
                        ),
                    ));
                }
                for k in 0..3 {
                    self.band[((col * 3 + k) * TILE + r) * w + x] = v[k];
                }
            }
        }
        Ok(())
    }

    /// Encodes band `band`'s light columns once its last tile is in (`done`).
    fn band_done(&mut self, band: usize, done: bool) {
        if done && !self.band.is_empty() {
            self.light_columns.set_rows(band * TILE, &self.band);
            self.band.fill(0.0);
        }
    }
}

/// The pixels of tile `t` of a `w` x `h` image `tx` tiles wide (its vertices for a mesh).
fn tile_pixels(w: usize, h: usize, mesh: Option<&VertexMesh>, [tx, t]: [usize; 2]) -> usize {
    match mesh {
        Some(m) => m
            .vertex_count()
            .saturating_sub(t * TILE * TILE)
            .min(TILE * TILE),
        None => {
            let (x, y) = (t % tx, t / tx);
            (w - x * TILE).min(TILE) * (h - y * TILE).min(TILE)
        }
    }
}

/// Whether each tile is this bake's: every tile, or a shard's band of tile rows (the other tiles
/// stay empty), of a grid `[tx, ty]` tiles.
fn shard_tiles(
    settings: &BakeSettings,
    [tx, ty]: [usize; 2],
) -> Result<impl Fn(usize) -> bool + Sync + use<>> {
    let shard = settings.shard;
    if let Some([_, count]) = shard
        && count as usize > ty
    {
        return Err(PrtError::invalid(
            "shard",
            format!("{count} shards for an image of only {ty} tile rows"),
        ));
    }
    Ok(move |tile: usize| match shard {
        None => true,
        Some([i, count]) => shard_of_band(tile / tx, ty, count as usize) == i as usize,
    })
}
