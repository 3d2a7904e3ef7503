//! The local lights' columns of a transport: for every light column (a light at one of its
//! positions) the RGB response of every pixel (or vertex) to it at unit colour and intensity.
//!
//! Unlike the environment's rows, these are dense: a lamp lights most of what it can see. They
//! are stored as 16-bit unsigned integers against a scale per (column, image row), the row's
//! largest value: `value = q · scale / 65535`, an absolute error of at most 2⁻¹⁷ of the row's
//! brightest value, closer on the point light test (`tests/local_lights.rs`) than 16-bit floats'
//! 2⁻¹² of every value, and faster to add up (criterion, `light_columns_256x256`): an integer
//! widens to f32 in the instruction that multiplies it, where a half needs a conversion the
//! compiler does not vectorise. They hold no subnormals: a row whose largest value is below
//! [`SMALLEST_SCALE`] is stored as zeros. A row belongs to one band of tile rows, so the
//! shards of a bake hold exactly the rows of the whole bake and merge bit for bit.
//!
//! Layout: `light_value` u16 `[L, 3, H, W]` (column, channel, pixel row, pixel), and
//! `light_scale` f32 `[L, H]`, the scale of each (column, row).

/// Rows whose largest value lies below this are stored as zeros: every decoded value of a row
/// stored is then a normal f32 (or zero), as GPUs that flush subnormals read it.
pub const SMALLEST_SCALE: f32 = 1e-30;

/// The largest stored integer: `q / QUANTA` of the row's scale.
const QUANTA: f32 = 65535.0;

/// The light columns of a transport (none for a scene without local lights).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightColumns {
    /// Pixels a row (the image's width).
    pub width: usize,
    /// Rows of pixels (the image's height).
    pub height: usize,
    /// `[L, H]`: each (column, row)'s largest value, which the integers are fractions of.
    pub scale: Vec<f32>,
    /// `[L, 3, H, W]`: the integers.
    pub values: Vec<u16>,
}

impl LightColumns {
    /// No columns, for an image of `width` x `height`.
    pub fn empty(width: usize, height: usize) -> Self {
        LightColumns {
            width,
            height,
            scale: Vec::new(),
            values: Vec::new(),
        }
    }

    /// Columns of zeros, to be filled row by row with [`LightColumns::set_rows`].
    pub fn zeros(columns: usize, width: usize, height: usize) -> Self {
        LightColumns {
            width,
            height,
            scale: vec![0.0; columns * height],
            values: vec![0; columns * 3 * width * height],
        }
    }

    /// Number of columns.
    pub fn count(&self) -> usize {
        self.scale.len().checked_div(self.height).unwrap_or(0)
    }

    /// Bytes they take in the file.
    pub fn bytes(&self) -> usize {
        self.values.len() * 2 + self.scale.len() * 4
    }

    /// Encodes rows `y0 ..` from `band`, `[L, 3, rows, W]` f32, each (column, row) against its
    /// own largest value. Values must be finite and >= 0 (light is; the bake checks its sums);
    /// anything else is stored as 0.
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
                    .fold(0.0f32, |m, &v| if v.is_finite() { m.max(v) } else { m });
                let scale = if largest >= SMALLEST_SCALE {
                    largest
                } else {
                    0.0
                };
                self.scale[col * h + y] = scale;
                let inv = if scale > 0.0 { QUANTA / scale } else { 0.0 };
                for c in 0..3 {
                    let dst = &mut self.values[((col * 3 + c) * h + y) * w..][..w];
                    for (d, v) in dst.iter_mut().zip(src(c)) {
                        // NaN and negative values saturate to 0, the largest to 65535.
                        *d = (v * inv).round().clamp(0.0, QUANTA) as u16;
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
            self.scale[e.clone()].copy_from_slice(&other.scale[e]);
            for c in 0..3 {
                let v = ((col * 3 + c) * h + rows.start) * w..((col * 3 + c) * h + rows.end) * w;
                self.values[v.clone()].copy_from_slice(&other.values[v]);
            }
        }
    }

    /// Whether rows `rows` of every column are all zero (a shard's rows of other bands).
    pub fn rows_are_zero(&self, rows: std::ops::Range<usize>) -> bool {
        let (w, h) = (self.width, self.height);
        (0..self.count()).all(|col| {
            self.scale[col * h + rows.start..col * h + rows.end]
                .iter()
                .all(|&s| s == 0.0)
        }) && (0..self.count() * 3).all(|plane| {
            self.values[(plane * h + rows.start) * w..(plane * h + rows.end) * w]
                .iter()
                .all(|&v| v == 0)
        })
    }

    /// The value of column `col`, channel `c`, pixel `p` (`y · W + x`), decoded.
    pub fn value(&self, col: usize, c: usize, p: usize) -> f32 {
        let (w, h) = (self.width, self.height);
        self.values[(col * 3 + c) * h * w + p] as f32 * self.step(col, p / w.max(1))
    }

    /// What one integer step of (column `col`, row `y`) is worth.
    #[inline]
    pub fn step(&self, col: usize, y: usize) -> f32 {
        self.scale[col * self.height + y] * (1.0 / QUANTA)
    }

    /// The first thing wrong with the tables for `columns` columns: their lengths, and scales
    /// that are not finite, negative, or so small that decoded values would be subnormal.
    pub fn problem(&self, columns: usize) -> Option<String> {
        let (w, h) = (self.width, self.height);
        if self.scale.len() != columns * h || self.values.len() != columns * 3 * w * h {
            return Some(format!(
                "light tables for {} columns do not match the header's {columns} columns of a \
                 {w} x {h} image",
                self.count()
            ));
        }
        if let Some(s) = self
            .scale
            .iter()
            .find(|&&s| !(s == 0.0 || (s.is_finite() && s >= SMALLEST_SCALE)))
        {
            return Some(format!(
                "tensor `{}` holds {s}: every scale must be 0, or finite and at least \
                 {SMALLEST_SCALE:e}",
                super::groups::LightTensors::SCALE
            ));
        }
        None
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Two columns of `w` x `h` whose value `i` in [`LightColumns::set_rows`]' order is
    /// `value(i)`, and those values.
    pub(crate) fn two_columns(
        w: usize,
        h: usize,
        value: impl Fn(usize) -> f32,
    ) -> (LightColumns, Vec<f32>) {
        let mut cols = LightColumns::zeros(2, w, h);
        let band: Vec<f32> = (0..2 * 3 * h * w).map(value).collect();
        cols.set_rows(0, &band);
        (cols, band)
    }

    #[test]
    fn rows_round_trip_within_half_a_step_of_their_largest_value() {
        let (w, h) = (5, 3);
        let (cols, band) = two_columns(w, h, |i| match i % 7 {
            0 => 0.0,
            1 => 1e-9,
            k => 1000.0 * k as f32 / (1 + i) as f32,
        });
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
                    let bound = row_max * (0.5 / QUANTA) * (1.0 + 1e-6) + want * 1e-6;
                    assert!((got - want).abs() <= bound, "{got} {want} {bound}");
                }
            }
        }
        // The largest value of a row comes back as stored, to f32 rounding.
        let largest = band[..w].iter().copied().fold(0.0f32, f32::max);
        assert!(cols.values[..w].contains(&65535), "{largest}");
    }

    #[test]
    fn tiny_rows_are_stored_as_zero_and_bad_scales_are_refused() {
        let mut cols = LightColumns::zeros(1, 2, 1);
        cols.set_rows(0, &[1e-35, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!((cols.scale[0], cols.values[0]), (0.0, 0));
        assert!(cols.problem(1).is_none());
        for bad in [f32::NAN, f32::INFINITY, -1.0, 1e-33] {
            cols.scale[0] = bad;
            assert!(cols.problem(1).unwrap().contains("light_scale"), "{bad}");
        }
        cols.scale[0] = 1.0;
        assert!(cols.problem(2).is_some());
    }
}
