//! Ray-marched volume relighting on the GPU (wgpu compute, `shaders/volume_march.wgsl`): the same
//! march as [`super::render_volume`], one thread per pixel. The density and the transfer grid are
//! uploaded once; per frame only the light (the phase-light table and the scattered field, when
//! the environment or the look changes), the camera and the view go up.

use super::{VolumeLight, VolumeTransfer, VolumeView};
use crate::error::{PrtError, Result};
use crate::gpu::{GpuDevice, Workgroup2, wait_and_read};
use crate::output::film::Image;
use crate::scene::Camera;

/// The march's workgroup (one thread per pixel).
const MARCH_WORKGROUP: Workgroup2 = Workgroup2 { x: 8, y: 8 };

/// The layout of `Params` in `shaders/volume_march.wgsl`: a vec3 and a scalar fill each 16-byte
/// row but the last, as WGSL lays out a uniform block, so the rows repeat one shape by design.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    eye: [f32; 3],
    width: u32,
    forward: [f32; 3],
    height: u32,
    right: [f32; 3],
    n2: u32,
    up: [f32; 3],
    view: u32,
    grid_min: [f32; 3],
    table_w: u32,
    cell: [f32; 3],
    table_h: u32,
    dims: [u32; 3],
    extinction: f32,
    albedo: [f32; 3],
    step: f32,
    g: f32,
    ms_n2: u32,
    pad: [u32; 2],
}
const _: () = assert!(std::mem::size_of::<Params>() == 144);

/// The most coefficients of the scattered field the march takes per voxel (SH order 3).
const MAX_FIELD_COEFFS: usize = 9;

/// The light as uploaded: the phase-light table and the scattered field (a 16-byte zero when
/// there is none).
struct Uploaded {
    light: VolumeLight,
    table: wgpu::Buffer,
    field: wgpu::Buffer,
}

/// A volume transfer resident on the GPU.
pub struct GpuVolume {
    pipeline: wgpu::ComputePipeline,
    density: wgpu::Buffer,
    transfer: wgpu::Buffer,
    params: wgpu::Buffer,
    light: Option<Uploaded>,
    base: Params,
}

impl GpuVolume {
    /// Uploads `vt` and builds the march pipeline.
    pub fn new(gpu: &GpuDevice, vt: &VolumeTransfer) -> Result<GpuVolume> {
        let device = &gpu.device;
        let bytes = (vt.transfer.len() * 4) as u64;
        if bytes > gpu.max_binding_bytes() {
            return Err(PrtError::Gpu(format!(
                "the transfer grid ({bytes} bytes) exceeds this device's storage binding limit \
                 ({} bytes); bake a smaller grid or a lower SH order",
                gpu.max_binding_bytes()
            )));
        }
        let pipeline = gpu.image_pipeline(
            "volume march",
            MARCH_WORKGROUP,
            include_str!("../../shaders/volume_march.wgsl"),
        )?;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let storage = |label, data: &[f32]| {
            crate::gpu::buffer_with(
                device,
                label,
                bytemuck::cast_slice(data),
                wgpu::BufferUsages::STORAGE,
            )
        };
        let density = storage("volume density", &vt.density);
        let transfer = storage("volume transfer", &vt.transfer);
        let params = crate::gpu::buffer(
            device,
            "volume params",
            std::mem::size_of::<Params>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        crate::gpu::end_scope(scope, "uploading the volume")?;
        let medium = vt.medium();
        let cell = medium.grid.cell();
        let base = Params {
            grid_min: vt.meta.min,
            cell: cell.to_array(),
            dims: vt.meta.dims.map(|d| d as u32),
            extinction: vt.meta.extinction,
            step: medium.camera_step(),
            ..Params::default()
        };
        Ok(GpuVolume {
            pipeline,
            density,
            transfer,
            params,
            light: None,
            base,
        })
    }

    /// Marches `camera`'s view of the medium lit by `light` and reads the image back. Returns
    /// the image and the GPU time (timestamp-free: wall time from submission to completion).
    pub fn render(
        &mut self,
        gpu: &GpuDevice,
        light: &VolumeLight,
        camera: &Camera,
        view: VolumeView,
    ) -> Result<(Image, f64)> {
        let n2 = light.phase.order * light.phase.order;
        let ms_n2 = light.scatter.as_ref().map_or(0, |s| s.angular.pow(2));
        if ms_n2 > MAX_FIELD_COEFFS {
            return Err(PrtError::invalid(
                "scattered field's SH order",
                "the GPU march takes up to order 3",
            ));
        }
        if n2 > 64 {
            return Err(PrtError::invalid(
                "SH order",
                "the GPU march takes up to order 8",
            ));
        }
        let device = &gpu.device;
        if self.light.as_ref().is_none_or(|u| &u.light != light) {
            let rgba = |v: &[[f32; 3]]| -> Vec<[f32; 4]> {
                v.iter().map(|c| [c[0], c[1], c[2], 0.0]).collect()
            };
            let storage = |label, data: &[[f32; 4]]| {
                crate::gpu::buffer_with(
                    device,
                    label,
                    bytemuck::cast_slice(data),
                    wgpu::BufferUsages::STORAGE,
                )
            };
            let field = match &light.scatter {
                Some(s) => rgba(&s.field),
                None => vec![[0.0; 4]],
            };
            let bytes = (field.len() * 16) as u64;
            if bytes > gpu.max_binding_bytes() {
                return Err(PrtError::Gpu(format!(
                    "the scattered field ({bytes} bytes) exceeds this device's storage binding \
                     limit ({} bytes); bake a smaller grid",
                    gpu.max_binding_bytes()
                )));
            }
            self.light = Some(Uploaded {
                light: light.clone(),
                table: storage("phase light", &rgba(&light.phase.table)),
                field: storage("scattered field", &field),
            });
        }
        let (w, h) = (camera.width, camera.height);
        let (forward, right, up) = camera.frame();
        let tan_half = (camera.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = w as f32 / h as f32;
        let params = Params {
            eye: camera.eye.to_array(),
            width: w,
            forward: forward.to_array(),
            height: h,
            right: (right * tan_half * aspect).to_array(),
            n2: n2 as u32,
            up: (up * tan_half).to_array(),
            view: view.index(),
            table_w: light.phase.width as u32,
            table_h: light.phase.height as u32,
            albedo: light.albedo.to_array(),
            g: light.g,
            ms_n2: ms_n2 as u32,
            ..self.base
        };
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let image_bytes = w as u64 * h as u64 * 16;
        let (image, readback) = crate::gpu::image_buffers(device, "volume image", w, h);
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let uploaded = self.light.as_ref().expect("uploaded");
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volume march"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.density.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: self.transfer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: uploaded.table.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: image.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: uploaded.field.as_entire_binding(),
                },
            ],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("volume march"),
        });
        MARCH_WORKGROUP.pass(
            &mut encoder,
            "volume march",
            (&self.pipeline, &group),
            [w, h],
        );
        encoder.copy_buffer_to_buffer(&image, 0, &readback, 0, image_bytes);
        let start = std::time::Instant::now();
        gpu.queue.submit([encoder.finish()]);
        let (pixels, seconds) = wait_and_read(device, &readback, start, "the volume march")?;
        crate::gpu::end_scope(scope, "volume march")?;
        Ok((
            Image {
                width: w as usize,
                height: h as usize,
                pixels,
            },
            seconds,
        ))
    }
}
