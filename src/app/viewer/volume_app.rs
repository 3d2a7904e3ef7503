//! The volume path of the viewer (`prt view FILE.prtv`): a medium relit from its SH self-transfer
//! by ray marching, with an orbit camera (drag to turn, scroll to move in and out), the
//! environment list and the sun of the transport viewer, the SH order, the medium's look
//! (albedo, Henyey–Greenstein g and scattering orders, none of which needs a new bake), the
//! debug views, and exposure. A worker thread prepares the light and marches (on the GPU when the window has one);
//! the window shows the newest finished frame and never waits.

use std::path::Path;
use std::time::{Duration, Instant};

use eframe::egui;
use glam::Vec3;

use super::worker::{Worker, next_batch};
use super::{EnvEntry, LightKey, LightState, env_entries};
use crate::draw::vertex::Orbit;
use crate::error::Result;
use crate::gpu::GpuDevice;
use crate::math::cubemap::CubeMap;
use crate::output::film::{Image, ToneCurve, ToneMap};
use crate::scene::Camera;
use crate::volume::gpu::GpuVolume;
use crate::volume::{MediumLook, VolumeLight, VolumeTransfer, VolumeView, render_volume};

/// Cube face size the environment is resampled to for the volume light.
const LIGHT_CUBE: usize = 32;

/// Every input of the volume view: the view and SH order, the light (as in the transport
/// window), the orbit camera about the file's camera, and the display.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeState {
    /// What the march shows (the image, or one of its parts).
    pub view: VolumeView,
    /// SH order of the light (1 to the baked order).
    pub sh_order: usize,
    /// Single-scattering albedo per channel (order k is scaled by albedo^k).
    pub albedo: Vec3,
    /// Henyey–Greenstein asymmetry (exact for the last scattering of every order; the inner
    /// scatterings of orders 2 and above keep the baked g).
    pub g: f32,
    /// Scattering orders drawn, 1 to the file's; the orders beyond are added by their tail.
    pub orders: usize,
    /// The light.
    pub light: LightState,
    /// The camera, turned from the file's own.
    pub orbit: Orbit,
    /// Exposure in stops.
    pub exposure: f32,
    /// Display curve after the exposure.
    pub tone: ToneCurve,
    /// March on the GPU when the window has one.
    pub gpu: bool,
}

impl VolumeState {
    /// The state of `vt`'s baked camera.
    pub fn initial(vt: &VolumeTransfer) -> VolumeState {
        VolumeState {
            view: VolumeView::Full,
            sh_order: vt.meta.sh_order,
            albedo: Vec3::from(vt.meta.albedo),
            g: vt.meta.g,
            orders: vt.orders(),
            light: LightState::default(),
            orbit: Orbit::default(),
            exposure: 0.0,
            tone: ToneCurve::Aces,
            gpu: false,
        }
    }

    /// The orbit camera at the file's field of view and image size.
    pub fn camera(&self, vt: &VolumeTransfer) -> Camera {
        self.orbit.camera(&file_camera(vt))
    }

    /// The medium's look in this state, for `vt`.
    pub fn look(&self, vt: &VolumeTransfer) -> MediumLook {
        MediumLook {
            sh_order: self.sh_order.clamp(1, vt.meta.sh_order),
            albedo: self.albedo,
            g: self.g,
            orders: self.orders.clamp(1, vt.orders()),
            tail: vt.scatter.is_some(),
        }
    }

    /// The tone mapping of this state.
    pub fn tone_map(&self) -> ToneMap {
        ToneMap {
            exposure: self.exposure,
            curve: self.tone,
        }
    }

    /// Everything but the display: what a frame depends on.
    fn frame_key(&self) -> VolumeState {
        VolumeState {
            exposure: 0.0,
            tone: ToneCurve::Clip,
            ..self.clone()
        }
    }
}

/// The camera a volume was baked with, upright (+Y up), at its image size: what the orbit turns.
pub fn file_camera(vt: &VolumeTransfer) -> Camera {
    let c = &vt.meta.camera;
    Camera {
        eye: Vec3::from(c.eye),
        target: Vec3::from(c.target),
        up: Vec3::Y,
        fov_y_deg: c.fov_y_deg,
        width: vt.meta.width,
        height: vt.meta.height,
    }
}

/// A finished frame.
pub struct VolumeFrame {
    /// The state it shows.
    pub state: VolumeState,
    /// The marched image, linear RGB.
    pub image: Image,
    /// Time spent preparing the light (0 when it was kept), seconds.
    pub light_seconds: f64,
    /// Time of the march, seconds.
    pub march_seconds: f64,
    /// What marched it: the GPU adapter, or `CPU`.
    pub device: String,
}

/// Prepares lights and marches; what the window and `--screenshot` share.
pub struct VolumeEngine {
    /// The volume transfer, loaded.
    pub vt: VolumeTransfer,
    /// The environment list.
    pub envs: Vec<EnvEntry>,
    /// The phase light, with the light and SH order it was made for.
    /// The light prepared last: its key, the cube it came from and the light.
    light: Option<((LightKey, MediumLook), CubeMap, VolumeLight)>,
    gpu: Option<(GpuDevice, GpuVolume)>,
}

impl VolumeEngine {
    /// An engine on `vt` with the environment list `envs`, marching on the CPU.
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

    /// Whether a GPU march is attached.
    pub fn has_gpu(&self) -> bool {
        self.gpu.is_some()
    }

    /// The linear frame of `state`.
    pub fn render(&mut self, state: &VolumeState) -> Result<VolumeFrame> {
        let key = (state.light.key(&self.envs), state.look(&self.vt));
        let start = Instant::now();
        match self.light.take() {
            Some((k, cube, light)) if k == key => self.light = Some((k, cube, light)),
            // The same environment in another look: its cube, and its phase table where the SH
            // order and g are unchanged (an albedo or orders drag), are kept.
            Some((k, cube, light)) if k.0 == key.0 => {
                let light = light.with_look(&self.vt, &cube, &key.1)?;
                self.light = Some((key, cube, light));
            }
            _ => {
                let cube = key.0.env.load()?.to_cube(LIGHT_CUBE, key.0.rotation)?;
                let light = VolumeLight::new(&self.vt, &cube, &key.1)?;
                self.light = Some((key, cube, light));
            }
        }
        let light_seconds = start.elapsed().as_secs_f64();
        let (_, _, light) = self.light.as_ref().expect("prepared");
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
    let tone = state.tone_map();
    let (w, h, rgb) = (
        frame.image.width,
        frame.image.height,
        frame.image.to_srgb8(tone),
    );
    crate::output::film::write_png(out, w, h, &rgb)?;
    Ok(frame)
}

/// The volume window.
pub struct VolumeApp {
    /// What is shown, as the controls set it.
    pub state: VolumeState,
    /// The last error, shown in red under the controls.
    pub error: Option<String>,
    envs: Vec<EnvEntry>,
    vt_meta_order: usize,
    /// Scattering orders the file holds.
    most_orders: usize,
    /// The file's camera, which the orbit turns.
    base: Camera,
    has_gpu: bool,
    worker: Worker<VolumeState, Result<VolumeFrame>>,
    sent: Option<VolumeState>,
    last: Option<VolumeFrame>,
    texture: Option<egui::TextureHandle>,
}

impl VolumeApp {
    /// Opens the window's state on a loaded volume; `gpu` marches on the window's device.
    pub fn new(vt: VolumeTransfer, cli_envs: &[String], gpu: Option<GpuDevice>) -> VolumeApp {
        let (envs, light) = env_entries(cli_envs);
        let mut state = VolumeState {
            light,
            ..VolumeState::initial(&vt)
        };
        let (order, base, most_orders) = (vt.meta.sh_order, file_camera(&vt), vt.orders());
        let mut engine = VolumeEngine::new(vt, envs.clone());
        let mut error = None;
        if let Some(g) = gpu {
            match engine.attach_gpu(g) {
                Ok(()) => state.gpu = true,
                Err(e) => error = Some(format!("GPU march unavailable: {e}")),
            }
        }
        let has_gpu = engine.has_gpu();
        let worker = Worker::start(
            "prt-view volume worker",
            0,
            move |jobs, frames, pending| {
                // Of the states queued, only the newest is marched.
                while let Some(batch) = next_batch(&jobs) {
                    let n = batch.len();
                    if let Some(state) = batch.last()
                        && frames.send(engine.render(state)).is_err()
                    {
                        return;
                    }
                    pending.done(n);
                }
            },
            |e| Err(crate::error::PrtError::invalid("viewer", e)),
        );
        VolumeApp {
            state,
            error,
            envs,
            vt_meta_order: order,
            most_orders,
            base,
            has_gpu,
            worker,
            sent: None,
            last: None,
            texture: None,
        }
    }

    /// Blocks until every frame asked for is done (for tests); returns whether it finished in
    /// `timeout`.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        self.worker.wait_idle(timeout)
    }

    /// Whether frames are being marched.
    pub fn busy(&self) -> bool {
        self.worker.busy()
    }

    /// The newest finished frame.
    pub fn frame(&self) -> Option<&VolumeFrame> {
        self.last.as_ref()
    }

    fn poll(&mut self, ctx: &egui::Context) {
        while let Some(frame) = self.worker.try_recv() {
            match frame {
                Ok(f) => {
                    self.upload(ctx, &f.image, self.state.tone_map());
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
        let mut grey = s.albedo.max_element();
        if ui
            .add(egui::Slider::new(&mut grey, 0.0..=1.0).text("albedo"))
            .on_hover_text("Scales scattering order k by albedo^k, with no new bake")
            .changed()
        {
            s.albedo = Vec3::splat(grey);
        }
        ui.add(egui::Slider::new(&mut s.g, -0.95..=0.95).text("g (phase)"))
            .on_hover_text(
                "Henyey–Greenstein asymmetry: exact for single scattering and for the last \
                 scattering of higher orders; their inner scatterings keep the baked g",
            );
        if self.most_orders > 1 {
            ui.add(egui::Slider::new(&mut s.orders, 1..=self.most_orders).text("orders"))
                .on_hover_text("Scattering orders drawn; the orders beyond are extrapolated");
        }
        if self.has_gpu {
            ui.checkbox(&mut s.gpu, "March on the GPU");
        } else {
            ui.label("No GPU adapter: marching on the CPU");
        }
        ui.separator();
        super::light_controls(ui, "Environment", &self.envs, &mut s.light);
        ui.separator();
        super::camera::camera_controls(ui, &mut s.orbit, &self.base);
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
        super::controls_panel(ui, "volume controls", 300.0, |ui| self.controls(ui));
        // Display-only changes re-tone-map the last frame; the rest asks the worker.
        if let Some(f) = &self.last
            && f.state.frame_key() == self.state.frame_key()
            && (f.state.exposure, f.state.tone) != (self.state.exposure, self.state.tone)
        {
            let image = f.image.clone();
            self.upload(&ctx, &image, self.state.tone_map());
            if let Some(f) = &mut self.last {
                f.state.exposure = self.state.exposure;
                f.state.tone = self.state.tone;
            }
        }
        if self.sent.as_ref().map(VolumeState::frame_key) != Some(self.state.frame_key()) {
            self.sent = Some(self.state.clone());
            self.worker.send(self.state.clone());
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
            let scroll = response
                .hovered()
                .then(|| ui.input(|i| i.smooth_scroll_delta.y))
                .filter(|s| *s != 0.0);
            super::camera::interact(&mut self.state.orbit, &self.base, &response, scroll);
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
