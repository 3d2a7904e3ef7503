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
mod camera;
mod display;
mod engine;
mod gpu_view;
mod lights;
mod state;
mod viewport;
mod volume_app;
mod worker;

pub use app::ViewerApp;
pub use display::{DisplayPath, Frame, GpuTiming, MeshDisplay};
pub use engine::{Engine, OnLight, save_view, screenshot, view_size};
pub use gpu_view::GpuView;
pub use lights::{LightControl, LightsState, lights_controls, outline_quads};
pub use state::{
    DisplayState, Layout, LightKey, LightState, Limits, MAX_DRAW_SIDE, RelightKey, RelightState,
    ViewState, sh_order_for_terms,
};
pub use viewport::Viewport;
pub use volume_app::{VolumeApp, VolumeEngine, VolumeFrame, VolumeState, volume_screenshot};

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::env::envmap::{EnvMap, SunSpec};
use crate::output::film::{Image, ToneCurve};
use crate::relight::gpu::Gpu;
use crate::relight::{PreparedLight, RelightRequest};
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
    /// The procedural sun and sky, placed by [`LightState::sun`].
    Sun,
}

/// One entry of the environment list.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvEntry {
    /// The name shown in the list.
    pub name: String,
    /// Where its map comes from.
    pub source: EnvSource,
}

/// The sun radius of the first `sun:ELEV,AZIM,RADIUS` on the command line, if it has one.
fn cli_sun_radius(cli: &[String]) -> Option<f64> {
    // The first sun given, if its radius was given too.
    let first = cli
        .iter()
        .find_map(|s| SunSpec::parse(s).map(|sun| (s, sun)))?;
    match first {
        (s, Ok(sun)) if s.split(',').count() == 3 => Some(sun.radius),
        _ => None,
    }
}

/// The environment picker (`label`), the sun's elevation, azimuth and radius sliders when the
/// procedural sun is picked, then yaw and pitch: the light controls both windows share.
pub(crate) fn light_controls(
    ui: &mut egui::Ui,
    label: &str,
    envs: &[EnvEntry],
    light: &mut LightState,
) {
    let current = envs
        .get(light.env)
        .map(|e| e.name.clone())
        .unwrap_or_default();
    egui::ComboBox::from_label(label)
        .selected_text(current)
        .show_ui(ui, |ui| {
            for (i, e) in envs.iter().enumerate() {
                ui.selectable_value(&mut light.env, i, &e.name);
            }
        });
    let sun = &mut light.sun;
    if envs
        .get(light.env)
        .is_some_and(|e| e.source == EnvSource::Sun)
    {
        ui.add(egui::Slider::new(&mut sun.elevation, -10.0..=90.0).text("sun elevation°"));
        ui.add(egui::Slider::new(&mut sun.azimuth, 0.0..=360.0).text("sun azimuth°"));
        ui.add(
            egui::Slider::new(&mut sun.radius, 0.25..=20.0)
                .logarithmic(true)
                .text("sun radius°"),
        );
    }
    let turn = &mut light.rotation;
    ui.add(egui::Slider::new(&mut turn.yaw_deg, -180.0..=180.0).text("yaw°"));
    ui.add(egui::Slider::new(&mut turn.pitch_deg, -90.0..=90.0).text("pitch°"));
}

/// The resizable panel of controls at the left of a window (`width` points wide at first),
/// scrolling when it is taller than the window.
pub(crate) fn controls_panel(
    ui: &mut egui::Ui,
    id: &str,
    width: f32,
    add: impl FnOnce(&mut egui::Ui),
) {
    egui::Panel::left(id.to_owned())
        .resizable(true)
        .default_size(width)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, add);
        });
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
/// procedural sun. Returns the list and the first light: the entry to select (the first
/// command-line environment, else [`FIRST_VIEW_MAP`], else the sun) and the sun as the first
/// `sun:ELEV,AZIM[,RADIUS]` on the command line places it.
pub fn env_entries(cli: &[String]) -> (Vec<EnvEntry>, LightState) {
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
    if entries.is_empty() {
        // No folder of maps beside the binary: the maps built into it, by name.
        for m in crate::env::envmap::BUNDLED_MAPS {
            entries.push(EnvEntry {
                name: m.stem().to_string(),
                source: EnvSource::File(PathBuf::from(m.stem())),
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
    let mut light = LightState {
        env: selected,
        ..LightState::default()
    };
    (light.sun.elevation, light.sun.azimuth) = sun;
    if let Some(r) = cli_sun_radius(cli) {
        light.sun.radius = r;
    }
    (entries, light)
}

/// A prepared light as the window holds it.
#[derive(Clone)]
pub struct LightShown {
    /// What it was prepared for.
    pub key: LightKey,
    /// The prepared light.
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
    let (w, h) = (camera.width as usize, camera.height as usize);
    let what = format!("a {w} x {h} backdrop");
    let open = crate::files::try_filled("camera.width/height", &what, w * h, 0.0f32)?;
    crate::draw::background::environment_behind_camera(camera, &open, map, key.rotation)
}

/// One relit view before tone mapping.
#[derive(Clone, Debug)]
pub struct LinearPane {
    /// The pane's title, as the window shows it.
    pub title: String,
    /// What was relit.
    pub request: RelightRequest,
    /// The relit image, linear RGB.
    pub image: Image,
    /// Light terms used.
    pub terms: usize,
    /// Transport values the relight read.
    pub nonzeros_touched: u64,
    /// Kernel time of the relight, seconds.
    pub kernel_seconds: f64,
    /// The whole relight call (the terms made, the kernels, the readback), seconds.
    pub relight_seconds: f64,
    /// Relative L2 error against `full`.
    pub rel_l2: f64,
}

/// One displayed view.
#[derive(Clone, Debug)]
pub struct Pane {
    /// The pane before tone mapping.
    pub linear: LinearPane,
    /// 8-bit sRGB, RGB interleaved, `width · height · 3` bytes.
    pub rgb: Vec<u8>,
}

/// What [`Engine::render`] returns.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Width of each pane, pixels.
    pub width: usize,
    /// Height of each pane, pixels.
    pub height: usize,
    /// The panes, left to right (with their error maps beside them when asked for).
    pub panes: Vec<Pane>,
    /// The state after clamping.
    pub state: ViewState,
    /// What was clamped, one note per value.
    pub notes: Vec<String>,
    /// Time spent preparing the light in this call (0 when cached), seconds: resampling, Haar
    /// and SH projection, up to the moment the GPU could draw it.
    pub light_seconds: f64,
    /// Time spent relighting the `full` image the errors are measured against (0 when cached).
    pub full_seconds: f64,
    /// The scale the error heat maps among the panes share; `None` without heat maps.
    pub heat: Option<crate::output::sheet::HeatScale>,
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
    /// [`Layout::Split`] each (SH, wavelet) pair as one image split at [`DisplayState::split`] by a
    /// white line.
    pub fn composite(&self, gap: usize) -> (usize, usize, Vec<u8>) {
        if !self.state.split_pairs() {
            return self.side_by_side(gap);
        }
        let (w, h) = (self.width, self.height);
        let cut = ((self.state.display.split * w as f32).round() as usize).min(w);
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
                display: DisplayState {
                    layout: Layout::SideBySide,
                    ..self.state.display
                },
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

    /// [`Rendered::composite`], with the heat maps' colour bar at its right when it has heat
    /// maps, under a dark strip that names each image: each caption wrapped (and smaller where
    /// need be) to fit its image, the strip as tall as the tallest.
    pub fn captioned(&self, gap: usize) -> (usize, usize, Vec<u8>) {
        use crate::output::sheet::{BAR_GAP, caption_strip_height, lay_out_caption};
        let (plain, h, rgb) = self.composite(gap);
        let (w, rgb) = match self.heat {
            Some(scale) => crate::output::sheet::with_color_bar(&rgb, plain, h, scale),
            None => (plain, rgb),
        };
        let (mut xs, mut captions) = (Vec::new(), Vec::new());
        for (i, caption) in self.captions().iter().enumerate() {
            xs.push(i * (self.width + gap) + 4);
            let fit = self.width.saturating_sub(8);
            captions.push(lay_out_caption(&[caption.as_str()], fit, 2));
        }
        if self.heat.is_some() {
            xs.push(plain + BAR_GAP);
            captions.push(lay_out_caption(&["% of mean"], w - plain - BAR_GAP, 2));
        }
        let strip = caption_strip_height(&captions);
        let mut out = vec![24u8; w * (h + strip) * 3];
        out[w * strip * 3..].copy_from_slice(&rgb);
        for (x, caption) in xs.into_iter().zip(&captions) {
            caption.draw(&mut out, w, x, 4, [235, 235, 235]);
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
