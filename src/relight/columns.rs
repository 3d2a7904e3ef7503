//! The local lights' part of a relight: the weighted sum of a transport's light columns
//! (`store::transport::lights`) added to the image, one weight per column, beside the
//! environment's sparse product.

use rayon::prelude::*;

use crate::store::transport::LightColumns;

/// Adds `Σ_col weights[col] ⊙ column` to `pixels` (RGB, `y · W + x`); columns whose weight is
/// zero are not read. `weights` has one entry per column.
pub fn add_columns(columns: &LightColumns, weights: &[[f32; 3]], pixels: &mut [[f32; 3]]) {
    let (w, h) = (columns.width, columns.height);
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
            // Channel planes of the row, summed over the lights, then added once: the inner
            // loop widens and multiplies contiguous integers, which the compiler vectorises.
            let mut planes = [vec![0.0f32; w], vec![0.0f32; w], vec![0.0f32; w]];
            for &(col, wt) in &lit {
                let step = columns.step(col, y);
                for (c, plane) in planes.iter_mut().enumerate() {
                    let weight = wt[c] * step;
                    if weight == 0.0 {
                        continue;
                    }
                    let src = &columns.values[((col * 3 + c) * h + y) * w..][..w];
                    for (a, &q) in plane.iter_mut().zip(src) {
                        *a += weight * q as f32;
                    }
                }
            }
            for (x, px) in line.iter_mut().enumerate() {
                for (c, plane) in planes.iter().enumerate() {
                    px[c] += plane[x];
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::transport::two_columns;

    #[test]
    fn adding_columns_is_the_weighted_sum_of_their_values() {
        let (w, h) = (4, 2);
        let (cols, _) = two_columns(w, h, |i| (i % 5) as f32 * 0.25);
        let weights = [[1.0, 0.0, 2.0], [0.5, 0.5, 0.5]];
        let mut pixels = vec![[1.0f32; 3]; w * h];
        add_columns(&cols, &weights, &mut pixels);
        for (p, px) in pixels.iter().enumerate() {
            for c in 0..3 {
                let want =
                    1.0 + weights[0][c] * cols.value(0, c, p) + weights[1][c] * cols.value(1, c, p);
                assert!((px[c] - want).abs() < 1e-6, "{} {want}", px[c]);
            }
        }
    }
}
