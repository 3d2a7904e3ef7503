//! The window: the side panel of controls and numbers, and the images with zoom, pan and the
//! split view. Every change is drawn at once by the GPU kernels (when the window has a device
//! and the transport is on it); the worker thread computes the CPU images and the errors against
//! `full` behind it, and the panel shows them when they arrive.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::Duration;

use eframe::{egui, wgpu};

use super::camera;
use super::viewport::Viewport;
use super::worker::{Job, Loaded, Reply, TransportWorker};
use super::{
    DisplayPath, Frame, GpuTiming, GpuView, Layout, LightShown, MAX_DRAW_SIDE, Rendered, ViewState,
    sh_order_for_terms,
};
use crate::env::select::Weighting;
use crate::output::sheet::heat_color;
use crate::relight::Method;
use crate::relight::gpu::Gpu;
use crate::relight::sh_transfer::MAX_TRANSFER_ORDER;

mod images;

/// Width of the error heat maps' colour bar with its labels, points.
const BAR_POINTS: f32 = 64.0;
/// Width of the ramp in that bar, points.
const RAMP_POINTS: f32 = 12.0;

/// The window's GPU: the device, the transport's display path once uploaded, one view per pane.
struct WindowGpu {
    gpu: Gpu,
    render_state: eframe::egui_wgpu::RenderState,
    /// The engine's display path ([`DisplayPath`]), once the transport is on the GPU.
    display: Option<DisplayPath>,
    uploading: bool,
    /// Each view and its texture in egui.
    views: Vec<(GpuView, egui::TextureId)>,
    /// What the views show, and how long each took.
    shown: Option<ViewState>,
    timings: Vec<GpuTiming>,
}

/// The window.
pub struct ViewerApp {
    /// What is shown, as the controls set it.
    pub state: ViewState,
    /// The last error of a render (a bad environment file, ...).
    pub error: Option<String>,
    /// Notes from clamping the state.
    pub notes: Vec<String>,
    /// Why the file could not be opened.
    pub load_error: Option<String>,
    /// The last message of a save.
    pub saved: Option<String>,
    /// Zoom and pan of a per-pixel bake's images.
    pub viewport: Viewport,
    worker: TransportWorker,
    loaded: Option<Loaded>,
    /// The state last sent to the worker.
    sent: Option<ViewState>,
    /// The last CPU result, and its textures.
    rendered: Option<Rendered>,
    textures: Vec<egui::TextureHandle>,
    /// The heat ramp of the error maps' colour bar, made on first use.
    heat_ramp: Option<egui::TextureHandle>,
    light: Option<LightShown>,
    gpu: Option<WindowGpu>,
    gpu_error: Option<String>,
    /// Frame start times of the last second, for the frame rate.
    frames: VecDeque<f64>,
    path_edit: String,
    /// Where "Save" writes: a `.png` (what is shown) and an `.exr` (the first image, linear).
    pub save_stem: String,
    cli_envs: Vec<String>,
}

impl ViewerApp {
    /// Starts loading `file` on the worker thread; the window shows the progress, and a file that
    /// does not load leaves a message.
    pub fn new(file: &Path, envs: &[String]) -> ViewerApp {
        ViewerApp {
            state: ViewState::default(),
            error: None,
            notes: Vec::new(),
            load_error: None,
            saved: None,
            viewport: Viewport::default(),
            worker: TransportWorker::start(file, envs),
            loaded: None,
            sent: None,
            rendered: None,
            textures: Vec::new(),
            heat_ramp: None,
            light: None,
            gpu: None,
            gpu_error: None,
            frames: VecDeque::new(),
            path_edit: file.display().to_string(),
            save_stem: "prt-view".to_string(),
            cli_envs: envs.to_vec(),
        }
    }

    fn open(&mut self, file: &Path) {
        let gpu = self.gpu.take();
        let cli = self.cli_envs.clone();
        *self = ViewerApp::new(file, &cli);
        if let Some(g) = gpu {
            self.attach_render_state(g.render_state);
        }
    }

    /// Uses the window's wgpu device for relighting and draws GPU results without a readback.
    pub fn attach_render_state(&mut self, rs: eframe::egui_wgpu::RenderState) {
        match Gpu::from_device(rs.device.clone(), rs.queue.clone(), &rs.adapter.get_info()) {
            Ok(gpu) => {
                self.gpu = Some(WindowGpu {
                    gpu,
                    render_state: rs,
                    display: None,
                    uploading: false,
                    views: Vec::new(),
                    shown: None,
                    timings: Vec::new(),
                });
                // The window draws from the GPU kernels by default on a hardware GPU; a software
                // adapter is slower than the CPU kernels, so there the box starts unticked.
                self.state.display.gpu = !self.gpu.as_ref().is_some_and(|g| g.gpu.software);
                self.start_upload();
            }
            Err(e) => self.gpu_error = Some(e.to_string()),
        }
    }

    fn start_upload(&mut self) {
        if let (Some(g), Some(_)) = (&mut self.gpu, &self.loaded)
            && g.display.is_none()
            && !g.uploading
        {
            g.uploading = true;
            self.worker.worker.send(Job::Upload(g.gpu.clone()));
        }
    }

    /// Whether the worker has jobs in hand.
    pub fn busy(&self) -> bool {
        self.worker.worker.busy()
    }

    /// Whether the file has loaded.
    pub fn is_loaded(&self) -> bool {
        self.loaded.is_some()
    }

    /// The latest CPU result (numbers, images).
    pub fn rendered(&self) -> Option<&Rendered> {
        self.rendered.as_ref()
    }

    /// GPU timings of the panes shown from the GPU (empty when the CPU images are shown).
    pub fn gpu_timings(&self) -> &[GpuTiming] {
        match &self.gpu {
            Some(g) if self.showing_gpu() => &g.timings,
            _ => &[],
        }
    }

    /// Blocks until the worker has answered every job (for tests and scripts); the next frame
    /// shows the results. Returns whether it became idle within `timeout`.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        self.worker.worker.wait_idle(timeout)
    }

    /// Takes in what the worker finished (each frame does this first).
    pub fn poll(&mut self, ctx: &egui::Context) {
        while let Some(reply) = self.worker.worker.try_recv() {
            match reply {
                Reply::Loaded(Ok(loaded)) => {
                    let gpu = self.state.display.gpu;
                    self.state = loaded.state.clone();
                    self.state.display.gpu = gpu;
                    self.loaded = Some(loaded);
                    self.start_upload();
                }
                Reply::Loaded(Err(e)) => self.load_error = Some(e.to_string()),
                Reply::Light(light) => {
                    self.light = Some(light);
                    self.invalidate_gpu();
                }
                Reply::Rendered(Ok(r)) => {
                    self.error = None;
                    if !r.notes.is_empty() {
                        self.notes = r.notes.clone();
                    }
                    self.upload_cpu_textures(ctx, &r);
                    self.rendered = Some(r);
                }
                Reply::Rendered(Err(e)) => self.error = Some(e.to_string()),
                Reply::Exposure(Ok(e)) => self.state.display.exposure = e,
                Reply::Exposure(Err(e)) => self.error = Some(e.to_string()),
                Reply::Saved(Ok(stem)) => {
                    self.saved = Some(format!(
                        "saved {} and {}",
                        stem.with_extension("png").display(),
                        stem.with_extension("exr").display()
                    ))
                }
                Reply::Saved(Err(e)) => self.error = Some(e.to_string()),
                Reply::Uploaded(result) => {
                    if let Some(g) = &mut self.gpu {
                        g.uploading = false;
                        match result {
                            Ok(t) => g.display = Some(DisplayPath::new(t)),
                            Err(e) => self.gpu_error = Some(format!("GPU upload: {e}")),
                        }
                    }
                    self.invalidate_gpu();
                }
            }
        }
    }

    fn invalidate_gpu(&mut self) {
        if let Some(g) = &mut self.gpu {
            g.shown = None;
        }
    }

    fn upload_cpu_textures(&mut self, ctx: &egui::Context, r: &Rendered) {
        self.textures.truncate(r.panes.len());
        for (i, p) in r.panes.iter().enumerate() {
            let img = egui::ColorImage::from_rgb([r.width, r.height], &p.rgb);
            if let Some(t) = self.textures.get_mut(i) {
                t.set(img, egui::TextureOptions::LINEAR);
            } else {
                self.textures.push(ctx.load_texture(
                    format!("pane {i}"),
                    img,
                    egui::TextureOptions::LINEAR,
                ));
            }
        }
    }

    /// Whether the images come from the GPU: asked for, possible (no heat map), and drawn.
    fn showing_gpu(&self) -> bool {
        self.gpu_wanted()
            && self
                .gpu
                .as_ref()
                .is_some_and(|g| g.shown.as_ref() == Some(&self.state))
    }

    fn gpu_wanted(&self) -> bool {
        // The GPU raster draws the glossy lobe, not SH glossy transfer.
        self.state.display.gpu
            && !self.state.display.error_map
            && self.state.display.sh_transfer.is_none()
            && self.gpu.is_some()
    }

    /// Relights the current state on the GPU when it changed and its light is at hand; a failure
    /// turns the GPU display off with a message.
    fn draw_on_gpu(&mut self) {
        if !self.gpu_wanted() {
            return;
        }
        if let Err(e) = self.try_draw_on_gpu() {
            self.gpu_error = Some(format!("GPU display: {e}"));
            self.state.display.gpu = false;
        }
    }

    fn try_draw_on_gpu(&mut self) -> crate::Result<()> {
        let (Some(loaded), Some(lit), Some(g)) = (&self.loaded, &self.light, &mut self.gpu) else {
            return Ok(());
        };
        let Some(display) = &mut g.display else {
            return Ok(());
        };
        if g.shown.as_ref() == Some(&self.state) || lit.key != self.state.light.key(&loaded.envs) {
            return Ok(());
        }
        let camera = loaded.camera(&self.state);
        let (w, h) = match &camera {
            Some(c) => (c.width, c.height),
            None => (loaded.size.0 as u32, loaded.size.1 as u32),
        };
        let requests = self.state.requests(loaded.limits);
        let mut lights = self.state.lights.clone();
        lights.clamp(&loaded.transport.meta.lights);
        let mix = lights.mix(&loaded.transport.meta.lights)?;
        g.views.retain(|(v, _)| (v.width, v.height) == (w, h));
        while g.views.len() < requests.len() {
            let view = GpuView::new(&g.render_state.device, w, h);
            let id = g.render_state.renderer.write().register_native_texture(
                &g.render_state.device,
                &view.display.create_view(&Default::default()),
                wgpu::FilterMode::Linear,
            );
            g.views.push((view, id));
        }
        g.timings.clear();
        for ((_, request), (view, _)) in requests.iter().zip(&mut g.views) {
            let frame = Frame {
                request,
                lights: &mix,
                environment: self.state.lights.environment_shown(),
                camera: camera.as_ref(),
                tone: self.state.tone_map(),
            };
            let timing = display.draw(&g.gpu, &loaded.transport, &loaded.ctx, lit, &frame, view)?;
            g.timings.push(timing);
        }
        g.shown = Some(self.state.clone());
        Ok(())
    }

    /// Keyboard shortcuts: `M` method, `+`/`-` terms, `E` environment, `C` compare, `0` fit.
    fn keys(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let (m, plus, minus, e, c, fit) = ctx.input(|i| {
            (
                i.key_pressed(egui::Key::M),
                i.key_pressed(egui::Key::Plus) || i.key_pressed(egui::Key::Equals),
                i.key_pressed(egui::Key::Minus),
                i.key_pressed(egui::Key::E),
                i.key_pressed(egui::Key::C),
                i.key_pressed(egui::Key::Num0),
            )
        });
        let s = &mut self.state;
        if m {
            s.relight.cycle_method();
        }
        if plus {
            s.relight.terms = s.relight.terms.saturating_mul(2);
        }
        if minus {
            s.relight.terms = (s.relight.terms / 2).max(1);
        }
        if c {
            s.relight.compare = !s.relight.compare;
        }
        if fit {
            self.viewport = Viewport::default();
        }
        if let Some(l) = &self.loaded {
            if e {
                s.light.env = (s.light.env + 1) % l.envs.len().max(1);
            }
            s.relight.terms = s.relight.terms.clamp(1, l.limits.coeffs);
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        if self.file_controls(ui) {
            return;
        }
        self.settings(ui);
        ui.separator();
        self.numbers(ui);
    }

    /// The file row; returns whether a new file was opened.
    fn file_controls(&mut self, ui: &mut egui::Ui) -> bool {
        ui.horizontal(|ui| {
            let label = ui.label("File");
            ui.text_edit_singleline(&mut self.path_edit)
                .labelled_by(label.id);
        });
        if ui.button("Open").clicked() {
            let p = PathBuf::from(self.path_edit.clone());
            self.open(&p);
            return true;
        }
        ui.separator();
        false
    }

    /// Every setting of the view, from the method to saving (also what the panel snapshot
    /// tests draw: no file path, no timings).
    pub fn settings(&mut self, ui: &mut egui::Ui) {
        let Some(loaded) = &self.loaded else {
            if self.load_error.is_none() {
                let (read, total) = self.worker.progress();
                let fraction = if total > 0 {
                    read as f32 / total as f32
                } else {
                    0.0
                };
                ui.label(format!(
                    "Loading: {:.0} of {:.0} MiB",
                    read as f64 / (1 << 20) as f64,
                    total as f64 / (1 << 20) as f64
                ));
                ui.add(egui::ProgressBar::new(fraction).show_percentage());
            }
            return;
        };
        let limits = loaded.limits;
        // The light the window shows is not yet the one the settings ask for.
        let light_pending = self
            .light
            .as_ref()
            .is_none_or(|l| l.key != self.state.light.key(&loaded.envs));
        let s = &mut self.state;
        ui.heading("Method (M)");
        ui.horizontal(|ui| {
            ui.selectable_value(&mut s.relight.method, Method::Wavelet, "Wavelet");
            ui.selectable_value(&mut s.relight.method, Method::Sh, "SH");
            ui.selectable_value(&mut s.relight.method, Method::Full, "Full");
            ui.selectable_value(&mut s.relight.method, Method::ShLight, "SH (light)")
                .on_hover_text("SH of any order through the light, relit with every stored term");
        });
        ui.checkbox(&mut s.relight.compare, "Compare SH | wavelet (C)");
        if s.relight.compare {
            ui.horizontal(|ui| {
                ui.selectable_value(&mut s.display.layout, Layout::SideBySide, "Side by side");
                ui.selectable_value(&mut s.display.layout, Layout::Split, "Split");
            });
            if s.display.layout == Layout::Split {
                ui.add(
                    egui::Slider::new(&mut s.display.split, 0.0..=1.0).text("split (SH | wavelet)"),
                );
            }
        }
        ui.checkbox(&mut s.display.error_map, "Error heat map vs full");
        super::gpu_controls(
            ui,
            self.gpu.as_ref().map(|g| (&g.gpu, g.uploading)),
            &mut s.display.gpu,
        );
        ui.separator();
        // The kept terms on two rows: what they are, then the slider with its number field.
        let label = ui.label(format!("Kept terms K (+/-), 1 to {}", limits.coeffs));
        ui.horizontal(|ui| {
            ui.add(
                egui::Slider::new(&mut s.relight.terms, 1..=limits.coeffs)
                    .logarithmic(true)
                    .show_value(false),
            )
            .labelled_by(label.id);
            ui.label("K =");
            ui.add(egui::DragValue::new(&mut s.relight.terms).range(1..=limits.coeffs))
                .labelled_by(label.id);
        });
        egui::ComboBox::from_label("Weighting")
            .selected_text(s.relight.weighting.name())
            .show_ui(ui, |ui| {
                for w in Weighting::ALL {
                    ui.selectable_value(&mut s.relight.weighting, w, w.name());
                }
            });
        let most = match s.relight.method {
            Method::ShLight => limits.sh_light_order,
            _ => limits.sh_order,
        };
        ui.add(egui::Slider::new(&mut s.relight.sh_order, 1..=most).text("SH order"));
        if s.relight.compare {
            let n = sh_order_for_terms(s.relight.terms, limits.sh_order);
            ui.label(format!("compare uses SH order {n} ({} terms)", n * n));
        }
        ui.separator();
        super::light_controls(ui, "Environment (E)", &loaded.envs, &mut s.light);
        if !loaded.transport.meta.lights.is_empty() {
            ui.separator();
            super::lights_controls(ui, &loaded.transport.meta.lights, &mut s.lights);
        }
        if light_pending {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("preparing the light");
            });
        }
        if let Some(base) = &loaded.camera {
            ui.separator();
            camera::camera_controls(ui, &mut s.orbit, base);
            let mesh = loaded.transport.mesh();
            if mesh.is_some_and(|m| m.visibility.is_some()) {
                glossy_controls(ui, &mut s.display.sh_transfer);
            }
        }
        ui.separator();
        super::tone_controls(ui, &mut s.display.exposure, &mut s.display.tone);
        // Auto exposure and the zoom share a row.
        let auto = ui
            .horizontal(|ui| {
                let auto = ui.button("Auto exposure").clicked();
                if loaded.camera.is_none() {
                    ui.label(format!("zoom {:.1}x", self.viewport.zoom));
                    if ui.button("Fit (0)").clicked() {
                        self.viewport = Viewport::default();
                    }
                }
                auto
            })
            .inner;
        ui.separator();
        let save = ui
            .horizontal(|ui| {
                let label = ui.label("Save as");
                ui.add(egui::TextEdit::singleline(&mut self.save_stem).desired_width(110.0))
                    .labelled_by(label.id);
                ui.button("Save PNG + EXR").clicked()
            })
            .inner;
        if auto {
            self.worker
                .worker
                .send(Job::AutoExposure(self.state.clone()));
        }
        if save {
            self.saved = None;
            self.worker.worker.send(Job::Save(
                self.state.clone(),
                PathBuf::from(&self.save_stem),
            ));
        }
    }

    /// Terms, nonzeros, times, frame rate and errors of what is shown.
    fn numbers(&self, ui: &mut egui::Ui) {
        let stale = self
            .rendered
            .as_ref()
            .is_none_or(|r| r.state.relight_key() != self.state.relight_key());
        if self.worker.worker.busy() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("CPU relight and errors updating");
            });
        }
        if let Some(r) = &self.rendered {
            let panes = r.panes.iter().take(r.state.requests(self.limits()).len());
            for p in panes {
                let l = &p.linear;
                ui.strong(&l.title);
                ui.label(format!(
                    "terms used: {}, nonzeros touched: {:.2} M",
                    l.terms,
                    l.nonzeros_touched as f64 * 1e-6
                ));
                let mark = if stale { " (previous settings)" } else { "" };
                ui.label(format!(
                    "CPU {:.2} ms (kernel {:.2}), rel. L2 vs full {}{mark}",
                    l.relight_seconds * 1e3,
                    l.kernel_seconds * 1e3,
                    l.rel_l2_percent()
                ));
            }
            if r.light_seconds > 0.0 {
                // One line in the panel's width.
                ui.label(format!(
                    "light prepared in {:.1} ms, full image in {:.1} ms",
                    r.light_seconds * 1e3,
                    r.full_seconds * 1e3
                ))
                .on_hover_text("the full image is the reference of the errors");
            }
        }
        for (i, t) in self.gpu_timings().iter().enumerate() {
            let text = match t.kernel_seconds {
                Some(k) => format!(
                    "GPU pane {}: {:.2} ms (timestamps), {:.1} ms with tone map",
                    i + 1,
                    k * 1e3,
                    t.wall_seconds * 1e3
                ),
                None => format!(
                    "GPU pane {}: relight + tone map {:.2} ms (wall clock)",
                    i + 1,
                    t.wall_seconds * 1e3
                ),
            };
            ui.label(text);
        }
        if let Some(fps) = self.frame_rate() {
            ui.label(format!(
                "window: {fps:.1} frames/s ({:.1} ms a frame)",
                1e3 / fps.max(1e-9)
            ));
        }
        for n in &self.notes {
            ui.colored_label(egui::Color32::YELLOW, n);
        }
        if let Some(m) = &self.saved {
            ui.label(m);
        }
        for e in [&self.error, &self.gpu_error].into_iter().flatten() {
            ui.colored_label(egui::Color32::RED, e);
        }
    }

    fn limits(&self) -> super::Limits {
        self.loaded
            .as_ref()
            .map(|l| l.limits)
            .unwrap_or(super::Limits {
                coeffs: 1,
                sh_order: 1,
                sh_light_order: 1,
                envs: 1,
            })
    }

    /// Frames per second over the last second, once there are a few frames.
    fn frame_rate(&self) -> Option<f64> {
        let (first, last) = (self.frames.front()?, self.frames.back()?);
        (self.frames.len() >= 3 && last > first)
            .then(|| (self.frames.len() - 1) as f64 / (last - first))
    }

    /// The textures to draw with their titles: the GPU views when they show the current state,
    /// else the CPU images.
    fn shown(&self) -> Vec<(egui::TextureId, String)> {
        let titles: Vec<String> = match &self.rendered {
            Some(r) if !self.showing_gpu() => {
                r.panes.iter().map(|p| p.linear.title.clone()).collect()
            }
            _ => self
                .state
                .requests(self.limits())
                .into_iter()
                .map(|(t, _)| t)
                .collect(),
        };
        let ids: Vec<egui::TextureId> = match &self.gpu {
            Some(g) if self.showing_gpu() => g.views.iter().map(|(_, id)| *id).collect(),
            _ => self.textures.iter().map(|t| t.id()).collect(),
        };
        ids.into_iter().zip(titles).collect()
    }

    /// The whole window, drawn into `ui` (also what the UI tests drive).
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        let now = ctx.input(|i| i.time);
        self.frames.push_back(now);
        while self.frames.front().is_some_and(|t| now - t > 1.0) {
            self.frames.pop_front();
        }
        self.poll(&ctx);
        self.keys(&ctx);
        super::controls_panel(ui, "controls", 320.0, |ui| self.controls(ui));
        if let Some(l) = &self.loaded {
            let notes = self.state.clamp(l.limits);
            if self.sent.as_ref() != Some(&self.state) {
                // What was clamped stays noted until the next change.
                self.notes = notes;
                self.sent = Some(self.state.clone());
                self.worker.worker.send(Job::Render(self.state.clone()));
            }
        }
        self.draw_on_gpu();
        egui::CentralPanel::default_margins().show(ui, |ui| self.images(ui));
        if self.worker.worker.busy() {
            ctx.request_repaint_after(Duration::from_millis(30));
        }
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

/// The glossy light of a per-vertex bake with visibility: the lobe per pixel, or SH glossy
/// transfer at an order (drawn on the CPU).
fn glossy_controls(ui: &mut egui::Ui, sh_transfer: &mut Option<usize>) {
    let mut on = sh_transfer.is_some();
    ui.checkbox(&mut on, "Glossy light by SH transfer")
        .on_hover_text(
            "Sloan, Kautz & Snyder 2002: the light's low SH orders, shadowed per vertex, reflected \
             about the view per pixel; off: the GGX lobe per pixel from the kept terms",
        );
    *sh_transfer = match (on, *sh_transfer) {
        (false, _) => None,
        (true, Some(order)) => Some(order),
        (true, None) => Some(DEFAULT_TRANSFER_ORDER),
    };
    if let Some(order) = sh_transfer {
        ui.add(egui::Slider::new(order, 1..=MAX_TRANSFER_ORDER).text("transfer order"));
    }
}

/// The SH order the glossy transfer starts at when switched on.
const DEFAULT_TRANSFER_ORDER: usize = 6;
