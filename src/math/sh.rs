//! Real spherical harmonics: evaluation, projection of sampled functions, reconstruction, rotation
//! of coefficient vectors, convolution with zonal kernels (clamped cosine, Henyey–Greenstein) and
//! ringing-reduction windows. Everything is f64; vectors and rotations are glam `DVec3` / `DMat3`.
//!
//! Convention: real SH, index `l(l+1)+m`, orthonormal, Condon–Shortley phase, +z polar axis, order n
//! = bands 0..n-1; see the conventions module (`crate::conventions`).
//!
//! The hand-written polynomials for l <= 3 are the fast path; [`eval_recurrence`] is their slow twin,
//! and the tests hold the two against each other and against scipy reference values.

use std::f64::consts::{PI, SQRT_2};
use std::sync::LazyLock;

use glam::{DMat3, DVec3, Vec3};

use crate::error::{PrtError, Result};

/// Largest order accepted from user input (scene files, command line). It bounds the memory of a
/// [`Rotation`] (about 4/3 n^3 matrix entries) and is the range the tests check the recurrence over.
pub const MAX_ORDER: usize = 32;

/// Largest order of SH lighting through the light ([`crate::relight::sh_light`]): 20,164 terms, past the
/// 20,000 of Ng et al. 2003's comparison at a 6x64x64 cube. The recurrence's factors are tabled
/// up to it.
pub const MAX_LIGHT_ORDER: usize = 142;

/// Bands written by the hand-written closed forms in [`eval`]; higher bands come from the recurrence.
const CLOSED_FORM_BANDS: usize = 4;

/// How far |dir| may be from 1: loose enough for directions normalised in f32 (error ~1e-7), tight
/// enough to catch a direction that was never normalised.
const UNIT_TOLERANCE: f64 = 1e-5;

/// How far R^T R may be from the identity (largest entry) and det R from 1 for a matrix to count as
/// a rotation: admits matrices built in f32, rejects scales, shears and reflections.
const ROTATION_TOLERANCE: f64 = 1e-6;

/// Number of coefficients of an order-`order` expansion: `order^2`.
pub const fn coeff_count(order: usize) -> usize {
    order * order
}

/// Position of Y_l^m in a coefficient vector: `l(l+1) + m`.
pub const fn index(l: usize, m: i32) -> usize {
    debug_assert!(m.unsigned_abs() as usize <= l);
    (l * (l + 1)).wrapping_add_signed(m as isize)
}

/// Checks an order taken from user input: 1 ..= [`MAX_ORDER`]. Returns it unchanged.
pub fn check_order(order: usize) -> Result<usize> {
    if (1..=MAX_ORDER).contains(&order) {
        Ok(order)
    } else {
        Err(PrtError::invalid(
            "SH order",
            format!("{order} is outside 1..={MAX_ORDER}"),
        ))
    }
}

/// Order of a coefficient vector of length `len` (e.g. read from a file): `len` must be a non-zero
/// perfect square n^2 with n <= [`MAX_ORDER`].
pub fn order_from_len(len: usize) -> Result<usize> {
    let order = len.isqrt();
    if order * order != len {
        return Err(PrtError::invalid(
            "SH coefficient count",
            format!("{len} is not a perfect square n^2"),
        ));
    }
    check_order(order).map_err(|_| {
        PrtError::invalid(
            "SH coefficient count",
            format!("{len} = {order}^2 is outside order 1..={MAX_ORDER}"),
        )
    })
}

/// Whole bands in a vector of `len` coefficients. Callers pass n^2 coefficients; a partial last
/// band is ignored rather than read past.
fn bands_in(len: usize) -> usize {
    let bands = len.isqrt();
    debug_assert_eq!(
        bands * bands,
        len,
        "SH coefficient count must be a perfect square"
    );
    bands
}

fn debug_check_unit(dir: DVec3) {
    debug_assert!(
        (dir.length() - 1.0).abs() <= UNIT_TOLERANCE,
        "SH direction must be a unit vector, got {dir} (length {})",
        dir.length()
    );
}

// Normalisation constants of the closed forms, from Y_l^m = sqrt(2) N_l^m P_l^m(cos theta) trig(m phi)
// with N_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!), multiplied out with the powers of sin theta
// absorbed into x and y (printed with Python's repr of math.sqrt(...)).
/// sqrt(1/(4 pi))
const K_00: f64 = 0.282_094_791_773_878_14;
/// sqrt(3/(4 pi))
const K_1: f64 = 0.488_602_511_902_919_9;
/// sqrt(15/(4 pi))
const K_2_XY: f64 = 1.092_548_430_592_079_2;
/// sqrt(5/(16 pi))
const K_20: f64 = 0.315_391_565_252_520_05;
/// sqrt(15/(16 pi))
const K_22: f64 = 0.546_274_215_296_039_6;
/// sqrt(35/(32 pi))
const K_33: f64 = 0.590_043_589_926_643_5;
/// sqrt(105/(4 pi))
const K_3_XYZ: f64 = 2.890_611_442_640_554;
/// sqrt(21/(32 pi))
const K_31: f64 = 0.457_045_799_464_465_8;
/// sqrt(7/(16 pi))
const K_30: f64 = 0.373_176_332_590_115_4;
/// sqrt(105/(16 pi))
const K_32: f64 = 1.445_305_721_320_277;

/// Bands 0..min(order, 4) from their polynomials in x, y, z. The polynomials are written
/// homogeneously (no `1 = x^2 + y^2 + z^2` substitutions) as in Sloan's tables, so they can be read
/// against them.
#[inline(always)]
fn closed_forms(order: usize, d: DVec3, mut put: impl FnMut(usize, f64)) {
    let (x, y, z) = (d.x, d.y, d.z);
    if order == 0 {
        return;
    }
    put(0, K_00);
    if order == 1 {
        return;
    }
    put(1, -K_1 * y);
    put(2, K_1 * z);
    put(3, -K_1 * x);
    if order == 2 {
        return;
    }
    let (x2, y2, z2) = (x * x, y * y, z * z);
    put(4, K_2_XY * x * y);
    put(5, -K_2_XY * y * z);
    put(6, K_20 * (2.0 * z2 - x2 - y2));
    put(7, -K_2_XY * x * z);
    put(8, K_22 * (x2 - y2));
    if order == 3 {
        return;
    }
    put(9, -K_33 * y * (3.0 * x2 - y2));
    put(10, K_3_XYZ * x * y * z);
    put(11, -K_31 * y * (4.0 * z2 - x2 - y2));
    put(12, K_30 * z * (2.0 * z2 - 3.0 * x2 - 3.0 * y2));
    put(13, -K_31 * x * (4.0 * z2 - x2 - y2));
    put(14, K_32 * z * (x2 - y2));
    put(15, -K_33 * x * (x2 - 3.0 * y2));
}

/// Factors of the normalised associated-Legendre recurrence for one (l, m), m >= 0.
///
/// With A_l^m = N_l^m P_l^m(z) / sin^m(theta) (a polynomial in z, Condon–Shortley sign included):
/// - diagonal: A_m^m = -sqrt((2m+1)/(2m)) A_{m-1}^{m-1}, from P_m^m = (-1)^m (2m-1)!! sin^m theta;
/// - off the diagonal: A_l^m = a (z A_{l-1}^m - b A_{l-2}^m), a = sqrt((4l^2-1)/(l^2-m^2)),
///   b = sqrt(((l-1)^2-m^2)/(4(l-1)^2-1)), from (l-m) P_l^m = (2l-1) z P_{l-1}^m - (l+m-1) P_{l-2}^m.
///   For l = m+1, b = 0 and a = sqrt(2m+3), so one formula covers it.
///
/// Forward in l this recurrence is stable, and dividing out sin^m theta keeps the poles exact.
#[derive(Clone, Copy)]
struct LegendreStep {
    a: f64,
    b: f64,
}

impl LegendreStep {
    fn new(l: usize, m: usize) -> Self {
        let (lf, mf) = (l as f64, m as f64);
        if l == m {
            let a = if m == 0 {
                (0.25 / PI).sqrt()
            } else {
                -((2.0 * mf + 1.0) / (2.0 * mf)).sqrt()
            };
            return LegendreStep { a, b: 0.0 };
        }
        let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
        let l1 = lf - 1.0;
        let b = ((l1 * l1 - mf * mf) / (4.0 * l1 * l1 - 1.0)).sqrt();
        LegendreStep { a, b }
    }
}

/// Recurrence factors for every (l, m >= 0) below [`MAX_LIGHT_ORDER`], at slot `index(l, m)`; the
/// square roots otherwise dominate the cost of the recurrence. Orders above fall back to computing
/// them.
static LEGENDRE_STEPS: LazyLock<Vec<LegendreStep>> = LazyLock::new(|| {
    let mut steps = vec![LegendreStep { a: 0.0, b: 0.0 }; coeff_count(MAX_LIGHT_ORDER)];
    for l in 0..MAX_LIGHT_ORDER {
        for m in 0..=l {
            steps[index(l, m as i32)] = LegendreStep::new(l, m);
        }
    }
    steps
});

/// Bands `first_band..order` by the associated-Legendre recurrence in z = cos theta. The azimuthal
/// factors sin^m(theta) (cos m phi, sin m phi) are Re and Im of (x + i y)^m, built by repeated
/// complex multiplication, so no angle is ever formed.
#[inline(always)]
fn recurrence(order: usize, d: DVec3, first_band: usize, mut put: impl FnMut(usize, f64)) {
    let steps: &[LegendreStep] = if order <= MAX_LIGHT_ORDER {
        &LEGENDRE_STEPS
    } else {
        &[]
    };
    let step = |l: usize, m: usize| match steps.get(index(l, m as i32)) {
        Some(s) => *s,
        None => LegendreStep::new(l, m),
    };
    let (x, y, z) = (d.x, d.y, d.z);
    let (mut re, mut im) = (1.0, 0.0);
    let mut diagonal = 0.0;
    for m in 0..order {
        if m == 0 {
            diagonal = step(0, 0).a;
        } else {
            (re, im) = (re * x - im * y, re * y + im * x);
            diagonal *= step(m, m).a;
        }
        let (mut older, mut old) = (0.0, 0.0);
        for l in m..order {
            let value = if l == m {
                diagonal
            } else {
                let s = step(l, m);
                s.a * (z * old - s.b * older)
            };
            (older, old) = (old, value);
            if l < first_band {
                continue;
            }
            if m == 0 {
                put(index(l, 0), value);
            } else {
                let m = m as i32;
                put(index(l, m), SQRT_2 * value * re);
                put(index(l, -m), SQRT_2 * value * im);
            }
        }
    }
}

/// Fast evaluation feeding each (index, value) to `put`: closed forms, then the recurrence.
#[inline(always)]
fn for_each_basis(order: usize, dir: DVec3, mut put: impl FnMut(usize, f64)) {
    debug_check_unit(dir);
    closed_forms(order, dir, &mut put);
    if order > CLOSED_FORM_BANDS {
        recurrence(order, dir, CLOSED_FORM_BANDS, put);
    }
}

/// Writes Y_0 .. Y_{n^2-1} at the unit direction `dir` into `out[..n^2]`, n = `order`.
/// Bands l <= 3 come from hand-written polynomials, higher bands from the recurrence.
///
/// Panics if `out` is shorter than n^2.
pub fn eval(order: usize, dir: DVec3, out: &mut [f64]) {
    debug_assert!(out.len() >= coeff_count(order));
    let out = &mut out[..coeff_count(order)];
    for_each_basis(order, dir, |i, v| out[i] = v);
}

/// Same as [`eval`], every band from the associated-Legendre recurrence: the slow twin that checks
/// the closed forms.
///
/// Panics if `out` is shorter than n^2.
pub fn eval_recurrence(order: usize, dir: DVec3, out: &mut [f64]) {
    debug_check_unit(dir);
    debug_assert!(out.len() >= coeff_count(order));
    let out = &mut out[..coeff_count(order)];
    recurrence(order, dir, 0, |i, v| out[i] = v);
}

/// [`eval`] into a new vector of n^2 values.
pub fn eval_vec(order: usize, dir: DVec3) -> Vec<f64> {
    let mut out = vec![0.0; coeff_count(order)];
    eval(order, dir, &mut out);
    out
}

/// [`eval`] for f32 callers (GPU buffers, viewer): computed in f64, stored as f32.
///
/// Panics if `out` is shorter than n^2.
pub fn eval_f32_into(order: usize, dir: Vec3, out: &mut [f32]) {
    debug_assert!(out.len() >= coeff_count(order));
    let out = &mut out[..coeff_count(order)];
    for_each_basis(order, dir.as_dvec3(), |i, v| out[i] = v as f32);
}

/// Adds two RGB coefficient vectors of one length, element by element: the reduction of the
/// parallel projections (per-thread accumulators summed into one).
pub fn add_rgb(mut a: Vec<[f64; 3]>, b: Vec<[f64; 3]>) -> Vec<[f64; 3]> {
    for (x, y) in a.iter_mut().zip(&b) {
        for c in 0..3 {
            x[c] += y[c];
        }
    }
    a
}

/// Projects sampled values onto the basis: c_i = sum_k value_k weight_k Y_i(dir_k), where the
/// weights are the samples' solid angles or quadrature weights. Samples are `(dir, value, weight)`.
pub fn project(order: usize, samples: impl IntoIterator<Item = (DVec3, f64, f64)>) -> Vec<f64> {
    let mut coeffs = vec![0.0; coeff_count(order)];
    for (dir, value, weight) in samples {
        let scaled = value * weight;
        for_each_basis(order, dir, |i, y| coeffs[i] += scaled * y);
    }
    coeffs
}

/// [`project`] for RGB values: samples are `(dir, [r, g, b], weight)`.
pub fn project_rgb(
    order: usize,
    samples: impl IntoIterator<Item = (DVec3, [f64; 3], f64)>,
) -> Vec<[f64; 3]> {
    let mut coeffs = vec![[0.0; 3]; coeff_count(order)];
    for (dir, value, weight) in samples {
        let scaled = value.map(|v| v * weight);
        for_each_basis(order, dir, |i, y| {
            for (c, s) in coeffs[i].iter_mut().zip(scaled) {
                *c += s * y;
            }
        });
    }
    coeffs
}

/// Value of the expansion `coeffs` (n^2 of them, order inferred) at the unit direction `dir`.
pub fn reconstruct(coeffs: &[f64], dir: DVec3) -> f64 {
    let mut sum = 0.0;
    for_each_basis(bands_in(coeffs.len()), dir, |i, y| sum += coeffs[i] * y);
    sum
}

/// [`reconstruct`] for RGB coefficients.
pub fn reconstruct_rgb(coeffs: &[[f64; 3]], dir: DVec3) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for_each_basis(bands_in(coeffs.len()), dir, |i, y| {
        for (s, c) in sum.iter_mut().zip(coeffs[i]) {
            *s += c * y;
        }
    });
    sum
}

/// Per-band rotation matrices for SH coefficient vectors, built for every band by the
/// Ivanic–Ruedenberg recurrence (J. Phys. Chem. 100, 6342, 1996; erratum 102, 9099, 1998) from the
/// 3x3 band-1 matrix.
#[derive(Clone, Debug)]
pub struct Rotation {
    order: usize,
    /// Band l is a (2l+1) x (2l+1) matrix, row-major, rows and columns ordered m = -l..=l.
    bands: Vec<Vec<f64>>,
}

impl Rotation {
    /// Rotation matrices for bands 0..order of the rotation `rotation` (a proper rotation: R^T R = I,
    /// det R = 1, within a tolerance that admits matrices built in f32).
    pub fn new(order: usize, rotation: DMat3) -> Result<Self> {
        check_order(order)?;
        check_rotation(rotation)?;
        let mut bands = Vec::with_capacity(order);
        bands.push(vec![1.0]);
        if order > 1 {
            bands.push(band1(rotation));
        }
        for l in 2..order {
            let next = next_band(l, &bands[1], &bands[l - 1]);
            bands.push(next);
        }
        Ok(Rotation { order, bands })
    }

    /// Number of bands the matrices cover.
    pub fn order(&self) -> usize {
        self.order
    }

    /// The (2l+1) x (2l+1) matrix of band `l`, row-major, rows and columns ordered m = -l..=l.
    pub fn band(&self, l: usize) -> &[f64] {
        &self.bands[l]
    }

    /// Coefficients of the rotated function g(w) = f(R^T w), i.e. f turned by R (a lobe about
    /// direction d moves to R d). `coeffs` and `out` hold n^2 values with n <= [`Self::order`].
    pub fn apply(&self, coeffs: &[f64], out: &mut [f64]) {
        debug_assert_eq!(coeffs.len(), out.len());
        let bands = bands_in(coeffs.len().min(out.len()));
        debug_assert!(
            bands <= self.order,
            "{bands} bands, rotation has {}",
            self.order
        );
        for (l, matrix) in self.bands.iter().enumerate().take(bands) {
            let band = l * l..(l + 1) * (l + 1);
            let src = &coeffs[band.clone()];
            for (row, dst) in matrix.chunks_exact(2 * l + 1).zip(&mut out[band]) {
                *dst = row.iter().zip(src).map(|(r, c)| r * c).sum();
            }
        }
    }

    /// [`Self::apply`] for RGB coefficients.
    pub fn apply_rgb(&self, coeffs: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let bands = bands_in(coeffs.len());
        debug_assert!(
            bands <= self.order,
            "{bands} bands, rotation has {}",
            self.order
        );
        let mut out = vec![[0.0; 3]; coeffs.len()];
        for (l, matrix) in self.bands.iter().enumerate().take(bands) {
            let band = l * l..(l + 1) * (l + 1);
            let src = &coeffs[band.clone()];
            for (row, dst) in matrix.chunks_exact(2 * l + 1).zip(&mut out[band]) {
                for (r, c) in row.iter().zip(src) {
                    for (d, c) in dst.iter_mut().zip(c) {
                        *d += r * c;
                    }
                }
            }
        }
        out
    }
}

fn check_rotation(rotation: DMat3) -> Result<()> {
    let gram = rotation.transpose() * rotation - DMat3::IDENTITY;
    let off = gram
        .to_cols_array()
        .iter()
        .fold(0.0_f64, |a, e| a.max(e.abs()));
    let det = rotation.determinant();
    // Written as negations so that NaN entries are rejected too.
    if !(off <= ROTATION_TOLERANCE && (det - 1.0).abs() <= ROTATION_TOLERANCE) {
        return Err(PrtError::invalid(
            "SH rotation",
            format!("not a proper rotation (max |R^T R - I| = {off:e}, det = {det}): {rotation}"),
        ));
    }
    Ok(())
}

/// Band-1 matrix. The band-1 functions are k(-y, z, -x), so f = k a.w with a = (-c_1, -c_-1, c_0),
/// and g(w) = f(R^T w) = k (R a).w. Reading the coefficients back out of R a gives
/// M_{m,m'} = s_m s_m' R[p(m)][p(m')] with p = (y, z, x) and the Condon–Shortley signs s = (-1, 1, -1).
fn band1(rotation: DMat3) -> Vec<f64> {
    const AXIS: [usize; 3] = [1, 2, 0];
    const SIGN: [f64; 3] = [-1.0, 1.0, -1.0];
    let mut out = vec![0.0; 9];
    for (row, (&i, &si)) in AXIS.iter().zip(&SIGN).enumerate() {
        for (col, (&j, &sj)) in AXIS.iter().zip(&SIGN).enumerate() {
            // glam is column-major: entry (row i, column j) is col(j)[i].
            out[row * 3 + col] = si * sj * rotation.col(j)[i];
        }
    }
    out
}

/// Band l from band 1 and band l-1 by the Ivanic–Ruedenberg recurrence (their Table 2, with the
/// erratum's sign for the m < 0 terms). The recurrence is written for the basis without the
/// Condon–Shortley phase; that phase is the per-band diagonal sign (-1)^m, and every product term of
/// the recurrence couples indices whose parities add up, so the same formulas hold with the phase.
fn next_band(l: usize, r1: &[f64], prev: &[f64]) -> Vec<f64> {
    let li = l as i32;
    let lf = l as f64;
    let width_prev = 2 * li - 1;
    let r = |i: i32, j: i32| r1[((i + 1) * 3 + (j + 1)) as usize];
    let at = |a: i32, b: i32| prev[((a + li - 1) * width_prev + (b + li - 1)) as usize];
    // The helper P of the paper: band-1 row i combined with band-(l-1) row a, column b.
    let p = |i: i32, a: i32, b: i32| {
        if b == li {
            r(i, 1) * at(a, li - 1) - r(i, -1) * at(a, 1 - li)
        } else if b == -li {
            r(i, 1) * at(a, 1 - li) + r(i, -1) * at(a, li - 1)
        } else {
            r(i, 0) * at(a, b)
        }
    };
    let width = 2 * l + 1;
    let mut out = vec![0.0; width * width];
    for m in -li..=li {
        let mf = m as f64;
        let am = mf.abs();
        for n in -li..=li {
            let nf = n as f64;
            let denom = if n.abs() < li {
                (lf + nf) * (lf - nf)
            } else {
                2.0 * lf * (2.0 * lf - 1.0)
            };
            let mut value = 0.0;
            if m.abs() < li {
                let u = ((lf + mf) * (lf - mf) / denom).sqrt();
                value += u * p(0, m, n);
            }
            let delta0 = if m == 0 { 1.0 } else { 0.0 };
            let v = 0.5
                * ((1.0 + delta0) * (lf + am - 1.0) * (lf + am) / denom).sqrt()
                * (1.0 - 2.0 * delta0);
            let big_v = match m {
                0 => p(1, 1, n) + p(-1, -1, n),
                1 => SQRT_2 * p(1, 0, n),
                -1 => SQRT_2 * p(-1, 0, n),
                m if m > 0 => p(1, m - 1, n) - p(-1, -m + 1, n),
                m => p(1, m + 1, n) + p(-1, -m - 1, n),
            };
            value += v * big_v;
            if m != 0 && m.abs() < li - 1 {
                let w = -0.5 * ((lf - am - 1.0) * (lf - am) / denom).sqrt();
                let big_w = if m > 0 {
                    p(1, m + 1, n) + p(-1, -m - 1, n)
                } else {
                    p(1, m - 1, n) - p(-1, -m + 1, n)
                };
                value += w * big_w;
            }
            out[(m + li) as usize * width + (n + li) as usize] = value;
        }
    }
    out
}

/// Per-band zonal coefficients z_l = integral k(w) Y_l^0(w) dw, l = 0..order-1, of the clamped
/// cosine k(w) = max(w.z, 0). Exact for every l: z_l = sqrt(pi (2l+1)) I_l with
/// I_l = integral_0^1 t P_l(t) dt, which is 1/2, 1/3, 0 for odd l > 1, and for even l = 2k:
/// I_2k = (-1)^(k-1) (2k-2)! / (4^k (k-1)! (k+1)!), so I_2 = 1/8 and
/// I_(2k+2) / I_2k = -(2k-1) / (2(k+2)) (a ratio, so no factorial overflows at high l).
pub fn clamped_cosine_zonal(order: usize) -> Vec<f64> {
    let mut even = 0.125;
    (0..order)
        .map(|l| {
            let moment = match l {
                0 => 0.5,
                1 => 1.0 / 3.0,
                l if l % 2 == 1 => 0.0,
                l => {
                    let k = (l / 2) as f64;
                    let current = even;
                    even *= -(2.0 * k - 1.0) / (2.0 * (k + 2.0));
                    current
                }
            };
            (PI * (2 * l + 1) as f64).sqrt() * moment
        })
        .collect()
}

/// Per-band zonal coefficients of the Henyey–Greenstein phase function
/// p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^1.5) about +z. Its Legendre series is
/// sum_l (2l+1)/(4 pi) g^l P_l(cos), hence z_l = sqrt((2l+1)/(4 pi)) g^l. `g` lies in [-1, 1]
/// (the scene loader checks it).
pub fn henyey_greenstein_zonal(order: usize, g: f64) -> Vec<f64> {
    debug_assert!(
        (-1.0..=1.0).contains(&g),
        "HG asymmetry g = {g} outside [-1, 1]"
    );
    let mut power = 1.0;
    (0..order)
        .map(|l| {
            let z = ((2 * l + 1) as f64 / (4.0 * PI)).sqrt() * power;
            power *= g;
            z
        })
        .collect()
}

/// A value scaled by a per-band factor: plain and RGB coefficients.
trait Scale {
    fn scale(&mut self, factor: f64);
}

impl Scale for f64 {
    fn scale(&mut self, factor: f64) {
        *self *= factor;
    }
}

impl Scale for [f64; 3] {
    fn scale(&mut self, factor: f64) {
        for c in self {
            *c *= factor;
        }
    }
}

fn scale_bands<T: Scale>(coeffs: &mut [T], factor: impl Fn(usize) -> f64) {
    for l in 0..bands_in(coeffs.len()) {
        let f = factor(l);
        for c in &mut coeffs[l * l..(l + 1) * (l + 1)] {
            c.scale(f);
        }
    }
}

/// Funk–Hecke factor of band l: c'_lm = sqrt(4 pi / (2l+1)) z_l c_lm. Bands the kernel does not
/// reach are zeroed, as a kernel truncated there has no energy in them.
fn funk_hecke(zonal: &[f64], l: usize) -> f64 {
    zonal
        .get(l)
        .map_or(0.0, |z| (4.0 * PI / (2 * l + 1) as f64).sqrt() * z)
}

/// Convolves `coeffs` in place with the zonal kernel `zonal` (per-band coefficients as returned by
/// [`clamped_cosine_zonal`]): c'_lm = sqrt(4 pi / (2l+1)) z_l c_lm (Funk–Hecke). For example the
/// irradiance E(n) = integral L(w) max(n.w, 0) dw has the coefficients of L convolved with the
/// clamped cosine. `zonal` must cover every band of `coeffs`.
pub fn convolve(coeffs: &mut [f64], zonal: &[f64]) {
    debug_assert!(zonal.len() >= bands_in(coeffs.len()));
    scale_bands(coeffs, |l| funk_hecke(zonal, l));
}

/// [`convolve`] for RGB coefficients.
pub fn convolve_rgb(coeffs: &mut [[f64; 3]], zonal: &[f64]) {
    debug_assert!(zonal.len() >= bands_in(coeffs.len()));
    scale_bands(coeffs, |l| funk_hecke(zonal, l));
}

/// Ringing-reduction window: per-band factors w_l applied to band l, with n the order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Window {
    /// No windowing, w_l = 1.
    #[default]
    None,
    /// Lanczos sigma factors w_l = sinc(pi l / n), sinc(x) = sin x / x.
    Lanczos,
    /// Hann window w_l = (1 + cos(pi l / n)) / 2.
    Hanning,
}

/// The factors w_0..w_{n-1} of `window` for order n: w_0 = 1, non-increasing, all in (0, 1].
pub fn window_factors(order: usize, window: Window) -> Vec<f64> {
    (0..order)
        .map(|l| window_factor(order, window, l))
        .collect()
}

fn window_factor(order: usize, window: Window, l: usize) -> f64 {
    let t = PI * l as f64 / order as f64;
    match window {
        Window::None => 1.0,
        Window::Lanczos if l == 0 => 1.0,
        Window::Lanczos => t.sin() / t,
        Window::Hanning => 0.5 * (1.0 + t.cos()),
    }
}

/// Multiplies each band of `coeffs` (order inferred from the length) by its window factor.
pub fn apply_window(coeffs: &mut [f64], window: Window) {
    let order = bands_in(coeffs.len());
    scale_bands(coeffs, |l| window_factor(order, window, l));
}

/// [`apply_window`] for RGB coefficients.
pub fn apply_window_rgb(coeffs: &mut [[f64; 3]], window: Window) {
    let order = bands_in(coeffs.len());
    scale_bands(coeffs, |l| window_factor(order, window, l));
}

#[cfg(test)]
mod tests;
