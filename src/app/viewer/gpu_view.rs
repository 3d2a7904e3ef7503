//! The GPU display path: the relight kernels write linear radiance into an RGBA32F texture, and a
//! small compute pass applies the exposure and the sRGB curve into an RGBA8 texture that egui
//! samples directly (egui-wgpu expects gamma-encoded `Rgba8Unorm`). No image comes back to the
//! CPU.

use eframe::wgpu;

use crate::error::Result;
use crate::gpu::{Workgroup2, map_and_read, texture_2d, wgsl};
use crate::output::film::{Image, ToneMap};

const TONE_WGSL: &str = include_str!("../../../shaders/tonemap.wgsl");

/// The tone-map pass's workgroup (one thread per pixel).
const TONE_WORKGROUP: Workgroup2 = Workgroup2 { x: 16, y: 16 };

/// The layout of `Params` in `shaders/tonemap.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct ToneParams {
    /// 2^exposure.
    scale: f32,
    width: u32,
    height: u32,
    /// [`crate::output::film::ToneCurve::index`].
    curve: u32,
}
const _: () = assert!(std::mem::size_of::<ToneParams>() == 16);

/// The two textures of one image size and the tone-mapping pass between them.
pub struct GpuView {
    /// Width of the textures, pixels.
    pub width: u32,
    /// Height of the textures, pixels.
    pub height: u32,
    /// Linear radiance, written by the relight kernels (alpha 0) or drawn by the raster of a
    /// per-vertex bake (alpha its coverage).
    pub linear: wgpu::Texture,
    /// Exposed, sRGB-encoded RGBA8, for display.
    pub display: wgpu::Texture,
    /// The environment behind the scene (RGBA32F), added before tone mapping where `linear`
    /// leaves the pixel open (1 − alpha); black until [`GpuView::set_behind`].
    pub behind: wgpu::Texture,
    /// The image `behind` holds, to upload it again only when another comes.
    behind_of: Option<std::sync::Arc<Image>>,
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    group: wgpu::BindGroup,
}

impl GpuView {
    /// The textures and the pass for `width` x `height` images on `device`.
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> GpuView {
        use wgpu::{TextureFormat as F, TextureUsages as U};
        let texture =
            |label, format, usage| texture_2d(device, label, [width, height], format, usage);
        // Written by the relight and read by the pass; the display is copied out for a save.
        let shared = U::STORAGE_BINDING | U::TEXTURE_BINDING;
        let linear = texture(
            "relit linear",
            F::Rgba32Float,
            shared | U::RENDER_ATTACHMENT,
        );
        let display = texture("relit display", F::Rgba8Unorm, shared | U::COPY_SRC);
        let behind = texture(
            "environment behind",
            F::Rgba32Float,
            U::TEXTURE_BINDING | U::COPY_DST,
        );
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty,
            count: None,
        };
        // RGBA32F is not filterable everywhere; the pass only loads texels.
        let linear_texture = wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("tone map"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(1, linear_texture),
                entry(
                    2,
                    wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: wgpu::TextureFormat::Rgba8Unorm,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                ),
                entry(3, linear_texture),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("tone map"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("tone map"),
            source: wgpu::ShaderSource::Wgsl(
                wgsl(&TONE_WORKGROUP.constants(), &[TONE_WGSL]).into(),
            ),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("tone map"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let params = crate::gpu::buffer(
            device,
            "tone map params",
            std::mem::size_of::<ToneParams>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let linear_view = linear.create_view(&Default::default());
        let display_view = display.create_view(&Default::default());
        let behind_view = behind.create_view(&Default::default());
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("tone map"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&linear_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&display_view),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&behind_view),
                },
            ],
        });
        GpuView {
            width,
            height,
            linear,
            display,
            behind,
            behind_of: None,
            pipeline,
            params,
            group,
        }
    }

    /// [`GpuView::set_behind`] unless `image` is the one it already holds.
    pub fn hold_behind(&mut self, queue: &wgpu::Queue, image: &std::sync::Arc<Image>) {
        if self
            .behind_of
            .as_ref()
            .is_some_and(|h| std::sync::Arc::ptr_eq(h, image))
        {
            return;
        }
        self.set_behind(queue, image);
        self.behind_of = Some(image.clone());
    }

    /// Uploads the environment behind the scene (an image of this view's size; others are
    /// ignored, leaving the last one).
    pub fn set_behind(&self, queue: &wgpu::Queue, image: &Image) {
        if (image.width, image.height) != (self.width as usize, self.height as usize) {
            return;
        }
        let mut bytes = Vec::with_capacity(image.pixels.len() * 16);
        for p in &image.pixels {
            for v in [p[0], p[1], p[2], 0.0] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        queue.write_texture(
            self.behind.as_image_copy(),
            &bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(self.width * 16),
                rows_per_image: None,
            },
            self.behind.size(),
        );
    }

    /// Tone-maps `linear` plus `behind` into `display` as `tone` says.
    pub fn tone_map(&self, device: &wgpu::Device, queue: &wgpu::Queue, tone: ToneMap) {
        let params = ToneParams {
            scale: tone.exposure.exp2(),
            width: self.width,
            height: self.height,
            curve: tone.curve.index(),
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("tone map"),
        });
        let (pipeline, dims) = ((&self.pipeline, &self.group), [self.width, self.height]);
        TONE_WORKGROUP.pass(&mut encoder, "tone map", pipeline, dims);
        queue.submit([encoder.finish()]);
    }

    /// Reads `display` back as RGB8 (for tests and checks).
    pub fn read_rgb8(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Vec<u8>> {
        let row = (self.width * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let buffer = crate::gpu::buffer(
            device,
            "display readback",
            (row * self.height) as u64,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            self.display.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: None,
                },
            },
            self.display.size(),
        );
        queue.submit([encoder.finish()]);
        let (width, height) = (self.width as usize, self.height as usize);
        map_and_read(device, &buffer, "the display", |data| {
            let mut out = Vec::with_capacity(width * height * 3);
            for y in 0..height {
                let start = y * row as usize;
                for px in data[start..start + width * 4].chunks_exact(4) {
                    out.extend_from_slice(&px[..3]);
                }
            }
            out
        })
    }
}
