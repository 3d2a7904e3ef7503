//! The strip kernel's panels: a block's whole slots added a panel of strips at a time, the
//! panel's accumulators held in vector registers across a chunk of terms (AVX2 and FMA), and
//! the probe that times this arithmetic alone ([`CachedPanels`]).

use super::{BLOCK_ROWS, Run, STRIP_ROWS, STRIPS_PER_BLOCK, StripValue, accumulator, has_avx2_fma};

/// Strips of a panel: their 3 x 4 accumulators and a strip's values fit the 16 vector registers.
const PANEL: usize = 4;
/// Terms added to a panel's registers between two writes to memory: their strips (16 KiB of
/// bytes) stay in the first-level cache while the block's 8 panels read them.
pub(super) const PANEL_TERMS: usize = 64;

/// Adds every slot of `list` (each of all `strips` strips of its block) to `block`, the
/// block's accumulators: a panel of [`PANEL`] strips at a time (fewer in the last panel of a
/// block whose strips are not a multiple of it), its accumulators in registers across up to
/// [`PANEL_TERMS`] terms, so each strip costs one load, one conversion and three fused
/// multiply-adds rather than three loads and three stores besides.
///
/// # Safety
/// The processor has AVX2 and FMA, `strips` is at most 32, and every slot's strips `first ..
/// first + strips` are in `values`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn add_panels<V: StripValue>(
    values: &[[V; STRIP_ROWS]],
    list: &[Run],
    strips: usize,
    block: &mut [f32; 3 * BLOCK_ROWS],
) {
    let out = block.as_mut_ptr();
    for chunk in list.chunks(PANEL_TERMS) {
        let mut at = 0;
        // SAFETY (each call): the contract, and panels of strips `at .. at + N` inside the
        // slots' `strips` and the block's 32.
        while at + PANEL <= strips {
            unsafe { add_panel::<V, PANEL>(values, chunk, at, out) };
            at += PANEL;
        }
        match strips - at {
            1 => unsafe { add_panel::<V, 1>(values, chunk, at, out) },
            2 => unsafe { add_panel::<V, 2>(values, chunk, at, out) },
            3 => unsafe { add_panel::<V, 3>(values, chunk, at, out) },
            _ => {}
        }
    }
}

/// Adds strips `at .. at + N` of every slot of `chunk` to their accumulators in `out` (a block's
/// `3 * BLOCK_ROWS`), held in registers meanwhile.
///
/// # Safety
/// The processor has AVX2 and FMA; every slot's strips `first + at .. first + at + N` are in
/// `values`, and `at + N` is at most 32.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn add_panel<V: StripValue, const N: usize>(
    values: &[[V; STRIP_ROWS]],
    chunk: &[Run],
    at: usize,
    out: *mut f32,
) {
    use std::arch::x86_64::*;
    let v0 = values.as_ptr();
    // SAFETY: the caller runs with AVX2 (the contract).
    let mut a = [[unsafe { _mm256_setzero_ps() }; 3]; N];
    for f in chunk {
        // SAFETY: the contract.
        let l = f.l.map(|x| unsafe { _mm256_set1_ps(x) });
        // SAFETY: strips `first + at .. first + at + N` are in `values` (the contract).
        let v = unsafe { v0.add(f.first() + at) };
        // The same panel of the next block's slot of this term follows the slot in memory (a
        // band stores a term's slots side by side): fetched ahead, as the hardware cannot guess
        // 64 interleaved runs, into the second-level cache (fetched into the first, the next
        // block's 16 KiB pushed out the current one's, and the full product ran 1.08 times
        // slower on the demo bake). This slot's next cache line, which the panel after next
        // reads, goes to the first. A prefetch never faults.
        unsafe { _mm_prefetch::<_MM_HINT_T1>(v.wrapping_add(f.count()).cast::<i8>()) };
        unsafe { _mm_prefetch::<_MM_HINT_T0>(v.cast::<i8>().wrapping_add(64)) };
        for (i, a) in a.iter_mut().enumerate() {
            // SAFETY: as above; eight values a strip, and AVX2 and FMA.
            unsafe {
                let x = V::widen_avx2(v.add(i).cast::<V>());
                for k in 0..3 {
                    a[k] = _mm256_fmadd_ps(x, l[k], a[k]);
                }
            }
        }
    }
    for (i, a) in a.iter().enumerate() {
        for (k, a) in a.iter().enumerate() {
            // SAFETY: strip `at + i` (below 32) of the block, channel `k`: inside the block's
            // `3 * BLOCK_ROWS` accumulators; AVX2.
            unsafe {
                let p = out.add(accumulator((at + i) * STRIP_ROWS, k));
                _mm256_storeu_ps(p, _mm256_add_ps(_mm256_loadu_ps(p), *a));
            }
        }
    }
}

/// Slots of [`CachedPanels`]: with 32 strips of 8 bytes each, 16 KiB.
const CACHED_SLOTS: usize = 64;

/// The panels' arithmetic alone, the ceiling of the product on this processor however its
/// strips are read: `add_panels` over 64 whole slots of 32 int8 strips that stay in the
/// first-level cache, made once so that a round times the panels and nothing else.
pub struct CachedPanels {
    values: Vec<[i8; STRIP_ROWS]>,
    runs: Vec<Run>,
    block: Box<[f32; 3 * BLOCK_ROWS]>,
}

impl CachedPanels {
    /// Strips a round adds.
    pub const STRIPS: usize = CACHED_SLOTS * STRIPS_PER_BLOCK;

    /// The slots, or `None` without AVX2 and FMA.
    pub fn new() -> Option<Self> {
        if !has_avx2_fma() {
            return None;
        }
        Some(CachedPanels {
            values: (0..Self::STRIPS)
                .map(|s| std::array::from_fn(|r| ((s * 7 + r * 3) % 255) as i8))
                .collect(),
            runs: (0..CACHED_SLOTS)
                .map(|slot| Run {
                    first: (slot * STRIPS_PER_BLOCK) as u32,
                    block: 0,
                    count: STRIPS_PER_BLOCK as u16,
                    l: [1.0, 0.5, 0.25].map(|l| l / (slot + 1) as f32),
                })
                .collect(),
            block: Box::new([0.0; 3 * BLOCK_ROWS]),
        })
    }

    /// Adds every slot `rounds` times ([`Self::STRIPS`] strips a round, on this thread) to
    /// accumulators that start at zero, and returns their sum.
    pub fn add(&mut self, rounds: usize) -> f64 {
        self.block.fill(0.0);
        #[cfg(target_arch = "x86_64")]
        for _ in 0..rounds {
            let runs = std::hint::black_box(&self.runs[..]);
            // SAFETY: AVX2 and FMA were detected where `self` was made; every slot holds 32
            // strips inside `values`.
            unsafe { add_panels(&self.values, runs, STRIPS_PER_BLOCK, &mut self.block) };
        }
        let _ = rounds;
        self.block.iter().map(|&a| a as f64).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arithmetic probe adds what it says: each strip's values times its slot's light, every
    /// round.
    #[test]
    fn the_panels_in_cache_add_every_strip_of_every_round() {
        let Some(mut panels) = CachedPanels::new() else {
            eprintln!("no AVX2: the probe does not run");
            return;
        };
        // Twice, to check that each call starts from zero.
        panels.add(1);
        let sum = panels.add(3);
        let mut want = 0.0f64;
        for slot in 0..CACHED_SLOTS {
            let light: f64 = [1.0f64, 0.5, 0.25].iter().sum::<f64>() / (slot + 1) as f64;
            for s in slot * STRIPS_PER_BLOCK..(slot + 1) * STRIPS_PER_BLOCK {
                for r in 0..STRIP_ROWS {
                    want += ((s * 7 + r * 3) % 255) as i8 as f64 * light;
                }
            }
        }
        want *= 3.0;
        assert!(
            (sum - want).abs() <= 1e-5 * want.abs().max(1.0),
            "{sum} against {want}"
        );
    }
}
