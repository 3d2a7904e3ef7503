//! Per-vertex bakes in the viewer: the GPU display path, where the relight kernels write the
//! vertex colours into the transport's image buffer and the raster draws them into the view's
//! texture, with nothing read back.

use std::sync::Arc;
use std::time::Instant;

use super::{GpuTiming, GpuView, LightKey, LightShown, backdrop};
use crate::error::Result;
use crate::output::film::{Image, ToneMap};
use crate::relight::gpu::{Gpu, GpuMesh, GpuRaster, GpuTransport};
use crate::relight::vertex::mesh_of;
use crate::relight::{LightContext, PreparedLight, RelightRequest, Terms};
use crate::scene::Camera;
use crate::store::transport::Transport;

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

/// A transport on the GPU and what draws it into a [`GpuView`]: the one display path, taken by
/// the window for every pane and by [`super::Engine::relight_to_view`], so the tests of the one
/// test the other.
pub struct DisplayPath {
    /// The transport, uploaded.
    pub transport: Arc<GpuTransport>,
    /// A per-vertex bake's mesh and raster, made on first use.
    mesh: Option<MeshDisplay>,
}

impl DisplayPath {
    /// The display path of a transport already on the GPU.
    pub fn new(transport: Arc<GpuTransport>) -> DisplayPath {
        DisplayPath {
            transport,
            mesh: None,
        }
    }

    /// Relights `request` under `lit` into `view` and tone-maps it as `tone` says: a per-pixel
    /// bake's image over the environment behind its open pixels, or, with a `camera`, a
    /// per-vertex bake drawn from it over the environment seen through it.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        gpu: &Gpu,
        t: &Transport,
        ctx: &LightContext,
        lit: &LightShown,
        request: &RelightRequest,
        camera: Option<&Camera>,
        view: &mut GpuView,
        tone: ToneMap,
    ) -> Result<GpuTiming> {
        let Some(camera) = camera else {
            view.hold_behind(&gpu.queue, &lit.behind);
            return super::relight_into_view(
                gpu,
                &self.transport,
                t,
                ctx,
                &lit.light,
                request,
                view,
                tone,
            );
        };
        if self.mesh.is_none() {
            self.mesh = Some(MeshDisplay::new(gpu, t)?);
        }
        let mesh = self.mesh.as_mut().expect("made above");
        let behind = mesh.backdrop(camera, lit)?;
        view.hold_behind(&gpu.queue, &behind);
        draw_into_view(
            gpu,
            &self.transport,
            t,
            ctx,
            &lit.light,
            request,
            mesh,
            camera,
            view,
            tone,
        )
    }
}
