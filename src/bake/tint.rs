//! Rows of one lobe of one material over a pixel's camera sub-samples, where the lobe's colour
//! changes from sub-sample to sub-sample (a texture under the pixel).
//!
//! The pixel's light is `Σ_s c_s ⊙ r_s`: each sub-sample's row weighed by its own colour, before
//! the sub-samples are averaged. A row of this engine carries one RGB weight, so the sum is held
//! as the plain sum `R = Σ_s r_s` with the colour `c` that best explains it (least squares per
//! channel), plus per channel the residual `Σ_s c_s,k r_s − c_k R`. The residual vanishes where
//! either the colour or the row is the same for every sub-sample, which is nearly everywhere, so
//! thresholding drops nearly all of it; where visibility and texture change together (a shadow
//! edge across a texel edge) it keeps what the product needs.

use glam::Vec3;

/// Residual entries smaller than this fraction of their channel's sum are rounding noise of the
/// subtraction (a colour that does not vary leaves one of about 1e-7) and are cleared, so that a
/// lossless bake stores no rows of noise.
const RESIDUAL_NOISE: f32 = 1e-5;

/// The running sums of one tinted lobe of a pixel.
pub(super) struct TintedRow {
    sum: Vec<f32>,
    channels: [Vec<f32>; 3],
}

impl TintedRow {
    /// Empty sums over rows of `len` texels.
    pub(super) fn new(len: usize) -> Self {
        TintedRow {
            sum: vec![0.0; len],
            channels: std::array::from_fn(|_| vec![0.0; len]),
        }
    }

    /// Adds one sub-sample's `row` of colour `colour`.
    pub(super) fn add(&mut self, colour: Vec3, row: &[f32]) {
        let [r, g, b] = &mut self.channels;
        for ((((s, cr), cg), cb), &v) in self
            .sum
            .iter_mut()
            .zip(r.iter_mut())
            .zip(g.iter_mut())
            .zip(b.iter_mut())
            .zip(row)
        {
            *s += v;
            *cr += colour.x * v;
            *cg += colour.y * v;
            *cb += colour.z * v;
        }
    }

    /// The (RGB weight, row) pairs whose weighted sum is `Σ_s c_s ⊙ r_s`: the plain sum with its
    /// best colour, then each channel's residual that is not zero. Rows that are all zero are
    /// left out.
    pub(super) fn finish(self) -> Vec<([f32; 3], Vec<f32>)> {
        let TintedRow { mut sum, channels } = self;
        let norm: f64 = sum.iter().map(|&v| (v as f64) * (v as f64)).sum();
        let colour: [f32; 3] = std::array::from_fn(|k| {
            if norm > 0.0 {
                let dot: f64 = channels[k]
                    .iter()
                    .zip(&sum)
                    .map(|(&c, &s)| c as f64 * s as f64)
                    .sum();
                (dot / norm) as f32
            } else {
                0.0
            }
        });
        let mut out = Vec::with_capacity(4);
        for (k, mut residual) in channels.into_iter().enumerate() {
            let mut any = false;
            for (d, &s) in residual.iter_mut().zip(&sum) {
                let r = *d - colour[k] * s;
                *d = if r.abs() <= RESIDUAL_NOISE * d.abs() {
                    0.0
                } else {
                    r
                };
                any |= *d != 0.0;
            }
            if any {
                out.push((std::array::from_fn(|i| (i == k) as u8 as f32), residual));
            }
        }
        if norm > 0.0 && colour != [0.0; 3] {
            out.insert(0, (colour, std::mem::take(&mut sum)));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Σ weight ⊙ row` of the pairs, per channel.
    fn total(pairs: &[([f32; 3], Vec<f32>)], len: usize) -> [Vec<f32>; 3] {
        std::array::from_fn(|k| {
            (0..len)
                .map(|j| pairs.iter().map(|(w, r)| w[k] * r[j]).sum())
                .collect()
        })
    }

    #[test]
    fn the_pairs_sum_to_the_tinted_rows() {
        let rows = [vec![1.0, 0.0, 0.5, 0.25], vec![1.0, 1.0, 0.0, 0.25]];
        let colours = [Vec3::new(0.9, 0.1, 0.2), Vec3::new(0.1, 0.8, 0.2)];
        let mut t = TintedRow::new(4);
        for (c, r) in colours.iter().zip(&rows) {
            t.add(*c, r);
        }
        let pairs = t.finish();
        let got = total(&pairs, 4);
        for k in 0..3 {
            for j in 0..4 {
                let want: f32 = (0..2).map(|s| colours[s][k] * rows[s][j]).sum();
                assert!((got[k][j] - want).abs() < 1e-6, "channel {k} texel {j}");
            }
        }
        // Blue is the same in both sub-samples: it needs no residual.
        assert!(pairs.iter().all(|(w, _)| *w != [0.0, 0.0, 1.0]));
        assert_eq!(pairs.len(), 3);
    }

    #[test]
    fn a_colour_that_varies_over_one_row_leaves_no_residual() {
        // The same row under two texture colours: one row of the mean colour, nothing else.
        let row = vec![0.3f32, 0.7, 0.1];
        let mut t = TintedRow::new(3);
        t.add(Vec3::new(0.2, 0.4, 0.6), &row);
        t.add(Vec3::new(0.6, 0.2, 0.3), &row);
        let pairs = t.finish();
        assert_eq!(pairs.len(), 1);
        let (w, r) = &pairs[0];
        let want = [0.4, 0.3, 0.45];
        for k in 0..3 {
            assert!((w[k] - want[k]).abs() < 1e-6);
        }
        assert_eq!(r, &vec![0.6, 1.4, 0.2]);
    }

    #[test]
    fn a_dark_pixel_has_no_rows() {
        let mut t = TintedRow::new(2);
        t.add(Vec3::ONE, &[0.0, 0.0]);
        assert!(t.finish().is_empty());
    }
}
