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
use std::sync::atomic::{AtomicU64, Ordering};

/// Bakes a scene in memory: [`crate::bake::bake_with`], with progress and cancellation.
pub use crate::bake::bake_with as bake;
pub use crate::bake::{BakeProgress, BakeSettings, Cancel};
pub use crate::env::envmap::{EnvMap, EnvRotation};
pub use crate::env::select::Weighting;
pub use crate::output::film::Image;
pub use crate::output::metrics::ErrorReport;
pub use crate::relight::background::Background;
pub use crate::relight::{LightMix, LightSetting, RelightRequest};
pub use crate::scene::{Camera, Framing, Scene};
pub use crate::store::transport::{BakeDomain, Transport, TransportMeta};

use crate::env::envmap::check_env_size;
use crate::error::{PrtError, Result};
use crate::relight::background::{composite, environment_behind};
use crate::relight::raster::DRAW_SAMPLES;
use crate::relight::vertex::{self, GlossEval};
use crate::relight::{Backend, Cpu, LightContext, PreparedLight};
use crate::store::transport::Domain;

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
/// Returns the file's metadata.
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

/// What messages call an environment made from an array.
const ARRAY: &str = "array";

/// Numbers the environments, so that a [`Relighter`] knows one it has prepared.
static NEXT_ENVIRONMENT: AtomicU64 = AtomicU64::new(0);

/// A lat-long environment map ready to light with: loaded, checked, and shared by its clones.
/// A [`Relighter`] prepares each environment once per rotation, so relight many times with the
/// same value (or its clones) rather than making it again.
#[derive(Clone, Debug)]
pub struct Environment {
    map: Arc<EnvMap>,
    id: u64,
}

impl Environment {
    /// A map already made (its pixels as they are).
    pub fn from_map(map: EnvMap) -> Environment {
        Environment {
            map: Arc::new(map),
            id: NEXT_ENVIRONMENT.fetch_add(1, Ordering::Relaxed),
        }
    }

    /// An OpenEXR or Radiance HDR lat-long file. NaN or infinite pixels are an error; negative
    /// ones (lossy compression leaves a few) are clamped to 0 ([`EnvMap::negatives_clamped`]).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Environment> {
        EnvMap::load(path.as_ref()).map(Environment::from_map)
    }

    /// What `--env` takes: a file, a map bundled in the binary by name (`blender_sunrise`), or
    /// the procedural sun and sky as `sun:ELEV,AZIM[,RADIUS]`.
    pub fn from_spec(spec: &str) -> Result<Environment> {
        EnvMap::from_spec(spec).map(Environment::from_map)
    }

    /// The procedural sun and sky with the sun `elevation_deg` above the horizon (-90 to 90)
    /// and `azimuth_deg` round from −Z towards +X, as `sun:ELEV,AZIM` gives it.
    pub fn sun(elevation_deg: f64, azimuth_deg: f64) -> Result<Environment> {
        // Rust writes an f64 so that it reads back the same.
        Environment::from_spec(&format!("sun:{elevation_deg},{azimuth_deg}"))
    }

    /// A lat-long map of `width` x `height` pixels, rows from the zenith down, linear RGB
    /// radiance. Checked as a file is (sizes from 1 to [`crate::env::envmap::MAX_ENV_SIDE`],
    /// finite values, some light), with `width · height` pixels, none of them negative.
    pub fn from_array(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Result<Environment> {
        check_env_size(Path::new(ARRAY), width, height)?;
        if pixels.len() != width * height {
            return Err(PrtError::file(
                ARRAY,
                format!(
                    "{} pixels for a {width} x {height} map, which takes {}",
                    pixels.len(),
                    width * height
                ),
            ));
        }
        let negative = pixels.iter().enumerate().find_map(|(i, p)| {
            let c = p.iter().position(|v| *v < 0.0)?;
            Some((i, c, p[c]))
        });
        if let Some((i, c, v)) = negative {
            return Err(PrtError::file(
                ARRAY,
                format!(
                    "pixel (x = {}, y = {}) channel {} is {v}: radiance must not be negative",
                    i % width,
                    i / width,
                    ["R", "G", "B"][c]
                ),
            ));
        }
        let map = EnvMap::from_pixels(width, height, pixels, ARRAY)?;
        let power: f64 = map.power().iter().sum();
        if power.is_nan() || power <= 0.0 {
            return Err(PrtError::file(
                ARRAY,
                format!(
                    "the map's power (Σ L Ω over its pixels) is {power:.4e}: it lights nothing"
                ),
            ));
        }
        Ok(Environment::from_map(map))
    }

    /// The map.
    pub fn map(&self) -> &EnvMap {
        &self.map
    }

    /// Where it came from: a file, a bundled map, the sun's description or "array".
    pub fn source(&self) -> &str {
        &self.map.source
    }
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
        match (self.background, &self.transport.domain) {
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
        let behind = (self.background == Background::Environment).then_some((env.map(), rotation));
        let raster = vertex::draw_relit(
            &self.transport,
            &relit,
            camera,
            behind,
            DRAW_SAMPLES,
            GlossEval::default(),
        )?;
        Ok(raster.image)
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
