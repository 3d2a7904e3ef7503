//! The interactive viewer (`prt view`): eframe on egui-wgpu, sharing its wgpu device with the
//! relight kernels of [`crate::relight::gpu`].
//!
//! The rendering core is [`Engine::render`]: a function from a [`ViewState`] to the tone-mapped
//! panes the window shows (one, or SH and wavelet side by side or split). The window, the
//! keyboard and the `--screenshot` mode all go through it; the engine only caches what does not
//! change between calls (loaded maps, the prepared light, the `full` relight used as the error
//! reference, the last linear images so an exposure change only re-tone-maps).
//!
//! The window ([`ViewerApp`], in `app.rs`) never waits on the CPU: an [`Engine`] lives on a
//! worker thread (`worker.rs`) that loads the file, prepares lights and computes the CPU images
//! and their errors, while the window draws the GPU relight of every change at once.

mod app;
mod gpu_view;
mod volume_app;
mod worker;

pub use app::{ViewerApp, run};
pub use gpu_view::GpuView;
pub use volume_app::{VolumeApp, VolumeEngine, VolumeFrame, VolumeState, volume_screenshot};

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use crate::light::envmap::{EnvMap, EnvRotation, SunSpec};
use crate::light::select::Weighting;
use crate::output::film::{Image, ToneCurve, ToneMap};
use crate::output::metrics::relative_l2;
use crate::relight::background::{composite, environment_behind};
use crate::relight::gpu::{Gpu, GpuTransport};
use crate::relight::{
    LightContext, Method, PreparedLight, RelightRequest, RelightStats, light_sh_order, relight,
    select_light,
};
use crate::store::transport::Transport;
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

/// The sun radius of the first `sun:ELEV,AZIM,RADIUS` on the command line, if it has one.
pub fn cli_sun_radius(cli: &[String]) -> Option<f64> {
    cli.iter()
        .find(|s| s.starts_with("sun:"))
        .filter(|s| s.split(',').count() == 3)
        .and_then(|s| SunSpec::parse(s)?.ok())
        .map(|sun| sun.radius)
}

/// The environment picker (`label`), the sun's elevation, azimuth and radius sliders when the
/// procedural sun is picked, then yaw and pitch: the light controls both windows share.
pub(crate) fn light_controls(
    ui: &mut egui::Ui,
    label: &str,
    envs: &[EnvEntry],
    env: &mut usize,
    sun: [&mut f64; 3],
    rotation: [&mut f64; 2],
) {
    let current = envs.get(*env).map(|e| e.name.clone()).unwrap_or_default();
    egui::ComboBox::from_label(label)
        .selected_text(current)
        .show_ui(ui, |ui| {
            for (i, e) in envs.iter().enumerate() {
                ui.selectable_value(env, i, &e.name);
            }
        });
    let [elev, azim, radius] = sun;
    if envs.get(*env).is_some_and(|e| e.source == EnvSource::Sun) {
        ui.add(egui::Slider::new(elev, -10.0..=90.0).text("sun elevation°"));
        ui.add(egui::Slider::new(azim, 0.0..=360.0).text("sun azimuth°"));
        ui.add(
            egui::Slider::new(radius, 0.25..=20.0)
                .logarithmic(true)
                .text("sun radius°"),
        );
    }
    let [yaw, pitch] = rotation;
    ui.add(egui::Slider::new(yaw, -180.0..=180.0).text("yaw°"));
    ui.add(egui::Slider::new(pitch, -90.0..=90.0).text("pitch°"));
}

/// Exposure and tone curve.
pub(crate) fn tone_controls(ui: &mut egui::Ui, exposure: &mut f32, tone: &mut ToneCurve) {
    ui.add(egui::Slider::new(exposure, -12.0..=12.0).text("exposure (stops)"));
    egui::ComboBox::from_label("Tone curve")
        .selected_text(tone.name())
        .show_ui(ui, |ui| {
            for c in ToneCurve::ALL {
                ui.selectable_value(tone, c, c.name());
            }
        });
}

/// The bundled map the viewer opens on when no environment is given.
pub const FIRST_VIEW_MAP: &str = "blender_sunrise";

/// The environment list: the bundled maps, then the files given on the command line, then the
/// procedural sun. Returns the list, the sun's initial (elevation, azimuth) and the entry to
/// select first (the first command-line environment, else [`FIRST_VIEW_MAP`], else the sun).
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
    let mut sun = (15.0, 45.0);
    let mut first_cli = None;
    let mut sun_given = false;
    for spec in cli {
        if let Some(parsed) = SunSpec::parse(spec) {
            if let Ok(s) = parsed
                && !sun_given
            {
                sun = (s.elevation, s.azimuth);
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
    // Without a choice the first view shows what wavelets are for: a low sun and hard shadows
    // (the bundled sunrise, else the procedural sun).
    let selected = match first_cli {
        Some(usize::MAX) => sun_index,
        Some(i) => i,
        None => entries
            .iter()
            .position(|e| e.name == FIRST_VIEW_MAP)
            .unwrap_or(sun_index),
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
    /// Procedural sun elevation, azimuth and angular radius, degrees.
    pub sun_elev: f64,
    pub sun_azim: f64,
    pub sun_radius: f64,
    /// Environment rotation, degrees.
    pub yaw: f64,
    pub pitch: f64,
    /// Exposure in stops.
    pub exposure: f32,
    /// Display curve after the exposure.
    pub tone: ToneCurve,
    /// SH and wavelet at the same term count.
    pub compare: bool,
    /// How the two images of `compare` are shown.
    pub layout: Layout,
    /// Where the split falls in [`Layout::Split`], as a fraction of the width (SH to its left).
    pub split: f32,
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
            sun_radius: 2.0,
            yaw: 0.0,
            pitch: 0.0,
            exposure: 0.0,
            tone: ToneCurve::Clip,
            compare: false,
            layout: Layout::SideBySide,
            split: 0.5,
            error_map: false,
            gpu: false,
        }
    }
}

/// How [`ViewState::compare`] shows its two images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Layout {
    /// Side by side.
    #[default]
    SideBySide,
    /// One image, SH left of the split and wavelet right of it.
    Split,
}

/// The light an environment entry, the sun and the rotation of `state` make: what a prepared
/// light is cached under.
#[derive(Clone, Debug, PartialEq)]
pub struct LightKey {
    pub spec: String,
    pub yaw: f64,
    pub pitch: f64,
}

impl LightKey {
    /// The key of `state` over the environment list `envs` (a path, or `sun:ELEV,AZIM,RADIUS`).
    pub fn of(envs: &[EnvEntry], state: &ViewState) -> LightKey {
        let spec = match envs.get(state.env).map(|e| &e.source) {
            Some(EnvSource::File(p)) => p.display().to_string(),
            _ => format!(
                "sun:{:.2},{:.2},{:.2}",
                state.sun_elev, state.sun_azim, state.sun_radius
            ),
        };
        LightKey {
            spec,
            yaw: state.yaw,
            pitch: state.pitch,
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
        if !(0.05..=45.0).contains(&self.sun_radius) {
            self.sun_radius = if self.sun_radius.is_finite() {
                self.sun_radius.clamp(0.05, 45.0)
            } else {
                2.0
            };
        }
        if !(0.0..=1.0).contains(&self.split) {
            self.split = if self.split.is_finite() {
                self.split.clamp(0.0, 1.0)
            } else {
                0.5
            };
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

    /// Everything but the display settings: what the linear images depend on.
    pub fn relight_key(&self) -> ViewState {
        ViewState {
            exposure: 0.0,
            tone: ToneCurve::Clip,
            error_map: false,
            layout: Layout::SideBySide,
            split: 0.5,
            gpu: false,
            ..self.clone()
        }
    }

    /// The tone mapping of this state.
    pub fn tone_map(&self) -> ToneMap {
        ToneMap {
            exposure: self.exposure,
            curve: self.tone,
        }
    }

    /// Whether the panes are shown in pairs split by [`ViewState::split`].
    pub fn split_pairs(&self) -> bool {
        self.compare && self.layout == Layout::Split
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
    /// Transport values the relight read.
    pub nonzeros_touched: u64,
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
    /// Time spent preparing the light in this call (0 when cached), seconds: resampling, Haar
    /// and SH projection, up to the moment the GPU could draw it.
    pub light_seconds: f64,
    /// Time spent relighting the `full` image the errors are measured against (0 when cached).
    pub full_seconds: f64,
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

    /// What the window shows, as one RGB8 image: the panes side by side, or with
    /// [`Layout::Split`] each (SH, wavelet) pair as one image split at [`ViewState::split`] by a
    /// white line.
    pub fn composite(&self, gap: usize) -> (usize, usize, Vec<u8>) {
        if !self.state.split_pairs() {
            return self.side_by_side(gap);
        }
        let (w, h) = (self.width, self.height);
        let cut = ((self.state.split * w as f32).round() as usize).min(w);
        let panes = self
            .panes
            .chunks(2)
            .map(|pair| {
                let (a, b) = (&pair[0], pair.get(1).unwrap_or(&pair[0]));
                let mut rgb = b.rgb.clone();
                for y in 0..h {
                    let row = y * w * 3;
                    rgb[row..row + cut * 3].copy_from_slice(&a.rgb[row..row + cut * 3]);
                    if cut > 0 && cut < w {
                        rgb[row + cut * 3..row + cut * 3 + 3].copy_from_slice(&[255; 3]);
                    }
                }
                Pane {
                    rgb,
                    linear: a.linear.clone(),
                }
            })
            .collect();
        Rendered {
            panes,
            state: ViewState {
                layout: Layout::SideBySide,
                ..self.state.clone()
            },
            notes: Vec::new(),
            ..*self
        }
        .side_by_side(gap)
    }
}

impl Rendered {
    /// The titles of the images [`Rendered::composite`] draws, left to right: a split pair's
    /// titles joined as left | right.
    pub fn captions(&self) -> Vec<String> {
        if self.state.split_pairs() {
            self.panes
                .chunks(2)
                .map(|pair| match pair {
                    [a, b] => format!("{} | {}", a.linear.title, b.linear.title),
                    [a] => a.linear.title.clone(),
                    _ => String::new(),
                })
                .collect()
        } else {
            self.panes.iter().map(|p| p.linear.title.clone()).collect()
        }
    }

    /// [`Rendered::composite`] under a dark strip that names each image.
    pub fn captioned(&self, gap: usize) -> (usize, usize, Vec<u8>) {
        let (w, h, rgb) = self.composite(gap);
        let strip = crate::output::sheet::CAPTION_HEIGHT;
        let mut out = vec![24u8; w * (h + strip) * 3];
        out[w * strip * 3..].copy_from_slice(&rgb);
        for (i, caption) in self.captions().iter().enumerate() {
            let x = i * (self.width + gap) + 4;
            let text = crate::output::sheet::fit_text(caption, self.width.saturating_sub(8));
            crate::output::sheet::draw_text(&mut out, w, x, 4, &text, [235, 235, 235]);
        }
        (w, h + strip, out)
    }
}

/// Wall and GPU time of one relight into a [`GpuView`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuTiming {
    /// From the first submission to the finished tone map, seconds.
    pub wall_seconds: f64,
    /// The relight passes alone, from GPU timestamp queries where the device has them.
    pub kernel_seconds: Option<f64>,
}

/// Relights `request` under `light` with the transport already on the GPU into `view`, and
/// tone-maps it there: the window's display path (no readback).
#[allow(clippy::too_many_arguments)]
pub fn relight_into_view(
    gpu: &Gpu,
    gt: &GpuTransport,
    t: &Transport,
    ctx: &LightContext,
    light: &PreparedLight,
    request: &RelightRequest,
    view: &GpuView,
    tone: ToneMap,
) -> Result<GpuTiming, String> {
    let start = Instant::now();
    match request.method {
        Method::Wavelet | Method::Full => {
            let sparse = select_light(t, ctx, light, request).map_err(|e| e.to_string())?;
            gt.relight_wavelet_to_texture(gpu, &sparse, &view.linear)
        }
        Method::Sh => {
            let sh = light_sh_order(&light.sh, request.sh_order, ctx.sh_order)
                .map_err(|e| e.to_string())?;
            gt.relight_sh_to_texture(gpu, &sh, &view.linear)
        }
    }
    .map_err(|e| e.to_string())?;
    let kernel_seconds = gpu.last_kernel_seconds();
    view.tone_map(&gpu.device, &gpu.queue, tone);
    gpu.device
        .poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: None,
        })
        .map_err(|e| e.to_string())?;
    Ok(GpuTiming {
        wall_seconds: start.elapsed().as_secs_f64(),
        kernel_seconds,
    })
}

/// Called with a newly prepared light, its key and the environment behind the scene.
pub type OnLight<'a> = dyn FnMut(&LightKey, &Arc<PreparedLight>, &Arc<Image>) + 'a;

/// A loaded transport, its environments and the caches behind [`Engine::render`].
pub struct Engine {
    pub path: PathBuf,
    pub transport: Arc<Transport>,
    pub ctx: Arc<LightContext>,
    pub envs: Vec<EnvEntry>,
    maps: HashMap<String, Arc<EnvMap>>,
    /// The prepared light, the `full` image under it, and the environment behind the scene.
    light: Option<(LightKey, Arc<PreparedLight>, Image, Arc<Image>)>,
    last: Option<(ViewState, Vec<LinearPane>)>,
    gpu: Option<Gpu>,
    gpu_transport: Option<GpuTransport>,
}

impl Engine {
    /// Loads a transport file; `envs` as on the command line (paths or `sun:ELEV,AZIM`).
    pub fn open(path: &Path, envs: Vec<EnvEntry>) -> Result<Engine, String> {
        Self::open_with_progress(path, envs, &|_, _| {})
    }

    /// [`Engine::open`], calling `progress(bytes read, file size)` while the file loads.
    pub fn open_with_progress(
        path: &Path,
        envs: Vec<EnvEntry>,
        progress: &dyn Fn(u64, u64),
    ) -> Result<Engine, String> {
        let transport = Transport::load_with_progress(path, progress).map_err(|e| e.to_string())?;
        Self::from_transport(path, transport, envs)
    }

    /// An engine on a transport already loaded from `path`.
    pub fn from_transport(
        path: &Path,
        transport: Transport,
        envs: Vec<EnvEntry>,
    ) -> Result<Engine, String> {
        let ctx = LightContext::new(&transport).map_err(|e| e.to_string())?;
        Ok(Engine {
            path: path.to_path_buf(),
            transport: Arc::new(transport),
            ctx: Arc::new(ctx),
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
    /// tone-maps it there, on the attached GPU.
    pub fn relight_to_view(
        &mut self,
        request: &RelightRequest,
        view: &GpuView,
        tone: ToneMap,
    ) -> Result<GpuTiming, String> {
        self.upload()?;
        let gpu = self.gpu.as_ref().ok_or("no GPU attached")?;
        let (_, light, _, _) = self.light.as_ref().ok_or("nothing rendered yet")?;
        let gt = self.gpu_transport.as_ref().expect("uploaded");
        relight_into_view(
            gpu,
            gt,
            &self.transport,
            &self.ctx,
            light,
            request,
            view,
            tone,
        )
    }

    fn upload(&mut self) -> Result<(), String> {
        let gpu = self.gpu.as_ref().ok_or("no GPU attached")?;
        if self.gpu_transport.is_none() {
            self.gpu_transport =
                Some(GpuTransport::upload(gpu, &self.transport, None).map_err(|e| e.to_string())?);
        }
        Ok(())
    }

    fn relight_gpu(
        &mut self,
        light: &PreparedLight,
        req: &RelightRequest,
    ) -> Result<(Image, RelightStats), String> {
        self.upload()?;
        let gpu = self.gpu.as_ref().ok_or("no GPU attached")?;
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

    /// The environment spec of `state` (a path, or `sun:ELEV,AZIM,RADIUS`).
    pub fn env_spec(&self, state: &ViewState) -> String {
        LightKey::of(&self.envs, state).spec
    }

    /// The prepared light of `state`, computing it (and the `full` image) when it changed;
    /// `on_light` sees a new light before the `full` relight starts. Returns the seconds spent on
    /// the light and on the `full` image.
    fn prepare_with(
        &mut self,
        state: &ViewState,
        on_light: &mut OnLight<'_>,
    ) -> Result<(f64, f64), String> {
        let key = LightKey::of(&self.envs, state);
        if self.light.as_ref().is_some_and(|(k, _, _, _)| *k == key) {
            return Ok((0.0, 0.0));
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
        let light = Arc::new(
            self.ctx
                .prepare(&map, rotation)
                .map_err(|e| e.to_string())?,
        );
        let behind = Arc::new(
            environment_behind(
                &self.transport.meta,
                &self.transport.coverage,
                &map,
                rotation,
            )
            .map_err(|e| e.to_string())?,
        );
        let light_seconds = start.elapsed().as_secs_f64();
        on_light(&key, &light, &behind);
        let full_start = Instant::now();
        let full_req = RelightRequest {
            method: Method::Full,
            terms: 0,
            weighting: Weighting::Unweighted,
            sh_order: 1,
        };
        let (full, _) =
            relight(&self.transport, &self.ctx, &light, &full_req).map_err(|e| e.to_string())?;
        self.light = Some((key, light, full, behind));
        self.last = None;
        Ok((light_seconds, full_start.elapsed().as_secs_f64()))
    }

    /// The light of the last render or exposure, its key, and the environment behind the scene.
    pub fn current_light(&self) -> Option<(LightKey, Arc<PreparedLight>, Arc<Image>)> {
        self.light
            .as_ref()
            .map(|(k, l, _, b)| (k.clone(), l.clone(), b.clone()))
    }

    fn prepare(&mut self, state: &ViewState) -> Result<(f64, f64), String> {
        self.prepare_with(state, &mut |_, _, _| {})
    }

    /// The exposure [`ToneMap::auto`] picks for the `full` image under `state`'s light.
    pub fn auto_exposure(&mut self, state: &ViewState) -> Result<f32, String> {
        let mut s = state.clone();
        s.clamp(self.limits());
        self.prepare(&s)?;
        let (_, _, full, _) = self.light.as_ref().expect("prepared");
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
                nonzeros_touched: stats.nonzeros_touched,
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
        self.render_with(state, &mut |_, _, _| {})
    }

    /// [`Engine::render`], handing a newly prepared light to `on_light` as soon as it exists
    /// (before the CPU relights), so a GPU can draw it meanwhile.
    pub fn render_with(
        &mut self,
        state: &ViewState,
        on_light: &mut OnLight<'_>,
    ) -> Result<Rendered, String> {
        let mut state = state.clone();
        let limits = self.limits();
        let notes = state.clamp(limits);
        let (light_seconds, full_seconds) = self.prepare_with(&state, on_light)?;
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
        let (_, _, full, behind) = self.light.as_ref().expect("prepared");
        let tone = state.tone_map();
        // Shown over the environment behind the scene; the errors were taken before.
        let mut panes: Vec<Pane> = linear
            .iter()
            .map(|l| {
                let shown = LinearPane {
                    image: composite(&l.image, behind),
                    ..l.clone()
                };
                Pane {
                    rgb: shown.image.to_srgb8(tone),
                    linear: shown,
                }
            })
            .collect();
        if state.error_map {
            let maps: Vec<Pane> = panes
                .iter()
                .zip(linear)
                .map(|(p, l)| Pane {
                    rgb: error_heat_map(&l.image, full, ERROR_MAP_GAIN),
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
            full_seconds,
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

/// Renders `state` as the window would show it and writes it as a PNG, each image under a
/// caption with its title (as the window shows them).
pub fn screenshot(engine: &mut Engine, state: &ViewState, out: &Path) -> Result<Rendered, String> {
    let r = engine.render(state)?;
    for p in &r.panes {
        p.linear
            .image
            .check_finite(&p.linear.title)
            .map_err(|e| e.to_string())?;
    }
    let (w, h, rgb) = r.captioned(4);
    crate::files::write_atomically(out, |tmp| crate::output::film::write_png(tmp, w, h, &rgb))
        .map_err(|e| e.to_string())?;
    Ok(r)
}
