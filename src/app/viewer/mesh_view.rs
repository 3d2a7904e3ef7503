//! Per-vertex bakes in the viewer: the orbit camera's controls (drag to turn, scroll to move in
//! and out, sliders, reset) and the GPU display path, where the relight kernels write the vertex
//! colours into the transport's image buffer and the raster draws them into the view's texture,
//! with nothing read back.

use std::sync::Arc;
use std::time::Instant;

use eframe::egui;

use super::{GpuTiming, GpuView, LightKey, LightShown, backdrop};
use crate::error::Result;
use crate::output::film::{Image, ToneMap};
use crate::relight::gpu::{Gpu, GpuMesh, GpuRaster, GpuTransport};
use crate::relight::vertex::{Orbit, mesh_of};
use crate::relight::{LightContext, PreparedLight, RelightRequest, Terms};
use crate::scene::Camera;
use crate::store::transport::Transport;

/// Degrees the camera turns for each point the pointer is dragged.
pub const DRAG_DEGREES_PER_POINT: f32 = 0.4;

/// A per-vertex bake's mesh on the GPU, the raster that draws it, and the backdrop of the last
/// camera and light.
pub struct MeshDisplay {
    mesh: GpuMesh,
    raster: GpuRaster,
    backdrop: Option<(Camera, LightKey, Arc<Image>)>,
}

impl MeshDisplay {
    /// Uploads the mesh of `t` (an error for a per-pixel bake).
    pub fn new(gpu: &Gpu, t: &Transport) -> Result<MeshDisplay> {
        let mesh = mesh_of(t)?;
        Ok(MeshDisplay {
            mesh: GpuMesh::new(gpu, &mesh.positions, &mesh.triangles)?,
            raster: GpuRaster::new(gpu)?,
            backdrop: None,
        })
    }

    /// The environment behind the scene seen through `camera` under `light`, kept until either
    /// changes.
    pub fn backdrop(&mut self, camera: &Camera, light: &LightShown) -> Result<Arc<Image>> {
        match &self.backdrop {
            Some((c, k, image)) if c == camera && *k == light.key => Ok(image.clone()),
            _ => {
                let image = Arc::new(backdrop(camera, &light.map, &light.key)?);
                self.backdrop = Some((camera.clone(), light.key.clone(), image.clone()));
                Ok(image)
            }
        }
    }
}

/// Relights `request` under `light` with the transport already on the GPU, draws the vertex
/// colours from `camera` into `view` and tone-maps them over the view's backdrop: the display
/// path of a per-vertex bake.
#[allow(clippy::too_many_arguments)]
pub fn draw_into_view(
    gpu: &Gpu,
    gt: &GpuTransport,
    t: &Transport,
    ctx: &LightContext,
    light: &PreparedLight,
    request: &RelightRequest,
    mesh: &mut MeshDisplay,
    camera: &Camera,
    view: &GpuView,
    tone: ToneMap,
) -> Result<GpuTiming> {
    let start = Instant::now();
    let terms = Terms::of(t, ctx, light, request)?;
    gt.relight_terms_in_place(gpu, &terms)?;
    let kernel_seconds = gpu.last_kernel_seconds();
    mesh.raster
        .render(gpu, camera, &mesh.mesh, gt.image_buffer(), &view.linear)?;
    super::engine::tone_map_and_wait(gpu, view, tone, start, kernel_seconds)
}

/// Turns the orbit of `base` by a drag of `delta` points: dragging right turns the scene to the
/// right, dragging down raises the eye; the elevation stops where the eye stops.
pub fn drag(orbit: &mut Orbit, base: &Camera, delta: egui::Vec2) {
    orbit.azimuth_deg -= delta.x * DRAG_DEGREES_PER_POINT;
    let range = Orbit::elevation_range(base);
    orbit.elevation_deg = (orbit.elevation_deg + delta.y * DRAG_DEGREES_PER_POINT)
        .clamp(*range.start(), *range.end());
    orbit.clamp();
}

/// Moves the eye in (scrolling up) or out by a scroll of `points`.
pub fn dolly(orbit: &mut Orbit, points: f32) {
    orbit.distance *= (-points * 0.002).exp();
    orbit.clamp();
}

/// The camera section of the panel for a per-vertex bake made with `base`: azimuth, elevation
/// and distance from the bake's camera, and a reset.
pub fn camera_controls(ui: &mut egui::Ui, orbit: &mut Orbit, base: &Camera) {
    ui.heading("Camera");
    ui.label("drag the image to orbit, scroll to move in and out, double-click to reset");
    ui.add(egui::Slider::new(&mut orbit.azimuth_deg, -180.0..=180.0).text("orbit azimuth°"));
    ui.add(
        egui::Slider::new(&mut orbit.elevation_deg, Orbit::elevation_range(base))
            .text("orbit elevation°"),
    );
    ui.add(
        egui::Slider::new(&mut orbit.distance, Orbit::DISTANCE)
            .logarithmic(true)
            .text("distance (x baked)"),
    );
    if ui.button("Bake camera").clicked() {
        *orbit = Orbit::default();
    }
}
