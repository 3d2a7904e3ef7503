//! The CPU wavelet product over dense strips in light-major bands ([`Strips`]): per band, every
//! kept light term adds its strips (8 rows each, widened and multiplied together) to the band's
//! RGB accumulators; then each row adds `weight ⊙ row_scale · sum` to its pixel. The portable
//! loop does this strip by strip in plain Rust, and is the twin the tests compare the fast one
//! with.
//!
//! Both loops walk a band's slots by its bitmask of the occupied ones ([`Strips::occupied`]),
//! skipping the empty ones unread: on the demo bake 66% of (block, coefficient) slots are empty.
//! With AVX2 and FMA (detected at run time) the walk goes a chunk of 64 terms at a time, and sorts
//! the chunk's occupied slots before adding them:
//! - A slot that holds every strip of its block (32, or fewer in a tile's last block; a bake
//!   stores a slot so from half full, and on the demo bake 96% of the strips lie in such slots)
//!   goes to its block's list. Those are added a panel of 4 strips at a time, with the panel's
//!   12 accumulators held in registers across up to 64 terms (`add_panels`): a strip then
//!   costs one widening load, one conversion and three fused multiply-adds, with no accumulator
//!   traffic. The slot's next cache line is fetched ahead into the first-level cache, and the
//!   next block's slot of the same term, which follows in memory, into the second.
//! - The other slots are added strip by strip into the accumulators in memory, each slot's values
//!   and places fetched a few slots ahead, since they are short runs scattered among the whole
//!   ones (which the panels have just read).
//! - The rows' sums go to their pixels a strip at a time (`add_rows_avx2`): scaled, turned
//!   from three channels into the rows' RGB, weighted and added to 8 pixels at once where the
//!   strip's rows light 8 pixels in a row, with the portable arithmetic, so the same bits.
//!
//! A whole band walked first wrote its lists (780 KiB a band in full) out of the nearest caches;
//! a chunk's stay in the first. With the next line fetched too, the full product ran 1.15 times
//! faster, K = 1000 1.17 and K = 200 1.06 (demo bake, alternated, four processes each).
//!
//! The accumulators of a strip's 8 rows lie together, red, green and blue lanes side by side (96
//! bytes), in a buffer aligned to a cache line, so a strip's three read-modify-writes touch
//! at most two lines and never split a 32-byte vector across two. Held as three planes of the
//! band's rows, each strip touched three lines 16 KiB apart, and the products ran 1.4 times
//! slower.
//!
//! The one module that allows `unsafe`: calling a function compiled for AVX2 needs it, and so do
//! the vector loads. Every block says why it is sound.
#![allow(unsafe_code)]

use std::ops::Range;

mod panels;

pub use panels::CachedPanels;
use panels::PANEL_TERMS;
#[cfg(target_arch = "x86_64")]
use panels::add_panels;
#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::{
    __m128i, __m256, _mm_loadl_epi64, _mm_loadu_si128, _mm256_cvtepi8_epi32, _mm256_cvtepi16_epi32,
    _mm256_cvtepi32_ps, _mm256_loadu_ps,
};

use rayon::prelude::*;

use crate::env::select::SparseLight;
use crate::output::film::Image;
use crate::store::quant::{BLOCK_ROWS, scale_table};
use crate::store::transport::strips::{self, BAND_BLOCKS, STRIP_ROWS, STRIPS_PER_BLOCK, Strips};
use crate::store::transport::{TILE, Transport, Values};

/// What a product read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Read {
    /// Strips of 8 values.
    pub strips: u64,
    /// Stored entries those strips hold.
    pub entries: u64,
    /// Strip places (a byte each): the SIMD loop reads none of a slot that holds its block's
    /// every strip.
    pub places: u64,
    /// Occupied slots, each a (block, coefficient)'s table entry.
    pub slots: u64,
}

impl std::ops::Add for Read {
    type Output = Read;
    fn add(self, o: Read) -> Read {
        Read {
            strips: self.strips + o.strips,
            entries: self.entries + o.entries,
            places: self.places + o.places,
            slots: self.slots + o.slots,
        }
    }
}

/// Which inner loop a product runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StripPath {
    /// AVX2 and FMA where the processor has them, else the portable loop.
    Best,
    /// The portable loop, whatever the processor.
    Portable,
}

/// A stored strip value: widened to f32 eight at a time (exactly: every i8 and i16 is an f32).
trait StripValue: Copy + Send + Sync + Into<f32> + 'static {
    #[inline(always)]
    fn widen(v: &[Self; STRIP_ROWS]) -> [f32; STRIP_ROWS] {
        v.map(Into::into)
    }
    /// # Safety
    /// `p` points at eight readable values, and the caller runs on a processor with AVX2.
    #[cfg(target_arch = "x86_64")]
    unsafe fn widen_avx2(p: *const Self) -> __m256;
}

impl StripValue for i8 {
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn widen_avx2(p: *const i8) -> __m256 {
        // SAFETY: the caller's contract; an unaligned 8-byte load.
        unsafe { _mm256_cvtepi32_ps(_mm256_cvtepi8_epi32(_mm_loadl_epi64(p as *const __m128i))) }
    }
}

impl StripValue for i16 {
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn widen_avx2(p: *const i16) -> __m256 {
        // SAFETY: the caller's contract; an unaligned 16-byte load.
        unsafe { _mm256_cvtepi32_ps(_mm256_cvtepi16_epi32(_mm_loadu_si128(p as *const __m128i))) }
    }
}

impl StripValue for f32 {
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn widen_avx2(p: *const f32) -> __m256 {
        // SAFETY: the caller's contract; an unaligned 32-byte load.
        unsafe { _mm256_loadu_ps(p) }
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
/// transport by the caller): the image, and what it read.
pub fn relight_strips(
    t: &Transport,
    strips: &Strips,
    light: &SparseLight,
    path: StripPath,
) -> (Image, Read) {
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
) -> (Image, Read) {
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let mut image = Image::new(w, h);
    let values: &[[V; STRIP_ROWS]] = values.as_chunks::<STRIP_ROWS>().0;
    let avx2 = path == StripPath::Best && has_avx2_fma();
    let rows = Rows::of(t);
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
        .map(|(g, y0, pixels)| {
            SCRATCH.with_borrow_mut(
                |Scratch {
                     buffer,
                     full,
                     parts,
                 }| {
                    // The accumulators from the buffer's first cache line on.
                    let line = buffer.as_ptr().align_offset(64).min(LINE_FLOATS);
                    let acc = &mut buffer[line..line + BAND_ACCUMULATORS];
                    let mut read = Read::default();
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
                        read = read
                            + if avx2 {
                                #[cfg(target_arch = "x86_64")]
                                // SAFETY: AVX2 and FMA were detected above.
                                unsafe {
                                    job.add_avx2(acc, full, parts)
                                }
                                #[cfg(not(target_arch = "x86_64"))]
                                unreachable!()
                            } else {
                                job.add_portable(acc)
                            };
                        if avx2 {
                            #[cfg(target_arch = "x86_64")]
                            // SAFETY: AVX2 was detected above.
                            unsafe {
                                add_rows_avx2(&rows, blocks, acc, pixels, y0)
                            }
                        } else {
                            add_rows(&rows, blocks, acc, pixels, y0);
                        }
                    }
                    read
                },
            )
        })
        .reduce(Read::default, |a, b| a + b);
    (image, read)
}

/// What the rows' sums need of a transport: its blocks' rows, and each row's scale, weight and
/// pixel.
struct Rows<'a> {
    block_row_start: &'a [u32],
    scale: &'a [f32],
    weight: &'a [[f32; 3]],
    pixel: &'a [u32],
}

impl<'a> Rows<'a> {
    fn of(t: &'a Transport) -> Self {
        Rows {
            block_row_start: &t.block_row_start,
            scale: &t.row_scale,
            weight: &t.row_weight,
            pixel: &t.row_pixel,
        }
    }
}

/// Adds each row of the band's `blocks` to its pixel, `weight ⊙ (sum · row_scale)`, its sums read
/// from `acc` (the band's accumulators, [`accumulator`]); `pixels` are a group's, from pixel `y0`.
fn add_rows(t: &Rows, blocks: Range<usize>, acc: &[f32], pixels: &mut [[f32; 3]], y0: usize) {
    for b in blocks.clone() {
        let rows = t.block_row_start[b] as usize..t.block_row_start[b + 1] as usize;
        let base = (b - blocks.start) * BLOCK_ROWS;
        add_rows_from(t, rows, base, acc, pixels, y0);
    }
}

/// Adds the global rows `rows`, the band's from row `base` on, to their pixels ([`add_rows`]).
#[inline(always)]
fn add_rows_from(
    t: &Rows,
    rows: Range<usize>,
    base: usize,
    acc: &[f32],
    pixels: &mut [[f32; 3]],
    y0: usize,
) {
    let each = t.scale[rows.clone()]
        .iter()
        .zip(&t.weight[rows.clone()])
        .zip(&t.pixel[rows]);
    for (i, ((&s, wgt), &p)) in each.enumerate() {
        let px = &mut pixels[p as usize - y0];
        let at = accumulator(base + i, 0);
        let a = &acc[at..at + 2 * STRIP_ROWS + 1];
        for k in 0..3 {
            px[k] += wgt[k] * (a[k * STRIP_ROWS] * s);
        }
    }
}

/// [`add_rows`] a strip of 8 rows at a time, with the same arithmetic in the same order, so
/// the same image to the bit: a strip's three channels scaled, interleaved into its rows' RGB
/// (24 floats), weighted, and added to 8 pixels in one go where the strip's rows light 8
/// pixels in a row (98% of the demo bake's strips), else pixel by pixel. A block's last rows
/// short of a strip go row by row.
///
/// # Safety
/// The processor has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn add_rows_avx2(
    t: &Rows,
    blocks: Range<usize>,
    acc: &[f32],
    pixels: &mut [[f32; 3]],
    y0: usize,
) {
    use std::arch::x86_64::*;
    let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    for b in blocks.clone() {
        let rows = t.block_row_start[b] as usize..t.block_row_start[b + 1] as usize;
        let base = (b - blocks.start) * BLOCK_ROWS;
        let strips = rows.len() / STRIP_ROWS;
        for k in 0..strips {
            let r = rows.start + k * STRIP_ROWS;
            let at = accumulator(base + k * STRIP_ROWS, 0);
            let sums = &acc[at..at + 3 * STRIP_ROWS];
            let scale = &t.scale[r..r + STRIP_ROWS];
            let weight = t.weight[r..r + STRIP_ROWS].as_flattened();
            let pixel = &t.pixel[r..r + STRIP_ROWS];
            // SAFETY: each pointer reads the slice just taken, of 24, 8, 24 and 8 elements; AVX2.
            let (rgb, together) = unsafe {
                let s = _mm256_loadu_ps(scale.as_ptr());
                let sums = sums.as_ptr();
                let rgb = interleave(
                    _mm256_mul_ps(_mm256_loadu_ps(sums), s),
                    _mm256_mul_ps(_mm256_loadu_ps(sums.add(STRIP_ROWS)), s),
                    _mm256_mul_ps(_mm256_loadu_ps(sums.add(2 * STRIP_ROWS)), s),
                );
                let w = weight.as_ptr();
                let rgb = [
                    _mm256_mul_ps(_mm256_loadu_ps(w), rgb[0]),
                    _mm256_mul_ps(_mm256_loadu_ps(w.add(8)), rgb[1]),
                    _mm256_mul_ps(_mm256_loadu_ps(w.add(16)), rgb[2]),
                ];
                let p = _mm256_loadu_si256(pixel.as_ptr().cast::<__m256i>());
                let row = _mm256_add_epi32(_mm256_set1_epi32(pixel[0] as i32), lanes);
                (rgb, _mm256_movemask_epi8(_mm256_cmpeq_epi32(p, row)) == -1)
            };
            let start = (pixel[0] as usize).wrapping_sub(y0);
            match pixels.get_mut(start..start.wrapping_add(STRIP_ROWS)) {
                Some(out) if together => {
                    let out = out.as_flattened_mut();
                    for (i, v) in rgb.into_iter().enumerate() {
                        // SAFETY: 24 floats of `out`, 8 from 8 · i; AVX2.
                        unsafe {
                            let o = out.as_mut_ptr().add(8 * i);
                            _mm256_storeu_ps(o, _mm256_add_ps(_mm256_loadu_ps(o), v));
                        }
                    }
                }
                _ => {
                    let mut each = [0.0f32; 3 * STRIP_ROWS];
                    for (i, v) in rgb.into_iter().enumerate() {
                        // SAFETY: 8 floats of `each`, from 8 · i; AVX2.
                        unsafe { _mm256_storeu_ps(each.as_mut_ptr().add(8 * i), v) };
                    }
                    for (&p, v) in pixel.iter().zip(each.as_chunks::<3>().0) {
                        let px = &mut pixels[p as usize - y0];
                        for k in 0..3 {
                            px[k] += v[k];
                        }
                    }
                }
            }
        }
        let done = strips * STRIP_ROWS;
        add_rows_from(t, rows.start + done..rows.end, base + done, acc, pixels, y0);
    }
}

/// A strip's three channels (8 rows each) as its rows' RGB, 24 floats in three vectors: R0 G0 B0
/// R1 G1 B1 R2 G2, then B2 R3 … R5, then G5 B5 … B7.
///
/// # Safety
/// The processor has AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn interleave(r: __m256, g: __m256, b: __m256) -> [__m256; 3] {
    use std::arch::x86_64::*;
    // SAFETY: AVX2, the contract.
    unsafe {
        // The row each float of a vector comes from, and the lanes taken from green and blue.
        let from = [
            _mm256_setr_epi32(0, 0, 0, 1, 1, 1, 2, 2),
            _mm256_setr_epi32(2, 3, 3, 3, 4, 4, 4, 5),
            _mm256_setr_epi32(5, 5, 6, 6, 6, 7, 7, 7),
        ];
        let pick = |v, i: usize| _mm256_permutevar8x32_ps(v, from[i]);
        [
            _mm256_blend_ps::<0b0010_0100>(
                _mm256_blend_ps::<0b1001_0010>(pick(r, 0), pick(g, 0)),
                pick(b, 0),
            ),
            _mm256_blend_ps::<0b0100_1001>(
                _mm256_blend_ps::<0b0010_0100>(pick(r, 1), pick(g, 1)),
                pick(b, 1),
            ),
            _mm256_blend_ps::<0b1001_0010>(
                _mm256_blend_ps::<0b0100_1001>(pick(r, 2), pick(g, 2)),
                pick(b, 2),
            ),
        ]
    }
}

/// True when [`StripPath::Best`] runs the SIMD loop: the processor has AVX2 and FMA.
pub fn has_avx2_fma() -> bool {
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
    /// Hands each occupied slot of the band to `visit`, term by term (skipping the empty ones by
    /// the band's bitmask); returns what those slots hold, every strip's place counted.
    #[inline(always)]
    fn walk(&self, terms: Range<usize>, mut visit: impl FnMut(Run)) -> Read {
        let c = self.t.coeff_count();
        let scales = scale_table();
        let mut read = Read::default();
        for (&j, l) in self.light.indices[terms.clone()]
            .iter()
            .zip(&self.light.values[terms])
        {
            let slots = self.strips.term_slots(self.band, j as usize, c);
            let mut occupied = self.strips.occupied(self.band, j as usize, c);
            while occupied != 0 {
                let block = occupied.trailing_zeros() as usize;
                occupied &= occupied - 1;
                let slot = slots[block];
                read.slots += 1;
                read.strips += slot.count as u64;
                read.entries += slot.entries as u64;
                let sc = scales[slot.code as usize];
                visit(Run {
                    block: block as u16,
                    first: slot.first,
                    count: slot.count as u16,
                    l: [l[0] * sc, l[1] * sc, l[2] * sc],
                });
            }
        }
        read.places = read.strips;
        read
    }

    /// A run's strips: each one's values and the band's row it starts at.
    #[inline(always)]
    fn strips_of(&self, run: &Run) -> impl Iterator<Item = (&[V; STRIP_ROWS], usize)> {
        let strips = run.first()..run.first() + run.count();
        let base = run.block() * BLOCK_ROWS;
        self.values[strips.clone()]
            .iter()
            .zip(&self.strips.index[strips])
            .map(move |(v, &k)| (v, base + (k as usize % STRIPS_PER_BLOCK) * STRIP_ROWS))
    }

    /// Adds the band's product to `acc`, the accumulators of its rows ([`accumulator`]).
    fn add_portable(&self, acc: &mut [f32]) -> Read {
        self.walk(0..self.light.indices.len(), |run| {
            for (v, row) in self.strips_of(&run) {
                let v = V::widen(v);
                let at = accumulator(row, 0);
                let lanes: &mut [f32; 3 * STRIP_ROWS] = (&mut acc[at..at + 3 * STRIP_ROWS])
                    .try_into()
                    .expect("a strip inside the band");
                for (a, l) in lanes.chunks_exact_mut(STRIP_ROWS).zip(run.l) {
                    for k in 0..STRIP_ROWS {
                        a[k] += v[k] * l;
                    }
                }
            }
        })
    }

    /// # Safety
    /// The processor has AVX2 and FMA.
    ///
    /// A slot that holds all its block's strips goes to its block's list in `full` and is added
    /// panel by panel ([`add_panels`]); the others strip by strip into `acc`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn add_avx2(
        &self,
        acc: &mut [f32],
        full: &mut [Vec<Run>],
        parts: &mut Vec<Run>,
    ) -> Read {
        use std::arch::x86_64::*;
        // The bounds the pointer arithmetic below relies on: `walk` hands rows of the band's
        // blocks (one per slot of the band), and `acc` holds the accumulators of all of them.
        let band_blocks = self.strips.band_blocks(self.band);
        let blocks = band_blocks.len();
        // Each block's strips: 32 but in a tile's last block, which may hold fewer rows.
        let mut block_strips = [0usize; BAND_BLOCKS];
        for (s, b) in block_strips.iter_mut().zip(band_blocks) {
            *s = strips::block_strips(
                (self.t.block_row_start[b + 1] - self.t.block_row_start[b]) as usize,
            );
        }
        assert!(
            acc.len() >= 3 * blocks * BLOCK_ROWS && full.len() >= blocks,
            "accumulators and lists for the whole band"
        );
        let p = acc.as_mut_ptr();
        let v0 = self.values.as_ptr();
        let mut whole = 0;
        let mut read = Read::default();
        // A chunk of terms at a time: its walk, then its whole slots panel by panel, then its
        // other slots. The chunk's lists (up to 64 slots a block) stay in the first-level cache
        // from the walk to the panels, and the other slots lie among the whole ones the panels
        // have just read (a band stores a term's slots side by side).
        let terms = self.light.indices.len();
        for start in (0..terms).step_by(PANEL_TERMS) {
            for list in full[..blocks].iter_mut() {
                list.clear();
            }
            parts.clear();
            read = read
                + self.walk(start..(start + PANEL_TERMS).min(terms), |run| {
                    // A block's strip places strictly increase below its strips (checked on
                    // load, and so made by a bake), so a slot that holds as many strips as its
                    // block holds places 0, 1, 2 and so on in order.
                    if run.count() == block_strips[run.block()]
                        && self.values.len() >= run.first() + run.count()
                    {
                        // The panels take strip k of the slot as place k, without reading places.
                        debug_assert!(
                            (0..run.count())
                                .all(|k| self.strips.index[run.first() + k] as usize == k),
                            "a whole slot's places are 0, 1, 2 and so on"
                        );
                        whole += run.count();
                        full[run.block()].push(run);
                    } else {
                        parts.push(run);
                    }
                });
            for (i, list) in full[..blocks].iter().enumerate() {
                let at = accumulator(i * BLOCK_ROWS, 0);
                let block: &mut [f32; 3 * BLOCK_ROWS] = (&mut acc[at..at + 3 * BLOCK_ROWS])
                    .try_into()
                    .expect("a block inside the band");
                // SAFETY: AVX2 and FMA, this function's contract; every slot in the list holds
                // the block's strips from its first, at most 32, checked where it was pushed.
                unsafe { add_panels(self.values, list, block_strips[i], block) };
            }
            // The other slots, strip by strip, each fetched a few slots ahead with its places.
            for (k, part) in parts.iter().enumerate() {
                if let Some(next) = parts.get(k + PART_AHEAD) {
                    let at = v0.wrapping_add(next.first()).cast::<i8>();
                    let bytes = next.count() * size_of::<[V; STRIP_ROWS]>();
                    // A prefetch never faults.
                    for line in (0..bytes).step_by(64) {
                        _mm_prefetch::<_MM_HINT_T0>(at.wrapping_add(line));
                    }
                    let places = self.strips.index.as_ptr().wrapping_add(next.first());
                    _mm_prefetch::<_MM_HINT_T0>(places.cast::<i8>());
                }
                for (v, row) in self.strips_of(part) {
                    // SAFETY: `row` is a block's start inside the band plus a strip's start
                    // inside its block (reduced modulo the strips of a block), a multiple of 8
                    // below the band's rows, so its strip's 24 accumulators lie inside `acc`
                    // (asserted above); `v` is eight values.
                    unsafe {
                        let x = V::widen_avx2(v.as_ptr());
                        for (k, l) in part.l.into_iter().enumerate() {
                            let a = p.add(accumulator(row, k));
                            _mm256_storeu_ps(
                                a,
                                _mm256_fmadd_ps(x, _mm256_set1_ps(l), _mm256_loadu_ps(a)),
                            );
                        }
                    }
                }
            }
        }
        read.places -= whole as u64;
        read
    }
}

/// An occupied slot as the walk hands it: its block within the band, its first strip and their
/// count, and its scaled light term. Held in 20 bytes: a K = 200 product on the demo bake walks
/// some 46,000 of them.
#[derive(Clone, Copy, Debug, Default)]
struct Run {
    first: u32,
    block: u16,
    count: u16,
    l: [f32; 3],
}

impl Run {
    #[inline(always)]
    fn first(&self) -> usize {
        self.first as usize
    }
    #[inline(always)]
    fn count(&self) -> usize {
        self.count as usize
    }
    #[inline(always)]
    fn block(&self) -> usize {
        self.block as usize
    }
}

/// What a worker reuses from one product to the next: a band's accumulators (with a cache
/// line's slack to align them), the whole slots of each block of a band, and the other slots.
struct Scratch {
    buffer: Vec<f32>,
    full: Vec<Vec<Run>>,
    parts: Vec<Run>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch {
        buffer: vec![0.0; BAND_ACCUMULATORS + LINE_FLOATS],
        full: vec![Vec::new(); BAND_BLOCKS],
        parts: Vec::new(),
    });
}

/// How many slots ahead the strip loop fetches a slot's values.
const PART_AHEAD: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::sampling::Rng;

    /// The SIMD rows' sums give the portable loop's pixels to the bit, on blocks of 256 rows and
    /// of fewer than a strip's multiple, strips whose rows light 8 pixels in a row (the last
    /// ending on the group's last pixel), strips with a gap, rows that share a pixel, and
    /// pixels out of order.
    #[test]
    fn the_simd_rows_sums_are_the_portable_ones_to_the_bit() {
        if !has_avx2_fma() {
            eprintln!("no AVX2: only the portable rows' sums run");
            return;
        }
        let (y0, len) = (40, 600);
        let mut rng = Rng::new(3, 0);
        // Blocks of 256, 37, 8 and 3 rows.
        let block_row_start = [0u32, 256, 293, 301, 304];
        let n = 304;
        let mut pixel: Vec<u32> = Vec::with_capacity(n);
        while pixel.len() < n {
            let at = pixel.len();
            let p = match (at / 8) % 5 {
                // 8 in a row: the first strips from the group's first pixel on.
                0 | 1 => y0 as u32 + at as u32,
                // A gap inside the strip.
                2 => y0 as u32 + at as u32 + (at % 8 >= 4) as u32,
                // Two rows a pixel.
                3 => y0 as u32 + (at / 2) as u32,
                // Backwards.
                _ => (y0 + len - 1 - at) as u32,
            };
            pixel.push(p);
        }
        // The 8 rows of the block of 8 light the group's last 8 pixels.
        for (i, p) in pixel[293..301].iter_mut().enumerate() {
            *p = (y0 + len - 8 + i) as u32;
        }
        let scale: Vec<f32> = (0..n).map(|_| rng.next_f32() * 3.0).collect();
        let weight: Vec<[f32; 3]> = (0..n)
            .map(|_| [rng.next_f32(), rng.next_f32(), rng.next_f32() - 0.5])
            .collect();
        let rows = Rows {
            block_row_start: &block_row_start,
            scale: &scale,
            weight: &weight,
            pixel: &pixel,
        };
        let acc: Vec<f32> = (0..3 * 4 * BLOCK_ROWS)
            .map(|_| rng.next_f32() - 0.25)
            .collect();
        let start: Vec<[f32; 3]> = (0..len)
            .map(|_| [rng.next_f32(), rng.next_f32(), rng.next_f32()])
            .collect();
        let mut portable = start.clone();
        add_rows(&rows, 0..4, &acc, &mut portable, y0);
        let mut simd = start.clone();
        // SAFETY: AVX2 was detected above.
        unsafe { add_rows_avx2(&rows, 0..4, &acc, &mut simd, y0) };
        let bits =
            |img: &[[f32; 3]]| -> Vec<u32> { img.iter().flatten().map(|v| v.to_bits()).collect() };
        assert_eq!(bits(&simd), bits(&portable));
        // The portable sums themselves: row 9 (block 0, strip 1, lane 1) alone lights its pixel.
        let at = accumulator(9, 0);
        let p = pixel[9] as usize - y0;
        assert_eq!(pixel.iter().filter(|&&q| q == pixel[9]).count(), 1);
        for k in 0..3 {
            let want = start[p][k] + weight[9][k] * (acc[at + k * STRIP_ROWS] * scale[9]);
            assert_eq!(portable[p][k].to_bits(), want.to_bits(), "channel {k}");
        }
    }
}
