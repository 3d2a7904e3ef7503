//! The GPU base stage: what every GPU pipeline of the crate stands on. Opening a device (the
//! adapter wgpu ranks first, or only a hardware one), assembling a pipeline's WGSL behind the
//! constants Rust defines for it (workgroup sizes included, so a dispatch and its shader never
//! disagree), building compute pipelines under a validation scope, 2D textures, reading buffers
//! back, and timestamp queries. The relight kernels ([`crate::relight::gpu`]), the volume march
//! ([`crate::volume::gpu`]) and the viewer's display pass build on it.
//!
//! Uniform blocks are `#[repr(C)]` [`bytemuck::Pod`] structs that mirror their WGSL `struct`
//! field by field (each asserts its size); a partial update writes a field at
//! [`std::mem::offset_of!`], never at a hand-counted byte offset.

mod readback;

pub use readback::{Timer, map_and_read, wait_and_read};

use crate::error::{PrtError, Result};

/// A device and its queue, with what messages and timings need to know of its adapter.
#[derive(Clone)]
pub struct GpuDevice {
    /// The wgpu device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Name, back-end and driver of the adapter, for messages.
    pub adapter: String,
    /// A software adapter (wgpu's device type `Cpu`: Mesa's lavapipe or llvmpipe, WARP): it runs
    /// the GPU kernels on the CPU, a correctness twin of the CPU kernels and far slower than
    /// them, so it is used only when asked for by name.
    pub software: bool,
    /// Timestamp queries around a run of passes, where the device has them.
    pub timer: Option<Timer>,
}

impl GpuDevice {
    /// Opens the first adapter wgpu finds (honouring `WGPU_BACKEND` and the other wgpu
    /// environment variables) with its full limits. Without an adapter the error says what to
    /// install.
    pub fn open_first() -> Result<GpuDevice> {
        Self::open(request_adapter()?)
    }

    /// A hardware GPU: the adapter [`GpuDevice::open_first`] would open, unless it is a
    /// software one ([`GpuDevice::software`]), which is an error saying so.
    pub fn open_hardware() -> Result<GpuDevice> {
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

    fn open(adapter: wgpu::Adapter) -> Result<GpuDevice> {
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("wavelet-prt"),
            required_limits: adapter.limits(),
            required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
            ..Default::default()
        }))
        .map_err(|e| PrtError::Gpu(format!("opening {}: {e}", info.name)))?;
        Ok(GpuDevice::from_device(device, queue, &info))
    }

    /// A device the caller already has (the viewer shares its own).
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: &wgpu::AdapterInfo,
    ) -> GpuDevice {
        let timer = Timer::new(&device, &queue);
        GpuDevice {
            device,
            queue,
            adapter: adapter_name(info),
            software: is_software(info),
            timer,
        }
    }

    /// Whether kernel times come from GPU timestamp queries (else from the wall clock).
    pub fn has_timestamps(&self) -> bool {
        self.timer.is_some()
    }

    /// The GPU time of the timed passes of the last finished submission, from timestamp
    /// queries; `None` when the device has none. Call after the submission has completed.
    pub fn last_kernel_seconds(&self) -> Option<f64> {
        self.timer.as_ref()?.read(&self.device)
    }

    /// The largest storage buffer one binding may hold on this device.
    pub fn max_binding_bytes(&self) -> u64 {
        let l = self.device.limits();
        l.max_storage_buffer_binding_size.min(l.max_buffer_size)
    }

    /// The pipeline of a pass with one thread per pixel: `source` behind the constants of its
    /// `workgroup` ([`Workgroup2`]).
    pub fn image_pipeline(
        &self,
        label: &str,
        workgroup: Workgroup2,
        source: &str,
    ) -> Result<wgpu::ComputePipeline> {
        self.compute_pipeline(label, &wgsl(&workgroup.constants(), &[source]))
    }

    /// A compute pipeline of `source`'s `main`, its bind group layout taken from the shader.
    /// Validation errors (a WGSL mistake, a limit the device lacks) are returned, naming
    /// `label`, not raised on the device.
    pub fn compute_pipeline(&self, label: &str, source: &str) -> Result<wgpu::ComputePipeline> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
        let pipeline = self
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
        end_scope(scope, &format!("building the {label} pipeline"))?;
        Ok(pipeline)
    }
}

/// Ends an error scope: the first error raised inside it (a validation error, say) as a GPU error
/// that names `what` was being done, or nothing.
pub fn end_scope(scope: wgpu::ErrorScopeGuard, what: &str) -> Result<()> {
    match pollster::block_on(scope.pop()) {
        Some(e) => Err(PrtError::Gpu(format!("{what}: {e}"))),
        None => Ok(()),
    }
}

/// Submits `encoder`'s commands and ends `scope` ([`end_scope`]): for work that nothing here
/// waits on, such as a draw into a texture shown next.
pub fn submit_in_scope(
    queue: &wgpu::Queue,
    encoder: wgpu::CommandEncoder,
    scope: wgpu::ErrorScopeGuard,
    what: &str,
) -> Result<()> {
    queue.submit([encoder.finish()]);
    end_scope(scope, what)
}

/// The threads of a workgroup of a pipeline with one thread per pixel: `x` by `y`. Defined once
/// in Rust: the shader gets it as `const WG_X` and `const WG_Y` ([`wgsl`]) for its
/// `@workgroup_size(WG_X, WG_Y)`, and the dispatch covers an image with it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Workgroup2 {
    /// Threads along x.
    pub x: u32,
    /// Threads along y.
    pub y: u32,
}

impl Workgroup2 {
    /// Its constants, as [`wgsl`] takes them.
    pub fn constants(self) -> [(&'static str, u32); 2] {
        [("WG_X", self.x), ("WG_Y", self.y)]
    }

    /// Workgroups along x and y that cover a `width` x `height` image.
    pub fn groups(self, width: u32, height: u32) -> [u32; 2] {
        [width.div_ceil(self.x), height.div_ceil(self.y)]
    }

    /// Dispatches enough workgroups to cover a `width` x `height` image.
    pub fn dispatch(self, pass: &mut wgpu::ComputePass<'_>, width: u32, height: u32) {
        let [x, y] = self.groups(width, height);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// Records a pass of `pipeline` with its bind group 0 `group` over a `width` x `height`
    /// image, named `label`.
    pub fn pass(
        self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        (pipeline, group): (&wgpu::ComputePipeline, &wgpu::BindGroup),
        [width, height]: [u32; 2],
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        self.dispatch(&mut pass, width, height);
    }
}

/// A pipeline's WGSL: a `const NAME: u32 = VALUE;` line for each of `constants` (the sizes Rust
/// defines), then `parts` in order (shared code before the pipeline's own).
pub fn wgsl(constants: &[(&str, u32)], parts: &[&str]) -> String {
    let mut out = String::new();
    for (name, value) in constants {
        out.push_str(&format!("const {name}: u32 = {value}u;\n"));
    }
    for part in parts {
        out.push_str(part);
        out.push('\n');
    }
    out
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

/// Whether an adapter emulates a GPU on the CPU (see [`GpuDevice::software`]).
pub fn is_software(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}

/// An RGBA32F image of `width` x `height` pixels in a storage buffer the kernels write, and the
/// mappable buffer it is copied into for reading back ([`wait_and_read`]).
pub fn image_buffers(
    device: &wgpu::Device,
    label: &str,
    width: u32,
    height: u32,
) -> (wgpu::Buffer, wgpu::Buffer) {
    let bytes = width as u64 * height as u64 * 16;
    let image = buffer(
        device,
        label,
        bytes,
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    );
    let readback = buffer(
        device,
        &format!("{label} readback"),
        bytes,
        wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
    );
    (image, readback)
}

/// A buffer of `size` bytes for `usage`, not mapped.
pub fn buffer(
    device: &wgpu::Device,
    label: &str,
    size: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage,
        mapped_at_creation: false,
    })
}

/// A buffer that starts out holding `contents`, for `usage`.
pub fn buffer_with(
    device: &wgpu::Device,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_come_before_the_parts_and_workgroups_cover_the_image() {
        let src = wgsl(
            &Workgroup2 { x: 8, y: 4 }.constants(),
            &["fn a() {}", "fn b() {}"],
        );
        assert_eq!(
            src,
            "const WG_X: u32 = 8u;\nconst WG_Y: u32 = 4u;\nfn a() {}\nfn b() {}\n"
        );
        let wg = Workgroup2 { x: 16, y: 16 };
        assert_eq!(wg.groups(16, 17), [1, 2]);
        assert_eq!(wg.groups(1, 1), [1, 1]);
        assert_eq!(wg.groups(33, 32), [3, 2]);
    }
}
