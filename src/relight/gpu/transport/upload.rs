//! A transport's upload: its tables, strips, slots and SH rows into storage buffers, the
//! tiles split into chunks whose buffers each fit one binding, and a chunk's bind groups.

use super::{Chunk, GpuTransport, MAX_DISPATCH, Params};
use crate::error::{PrtError, Result};
use crate::relight::gpu::Gpu;
use crate::store::quant::Quantization;
use crate::store::transport::strips::STRIP_ROWS;
use crate::store::transport::{Transport, Values, tile_grid};

/// `Params::format`: how strip values are packed in the `strips` buffer (see
/// `shaders/relight_wavelet.wgsl`).
fn format_code(q: Quantization) -> u32 {
    match q {
        Quantization::Q8 => 0,
        Quantization::Q16 => 1,
        Quantization::F32 => 2,
    }
}

/// Bytes `count` strips take on the device: their places, four to a word, and their eight
/// values each.
fn device_strip_bytes(q: Quantization, count: u64) -> u64 {
    count.div_ceil(4) * 4 + count * (STRIP_ROWS * q.value_bytes()) as u64
}

fn storage(device: &wgpu::Device, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    // Bindings may not be empty: pad to one vec4 (copying only what is that small).
    let mut padded = [0u8; 16];
    let data = if bytes.len() < padded.len() {
        padded[..bytes.len()].copy_from_slice(bytes);
        &padded[..]
    } else {
        bytes
    };
    crate::gpu::buffer_with(device, label, data, wgpu::BufferUsages::STORAGE)
}

impl GpuTransport {
    /// Uploads `t`. `max_binding_bytes` caps every storage binding (default: the device's limit;
    /// tests lower it to exercise the split into chunks).
    pub fn upload(gpu: &Gpu, t: &Transport, max_binding_bytes: Option<u64>) -> Result<Self> {
        let device = &gpu.device;
        let limit = max_binding_bytes
            .unwrap_or(u64::MAX)
            .min(gpu.max_binding_bytes());
        let (w, h) = (t.meta.width as usize, t.meta.height as usize);
        let (tiles_x, _) = tile_grid(w, h);
        let c = t.coeff_count();
        let shc = t.sh_count();
        let rows = t.row_pixel.len();
        let quant = t.quantization();
        let strips = &t.strips;
        // Per block: two words a coefficient, its first strip and its count and scale code.
        let ptr_bytes = 2 * c as u64 * 4;
        let block_strips: Vec<u64> = (0..t.block_count())
            .map(|b| strips.block_slots(b, c).map(|s| s.count as u64).sum())
            .collect();
        for (what, bytes) in [
            ("row table", rows as u64 * 16),
            ("image", (w * h) as u64 * 16),
            ("tile pointers", ptr_bytes),
        ] {
            if bytes > limit {
                return Err(PrtError::Gpu(format!(
                    "the {what} needs {bytes} bytes in one binding; this device allows {limit}"
                )));
            }
        }
        // The tiles' row starts, then their block starts (at `Params::block_table`).
        let tile_table: Vec<u32> = t
            .tile_row_start
            .iter()
            .chain(&t.tile_block_start)
            .copied()
            .collect();
        let tile_rows = storage(device, "tile rows", bytemuck::cast_slice(&tile_table));
        let row_data: Vec<[f32; 4]> = t
            .row_weight
            .iter()
            .zip(&t.row_pixel)
            .map(|(wgt, p)| [wgt[0], wgt[1], wgt[2], f32::from_bits(*p)])
            .collect();
        let row_buf = storage(device, "rows", bytemuck::cast_slice(&row_data));
        // The wavelet pass applies each row's value scale with its weight.
        let scaled: Vec<[f32; 4]> = row_data
            .iter()
            .zip(&t.row_scale)
            .map(|(r, s)| [r[0] * s, r[1] * s, r[2] * s, r[3]])
            .collect();
        let scaled_buf = storage(device, "scaled rows", bytemuck::cast_slice(&scaled));
        let acc = crate::gpu::buffer(
            device,
            "row accumulators",
            (rows.max(1) * 16) as u64,
            wgpu::BufferUsages::STORAGE,
        );
        let (image, readback) = crate::gpu::image_buffers(device, "image", w as u32, h as u32);
        let light = crate::gpu::buffer(
            device,
            "light terms",
            (c.max(shc) * 16) as u64,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        // Split the tiles into chunks whose strips, slots and SH rows each fit one binding.
        let mut chunks = Vec::new();
        let tiles = t.tile_count();
        let mut start = 0;
        while start < tiles {
            let mut end = start;
            loop {
                let next = end + 1;
                let (b0, b1) = (t.tile_block_start[start], t.tile_block_start[next]);
                let count: u64 = block_strips[b0 as usize..b1 as usize].iter().sum();
                let rows_in = (t.tile_row_start[next] - t.tile_row_start[start]) as u64;
                let fits = device_strip_bytes(quant, count) <= limit
                    && (b1 - b0) as u64 * ptr_bytes <= limit
                    && rows_in * shc as u64 * 4 <= limit;
                if !fits {
                    break;
                }
                end = next;
                if end == tiles {
                    break;
                }
            }
            if end == start {
                return Err(PrtError::Gpu(format!(
                    "tile {start} alone does not fit a {limit}-byte binding"
                )));
            }
            let (b0, b1) = (t.tile_block_start[start], t.tile_block_start[end]);
            chunks.push(Self::chunk(
                gpu,
                t,
                start..end,
                block_strips[b0 as usize..b1 as usize].iter().sum::<u64>() as usize,
                tiles_x,
                [&tile_rows, &row_buf, &scaled_buf, &acc, &image, &light],
            )?);
            start = end;
        }
        let lights =
            crate::relight::gpu::lights::GpuLights::upload(gpu, &t.attached.lights, &image, limit)?;
        Ok(GpuTransport {
            lights,
            width: w,
            height: h,
            coeffs: c,
            sh_count: shc,
            rows,
            strips: strips.strip_count() as u64,
            strip_bytes: device_strip_bytes(quant, 4) / 4,
            chunks,
            light,
            image,
            readback,
        })
    }

    fn chunk(
        gpu: &Gpu,
        t: &Transport,
        tiles: std::ops::Range<usize>,
        strip_count: usize,
        tiles_x: usize,
        [tile_rows, rows, scaled_rows, acc, image, light]: [&wgpu::Buffer; 6],
    ) -> Result<Chunk> {
        let device = &gpu.device;
        let c = t.coeff_count();
        let blocks =
            t.tile_block_start[tiles.start] as usize..t.tile_block_start[tiles.end] as usize;
        // The blocks' strips (`strip_count` of them), coefficient by coefficient, in one buffer:
        // first every strip's place (four to a word), then from `values_base` on their values,
        // packed as the stored type.
        let strips = &t.strips;
        let places_len = strip_count.next_multiple_of(4);
        let values_base = (places_len / 4) as u32;
        let mut data =
            vec![0u8; places_len + strip_count * STRIP_ROWS * strips.values.value_bytes()];
        let (places, values) = data.split_at_mut(places_len);
        let mut slots = Vec::with_capacity(blocks.len() * 2 * c);
        let (mut p, mut v) = (0, 0);
        for b in blocks.clone() {
            for slot in strips.block_slots(b, c) {
                let run = slot.first as usize..slot.first as usize + slot.count as usize;
                slots.push(p as u32);
                slots.push(slot.count as u32 | (slot.code as u32) << 8);
                places[p..p + run.len()].copy_from_slice(&strips.index[run.clone()]);
                p += run.len();
                let values_of = run.start * STRIP_ROWS..run.end * STRIP_ROWS;
                let bytes: &[u8] = match &strips.values {
                    Values::Q8(x) => bytemuck::cast_slice(&x[values_of]),
                    Values::Q16(x) => bytemuck::cast_slice(&x[values_of]),
                    Values::F32(x) => bytemuck::cast_slice(&x[values_of]),
                };
                values[v..v + bytes.len()].copy_from_slice(bytes);
                v += bytes.len();
            }
        }
        let (r0, r1) = (
            t.tile_row_start[tiles.start] as usize,
            t.tile_row_start[tiles.end] as usize,
        );
        let shc = t.sh_count();
        let strip_buf = storage(device, "strips", &data);
        let slot_buf = storage(device, "slots", bytemuck::cast_slice(&slots));
        let sh_buf = storage(
            device,
            "sh rows",
            bytemuck::cast_slice(&t.sh[r0 * shc..r1 * shc]),
        );
        let count = tiles.len() as u32;
        let dispatch_x = count.min(MAX_DISPATCH);
        let params = Params {
            tile_base: tiles.start as u32,
            tile_count: count,
            dispatch_x,
            width: t.meta.width,
            height: t.meta.height,
            tiles_x: tiles_x as u32,
            coeffs: c as u32,
            terms: 0,
            format: format_code(t.quantization()),
            row_base: r0 as u32,
            shared_rows: u32::MAX,
            block_base: blocks.start as u32,
            block_table: t.tile_row_start.len() as u32,
            term_base: 0,
            accumulate: 0,
            values_base,
        };
        let params = crate::gpu::buffer_with(
            device,
            "params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let shared = [(0, &params), (1, tile_rows), (4, image)];
        let group = |pipeline: &wgpu::ComputePipeline, extra: &[(u32, &wgpu::Buffer)]| {
            let entries: Vec<wgpu::BindGroupEntry> = shared
                .iter()
                .chain(extra)
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: *i,
                    resource: b.as_entire_binding(),
                })
                .collect();
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            })
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let wavelet_group = group(
            &gpu.wavelet,
            &[
                (2, scaled_rows),
                (3, acc),
                (5, &strip_buf),
                (6, &slot_buf),
                (7, light),
                (8, &gpu.scales),
            ],
        );
        let sh_group = group(&gpu.sh, &[(2, rows), (5, &sh_buf), (7, light)]);
        crate::gpu::end_scope(scope, "binding the transport")?;
        Ok(Chunk {
            tiles,
            params,
            wavelet_group,
            sh_group,
        })
    }
}
