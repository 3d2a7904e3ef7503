//! The local lights on the GPU: their columns resident beside the transport, and the pass that
//! adds the lights that are on to the relit image (`shaders/relight_lights.wgsl`), after the
//! environment's product and in the same submission.

use std::mem::offset_of;

use super::{Gpu, LIGHTS_WORKGROUP};
use crate::error::{PrtError, Result};
use crate::scene::light_mix::LightMix;
use crate::store::transport::LightColumns;

/// The pass's uniform block (`Params` in the shader).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    width: u32,
    height: u32,
    count: u32,
    pixels: u32,
}
const _: () = assert!(std::mem::size_of::<Params>() == 16);

/// A transport's light columns on the device, bound to its image buffer.
pub struct GpuLights {
    columns: usize,
    width: u32,
    height: u32,
    params: wgpu::Buffer,
    mix: wgpu::Buffer,
    group: wgpu::BindGroup,
}

impl GpuLights {
    /// Uploads `lights` (none: `None`) for the image buffer `image`, checking every binding
    /// against `limit` bytes.
    pub fn upload(
        gpu: &Gpu,
        lights: &LightColumns,
        image: &wgpu::Buffer,
        limit: u64,
    ) -> Result<Option<GpuLights>> {
        let columns = lights.count();
        if columns == 0 {
            return Ok(None);
        }
        let device = &gpu.device;
        let value_bytes = (lights.values.len().div_ceil(2) * 4) as u64;
        if value_bytes > limit {
            return Err(PrtError::Gpu(format!(
                "the {columns} light columns need {value_bytes} bytes in one binding; this \
                 device allows {limit}: relight with --device cpu"
            )));
        }
        // Two integers a word, the last padded.
        let mut words = vec![0u32; lights.values.len().div_ceil(2)];
        for (i, v) in lights.values.iter().enumerate() {
            words[i / 2] |= (*v as u32) << (16 * (i % 2));
        }
        let storage = |label: &str, bytes: &[u8]| {
            crate::gpu::buffer_with(device, label, bytes, wgpu::BufferUsages::STORAGE)
        };
        let values = storage("light columns", bytemuck::cast_slice(&words));
        let scale_buf = storage("light scales", bytemuck::cast_slice(&lights.scale));
        let mix = crate::gpu::buffer(
            device,
            "light mix",
            (columns * 16) as u64,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        let params = crate::gpu::buffer_with(
            device,
            "light params",
            bytemuck::bytes_of(&Params {
                width: lights.width as u32,
                height: lights.height as u32,
                count: 0,
                pixels: (lights.width * lights.height) as u32,
            }),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let layout = gpu.lights.get_bind_group_layout(0);
        let entries: Vec<wgpu::BindGroupEntry> = [&params, &values, &scale_buf, &mix, image]
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lights"),
            layout: &layout,
            entries: &entries,
        });
        Ok(Some(GpuLights {
            columns,
            width: lights.width as u32,
            height: lights.height as u32,
            params,
            mix,
            group,
        }))
    }

    /// Records the pass that adds `mix` (one weight per column) to the image; nothing when every
    /// light is off.
    pub fn encode(&self, gpu: &Gpu, encoder: &mut wgpu::CommandEncoder, mix: &LightMix) {
        let on: Vec<[f32; 4]> = mix
            .weights
            .iter()
            .enumerate()
            .filter(|(_, w)| w.iter().any(|v| *v != 0.0))
            .map(|(col, w)| [w[0], w[1], w[2], f32::from_bits(col as u32)])
            .collect();
        if on.is_empty() {
            return;
        }
        gpu.queue
            .write_buffer(&self.mix, 0, bytemuck::cast_slice(&on));
        gpu.queue.write_buffer(
            &self.params,
            offset_of!(Params, count) as u64,
            bytemuck::bytes_of(&(on.len() as u32)),
        );
        let (pipeline, dims) = ((&gpu.lights, &self.group), [self.width, self.height]);
        LIGHTS_WORKGROUP.pass(encoder, "lights", pipeline, dims);
    }

    /// Light columns on the device.
    pub fn columns(&self) -> usize {
        self.columns
    }
}
