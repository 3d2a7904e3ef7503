//! The local lights' columns of a transport: for every light column (a light at one of its
//! positions) the RGB response of every pixel (or vertex) to it at unit colour and intensity.
//!
//! Unlike the environment's rows, these are dense: a lamp lights most of what it can see. They
//! are stored as 16-bit floats relative to a power of two per (column, image row), chosen so that
//! the row's largest magnitude lies in (1/2, 1]:
//!
//! - halves keep 11 significant bits, a relative error of at most 2⁻¹¹ (4.9e-4), over the whole
//!   range a row of one light spans (its bright pool and its dim bounce light), where 16-bit
//!   integers against one scale lose the dim part;
//! - values below the smallest normal half (2⁻¹⁴ of the row's scale) are stored as 0, so no
//!   stored value is subnormal, which GPUs may flush;
//! - the scale is a power of two, so decoding is exact, and a row belongs to one band of tile
//!   rows, so the shards of a bake hold exactly the rows of the whole bake and merge bit for bit.
//!
//! Layout: `light_value` f16 `[L, 3, H, W]` (column, channel, pixel row, pixel), and
//! `light_exponent` i8 `[L, H]`, the power of two of each (column, row).

use half::f16;

/// The light columns of a transport (none for a scene without local lights).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightColumns {
    /// Pixels a row (the image's width).
    pub width: usize,
    /// Rows of pixels (the image's height).
    pub height: usize,
    /// `[L, H]`: the power of two each (column, row) is stored against.
    pub exponent: Vec<i8>,
    /// `[L, 3, H, W]`: the bits of the 16-bit floats.
    pub values: Vec<u16>,
}

/// Exponents a file may hold: every scale a finite f32 row can need.
pub const EXPONENTS: std::ops::RangeInclusive<i8> = -126..=127;

impl LightColumns {
    /// No columns, for an image of `width` x `height`.
    pub fn empty(width: usize, height: usize) -> Self {
        LightColumns {
            width,
            height,
            exponent: Vec::new(),
            values: Vec::new(),
        }
    }

    /// Columns of zeros, to be filled row by row with [`LightColumns::set_rows`].
    pub fn zeros(columns: usize, width: usize, height: usize) -> Self {
        LightColumns {
            width,
            height,
            exponent: vec![0; columns * height],
            values: vec![0; columns * 3 * width * height],
        }
    }

    /// Number of columns.
    pub fn count(&self) -> usize {
        self.exponent.len().checked_div(self.height).unwrap_or(0)
    }

    /// Bytes they take in the file.
    pub fn bytes(&self) -> usize {
        self.values.len() * 2 + self.exponent.len()
    }

    /// Encodes rows `y0 ..` from `band`, `[L, 3, rows, W]` f32, each (column, row) against its
    /// own power of two. Values must be finite (the bake checks its sums).
    pub fn set_rows(&mut self, y0: usize, band: &[f32]) {
        let (w, h) = (self.width, self.height);
        let l = self.count();
        let rows = band.len() / (l * 3 * w).max(1);
        for col in 0..l {
            for r in 0..rows.min(h.saturating_sub(y0)) {
                let y = y0 + r;
                let src = |c: usize| &band[((col * 3 + c) * rows + r) * w..][..w];
                let largest = (0..3)
                    .flat_map(|c| src(c).iter())
                    .fold(0.0f32, |m, v| m.max(v.abs()));
                let e = if largest > 0.0 && largest.is_finite() {
                    (largest.log2().ceil() as i32).clamp(-126, 127)
                } else {
                    0
                };
                // log2 can round either way near a power of two: keep the largest at most 1.
                let e = if largest / pow2(e) > 1.0 { e + 1 } else { e }.min(127);
                self.exponent[col * h + y] = e as i8;
                let inv = 1.0 / pow2(e);
                for c in 0..3 {
                    let dst = &mut self.values[((col * 3 + c) * h + y) * w..][..w];
                    for (d, v) in dst.iter_mut().zip(src(c)) {
                        let x = v * inv;
                        *d = if x.abs() < f16::MIN_POSITIVE.to_f32() {
                            0
                        } else {
                            f16::from_f32(x).to_bits()
                        };
                    }
                }
            }
        }
    }

    /// Copies rows `rows` of every column from `other` (same size and count): a merge takes
    /// each band from the shard that baked it.
    pub fn copy_rows(&mut self, other: &LightColumns, rows: std::ops::Range<usize>) {
        let (w, h) = (self.width, self.height);
        for col in 0..self.count() {
            let e = col * h + rows.start..col * h + rows.end;
            self.exponent[e.clone()].copy_from_slice(&other.exponent[e]);
            for c in 0..3 {
                let v = ((col * 3 + c) * h + rows.start) * w..((col * 3 + c) * h + rows.end) * w;
                self.values[v.clone()].copy_from_slice(&other.values[v]);
            }
        }
    }

    /// Whether rows `rows` of every column are all zero (a shard's rows of other bands).
    pub fn rows_are_zero(&self, rows: std::ops::Range<usize>) -> bool {
        let (w, h) = (self.width, self.height);
        (0..self.count() * 3).all(|plane| {
            self.values[(plane * h + rows.start) * w..(plane * h + rows.end) * w]
                .iter()
                .all(|&v| v & 0x7fff == 0)
        })
    }

    /// The value of column `col`, channel `c`, pixel `p` (`y · W + x`), decoded.
    pub fn value(&self, col: usize, c: usize, p: usize) -> f32 {
        let (w, h) = (self.width, self.height);
        f16::from_bits(self.values[(col * 3 + c) * h * w + p]).to_f32()
            * pow2(self.exponent[col * h + p / w.max(1)] as i32)
    }

    /// Adds `Σ_col weights[col] ⊙ column` to `pixels` (RGB, `y · W + x`); columns whose weight is
    /// zero are not read. `weights` has one entry per column.
    pub fn add_to(&self, weights: &[[f32; 3]], pixels: &mut [[f32; 3]]) {
        use rayon::prelude::*;
        let (w, h) = (self.width, self.height);
        let lit: Vec<(usize, [f32; 3])> = weights
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, wt)| wt.iter().any(|v| *v != 0.0))
            .collect();
        if lit.is_empty() || w == 0 {
            return;
        }
        pixels
            .par_chunks_mut(w)
            .take(h)
            .enumerate()
            .for_each(|(y, line)| {
                let mut decoded = vec![0.0f32; w];
                for &(col, wt) in &lit {
                    let scale = pow2(self.exponent[col * h + y] as i32);
                    for (c, &weight) in wt.iter().enumerate() {
                        if weight == 0.0 {
                            continue;
                        }
                        let src = &self.values[((col * 3 + c) * h + y) * w..][..w];
                        half::slice::HalfFloatSliceExt::convert_to_f32_slice(
                            bytemuck::cast_slice::<u16, f16>(src),
                            &mut decoded,
                        );
                        let s = weight * scale;
                        for (px, v) in line.iter_mut().zip(&decoded) {
                            px[c] += s * v;
                        }
                    }
                }
            });
    }

    /// The first thing wrong with the tables for `columns` columns of a `width` x `height`
    /// image: their lengths, exponents outside [`EXPONENTS`], and values that are not finite or
    /// are subnormal.
    pub fn problem(&self, columns: usize) -> Option<String> {
        let (w, h) = (self.width, self.height);
        if self.exponent.len() != columns * h || self.values.len() != columns * 3 * w * h {
            return Some(format!(
                "light tables for {} columns do not match the header's {columns} columns of a \
                 {w} x {h} image",
                self.count()
            ));
        }
        if let Some(e) = self.exponent.iter().find(|e| !EXPONENTS.contains(e)) {
            return Some(format!(
                "tensor `light_exponent` holds {e}, outside {} to {}",
                EXPONENTS.start(),
                EXPONENTS.end()
            ));
        }
        // Exponent bits all ones: infinity or NaN; all zeros with a mantissa: subnormal.
        if let Some(v) = self.values.iter().find(|&&v| {
            let exp = (v >> 10) & 0x1f;
            exp == 0x1f || (exp == 0 && v & 0x3ff != 0)
        }) {
            return Some(format!(
                "tensor `light_value` holds {} (bits {v:#06x}): every value must be finite and \
                 normal or zero",
                f16::from_bits(*v)
            ));
        }
        None
    }
}

/// 2^e as f32 for e in [-126, 127], exactly.
fn pow2(e: i32) -> f32 {
    f32::from_bits(((e.clamp(-126, 127) + 127) as u32) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_within_half_precision_and_flush_only_below_normal() {
        let (w, h) = (5, 3);
        let mut cols = LightColumns::zeros(2, w, h);
        let band: Vec<f32> = (0..2 * 3 * h * w)
            .map(|i| match i % 7 {
                0 => 0.0,
                1 => 1e-9,
                k => 1000.0 * k as f32 / (1 + i) as f32,
            })
            .collect();
        cols.set_rows(0, &band);
        assert!(cols.problem(2).is_none());
        for col in 0..2 {
            for c in 0..3 {
                for p in 0..w * h {
                    let want = band[((col * 3 + c) * h + p / w) * w + p % w];
                    let row_max = (0..3)
                        .flat_map(|c| {
                            let b = &band[((col * 3 + c) * h + p / w) * w..][..w];
                            b.iter().copied()
                        })
                        .fold(0.0f32, f32::max);
                    let got = cols.value(col, c, p);
                    let bound = (want.abs() * 2f32.powi(-11)).max(row_max * 2f32.powi(-14));
                    assert!((got - want).abs() <= bound, "{got} {want} {bound}");
                }
            }
        }
    }

    #[test]
    fn adding_columns_is_the_weighted_sum_of_their_values() {
        let (w, h) = (4, 2);
        let mut cols = LightColumns::zeros(2, w, h);
        let band: Vec<f32> = (0..2 * 3 * h * w).map(|i| (i % 5) as f32 * 0.25).collect();
        cols.set_rows(0, &band);
        let weights = [[1.0, 0.0, 2.0], [0.5, 0.5, 0.5]];
        let mut pixels = vec![[1.0f32; 3]; w * h];
        cols.add_to(&weights, &mut pixels);
        for (p, px) in pixels.iter().enumerate() {
            for c in 0..3 {
                let want =
                    1.0 + weights[0][c] * cols.value(0, c, p) + weights[1][c] * cols.value(1, c, p);
                assert!((px[c] - want).abs() < 1e-6, "{} {want}", px[c]);
            }
        }
    }

    #[test]
    fn subnormal_and_infinite_halves_are_refused() {
        let mut cols = LightColumns::zeros(1, 2, 1);
        assert!(cols.problem(1).is_none());
        cols.values[1] = 0x0001;
        assert!(cols.problem(1).unwrap().contains("normal"));
        cols.values[1] = 0x7c00;
        assert!(cols.problem(1).is_some());
        cols.values[1] = 0;
        cols.exponent[0] = -127;
        assert!(cols.problem(1).unwrap().contains("light_exponent"));
        assert!(cols.problem(2).is_some());
    }
}
