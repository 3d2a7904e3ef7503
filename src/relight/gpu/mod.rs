//! Relighting on the GPU (wgpu compute): the tiled sparse wavelet product and the SH product of
//! [`crate::relight`], with the same inputs and the same results.
//!
//! One workgroup of [`WORKGROUP_SIZE`] threads relights one 16 x 16 tile (`shaders/common.wgsl`):
//! for every kept light term it walks that coefficient's column in the tile, each thread taking
//! every 256th entry. A column holds each row at most once, so the threads of one column never
//! write the same accumulator, and a barrier between columns orders the rest: no float atomics.
//! The accumulators sit in workgroup memory (up to 1024 rows per tile, 16 KiB; a tile usually has
//! one row per pixel and material), in device memory beyond that. Then each thread owns one pixel
//! and sums its rows. On a real GPU the entries of one column are contiguous, so a warp's loads
//! coalesce; thousands of tiles keep every compute unit busy. The SH pipeline needs no
//! cooperation: each thread dots its own pixel's SH rows with the SH light.
//!
//! The transport is uploaded once. Matrices larger than the device's storage-binding limit are
//! split by tiles into chunks, each with its own buffers and dispatch. Per relight, only the kept
//! light terms (16 bytes each) and a few parameters go up.
//!
//! [`raster`] draws a mesh with one colour per vertex, read from such a buffer, from any camera.

pub mod raster;
mod readback;
mod transport;

use wgpu::util::DeviceExt;

use crate::error::{PrtError, Result};
use crate::store::quant::BLOCK_ROWS;

pub use raster::{GpuMesh, GpuRaster, upload_colours};
use readback::Timer;
pub use readback::map_and_read;
pub(crate) use readback::wait_and_read;
pub use transport::{GpuBackend, GpuTransport, TERMS_PER_DISPATCH};

/// Threads per workgroup: one per pixel of a tile. The shaders receive it as `WORKGROUP`.
pub const WORKGROUP_SIZE: u32 =
    (crate::store::transport::TILE * crate::store::transport::TILE) as u32;
/// A device, its queue and the relight pipelines (cloning shares them).
#[derive(Clone)]
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Name, back-end and driver of the adapter, for messages.
    pub adapter: String,
    /// A software adapter (wgpu's device type `Cpu`: Mesa's lavapipe or llvmpipe, WARP): it runs
    /// the GPU kernels on the CPU, a correctness twin of the CPU kernels and far slower than
    /// them, so it is used only when asked for by name.
    pub software: bool,
    pub(crate) wavelet: wgpu::ComputePipeline,
    pub(crate) sh: wgpu::ComputePipeline,
    pub(crate) to_texture: wgpu::ComputePipeline,
    /// The 256 scales of the stored values' codes (`crate::store::quant`), a uniform buffer.
    pub(crate) scales: wgpu::Buffer,
    /// Timestamp queries around the relight passes, where the device has them.
    pub(crate) timer: Option<Timer>,
}

/// WGSL of a pipeline: the relight pipelines get the tile and workgroup sizes from here (the one
/// place they are defined) and the shared part in `shaders/common.wgsl`.
fn shader_source(pipeline: &str) -> String {
    let relight = |specific: &str| {
        format!(
            "const TILE: u32 = {}u;\nconst WORKGROUP: u32 = {WORKGROUP_SIZE}u;\n\
             const BLOCK_ROWS: u32 = {BLOCK_ROWS}u;\n{}\n{specific}",
            crate::store::transport::TILE,
            include_str!("../../../shaders/common.wgsl"),
        )
    };
    match pipeline {
        "wavelet" => relight(include_str!("../../../shaders/relight_wavelet.wgsl")),
        "sh" => relight(include_str!("../../../shaders/relight_sh.wgsl")),
        _ => include_str!("../../../shaders/to_texture.wgsl").to_string(),
    }
}

impl Gpu {
    /// Opens the first adapter wgpu finds (honouring `WGPU_BACKEND` and the other wgpu
    /// environment variables) with its full limits. Without an adapter the error says what to
    /// install.
    pub fn new() -> Result<Gpu> {
        Self::open(request_adapter()?)
    }

    /// A hardware GPU: the adapter [`Gpu::new`] would open, unless it is a software one
    /// ([`Gpu::software`]), which is an error saying so. What `--device auto` and the viewer
    /// start on.
    pub fn hardware() -> Result<Gpu> {
        let adapter = request_adapter()?;
        let info = adapter.get_info();
        if is_software(&info) {
            return Err(PrtError::Gpu(format!(
                "the only adapter, {}, is a software one: it runs the GPU kernels on the CPU, \
                 slower than the CPU kernels (ask for it with --device gpu)",
                adapter_name(&info)
            )));
        }
        Self::open(adapter)
    }

    fn open(adapter: wgpu::Adapter) -> Result<Gpu> {
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("wavelet-prt relight"),
            required_limits: adapter.limits(),
            required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
            ..Default::default()
        }))
        .map_err(|e| PrtError::Gpu(format!("opening {}: {e}", info.name)))?;
        Gpu::from_device(device, queue, &info)
    }

    /// Builds the pipelines on a device the caller already has (the viewer shares its own).
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: &wgpu::AdapterInfo,
    ) -> Result<Gpu> {
        let make = |name: &str| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(shader_source(name).into()),
            });
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let wavelet = make("wavelet");
        let sh = make("sh");
        let to_texture = make("to_texture");
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(PrtError::Gpu(format!(
                "building the relight pipelines: {e}"
            )));
        }
        let timer = Timer::new(&device, &queue);
        let scales = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("value scales"),
            contents: bytemuck::cast_slice(crate::store::quant::scale_table()),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        Ok(Gpu {
            device,
            queue,
            adapter: adapter_name(info),
            software: is_software(info),
            wavelet,
            sh,
            to_texture,
            scales,
            timer,
        })
    }

    /// Whether relight times come from GPU timestamp queries (else from the wall clock).
    pub fn has_timestamps(&self) -> bool {
        self.timer.is_some()
    }

    /// The GPU time of the relight passes of the last finished relight, from timestamp queries;
    /// `None` when the device has none. Call after the relight's submission has completed.
    pub fn last_kernel_seconds(&self) -> Option<f64> {
        self.timer.as_ref()?.read(&self.device)
    }

    /// The largest storage buffer one binding may hold on this device.
    pub fn max_binding_bytes(&self) -> u64 {
        let l = self.device.limits();
        l.max_storage_buffer_binding_size.min(l.max_buffer_size)
    }
}

/// The adapter wgpu ranks first (honouring `WGPU_BACKEND` and the other wgpu environment
/// variables; a hardware GPU before a software one). Without an adapter the error says what to
/// install.
fn request_adapter() -> Result<wgpu::Adapter> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
        ..Default::default()
    }))
    .map_err(|e| {
        PrtError::Gpu(format!(
            "no GPU adapter ({e}); without a GPU, install Mesa's software drivers \
             (Debian/Ubuntu: apt-get install mesa-vulkan-drivers) or use --device cpu"
        ))
    })
}

/// Name, back-end and driver of an adapter, for messages.
pub fn adapter_name(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {})", info.name, info.backend, info.driver)
}

/// Whether an adapter emulates a GPU on the CPU (see [`Gpu::software`]).
pub fn is_software(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}

/// A 2D texture of `width` x `height` texels: one mip level, one sample.
pub fn texture_2d(
    device: &wgpu::Device,
    label: &str,
    [width, height]: [u32; 2],
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}
