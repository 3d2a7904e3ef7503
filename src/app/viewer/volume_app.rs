//! The volume path of the viewer (`prt view FILE.prtv`): a medium relit from its SH self-transfer
//! by ray marching, with an orbit camera (drag to turn, scroll to move in and out), the
//! environment list and the sun of the transport viewer, the SH order, the debug views, and
//! exposure. A worker thread prepares the light and marches (on the GPU when the window has one);
//! the window shows the newest finished frame and never waits.

use std::path::Path;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use eframe::egui;
use glam::Vec3;

use super::{EnvEntry, EnvSource, env_entries};
use crate::error::Result;
use crate::gpu::GpuDevice;
use crate::light::envmap::{EnvMap, EnvRotation};
use crate::output::film::{Image, ToneCurve, ToneMap};
use crate::scene::Camera;
use crate::volume::gpu::GpuVolume;
use crate::volume::{PhaseLight, VolumeTransfer, VolumeView, render_volume};

/// Cube face size the environment is resampled to for the volume light.
const LIGHT_CUBE: usize = 32;

/// Every input of the volume view.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeState {
    pub view: VolumeView,
    pub sh_order: usize,
    pub env: usize,
    pub sun_elev: f64,
    pub sun_azim: f64,
    pub sun_radius: f64,
    pub yaw: f64,
    pub pitch: f64,
    /// Orbit around `target`: azimuth and elevation in degrees, distance.
    pub orbit_azim: f32,
    pub orbit_elev: f32,
    pub distance: f32,
    pub target: Vec3,
    pub exposure: f32,
    pub tone: ToneCurve,
    /// March on the GPU when the window has one.
    pub gpu: bool,
}

impl VolumeState {
    /// The state of `vt`'s baked camera.
    pub fn initial(vt: &VolumeTransfer) -> VolumeState {
        let c = &vt.meta.camera;
        let (eye, target) = (Vec3::from(c.eye), Vec3::from(c.target));
        let d = eye - target;
        let distance = d.length().max(1e-3);
        VolumeState {
            view: VolumeView::Full,
            sh_order: vt.meta.sh_order,
            env: 0,
            sun_elev: 30.0,
            sun_azim: 45.0,
            sun_radius: 2.0,
            yaw: 0.0,
            pitch: 0.0,
            orbit_azim: d.x.atan2(d.z).to_degrees(),
            orbit_elev: (d.y / distance).clamp(-1.0, 1.0).asin().to_degrees(),
            distance,
            target,
            exposure: 0.0,
            tone: ToneCurve::Aces,
            gpu: false,
        }
    }

    /// The orbit camera at the file's field of view and image size.
    pub fn camera(&self, vt: &VolumeTransfer) -> Camera {
        let (az, el) = (self.orbit_azim.to_radians(), self.orbit_elev.to_radians());
        let offset = Vec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
        Camera {
            eye: self.target + offset * self.distance,
            target: self.target,
            up: Vec3::Y,
            fov_y_deg: vt.meta.camera.fov_y_deg,
            width: vt.meta.width,
            height: vt.meta.height,
        }
    }

    fn light_key(&self, envs: &[EnvEntry]) -> (String, f64, f64, usize) {
        let spec = match envs.get(self.env).map(|e| &e.source) {
            Some(EnvSource::File(p)) => p.display().to_string(),
            _ => format!(
                "sun:{:.2},{:.2},{:.2}",
                self.sun_elev, self.sun_azim, self.sun_radius
            ),
        };
        (spec, self.yaw, self.pitch, self.sh_order)
    }
}

/// A finished frame.
pub struct VolumeFrame {
    pub state: VolumeState,
    pub image: Image,
    pub light_seconds: f64,
    pub march_seconds: f64,
    pub device: String,
}

/// Prepares lights and marches; what the window and `--screenshot` share.
pub struct VolumeEngine {
    pub vt: VolumeTransfer,
    pub envs: Vec<EnvEntry>,
    light: Option<((String, f64, f64, usize), PhaseLight)>,
    gpu: Option<(GpuDevice, GpuVolume)>,
}

impl VolumeEngine {
    pub fn new(vt: VolumeTransfer, envs: Vec<EnvEntry>) -> VolumeEngine {
        VolumeEngine {
            vt,
            envs,
            light: None,
            gpu: None,
        }
    }

    /// Marches on `gpu` from now on when a state asks for it.
    pub fn attach_gpu(&mut self, gpu: GpuDevice) -> Result<()> {
        let gv = GpuVolume::new(&gpu, &self.vt)?;
        self.gpu = Some((gpu, gv));
        Ok(())
    }

    pub fn has_gpu(&self) -> bool {
        self.gpu.is_some()
    }

    /// The linear frame of `state`.
    pub fn render(&mut self, state: &VolumeState) -> Result<VolumeFrame> {
        let key = state.light_key(&self.envs);
        let start = Instant::now();
        if self.light.as_ref().is_none_or(|(k, _)| *k != key) {
            let env = EnvMap::from_spec(&key.0)?;
            let cube = env.to_cube(
                LIGHT_CUBE,
                EnvRotation {
                    yaw_deg: key.1,
                    pitch_deg: key.2,
                },
            )?;
            let order = state.sh_order.clamp(1, self.vt.meta.sh_order);
            self.light = Some((key, PhaseLight::new(&cube, order, self.vt.meta.g)));
        }
        let light_seconds = start.elapsed().as_secs_f64();
        let (_, light) = self.light.as_ref().expect("prepared");
        let camera = state.camera(&self.vt);
        let start = Instant::now();
        let (image, device) = match &mut self.gpu {
            Some((gpu, gv)) if state.gpu => (
                gv.render(gpu, light, &camera, state.view)?.0,
                gpu.adapter.clone(),
            ),
            _ => (
                render_volume(&self.vt, light, &camera, state.view),
                "CPU".to_string(),
            ),
        };
        Ok(VolumeFrame {
            state: state.clone(),
            image,
            light_seconds,
            march_seconds: start.elapsed().as_secs_f64(),
            device,
        })
    }
}

/// Renders `state` and writes the tone-mapped PNG.
pub fn volume_screenshot(
    engine: &mut VolumeEngine,
    state: &VolumeState,
    out: &Path,
) -> Result<VolumeFrame> {
    let frame = engine.render(state)?;
    frame.image.check_finite("volume image")?;
    let tone = ToneMap {
        exposure: state.exposure,
        curve: state.tone,
    };
    let (w, h, rgb) = (
        frame.image.width,
        frame.image.height,
        frame.image.to_srgb8(tone),
    );
    crate::output::film::write_png(out, w, h, &rgb)?;
    Ok(frame)
}

#[derive(Default)]
struct Pending {
    count: Mutex<usize>,
    idle: Condvar,
}

/// The volume window.
pub struct VolumeApp {
    pub state: VolumeState,
    pub error: Option<String>,
    envs: Vec<EnvEntry>,
    vt_meta_order: usize,
    has_gpu: bool,
    jobs: Sender<VolumeState>,
    frames: Receiver<Result<VolumeFrame>>,
    pending: Arc<Pending>,
    sent: Option<VolumeState>,
    last: Option<VolumeFrame>,
    texture: Option<egui::TextureHandle>,
}

impl VolumeApp {
    /// Opens the window's state on a loaded volume; `gpu` marches on the window's device.
    pub fn new(vt: VolumeTransfer, cli_envs: &[String], gpu: Option<GpuDevice>) -> VolumeApp {
        let (envs, sun, selected) = env_entries(cli_envs);
        let mut state = VolumeState::initial(&vt);
        state.env = selected;
        (state.sun_elev, state.sun_azim) = sun;
        if let Some(r) = super::cli_sun_radius(cli_envs) {
            state.sun_radius = r;
        }
        let order = vt.meta.sh_order;
        let mut engine = VolumeEngine::new(vt, envs.clone());
        let mut error = None;
        if let Some(g) = gpu {
            match engine.attach_gpu(g) {
                Ok(()) => state.gpu = true,
                Err(e) => error = Some(format!("GPU march unavailable: {e}")),
            }
        }
        let has_gpu = engine.has_gpu();
        let (jobs, job_rx) = channel::<VolumeState>();
        let (frame_tx, frames) = channel();
        let pending = Arc::new(Pending::default());
        let p = pending.clone();
        std::thread::spawn(move || {
            while let Ok(mut state) = job_rx.recv() {
                let mut n = 1;
                for newer in job_rx.try_iter() {
                    state = newer;
                    n += 1;
                }
                let frame = engine.render(&state);
                if frame_tx.send(frame).is_err() {
                    return;
                }
                let mut c = p.count.lock().expect("pending");
                *c = c.saturating_sub(n);
                if *c == 0 {
                    p.idle.notify_all();
                }
            }
        });
        VolumeApp {
            state,
            error,
            envs,
            vt_meta_order: order,
            has_gpu,
            jobs,
            frames,
            pending,
            sent: None,
            last: None,
            texture: None,
        }
    }

    /// Blocks until every frame asked for is done (for tests); returns whether it finished in
    /// `timeout`.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        let c = self.pending.count.lock().expect("pending");
        let (c, _) = self
            .pending
            .idle
            .wait_timeout_while(c, timeout, |c| *c > 0)
            .expect("pending");
        *c == 0
    }

    pub fn busy(&self) -> bool {
        *self.pending.count.lock().expect("pending") > 0
    }

    /// The newest finished frame.
    pub fn frame(&self) -> Option<&VolumeFrame> {
        self.last.as_ref()
    }

    fn poll(&mut self, ctx: &egui::Context) {
        while let Ok(frame) = self.frames.try_recv() {
            match frame {
                Ok(f) => {
                    let tone = ToneMap {
                        exposure: self.state.exposure,
                        curve: self.state.tone,
                    };
                    self.upload(ctx, &f.image, tone);
                    self.error = None;
                    self.last = Some(f);
                }
                Err(e) => self.error = Some(e.to_string()),
            }
        }
    }

    fn upload(&mut self, ctx: &egui::Context, image: &Image, tone: ToneMap) {
        let img = egui::ColorImage::from_rgb([image.width, image.height], &image.to_srgb8(tone));
        match &mut self.texture {
            Some(t) => t.set(img, egui::TextureOptions::LINEAR),
            None => {
                self.texture = Some(ctx.load_texture("volume", img, egui::TextureOptions::LINEAR))
            }
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        let s = &mut self.state;
        ui.heading("Volume (SH self-transfer)");
        egui::ComboBox::from_label("View")
            .selected_text(s.view.name())
            .show_ui(ui, |ui| {
                for v in VolumeView::ALL {
                    ui.selectable_value(&mut s.view, v, v.name());
                }
            });
        ui.add(egui::Slider::new(&mut s.sh_order, 1..=self.vt_meta_order).text("SH order"));
        if self.has_gpu {
            ui.checkbox(&mut s.gpu, "March on the GPU");
        } else {
            ui.label("No GPU adapter: marching on the CPU");
        }
        ui.separator();
        super::light_controls(
            ui,
            "Environment",
            &self.envs,
            &mut s.env,
            [&mut s.sun_elev, &mut s.sun_azim, &mut s.sun_radius],
            [&mut s.yaw, &mut s.pitch],
        );
        ui.separator();
        ui.label("Camera: drag the image to orbit, scroll to move in and out");
        ui.add(egui::Slider::new(&mut s.orbit_azim, -180.0..=180.0).text("orbit azimuth°"));
        ui.add(egui::Slider::new(&mut s.orbit_elev, -89.0..=89.0).text("orbit elevation°"));
        ui.add(
            egui::Slider::new(&mut s.distance, 0.1..=50.0)
                .logarithmic(true)
                .text("distance"),
        );
        ui.separator();
        super::tone_controls(ui, &mut s.exposure, &mut s.tone);
        if let Some(f) = &self.last
            && ui.button("Auto exposure").clicked()
        {
            s.exposure = ToneMap::auto(&f.image, None).exposure;
        }
        ui.separator();
        if self.busy() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("marching");
            });
        }
        if let Some(f) = &self.last {
            ui.label(format!(
                "march {:.1} ms on {} ({}x{})",
                f.march_seconds * 1e3,
                f.device,
                f.image.width,
                f.image.height
            ));
            if f.light_seconds > 1e-4 {
                ui.label(format!("light prepared in {:.0} ms", f.light_seconds * 1e3));
            }
        }
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::RED, e);
        }
    }

    /// The whole window (also what the UI tests drive).
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        self.poll(&ctx);
        egui::Panel::left("volume controls")
            .resizable(true)
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        // Display-only changes re-tone-map the last frame; the rest asks the worker.
        let display_key = |s: &VolumeState| VolumeState {
            exposure: 0.0,
            tone: ToneCurve::Clip,
            ..s.clone()
        };
        if let Some(f) = &self.last
            && display_key(&f.state) == display_key(&self.state)
            && (f.state.exposure, f.state.tone) != (self.state.exposure, self.state.tone)
        {
            let image = f.image.clone();
            let tone = ToneMap {
                exposure: self.state.exposure,
                curve: self.state.tone,
            };
            self.upload(&ctx, &image, tone);
            if let Some(f) = &mut self.last {
                f.state.exposure = self.state.exposure;
                f.state.tone = self.state.tone;
            }
        }
        if self.sent.as_ref().map(display_key) != Some(display_key(&self.state)) {
            self.sent = Some(self.state.clone());
            *self.pending.count.lock().expect("pending") += 1;
            if self.jobs.send(self.state.clone()).is_err() {
                *self.pending.count.lock().expect("pending") -= 1;
            }
        }
        egui::CentralPanel::default_margins().show(ui, |ui| {
            let Some(tex) = &self.texture else {
                ui.centered_and_justified(|ui| ui.spinner());
                return;
            };
            let size = tex.size_vec2();
            let avail = ui.available_size();
            let scale = (avail.x / size.x).min(avail.y / size.y).max(0.01);
            let response =
                ui.add(egui::Image::new((tex.id(), size * scale)).sense(egui::Sense::drag()));
            if response.dragged() {
                let d = response.drag_delta();
                self.state.orbit_azim = (self.state.orbit_azim - d.x * 0.4 + 540.0) % 360.0 - 180.0;
                self.state.orbit_elev = (self.state.orbit_elev + d.y * 0.4).clamp(-89.0, 89.0);
            }
            if response.hovered() {
                let scroll = ui.input(|i| i.smooth_scroll_delta.y);
                if scroll != 0.0 {
                    self.state.distance =
                        (self.state.distance * (-scroll * 0.003).exp()).clamp(0.1, 50.0);
                }
            }
        });
        if self.busy() {
            ctx.request_repaint_after(Duration::from_millis(30));
        }
    }
}

impl eframe::App for VolumeApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}
