//! How transport values are stored: small integers against one scale per (row block, Haar
//! coefficient), so no stored value is ever a subnormal float and a coefficient costs two bytes
//! with its row index.
//!
//! A tile's rows are cut into blocks of at most [`BLOCK_ROWS`] rows, so a row index fits one byte
//! (Ng et al. 2003 used 8-bit indices in blocks of 256 rows the same way). Inside a block, the
//! entries of coefficient j are integers q with the value `q · scale(code)`, where `code` is one
//! byte per (block, coefficient) and `scale(code) = 2^((code − 192) / 4)`: quarter-octave steps
//! from 2^-48 to 2^15.75. The code is the smallest whose scale lets the column's largest
//! magnitude reach the integer range, so the largest value of a column is stored with at least
//! 6.7 significant bits (q8: |q| from 107 to 127) and every value with an absolute error of at
//! most half a step, `scale / 2`. The kernels fold the scale into the light term once per block
//! and column, so the inner loop only widens an integer.

use std::sync::LazyLock;

use serde::{Deserialize, Serialize};
use strum::{IntoStaticStr, VariantArray};

/// Most rows in one block: row indices are one byte.
pub const BLOCK_ROWS: usize = 256;
/// `scale(code) = 2^((code − SCALE_CODE_BIAS) / SCALE_STEPS_PER_OCTAVE)`.
pub const SCALE_CODE_BIAS: i32 = 192;
/// Scale steps per factor of two.
pub const SCALE_STEPS_PER_OCTAVE: i32 = 4;
/// The code of scale 1, used by lossless (f32) files.
pub const UNIT_SCALE_CODE: u8 = SCALE_CODE_BIAS as u8;

/// How stored coefficient values are quantised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[derive(Serialize, Deserialize, IntoStaticStr, strum::Display, VariantArray)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Quantization {
    /// Signed 8-bit integers against the column scale (one byte).
    Q8,
    /// Signed 16-bit integers against the column scale (two bytes).
    Q16,
    /// 32-bit floats with unit scale, for lossless bakes.
    F32,
}

impl Quantization {
    /// Largest integer magnitude stored (the float range for f32).
    pub fn q_max(self) -> f32 {
        match self {
            Quantization::Q8 => i8::MAX as f32,
            Quantization::Q16 => i16::MAX as f32,
            Quantization::F32 => f32::MAX,
        }
    }
    /// Bytes per stored value.
    pub fn value_bytes(self) -> usize {
        match self {
            Quantization::Q8 => 1,
            Quantization::Q16 => 2,
            Quantization::F32 => 4,
        }
    }
    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

crate::named!(Quantization, "quantization");

static SCALES: LazyLock<[f32; 256]> = LazyLock::new(|| {
    std::array::from_fn(|code| {
        2f64.powf((code as i32 - SCALE_CODE_BIAS) as f64 / SCALE_STEPS_PER_OCTAVE as f64) as f32
    })
});

/// The scale of a code (every one a normal f32).
#[inline]
pub fn scale_of(code: u8) -> f32 {
    SCALES[code as usize]
}

/// All 256 scales, indexed by code (the GPU gets this table).
pub fn scale_table() -> &'static [f32; 256] {
    &SCALES
}

/// The smallest code whose scale times `q_max` reaches `max_abs`; `None` when even the largest
/// scale cannot (a value beyond 2^15.75 · q_max).
pub fn code_for(max_abs: f32, q_max: f32) -> Option<u8> {
    if !max_abs.is_finite() {
        return None;
    }
    let table = scale_table();
    // The first code whose reach covers max_abs; the table is increasing.
    let code = table.partition_point(|&s| s * q_max < max_abs);
    u8::try_from(code).ok()
}

/// Quantises `v` against `scale`: the nearest integer, clamped to ±`q_max`.
#[inline]
pub fn quantize(v: f32, scale: f32, q_max: f32) -> f32 {
    (v / scale).round().clamp(-q_max, q_max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A decoded value's distance from the original, in steps: rounding to the nearest integer
    /// multiple of the step errs by at most half of it, the bound the module documents...
    const HALF_STEP: f32 = 0.5;
    /// ...plus this much of the value, for the f32 rounding of the division by the step and of
    /// the product that decodes: half an ulp each at most, inside 2ε of the value.
    const DECODE_ROUNDING: f32 = 2.0 * f32::EPSILON;

    #[test]
    fn scales_are_normal_increasing_and_exact_at_powers_of_two() {
        let t = scale_table();
        assert!(t.iter().all(|s| s.is_normal()));
        assert!(t.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(scale_of(UNIT_SCALE_CODE), 1.0);
        assert_eq!(scale_of(UNIT_SCALE_CODE - 4), 0.5);
        assert_eq!(scale_of(0), 2f32.powi(-48));
    }

    #[test]
    fn code_is_the_smallest_that_reaches() {
        for q in [Quantization::Q8, Quantization::Q16] {
            let q_max = q.q_max();
            for &m in &[1e-12f32, 3.3e-6, 1.5e-5, 4.0e-5, 2.6e-3, 0.3, 7.0] {
                let code = code_for(m, q_max).unwrap();
                assert!(scale_of(code) * q_max >= m);
                assert!(code == 0 || scale_of(code - 1) * q_max < m);
                // The column maximum keeps at least 6.7 significant bits in q8 (unless the
                // smallest scale already reaches it).
                let top = quantize(m, scale_of(code), q_max).abs();
                assert!(
                    code == 0 || top >= (q_max / 2f32.powf(0.25)).floor(),
                    "{m}: {top}"
                );
            }
        }
        assert_eq!(code_for(f32::INFINITY, 127.0), None);
        assert_eq!(code_for(1e9, 127.0), None);
    }

    /// Round trip: the decoded value is within half a step of the original, whatever its size
    /// relative to the column maximum.
    #[test]
    fn round_trip_error_is_at_most_half_a_step() {
        let mut state = 7u64;
        for q in [Quantization::Q8, Quantization::Q16] {
            let q_max = q.q_max();
            for _ in 0..2000 {
                state = crate::math::sampling::mix64(state);
                let m = 10f32.powf(-8.0 + 8.0 * (state % 1000) as f32 / 1000.0);
                let code = code_for(m, q_max).unwrap();
                let s = scale_of(code);
                for k in 0..16 {
                    let v = m * (k as f32 / 15.0) * if k % 2 == 0 { 1.0 } else { -1.0 };
                    let back = quantize(v, s, q_max) * s;
                    // Half a step, plus the f32 rounding of the division and the product.
                    assert!(
                        (back - v).abs() <= HALF_STEP * s + DECODE_ROUNDING * v.abs(),
                        "{v} -> {back}, step {s}"
                    );
                }
            }
        }
    }
}
