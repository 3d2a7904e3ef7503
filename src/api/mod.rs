//! The library's front door: load a scene, bake it (with settings that read from TOML or JSON,
//! a progress callback and cancellation), open a transport, make an environment (a file, an
//! array of pixels, the procedural sun, a bundled map), relight it into an image, and measure
//! an image against a reference. The command line and Python bindings need no more than this;
//! the stages underneath stay public for everything else.
//!
//! A bake and a relight:
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # const SCENE: &str = r#"
//! # [camera]
//! # eye = [0.0, 1.5, 4.0]
//! # target = [0.0, 0.5, 0.0]
//! # up = [0.0, 1.0, 0.0]
//! # fov_y_deg = 40.0
//! # width = 8
//! # height = 6
//! # [material.clay]
//! # type = "diffuse"
//! # albedo = [0.8, 0.3, 0.2]
//! # [[shape]]
//! # type = "quad"
//! # corners = [[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]
//! # material = "clay"
//! # [[shape]]
//! # type = "sphere"
//! # center = [0.0, 0.6, 0.0]
//! # radius = 0.6
//! # material = "clay"
//! # "#;
//! use wavelet_prt::api::{self, BakeSettings, Cancel, EnvRotation, Environment, Framing};
//! use wavelet_prt::api::{LightMix, RelightRequest, Relighter, Weighting};
//! let dir = std::env::temp_dir().join(format!("prt-api-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! std::fs::write(dir.join("scene.toml"), SCENE)?; // an 8 x 6 camera, a sphere on a quad
//! let scene = api::load_scene(dir.join("scene.toml"), &Framing::default())?;
//! let settings = BakeSettings { cube_n: 4, sh_order: 2, ..BakeSettings::default() };
//! let transport = api::bake(&scene, &settings, &|_| {}, &Cancel::new())?;
//! let mut relighter = Relighter::new(transport)?;
//! let sun = Environment::sun(40.0, 30.0)?;
//! let request = RelightRequest::Wavelet { k: 8, weighting: Weighting::Area };
//! let image = relighter.relight(&sun, &request, EnvRotation::default(), &LightMix::none())?;
//! assert_eq!((image.width, image.height), (8, 6));
//! assert!(image.pixels.iter().flatten().all(|v| v.is_finite()));
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok(())
//! # }
//! ```
//!
//! [`BakeSettings`] reads from a partial TOML or JSON document (`toml::from_str("cube_n = 8")`,
//! `serde_json::from_str(r#"{"cube_n": 8}"#)`), every key left out taking its default; its
//! documentation lists the keys against the flags of `prt bake`.

use std::path::Path;
use std::sync::Arc;

/// Bakes a scene in memory: [`crate::bake::bake_with`], with progress and cancellation.
pub use crate::bake::bake_with as bake;
pub use crate::bake::{BakeProgress, BakeSettings, Cancel};
pub use environment::Environment;
pub use still::Still;

mod environment;
mod still;
pub use crate::draw::background::Background;
pub use crate::env::envmap::{EnvMap, EnvRotation};
pub use crate::env::select::Weighting;
pub use crate::math::cubemap::CubeMap;
pub use crate::output::film::Image;
pub use crate::output::metrics::ErrorReport;
pub use crate::relight::{LightMix, LightSetting, RelightRequest};
pub use crate::relight::{Method, Terms};
pub use crate::scene::{Camera, Framing, Scene};
pub use crate::store::transport::{BakeDomain, Transport, TransportMeta};

use crate::draw::background::{composite, environment_behind, environment_behind_camera};
use crate::draw::raster::DRAW_SAMPLES;
use crate::draw::vertex;
pub use crate::env::select::SparseLight;
use crate::error::{PrtError, Result};
use crate::math::cube_pyramid::CubePyramid;
pub use crate::relight::PreparedLight;
use crate::relight::{Backend, Cpu, LightContext, lobe_light};
use crate::store::transport::Domain;

/// Kept wavelet terms K when none are asked for: `prt relight --terms`, the viewer's first view
/// and the Python package's `terms` (at most the file's 6 N², [`terms_for`]).
pub const DEFAULT_TERMS: usize = 200;

/// The K a relight of a cube of face size `cube_n` keeps when `asked` for: `asked`, except that
/// the default [`DEFAULT_TERMS`] on a cube with fewer terms keeps every term (a K asked for
/// that is out of range is left for the relight to refuse).
pub fn terms_for(asked: usize, cube_n: usize) -> usize {
    let total = crate::math::cubemap::texel_count(cube_n);
    if asked == DEFAULT_TERMS && asked > total {
        total
    } else {
        asked
    }
}

/// The request `prt relight --method --terms --weighting --sh-order` makes of a transport
/// baked as `meta` says: for wavelets K by [`terms_for`], checked against the cube's 6 N²
/// terms; for both SH methods `sh_order`, by default the baked order, checked against it for
/// `sh` (given with any other method but `sh-light`, it is still checked, as a flag that
/// cannot apply).
pub fn request(
    meta: &TransportMeta,
    method: Method,
    terms: usize,
    weighting: Weighting,
    sh_order: Option<usize>,
) -> Result<RelightRequest> {
    let (n, baked) = (
        meta.identity.cube_n as usize,
        meta.identity.sh_order as usize,
    );
    if let Some(o) = sh_order
        && method != Method::ShLight
    {
        crate::flags::sh_order(o, baked)?;
    }
    let k = terms_for(terms, n);
    if method == Method::Wavelet {
        crate::flags::terms(k, n)?;
    }
    Ok(RelightRequest::new(
        method,
        k,
        weighting,
        sh_order.unwrap_or(baked),
    ))
}

/// The environment turned `yaw_deg` about +Y, then `pitch_deg` about +X, as `--yaw` and
/// `--pitch` take it: finite angles.
pub fn rotation(yaw_deg: f64, pitch_deg: f64) -> Result<EnvRotation> {
    crate::flags::angle("yaw", yaw_deg)?;
    crate::flags::angle("pitch", pitch_deg)?;
    Ok(EnvRotation { yaw_deg, pitch_deg })
}

/// The domain of a per-vertex bake of `scene` with triangle edges up to `edge_length`, or by
/// default the scene's `edge_length`, else 1/160 of the diagonal of its bounds (as `prt bake
/// --per-vertex [--edge-length E]` takes it).
pub fn vertices(scene: &Scene, edge_length: Option<f32>) -> BakeDomain {
    BakeDomain::Vertices {
        edge_length: edge_length
            .unwrap_or_else(|| crate::scene::tessellate::VertexMesh::default_edge_length(scene)),
    }
}

/// Whether a per-vertex bake of `scene` keeps its glossy vertices' visibility unless told: when
/// it has a glossy material, as `prt bake --per-vertex` does.
pub fn glossy_visibility(scene: &Scene) -> bool {
    scene.materials.iter().any(|m| m.glossy_lobe().is_some())
}

/// The metadata of the transport file at `path` when it already holds this bake (or shard) of
/// `scene` with `settings`, whole and readable: [`bake_to_file`] then keeps it rather than
/// baking again.
pub fn already_baked(path: &Path, scene: &Scene, settings: &BakeSettings) -> Option<TransportMeta> {
    crate::bake::load_if_baked_with(path, scene, settings).map(|t| t.meta)
}

/// Joins the shards of one bake (files of `prt bake --shard I/COUNT`, in any order) into the
/// file a single bake writes, byte for byte. `progress(read, total)` follows the bytes read.
/// Returns the merged file's metadata.
pub fn merge(
    shards: &[std::path::PathBuf],
    path: impl AsRef<Path>,
    progress: &dyn Fn(u64, u64),
) -> Result<TransportMeta> {
    let path = path.as_ref();
    let inputs: Vec<&Path> = shards.iter().map(|p| p.as_path()).collect();
    crate::files::check_output(path, &["prt"], "a transport file", &inputs)?;
    let size = |p: &Path| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    let total: u64 = shards.iter().map(|p| size(p)).sum();
    let mut loaded = Vec::with_capacity(shards.len());
    let mut before = 0;
    for p in shards {
        loaded.push(Transport::load_with_progress(p, &|read, _| {
            progress(before + read, total)
        })?);
        before += size(p);
    }
    let names: Vec<String> = shards.iter().map(|p| p.display().to_string()).collect();
    Transport::merge_to_file(&loaded, &names, path)
}

/// Loads a scene file: TOML, or glTF (`.gltf`, `.glb`), framed as `framing` says (which of a
/// glTF file's cameras, the image size); `Framing::default()` keeps what the file gives.
pub fn load_scene(path: impl AsRef<Path>, framing: &Framing) -> Result<Scene> {
    Scene::load_with(path.as_ref(), framing)
}

/// Bakes `scene` with `settings` into the transport file `path` as `prt bake` does: the
/// settings and the output are checked before any work (a `.prt` name, a folder that exists and
/// can be written, none of the scene's own files), and each tile is written out once the tiles
/// before it are, so memory holds only the tiles under way. The file appears whole when the
/// bake ends; a cancelled or failed bake leaves nothing at `path` (and replaces no file there).
/// A file at `path` that already holds this very bake is kept, not baked again
/// ([`already_baked`]), so that a bake started again after a failure redoes only what is
/// missing. Returns the file's metadata.
pub fn bake_to_file(
    scene: &Scene,
    settings: &BakeSettings,
    path: impl AsRef<Path>,
    progress: &(dyn Fn(BakeProgress) + Sync),
    cancel: &Cancel,
) -> Result<TransportMeta> {
    let path = path.as_ref();
    settings.validate_for(scene)?;
    let inputs: Vec<&Path> = scene.input_files.iter().map(|p| p.as_path()).collect();
    crate::files::check_output(path, &["prt"], "a transport file", &inputs)?;
    // A run killed while writing left its temporary file; this one takes its place.
    crate::files::remove_stale_partials(path);
    if let Some(meta) = already_baked(path, scene, settings) {
        return Ok(meta);
    }
    crate::bake::bake_to_file_with(scene, settings, path, progress, cancel)
}

/// Opens a transport file.
pub fn open(path: impl AsRef<Path>) -> Result<Transport> {
    Transport::load(path.as_ref())
}

/// Every error metric of `image` against `reference` (relative L2, RMSE, PSNR, gradient error,
/// DSSIM) over the pixels where `mask` is above 0 (all of them without a mask): for a relit
/// view, [`Relighter::coverage`].
pub fn compare(image: &Image, reference: &Image, mask: Option<&[f32]>) -> Result<ErrorReport> {
    crate::output::metrics::compare(image, reference, mask)
}

/// Reads an OpenEXR image (its R, G and B channels as linear floats), as `prt compare` does.
pub fn read_image(path: impl AsRef<Path>) -> Result<Image> {
    Image::load_exr(path.as_ref())
}

/// Writes `image` as `prt relight -o` does: `.exr` linear 32-bit floats, `.png` tone-mapped at
/// `exposure` stops (by default chosen from the image over the pixels where `mask` is above 0),
/// atomically and never over an input.
pub fn save_image(
    image: &Image,
    path: impl AsRef<Path>,
    exposure: Option<f32>,
    mask: Option<&[f32]>,
) -> Result<()> {
    let tone = match exposure {
        Some(e) => crate::output::film::ToneMap::exposure(e),
        None => crate::output::film::ToneMap::auto(image, mask),
    };
    image.save(path.as_ref(), tone)
}

/// How many prepared lights a [`Relighter`] keeps: a few environments or rotations in turn.
const KEPT_LIGHTS: usize = 4;

/// What a prepared light was prepared from.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LightKey {
    environment: u64,
    rotation: EnvRotation,
}

/// Relights one transport on the CPU, again and again: it holds what the light side needs of
/// the transport ([`LightContext`]) and keeps the last few environments prepared (turned,
/// resampled to the transport's cube, Haar-transformed and projected onto SH) under their
/// rotation, so that another request, K or set of lights under the same environment and
/// rotation prepares nothing.
pub struct Relighter {
    transport: Arc<Transport>,
    ctx: LightContext,
    /// Prepared lights, the most recently used last.
    lights: Vec<(LightKey, PreparedLight)>,
    prepared: usize,
    background: Background,
}

impl Relighter {
    /// A relighter of `transport` (a [`Transport`] or an `Arc` of one), pixels that see no
    /// geometry black.
    pub fn new(transport: impl Into<Arc<Transport>>) -> Result<Relighter> {
        let transport = transport.into();
        let ctx = LightContext::new(&transport)?;
        Ok(Relighter {
            transport,
            ctx,
            lights: Vec::new(),
            prepared: 0,
            background: Background::Black,
        })
    }

    /// The same, with what pixels that see no geometry show: black (the default, the relit
    /// light alone, as metrics take it) or the environment behind, turned with it.
    pub fn with_background(mut self, background: Background) -> Relighter {
        self.background = background;
        self
    }

    /// Sets what pixels that see no geometry show from now on ([`Relighter::with_background`]).
    pub fn set_background(&mut self, background: Background) {
        self.background = background;
    }

    /// The transport.
    pub fn transport(&self) -> &Transport {
        &self.transport
    }

    /// How much of each pixel of a per-pixel bake's view sees geometry (0 to 1): the mask of
    /// [`compare`].
    pub fn coverage(&self) -> &[f32] {
        &self.transport.coverage
    }

    /// How many lights it has prepared so far: one per environment and rotation, unless more
    /// than a few were used in turn.
    pub fn prepared(&self) -> usize {
        self.prepared
    }

    /// The weights of the transport's local lights relit as `settings` say, one per light in
    /// the file's order; `LightSetting::defaults(&relighter.transport().meta.lights)` gives them
    /// as the scene did, [`LightMix::none`] switches them all off.
    pub fn lights(&self, settings: &[LightSetting]) -> Result<LightMix> {
        LightMix::new(&self.transport.meta.lights, settings)
    }

    /// The image `prt relight --device cpu` writes: `request` under `env` turned by
    /// `rotation` (none: the local lights alone), plus the local `lights`, and for a per-vertex
    /// bake drawn from `still`'s camera with `samples` samples a pixel (1, 4 or 16). Pixels that see
    /// no geometry show what the background says.
    pub fn render(
        &mut self,
        env: Option<&Environment>,
        request: &RelightRequest,
        rotation: EnvRotation,
        lights: &LightMix,
        still: &Still,
        samples: u32,
    ) -> Result<Image> {
        crate::draw::raster::sample_offsets(samples)?;
        let camera = still.camera(&self.transport)?;
        let terms = match env {
            Some(env) => self.terms(env, request, rotation)?,
            None => Terms::dark(),
        };
        let image = self.lit(&terms, lights)?;
        let lobe = match &camera {
            Some(_) => self.lobe(env, request, rotation)?,
            None => None,
        };
        let t = &self.transport;
        let (image, coverage) = match &camera {
            Some(camera) => {
                let light = (lobe.as_ref(), &lights.weights[..]);
                let r = vertex::draw_relit_lit(t, &image, light, camera, None, samples)?;
                (r.image, r.coverage)
            }
            None => (image, t.coverage.clone()),
        };
        let behind = match (self.background, env, &camera) {
            (Background::Black, ..) | (_, None, _) => return Ok(image),
            (Background::Environment, Some(env), Some(camera)) => {
                environment_behind_camera(camera, &coverage, env.map(), rotation)?
            }
            (Background::Environment, Some(env), None) => {
                environment_behind(&t.meta, &coverage, env.map(), rotation)?
            }
        };
        Ok(composite(&image, &behind))
    }

    /// The light a bake with visibility draws its glossy lobes from for `request` under `env`
    /// turned by `rotation` (none: dark); `None` for any other bake.
    fn lobe(
        &mut self,
        env: Option<&Environment>,
        request: &RelightRequest,
        rotation: EnvRotation,
    ) -> Result<Option<CubePyramid>> {
        let light = match env {
            Some(env) => Some(self.prepare(env, rotation)?),
            None => None,
        };
        let light = light.map(|i| &self.lights[i].1);
        lobe_light(&self.transport, &self.ctx, light, request)
    }

    /// The relit image of `terms` plus `lights`, checked finite: a per-pixel bake's view, a
    /// per-vertex bake's vertex colours.
    fn lit(&mut self, terms: &Terms, lights: &LightMix) -> Result<Image> {
        let (image, _) = Cpu(&self.transport).relight_lit(terms, lights)?;
        image.check_finite("relit image")?;
        Ok(image)
    }

    /// The light terms `request` relights with under `env` turned by `rotation`: the K kept
    /// Haar terms with their indices, every term, or the SH coefficients.
    pub fn terms(
        &mut self,
        env: &Environment,
        request: &RelightRequest,
        rotation: EnvRotation,
    ) -> Result<Terms> {
        let i = self.prepare(env, rotation)?;
        Terms::of(&self.transport, &self.ctx, &self.lights[i].1, request)
    }

    /// `env` turned by `rotation` and prepared for the transport: its 6 N² Haar coefficients
    /// (the layout of [`crate::math::haar`]) and its SH coefficients at the baked order.
    pub fn light(&mut self, env: &Environment, rotation: EnvRotation) -> Result<&PreparedLight> {
        let i = self.prepare(env, rotation)?;
        Ok(&self.lights[i].1)
    }

    /// `env` turned by `rotation` resampled to the transport's cube, exactly as a relight takes
    /// it (6 faces of N x N texels, the layout of [`crate::math::cubemap`]).
    pub fn cube(&self, env: &Environment, rotation: EnvRotation) -> Result<CubeMap> {
        env.map().to_cube(self.ctx.n, rotation)
    }

    /// The weights of the transport's local lights after `--light`-style arguments
    /// (`NAME=SCALE`, `NAME=R,G,B`, `NAME@POS[=…]`), lights not named as the scene file says.
    pub fn light_args(&self, args: &[impl AsRef<str>]) -> Result<LightMix> {
        let lights = &self.transport.meta.lights;
        LightMix::new(
            lights,
            &crate::scene::light_mix::settings_from_args(lights, args)?,
        )
    }

    /// Relights `request` under `env` turned by `rotation`, plus the local `lights`. For a
    /// per-pixel bake this is the image of its view (with the environment behind where
    /// [`Relighter::with_background`] asks for it); a per-vertex bake's holds its vertex
    /// colours, which [`Relighter::draw`] draws.
    pub fn relight(
        &mut self,
        env: &Environment,
        request: &RelightRequest,
        rotation: EnvRotation,
        lights: &LightMix,
    ) -> Result<Image> {
        let i = self.prepare(env, rotation)?;
        let light = &self.lights[i].1;
        let (image, _) = Cpu(&self.transport).relight_with(&self.ctx, light, request, lights)?;
        match (self.background, &self.transport.attached.domain) {
            (Background::Environment, Domain::View) => {
                let t = &self.transport;
                let behind = environment_behind(&t.meta, &t.coverage, env.map(), rotation)?;
                Ok(composite(&image, &behind))
            }
            _ => Ok(image),
        }
    }

    /// Relights a per-vertex bake as [`Relighter::relight`] does and draws it as `camera` sees
    /// it (its textures and glossy terms included, 4 samples a pixel, as `prt relight --eye`
    /// draws); an error for a per-pixel bake, whose camera cannot move.
    pub fn draw(
        &mut self,
        env: &Environment,
        request: &RelightRequest,
        rotation: EnvRotation,
        lights: &LightMix,
        camera: &Camera,
    ) -> Result<Image> {
        vertex::mesh_of(&self.transport)?;
        // A per-vertex bake's relit image is its vertex colours, with nothing behind them.
        let relit = self.relight(env, request, rotation, lights)?;
        let light = self.lobe(Some(env), request, rotation)?;
        let behind = (self.background == Background::Environment).then_some((env.map(), rotation));
        let raster = vertex::draw_relit_lit(
            &self.transport,
            &relit,
            (light.as_ref(), &lights.weights),
            camera,
            behind,
            DRAW_SAMPLES,
        )?;
        Ok(raster.image)
    }

    /// The pixel whose rows are vertex `vertex`'s diffuse light in a per-vertex bake; an error
    /// for a per-pixel bake or a vertex out of range.
    pub fn vertex_pixel(&self, vertex: usize) -> Result<usize> {
        let mesh = vertex::mesh_of(&self.transport)?;
        if vertex >= mesh.vertex_count() {
            return Err(PrtError::invalid(
                "vertex",
                format!(
                    "{vertex}, but the bake has {} vertices",
                    mesh.vertex_count()
                ),
            ));
        }
        Ok(vertex)
    }

    /// Pixel `pixel`'s transport row as the relight takes it, dense: for each of the 6 N² Haar
    /// coefficients j, the RGB value that light coefficient j adds to the pixel per unit of
    /// light (the pixel's rows weighed by their albedo and sub-sample weights, as stored, so
    /// quantised unless the bake was lossless). The wavelet relight of a light L is
    /// `Σ_j row[j] · L[j]`, plus the local lights.
    pub fn row(&self, pixel: usize) -> Result<Vec<[f32; 3]>> {
        let t = &self.transport;
        let mut dense = vec![[0.0f64; 3]; t.coeff_count()];
        for r in self.rows_of(pixel)? {
            // The block that holds row r: blocks are in row order.
            let b = t.block_row_start.partition_point(|&s| s as usize <= r) - 1;
            let w = t.row_weight[r];
            for (j, d) in dense.iter_mut().enumerate() {
                if let Some((_, v)) = t.column(b, j).find(|&(row, _)| row == r) {
                    for k in 0..3 {
                        d[k] += w[k] as f64 * v as f64;
                    }
                }
            }
        }
        Ok(dense.iter().map(|d| d.map(|v| v as f32)).collect())
    }

    /// Pixel `pixel`'s SH transport row, n² RGB values at the baked order, weighed as
    /// [`Relighter::row`] is: the SH relight of a light of SH coefficients L is
    /// `Σ_i row[i] · L[i]`.
    pub fn sh_row(&self, pixel: usize) -> Result<Vec<[f32; 3]>> {
        let t = &self.transport;
        let shc = t.sh_count();
        let mut dense = vec![[0.0f64; 3]; shc];
        for r in self.rows_of(pixel)? {
            let w = t.row_weight[r];
            for (d, &v) in dense.iter_mut().zip(&t.sh[r * shc..(r + 1) * shc]) {
                for k in 0..3 {
                    d[k] += w[k] as f64 * v as f64;
                }
            }
        }
        Ok(dense.iter().map(|d| d.map(|v| v as f32)).collect())
    }

    /// The rows that light `pixel`, checked against the image.
    fn rows_of(&self, pixel: usize) -> Result<Vec<usize>> {
        let t = &self.transport;
        let pixels = t.meta.width as usize * t.meta.height as usize;
        if pixel >= pixels {
            return Err(PrtError::invalid(
                "pixel",
                format!(
                    "{pixel}, but the transport's image has {pixels} ({} x {})",
                    t.meta.width, t.meta.height
                ),
            ));
        }
        Ok((0..t.row_pixel.len())
            .filter(|&r| t.row_pixel[r] as usize == pixel)
            .collect())
    }

    /// The camera a per-vertex bake was made with: the scene's, at its image size.
    pub fn bake_camera(&self) -> Result<Camera> {
        vertex::bake_camera(&self.transport)
    }

    /// The bake's camera moved to look from `eye` at `target`, upright (its up +Y, as
    /// `prt relight --eye --target` moves it); same field of view and image size.
    pub fn camera_at(&self, eye: [f32; 3], target: [f32; 3]) -> Result<Camera> {
        Ok(vertex::moved_camera(
            &self.bake_camera()?,
            eye.into(),
            target.into(),
            None,
        ))
    }

    /// The index of `env`'s light under `rotation` in the kept lights, prepared when it is not
    /// kept (the least recently used one dropped to make room).
    fn prepare(&mut self, env: &Environment, rotation: EnvRotation) -> Result<usize> {
        let key = LightKey {
            environment: env.id,
            rotation,
        };
        match self.lights.iter().position(|(k, _)| *k == key) {
            Some(i) => {
                let kept = self.lights.remove(i);
                self.lights.push(kept);
            }
            None => {
                let light = self.ctx.prepare(&env.map, rotation)?;
                self.prepared += 1;
                if self.lights.len() >= KEPT_LIGHTS {
                    self.lights.remove(0);
                }
                self.lights.push((key, light));
            }
        }
        Ok(self.lights.len() - 1)
    }
}
