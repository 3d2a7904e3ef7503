//! Real spherical harmonics at the texel centres of a cube: the one table that projects both a
//! cube-map light (`L_i = Σ_j L_j Ω_j Y_i(d_j)`) and the bake's transport rows, so the two meet
//! on the same directions. The light stage and the bake both use it.

use rayon::prelude::*;

use crate::error::Result;
use crate::math::cubemap::{CubeMap, solid_angles, texel_count, texel_dirs};

/// Real SH evaluated at every texel centre of a cube: `values[j·n² + i] = Y_i(d_j)`. Projects cube
/// lights and transport rows consistently (the same texel directions on both sides).
#[derive(Clone, Debug)]
pub struct TexelShBasis {
    /// SH order.
    pub order: usize,
    /// Cube face size.
    pub n: usize,
    /// Texel-major values.
    pub values: Vec<f32>,
    /// Exact texel solid angles, kept so projecting a light does not recompute them.
    pub omega: Vec<f64>,
}

impl TexelShBasis {
    /// Tabulates the basis.
    pub fn new(n: usize, order: usize) -> Result<Self> {
        crate::math::cubemap::validate_n(n)?;
        crate::math::sh::check_order(order)?;
        let count = order * order;
        let mut values = vec![0.0f32; texel_count(n) * count];
        let mut y = vec![0.0f64; count];
        for (j, d) in texel_dirs(n).into_iter().enumerate() {
            crate::math::sh::eval(order, d, &mut y);
            for (o, v) in values[j * count..(j + 1) * count].iter_mut().zip(&y) {
                *o = *v as f32;
            }
        }
        Ok(TexelShBasis {
            order,
            n,
            values,
            omega: solid_angles(n),
        })
    }

    /// SH light vector of a cube map, `L_i = Σ_j L_j Ω_j Y_i(d_j)`.
    pub fn project_light(&self, cube: &CubeMap) -> Result<Vec<[f64; 3]>> {
        cube.expect_n(self.n, "the SH basis was made for")?;
        let count = self.order * self.order;
        // One accumulator per channel, so the loop over coefficients is a plain multiply-add
        // over contiguous values; texels are split across threads in chunks.
        const CHUNK: usize = 1024;
        let sums = cube
            .texels
            .par_chunks(CHUNK)
            .enumerate()
            .fold(
                || vec![0.0f64; 3 * count],
                |mut acc, (chunk, texels)| {
                    let (r, rest) = acc.split_at_mut(count);
                    let (g, b) = rest.split_at_mut(count);
                    for (i, l) in texels.iter().enumerate() {
                        if *l == [0.0; 3] {
                            continue;
                        }
                        let j = chunk * CHUNK + i;
                        let w = self.omega[j];
                        let (lr, lg, lb) = (l[0] as f64 * w, l[1] as f64 * w, l[2] as f64 * w);
                        let row = &self.values[j * count..(j + 1) * count];
                        for (((y, r), g), b) in row.iter().zip(&mut *r).zip(&mut *g).zip(&mut *b) {
                            let y = *y as f64;
                            *r += lr * y;
                            *g += lg * y;
                            *b += lb * y;
                        }
                    }
                    acc
                },
            )
            .reduce(
                || vec![0.0f64; 3 * count],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
                    a
                },
            );
        Ok((0..count)
            .map(|i| [sums[i], sums[count + i], sums[2 * count + i]])
            .collect())
    }

    /// SH transport of rows of texel transport (already containing solid angles):
    /// `out[r]_i = Σ_j rows[r]_j Y_i(d_j)`, n² values a row. The table is read in blocks of
    /// texels that every row goes through in turn, so a pixel's rows read it from memory once;
    /// each sum still runs over the texels in order, so a row's values are the same to the bit
    /// as when it is projected alone.
    pub fn project_rows(&self, rows: &[&[f32]]) -> Vec<Vec<f32>> {
        let arch = pulp::Arch::new();
        let values = &self.values;
        match self.order * self.order {
            // The orders a bake takes most: the sums of a row held in registers, in the widest
            // vector instructions the machine has.
            16 => arch.dispatch(ProjectBlocks::<16> { values, rows }),
            25 => arch.dispatch(ProjectBlocks::<25> { values, rows }),
            36 => arch.dispatch(ProjectBlocks::<36> { values, rows }),
            49 => arch.dispatch(ProjectBlocks::<49> { values, rows }),
            count => {
                let mut out = vec![vec![0.0f32; count]; rows.len()];
                for (j, y) in self.values.chunks_exact(count).enumerate() {
                    for (row, sums) in rows.iter().zip(out.iter_mut()) {
                        let t = row.get(j).copied().unwrap_or(0.0);
                        add_scaled(sums, t, y);
                    }
                }
                out
            }
        }
    }
}

/// Texels of the table a block holds: 256 texels of 36 values, 36 KiB, stay in the first cache
/// while each row goes through them.
const PROJECT_BLOCK: usize = 256;

/// [`TexelShBasis::project_rows`] for `C` values a texel, as a [`pulp::WithSimd`] so that its
/// loops are compiled for every vector instruction set `pulp` dispatches to.
struct ProjectBlocks<'a, const C: usize> {
    values: &'a [f32],
    rows: &'a [&'a [f32]],
}

impl<const C: usize> pulp::WithSimd for ProjectBlocks<'_, C> {
    type Output = Vec<Vec<f32>>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Vec<Vec<f32>> {
        project_blocks::<C>(self.values, self.rows)
    }
}

/// [`TexelShBasis::project_rows`] for `C` values a texel.
#[inline(always)]
fn project_blocks<const C: usize>(values: &[f32], rows: &[&[f32]]) -> Vec<Vec<f32>> {
    let mut out = vec![[0.0f32; C]; rows.len()];
    for (b, block) in values.chunks(PROJECT_BLOCK * C).enumerate() {
        let j0 = b * PROJECT_BLOCK;
        for (row, sums) in rows.iter().zip(out.iter_mut()) {
            let mut acc = *sums;
            let ts = row.get(j0..).unwrap_or(&[]);
            for (y, &t) in block.chunks_exact(C).zip(ts) {
                add_scaled(&mut acc, t, y);
            }
            *sums = acc;
        }
    }
    out.into_iter().map(|sums| sums.to_vec()).collect()
}

/// `sums += t · y`, value by value; nothing for `t = 0` (a texel below the surface, or past the
/// end of a short row).
#[inline(always)]
fn add_scaled(sums: &mut [f32], t: f32, y: &[f32]) {
    if t == 0.0 {
        return;
    }
    for (o, y) in sums.iter_mut().zip(y) {
        *o += t * y;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Projecting several rows together gives each row the values of a plain loop over that
    /// row alone, to the bit: at order 6 (the blocked loop, over more than one block of texels)
    /// and order 3 (the plain one).
    #[test]
    fn rows_projected_together_are_each_row_alone() {
        let n = 8;
        for order in [6, 3] {
            let basis = TexelShBasis::new(n, order).unwrap();
            let rows: Vec<Vec<f32>> = (0..5)
                .map(|r| {
                    (0..texel_count(n))
                        .map(|j| match (j * 31 + r * 17) % 7 {
                            0 => 0.0,
                            k => (k as f32 - 3.3) * 1e-3 * (1.0 + r as f32),
                        })
                        .collect()
                })
                .collect();
            let refs: Vec<&[f32]> = rows.iter().map(|r| &r[..]).collect();
            let together = basis.project_rows(&refs);
            let count = order * order;
            for (row, got) in rows.iter().zip(&together) {
                let mut alone = vec![0.0f32; count];
                for (j, &t) in row.iter().enumerate() {
                    for (i, o) in alone.iter_mut().enumerate() {
                        *o += t * basis.values[j * count + i];
                    }
                }
                assert_eq!(got, &alone, "order {order}");
            }
        }
    }

    #[test]
    fn light_projection_is_the_plain_sum() {
        // L_i = Σ_j L_j Ω_j Y_i(d_j), written out serially against the chunked, per-channel
        // projection: only the order of f64 sums differs.
        const SUM_ORDER_REL: f64 = 1e-12;
        let n = 16;
        let texels: Vec<[f32; 3]> = (0..texel_count(n))
            .map(|j| {
                let a = ((j * 7919) % 1000) as f32 / 100.0;
                if j % 5 == 0 {
                    [0.0; 3]
                } else {
                    [a, 0.5 * a, 2.0]
                }
            })
            .collect();
        let cube = CubeMap { n, texels };
        let basis = TexelShBasis::new(n, 6).unwrap();
        let got = basis.project_light(&cube).unwrap();
        let omega = solid_angles(n);
        let mut y = vec![0.0f64; 36];
        let mut want = vec![[0.0f64; 3]; 36];
        for (j, d) in texel_dirs(n).into_iter().enumerate() {
            crate::math::sh::eval(6, d, &mut y);
            for (w, y) in want.iter_mut().zip(&y) {
                for (w, l) in w.iter_mut().zip(cube.texels[j]) {
                    *w += l as f64 * omega[j] * (*y as f32) as f64;
                }
            }
        }
        let scale = want[0][0].abs();
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            for c in 0..3 {
                assert!(
                    (g[c] - w[c]).abs() <= SUM_ORDER_REL * scale,
                    "coefficient {i}, channel {c}: {} vs {}",
                    g[c],
                    w[c]
                );
            }
        }
    }
}
