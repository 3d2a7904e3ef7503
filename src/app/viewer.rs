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
mod engine;
mod gpu_view;
mod mesh_view;
mod viewport;
mod volume_app;
mod worker;

pub use app::ViewerApp;
pub use engine::{
    ERROR_MAP_GAIN, Engine, GpuTiming, OnLight, error_heat_map, relight_into_view, save_view,
    screenshot, view_size,
};
pub use gpu_view::GpuView;
pub use mesh_view::{MeshDisplay, draw_into_view};
pub use viewport::Viewport;
pub use volume_app::{VolumeApp, VolumeEngine, VolumeFrame, VolumeState, volume_screenshot};

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::light::envmap::{EnvMap, EnvRotation, SunSpec};
use crate::light::select::Weighting;
use crate::output::film::{Image, ToneCurve, ToneMap};
use crate::relight::gpu::Gpu;
use crate::relight::vertex::Orbit;
use crate::relight::{Method, PreparedLight, RelightRequest};
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

/// The GPU row of a panel: the box that draws with the GPU kernels, the adapter and why the box
/// starts as it does (its full name on hover), and a spinner while the transport uploads; a
/// notice without an adapter.
pub(crate) fn gpu_controls(ui: &mut egui::Ui, gpu: Option<(&Gpu, bool)>, on: &mut bool) {
    let Some((gpu, uploading)) = gpu else {
        ui.label("No GPU adapter: relighting on the CPU");
        return;
    };
    ui.checkbox(on, "Relight on the GPU")
        .on_hover_text(gpu.adapter.clone());
    let why = if gpu.software {
        "a software adapter, slower than the CPU kernels"
    } else {
        "a hardware GPU"
    };
    let name = gpu.adapter.split(" (").next().unwrap_or_default();
    ui.add(egui::Label::new(format!("{name}: {why}")).wrap())
        .on_hover_text(gpu.adapter.clone());
    if uploading {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.label("uploading the transport to the GPU");
        });
    }
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
    /// The camera of a per-vertex bake, turned from the bake's own (ignored by a per-pixel bake,
    /// whose view is fixed).
    pub orbit: Orbit,
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
            orbit: Orbit::default(),
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

/// A prepared light as the window holds it.
#[derive(Clone)]
pub struct LightShown {
    pub key: LightKey,
    pub light: Arc<PreparedLight>,
    /// The environment behind a per-pixel bake's view, weighted by each pixel's uncovered
    /// fraction; empty for a per-vertex bake, whose backdrop depends on the camera (see
    /// [`backdrop`]).
    pub behind: Arc<Image>,
    /// The map itself, as the key's environment gives it.
    pub map: Arc<EnvMap>,
}

/// The whole environment seen through `camera`, turned as `key` says: what is behind a drawn
/// per-vertex bake where it leaves a pixel open.
pub fn backdrop(
    camera: &crate::scene::Camera,
    map: &EnvMap,
    key: &LightKey,
) -> crate::Result<Image> {
    let open = vec![0.0; camera.width as usize * camera.height as usize];
    crate::relight::background::environment_behind_camera(camera, &open, map, key.rotation())
}

impl LightKey {
    /// The environment's rotation.
    pub fn rotation(&self) -> EnvRotation {
        EnvRotation {
            yaw_deg: self.yaw,
            pitch_deg: self.pitch,
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
    /// Highest SH order through the light: no more terms than texels, at most
    /// [`crate::math::sh::MAX_LIGHT_ORDER`].
    pub sh_light_order: usize,
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
        if self.method == Method::ShLight {
            let most = limits.sh_light_order.max(1);
            if self.sh_order == 0 || self.sh_order > most {
                let n = self.sh_order.clamp(1, most);
                notes.push(format!(
                    "SH order {} clamped to {n} (through the light, up to order {most})",
                    self.sh_order
                ));
                self.sh_order = n;
            }
        } else if self.sh_order == 0 || self.sh_order > limits.sh_order {
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
        // Turning past a half turn wraps around: no note.
        self.orbit.clamp();
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
            Method::Full => Method::ShLight,
            Method::ShLight => Method::Wavelet,
        };
    }

    /// The panes this state shows: the requests and their titles.
    pub fn requests(&self, limits: Limits) -> Vec<(String, RelightRequest)> {
        let base = RelightRequest::new(self.method, self.terms, self.weighting, self.sh_order);
        if self.compare {
            let n = sh_order_for_terms(self.terms, limits.sh_order);
            vec![
                (
                    format!("SH order {n} ({} terms)", n * n),
                    RelightRequest::Sh { order: n },
                ),
                (
                    format!("wavelet, {} terms", self.terms),
                    RelightRequest::Wavelet {
                        k: self.terms,
                        weighting: self.weighting,
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
                Method::ShLight => format!(
                    "SH order {} through the light ({} terms)",
                    self.sh_order,
                    self.sh_order.pow(2)
                ),
            };
            vec![(title, base)]
        }
    }

    /// Everything but the display settings and the camera: what the relit values (pixels, or a
    /// per-vertex bake's vertex colours) depend on.
    pub fn relight_key(&self) -> ViewState {
        ViewState {
            orbit: Orbit::default(),
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
        let strip = crate::output::text::CAPTION_HEIGHT;
        let mut out = vec![24u8; w * (h + strip) * 3];
        out[w * strip * 3..].copy_from_slice(&rgb);
        for (i, caption) in self.captions().iter().enumerate() {
            let x = i * (self.width + gap) + 4;
            let text = crate::output::text::fit_text(caption, self.width.saturating_sub(8));
            crate::output::text::draw_text(&mut out, w, x, 4, &text, [235, 235, 235]);
        }
        (w, h + strip, out)
    }
}

/// Opens the window on `file` with the extra environments `envs`. The window's device asks for
/// the adapter's full limits (large transports fit in fewer bindings) and for timestamp queries
/// where the adapter has them. Without a display to open it on, the error says so and what to do
/// instead.
pub fn run(file: &Path, envs: &[String]) -> crate::Result<()> {
    // X11 and Wayland name their display in the environment; macOS and Windows always have one.
    let named_display = ["WAYLAND_DISPLAY", "DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|d| !d.is_empty()));
    let uses_x11_or_wayland = cfg!(all(
        unix,
        not(any(
            target_os = "macos",
            target_os = "ios",
            target_os = "android"
        ))
    ));
    if uses_x11_or_wayland && !named_display {
        return Err(crate::PrtError::invalid(
            "display",
            "no display to open a window on (neither WAYLAND_DISPLAY nor DISPLAY is set): use \
             --screenshot OUT.png to render the view to a file",
        ));
    }
    open_window(file, envs).map_err(|e| crate::PrtError::invalid("window", e.to_string()))
}

fn open_window(file: &Path, envs: &[String]) -> eframe::Result {
    use eframe::egui_wgpu::{WgpuConfiguration, WgpuSetup, WgpuSetupCreateNew};
    let mut setup = WgpuSetupCreateNew::without_display_handle();
    setup.device_descriptor = Arc::new(|adapter: &wgpu::Adapter| wgpu::DeviceDescriptor {
        label: Some("prt view"),
        required_limits: adapter.limits(),
        required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
        ..Default::default()
    });
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1280.0, 800.0])
            .with_title("wavelet-prt viewer"),
        wgpu_options: WgpuConfiguration {
            wgpu_setup: WgpuSetup::CreateNew(setup),
            ..Default::default()
        },
        ..Default::default()
    };
    if crate::volume::is_volume_file(file) {
        // The volume path: load now (volume files are small), march on the window's device.
        let vt = crate::volume::VolumeTransfer::load(file)
            .map_err(|e| eframe::Error::AppCreation(Box::new(e)))?;
        let envs = envs.to_vec();
        return eframe::run_native(
            "wavelet-prt volume viewer",
            options,
            Box::new(move |cc| {
                let gpu = cc.wgpu_render_state.as_ref().map(|rs| {
                    crate::gpu::GpuDevice::from_device(
                        rs.device.clone(),
                        rs.queue.clone(),
                        &rs.adapter.get_info(),
                    )
                });
                Ok(Box::new(VolumeApp::new(vt, &envs, gpu)))
            }),
        );
    }
    let app = ViewerApp::new(file, envs);
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
