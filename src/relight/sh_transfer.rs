//! SH glossy transfer (Sloan, Kautz & Snyder 2002) of a per-vertex bake with visibility: per
//! glossy vertex, the matrix that takes the light's SH coefficients to those of the light the
//! vertex receives, shadowed, `M_ij = ∫ V(ω) y_i(ω) y_j(ω) dω`, summed over the open texels of
//! its visibility bits ([`Visibility`]), so the file stores nothing more for it. Per frame, `M · l`
//! is each vertex's transferred radiance, which the raster turns into exit radiance for any view
//! ([`crate::draw::sh_gloss`]).

use rayon::prelude::*;

use crate::error::{PrtError, Result};
use crate::math::cube_pyramid::{CubePyramid, morton_of_linear};
use crate::math::cubemap::{solid_angles, texel_count, texel_dirs};
use crate::math::sh::eval_f32_into;
use crate::scene::visibility::Visibility;

/// The highest SH order of a transfer matrix (64 coefficients, a 64 × 64 matrix a vertex).
pub const MAX_TRANSFER_ORDER: usize = 8;

/// The transfer matrices of a bake's glossy vertices at one SH order.
#[derive(Clone, Debug)]
pub struct ShTransfer {
    /// SH order n: n² coefficients in and out.
    pub order: usize,
    /// Per visibility row, the upper triangle of its symmetric n² × n² matrix, row by row.
    matrices: Vec<f32>,
    /// The visibility's rows.
    rows: usize,
}

/// Each texel's SH basis (`n²` values) and solid angle, indexed by its Morton index at face size
/// `cube_n`.
fn morton_basis(cube_n: usize, order: usize) -> (Vec<f32>, Vec<f32>) {
    let nn = order * order;
    let (dirs, omega, morton) = (
        texel_dirs(cube_n),
        solid_angles(cube_n),
        morton_of_linear(cube_n),
    );
    let mut basis = vec![0.0f32; texel_count(cube_n) * nn];
    let mut weight = vec![0.0f32; texel_count(cube_n)];
    for (i, &m) in morton.iter().enumerate() {
        let m = m as usize;
        eval_f32_into(order, dirs[i].as_vec3(), &mut basis[m * nn..(m + 1) * nn]);
        weight[m] = omega[i] as f32;
    }
    (basis, weight)
}

/// Checks that the glossy transfer matrix takes SH order `order`: 1 to [`MAX_TRANSFER_ORDER`].
pub fn check_order(order: usize) -> Result<()> {
    if !(1..=MAX_TRANSFER_ORDER).contains(&order) {
        return Err(PrtError::invalid(
            "SH transfer order",
            format!("{order}; the glossy transfer matrix takes orders 1 to {MAX_TRANSFER_ORDER}"),
        ));
    }
    Ok(())
}

impl ShTransfer {
    /// The matrices at SH order `order` (1 to [`MAX_TRANSFER_ORDER`]) of every vertex with
    /// visibility bits.
    pub fn new(vis: &Visibility, order: usize) -> Result<ShTransfer> {
        check_order(order)?;
        let nn = order * order;
        let packed = nn * (nn + 1) / 2;
        let (basis, weight) = morton_basis(vis.n, order);
        let words = Visibility::words(vis.n);
        let rows = vis.bits.len() / words;
        let mut matrices = vec![0.0f32; rows * packed];
        matrices
            .par_chunks_mut(packed)
            .zip(vis.bits.par_chunks(words))
            .for_each(|(m, bits)| {
                for (w, &word) in bits.iter().enumerate() {
                    let mut rest = word;
                    while rest != 0 {
                        let t = w * 32 + rest.trailing_zeros() as usize;
                        rest &= rest - 1;
                        let y = &basis[t * nn..(t + 1) * nn];
                        let mut at = 0;
                        for i in 0..nn {
                            let s = weight[t] * y[i];
                            for (e, yj) in m[at..at + nn - i].iter_mut().zip(&y[i..]) {
                                *e += s * yj;
                            }
                            at += nn - i;
                        }
                    }
                }
            });
        Ok(ShTransfer {
            order,
            matrices,
            rows,
        })
    }

    /// Bytes a vertex's matrix would take stored (the upper triangle in f32).
    pub fn bytes_per_vertex(order: usize) -> usize {
        let nn = order * order;
        nn * (nn + 1) / 2 * 4
    }

    /// Vertices with a matrix (the visibility's rows).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Row `row`'s matrix times `light` (n² RGB coefficients) into `out`.
    pub fn transfer_into(&self, row: usize, light: &[[f32; 3]], out: &mut [[f32; 3]]) {
        let nn = self.order * self.order;
        let packed = nn * (nn + 1) / 2;
        let m = &self.matrices[row * packed..(row + 1) * packed];
        out[..nn].fill([0.0; 3]);
        let mut at = 0;
        for i in 0..nn {
            let d = m[at];
            for c in 0..3 {
                out[i][c] += d * light[i][c];
            }
            for j in i + 1..nn {
                let e = m[at + j - i];
                for c in 0..3 {
                    out[i][c] += e * light[j][c];
                    out[j][c] += e * light[i][c];
                }
            }
            at += nn - i;
        }
    }

    /// Every row's transferred radiance under `light`: n² RGB coefficients a row.
    pub fn transferred(&self, light: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let nn = self.order * self.order;
        let mut out = vec![[0.0; 3]; self.rows() * nn];
        out.par_chunks_mut(nn)
            .enumerate()
            .for_each(|(r, o)| self.transfer_into(r, light, o));
        out
    }
}

/// The SH coefficients to `order` of the light a pyramid holds: its texels' `Σ L Ω` against the
/// basis at their centres.
pub fn pyramid_sh(light: &CubePyramid, order: usize) -> Vec<[f32; 3]> {
    let nn = order * order;
    let (basis, _) = morton_basis(light.n, order);
    let mut out = vec![[0.0f64; 3]; nn];
    for (m, s) in light.levels[0].iter().enumerate() {
        let y = &basis[m * nn..(m + 1) * nn];
        for k in 0..nn {
            for c in 0..3 {
                out[k][c] += s[c] as f64 * y[k] as f64;
            }
        }
    }
    out.iter().map(|c| c.map(|v| v as f32)).collect()
}
