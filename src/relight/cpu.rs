//! The CPU kernels (rayon over whole tile rows): the sparse wavelet product (its inner loops in
//! [`super::strip_kernel`]), the SH dot product, and the dense product that is their slow twin in
//! the tests.

use std::time::Instant;

use rayon::prelude::*;

use super::RelightStats;
use super::strip_kernel::{StripPath, relight_strips};
use crate::env::select::SparseLight;
use crate::error::{PrtError, Result};
use crate::output::film::Image;
use crate::store::transport::strips::{STRIP_ROWS, Slot};
use crate::store::transport::{TILE, Transport, tile_grid};

/// The sparse wavelet product (see [`super::strip_kernel`]): the matrix's strips in light-major
/// bands, every kept term's strips added to the band's rows. Checks that the light fits the
/// transport (N, index range). The first call makes the transport's strips
/// ([`Transport::strips`]), outside the kernel's time.
pub fn relight_wavelet(t: &Transport, light: &SparseLight) -> Result<(Image, RelightStats)> {
    let c = t.coeff_count();
    if light.indices.iter().any(|&j| j as usize >= c) || light.indices.len() != light.values.len() {
        return Err(PrtError::invalid(
            "light",
            format!("its coefficients do not fit a transport with 6·N² = {c} coefficients"),
        ));
    }
    let strips = &t.strips;
    let start = Instant::now();
    let (image, read) = relight_strips(t, strips, light, StripPath::Best);
    let kernel_seconds = start.elapsed().as_secs_f64();
    let stats = RelightStats {
        terms: light.len(),
        nonzeros_touched: read.entries,
        // The strips' values and the places read, the slots that hold them, and a band's
        // bitmask of those per term.
        bytes_touched: read.strips * (STRIP_ROWS * t.strips.values.value_bytes()) as u64
            + read.places
            + read.slots * std::mem::size_of::<Slot>() as u64
            + (t.strips.band_count() * light.len() * std::mem::size_of::<u16>()) as u64,
        kernel_seconds,
        light_columns: 0,
    };
    Ok((image, stats))
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
            for (row, v) in t.column(b, j) {
                dense[row - r0][j] = v as f64;
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
