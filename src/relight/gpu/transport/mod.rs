//! A transport resident on the GPU: its strips, their slots and SH rows uploaded once (split
//! by tiles into chunks where a binding would exceed the device's limit), relit per request by
//! the wavelet and SH pipelines into a buffer read back, or into a texture for display.

mod upload;

use std::mem::offset_of;
use std::time::Instant;

use super::{Gpu, TO_TEXTURE_WORKGROUP};
use crate::env::select::SparseLight;
use crate::error::{PrtError, Result};
use crate::gpu::wait_and_read;
use crate::output::film::Image;
use crate::relight::{LightMix, RelightStats, Terms};

/// Most workgroups along one dispatch dimension (WebGPU's guaranteed minimum).
const MAX_DISPATCH: u32 = 65535;

/// Most wavelet terms one dispatch takes; more are run in batches that add to the image. Each
/// term costs a workgroup three barriers, and lavapipe (Mesa 22.3, LLVM 15) gives wrong images
/// past about 10,900 terms in one dispatch (right at 10,000, wrong at 11,000 on a 6x64²
/// bake), as if it kept 2^15 barriers at most; batches also bound the time of one dispatch, which
/// drivers with a watchdog limit.
pub const TERMS_PER_DISPATCH: usize = 4096;

/// Uniform parameters of one dispatch; the layout of `Params` in `shaders/common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    tile_base: u32,
    tile_count: u32,
    dispatch_x: u32,
    width: u32,
    height: u32,
    tiles_x: u32,
    coeffs: u32,
    terms: u32,
    format: u32,
    row_base: u32,
    shared_rows: u32,
    block_base: u32,
    block_table: u32,
    term_base: u32,
    accumulate: u32,
    values_base: u32,
}
const _: () = assert!(std::mem::size_of::<Params>() == 64);
// Fields written together are neighbours.
const _: () = assert!(offset_of!(Params, terms) == offset_of!(Params, coeffs) + 4);
const _: () = assert!(offset_of!(Params, accumulate) == offset_of!(Params, term_base) + 4);

/// Writes consecutive `u32` fields of a uniform block, from the field at `offset` on.
fn write_field(gpu: &Gpu, buffer: &wgpu::Buffer, offset: usize, words: &[u32]) {
    gpu.queue
        .write_buffer(buffer, offset as u64, bytemuck::cast_slice(words));
}

/// Tiles whose strips, slots and SH rows share one set of buffers.
struct Chunk {
    tiles: std::ops::Range<usize>,
    params: wgpu::Buffer,
    wavelet_group: wgpu::BindGroup,
    sh_group: wgpu::BindGroup,
}

/// A transport resident on the GPU.
pub struct GpuTransport {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) coeffs: usize,
    sh_count: usize,
    rows: usize,
    strips: u64,
    strip_bytes: u64,
    chunks: Vec<Chunk>,
    light: wgpu::Buffer,
    image: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// The local lights' columns, if the transport has any.
    lights: Option<super::lights::GpuLights>,
}

impl GpuTransport {
    /// Makes tiles with more than `rows` rows accumulate in device memory instead of workgroup
    /// memory (the shader caps it at 1024). Tests set 0 to exercise that path.
    pub fn set_shared_rows(&self, gpu: &Gpu, rows: u32) {
        for chunk in &self.chunks {
            write_field(gpu, &chunk.params, offset_of!(Params, shared_rows), &[rows]);
        }
    }

    /// Number of chunks the transport was split into.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Bytes per strip of 8 values on the device (its place and values).
    pub fn bytes_per_strip(&self) -> u64 {
        self.strip_bytes
    }

    fn wavelet_terms(&self, light: &SparseLight) -> Result<Vec<[f32; 4]>> {
        if light.indices.iter().any(|&j| j as usize >= self.coeffs)
            || light.is_empty()
            || light.indices.len() != light.values.len()
        {
            return Err(PrtError::invalid(
                "light",
                format!(
                    "its terms do not fit a transport with {} coefficients",
                    self.coeffs
                ),
            ));
        }
        Ok(light
            .indices
            .iter()
            .zip(&light.values)
            .map(|(j, v)| [v[0], v[1], v[2], f32::from_bits(*j)])
            .collect())
    }

    fn sh_terms(&self, sh: &[[f64; 3]]) -> Result<Vec<[f32; 4]>> {
        if sh.is_empty() || sh.len() > self.sh_count {
            return Err(PrtError::invalid(
                "SH light",
                format!(
                    "{} coefficients for a transport baked with {}",
                    sh.len(),
                    self.sh_count
                ),
            ));
        }
        Ok(sh
            .iter()
            .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32, 0.0])
            .collect())
    }

    /// Wavelet relighting with the kept terms of `light`, read back.
    pub fn relight_wavelet(&self, gpu: &Gpu, light: &SparseLight) -> Result<(Image, RelightStats)> {
        let terms = self.wavelet_terms(light)?;
        let (image, seconds) = self.run(gpu, &terms, true, &LightMix::none())?;
        Ok((
            image,
            RelightStats {
                terms: terms.len(),
                // Not counted on the device; `GpuBackend` counts them from the strips' slots.
                nonzeros_touched: 0,
                bytes_touched: 0,
                kernel_seconds: seconds,
                light_columns: 0,
            },
        ))
    }

    /// SH relighting with the first `sh.len()` SH coefficients of every row, read back.
    pub fn relight_sh(&self, gpu: &Gpu, sh: &[[f64; 3]]) -> Result<(Image, RelightStats)> {
        let terms = self.sh_terms(sh)?;
        let (image, seconds) = self.run(gpu, &terms, false, &LightMix::none())?;
        let touched = (self.rows * sh.len()) as u64;
        Ok((
            image,
            RelightStats {
                terms: sh.len(),
                nonzeros_touched: touched,
                bytes_touched: touched * 4,
                kernel_seconds: seconds,
                light_columns: 0,
            },
        ))
    }

    /// Relights with `terms` plus the local lights of `lights`, read back; the statistics are
    /// those of [`GpuTransport::relight_wavelet`] or [`GpuTransport::relight_sh`].
    pub fn relight_lit(
        &self,
        gpu: &Gpu,
        terms: &Terms,
        lights: &LightMix,
    ) -> Result<(Image, RelightStats)> {
        self.check_lights(lights)?;
        let (device_terms, wavelet) = self.device_terms(terms)?;
        let (image, seconds) = self.run(gpu, &device_terms, wavelet, lights)?;
        let touched = if wavelet {
            0
        } else {
            (self.rows * device_terms.len()) as u64
        };
        Ok((
            image,
            RelightStats {
                terms: terms.count(),
                nonzeros_touched: touched,
                bytes_touched: touched * 4,
                kernel_seconds: seconds,
                light_columns: lights.lit_columns(),
            },
        ))
    }

    /// The terms as the device takes them, and whether they are wavelet terms.
    fn device_terms(&self, terms: &Terms) -> Result<(Vec<[f32; 4]>, bool)> {
        Ok(match terms {
            Terms::Wavelet(light) | Terms::ShLight { haar: light, .. } => {
                (self.wavelet_terms(light)?, true)
            }
            Terms::Sh(sh) => (self.sh_terms(sh)?, false),
        })
    }

    /// Checks that `lights` fits the light columns on the device.
    fn check_lights(&self, lights: &LightMix) -> Result<()> {
        let columns = self.lights.as_ref().map_or(0, |l| l.columns());
        if lights.weights.is_empty() || lights.weights.len() == columns {
            Ok(())
        } else {
            Err(PrtError::invalid(
                "lights",
                format!(
                    "{} light weights for {columns} light columns on the device",
                    lights.weights.len()
                ),
            ))
        }
    }

    /// Relights with `terms` plus the local lights of `lights` into `texture` (RGBA32F,
    /// storage-binding usage, the image's size), with no readback: for display.
    pub fn relight_terms_to_texture(
        &self,
        gpu: &Gpu,
        terms: &Terms,
        lights: &LightMix,
        texture: &wgpu::Texture,
    ) -> Result<()> {
        self.check_lights(lights)?;
        let (device_terms, wavelet) = self.device_terms(terms)?;
        self.run_to_texture(gpu, &device_terms, wavelet, lights, texture)
    }

    /// Relights with `terms` into this transport's own image buffer and submits, with no
    /// readback: for a pass that reads [`GpuTransport::image_buffer`] next, such as the raster of
    /// a per-vertex bake (whose pixel `v · stride` is vertex `v`).
    pub fn relight_terms_in_place(
        &self,
        gpu: &Gpu,
        terms: &Terms,
        lights: &LightMix,
    ) -> Result<()> {
        self.check_lights(lights)?;
        let (terms, wavelet) = self.device_terms(terms)?;
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let (encoder, _) = self.encode(gpu, &terms, wavelet, lights, "relight in place");
        crate::gpu::submit_in_scope(&gpu.queue, encoder, scope, "relight in place")
    }

    /// The relit image on the device: one `vec4<f32>` per pixel, pixel `y · width + x`, alpha 1.
    pub fn image_buffer(&self) -> &wgpu::Buffer {
        &self.image
    }

    /// Uploads the terms and records the relight: one dispatch per chunk for each batch of at
    /// most [`TERMS_PER_DISPATCH`] terms, every batch after the first adding to the image.
    /// Batches before the last are submitted here; the last is left in the returned encoder for
    /// the caller to finish and submit. Also returns when the first submission was made (or the
    /// encoder created).
    fn encode(
        &self,
        gpu: &Gpu,
        terms: &[[f32; 4]],
        wavelet: bool,
        lights: &LightMix,
        label: &str,
    ) -> (wgpu::CommandEncoder, Instant) {
        let new_encoder = || {
            gpu.device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) })
        };
        gpu.queue
            .write_buffer(&self.light, 0, bytemuck::cast_slice(terms));
        // SH terms (at most 100) are one batch.
        let per_batch = if wavelet {
            TERMS_PER_DISPATCH
        } else {
            terms.len().max(1)
        };
        let batches = terms.len().div_ceil(per_batch).max(1);
        let n = self.chunks.len();
        let start = Instant::now();
        let mut encoder = new_encoder();
        for batch in 0..batches {
            if batch > 0 {
                // The parameter writes of this batch land after the dispatches of the last.
                gpu.queue
                    .submit([std::mem::replace(&mut encoder, new_encoder()).finish()]);
            }
            let first = batch * per_batch;
            let count = per_batch.min(terms.len() - first.min(terms.len()));
            for (i, chunk) in self.chunks.iter().enumerate() {
                // `coeffs` is the row stride (6 N² for wavelets, n² for SH), followed by `terms`;
                // `term_base` by `accumulate`.
                let stride = if wavelet { self.coeffs } else { self.sh_count } as u32;
                write_field(
                    gpu,
                    &chunk.params,
                    offset_of!(Params, coeffs),
                    &[stride, count as u32],
                );
                write_field(
                    gpu,
                    &chunk.params,
                    offset_of!(Params, term_base),
                    &[first as u32, (batch > 0) as u32],
                );
                let pass_index = batch * n + i;
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("relight"),
                    timestamp_writes: gpu
                        .timer
                        .as_ref()
                        .and_then(|t| t.writes(pass_index, batches * n)),
                });
                let (pipeline, group) = if wavelet {
                    (&gpu.wavelet, &chunk.wavelet_group)
                } else {
                    (&gpu.sh, &chunk.sh_group)
                };
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, group, &[]);
                let count = chunk.tiles.len() as u32;
                let x = count.min(MAX_DISPATCH);
                pass.dispatch_workgroups(x, count.div_ceil(x), 1);
            }
        }
        if let Some(l) = &self.lights {
            l.encode(gpu, &mut encoder, lights);
        }
        if let Some(t) = &gpu.timer {
            t.resolve(&mut encoder);
        }
        // Each chunk has its own parameter buffer, and queued writes land before the submission
        // that follows them; chunks touch disjoint tiles, rows and pixels.
        (encoder, start)
    }

    fn run_to_texture(
        &self,
        gpu: &Gpu,
        terms: &[[f32; 4]],
        wavelet: bool,
        lights: &LightMix,
        texture: &wgpu::Texture,
    ) -> Result<()> {
        let size = texture.size();
        if (size.width as usize, size.height as usize) != (self.width, self.height)
            || texture.format() != wgpu::TextureFormat::Rgba32Float
        {
            return Err(PrtError::invalid(
                "texture",
                format!(
                    "{}x{} {:?}; expected {}x{} Rgba32Float",
                    size.width,
                    size.height,
                    texture.format(),
                    self.width,
                    self.height
                ),
            ));
        }
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let (mut encoder, _) = self.encode(gpu, terms, wavelet, lights, "relight to texture");
        let dims = [self.width as u32, self.height as u32];
        let size_buf = crate::gpu::buffer_with(
            &gpu.device,
            "texture size",
            bytemuck::cast_slice(&dims),
            wgpu::BufferUsages::UNIFORM,
        );
        let view = texture.create_view(&Default::default());
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("to texture"),
            layout: &gpu.to_texture.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: size_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.image.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
            ],
        });
        TO_TEXTURE_WORKGROUP.pass(&mut encoder, "to texture", (&gpu.to_texture, &group), dims);
        crate::gpu::submit_in_scope(&gpu.queue, encoder, scope, "relight to texture")
    }

    /// Records the relight, reads the image back. Returns the image and the GPU time of the relight
    /// passes (timestamp queries), or where the device has none the wall time from submission to
    /// completion.
    fn run(
        &self,
        gpu: &Gpu,
        terms: &[[f32; 4]],
        wavelet: bool,
        lights: &LightMix,
    ) -> Result<(Image, f64)> {
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let (mut encoder, start) = self.encode(gpu, terms, wavelet, lights, "relight");
        encoder.copy_buffer_to_buffer(&self.image, 0, &self.readback, 0, self.image.size());
        gpu.queue.submit([encoder.finish()]);
        let (pixels, wall) = wait_and_read(&gpu.device, &self.readback, start, "the relight")?;
        crate::gpu::end_scope(scope, "relight")?;
        let seconds = gpu.last_kernel_seconds().unwrap_or(wall);
        Ok((
            Image {
                width: self.width,
                height: self.height,
                pixels,
            },
            seconds,
        ))
    }

    /// Strips on the device, for reporting.
    pub fn strip_count(&self) -> u64 {
        self.strips
    }
}
