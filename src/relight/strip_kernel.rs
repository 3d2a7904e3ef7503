//! The CPU wavelet product over dense strips in light-major bands ([`Strips`]): per band, every
//! kept light term adds its strips (8 rows each, widened and multiplied together) to the band's
//! RGB accumulators; then each row adds `weight ⊙ row_scale · sum` to its pixel. With AVX2 and
//! FMA (detected at run time) a strip is one widening load, one conversion and three fused
//! multiply-adds; the portable loop beside it is the same product in plain Rust, and the twin the
//! tests compare it with.
//!
//! The accumulators of a strip's 8 rows lie together, red, green and blue lanes side by side (96
//! bytes), in a buffer aligned to a cache line, so a strip's three read-modify-writes touch
//! at most two lines and never split a 32-byte vector across two. Held as three planes of the
//! band's rows, as before, each strip touched three lines 16 KiB apart, and a vector's low
//! address bits matched the store before it in the next plane's: the demo's K = 200 product ran
//! 1.40 times slower, and its full product 1.43 times (the README's kernel section).
//!
//! The one module that allows `unsafe`: calling a function compiled for AVX2 needs it, and so do
//! the vector loads. Every block says why it is sound.
#![allow(unsafe_code)]

use rayon::prelude::*;

use crate::light::select::SparseLight;
use crate::output::film::Image;
use crate::store::quant::{BLOCK_ROWS, scale_table};
use crate::store::transport::strips::{BAND_BLOCKS, STRIP_ROWS, STRIPS_PER_BLOCK, Strips};
use crate::store::transport::{TILE, Transport, Values};

/// Which inner loop a product runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StripPath {
    /// AVX2 and FMA where the processor has them, else the portable loop.
    Best,
    /// The portable loop, whatever the processor.
    Portable,
}

/// A stored strip value: widened to f32 eight at a time.
trait StripValue: Copy + Send + Sync + 'static {
    fn widen(v: &[Self; STRIP_ROWS]) -> [f32; STRIP_ROWS];
    /// # Safety
    /// `p` points at eight readable values, and the caller runs on a processor with AVX2.
    #[cfg(target_arch = "x86_64")]
    unsafe fn widen_avx2(p: *const Self) -> std::arch::x86_64::__m256;
}

impl StripValue for i8 {
    #[inline(always)]
    fn widen(v: &[i8; STRIP_ROWS]) -> [f32; STRIP_ROWS] {
        v.map(|x| x as f32)
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn widen_avx2(p: *const i8) -> std::arch::x86_64::__m256 {
        use std::arch::x86_64::*;
        // SAFETY: the caller's contract; an unaligned 8-byte load.
        unsafe { _mm256_cvtepi32_ps(_mm256_cvtepi8_epi32(_mm_loadl_epi64(p as *const __m128i))) }
    }
}

impl StripValue for i16 {
    #[inline(always)]
    fn widen(v: &[i16; STRIP_ROWS]) -> [f32; STRIP_ROWS] {
        v.map(|x| x as f32)
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn widen_avx2(p: *const i16) -> std::arch::x86_64::__m256 {
        use std::arch::x86_64::*;
        // SAFETY: the caller's contract; an unaligned 16-byte load.
        unsafe { _mm256_cvtepi32_ps(_mm256_cvtepi16_epi32(_mm_loadu_si128(p as *const __m128i))) }
    }
}

impl StripValue for f32 {
    #[inline(always)]
    fn widen(v: &[f32; STRIP_ROWS]) -> [f32; STRIP_ROWS] {
        *v
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn widen_avx2(p: *const f32) -> std::arch::x86_64::__m256 {
        // SAFETY: the caller's contract; an unaligned 32-byte load.
        unsafe { std::arch::x86_64::_mm256_loadu_ps(p) }
    }
}

/// Accumulators of a band: RGB for each of its rows.
const BAND_ACCUMULATORS: usize = 3 * BAND_BLOCKS * BLOCK_ROWS;
/// Floats of a cache line: the accumulators start on one.
const LINE_FLOATS: usize = 64 / size_of::<f32>();

/// Where the accumulator of row `row` of a band (counted from the band's first) and channel `k`
/// lies: strip by strip, each strip's red lanes, then its green, then its blue.
#[inline(always)]
fn accumulator(row: usize, k: usize) -> usize {
    (row / STRIP_ROWS) * 3 * STRIP_ROWS + k * STRIP_ROWS + row % STRIP_ROWS
}

/// The product of `t`'s matrix, laid out as `strips`, with `light` (checked against the
/// transport by the caller): the image, and the strips and stored entries read.
pub fn relight_strips(
    t: &Transport,
    strips: &Strips,
    light: &SparseLight,
    path: StripPath,
) -> (Image, [u64; 2]) {
    match &strips.values {
        Values::Q8(v) => product(t, strips, light, v, path),
        Values::Q16(v) => product(t, strips, light, v, path),
        Values::F32(v) => product(t, strips, light, v, path),
    }
}

fn product<V: StripValue>(
    t: &Transport,
    strips: &Strips,
    light: &SparseLight,
    values: &[V],
    path: StripPath,
) -> (Image, [u64; 2]) {
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let mut image = Image::new(w, h);
    let values: &[[V; STRIP_ROWS]] = values.as_chunks::<STRIP_ROWS>().0;
    let avx2 = path == StripPath::Best && has_avx2_fma();
    // Each group's pixels (whole tile rows) go to one worker.
    let mut parts = Vec::with_capacity(strips.group_count());
    let mut rest = &mut image.pixels[..];
    for g in 0..strips.group_count() {
        let rows = strips.group_rows(g);
        let y0 = (rows.start * TILE).min(h) * w;
        let len = (rows.end * TILE).min(h) * w - y0;
        let (part, tail) = rest.split_at_mut(len);
        parts.push((g, y0, part));
        rest = tail;
    }
    let read = parts
        .into_par_iter()
        .map_init(
            || vec![0.0f32; BAND_ACCUMULATORS + LINE_FLOATS],
            |buffer, (g, y0, pixels)| {
                // The accumulators from the buffer's first cache line on.
                let line = buffer.as_ptr().align_offset(64).min(LINE_FLOATS);
                let acc = &mut buffer[line..line + BAND_ACCUMULATORS];
                let mut read = [0u64; 2];
                for band in strips.group_bands(g) {
                    let blocks = strips.band_blocks(band);
                    let job = Band {
                        t,
                        strips,
                        light,
                        values,
                        band,
                    };
                    // Only the band's own rows: a per-vertex bake's bands are one or two blocks.
                    let used = (3 * blocks.len() * BLOCK_ROWS).min(BAND_ACCUMULATORS);
                    let acc = &mut acc[..used];
                    acc.fill(0.0);
                    let [strips, entries] = if avx2 {
                        #[cfg(target_arch = "x86_64")]
                        // SAFETY: AVX2 and FMA were detected above.
                        unsafe {
                            job.add_avx2(acc)
                        }
                        #[cfg(not(target_arch = "x86_64"))]
                        unreachable!()
                    } else {
                        job.add_portable(acc)
                    };
                    read[0] += strips;
                    read[1] += entries;
                    for b in blocks.clone() {
                        let rows = t.block_row_start[b] as usize..t.block_row_start[b + 1] as usize;
                        let base = (b - blocks.start) * BLOCK_ROWS;
                        for (i, r) in rows.enumerate() {
                            let s = t.row_scale[r];
                            let wgt = t.row_weight[r];
                            let px = &mut pixels[t.row_pixel[r] as usize - y0];
                            for k in 0..3 {
                                px[k] += wgt[k] * (acc[accumulator(base + i, k)] * s);
                            }
                        }
                    }
                }
                read
            },
        )
        .reduce(|| [0, 0], |a, b| [a[0] + b[0], a[1] + b[1]]);
    (image, read)
}

fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// One band's product.
struct Band<'a, V> {
    t: &'a Transport,
    strips: &'a Strips,
    light: &'a SparseLight,
    values: &'a [[V; STRIP_ROWS]],
    band: usize,
}

impl<V: StripValue> Band<'_, V> {
    /// Walks the band's strips term by term, handing each strip's values, the accumulator row
    /// it starts at and the scaled light term to `add`; returns the strips and stored entries
    /// read.
    #[inline(always)]
    fn walk(&self, mut add: impl FnMut(&[V; STRIP_ROWS], usize, [f32; 3])) -> [u64; 2] {
        let c = self.t.coeff_count();
        let scales = scale_table();
        let (mut strips, mut entries) = (0u64, 0u64);
        for (&j, l) in self.light.indices.iter().zip(&self.light.values) {
            for (i, slot) in self
                .strips
                .term_slots(self.band, j as usize, c)
                .iter()
                .enumerate()
            {
                let n = slot.count as usize;
                if n == 0 {
                    continue;
                }
                let s0 = slot.first as usize;
                strips += n as u64;
                entries += slot.entries as u64;
                let sc = scales[slot.code as usize];
                let l = [l[0] * sc, l[1] * sc, l[2] * sc];
                let base = i * BLOCK_ROWS;
                for (v, &k) in self.values[s0..s0 + n]
                    .iter()
                    .zip(&self.strips.index[s0..s0 + n])
                {
                    add(v, base + (k as usize % STRIPS_PER_BLOCK) * STRIP_ROWS, l);
                }
            }
        }
        [strips, entries]
    }

    /// Adds the band's product to `acc`, the accumulators of its rows ([`accumulator`]).
    fn add_portable(&self, acc: &mut [f32]) -> [u64; 2] {
        self.walk(|v, row, l| {
            let v = V::widen(v);
            let at = accumulator(row, 0);
            let lanes: &mut [f32; 3 * STRIP_ROWS] = (&mut acc[at..at + 3 * STRIP_ROWS])
                .try_into()
                .expect("a strip inside the band");
            for (a, l) in lanes.chunks_exact_mut(STRIP_ROWS).zip(l) {
                for k in 0..STRIP_ROWS {
                    a[k] += v[k] * l;
                }
            }
        })
    }

    /// # Safety
    /// The processor has AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn add_avx2(&self, acc: &mut [f32]) -> [u64; 2] {
        use std::arch::x86_64::*;
        // The bounds the pointer arithmetic below relies on: `walk` hands rows of the band's
        // blocks (one per slot of the band), and `acc` holds the accumulators of all of them.
        let blocks = self.strips.band_blocks(self.band).len();
        assert!(
            acc.len() >= 3 * blocks * BLOCK_ROWS,
            "accumulators for the whole band"
        );
        let p = acc.as_mut_ptr();
        self.walk(|v, row, l| {
            // SAFETY: `row` is a block's start inside the band plus a strip's start inside its
            // block (reduced modulo the strips of a block), a multiple of 8 below the band's
            // rows, so its strip's 24 accumulators lie inside `acc` (asserted above); `v` is
            // eight values.
            unsafe {
                let x = V::widen_avx2(v.as_ptr());
                for (k, l) in l.into_iter().enumerate() {
                    let a = p.add(accumulator(row, k));
                    _mm256_storeu_ps(a, _mm256_fmadd_ps(x, _mm256_set1_ps(l), _mm256_loadu_ps(a)));
                }
            }
        })
    }
}
