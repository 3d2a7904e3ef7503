//! The leading singular triplets of a dense matrix, for the in-out factorisation of BRDFs.
//!
//! Block subspace iteration (Golub & Van Loan, "Matrix Computations", 4th ed., section 8.2.4, on
//! `AᵀA`): a block of `k + 8` orthonormal columns is multiplied by `A` then `Aᵀ` and orthonormalised
//! again until its span settles, then the small Gram matrix of the block is diagonalised by cyclic
//! Jacobi rotations (section 8.5) for the singular values and right vectors. The spectra it is
//! used on fall off fast, so a few dozen sweeps converge; the tests check the triplets against
//! the Eckart–Young identity and a known factorisation.

use rayon::prelude::*;

use crate::math::sampling::Rng;

/// The leading singular triplets `A ≈ Σ s_k u_k v_kᵀ` of a `rows × cols` matrix.
#[derive(Clone, Debug)]
pub struct Svd {
    /// Singular values, largest first.
    pub values: Vec<f64>,
    /// Left vectors, `rows` values each.
    pub left: Vec<Vec<f64>>,
    /// Right vectors, `cols` values each.
    pub right: Vec<Vec<f64>>,
}

/// Extra columns of the iterated block beyond those asked for: they speed convergence of the last
/// wanted vectors.
const OVERSAMPLE: usize = 8;
/// Block iterations.
const ITERATIONS: usize = 60;

/// `out = A x` for a row-major `rows × cols` matrix.
fn times(a: &[f64], cols: usize, x: &[f64], out: &mut [f64]) {
    for (o, row) in out.iter_mut().zip(a.chunks_exact(cols)) {
        *o = row.iter().zip(x).map(|(a, b)| a * b).sum();
    }
}

/// `out = Aᵀ y` for a row-major `rows × cols` matrix.
fn times_transposed(a: &[f64], cols: usize, y: &[f64], out: &mut [f64]) {
    out.iter_mut().for_each(|o| *o = 0.0);
    for (row, &yi) in a.chunks_exact(cols).zip(y) {
        if yi != 0.0 {
            for (o, &v) in out.iter_mut().zip(row) {
                *o += v * yi;
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Orthonormalises `block` in place by modified Gram–Schmidt, twice for accuracy; a column that
/// vanishes against the earlier ones is left zero.
fn orthonormalise(block: &mut [Vec<f64>]) {
    for _ in 0..2 {
        for i in 0..block.len() {
            let (done, rest) = block.split_at_mut(i);
            let v = &mut rest[0];
            for q in done.iter() {
                let d = dot(q, v);
                v.iter_mut().zip(q).for_each(|(x, y)| *x -= d * y);
            }
            let norm = dot(v, v).sqrt();
            let scale = if norm > 1e-300 { 1.0 / norm } else { 0.0 };
            v.iter_mut().for_each(|x| *x *= scale);
        }
    }
}

/// Eigenvalues and eigenvectors (columns of the returned row-major matrix) of the symmetric
/// `n × n` matrix `m`, by cyclic Jacobi rotations.
fn symmetric_eigen(mut m: Vec<f64>, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    for _ in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i * n + j] * m[i * n + j])
            .sum();
        let scale: f64 = (0..n).map(|i| m[i * n + i] * m[i * n + i]).sum();
        if off <= 1e-30 * scale.max(1e-300) {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = m[p * n + q];
                if apq.abs() < 1e-300 {
                    continue;
                }
                let theta = (m[q * n + q] - m[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (mkp, mkq) = (m[k * n + p], m[k * n + q]);
                    m[k * n + p] = c * mkp - s * mkq;
                    m[k * n + q] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let (mpk, mqk) = (m[p * n + k], m[q * n + k]);
                    m[p * n + k] = c * mpk - s * mqk;
                    m[q * n + k] = s * mpk + c * mqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| m[i * n + i]).collect(), v)
}

/// The `k` leading singular triplets of the row-major `rows × cols` matrix `a` (fewer when the
/// matrix is smaller), from a seeded start.
pub fn leading(a: &[f64], rows: usize, cols: usize, k: usize, seed: u64) -> Svd {
    assert_eq!(a.len(), rows * cols, "matrix of {rows} x {cols}");
    let k = k.min(rows).min(cols);
    let b = (k + OVERSAMPLE).min(cols);
    let mut rng = Rng::new(seed, 0x5fd);
    let mut block: Vec<Vec<f64>> = (0..b)
        .map(|_| (0..cols).map(|_| rng.next_f64() - 0.5).collect())
        .collect();
    orthonormalise(&mut block);
    for _ in 0..ITERATIONS {
        block.par_iter_mut().for_each(|q| {
            let mut image = vec![0.0; rows];
            times(a, cols, q, &mut image);
            times_transposed(a, cols, &image, q);
        });
        orthonormalise(&mut block);
    }
    // Rayleigh–Ritz: the Gram matrix of A on the block, diagonalised.
    let images: Vec<Vec<f64>> = block
        .iter()
        .map(|q| {
            let mut y = vec![0.0; rows];
            times(a, cols, q, &mut y);
            y
        })
        .collect();
    let mut gram = vec![0.0; b * b];
    for i in 0..b {
        for j in 0..b {
            gram[i * b + j] = dot(&images[i], &images[j]);
        }
    }
    let (eigen, vectors) = symmetric_eigen(gram, b);
    let mut order: Vec<usize> = (0..b).collect();
    order.sort_by(|&i, &j| eigen[j].total_cmp(&eigen[i]));
    let mut svd = Svd {
        values: Vec::with_capacity(k),
        left: Vec::with_capacity(k),
        right: Vec::with_capacity(k),
    };
    for &e in order.iter().take(k) {
        let s = eigen[e].max(0.0).sqrt();
        let right: Vec<f64> = (0..cols)
            .map(|c| (0..b).map(|i| vectors[i * b + e] * block[i][c]).sum())
            .collect();
        let mut left = vec![0.0; rows];
        times(a, cols, &right, &mut left);
        let inv = if s > 0.0 { 1.0 / s } else { 0.0 };
        left.iter_mut().for_each(|x| *x *= inv);
        svd.values.push(s);
        svd.left.push(left);
        svd.right.push(right);
    }
    svd
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `rows × cols` matrix with the given singular values and random orthonormal vectors.
    fn with_spectrum(rows: usize, cols: usize, values: &[f64], seed: u64) -> (Vec<f64>, Svd) {
        let mut rng = Rng::new(seed, 1);
        let mut random = |n: usize, count: usize| {
            let mut b: Vec<Vec<f64>> = (0..count)
                .map(|_| (0..n).map(|_| rng.next_f64() - 0.5).collect())
                .collect();
            orthonormalise(&mut b);
            b
        };
        let (left, right) = (random(rows, values.len()), random(cols, values.len()));
        let mut a = vec![0.0; rows * cols];
        for (k, s) in values.iter().enumerate() {
            for r in 0..rows {
                for c in 0..cols {
                    a[r * cols + c] += s * left[k][r] * right[k][c];
                }
            }
        }
        let svd = Svd {
            values: values.to_vec(),
            left,
            right,
        };
        (a, svd)
    }

    #[test]
    fn a_known_spectrum_is_recovered_with_its_vectors() {
        let values = [9.0, 4.0, 2.5, 1.0, 0.3, 0.05];
        let (a, want) = with_spectrum(70, 50, &values, 3);
        let got = leading(&a, 70, 50, 4, 1);
        assert_eq!(got.values.len(), 4);
        for k in 0..4 {
            assert!(
                (got.values[k] - want.values[k]).abs() < 1e-9,
                "s{k}: {} vs {}",
                got.values[k],
                want.values[k]
            );
            // Vectors up to sign.
            let l = dot(&got.left[k], &want.left[k]).abs();
            let r = dot(&got.right[k], &want.right[k]).abs();
            assert!(
                (l - 1.0).abs() < 1e-9 && (r - 1.0).abs() < 1e-9,
                "{k}: {l} {r}"
            );
        }
    }

    #[test]
    fn truncation_error_is_the_tail_of_the_spectrum() {
        // Eckart–Young: the best rank-k approximation leaves exactly the tail's energy.
        let values: Vec<f64> = (0..20).map(|i| 0.6f64.powi(i)).collect();
        let (a, _) = with_spectrum(40, 30, &values, 5);
        let got = leading(&a, 40, 30, 6, 2);
        let mut residual = a.clone();
        for k in 0..6 {
            for r in 0..40 {
                for c in 0..30 {
                    residual[r * 30 + c] -= got.values[k] * got.left[k][r] * got.right[k][c];
                }
            }
            // Orthonormal vectors.
            for j in 0..k {
                assert!(dot(&got.right[k], &got.right[j]).abs() < 1e-9);
                assert!(dot(&got.left[k], &got.left[j]).abs() < 1e-9);
            }
        }
        let left: f64 = dot(&residual, &residual);
        let tail: f64 = values[6..].iter().map(|s| s * s).sum();
        assert!(
            (left - tail).abs() < 1e-9 * tail.max(1.0),
            "{left} vs {tail}"
        );
    }
}
