//! Drawing a mesh with one colour per vertex on the GPU (a wgpu render pipeline,
//! `shaders/raster.wgsl`): the twin of the CPU rasteriser [`crate::draw::raster`], with the
//! same camera, culling and near plane, so the two give the same pixels but at exact edges. The
//! hardware rasterises and depth-tests; each fragment then takes the barycentrics of its pixel's
//! ray on its triangle as the CPU does, rather than the hardware's interpolation, which works
//! from corners snapped to a sub-pixel grid that differs between GPUs.
//!
//! The colours come from a storage buffer of `vec4<f32>` per vertex (vertex `i` at index `i`, the
//! layout of the relight's output image buffer when vertex `i` is its pixel `i`), so relit
//! colours need not leave the GPU. A glossy per-vertex bake's mesh
//! ([`crate::draw::shading::GlossMesh`], with visibility) evaluates each pixel's GGX lobe against
//! the light's pyramid ([`GpuRaster::set_light`]) and the vertices' visibility bits, as the
//! CPU's [`crate::draw::lobe::Lobe`] does. [`GpuRaster::draw`] renders offscreen and reads the image
//! and coverage back; [`GpuRaster::render`] draws into a caller's texture for display.
//!
//! Conventions: clip space comes from [`clip_from_world`] (NDC y up is the film's top row, as
//! wgpu's viewport puts NDC y = 1 on row 0, so no flip is needed), depth is reversed (`NEAR / w`
//! in Depth32Float, cleared to 0, `Greater` wins: the first of two equal depths stays, as on the
//! CPU) and triangles counter-clockwise in NDC are front faces, which is the CPU's rule that the
//! right-handed winding normal points at the eye.

use super::lights::{LIGHT_VEC4S, pack_light};
use super::mesh::TEXEL_BYTES;
pub use super::mesh::{GpuMesh, upload_colours};
use crate::draw::lobe::LitColumn;
use crate::draw::raster::{Frame, Raster, clip_from_world, sample_offsets};
use crate::error::{PrtError, Result};
use crate::gpu::GpuDevice as Gpu;
use crate::gpu::{map_and_read, texture_2d};
use crate::math::cube_pyramid::CubePyramid;
use crate::output::film::Image;
use crate::scene::Camera;

/// The colour target's format: linear RGB and coverage in alpha, unclamped.
pub const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Bytes of the view uniform: the clip transform, then eight 16-byte rows (the camera's frame,
/// the image size, the light pyramid's size, the lobe's shape and its tables' offsets).
const VIEW_BYTES: u64 = 64 + 8 * 16;

/// The textures of one image size: the offscreen colour target, the depth buffer and the buffer
/// the colours are read back through (rows padded to wgpu's copy alignment).
struct Targets {
    width: u32,
    height: u32,
    colour: wgpu::Texture,
    depth: wgpu::TextureView,
    readback: wgpu::Buffer,
    row_bytes: u32,
    /// With several samples a pixel: one layer per sample, and the view of each layer.
    layers: Option<(wgpu::TextureView, Vec<wgpu::TextureView>)>,
}

impl Targets {
    fn new(device: &wgpu::Device, width: u32, height: u32, samples: u32) -> Targets {
        let texture =
            |label, format, usage| texture_2d(device, label, [width, height], format, usage);
        let colour = texture(
            "raster colour",
            COLOUR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = texture(
            "raster depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        )
        .create_view(&Default::default());
        let row_bytes = (width * TEXEL_BYTES).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = crate::gpu::buffer(
            device,
            "raster readback",
            row_bytes as u64 * height as u64,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        let layers = (samples > 1).then(|| {
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("raster samples"),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: samples,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: COLOUR_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            });
            let all = texture.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            });
            let each = (0..samples)
                .map(|k| {
                    texture.create_view(&wgpu::TextureViewDescriptor {
                        dimension: Some(wgpu::TextureViewDimension::D2),
                        base_array_layer: k,
                        array_layer_count: Some(1),
                        ..Default::default()
                    })
                })
                .collect();
            (all, each)
        });
        Targets {
            width,
            height,
            colour,
            depth,
            readback,
            row_bytes,
            layers,
        }
    }
}

/// The render pipeline of `shaders/raster.wgsl`, a view uniform per sample, the resolve pipeline
/// of `shaders/raster_resolve.wgsl` with several samples a pixel, and the targets of the last
/// image size drawn.
pub struct GpuRaster {
    pipeline: wgpu::RenderPipeline,
    views: Vec<wgpu::Buffer>,
    offsets: &'static [[f32; 2]],
    resolve: Option<(wgpu::RenderPipeline, wgpu::BindGroupLayout)>,
    targets: Option<Targets>,
    /// The light a lobe is drawn from: its pyramid's face size and each node's mean radiance,
    /// level after level (one zero entry before [`GpuRaster::set_light`]), then the lit light
    /// columns ([`GpuRaster::set_lights`]), all in one buffer.
    light: (u32, wgpu::Buffer),
    /// The pyramid's node means, and the lit columns packed ([`pack_light`]), as the buffer
    /// holds them.
    means: Vec<[f32; 4]>,
    lights: Vec<[f32; 4]>,
}

impl GpuRaster {
    /// Builds the pipeline on `gpu`'s device, drawing one sample a pixel, at its centre.
    pub fn new(gpu: &Gpu) -> Result<GpuRaster> {
        GpuRaster::multisampled(gpu, 1)
    }

    /// Builds the pipeline on `gpu`'s device, drawing `samples` samples a pixel (1, 4 or 16, at the
    /// positions of [`sample_offsets`]), as [`crate::draw::raster::rasterize_with`]
    /// draws them: each sample in a pass of its own, then each pixel the mean of its samples.
    pub fn multisampled(gpu: &Gpu, samples: u32) -> Result<GpuRaster> {
        let offsets = sample_offsets(samples)?;
        let device = &gpu.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("raster"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../../../shaders/raster.wgsl").into()),
        });
        let pipeline = render_pipeline(
            device,
            "raster",
            &module,
            None,
            wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: Some(wgpu::Face::Back),
                ..Default::default()
            },
            Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Greater),
                stencil: Default::default(),
                bias: Default::default(),
            }),
        );
        let views = offsets
            .iter()
            .map(|_| {
                crate::gpu::buffer(
                    device,
                    "raster view",
                    VIEW_BYTES,
                    wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                )
            })
            .collect();
        let resolve = (offsets.len() > 1).then(|| resolve_pipeline(device));
        crate::gpu::end_scope(scope, "building the raster pipeline")?;
        let light = (0, light_buffer(device, &[[0.0; 4]]));
        Ok(GpuRaster {
            pipeline,
            views,
            offsets,
            resolve,
            targets: None,
            light,
            means: vec![[0.0; 4]],
            lights: Vec::new(),
        })
    }

    /// Sets the local light columns whose highlights a glossy bake with visibility draws, as
    /// the relight lit them ([`crate::draw::lobe::lit_columns`]), or none: the GPU twin of
    /// [`crate::draw::lobe::Lobe::with_lights`].
    pub fn set_lights(&mut self, gpu: &Gpu, lights: &[LitColumn]) -> Result<()> {
        let packed: Vec<[f32; 4]> = lights.iter().flat_map(pack_light).collect();
        let (n, means) = (self.light.0, std::mem::take(&mut self.means));
        self.fill_light(gpu, n, means, packed)
    }

    /// The light buffer made of a pyramid of face size `n` (0 for none) with node `means`, then
    /// the lit columns `lights`: an error where they outgrow one binding.
    fn fill_light(
        &mut self,
        gpu: &Gpu,
        n: u32,
        means: Vec<[f32; 4]>,
        lights: Vec<[f32; 4]>,
    ) -> Result<()> {
        let bytes = (means.len() + lights.len()) as u64 * TEXEL_BYTES as u64;
        if bytes > gpu.max_binding_bytes() {
            return Err(PrtError::invalid(
                "light",
                format!(
                    "a pyramid and lights of {bytes} bytes; the device binds at most {}",
                    gpu.max_binding_bytes()
                ),
            ));
        }
        let all: Vec<[f32; 4]> = means.iter().chain(&lights).copied().collect();
        self.light = (n, light_buffer(&gpu.device, &all));
        (self.means, self.lights) = (means, lights);
        Ok(())
    }

    /// Sets the light that the lobes of a bake with visibility are drawn from, as the relight
    /// used it (what [`crate::relight::lobe_light()`] gives), or none. Errors where its nodes
    /// outgrow one binding.
    pub fn set_light(&mut self, gpu: &Gpu, light: Option<&CubePyramid>) -> Result<()> {
        let lights = std::mem::take(&mut self.lights);
        let Some(p) = light else {
            return self.fill_light(gpu, 0, vec![[0.0; 4]], lights);
        };
        let means: Vec<[f32; 4]> = (0..p.levels.len())
            .flat_map(|level| {
                (0..p.levels[level].len()).map(move |i| {
                    let [r, g, b] = p.mean(i << (2 * level), level);
                    [r, g, b, 0.0]
                })
            })
            .collect();
        self.fill_light(gpu, p.n as u32, means, lights)
    }

    /// Draws `mesh` with per-vertex colours read from `colours` (a storage buffer of
    /// `vec4<f32>`, vertex `i`'s colour at index `i`, at least one per vertex) as `camera` sees
    /// it, offscreen, and reads the image (RGB) and coverage (alpha: 1 drawn, 0 not) back.
    pub fn draw(
        &mut self,
        gpu: &Gpu,
        camera: &Camera,
        mesh: &GpuMesh,
        colours: &wgpu::Buffer,
    ) -> Result<Raster> {
        self.check(gpu, camera, mesh, colours)?;
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.targets_for(gpu, camera);
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("raster"),
            });
        let t = self.targets.as_ref().expect("targets were just made");
        let colour = t.colour.create_view(&Default::default());
        self.encode(gpu, camera, mesh, colours, &colour, &mut encoder);
        encoder.copy_texture_to_buffer(
            t.colour.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &t.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(t.row_bytes),
                    rows_per_image: None,
                },
            },
            t.colour.size(),
        );
        gpu.queue.submit([encoder.finish()]);
        let (w, h, row) = (t.width as usize, t.height as usize, t.row_bytes as usize);
        let (pixels, coverage) = map_and_read(&gpu.device, &t.readback, "the raster", |bytes| {
            let mut pixels = Vec::with_capacity(w * h);
            let mut coverage = Vec::with_capacity(w * h);
            for y in 0..h {
                let texels: &[[f32; 4]] =
                    bytemuck::cast_slice(&bytes[y * row..y * row + w * TEXEL_BYTES as usize]);
                for p in texels {
                    pixels.push([p[0], p[1], p[2]]);
                    coverage.push(p[3]);
                }
            }
            (pixels, coverage)
        })?;
        crate::gpu::end_scope(scope, "raster")?;
        let image = Image {
            width: w,
            height: h,
            pixels,
        };
        image.check_finite("rasterised image")?;
        Ok(Raster { image, coverage })
    }

    /// Draws as [`GpuRaster::draw`] does into `target`, a [`COLOUR_FORMAT`] texture of the
    /// camera's size with render-attachment usage, without reading anything back: RGB the
    /// colours, alpha the coverage, cleared first.
    pub fn render(
        &mut self,
        gpu: &Gpu,
        camera: &Camera,
        mesh: &GpuMesh,
        colours: &wgpu::Buffer,
        target: &wgpu::Texture,
    ) -> Result<()> {
        self.check(gpu, camera, mesh, colours)?;
        let size = target.size();
        if (size.width, size.height) != (camera.width, camera.height)
            || target.format() != COLOUR_FORMAT
            || !target
                .usage()
                .contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
        {
            return Err(PrtError::invalid(
                "texture",
                format!(
                    "{}x{} {:?} with usage {:?}; expected {}x{} {COLOUR_FORMAT:?} with \
                     RENDER_ATTACHMENT",
                    size.width,
                    size.height,
                    target.format(),
                    target.usage(),
                    camera.width,
                    camera.height
                ),
            ));
        }
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("raster to texture"),
            });
        self.targets_for(gpu, camera);
        let view = target.create_view(&Default::default());
        self.encode(gpu, camera, mesh, colours, &view, &mut encoder);
        crate::gpu::submit_in_scope(&gpu.queue, encoder, scope, "raster to texture")
    }

    /// What both draws check before recording anything: the camera, the device's texture size
    /// limit, and a colour buffer with storage usage and a colour for every vertex.
    fn check(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        mesh: &GpuMesh,
        colours: &wgpu::Buffer,
    ) -> Result<()> {
        camera.validate()?;
        if mesh.has_lobe() && self.light.0 == 0 {
            return Err(PrtError::invalid(
                "light",
                "a glossy bake with visibility draws its highlights from the light: set the \
                 light the relight used first (GpuRaster::set_light)",
            ));
        }
        let limits = gpu.device.limits();
        let max = limits.max_texture_dimension_2d;
        let readback = (camera.width * TEXEL_BYTES)
            .next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) as u64
            * camera.height as u64;
        if camera.width.max(camera.height) > max || readback > limits.max_buffer_size {
            return Err(PrtError::invalid(
                "camera",
                format!(
                    "{}x{} image; the device draws at most {max} pixels a side and reads back \
                     at most {} bytes",
                    camera.width, camera.height, limits.max_buffer_size
                ),
            ));
        }
        let need = mesh.vertices as u64 * TEXEL_BYTES as u64;
        if colours.size() < need
            || need > gpu.max_binding_bytes()
            || !colours.usage().contains(wgpu::BufferUsages::STORAGE)
        {
            return Err(PrtError::invalid(
                "colours",
                format!(
                    "a buffer of {} bytes with usage {:?}; {} vertices need {need} bytes of \
                     vec4<f32> with STORAGE usage, in one binding of at most {}",
                    colours.size(),
                    colours.usage(),
                    mesh.vertices,
                    gpu.max_binding_bytes()
                ),
            ));
        }
        Ok(())
    }

    /// Makes the targets for the camera's image size, unless the last ones have that size.
    fn targets_for(&mut self, gpu: &Gpu, camera: &Camera) {
        let (w, h) = (camera.width, camera.height);
        if self
            .targets
            .as_ref()
            .is_none_or(|t| (t.width, t.height) != (w, h))
        {
            self.targets = Some(Targets::new(&gpu.device, w, h, self.offsets.len() as u32));
        }
    }

    /// Records the render passes into `colour` (with the depth buffer of the current targets):
    /// straight into it with one sample a pixel, else one pass per sample into its layer and the
    /// resolve into `colour`.
    fn encode(
        &self,
        gpu: &Gpu,
        camera: &Camera,
        mesh: &GpuMesh,
        colours: &wgpu::Buffer,
        colour: &wgpu::TextureView,
        encoder: &mut wgpu::CommandEncoder,
    ) {
        let t = self
            .targets
            .as_ref()
            .expect("targets are made before encoding");
        let f = Frame::new(camera);
        for (k, (&offset, view)) in self.offsets.iter().zip(&self.views).enumerate() {
            let mut uniform = clip_from_world(camera, offset).to_cols_array().to_vec();
            uniform.extend(f.eye.extend(0.0).to_array());
            uniform.extend(f.right.extend(f.half_w).to_array());
            uniform.extend(f.up.extend(f.half_h).to_array());
            uniform.extend(f.forward.extend(0.0).to_array());
            uniform.extend([
                camera.width as f32,
                camera.height as f32,
                offset[0],
                offset[1],
            ]);
            let lit = (self.lights.len() / LIGHT_VEC4S) as u32;
            let pyramid = [
                self.light.0,
                lit,
                self.means.len() as u32,
                mesh.light_columns,
            ];
            uniform.extend(pyramid.map(f32::from_bits));
            uniform.extend(mesh.lobe_shape.map(f32::from_bits));
            debug_assert_eq!(uniform.len() as u64 * 4, VIEW_BYTES);
            gpu.queue
                .write_buffer(view, 0, bytemuck::cast_slice(&uniform));
            let target = match &t.layers {
                Some((_, each)) => &each[k],
                None => colour,
            };
            self.draw_pass(gpu, (mesh, colours), view, (target, &t.depth), encoder);
        }
        if let (Some((pipeline, layout)), Some((all, _))) = (&self.resolve, &t.layers) {
            let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("raster resolve"),
                layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(all),
                }],
            });
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("raster resolve"),
                color_attachments: &[Some(cleared(colour))],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.draw(0..3, 0..1);
        }
    }

    /// Records one sample's pass: the mesh with its colours drawn with `view`'s uniform into
    /// `target`, with the `depth` buffer cleared first.
    fn draw_pass(
        &self,
        gpu: &Gpu,
        (mesh, colours): (&GpuMesh, &wgpu::Buffer),
        view: &wgpu::Buffer,
        (target, depth): (&wgpu::TextureView, &wgpu::TextureView),
        encoder: &mut wgpu::CommandEncoder,
    ) {
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raster"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: view.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    // The vertices' colours only: the buffer may hold more (checked to hold as
                    // many), and an empty mesh still binds one.
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: colours,
                        offset: 0,
                        size: wgpu::BufferSize::new(
                            (mesh.vertices.max(1) as u64 * TEXEL_BYTES as u64).min(colours.size()),
                        ),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: mesh.maps.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: mesh.levels.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: mesh.texels.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: mesh.table.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: mesh.indices.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 7,
                    resource: mesh.gloss.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 8,
                    resource: self.light.1.as_entire_binding(),
                },
            ],
        });
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("raster"),
            color_attachments: &[Some(cleared(target))],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if mesh.index_count == 0 {
            return;
        }
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group, &[]);
        // Not indexed: the shader reads each corner's vertex from `indices` itself.
        pass.draw(0..mesh.index_count, 0..1);
    }
}

/// A storage buffer of a light pyramid's node means.
fn light_buffer(device: &wgpu::Device, means: &[[f32; 4]]) -> wgpu::Buffer {
    crate::gpu::buffer_with(
        device,
        "raster light",
        bytemuck::cast_slice(means),
        wgpu::BufferUsages::STORAGE,
    )
}

/// The resolve pipeline (`shaders/raster_resolve.wgsl`) into a [`COLOUR_FORMAT`] target, and its
/// bind group's layout: the samples' layers, read with `textureLoad` (32-bit floats are not
/// filterable everywhere, so the layout says so rather than being derived).
fn resolve_pipeline(device: &wgpu::Device) -> (wgpu::RenderPipeline, wgpu::BindGroupLayout) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("raster resolve"),
        source: wgpu::ShaderSource::Wgsl(
            include_str!("../../../shaders/raster_resolve.wgsl").into(),
        ),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("raster resolve"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
            count: None,
        }],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("raster resolve"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = render_pipeline(
        device,
        "raster resolve",
        &module,
        Some(&pipeline_layout),
        Default::default(),
        None,
    );
    (pipeline, layout)
}

/// A render pipeline of `module`'s `vertex` and `fragment` entry points, with no vertex buffers,
/// into one [`COLOUR_FORMAT`] target.
fn render_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: Option<&wgpu::PipelineLayout>,
    primitive: wgpu::PrimitiveState,
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout,
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vertex"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive,
        depth_stencil,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fragment"),
            compilation_options: Default::default(),
            targets: &[Some(COLOUR_FORMAT.into())],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A colour attachment of `view`, cleared to transparent black and stored.
fn cleared(view: &wgpu::TextureView) -> wgpu::RenderPassColorAttachment<'_> {
    wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
            store: wgpu::StoreOp::Store,
        },
    }
}
