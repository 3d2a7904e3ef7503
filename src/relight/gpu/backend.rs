//! The wgpu kernels behind the one relight interface ([`Backend`]): a device and a transport
//! resident on it, returning the image and the statistics the CPU returns.

use super::{Gpu, GpuTransport};
use crate::error::{PrtError, Result};
use crate::output::film::Image;
use crate::relight::{Backend, LightMix, RelightStats, Terms};
use crate::store::transport::Transport;

/// The wgpu kernels as a [`Backend`]: a device and a transport resident on it, with the
/// transport in memory for the statistics the device does not count.
pub struct GpuBackend<'a> {
    gpu: &'a Gpu,
    resident: &'a GpuTransport,
    transport: &'a Transport,
}

impl<'a> GpuBackend<'a> {
    /// `resident` must be `transport` uploaded to `gpu`.
    pub fn new(gpu: &'a Gpu, resident: &'a GpuTransport, transport: &'a Transport) -> Result<Self> {
        let m = &transport.meta;
        if (resident.width, resident.height, resident.coeffs)
            != (m.width as usize, m.height as usize, transport.coeff_count())
        {
            return Err(PrtError::invalid(
                "GPU transport",
                "it was uploaded from another transport".to_string(),
            ));
        }
        Ok(GpuBackend {
            gpu,
            resident,
            transport,
        })
    }
}

impl Backend for GpuBackend<'_> {
    fn transport(&self) -> &Transport {
        self.transport
    }

    fn name(&self) -> String {
        self.gpu.adapter.clone()
    }

    fn relight_lit(&self, terms: &Terms, lights: &LightMix) -> Result<(Image, RelightStats)> {
        crate::relight::check_mix(self.transport, lights)?;
        let (image, mut stats) = self.resident.relight_lit(self.gpu, terms, lights)?;
        if let Terms::Wavelet(light) | Terms::ShLight { haar: light, .. } = terms {
            // Counted from the transport in memory: the same strips the CPU kernel reads, at
            // the device's bytes a strip, plus two words per (block, term).
            let t = self.transport;
            let (read, entries) = t.strips.read_by(&light.indices, t.coeff_count());
            stats.nonzeros_touched = entries;
            stats.bytes_touched =
                read * self.resident.bytes_per_strip() + (t.block_count() * light.len() * 8) as u64;
        }
        Ok((image, stats))
    }
}
