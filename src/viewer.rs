//! The interactive viewer (`prt view`): eframe on egui-wgpu, sharing its wgpu device with the
//! relight kernels of [`crate::gpu`].
//!
//! The rendering core is [`Engine::render`]: a function from a [`ViewState`] to the tone-mapped
//! panes the window shows (one, or SH and wavelet side by side). The window, the keyboard and the
//! `--screenshot` mode all go through it; the engine only caches what does not change between
//! calls (loaded maps, the prepared light, the `full` relight used as the error reference, the
//! last linear images so an exposure change only re-tone-maps).

mod gpu_view;

pub use gpu_view::GpuView;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use crate::envmap::{EnvMap, EnvRotation};
use crate::film::{Image, ToneMap};
use crate::gpu::{Gpu, GpuTransport};
use crate::light::Weighting;
use crate::metrics::relative_l2;
use crate::relight::{
    LightContext, Method, PreparedLight, RelightRequest, RelightStats, light_sh_order, relight,
    select_light,
};
use crate::transport::Transport;
use eframe::{egui, wgpu};

/// Where the bundled environment maps are looked for: `$PRT_ENVMAPS`, else the checkout this
/// binary was built from, else `assets/envmaps` under the working directory.
pub fn bundled_env_dir() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("PRT_ENVMAPS").map(PathBuf::from),
        Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/envmaps")),
        Some(PathBuf::from("assets/envmaps")),
    ];
    candidates.into_iter().flatten().find(|d| d.is_dir())
}

/// Where an environment comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvSource {
    /// A lat-long EXR or HDR file.
    File(PathBuf),
    /// The procedural sun and sky, placed by [`ViewState::sun_elev`] and [`ViewState::sun_azim`].
    Sun,
}

/// One entry of the environment list.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvEntry {
    pub name: String,
    pub source: EnvSource,
}

/// The environment list: the bundled maps, then the files given on the command line, then the
/// procedural sun. Returns the list, the sun's initial (elevation, azimuth) and the entry to
/// select first (the first command-line environment, else the first bundled map).
pub fn env_entries(cli: &[String]) -> (Vec<EnvEntry>, (f64, f64), usize) {
    let mut entries = Vec::new();
    if let Some(dir) = bundled_env_dir()
        && let Ok(read) = std::fs::read_dir(&dir)
    {
        let mut files: Vec<PathBuf> = read
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                matches!(
                    p.extension()
                        .and_then(|e| e.to_str())
                        .map(str::to_ascii_lowercase)
                        .as_deref(),
                    Some("exr" | "hdr")
                )
            })
            .collect();
        files.sort();
        for p in files {
            let name = p
                .file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            entries.push(EnvEntry {
                name,
                source: EnvSource::File(p),
            });
        }
    }
    let mut sun = (30.0, 45.0);
    let mut first_cli = None;
    let mut sun_given = false;
    for spec in cli {
        if let Some(args) = spec.strip_prefix("sun:") {
            let nums: Vec<f64> = args
                .split(',')
                .filter_map(|v| v.trim().parse().ok())
                .collect();
            if nums.len() >= 2 && !sun_given {
                sun = (nums[0].clamp(-90.0, 90.0), nums[1]);
                sun_given = true;
            }
            first_cli.get_or_insert(usize::MAX);
        } else {
            let p = PathBuf::from(spec);
            let name = p
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            first_cli.get_or_insert(entries.len());
            entries.push(EnvEntry {
                name,
                source: EnvSource::File(p),
            });
        }
    }
    let sun_index = entries.len();
    entries.push(EnvEntry {
        name: "sun (procedural)".into(),
        source: EnvSource::Sun,
    });
    let selected = match first_cli {
        Some(usize::MAX) => sun_index,
        Some(i) => i,
        None => 0,
    };
    (entries, sun, selected)
}

/// Every input of the displayed image.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewState {
    pub method: Method,
    /// Kept wavelet terms K (1 to 6 N²).
    pub terms: usize,
    pub weighting: Weighting,
    /// SH order n (1 to the baked order).
    pub sh_order: usize,
    /// Index into the environment list.
    pub env: usize,
    /// Procedural sun elevation and azimuth, degrees.
    pub sun_elev: f64,
    pub sun_azim: f64,
    /// Environment rotation, degrees.
    pub yaw: f64,
    pub pitch: f64,
    /// Exposure in stops.
    pub exposure: f32,
    /// SH and wavelet side by side at the same term count.
    pub compare: bool,
    /// Show, beside each image, its error against `full` as a heat map.
    pub error_map: bool,
    /// Take the image from the GPU kernels, when a GPU is attached: in the window they write
    /// straight into a texture (the numbers still come from the CPU relight); in
    /// [`Engine::render`] the image is read back.
    pub gpu: bool,
}

impl Default for ViewState {
    fn default() -> Self {
        ViewState {
            method: Method::Wavelet,
            terms: 64,
            weighting: Weighting::Transport,
            sh_order: 4,
            env: 0,
            sun_elev: 30.0,
            sun_azim: 45.0,
            yaw: 0.0,
            pitch: 0.0,
            exposure: 0.0,
            compare: false,
            error_map: false,
            gpu: false,
        }
    }
}

/// What a transport and the environment list allow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// 6 N².
    pub coeffs: usize,
    /// Baked SH order.
    pub sh_order: usize,
    /// Entries in the environment list.
    pub envs: usize,
}

impl ViewState {
    /// Brings every field into range; returns a note for each field that was out of range.
    pub fn clamp(&mut self, limits: Limits) -> Vec<String> {
        let mut notes = Vec::new();
        if self.terms == 0 || self.terms > limits.coeffs {
            let k = self.terms.clamp(1, limits.coeffs.max(1));
            notes.push(format!(
                "terms {} clamped to {k} (1 to 6N² = {})",
                self.terms, limits.coeffs
            ));
            self.terms = k;
        }
        if self.sh_order == 0 || self.sh_order > limits.sh_order {
            let n = self.sh_order.clamp(1, limits.sh_order.max(1));
            notes.push(format!(
                "SH order {} clamped to {n} (this file was baked up to order {})",
                self.sh_order, limits.sh_order
            ));
            self.sh_order = n;
        }
        if self.env >= limits.envs {
            notes.push(format!(
                "environment {} does not exist; using the first",
                self.env
            ));
            self.env = 0;
        }
        if !(-90.0..=90.0).contains(&self.sun_elev) {
            self.sun_elev = self.sun_elev.clamp(-90.0, 90.0);
        }
        if !self.sun_azim.is_finite() {
            self.sun_azim = 0.0;
        }
        notes
    }

    /// Next method in the cycle wavelet → SH → full.
    pub fn cycle_method(&mut self) {
        self.method = match self.method {
            Method::Wavelet => Method::Sh,
            Method::Sh => Method::Full,
            Method::Full => Method::Wavelet,
        };
    }

    /// The panes this state shows: the requests and their titles.
    pub fn requests(&self, limits: Limits) -> Vec<(String, RelightRequest)> {
        let base = RelightRequest {
            method: self.method,
            terms: self.terms,
            weighting: self.weighting,
            sh_order: self.sh_order,
        };
        if self.compare {
            let n = sh_order_for_terms(self.terms, limits.sh_order);
            vec![
                (
                    format!("SH order {n} ({} terms)", n * n),
                    RelightRequest {
                        method: Method::Sh,
                        sh_order: n,
                        ..base
                    },
                ),
                (
                    format!("wavelet, {} terms", self.terms),
                    RelightRequest {
                        method: Method::Wavelet,
                        ..base
                    },
                ),
            ]
        } else {
            let title = match self.method {
                Method::Wavelet => {
                    format!("wavelet, {} terms ({})", self.terms, self.weighting.name())
                }
                Method::Sh => format!(
                    "SH order {} ({} terms)",
                    self.sh_order,
                    self.sh_order.pow(2)
                ),
                Method::Full => format!("full ({} terms)", limits.coeffs),
            };
            vec![(title, base)]
        }
    }

    /// Everything but the exposure: what the linear images depend on.
    fn relight_key(&self) -> ViewState {
        ViewState {
            exposure: 0.0,
            error_map: false,
            ..self.clone()
        }
    }
}

/// The SH order whose n² terms are nearest to `terms`, within 1 and the baked order.
pub fn sh_order_for_terms(terms: usize, baked: usize) -> usize {
    let n = (terms as f64).sqrt().round() as usize;
    n.clamp(1, baked.max(1))
}

/// One relit view before tone mapping.
#[derive(Clone, Debug)]
pub struct LinearPane {
    pub title: String,
    pub request: RelightRequest,
    pub image: Image,
    /// Light terms used.
    pub terms: usize,
    /// Kernel time and the whole relight call, seconds.
    pub kernel_seconds: f64,
    pub relight_seconds: f64,
    /// Relative L2 error against `full`.
    pub rel_l2: f64,
}

/// One displayed view.
#[derive(Clone, Debug)]
pub struct Pane {
    pub linear: LinearPane,
    /// 8-bit sRGB, RGB interleaved, `width · height · 3` bytes.
    pub rgb: Vec<u8>,
}

/// What [`Engine::render`] returns.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub width: usize,
    pub height: usize,
    pub panes: Vec<Pane>,
    /// The state after clamping, and what was clamped.
    pub state: ViewState,
    pub notes: Vec<String>,
    /// Time spent preparing the light in this call (0 when cached), seconds.
    pub light_seconds: f64,
}

impl Rendered {
    /// The panes side by side with a `gap`-pixel black gutter, as one RGB8 image.
    pub fn side_by_side(&self, gap: usize) -> (usize, usize, Vec<u8>) {
        let n = self.panes.len();
        let w = self.width * n + gap * n.saturating_sub(1);
        let h = self.height;
        let mut out = vec![0u8; w * h * 3];
        for (i, pane) in self.panes.iter().enumerate() {
            let x0 = i * (self.width + gap);
            for y in 0..h {
                let src = &pane.rgb[y * self.width * 3..(y + 1) * self.width * 3];
                let d = (y * w + x0) * 3;
                out[d..d + src.len()].copy_from_slice(src);
            }
        }
        (w, h, out)
    }
}

#[derive(Clone, Debug, PartialEq)]
struct LightKey {
    spec: String,
    yaw: f64,
    pitch: f64,
}

/// A loaded transport, its environments and the caches behind [`Engine::render`].
pub struct Engine {
    pub path: PathBuf,
    pub transport: Transport,
    pub ctx: LightContext,
    pub envs: Vec<EnvEntry>,
    maps: HashMap<String, Arc<EnvMap>>,
    light: Option<(LightKey, PreparedLight, Image)>,
    last: Option<(ViewState, Vec<LinearPane>)>,
    gpu: Option<Gpu>,
    gpu_transport: Option<GpuTransport>,
}

impl Engine {
    /// Loads a transport file; `envs` as on the command line (paths or `sun:ELEV,AZIM`).
    pub fn open(path: &Path, envs: Vec<EnvEntry>) -> Result<Engine, String> {
        let transport = Transport::load(path).map_err(|e| e.to_string())?;
        let ctx = LightContext::new(&transport).map_err(|e| e.to_string())?;
        Ok(Engine {
            path: path.to_path_buf(),
            transport,
            ctx,
            envs,
            maps: HashMap::new(),
            light: None,
            last: None,
            gpu: None,
            gpu_transport: None,
        })
    }

    /// Lets [`ViewState::gpu`] relight on `gpu` (the transport is uploaded on first use).
    pub fn attach_gpu(&mut self, gpu: Gpu) {
        self.gpu = Some(gpu);
        self.gpu_transport = None;
        self.last = None;
    }

    /// The attached GPU.
    pub fn gpu(&self) -> Option<&Gpu> {
        self.gpu.as_ref()
    }

    /// Name of the attached GPU adapter.
    pub fn gpu_name(&self) -> Option<&str> {
        self.gpu.as_ref().map(|g| g.adapter.as_str())
    }

    /// Relights `request` under the light of the last [`Engine::render`] into `view` and
    /// tone-maps it there with `exposure`, on the attached GPU. Returns the wall time until the
    /// GPU finished, seconds.
    pub fn relight_to_view(
        &mut self,
        request: &RelightRequest,
        view: &GpuView,
        exposure: f32,
    ) -> Result<f64, String> {
        let gpu = self.gpu.as_ref().ok_or("no GPU attached")?;
        let (_, light, _) = self.light.as_ref().ok_or("nothing rendered yet")?;
        if self.gpu_transport.is_none() {
            self.gpu_transport =
                Some(GpuTransport::upload(gpu, &self.transport, None).map_err(|e| e.to_string())?);
        }
        let gt = self.gpu_transport.as_ref().expect("uploaded");
        let start = Instant::now();
        match request.method {
            Method::Wavelet | Method::Full => {
                let sparse = select_light(&self.transport, &self.ctx, light, request)
                    .map_err(|e| e.to_string())?;
                gt.relight_wavelet_to_texture(gpu, &sparse, &view.linear)
            }
            Method::Sh => {
                let sh = light_sh_order(&light.sh, request.sh_order, self.ctx.sh_order)
                    .map_err(|e| e.to_string())?;
                gt.relight_sh_to_texture(gpu, &sh, &view.linear)
            }
        }
        .map_err(|e| e.to_string())?;
        view.tone_map(&gpu.device, &gpu.queue, exposure);
        gpu.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .map_err(|e| e.to_string())?;
        Ok(start.elapsed().as_secs_f64())
    }

    fn relight_gpu(
        &mut self,
        light: &PreparedLight,
        req: &RelightRequest,
    ) -> Result<(Image, RelightStats), String> {
        let gpu = self.gpu.as_ref().ok_or("no GPU attached")?;
        if self.gpu_transport.is_none() {
            self.gpu_transport =
                Some(GpuTransport::upload(gpu, &self.transport, None).map_err(|e| e.to_string())?);
        }
        let gt = self.gpu_transport.as_ref().expect("uploaded");
        let t = &self.transport;
        let out = match req.method {
            Method::Wavelet | Method::Full => {
                let sparse = select_light(t, &self.ctx, light, req).map_err(|e| e.to_string())?;
                gt.relight_wavelet(gpu, &sparse)
            }
            Method::Sh => {
                let sh = light_sh_order(&light.sh, req.sh_order, self.ctx.sh_order)
                    .map_err(|e| e.to_string())?;
                gt.relight_sh(gpu, &sh)
            }
        };
        out.map_err(|e| e.to_string())
    }

    pub fn limits(&self) -> Limits {
        Limits {
            coeffs: self.transport.coeff_count(),
            sh_order: self.ctx.sh_order,
            envs: self.envs.len(),
        }
    }

    /// A state that suits this file: the given environment, SH at the baked order, K = 1% of
    /// 6 N² (at least 16), exposure from the `full` image.
    pub fn initial_state(&mut self, env: usize, sun: (f64, f64)) -> ViewState {
        let limits = self.limits();
        let mut s = ViewState {
            env,
            sun_elev: sun.0,
            sun_azim: sun.1,
            sh_order: limits.sh_order,
            terms: (limits.coeffs / 100).max(16).min(limits.coeffs),
            ..ViewState::default()
        };
        s.clamp(limits);
        if let Ok(e) = self.auto_exposure(&s) {
            s.exposure = e;
        }
        s
    }

    /// The environment spec of entry `i` under `state` (a path, or `sun:ELEV,AZIM`).
    pub fn env_spec(&self, state: &ViewState) -> String {
        match &self.envs[state.env].source {
            EnvSource::File(p) => p.display().to_string(),
            EnvSource::Sun => format!("sun:{:.2},{:.2}", state.sun_elev, state.sun_azim),
        }
    }

    fn prepare(&mut self, state: &ViewState) -> Result<f64, String> {
        let key = LightKey {
            spec: self.env_spec(state),
            yaw: state.yaw,
            pitch: state.pitch,
        };
        if self.light.as_ref().is_some_and(|(k, _, _)| *k == key) {
            return Ok(0.0);
        }
        let start = Instant::now();
        let map = match self.maps.get(&key.spec) {
            Some(m) => m.clone(),
            None => {
                let m = Arc::new(EnvMap::from_spec(&key.spec).map_err(|e| e.to_string())?);
                // Keep file maps; procedural suns change with every slider move.
                if !key.spec.starts_with("sun:") {
                    self.maps.insert(key.spec.clone(), m.clone());
                }
                m
            }
        };
        let rotation = EnvRotation {
            yaw_deg: key.yaw,
            pitch_deg: key.pitch,
        };
        let light = self
            .ctx
            .prepare(&map, rotation)
            .map_err(|e| e.to_string())?;
        let full_req = RelightRequest {
            method: Method::Full,
            terms: 0,
            weighting: Weighting::Unweighted,
            sh_order: 1,
        };
        let (full, _) =
            relight(&self.transport, &self.ctx, &light, &full_req).map_err(|e| e.to_string())?;
        self.light = Some((key, light, full));
        self.last = None;
        Ok(start.elapsed().as_secs_f64())
    }

    /// The exposure [`ToneMap::auto`] picks for the `full` image under `state`'s light.
    pub fn auto_exposure(&mut self, state: &ViewState) -> Result<f32, String> {
        let mut s = state.clone();
        s.clamp(self.limits());
        self.prepare(&s)?;
        let (_, _, full) = self.light.as_ref().expect("prepared");
        Ok(ToneMap::auto(full, None).exposure)
    }

    fn relight_panes(
        &mut self,
        state: &ViewState,
        limits: Limits,
        light: &PreparedLight,
        full: &Image,
    ) -> Result<Vec<LinearPane>, String> {
        let mut panes = Vec::new();
        for (title, request) in state.requests(limits) {
            let start = Instant::now();
            let (image, stats) = if state.gpu && self.gpu.is_some() {
                self.relight_gpu(light, &request)?
            } else {
                relight(&self.transport, &self.ctx, light, &request).map_err(|e| e.to_string())?
            };
            let relight_seconds = start.elapsed().as_secs_f64();
            let rel_l2 = relative_l2(&image, full, None).map_err(|e| e.to_string())?;
            panes.push(LinearPane {
                title,
                request,
                image,
                terms: stats.terms,
                kernel_seconds: stats.kernel_seconds,
                relight_seconds,
                rel_l2,
            });
        }
        Ok(panes)
    }

    /// Relights and tone-maps what `state` asks for. The same call serves the window, the
    /// screenshot and the tests.
    pub fn render(&mut self, state: &ViewState) -> Result<Rendered, String> {
        let mut state = state.clone();
        let limits = self.limits();
        let notes = state.clamp(limits);
        let light_seconds = self.prepare(&state)?;
        let key = state.relight_key();
        let cached = self.last.as_ref().is_some_and(|(k, _)| *k == key);
        if !cached {
            // Taken out for the loop (the GPU path borrows the engine mutably), put back after.
            let prepared = self.light.take().expect("prepared");
            let panes = self.relight_panes(&state, limits, &prepared.1, &prepared.2);
            self.light = Some(prepared);
            self.last = Some((key, panes?));
        }
        let (_, linear) = self.last.as_ref().expect("relit");
        let tone = ToneMap {
            exposure: state.exposure,
        };
        let mut panes: Vec<Pane> = linear
            .iter()
            .map(|l| Pane {
                rgb: l.image.to_srgb8(tone),
                linear: l.clone(),
            })
            .collect();
        if state.error_map
            && let Some((_, _, full)) = &self.light
        {
            let maps: Vec<Pane> = panes
                .iter()
                .map(|p| Pane {
                    rgb: error_heat_map(&p.linear.image, full, ERROR_MAP_GAIN),
                    linear: LinearPane {
                        title: format!("error of {} x{ERROR_MAP_GAIN}", p.linear.title),
                        ..p.linear.clone()
                    },
                })
                .collect();
            panes.extend(maps);
        }
        Ok(Rendered {
            width: self.transport.meta.width as usize,
            height: self.transport.meta.height as usize,
            panes,
            state,
            notes,
            light_seconds,
        })
    }
}

/// Writes what `state` shows as `stem.png` (tone-mapped, side by side) and the first image as
/// `stem.exr` (linear radiance).
pub fn save_view(engine: &mut Engine, state: &ViewState, stem: &Path) -> Result<(), String> {
    let r = screenshot(engine, state, &stem.with_extension("png"))?;
    let first = r.panes.first().ok_or("nothing to save")?;
    first
        .linear
        .image
        .save(&stem.with_extension("exr"), ToneMap::default())
        .map_err(|e| e.to_string())
}

/// How much the error heat map magnifies: a difference of 1/10 of the image's mean luminance
/// shows at full heat.
pub const ERROR_MAP_GAIN: f32 = 10.0;

/// |image − full| in luminance, over the mean luminance of `full`, times `gain`, as a black →
/// red → yellow → white heat map (RGB8).
pub fn error_heat_map(image: &Image, full: &Image, gain: f32) -> Vec<u8> {
    let lum = |p: &[f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    let lit: Vec<f32> = full.pixels.iter().map(lum).filter(|l| *l > 0.0).collect();
    let mean = if lit.is_empty() {
        1.0
    } else {
        lit.iter().sum::<f32>() / lit.len() as f32
    };
    image
        .pixels
        .iter()
        .zip(&full.pixels)
        .flat_map(|(a, b)| {
            let e = ((lum(a) - lum(b)).abs() / mean * gain).clamp(0.0, 1.0);
            let ramp = |lo: f32| ((3.0 * e - lo).clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            [ramp(0.0), ramp(1.0), ramp(2.0)]
        })
        .collect()
}

/// Renders `state` as the window would show it and writes it as a PNG.
pub fn screenshot(engine: &mut Engine, state: &ViewState, out: &Path) -> Result<Rendered, String> {
    let r = engine.render(state)?;
    let (w, h, rgb) = r.side_by_side(4);
    crate::film::write_png(out, w, h, &rgb).map_err(|e| e.to_string())?;
    Ok(r)
}

/// The window.
pub struct ViewerApp {
    /// The loaded file, or why it could not be loaded.
    pub engine: Result<Engine, String>,
    pub state: ViewState,
    /// The last error of a render (a bad environment file, ...).
    pub error: Option<String>,
    /// Notes from clamping the state.
    pub notes: Vec<String>,
    shown: Option<ViewState>,
    textures: Vec<egui::TextureHandle>,
    info: Vec<LinearPane>,
    size: [usize; 2],
    light_seconds: f64,
    path_edit: String,
    /// Where "Save" writes: a `.png` (what is shown) and an `.exr` (the first image, linear).
    pub save_stem: String,
    cli_envs: Vec<String>,
    /// The window's wgpu device, queue and adapter name, for GPU relighting.
    device: Option<(wgpu::Device, wgpu::Queue, String)>,
    /// The window's renderer, to draw GPU textures.
    render_state: Option<eframe::egui_wgpu::RenderState>,
    gpu_views: Vec<(GpuView, egui::TextureId)>,
    /// GPU relight + tone-map time of each pane shown from the GPU.
    gpu_seconds: Vec<f64>,
}

impl ViewerApp {
    /// Opens `file`; a file that does not load leaves a message for the window.
    pub fn new(file: &Path, envs: &[String]) -> ViewerApp {
        let mut app = ViewerApp {
            engine: Err(String::new()),
            state: ViewState::default(),
            error: None,
            notes: Vec::new(),
            shown: None,
            textures: Vec::new(),
            info: Vec::new(),
            size: [0, 0],
            light_seconds: 0.0,
            path_edit: file.display().to_string(),
            save_stem: "prt-view".to_string(),
            cli_envs: envs.to_vec(),
            device: None,
            render_state: None,
            gpu_views: Vec::new(),
            gpu_seconds: Vec::new(),
        };
        app.open(file);
        app
    }

    fn open(&mut self, file: &Path) {
        let (entries, sun, selected) = env_entries(&self.cli_envs);
        self.engine = Engine::open(file, entries);
        self.shown = None;
        self.error = None;
        self.textures.clear();
        self.gpu_seconds.clear();
        self.info.clear();
        if let Ok(engine) = &mut self.engine {
            self.state = engine.initial_state(selected, sun);
        }
        self.connect_gpu();
    }

    /// Shares a wgpu device (the window's) with the relight kernels; the side panel then offers
    /// GPU relighting.
    pub fn attach_device(&mut self, device: wgpu::Device, queue: wgpu::Queue, name: String) {
        self.device = Some((device, queue, name));
        self.connect_gpu();
    }

    /// Uses the window's wgpu device for relighting and draws GPU results without a readback.
    pub fn attach_render_state(&mut self, rs: eframe::egui_wgpu::RenderState) {
        let info = rs.adapter.get_info();
        let name = format!("{} ({:?}, {})", info.name, info.backend, info.driver);
        self.attach_device(rs.device.clone(), rs.queue.clone(), name);
        self.render_state = Some(rs);
        // The window draws from the GPU kernels by default; the box in the panel turns it off.
        self.state.gpu = true;
    }

    fn connect_gpu(&mut self) {
        if let (Ok(engine), Some((device, queue, name))) = (&mut self.engine, &self.device) {
            match Gpu::from_device(device.clone(), queue.clone(), name.clone()) {
                Ok(gpu) => engine.attach_gpu(gpu),
                Err(e) => self.error = Some(e.to_string()),
            }
        }
    }

    /// Keyboard shortcuts: `M` method, `+`/`-` terms, `E` environment.
    fn keys(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let (m, plus, minus, e) = ctx.input(|i| {
            (
                i.key_pressed(egui::Key::M),
                i.key_pressed(egui::Key::Plus) || i.key_pressed(egui::Key::Equals),
                i.key_pressed(egui::Key::Minus),
                i.key_pressed(egui::Key::E),
            )
        });
        if m {
            self.state.cycle_method();
        }
        if plus {
            self.state.terms = self.state.terms.saturating_mul(2);
        }
        if minus {
            self.state.terms = (self.state.terms / 2).max(1);
        }
        if e && let Ok(engine) = &self.engine {
            self.state.env = (self.state.env + 1) % engine.envs.len();
        }
        if let Ok(engine) = &self.engine {
            let lim = engine.limits();
            self.state.terms = self.state.terms.clamp(1, lim.coeffs);
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let label = ui.label("File");
            ui.text_edit_singleline(&mut self.path_edit)
                .labelled_by(label.id);
        });
        if ui.button("Open").clicked() {
            let p = PathBuf::from(self.path_edit.clone());
            self.open(&p);
        }
        ui.separator();
        let Ok(engine) = &mut self.engine else {
            return;
        };
        let limits = engine.limits();
        let s = &mut self.state;
        ui.heading("Method (M)");
        ui.horizontal(|ui| {
            ui.selectable_value(&mut s.method, Method::Wavelet, "Wavelet");
            ui.selectable_value(&mut s.method, Method::Sh, "SH");
            ui.selectable_value(&mut s.method, Method::Full, "Full");
        });
        ui.checkbox(&mut s.compare, "Compare SH | wavelet");
        ui.checkbox(&mut s.error_map, "Error heat map vs full");
        match engine.gpu_name() {
            Some(name) => {
                ui.checkbox(&mut s.gpu, "Relight on the GPU")
                    .on_hover_text(name.to_string());
            }
            None => {
                ui.label("No GPU adapter: relighting on the CPU");
            }
        }
        ui.separator();
        ui.label(format!("Kept terms (+/-), 1 to {}", limits.coeffs));
        ui.add(
            egui::Slider::new(&mut s.terms, 1..=limits.coeffs)
                .logarithmic(true)
                .show_value(false)
                .text("K"),
        );
        ui.horizontal(|ui| {
            let label = ui.label("K =");
            ui.add(egui::DragValue::new(&mut s.terms).range(1..=limits.coeffs))
                .labelled_by(label.id);
        });
        egui::ComboBox::from_label("Weighting")
            .selected_text(s.weighting.name())
            .show_ui(ui, |ui| {
                for w in Weighting::ALL {
                    ui.selectable_value(&mut s.weighting, w, w.name());
                }
            });
        ui.add(egui::Slider::new(&mut s.sh_order, 1..=limits.sh_order).text("SH order"));
        ui.separator();
        let current = engine
            .envs
            .get(s.env)
            .map(|e| e.name.clone())
            .unwrap_or_default();
        egui::ComboBox::from_label("Environment (E)")
            .selected_text(current)
            .show_ui(ui, |ui| {
                for (i, e) in engine.envs.iter().enumerate() {
                    ui.selectable_value(&mut s.env, i, &e.name);
                }
            });
        if engine
            .envs
            .get(s.env)
            .is_some_and(|e| e.source == EnvSource::Sun)
        {
            ui.add(egui::Slider::new(&mut s.sun_elev, -10.0..=90.0).text("sun elevation°"));
            ui.add(egui::Slider::new(&mut s.sun_azim, 0.0..=360.0).text("sun azimuth°"));
        }
        ui.add(egui::Slider::new(&mut s.yaw, -180.0..=180.0).text("yaw°"));
        ui.add(egui::Slider::new(&mut s.pitch, -90.0..=90.0).text("pitch°"));
        ui.add(egui::Slider::new(&mut s.exposure, -12.0..=12.0).text("exposure (stops)"));
        ui.separator();
        ui.horizontal(|ui| {
            let label = ui.label("Save as");
            ui.text_edit_singleline(&mut self.save_stem)
                .labelled_by(label.id);
        });
        if ui.button("Save PNG + EXR").clicked() {
            let stem = PathBuf::from(&self.save_stem);
            let state = s.clone();
            self.error = save_view(engine, &state, &stem).err();
        }
        if ui.button("Auto exposure").clicked()
            && let Ok(e) = engine.auto_exposure(s)
        {
            s.exposure = e;
        }
        ui.separator();
        for p in &self.info {
            ui.strong(&p.title);
            ui.label(format!("terms used: {}", p.terms));
            ui.label(format!(
                "CPU relight: {:.2} ms (kernel {:.2} ms)",
                p.relight_seconds * 1e3,
                p.kernel_seconds * 1e3
            ));
            ui.label(format!("relative L2 vs full: {:.4}", p.rel_l2));
        }
        for (i, t) in self.gpu_seconds.iter().enumerate() {
            ui.label(format!(
                "GPU pane {}: relight + tone map {:.2} ms",
                i + 1,
                t * 1e3
            ));
        }
        if self.light_seconds > 0.0 {
            ui.label(format!(
                "light prepared in {:.1} ms",
                self.light_seconds * 1e3
            ));
        }
        for n in &self.notes {
            ui.colored_label(egui::Color32::YELLOW, n);
        }
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::RED, e);
        }
    }

    /// Re-renders when the state changed since the last shown image.
    fn refresh(&mut self, ctx: &egui::Context) {
        let Ok(engine) = &mut self.engine else {
            return;
        };
        if self.shown.as_ref() == Some(&self.state) {
            return;
        }
        self.shown = Some(self.state.clone());
        let gpu_display = self.state.gpu
            && !self.state.error_map
            && self.render_state.is_some()
            && engine.gpu_name().is_some();
        // The numbers (and the CPU image) always come from the CPU relight.
        let cpu_state = ViewState {
            gpu: false,
            ..self.state.clone()
        };
        let r = match engine.render(&cpu_state) {
            Ok(r) => r,
            Err(e) => {
                self.error = Some(e);
                return;
            }
        };
        self.error = None;
        self.notes = r.notes.clone();
        self.state = ViewState {
            gpu: self.state.gpu,
            ..r.state.clone()
        };
        self.shown = Some(self.state.clone());
        if r.light_seconds > 0.0 {
            self.light_seconds = r.light_seconds;
        }
        self.size = [r.width, r.height];
        self.gpu_seconds.clear();
        if gpu_display {
            if let Err(e) = self.show_on_gpu(&r) {
                self.error = Some(format!("GPU display: {e}"));
            }
        } else {
            self.textures.truncate(r.panes.len());
            for (i, p) in r.panes.iter().enumerate() {
                let img = egui::ColorImage::from_rgb([r.width, r.height], &p.rgb);
                if let Some(t) = self.textures.get_mut(i) {
                    t.set(img, egui::TextureOptions::NEAREST);
                } else {
                    self.textures.push(ctx.load_texture(
                        format!("pane {i}"),
                        img,
                        egui::TextureOptions::NEAREST,
                    ));
                }
            }
        }
        self.info = r.panes.into_iter().map(|p| p.linear).collect();
    }

    /// Relights every pane of `r` straight into GPU textures egui draws.
    fn show_on_gpu(&mut self, r: &Rendered) -> Result<(), String> {
        let (Ok(engine), Some(rs)) = (&mut self.engine, &self.render_state) else {
            return Err("no GPU".into());
        };
        let (w, h) = (r.width as u32, r.height as u32);
        self.gpu_views
            .retain(|(v, _)| (v.width, v.height) == (w, h));
        while self.gpu_views.len() < r.panes.len() {
            let view = GpuView::new(&rs.device, w, h);
            let id = rs.renderer.write().register_native_texture(
                &rs.device,
                &view.display.create_view(&Default::default()),
                wgpu::FilterMode::Nearest,
            );
            self.gpu_views.push((view, id));
        }
        for (p, (view, _)) in r.panes.iter().zip(&self.gpu_views) {
            let seconds = engine.relight_to_view(&p.linear.request, view, r.state.exposure)?;
            self.gpu_seconds.push(seconds);
        }
        Ok(())
    }

    /// The textures to draw: the GPU ones after a GPU relight, else the CPU uploads.
    fn shown_textures(&self) -> Vec<egui::TextureId> {
        if !self.gpu_seconds.is_empty() {
            self.gpu_views
                .iter()
                .take(self.gpu_seconds.len())
                .map(|(_, id)| *id)
                .collect()
        } else {
            self.textures.iter().map(|t| t.id()).collect()
        }
    }

    fn images(&self, ui: &mut egui::Ui) {
        if let Err(e) = &self.engine {
            ui.centered_and_justified(|ui| {
                ui.colored_label(
                    egui::Color32::RED,
                    format!("Could not open the transport file:\n{e}"),
                );
            });
            return;
        }
        let ids = self.shown_textures();
        if ids.is_empty() {
            if let Some(e) = &self.error {
                ui.colored_label(egui::Color32::RED, e);
            }
            return;
        }
        let n = ids.len() as f32;
        let avail = ui.available_size();
        let [w, h] = [self.size[0] as f32, self.size[1] as f32];
        let gap = 8.0;
        let title_h = 20.0;
        let scale = (((avail.x - gap * (n - 1.0)) / n) / w)
            .min((avail.y - title_h) / h)
            .max(0.01);
        ui.horizontal_top(|ui| {
            for (id, info) in ids.iter().zip(&self.info) {
                ui.vertical(|ui| {
                    ui.label(&info.title);
                    ui.add(egui::Image::new((*id, egui::vec2(w * scale, h * scale))));
                });
                ui.add_space(gap);
            }
        });
    }

    /// The whole window, drawn into `ui` (also what the UI tests drive).
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        self.keys(&ctx);
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        self.refresh(&ctx);
        egui::CentralPanel::default_margins().show(ui, |ui| self.images(ui));
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

/// Opens the window on `file` with the extra environments `envs`.
pub fn run(file: &Path, envs: &[String]) -> eframe::Result {
    let app = ViewerApp::new(file, envs);
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1280.0, 800.0])
            .with_title("wavelet-prt viewer"),
        ..Default::default()
    };
    eframe::run_native(
        "wavelet-prt viewer",
        options,
        Box::new(move |cc| {
            let mut app = app;
            if let Some(rs) = &cc.wgpu_render_state {
                app.attach_render_state(rs.clone());
            }
            Ok(Box::new(app))
        }),
    )
}
