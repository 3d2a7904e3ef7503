//! Relighting on the GPU (wgpu compute): the tiled sparse wavelet product and the SH product of
//! [`crate::relight`], with the same inputs and the same results.
//!
//! One workgroup of [`WORKGROUP_SIZE`] threads relights one 16 x 16 tile (`shaders/common.wgsl`):
//! for every kept light term it walks that coefficient's strips in the tile's blocks (the CPU
//! kernel's dense strips of 8 rows, [`crate::store::transport::strips`]), each thread taking
//! every 256th value. A column holds each row at most once, so the threads of one column never
//! write the same accumulator, and a barrier between columns orders the rest: no float atomics.
//! The accumulators sit in workgroup memory (up to 1024 rows per tile, 16 KiB; a tile usually has
//! one row per pixel and material), in device memory beyond that. Then each thread owns one pixel
//! and sums its rows. On a real GPU a column's strips are contiguous, so a warp's loads
//! coalesce; thousands of tiles keep every compute unit busy. The SH pipeline needs no
//! cooperation: each thread dots its own pixel's SH rows with the SH light.
//!
//! The transport is uploaded once. Matrices larger than the device's storage-binding limit are
//! split by tiles into chunks, each with its own buffers and dispatch. Per relight, only the kept
//! light terms (16 bytes each) and a few parameters go up.
//!
//! [`crate::draw::gpu`] draws a mesh with one colour per vertex, read from such a buffer, from
//! any camera.

mod backend;
mod lights;
mod transport;

use crate::error::Result;
use crate::gpu::{GpuDevice, Workgroup2, wgsl};
use crate::store::quant::BLOCK_ROWS;

pub use backend::GpuBackend;
pub use transport::{GpuTransport, TERMS_PER_DISPATCH};

/// Threads per workgroup of the relight kernels: one per pixel of a tile. The shaders receive it
/// as `WORKGROUP`.
pub const WORKGROUP_SIZE: u32 =
    (crate::store::transport::TILE * crate::store::transport::TILE) as u32;

/// The workgroup of the pass that copies a relit image into a texture (one thread per pixel).
pub const TO_TEXTURE_WORKGROUP: Workgroup2 = Workgroup2 { x: 16, y: 16 };

/// The workgroup of the pass that adds the local lights (one thread per pixel).
pub const LIGHTS_WORKGROUP: Workgroup2 = Workgroup2 { x: 16, y: 16 };

/// A device with the relight pipelines (cloning shares them). It dereferences to its
/// [`GpuDevice`], so `gpu.device`, `gpu.queue` and the adapter's facts read as on the base.
#[derive(Clone)]
pub struct Gpu {
    base: GpuDevice,
    pub(crate) wavelet: wgpu::ComputePipeline,
    pub(crate) sh: wgpu::ComputePipeline,
    pub(crate) to_texture: wgpu::ComputePipeline,
    pub(crate) lights: wgpu::ComputePipeline,
    /// The 256 scales of the stored values' codes (`crate::store::quant`), a uniform buffer.
    pub(crate) scales: wgpu::Buffer,
}

impl std::ops::Deref for Gpu {
    type Target = GpuDevice;
    fn deref(&self) -> &GpuDevice {
        &self.base
    }
}

/// WGSL of a relight pipeline: the tile, workgroup and block sizes from here (the one place they
/// are defined), the shared part in `shaders/common.wgsl`, then the pipeline's own.
fn relight_source(specific: &str) -> String {
    wgsl(
        &[
            ("TILE", crate::store::transport::TILE as u32),
            ("WORKGROUP", WORKGROUP_SIZE),
            ("BLOCK_ROWS", BLOCK_ROWS as u32),
        ],
        &[include_str!("../../../shaders/common.wgsl"), specific],
    )
}

impl Gpu {
    /// The relight pipelines on the first adapter wgpu finds ([`GpuDevice::open_first`]).
    pub fn new() -> Result<Gpu> {
        Self::on(GpuDevice::open_first()?)
    }

    /// The relight pipelines on a hardware GPU ([`GpuDevice::open_hardware`]): what `--device
    /// auto` and the viewer start on.
    pub fn hardware() -> Result<Gpu> {
        Self::on(GpuDevice::open_hardware()?)
    }

    /// Builds the pipelines on a device the caller already has (the viewer shares its own).
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: &wgpu::AdapterInfo,
    ) -> Result<Gpu> {
        Self::on(GpuDevice::from_device(device, queue, info))
    }

    /// Builds the relight pipelines on `base`.
    pub fn on(base: GpuDevice) -> Result<Gpu> {
        let wavelet = base.compute_pipeline(
            "relight wavelet",
            &relight_source(include_str!("../../../shaders/relight_wavelet.wgsl")),
        )?;
        let sh = base.compute_pipeline(
            "relight SH",
            &relight_source(include_str!("../../../shaders/relight_sh.wgsl")),
        )?;
        let to_texture = base.image_pipeline(
            "to texture",
            TO_TEXTURE_WORKGROUP,
            include_str!("../../../shaders/to_texture.wgsl"),
        )?;
        let lights = base.image_pipeline(
            "lights",
            LIGHTS_WORKGROUP,
            include_str!("../../../shaders/relight_lights.wgsl"),
        )?;
        let scales = crate::gpu::buffer_with(
            &base.device,
            "value scales",
            bytemuck::cast_slice(crate::store::quant::scale_table()),
            wgpu::BufferUsages::UNIFORM,
        );
        Ok(Gpu {
            base,
            wavelet,
            sh,
            to_texture,
            lights,
            scales,
        })
    }
}
