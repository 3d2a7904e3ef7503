//! Orthonormal non-standard 2-D Haar transform of each cube face on its own (see
//! [`crate::conventions`]), its inverse, and what each coefficient is: face, level, band, position
//! and the solid angle of its support.
//!
//! # Layout inside a face
//! The N x N coefficients of a face sit in the usual pyramid layout: (0, 0) is the face's scaling
//! coefficient; for every band size s = 1, 2, 4, ..., N/2 the block `rows 0..s, cols s..2s` holds the
//! horizontal details (left minus right), `rows s..2s, cols 0..s` the vertical details (top minus
//! bottom) and `rows s..2s, cols s..2s` the diagonal ones. Coefficient (face, r, c) has the linear
//! index `face·N² + r·N + c`, like a texel. One step maps a 2 x 2 block (a b / c d) to
//! `(a+b+c+d)/2, (a−b+c−d)/2, (a+b−c−d)/2, (a−b−c+d)/2`: orthonormal, so Parseval holds exactly.

use crate::error::Result;
use crate::math::cubemap::{texel_count, validate_n};

/// A value the transform can act on: a scalar or an RGB triple.
pub trait HaarValue: Copy + Default + Send + Sync {
    /// Sum of two values.
    fn add(self, o: Self) -> Self;
    /// Difference of two values.
    fn sub(self, o: Self) -> Self;
    /// Scaled value.
    fn scale(self, f: f32) -> Self;
}

impl HaarValue for f32 {
    #[inline]
    fn add(self, o: Self) -> Self {
        self + o
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        self - o
    }
    #[inline]
    fn scale(self, f: f32) -> Self {
        self * f
    }
}

/// RGB triples of `f32` or `f64`, channel by channel (the scale is applied at the triple's
/// precision).
macro_rules! haar_rgb {
    ($t:ty) => {
        impl HaarValue for [$t; 3] {
            #[inline]
            fn add(self, o: Self) -> Self {
                [self[0] + o[0], self[1] + o[1], self[2] + o[2]]
            }
            #[inline]
            fn sub(self, o: Self) -> Self {
                [self[0] - o[0], self[1] - o[1], self[2] - o[2]]
            }
            #[inline]
            fn scale(self, f: f32) -> Self {
                let f = <$t>::from(f);
                [self[0] * f, self[1] * f, self[2] * f]
            }
        }
    };
}
haar_rgb!(f32);
haar_rgb!(f64);

/// Forward transform of one N x N face in place; `scratch` is reused between calls.
pub fn forward_face<T: HaarValue>(face: &mut [T], n: usize, scratch: &mut Vec<T>) {
    debug_assert_eq!(face.len(), n * n);
    scratch.resize(n * n, T::default());
    let mut size = n;
    while size > 1 {
        let half = size / 2;
        for i in 0..half {
            for j in 0..half {
                let a = face[2 * i * n + 2 * j];
                let b = face[2 * i * n + 2 * j + 1];
                let c = face[(2 * i + 1) * n + 2 * j];
                let d = face[(2 * i + 1) * n + 2 * j + 1];
                let (ab, cd) = (a.add(b), c.add(d));
                let (amb, cmd) = (a.sub(b), c.sub(d));
                scratch[i * n + j] = ab.add(cd).scale(0.5);
                scratch[i * n + half + j] = amb.add(cmd).scale(0.5);
                scratch[(half + i) * n + j] = ab.sub(cd).scale(0.5);
                scratch[(half + i) * n + half + j] = amb.sub(cmd).scale(0.5);
            }
        }
        for r in 0..size {
            face[r * n..r * n + size].copy_from_slice(&scratch[r * n..r * n + size]);
        }
        size = half;
    }
}

/// Inverse of [`forward_face`], in place.
pub fn inverse_face<T: HaarValue>(face: &mut [T], n: usize, scratch: &mut Vec<T>) {
    debug_assert_eq!(face.len(), n * n);
    scratch.resize(n * n, T::default());
    let mut size = 2;
    while size <= n {
        let half = size / 2;
        for i in 0..half {
            for j in 0..half {
                let s = face[i * n + j];
                let h = face[i * n + half + j];
                let v = face[(half + i) * n + j];
                let dg = face[(half + i) * n + half + j];
                let (sph, smh) = (s.add(h), s.sub(h));
                let (vpd, vmd) = (v.add(dg), v.sub(dg));
                scratch[2 * i * n + 2 * j] = sph.add(vpd).scale(0.5);
                scratch[2 * i * n + 2 * j + 1] = smh.add(vmd).scale(0.5);
                scratch[(2 * i + 1) * n + 2 * j] = sph.sub(vpd).scale(0.5);
                scratch[(2 * i + 1) * n + 2 * j + 1] = smh.sub(vmd).scale(0.5);
            }
        }
        for r in 0..size {
            face[r * n..r * n + size].copy_from_slice(&scratch[r * n..r * n + size]);
        }
        size *= 2;
    }
}

/// Forward transform of the six faces of an already validated cube (hot-path form of
/// [`forward_cube`]: no checks, caller-owned scratch).
pub fn forward_face_all<T: HaarValue>(cube: &mut [T], n: usize, scratch: &mut Vec<T>) {
    debug_assert_eq!(cube.len(), texel_count(n));
    for face in cube.chunks_exact_mut(n * n) {
        forward_face(face, n, scratch);
    }
}

/// Forward transform of all six faces of a cube (6 N² values in texel order) in place.
pub fn forward_cube<T: HaarValue>(cube: &mut [T], n: usize) -> Result<()> {
    each_face(cube, n, forward_face)
}

/// Inverse of [`forward_cube`], in place.
pub fn inverse_cube<T: HaarValue>(cube: &mut [T], n: usize) -> Result<()> {
    each_face(cube, n, inverse_face)
}

/// `transform` of each face of a cube of face size `n`, once its size and length are checked.
fn each_face<T: HaarValue>(
    cube: &mut [T],
    n: usize,
    transform: fn(&mut [T], usize, &mut Vec<T>),
) -> Result<()> {
    validate_n(n)?;
    check_len(cube.len(), n)?;
    let mut scratch = Vec::new();
    for face in cube.chunks_exact_mut(n * n) {
        transform(face, n, &mut scratch);
    }
    Ok(())
}

fn check_len(len: usize, n: usize) -> Result<()> {
    if len != texel_count(n) {
        return Err(crate::error::PrtError::invalid(
            "cube data",
            format!(
                "{len} values for N = {n}; expected 6·N² = {}",
                texel_count(n)
            ),
        ));
    }
    Ok(())
}

/// Which sub-band a coefficient belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Band {
    /// The face average (scaled): one per face.
    Scaling,
    /// Left minus right.
    Horizontal,
    /// Top minus bottom.
    Vertical,
    /// Diagonal difference.
    Diagonal,
}

/// What a coefficient is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoeffInfo {
    /// Cube face 0..5.
    pub face: usize,
    /// 0 for the scaling coefficient and the coarsest details (band size 1); band size s has level
    /// log2(s).
    pub level: u32,
    /// Sub-band.
    pub band: Band,
    /// Position inside its band: the support is the block of (N/s)² texels at rows
    /// `row·N/s ..`, cols `col·N/s ..`.
    pub row: usize,
    /// See `row`.
    pub col: usize,
    /// Texels on a side of the support.
    pub support: usize,
}

/// Describes coefficient `index` of a cube with N x N faces.
pub fn coeff_info(n: usize, index: usize) -> CoeffInfo {
    let face = index / (n * n);
    let r = (index / n) % n;
    let c = index % n;
    if r == 0 && c == 0 {
        return CoeffInfo {
            face,
            level: 0,
            band: Band::Scaling,
            row: 0,
            col: 0,
            support: n,
        };
    }
    // Band size: the largest power of two not above max(r, c).
    let m = r.max(c);
    let s = 1usize << (usize::BITS - 1 - m.leading_zeros());
    let (band, row, col) = match (r >= s, c >= s) {
        (false, true) => (Band::Horizontal, r, c - s),
        (true, false) => (Band::Vertical, r - s, c),
        _ => (Band::Diagonal, r - s, c - s),
    };
    CoeffInfo {
        face,
        level: s.trailing_zeros(),
        band,
        row,
        col,
        support: n / s,
    }
}

/// Solid angle of the support of every coefficient (the area weight of Ng et al. 2003), in
/// coefficient order. Exact: the corner formula over the support block.
pub fn support_solid_angles(n: usize) -> Vec<f64> {
    (0..texel_count(n))
        .map(|i| {
            let info = coeff_info(n, i);
            let b = info.support;
            block_solid_angle(n, info.row * b, info.col * b, b)
        })
        .collect()
}

/// Solid angle of the b x b texel block whose top-left texel is (row, col).
fn block_solid_angle(n: usize, row: usize, col: usize, b: usize) -> f64 {
    let inv = 2.0 / n as f64;
    let (s0, s1) = (col as f64 * inv - 1.0, (col + b) as f64 * inv - 1.0);
    let (t0, t1) = (row as f64 * inv - 1.0, (row + b) as f64 * inv - 1.0);
    crate::math::cubemap::patch_solid_angle(s0, t0, s1, t1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Support solid angles from the exact corner formula in f64 against the face's 4π/6: four
    /// atan2 per block, summed over at most 16 blocks, leave a few ulps of values near 2.
    const EXACT_SOLID_ANGLE: f64 = 1e-12;

    #[test]
    fn coefficient_info_covers_every_band_once() {
        let n = 8;
        let mut counts = std::collections::HashMap::new();
        for i in 0..n * n {
            let info = coeff_info(n, i);
            *counts.entry((info.level, info.band)).or_insert(0) += 1;
            assert_eq!(info.support * (n / info.support), n);
        }
        assert_eq!(counts[&(0, Band::Scaling)], 1);
        for (level, s) in [(0u32, 1usize), (1, 2), (2, 4)] {
            for band in [Band::Horizontal, Band::Vertical, Band::Diagonal] {
                assert_eq!(counts[&(level, band)], s * s, "level {level} {band:?}");
            }
        }
    }

    #[test]
    fn support_areas_of_one_band_tile_the_face() {
        let n = 16;
        let areas = support_solid_angles(n);
        let face = 4.0 * std::f64::consts::PI / 6.0;
        assert!((areas[0] - face).abs() < EXACT_SOLID_ANGLE);
        // The horizontal details of band size 4 tile the face exactly once.
        let sum: f64 = (0..n * n)
            .filter(|&i| {
                let c = coeff_info(n, i);
                c.level == 2 && c.band == Band::Horizontal
            })
            .map(|i| areas[i])
            .sum();
        assert!((sum - face).abs() < EXACT_SOLID_ANGLE, "{sum} vs {face}");
    }
}
