//! Reading results back from the device: an image from a buffer, the timestamps around a run of
//! passes, and the display texture. One wait-and-map does all three.

use std::time::Instant;

use crate::error::{PrtError, Result};

/// Maps `buffer` for reading once the submitted work is done, and hands its bytes to `read`.
/// `what` names the work in errors.
pub fn map_and_read<T>(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    what: &str,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: None,
        })
        .map_err(|e| PrtError::Gpu(format!("waiting for {what}: {e}")))?;
    rx.recv()
        .map_err(|_| PrtError::Gpu(format!("reading {what} back: the mapping was dropped")))?
        .map_err(|e| PrtError::Gpu(format!("reading {what} back: {e}")))?;
    let out = {
        let view = slice
            .get_mapped_range()
            .map_err(|e| PrtError::Gpu(format!("reading {what} back: {e:?}")))?;
        read(&view)
    };
    buffer.unmap();
    Ok(out)
}

/// Waits for the submissions, then reads `readback` (RGBA32F pixels) as RGB. Returns the pixels
/// and the seconds from `start` until the GPU finished; `what` names the work in errors.
pub fn wait_and_read(
    device: &wgpu::Device,
    readback: &wgpu::Buffer,
    start: Instant,
    what: &str,
) -> Result<(Vec<[f32; 3]>, f64)> {
    map_and_read(device, readback, what, |bytes| {
        let seconds = start.elapsed().as_secs_f64();
        let data: &[[f32; 4]] = bytemuck::cast_slice(bytes);
        (data.iter().map(|p| [p[0], p[1], p[2]]).collect(), seconds)
    })
}

/// Two timestamps (start of the first pass of a run, end of the last), resolved and copied to a
/// mappable buffer in the same submission.
#[derive(Clone)]
pub struct Timer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    period_ns: f64,
}

impl Timer {
    /// The timer of a device with timestamp queries; `None` without them.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Option<Timer> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let set = device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("relight timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        Some(Timer {
            set,
            resolve: buffer(
                "timestamps",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            readback: buffer(
                "timestamps readback",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            period_ns: queue.get_timestamp_period() as f64,
        })
    }

    /// Timestamp writes for pass `i` of `n`: the start of the first, the end of the last.
    pub fn writes(&self, i: usize, n: usize) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let (begin, end) = (i == 0, i + 1 == n);
        (begin || end).then(|| wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: begin.then_some(0),
            end_of_pass_write_index: end.then_some(1),
        })
    }

    /// Resolves the two stamps into the readback buffer, at the end of the submission.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        encoder.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, 16);
    }

    /// The time between the two stamps of the last finished submission, seconds.
    pub fn read(&self, device: &wgpu::Device) -> Option<f64> {
        let stamps: [u64; 2] = map_and_read(device, &self.readback, "timestamps", |bytes| {
            bytemuck::pod_read_unaligned(&bytes[..16])
        })
        .ok()?;
        // Some drivers stamp a pass that was skipped as 0; a reversed pair is no measurement.
        (stamps[1] > stamps[0] && stamps[0] != 0)
            .then(|| (stamps[1] - stamps[0]) as f64 * self.period_ns * 1e-9)
    }
}
