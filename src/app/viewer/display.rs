//! The viewer's GPU display path ([`DisplayPath`]): the relight kernels write a per-pixel bake's
//! image straight into the view's texture, or a per-vertex bake's colours into the transport's
//! buffer, which the raster draws into it; then the tone map, with nothing read back.

use std::sync::Arc;
use std::time::Instant;

use eframe::wgpu;

use super::{GpuView, LightKey, LightShown, backdrop};
use crate::draw::gpu::{GpuMesh, GpuRaster};
use crate::draw::raster::DRAW_SAMPLES;
use crate::draw::vertex::mesh_of;
use crate::error::{PrtError, Result};
use crate::output::film::{Image, ToneMap};
use crate::relight::gpu::{Gpu, GpuTransport};
use crate::relight::{LightContext, LightMix, RelightRequest, Terms};
use crate::scene::Camera;
use crate::store::transport::Transport;

/// Wall and GPU time of one relight into a [`GpuView`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuTiming {
    /// From the first submission to the finished tone map, seconds.
    pub wall_seconds: f64,
    /// The relight passes alone, from GPU timestamp queries where the device has them.
    pub kernel_seconds: Option<f64>,
}

/// Tone-maps `view` as `tone` says and waits for the device: the end of a display draw begun
/// at `start`, whose relight passes took `kernel_seconds` by the timestamps.
fn tone_map_and_wait(
    gpu: &Gpu,
    view: &GpuView,
    tone: ToneMap,
    start: Instant,
    kernel_seconds: Option<f64>,
) -> Result<GpuTiming> {
    view.tone_map(&gpu.device, &gpu.queue, tone);
    gpu.device
        .poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: None,
        })
        .map_err(|e| PrtError::Gpu(format!("waiting for the tone map: {e}")))?;
    Ok(GpuTiming {
        wall_seconds: start.elapsed().as_secs_f64(),
        kernel_seconds,
    })
}

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
        Ok(MeshDisplay {
            mesh: GpuMesh::of_bake(gpu, mesh_of(t)?)?,
            raster: GpuRaster::multisampled(gpu, DRAW_SAMPLES)?,
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

/// What one frame of a display shows.
#[derive(Clone, Copy)]
pub struct Frame<'a> {
    /// The relight request: method, kept terms, weighting, SH order.
    pub request: &'a RelightRequest,
    /// The local lights' mix.
    pub lights: &'a LightMix,
    /// Whether the environment lights the scene and shows behind it.
    pub environment: bool,
    /// A per-vertex bake's camera; `None` for a per-pixel bake.
    pub camera: Option<&'a Camera>,
    /// How the result is tone-mapped.
    pub tone: ToneMap,
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

    /// Relights `frame` under `lit` into `view` and tone-maps it: a per-pixel bake's image over
    /// the environment behind its open pixels, or, with a camera, a per-vertex bake drawn from it
    /// over the environment seen through it.
    pub fn draw(
        &mut self,
        gpu: &Gpu,
        t: &Transport,
        ctx: &LightContext,
        lit: &LightShown,
        frame: &Frame,
        view: &mut GpuView,
    ) -> Result<GpuTiming> {
        let Frame {
            request,
            lights,
            environment,
            camera,
            tone,
        } = *frame;
        // The environment behind goes up before the clock starts: a per-pixel bake's comes
        // with the light, a per-vertex bake's is the environment seen through the camera.
        // With the environment off, nothing is behind: the local lights alone.
        let mesh = match camera {
            None => {
                match environment {
                    true => view.hold_behind(&gpu.queue, &lit.behind),
                    false => view.hold_behind(
                        &gpu.queue,
                        &Arc::new(Image::new(t.meta.width as usize, t.meta.height as usize)),
                    ),
                }
                None
            }
            Some(camera) => {
                if self.mesh.is_none() {
                    self.mesh = Some(MeshDisplay::new(gpu, t)?);
                }
                let mesh = self.mesh.as_mut().expect("made above");
                match environment {
                    true => view.hold_behind(&gpu.queue, &mesh.backdrop(camera, lit)?),
                    false => view.hold_behind(
                        &gpu.queue,
                        &Arc::new(Image::new(camera.width as usize, camera.height as usize)),
                    ),
                }
                Some((mesh, camera))
            }
        };
        let start = Instant::now();
        let terms = match environment {
            true => Terms::of(t, ctx, &lit.light, request)?,
            false => Terms::dark(),
        };
        let gt = &self.transport;
        let kernel_seconds = match mesh {
            None => {
                gt.relight_terms_to_texture(gpu, &terms, lights, &view.linear)?;
                gpu.last_kernel_seconds()
            }
            // The vertex colours stay in the transport's buffer, which the raster reads.
            Some((mesh, camera)) => {
                if mesh.mesh.has_lobe() {
                    // The lobe's light, as the request keeps it, from the CPU.
                    let env = environment.then_some(&*lit.light);
                    let lobe = crate::relight::lobe_light(t, ctx, env, request)?;
                    mesh.raster.set_light(gpu, lobe.as_ref())?;
                    let lit = crate::draw::lobe::lit_columns(&t.meta.lights, &lights.weights);
                    mesh.raster.set_lights(gpu, &lit)?;
                }
                gt.relight_terms_in_place(gpu, &terms, lights)?;
                let kernel_seconds = gpu.last_kernel_seconds();
                mesh.raster
                    .render(gpu, camera, &mesh.mesh, gt.image_buffer(), &view.linear)?;
                kernel_seconds
            }
        };
        tone_map_and_wait(gpu, view, tone, start, kernel_seconds)
    }
}
