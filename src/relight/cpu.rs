//! The CPU kernels (rayon over tile rows): the tiled sparse wavelet product, the SH dot product,
//! and the dense product that is their slow twin in the tests.

use std::time::Instant;

use rayon::prelude::*;

use super::RelightStats;
use crate::error::{PrtError, Result};
use crate::light::select::SparseLight;
use crate::output::film::Image;
use crate::store::quant::{BLOCK_ROWS, scale_of};
use crate::store::transport::{TILE, Transport, Values, tile_grid};

/// Transport values the sparse product reads for `light`: the lengths of its kept columns in
/// every block.
pub fn nonzeros_touched(t: &Transport, light: &SparseLight) -> u64 {
    let c = t.coeff_count();
    (0..t.block_count())
        .map(|b| {
            let ptr = &t.col_ptr[b * (c + 1)..(b + 1) * (c + 1)];
            light
                .indices
                .iter()
                .map(|&j| (ptr[j as usize + 1] - ptr[j as usize]) as u64)
                .sum::<u64>()
        })
        .sum()
}

/// Widens a stored value (an integer, or a lossless float) to f32; the column's scale is applied
/// to the light term instead, once per block and column.
trait StoredValue: Copy + Send + Sync {
    fn f32(self) -> f32;
}
impl StoredValue for f32 {
    #[inline(always)]
    fn f32(self) -> f32 {
        self
    }
}
impl StoredValue for i8 {
    #[inline(always)]
    fn f32(self) -> f32 {
        self as f32
    }
}
impl StoredValue for i16 {
    #[inline(always)]
    fn f32(self) -> f32 {
        self as f32
    }
}

/// The tiled sparse product: for every block of every tile, every kept light term's column adds
/// `integer · (scale · L)` to its rows; the rows then add `weight ⊙ sum` to their pixels. Checks
/// that the light fits the transport (N, index range).
pub fn relight_wavelet(t: &Transport, light: &SparseLight) -> Result<(Image, RelightStats)> {
    let c = t.coeff_count();
    if light.indices.iter().any(|&j| j as usize >= c) || light.indices.len() != light.values.len() {
        return Err(PrtError::invalid(
            "light",
            format!("its coefficients do not fit a transport with 6·N² = {c} coefficients"),
        ));
    }
    let start = Instant::now();
    let (image, touched) = match &t.values {
        Values::Q8(v) => wavelet_kernel(t, light, v),
        Values::Q16(v) => wavelet_kernel(t, light, v),
        Values::F32(v) => wavelet_kernel(t, light, v),
    };
    let stats = RelightStats {
        terms: light.len(),
        nonzeros_touched: touched,
        bytes_touched: touched * (1 + t.values.value_bytes() as u64)
            + t.block_count() as u64 * light.len() as u64 * 9,
        kernel_seconds: start.elapsed().as_secs_f64(),
        light_columns: 0,
    };
    Ok((image, stats))
}

/// One block's accumulators: a row index is a byte, so indexing needs no bounds check.
type BlockAcc = [[f32; 4]; BLOCK_ROWS];

/// Entries widened to f32 together before they are scattered.
const CHUNK: usize = 32;

fn wavelet_kernel<V: StoredValue>(
    t: &Transport,
    light: &SparseLight,
    values: &[V],
) -> (Image, u64) {
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let (tx, _) = tile_grid(w, h);
    let c = t.coeff_count();
    let mut image = Image::new(w, h);
    let touched: u64 = image
        .pixels
        .par_chunks_mut(w * TILE)
        .enumerate()
        .map_init(
            || Box::new([[0.0f32; 4]; BLOCK_ROWS]),
            |acc: &mut Box<BlockAcc>, (ty, band)| {
                let mut touched = 0u64;
                let y0 = ty * TILE * w;
                for tile in ty * tx..(ty + 1) * tx {
                    for b in t.blocks(tile) {
                        let (r0, r1) = (
                            t.block_row_start[b] as usize,
                            t.block_row_start[b + 1] as usize,
                        );
                        acc[..r1 - r0].fill([0.0; 4]);
                        let base = t.block_entry_start[b] as usize;
                        let ptr = &t.col_ptr[b * (c + 1)..(b + 1) * (c + 1)];
                        let codes = &t.col_scale[b * c..(b + 1) * c];
                        for (&j, l) in light.indices.iter().zip(&light.values) {
                            let j = j as usize;
                            let (e0, e1) = (base + ptr[j] as usize, base + ptr[j + 1] as usize);
                            if e0 == e1 {
                                continue;
                            }
                            touched += (e1 - e0) as u64;
                            // Four lanes (the last unused) so one vector op updates a row.
                            let s = scale_of(codes[j]);
                            let l = [l[0] * s, l[1] * s, l[2] * s, 0.0];
                            // Widen a chunk of values at once (a vector conversion), then
                            // scatter: one row update per entry with no scalar conversion.
                            let rows = t.entry_row[e0..e1].chunks(CHUNK);
                            for (rows, vals) in rows.zip(values[e0..e1].chunks(CHUNK)) {
                                let mut wide = [0.0f32; CHUNK];
                                for (w, &v) in wide.iter_mut().zip(vals) {
                                    *w = v.f32();
                                }
                                for (&r, &v) in rows.iter().zip(&wide) {
                                    let a = &mut acc[r as usize];
                                    for k in 0..4 {
                                        a[k] += v * l[k];
                                    }
                                }
                            }
                        }
                        for (r, a) in acc[..r1 - r0].iter().enumerate() {
                            let p = t.row_pixel[r0 + r] as usize - y0;
                            let wgt = t.row_weight[r0 + r];
                            let s = t.row_scale[r0 + r];
                            let px = &mut band[p];
                            for k in 0..3 {
                                px[k] += wgt[k] * (a[k] * s);
                            }
                        }
                    }
                }
                touched
            },
        )
        .sum();
    (image, touched)
}

/// SH relighting: every row's SH transport (its first `sh.len()` coefficients) dotted with the SH
/// light.
pub fn relight_sh(t: &Transport, sh: &[[f64; 3]]) -> Result<(Image, RelightStats)> {
    let stride = t.sh_count();
    let count = sh.len();
    if count == 0 || count > stride {
        return Err(PrtError::invalid(
            "SH light",
            format!("{count} coefficients for a transport baked with {stride}"),
        ));
    }
    let start = Instant::now();
    let light: Vec<[f32; 3]> = sh.iter().map(|c| c.map(|v| v as f32)).collect();
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let (tx, _) = tile_grid(w, h);
    let mut image = Image::new(w, h);
    image
        .pixels
        .par_chunks_mut(w * TILE)
        .enumerate()
        .for_each(|(ty, band)| {
            let rows = t.tile_row_start[ty * tx] as usize..t.tile_row_start[(ty + 1) * tx] as usize;
            let y0 = ty * TILE * w;
            for r in rows {
                let coeffs = &t.sh[r * stride..r * stride + count];
                let mut a = [0.0f32; 3];
                for (tc, l) in coeffs.iter().zip(&light) {
                    a[0] += tc * l[0];
                    a[1] += tc * l[1];
                    a[2] += tc * l[2];
                }
                let wgt = t.row_weight[r];
                let px = &mut band[t.row_pixel[r] as usize - y0];
                for k in 0..3 {
                    px[k] += wgt[k] * a[k];
                }
            }
        });
    let rows = t.row_pixel.len() as u64;
    let stats = RelightStats {
        terms: count,
        nonzeros_touched: rows * count as u64,
        bytes_touched: rows * count as u64 * 4,
        kernel_seconds: start.elapsed().as_secs_f64(),
        light_columns: 0,
    };
    Ok((image, stats))
}

/// The slow twin of the wavelet kernel: rebuilds every row densely and takes plain dot products.
/// For tests and checks only.
pub fn relight_dense_reference(t: &Transport, light: &SparseLight) -> Image {
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let c = t.coeff_count();
    let mut dense_light = vec![[0.0f64; 3]; c];
    for (&j, l) in light.indices.iter().zip(&light.values) {
        dense_light[j as usize] = l.map(|v| v as f64);
    }
    let mut image = Image::new(w, h);
    for b in 0..t.block_count() {
        let r0 = t.block_row_start[b] as usize;
        let rows = t.block_row_start[b + 1] as usize - r0;
        let mut dense = vec![vec![0.0f64; c]; rows];
        // Column by column, as stored; `j` indexes the stored columns and each dense row.
        #[allow(clippy::needless_range_loop)]
        for j in 0..c {
            for e in t.block_column(b, j) {
                dense[t.entry_row[e] as usize][j] = t.value(b, j, e) as f64;
            }
        }
        for (r, row) in dense.iter().enumerate() {
            let mut a = [0.0f64; 3];
            for (v, l) in row.iter().zip(&dense_light) {
                for k in 0..3 {
                    a[k] += v * l[k];
                }
            }
            let wgt = t.row_weight[r0 + r];
            let px = &mut image.pixels[t.row_pixel[r0 + r] as usize];
            for k in 0..3 {
                px[k] += (wgt[k] as f64 * a[k]) as f32;
            }
        }
    }
    image
}
