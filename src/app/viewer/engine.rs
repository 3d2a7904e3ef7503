//! The viewer's engine, apart from any window: a loaded transport, its environments and the
//! caches of prepared lights, relit on the CPU or the GPU back-end for every pane of a view
//! state; and the still images made from it (screenshots, saved views, error maps).

use crate::store::transport::Domain;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use super::*;
use crate::draw::background::{composite, environment_behind};
use crate::draw::raster::Raster;
use crate::draw::vertex::{self, bake_camera};
use crate::env::envmap::{EnvMap, EnvRotation, EnvSpec};
use crate::error::{PrtError, Result};
use crate::math::cube_pyramid::CubePyramid;
use crate::output::film::{Image, ToneMap};
use crate::output::metrics::relative_l2;
use crate::output::sheet::{ErrorImage, HeatScale};
use crate::relight::gpu::{Gpu, GpuBackend, GpuTransport};
use crate::relight::sh_transfer::ShTransfer;
use crate::relight::{Backend, LightContext, PreparedLight, RelightRequest, RelightStats, relight};
use crate::scene::Camera;
use crate::store::transport::Transport;

/// Called with a newly prepared light.
pub type OnLight<'a> = dyn FnMut(&LightShown) + 'a;

/// The prepared light and the `full` relight under it (the reference of the errors).
struct Lit {
    shown: LightShown,
    full: Image,
}

/// A map and its SH light, unturned, under the light context it was projected with.
type UnturnedSh = (Arc<EnvMap>, Arc<LightContext>, Arc<Vec<[f64; 3]>>);

/// A loaded transport, its environments and the caches behind [`Engine::render`].
pub struct Engine {
    /// The transport file.
    pub path: PathBuf,
    /// The transport, loaded.
    pub transport: Arc<Transport>,
    /// What the light side needs of it.
    pub ctx: Arc<LightContext>,
    /// The environment list.
    pub envs: Vec<EnvEntry>,
    maps: HashMap<PathBuf, Arc<EnvMap>>,
    /// The last map's SH light, unturned: a drag turns it rather than projecting the map again.
    unturned_sh: Option<UnturnedSh>,
    light: Option<Lit>,
    last: Option<(RelightKey, Vec<LinearPane>)>,
    /// The environment's part of the last relit panes, keyed with the local lights at their
    /// defaults: a change of the lights alone adds them again to these, and relights nothing.
    environment: Option<(RelightKey, Vec<LinearPane>)>,
    /// The camera a per-vertex bake was made with; `None` for a per-pixel bake.
    base_camera: Option<Camera>,
    /// The backdrop of the last per-vertex view: the camera and light it was drawn for.
    backdrop: Option<(Camera, LightKey, Image)>,
    gpu: Option<Gpu>,
    /// The transport on the attached GPU and its display path, once uploaded.
    display: Option<DisplayPath>,
    /// The SH glossy transfer matrices of a per-vertex bake with visibility, at the order last
    /// drawn with.
    transfer: Option<(usize, ShTransfer)>,
}

impl Engine {
    /// Loads a transport file; `envs` as on the command line (paths or `sun:ELEV,AZIM`).
    pub fn open(path: &Path, envs: Vec<EnvEntry>) -> Result<Engine> {
        Self::open_with_progress(path, envs, &|_, _| {})
    }

    /// [`Engine::open`], calling `progress(bytes read, file size)` while the file loads.
    pub fn open_with_progress(
        path: &Path,
        envs: Vec<EnvEntry>,
        progress: &dyn Fn(u64, u64),
    ) -> Result<Engine> {
        let transport = Transport::load_with_progress(path, progress)?;
        Self::from_transport(path, transport, envs)
    }

    /// An engine on a transport already loaded from `path`.
    pub fn from_transport(
        path: &Path,
        transport: Transport,
        envs: Vec<EnvEntry>,
    ) -> Result<Engine> {
        let ctx = LightContext::new(&transport)?;
        let base_camera = match transport.attached.domain {
            Domain::Mesh(_) => Some(bake_camera(&transport)?),
            Domain::View => None,
        };
        Ok(Engine {
            path: path.to_path_buf(),
            transport: Arc::new(transport),
            ctx: Arc::new(ctx),
            envs,
            maps: HashMap::new(),
            unturned_sh: None,
            light: None,
            last: None,
            environment: None,
            base_camera,
            backdrop: None,
            gpu: None,
            display: None,
            transfer: None,
        })
    }

    /// Lets [`DisplayState::gpu`](super::DisplayState::gpu) relight on `gpu` (the transport is uploaded on first use).
    pub fn attach_gpu(&mut self, gpu: Gpu) {
        self.gpu = Some(gpu);
        self.display = None;
        self.last = None;
        self.environment = None;
    }

    /// The attached GPU.
    pub fn gpu(&self) -> Option<&Gpu> {
        self.gpu.as_ref()
    }

    /// Name of the attached GPU adapter.
    pub fn gpu_name(&self) -> Option<&str> {
        self.gpu.as_ref().map(|g| g.adapter.as_str())
    }

    /// Relights `request` under the light of the last [`Engine::render`] into `view`, over the
    /// environment behind, and tone-maps it there as `state` says, on the attached GPU: what the
    /// window shows. A per-vertex bake is drawn from `state`'s camera.
    pub fn relight_to_view(
        &mut self,
        request: &RelightRequest,
        view: &mut GpuView,
        state: &ViewState,
    ) -> Result<GpuTiming> {
        self.upload()?;
        let camera = self.camera(state);
        let gpu = self.gpu.as_ref().ok_or_else(no_gpu)?;
        let lit = &self
            .light
            .as_ref()
            .ok_or_else(|| PrtError::invalid("view", "nothing rendered yet"))?
            .shown;
        let display = self.display.as_mut().ok_or_else(no_gpu)?;
        let frame = Frame {
            request,
            lights: &state.lights.mix(&self.transport.meta.lights)?,
            environment: state.lights.environment_shown(),
            camera: camera.as_ref(),
            tone: state.tone_map(),
        };
        display.draw(gpu, &self.transport, &self.ctx, lit, &frame, view)
    }

    fn upload(&mut self) -> Result<()> {
        let gpu = self.gpu.as_ref().ok_or_else(no_gpu)?;
        if self.display.is_none() {
            let gt = GpuTransport::upload(gpu, &self.transport, None)?;
            self.display = Some(DisplayPath::new(Arc::new(gt)));
        }
        Ok(())
    }

    fn relight_gpu(
        &mut self,
        light: &PreparedLight,
        req: &RelightRequest,
    ) -> Result<(Image, RelightStats)> {
        self.upload()?;
        let gpu = self.gpu.as_ref().ok_or_else(no_gpu)?;
        let gt = &self.display.as_ref().ok_or_else(no_gpu)?.transport;
        GpuBackend::new(gpu, gt, &self.transport)?.relight(&self.ctx, light, req)
    }

    /// What the transport and the environment list allow a state.
    pub fn limits(&self) -> Limits {
        Limits {
            coeffs: self.transport.coeff_count(),
            sh_order: self.ctx.sh_order,
            sh_light_order: crate::math::sh::MAX_LIGHT_ORDER
                .min((self.transport.coeff_count() as f64).sqrt() as usize),
            envs: self.envs.len(),
        }
    }

    /// The camera `state` looks through: a per-vertex bake's camera turned by
    /// [`ViewState::orbit`]; `None` for a per-pixel bake, whose view is fixed.
    pub fn camera(&self, state: &ViewState) -> Option<Camera> {
        self.base_camera.as_ref().map(|c| state.camera_of(c))
    }

    /// Width and height of the images shown: the bake's, or a per-vertex bake's camera's.
    pub fn view_size(&self) -> (usize, usize) {
        view_size(&self.transport)
    }

    /// A state that suits this file: the given environment, SH at the baked order, K as
    /// `prt relight` takes it ([`crate::app::cli::DEFAULT_TERMS`], at most 6 N²), exposure from
    /// the `full` image.
    pub fn initial_state(&mut self, light: LightState) -> ViewState {
        let limits = self.limits();
        let mut s = ViewState {
            light,
            lights: LightsState::of(&self.transport.meta.lights),
            ..ViewState::default()
        };
        s.relight.sh_order = limits.sh_order;
        s.relight.terms = s.relight.terms.min(limits.coeffs);
        s.clamp(limits);
        if let Ok(e) = self.auto_exposure(&s) {
            s.display.exposure = e;
        }
        s
    }

    /// The environment `state` shows: a file, or the procedural sun.
    pub fn env_spec(&self, state: &ViewState) -> EnvSpec {
        state.light.env_spec(&self.envs)
    }

    /// The prepared light of `state`, computing it (and the `full` image) when it changed;
    /// `on_light` sees a new light before the `full` relight starts. Returns the seconds spent on
    /// the light and on the `full` image.
    fn prepare_with(
        &mut self,
        state: &ViewState,
        on_light: &mut OnLight<'_>,
    ) -> Result<(f64, f64)> {
        let key = state.light.key(&self.envs);
        if self.light.as_ref().is_some_and(|l| l.shown.key == key) {
            return Ok((0.0, 0.0));
        }
        let start = Instant::now();
        let kept = key.file().and_then(|f| self.maps.get(f));
        let map = match kept {
            Some(m) => m.clone(),
            None => {
                let m = Arc::new(key.env.load()?);
                // Keep file maps; procedural suns change with every slider move.
                if let Some(f) = key.file() {
                    self.maps.insert(f.clone(), m.clone());
                }
                m
            }
        };
        let rotation = key.rotation;
        let light = Arc::new(self.prepare_light(&map, rotation)?);
        let behind = Arc::new(match self.base_camera {
            Some(_) => Image::new(0, 0),
            None => environment_behind(
                &self.transport.meta,
                &self.transport.coverage,
                &map,
                rotation,
            )?,
        });
        let light_seconds = start.elapsed().as_secs_f64();
        let shown = LightShown {
            key,
            light,
            behind,
            map,
        };
        on_light(&shown);
        let full_start = Instant::now();
        let (full, _) = relight(
            &self.transport,
            &self.ctx,
            &shown.light,
            &RelightRequest::Full,
        )?;
        self.light = Some(Lit { shown, full });
        self.last = None;
        self.environment = None;
        Ok((light_seconds, full_start.elapsed().as_secs_f64()))
    }

    /// [`LightContext::prepare`] of `map` under `rotation`, with the map's unturned SH light kept
    /// from the last call on the same map and context (a drag's), where `prepare` projects it
    /// every time.
    fn prepare_light(&mut self, map: &Arc<EnvMap>, rotation: EnvRotation) -> Result<PreparedLight> {
        if rotation == EnvRotation::default() {
            // Unturned, the light's SH is the map's.
            let light = self.ctx.prepare(map, rotation)?;
            self.unturned_sh = Some((map.clone(), self.ctx.clone(), Arc::new(light.sh.clone())));
            return Ok(light);
        }
        let unturned = match &self.unturned_sh {
            Some((kept, ctx, sh)) if Arc::ptr_eq(kept, map) && Arc::ptr_eq(ctx, &self.ctx) => {
                sh.clone()
            }
            _ => {
                let sh = Arc::new(self.ctx.prepare_sh(map)?);
                self.unturned_sh = Some((map.clone(), self.ctx.clone(), sh.clone()));
                sh
            }
        };
        self.ctx.prepare_turned(map, &unturned, rotation)
    }

    /// The light of the last render or exposure.
    pub fn current_light(&self) -> Option<LightShown> {
        self.light.as_ref().map(|l| l.shown.clone())
    }

    fn prepare(&mut self, state: &ViewState) -> Result<(f64, f64)> {
        self.prepare_with(state, &mut |_| {})
    }

    /// The exposure [`ToneMap::auto`] picks for what `state` shows: the `full` image under its
    /// light with its local lights added (the lights alone when the environment is off).
    pub fn auto_exposure(&mut self, state: &ViewState) -> Result<f32> {
        let mut s = state.clone();
        s.clamp(self.limits());
        s.lights.clamp(&self.transport.meta.lights);
        self.prepare(&s)?;
        let mut shown = self.light.as_ref().expect("prepared").full.clone();
        if !s.lights.environment_shown() {
            shown.pixels.fill([0.0; 3]);
        }
        let mix = s.lights.mix(&self.transport.meta.lights)?;
        crate::relight::columns::add_columns(
            &self.transport.attached.lights,
            &mix.weights,
            &mut shown.pixels,
        );
        let full = &shown;
        // A per-vertex bake is exposed for what its camera sees, not for every vertex (the
        // unlit undersides of two-sided surfaces among them).
        Ok(match self.camera(&s) {
            Some(camera) => {
                let lobe = self.lobe_light(&RelightRequest::Full, s.lights.environment_shown())?;
                self.make_transfer(s.display.sh_transfer)?;
                let drawn = self.draw_vertices(full, lobe.as_ref(), &camera, &s)?;
                ToneMap::auto(&drawn.image, Some(&drawn.coverage)).exposure
            }
            None => ToneMap::auto(full, None).exposure,
        })
    }

    /// Makes the SH glossy transfer matrices at `order` (a per-vertex bake with visibility;
    /// nothing otherwise), unless they are the last ones made.
    fn make_transfer(&mut self, order: Option<usize>) -> Result<()> {
        let Some(order) = order else {
            return Ok(());
        };
        let mesh = self.transport.mesh();
        let Some(vis) = mesh.and_then(|m| m.visibility.as_deref()) else {
            return Ok(());
        };
        if self.transfer.as_ref().is_none_or(|(o, _)| *o != order) {
            self.transfer = Some((order, ShTransfer::new(vis, order)?));
        }
        Ok(())
    }

    /// A per-vertex bake's `relit` vertex colours drawn from `camera`, its glossy light from
    /// `lobe` (the light's pyramid, for a bake with visibility) as `state` says: by SH glossy
    /// transfer at its order ([`Engine::make_transfer`] made the matrices), or the lobe per pixel.
    fn draw_vertices(
        &self,
        relit: &Image,
        lobe: Option<&CubePyramid>,
        camera: &Camera,
        state: &ViewState,
    ) -> Result<Raster> {
        let (t, samples) = (&self.transport, state.draw_samples());
        let mix = state.lights.mix(&t.meta.lights)?;
        let transfer = self
            .transfer
            .as_ref()
            .filter(|(order, _)| state.display.sh_transfer == Some(*order));
        match (transfer, lobe) {
            (Some((_, transfer)), Some(light)) => {
                let lights = (light, &mix.weights[..]);
                vertex::draw_sh_glossy(t, relit, lights, transfer, camera, None, samples)
            }
            _ => vertex::draw_relit_lit(t, relit, (lobe, &mix.weights), camera, None, samples),
        }
    }

    /// The light a per-vertex bake with visibility draws its glossy lobes from for `request`
    /// under the prepared light (dark where the environment is not `shown`); `None` for any
    /// other transport.
    fn lobe_light(&self, request: &RelightRequest, shown: bool) -> Result<Option<CubePyramid>> {
        let t = &self.transport;
        if t.mesh().is_none_or(|m| m.visibility.is_none()) {
            return Ok(None);
        }
        let light = self.light.as_ref().filter(|_| shown);
        crate::relight::lobe_light(t, &self.ctx, light.map(|l| &*l.shown.light), request)
    }

    fn relight_panes(
        &mut self,
        state: &ViewState,
        limits: Limits,
        light: &PreparedLight,
        full: &Image,
    ) -> Result<Vec<LinearPane>> {
        let mut panes = Vec::new();
        for (title, request) in state.requests(limits) {
            let start = Instant::now();
            let (image, stats) = if state.display.gpu && self.gpu.is_some() {
                self.relight_gpu(light, &request)?
            } else {
                relight(&self.transport, &self.ctx, light, &request)?
            };
            let relight_seconds = start.elapsed().as_secs_f64();
            // The numbers are the environment's; the local lights are added to what is shown.
            let rel_l2 = relative_l2(&image, full, None)?;
            panes.push(LinearPane {
                title,
                request,
                image,
                terms: stats.terms,
                nonzeros_touched: stats.nonzeros_touched,
                kernel_seconds: stats.kernel_seconds,
                relight_seconds,
                rel_l2,
            });
        }
        Ok(panes)
    }

    /// The environment's panes with the local lights of `state` added (the environment left out
    /// when it is off): the numbers stay the environment's; the time is the lights', and the
    /// environment's too when it was `relit` for this render.
    fn with_lights(
        &self,
        state: &ViewState,
        environment: &[LinearPane],
        relit: bool,
    ) -> Result<Vec<LinearPane>> {
        let mix = state.lights.mix(&self.transport.meta.lights)?;
        let mut panes = Vec::with_capacity(environment.len());
        for pane in environment {
            let start = Instant::now();
            let mut image = pane.image.clone();
            if !state.lights.environment_shown() {
                image.pixels.fill([0.0; 3]);
            }
            crate::relight::columns::add_columns(
                &self.transport.attached.lights,
                &mix.weights,
                &mut image.pixels,
            );
            image.check_finite("relit image")?;
            panes.push(LinearPane {
                image,
                relight_seconds: start.elapsed().as_secs_f64()
                    + if relit { pane.relight_seconds } else { 0.0 },
                ..pane.clone()
            });
        }
        Ok(panes)
    }

    /// Relights and tone-maps what `state` asks for. The same call serves the window, the
    /// screenshot and the tests.
    pub fn render(&mut self, state: &ViewState) -> Result<Rendered> {
        self.render_with(state, &mut |_| {})
    }

    /// [`Engine::render`], handing a newly prepared light to `on_light` as soon as it exists
    /// (before the CPU relights), so a GPU can draw it meanwhile.
    pub fn render_with(
        &mut self,
        state: &ViewState,
        on_light: &mut OnLight<'_>,
    ) -> Result<Rendered> {
        let mut state = state.clone();
        let limits = self.limits();
        let notes = state.clamp(limits);
        state.lights.clamp(&self.transport.meta.lights);
        let (light_seconds, full_seconds) = self.prepare_with(&state, on_light)?;
        let key = state.relight_key();
        let cached = self.last.as_ref().is_some_and(|(k, _)| *k == key);
        if !cached {
            let env_key = RelightKey {
                lights: LightsState::default(),
                ..key.clone()
            };
            let relit = !self
                .environment
                .as_ref()
                .is_some_and(|(k, _)| *k == env_key);
            if relit {
                // Taken out for the loop (the GPU path borrows the engine mutably), put back
                // after.
                let prepared = self.light.take().expect("prepared");
                let panes =
                    self.relight_panes(&state, limits, &prepared.shown.light, &prepared.full);
                self.light = Some(prepared);
                self.environment = Some((env_key, panes?));
            }
            let (_, environment) = self.environment.as_ref().expect("relit");
            let panes = self.with_lights(&state, environment, relit)?;
            self.last = Some((key, panes));
        }
        let tone = state.tone_map();
        let mut panes: Vec<Pane> = Vec::new();
        let mut errors: Vec<(LinearPane, ErrorImage)> = Vec::new();
        // One pane: its numbers, the relit image the error map compares with `full`, and the
        // image shown (over the environment behind the scene; the errors were taken before).
        let mut show = |linear: &LinearPane, relit: &Image, image: Image, full: &Image| {
            if state.display.error_map {
                let pane = LinearPane {
                    title: format!("error of {}", linear.title),
                    image: image.clone(),
                    ..linear.clone()
                };
                errors.push((pane, ErrorImage::of(relit, full)));
            }
            let linear = LinearPane {
                image,
                ..linear.clone()
            };
            panes.push(Pane {
                rgb: linear.image.to_srgb8(tone),
                linear,
            });
        };
        // With the environment off, nothing shows behind the scene.
        let behind = state.lights.environment_shown();
        match self.camera(&state) {
            Some(camera) => {
                let (drawn, full) = self.draw_panes(&state, &camera)?;
                for (linear, relit, image) in drawn {
                    let image = if behind { image } else { relit.clone() };
                    show(&linear, &relit, image, &full);
                }
            }
            None => {
                let (_, linear) = self.last.as_ref().expect("relit");
                let lit = self.light.as_ref().expect("prepared");
                for l in linear {
                    let image = match behind {
                        true => composite(&l.image, &lit.shown.behind),
                        false => l.image.clone(),
                    };
                    show(l, &l.image, image, &lit.full);
                }
            }
        }
        // One scale for every heat map, so that equal colours are equal errors.
        let heat = (!errors.is_empty())
            .then(|| HeatScale::of(&errors.iter().map(|(_, e)| e).collect::<Vec<_>>()));
        if let Some(scale) = heat {
            for (linear, error) in errors {
                panes.push(Pane {
                    rgb: error.heat_map(scale),
                    linear,
                });
            }
        }
        // A per-vertex bake's images are its camera's size, which the draw size sets.
        let (width, height) = match self.camera(&state) {
            Some(c) => (c.width as usize, c.height as usize),
            None => self.view_size(),
        };
        Ok(Rendered {
            width,
            height,
            panes,
            state,
            notes,
            light_seconds,
            full_seconds,
            heat,
        })
    }
}

impl Engine {
    /// A per-vertex bake's relit panes drawn from `camera`: for each pane its numbers (taken on
    /// the vertex colours), the drawn image and the drawn image over the backdrop; and `full`
    /// drawn from the same camera (the error map's reference).
    #[allow(clippy::type_complexity)]
    fn draw_panes(
        &mut self,
        state: &ViewState,
        camera: &Camera,
    ) -> Result<(Vec<(LinearPane, Image, Image)>, Image)> {
        // The light each pane's glossy lobes are drawn from (a bake with visibility), and the
        // full light's.
        let shown = state.lights.environment_shown();
        let (_, linear) = self.last.as_ref().expect("relit");
        let lobes = linear
            .iter()
            .map(|l| self.lobe_light(&l.request, shown))
            .collect::<Result<Vec<_>>>()?;
        let full_lobe = self.lobe_light(&RelightRequest::Full, shown)?;
        self.make_transfer(state.display.sh_transfer)?;
        let lit = self.light.as_ref().expect("prepared");
        if !self
            .backdrop
            .as_ref()
            .is_some_and(|(c, k, _)| c == camera && *k == lit.shown.key)
        {
            let image = backdrop(camera, &lit.shown.map, &lit.shown.key)?;
            self.backdrop = Some((camera.clone(), lit.shown.key.clone(), image));
        }
        let (_, _, back) = self.backdrop.as_ref().expect("drawn");
        let draw = |relit: &Image, lobe: &Option<CubePyramid>| -> Result<(Image, Image)> {
            let raster = self.draw_vertices(relit, lobe.as_ref(), camera, state)?;
            let mut over = raster.image.clone();
            for ((o, b), c) in over
                .pixels
                .iter_mut()
                .zip(&back.pixels)
                .zip(&raster.coverage)
            {
                for k in 0..3 {
                    o[k] += (1.0 - c) * b[k];
                }
            }
            Ok((raster.image, over))
        };
        let (_, linear) = self.last.as_ref().expect("relit");
        let mut panes = Vec::with_capacity(linear.len());
        for (l, lobe) in linear.iter().zip(&lobes) {
            let (drawn, over) = draw(&l.image, lobe)?;
            panes.push((l.clone(), drawn, over));
        }
        let full = if state.display.error_map {
            draw(&lit.full, &full_lobe)?.0
        } else {
            Image::new(0, 0)
        };
        Ok((panes, full))
    }
}

impl LinearPane {
    /// Its relative L2 error against `full` in percent, two decimals (`53.29%`), as every
    /// relative error is shown.
    pub fn rel_l2_percent(&self) -> String {
        format!("{:.2}%", 100.0 * self.rel_l2)
    }
}

/// Width and height of the images a viewer shows of `t`: the bake's, or for a per-vertex bake
/// its camera's.
pub fn view_size(t: &Transport) -> (usize, usize) {
    match &t.meta.per_vertex {
        Some(pv) => (pv.image[0] as usize, pv.image[1] as usize),
        None => (t.meta.width as usize, t.meta.height as usize),
    }
}

/// Writes what `state` shows as `stem.png` (tone-mapped, side by side) and the first image as
/// `stem.exr` (linear radiance).
pub fn save_view(engine: &mut Engine, state: &ViewState, stem: &Path) -> Result<()> {
    let r = screenshot(engine, state, &stem.with_extension("png"))?;
    let first = r
        .panes
        .first()
        .ok_or_else(|| PrtError::invalid("view", "nothing to save"))?;
    first
        .linear
        .image
        .save(&stem.with_extension("exr"), ToneMap::default())
}

/// Renders `state` as the window would show it and writes it as a PNG, each image under a
/// caption with its title (as the window shows them).
pub fn screenshot(engine: &mut Engine, state: &ViewState, out: &Path) -> Result<Rendered> {
    let r = engine.render(state)?;
    for p in &r.panes {
        p.linear.image.check_finite(&p.linear.title)?;
    }
    let (w, h, rgb) = r.captioned(4);
    crate::output::film::write_png(out, w, h, &rgb)?;
    Ok(r)
}

fn no_gpu() -> PrtError {
    PrtError::Gpu("no GPU attached to the viewer".into())
}
