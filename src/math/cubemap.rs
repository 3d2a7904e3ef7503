//! Cube maps: texel <-> direction, exact texel solid angles, lookup, and the texel-average radiance
//! of a lat-long environment (area resampling). Face order, texel directions and indexing follow
//! [`crate::conventions`].

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::error::{PrtError, Result};

/// Largest supported face resolution: 6·256² texels are 393 216 lights per pixel row.
pub const MAX_CUBE_N: usize = 256;

/// Checks that `n` is a supported face resolution (a power of two, 1..=[`MAX_CUBE_N`]).
pub fn validate_n(n: usize) -> Result<()> {
    if n == 0 || !n.is_power_of_two() || n > MAX_CUBE_N {
        return Err(PrtError::invalid(
            "cube size",
            format!("N = {n}; it must be a power of two from 1 to {MAX_CUBE_N}"),
        ));
    }
    Ok(())
}

/// Number of texels of a cube with N x N faces.
pub fn texel_count(n: usize) -> usize {
    6 * n * n
}

/// Linear texel index `face·N² + row·N + col`.
#[inline]
pub fn texel_index(n: usize, face: usize, row: usize, col: usize) -> usize {
    face * n * n + row * n + col
}

/// Unnormalised direction of face coordinates (s, t) in [-1, 1]².
#[inline]
pub fn face_st_to_dir(face: usize, s: f64, t: f64) -> DVec3 {
    match face {
        0 => DVec3::new(1.0, -t, -s),
        1 => DVec3::new(-1.0, -t, s),
        2 => DVec3::new(s, 1.0, t),
        3 => DVec3::new(s, -1.0, -t),
        4 => DVec3::new(s, -t, 1.0),
        _ => DVec3::new(-s, -t, -1.0),
    }
}

/// Face and face coordinates (s, t) in [-1, 1]² of a (not necessarily unit) direction; the inverse
/// of [`face_st_to_dir`]. Ties between faces go to the first face in order.
#[inline]
pub fn dir_to_face_st(d: DVec3) -> (usize, f64, f64) {
    let a = d.abs();
    if a.x >= a.y && a.x >= a.z {
        if d.x >= 0.0 {
            (0, -d.z / a.x, -d.y / a.x)
        } else {
            (1, d.z / a.x, -d.y / a.x)
        }
    } else if a.y >= a.z {
        if d.y >= 0.0 {
            (2, d.x / a.y, d.z / a.y)
        } else {
            (3, d.x / a.y, -d.z / a.y)
        }
    } else if d.z >= 0.0 {
        (4, d.x / a.z, -d.y / a.z)
    } else {
        (5, -d.x / a.z, -d.y / a.z)
    }
}

/// Unit direction through the centre of texel (face, row, col).
pub fn texel_dir(n: usize, face: usize, row: usize, col: usize) -> DVec3 {
    let s = (2 * col + 1) as f64 / n as f64 - 1.0;
    let t = (2 * row + 1) as f64 / n as f64 - 1.0;
    face_st_to_dir(face, s, t).normalize()
}

/// Face, row and column of the texel containing direction `d`.
#[inline]
pub fn dir_to_cell(n: usize, d: DVec3) -> (usize, usize, usize) {
    let (face, s, t) = dir_to_face_st(d);
    face_st_to_cell(n, face, s, t)
}

/// The (face, row, col) of the texel of an N-cube that holds face position (`s`, `t`) of
/// `face`, each from -1 to 1 ([`dir_to_face_st`]); the last row or column holds 1.
#[inline]
pub fn face_st_to_cell(n: usize, face: usize, s: f64, t: f64) -> (usize, usize, usize) {
    // Through i32, whose conversion is one instruction where usize's takes several; the clamp
    // gives what usize's saturation and the `min` gave, for any x (NaN to 0).
    let to_cell = |x: f64| (((x + 1.0) * 0.5 * n as f64) as i32).clamp(0, n as i32 - 1) as usize;
    (face, to_cell(t), to_cell(s))
}

/// Linear index of the texel containing direction `d`.
#[inline]
pub fn dir_to_texel(n: usize, d: DVec3) -> usize {
    let (face, row, col) = dir_to_cell(n, d);
    texel_index(n, face, row, col)
}

/// Solid angle of the face region [0, s] x [0, t] as seen from the cube centre (cube of half-size 1).
fn area_element(s: f64, t: f64) -> f64 {
    (s * t).atan2((s * s + t * t + 1.0).sqrt())
}

/// Exact solid angle of the face region [s0, s1] x [t0, t1], from the area element at its four
/// corners. The same for every face.
pub fn patch_solid_angle(s0: f64, t0: f64, s1: f64, t1: f64) -> f64 {
    area_element(s1, t1) - area_element(s0, t1) - area_element(s1, t0) + area_element(s0, t0)
}

/// Exact solid angle of a texel. The same for every face.
pub fn texel_solid_angle(n: usize, row: usize, col: usize) -> f64 {
    let inv = 2.0 / n as f64;
    let (s0, s1) = (col as f64 * inv - 1.0, (col + 1) as f64 * inv - 1.0);
    let (t0, t1) = (row as f64 * inv - 1.0, (row + 1) as f64 * inv - 1.0);
    patch_solid_angle(s0, t0, s1, t1)
}

/// Solid angles of all 6 N² texels in linear order.
pub fn solid_angles(n: usize) -> Vec<f64> {
    let face: Vec<f64> = (0..n * n)
        .map(|i| texel_solid_angle(n, i / n, i % n))
        .collect();
    (0..6).flat_map(|_| face.iter().copied()).collect()
}

/// Unit directions of all 6 N² texel centres in linear order.
pub fn texel_dirs(n: usize) -> Vec<DVec3> {
    (0..texel_count(n))
        .map(|i| texel_dir(n, i / (n * n), (i / n) % n, i % n))
        .collect()
}

/// The texel centres of an N-cube in f32 and their solid angles over π, so that the cosines of
/// an open hemisphere weigh about 1: the coarse direction sets that ask what a point sees (an
/// edge pixel's shadows, a vertex's visibility signature), each stage adding its own queries.
pub struct Directions {
    /// Unit texel centres, in the cube's linear order.
    pub dirs: Vec<glam::Vec3>,
    /// Each one's solid angle over π.
    pub weights: Vec<f32>,
}

impl Directions {
    /// The directions of the N-cube.
    pub fn diffuse(n: usize) -> Directions {
        Directions {
            dirs: texel_dirs(n).iter().map(|d| d.as_vec3()).collect(),
            weights: solid_angles(n)
                .iter()
                .map(|&w| (w / std::f64::consts::PI) as f32)
                .collect(),
        }
    }
}

/// An RGB cube map of texel-average radiance.
#[derive(Clone, Debug, PartialEq)]
pub struct CubeMap {
    /// Face resolution N.
    pub n: usize,
    /// 6 N² texels in linear order.
    pub texels: Vec<[f32; 3]>,
}

impl CubeMap {
    /// An error unless the face size is `n`: "N = 8 but {wanted} N = 16".
    pub fn expect_n(&self, n: usize, wanted: &str) -> Result<()> {
        if self.n != n {
            return Err(PrtError::invalid(
                "cube map",
                format!("N = {} but {wanted} N = {n}", self.n),
            ));
        }
        Ok(())
    }

    /// A cube map with every texel set to `value`.
    pub fn constant(n: usize, value: [f32; 3]) -> Result<Self> {
        validate_n(n)?;
        Ok(CubeMap {
            n,
            texels: vec![value; texel_count(n)],
        })
    }

    /// A cube map whose every texel holds `radiance` of its centre's unit direction: an
    /// analytic sky, a test light, a basis function drawn on the cube.
    pub fn from_fn(n: usize, radiance: impl FnMut(DVec3) -> [f32; 3]) -> Result<Self> {
        validate_n(n)?;
        Ok(CubeMap {
            n,
            texels: texel_dirs(n).into_iter().map(radiance).collect(),
        })
    }

    /// Radiance of the texel containing `d` (nearest texel: the map is piecewise constant).
    pub fn lookup(&self, d: DVec3) -> [f32; 3] {
        self.texels[dir_to_texel(self.n, d)]
    }

    /// Radiant power per channel, Σ L_j Ω_j (W/m² per unit radiance scale).
    pub fn power(&self) -> [f64; 3] {
        let omega = solid_angles(self.n);
        let mut p = [0.0f64; 3];
        for (l, w) in self.texels.iter().zip(&omega) {
            for c in 0..3 {
                p[c] += l[c] as f64 * w;
            }
        }
        p
    }

    /// Relative L2 of this cube against `reference`, over every channel of every texel (texels
    /// unweighted): ‖a − b‖ / ‖b‖.
    pub fn relative_l2(&self, reference: &CubeMap) -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        for (x, y) in self.texels.iter().zip(&reference.texels) {
            for c in 0..3 {
                num += (x[c] as f64 - y[c] as f64).powi(2);
                den += (y[c] as f64).powi(2);
            }
        }
        (num / den).sqrt()
    }
}

/// Splits lat-long cells over cube texels. A cell whose four corners fall in one texel and that
/// is smaller than a texel lies inside that texel (up to the bulge of its parallels, negligible at
/// this size) and goes there whole; any other cell is cut in halves of exact solid angle ([`Cut`]:
/// across, along or both ways, keeping the pieces near square), recursively, until the pieces are below `finest`, where the last pieces go to the texel of
/// their centre. So the split of a cell over the texels it straddles is exact up to a band
/// `finest` wide along texel borders.
struct Splatter {
    n: usize,
    world_from_map: DMat3,
    /// Angular size (radians) below which a cell that straddles texels is no longer cut.
    finest: f64,
    /// Angular size of the smallest texel (a cube corner's), radians.
    texel_min: f64,
}

impl Splatter {
    fn texel_of(&self, u: f64, v: f64) -> usize {
        use std::f64::consts::PI;
        let (sin_u, cos_u) = (2.0 * PI * u).sin_cos();
        let (sin_v, cos_v) = (PI * v).sin_cos();
        dir_to_texel(
            self.n,
            self.world_from_map * DVec3::new(sin_u * sin_v, cos_v, -cos_u * sin_v),
        )
    }

    /// Adds radiance `l` times the solid angle of [u0, u1] x [v0, v1] to the texels it covers.
    /// `corners` are the texels of (u0, v0), (u1, v0), (u0, v1), (u1, v1).
    fn splat(
        &self,
        (u0, u1, v0, v1): (f64, f64, f64, f64),
        corners: [usize; 4],
        l: [f32; 3],
        acc: &mut [[f64; 4]],
    ) {
        use std::f64::consts::PI;
        let height = PI * (v1 - v0);
        let width = 2.0 * PI * (u1 - u0) * widest_sin(v0, v1, (PI * v0).sin(), (PI * v1).sin());
        let size = height.max(width);
        let same = corners.iter().all(|&c| c == corners[0]);
        if (same && size < self.texel_min) || size < self.finest {
            let j = if same {
                corners[0]
            } else {
                self.texel_of(0.5 * (u0 + u1), 0.5 * (v0 + v1))
            };
            let omega = 2.0 * PI * (u1 - u0) * ((PI * v0).cos() - (PI * v1).cos());
            for c in 0..3 {
                acc[j][c] += l[c] as f64 * omega;
            }
            acc[j][3] += omega;
            return;
        }
        let (um, vm) = (0.5 * (u0 + u1), 0.5 * (v0 + v1));
        let [c00, c10, c01, c11] = corners;
        match Cut::of(width, height) {
            Cut::Across => {
                let (top, bottom) = (self.texel_of(um, v0), self.texel_of(um, v1));
                self.splat((u0, um, v0, v1), [c00, top, c01, bottom], l, acc);
                self.splat((um, u1, v0, v1), [top, c10, bottom, c11], l, acc);
            }
            Cut::Along => {
                let (left, right) = (self.texel_of(u0, vm), self.texel_of(u1, vm));
                self.splat((u0, u1, v0, vm), [c00, c10, left, right], l, acc);
                self.splat((u0, u1, vm, v1), [left, right, c01, c11], l, acc);
            }
            Cut::Both => {
                let top = self.texel_of(um, v0);
                let left = self.texel_of(u0, vm);
                let mid = self.texel_of(um, vm);
                let right = self.texel_of(u1, vm);
                let bottom = self.texel_of(um, v1);
                self.splat((u0, um, v0, vm), [c00, top, left, mid], l, acc);
                self.splat((um, u1, v0, vm), [top, c10, mid, right], l, acc);
                self.splat((u0, um, vm, v1), [left, mid, c01, bottom], l, acc);
                self.splat((um, u1, vm, v1), [mid, right, bottom, c11], l, acc);
            }
        }
    }
}

/// How a cell part is cut: across its width (u halved), along it (v halved) or both ways. A part
/// more than twice as wide as it is tall is cut across only, and one more than twice as tall as
/// wide along only, so pieces stay near square whatever the map's shape: a cell of a map one pixel
/// wide spans the whole circle of its row, and halving both ways would cut it into as many pieces
/// along its short side as along its long one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cut {
    Across,
    Along,
    Both,
}

impl Cut {
    /// The cut of a part `width` x `height` (radians of arc).
    pub(crate) fn of(width: f64, height: f64) -> Self {
        if width > 2.0 * height {
            Cut::Across
        } else if height > 2.0 * width {
            Cut::Along
        } else {
            Cut::Both
        }
    }
}

/// The largest sine of the polar angle over the rows [v0, v1] (lat-long v, angle πv), given the
/// sines at the ends: 1 when the span holds the equator, so a cell from pole to pole has its
/// width.
pub(crate) fn widest_sin(v0: f64, v1: f64, sin0: f64, sin1: f64) -> f64 {
    if v0 <= 0.5 && v1 >= 0.5 {
        1.0
    } else {
        sin0.max(sin1)
    }
}

/// A lat-long map's pixels as the resamplers take them: `width` x `height`, rows from the north
/// pole. Every resampler checks that the pixels fit ([`LatLong::check`]); [`LatLong::new`]
/// checks them where the map is made.
#[derive(Clone, Copy)]
pub struct LatLong<'a> {
    /// Pixels a row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The pixels, row by row from the north pole.
    pub pixels: &'a [[f32; 3]],
}

impl<'a> LatLong<'a> {
    /// The map of `pixels`, an error unless they make a non-empty `width` x `height` map.
    pub fn new(width: usize, height: usize, pixels: &'a [[f32; 3]]) -> Result<LatLong<'a>> {
        let map = LatLong {
            width,
            height,
            pixels,
        };
        map.check()?;
        Ok(map)
    }

    /// An error unless the pixels make a non-empty `width` x `height` map.
    pub fn check(&self) -> Result<()> {
        check_latlong(self.width, self.height, self.pixels.len())
    }
}

impl std::fmt::Debug for LatLong<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LatLong({} x {})", self.width, self.height)
    }
}

/// Checks that `len` pixels make a non-empty `width` x `height` lat-long map.
pub(crate) fn check_latlong(width: usize, height: usize, len: usize) -> Result<()> {
    if width == 0 || height == 0 || width.checked_mul(height) != Some(len) {
        return Err(PrtError::invalid(
            "environment map",
            format!(
                "{width} x {height} needs {} pixels, got {len}",
                width.saturating_mul(height)
            ),
        ));
    }
    Ok(())
}

/// The two sizes that steer the splat of a map with `height` rows into a cube of face size `n`:
/// (`texel_min`, `finest`) of [`Splatter`]. Shared with the recorded splat of
/// [`crate::env::resample`], so both cut cells alike.
pub(crate) fn splat_limits(n: usize, width: usize, height: usize) -> (f64, f64) {
    // A face-corner texel spans about a third of the angle of a face-centre one (2/N).
    let texel_min = 2.0 / (3.0 * n as f64);
    // Cells larger than texels are cut just finely enough that every texel gets pieces (their
    // radiance is one value, so the normalisation below makes the split exact inside a cell);
    // finer maps are cut finer along texel borders, where neighbouring cells differ.
    // A cell's largest side: its height, or on a map less than twice as wide as tall its width at
    // the equator.
    let cell = (std::f64::consts::PI / height as f64).max(std::f64::consts::TAU / width as f64);
    let finest = if cell > texel_min {
        texel_min / 4.0
    } else {
        texel_min / 16.0
    };
    (texel_min, finest)
}

/// Resamples a lat-long radiance map (`width` x `height`, rows from the zenith) into a cube map of
/// texel-average radiance, with the environment turned by `world_from_map` (any rotation).
///
/// Each lat-long cell's power (radiance x exact cell solid angle) is split over the texels it
/// overlaps (see `Splatter`); a texel's radiance is its power over the solid angle it received.
/// A constant map gives a constant cube and the total power is kept to rounding error.
///
/// This is the direct splat, cell by cell, with trigonometry at every cut: the slow twin of
/// [`crate::env::resample`], which records the same split once per (map size, N, pitch) and reuses
/// it. [`crate::env::envmap::EnvMap::to_cube`] takes the fast path; this one stays as its reference
/// and for rotations that are not a yaw followed by a pitch.
pub fn resample_latlong_exact(map: LatLong, n: usize, world_from_map: DMat3) -> Result<CubeMap> {
    validate_n(n)?;
    map.check()?;
    let LatLong {
        width,
        height,
        pixels,
    } = map;
    let (texel_min, finest) = splat_limits(n, width, height);
    let splatter = Splatter {
        n,
        world_from_map,
        finest,
        texel_min,
    };
    let count = texel_count(n);
    let power = (0..height)
        .into_par_iter()
        .fold(
            || vec![[0.0f64; 4]; count],
            |mut acc, y| {
                let v0 = y as f64 / height as f64;
                let v1 = (y + 1) as f64 / height as f64;
                let row = &pixels[y * width..(y + 1) * width];
                let corner = |x: usize, v: f64| splatter.texel_of(x as f64 / width as f64, v);
                let (mut c00, mut c01) = (corner(0, v0), corner(0, v1));
                for (x, l) in row.iter().enumerate() {
                    let (c10, c11) = (corner(x + 1, v0), corner(x + 1, v1));
                    let u0 = x as f64 / width as f64;
                    let u1 = (x + 1) as f64 / width as f64;
                    splatter.splat((u0, u1, v0, v1), [c00, c10, c01, c11], *l, &mut acc);
                    (c00, c01) = (c10, c11);
                }
                acc
            },
        )
        .reduce(
            || vec![[0.0f64; 4]; count],
            |mut a, b| {
                for (x, y) in a.iter_mut().zip(&b) {
                    for c in 0..4 {
                        x[c] += y[c];
                    }
                }
                a
            },
        );
    // Radiance is power over the solid angle the splat actually gave the texel, so a constant map
    // gives a constant cube; a last global factor per channel then restores the total power
    // exactly (it differs from 1 by the residual border error, about 1e-3 at most).
    let want = std::array::from_fn(|c| power.iter().map(|p| p[c]).sum());
    Ok(splat_radiance(
        n,
        power.iter().map(|p| ([p[0], p[1], p[2]], p[3])),
        want,
        &solid_angles(n),
    ))
}

/// The cube a splat of face size `n` leaves: each texel's power over the solid angle it
/// received (`received`, texel by texel; black where it received none), then one factor per
/// channel that makes the cube's power (over the exact solid angles `omega`) `want`, in f32.
/// The exact splat, the recorded one and the pitch's all finish this way.
pub(crate) fn splat_radiance(
    n: usize,
    received: impl Iterator<Item = ([f64; 3], f64)>,
    want: [f64; 3],
    omega: &[f64],
) -> CubeMap {
    let mut texels: Vec<[f64; 3]> = received
        .map(|(p, a)| if a > 0.0 { p.map(|v| v / a) } else { [0.0; 3] })
        .collect();
    for (c, want) in want.iter().enumerate() {
        let got: f64 = texels.iter().zip(omega).map(|(t, w)| t[c] * w).sum();
        if got > 0.0 {
            let f = want / got;
            texels.iter_mut().for_each(|t| t[c] *= f);
        }
    }
    let texels = texels.iter().map(|t| t.map(|v| v as f32)).collect();
    CubeMap { n, texels }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Sum of up to 6·256² exact f64 texel solid angles against 4π: rounding accumulates over the
    /// terms to ~1e-12 at most.
    const FOUR_PI_SUM: f64 = 1e-10;

    #[test]
    fn relative_l2_of_a_scaled_cube_is_the_scale_less_one() {
        let mut a = CubeMap::constant(4, [1.0, 2.0, 0.5]).unwrap();
        a.texels[7] = [3.0, 0.0, 1.0];
        let b = CubeMap {
            n: 4,
            texels: a.texels.iter().map(|t| t.map(|v| 1.25 * v)).collect(),
        };
        assert_eq!(a.relative_l2(&a), 0.0);
        assert!((b.relative_l2(&a) - 0.25).abs() < 1e-7);
        assert!((a.relative_l2(&b) - 0.2).abs() < 1e-7);
    }

    #[test]
    fn solid_angles_sum_to_four_pi() {
        for n in [1, 2, 4, 16, 64, 256] {
            let total: f64 = solid_angles(n).iter().sum();
            assert!((total - 4.0 * PI).abs() < FOUR_PI_SUM, "n = {n}: {total}");
        }
    }

    #[test]
    fn face_coordinates_round_trip() {
        for n in [1, 2, 8, 32] {
            for i in 0..texel_count(n) {
                let d = texel_dir(n, i / (n * n), (i / n) % n, i % n);
                assert_eq!(dir_to_texel(n, d), i, "n = {n}, texel {i}");
            }
        }
    }

    #[test]
    fn face_positions_past_the_face_or_not_a_number_land_in_its_edge_cells() {
        assert_eq!(face_st_to_cell(4, 2, -1.0, 1.0), (2, 3, 0));
        assert_eq!(face_st_to_cell(4, 2, -0.5001, -0.4999), (2, 1, 0));
        assert_eq!(face_st_to_cell(4, 2, -1.5, 1e12), (2, 3, 0));
        assert_eq!(face_st_to_cell(4, 2, f64::NAN, f64::INFINITY), (2, 3, 0));
        assert_eq!(
            face_st_to_cell(4, 2, f64::NEG_INFINITY, f64::NAN),
            (2, 0, 0)
        );
    }

    #[test]
    fn invalid_sizes_are_errors() {
        for n in [0, 3, 12, 512] {
            let e = validate_n(n).unwrap_err().to_string();
            assert!(e.contains("power of two"), "{e}");
            assert!(CubeMap::from_fn(n, |_| [0.0; 3]).is_err());
        }
    }

    #[test]
    fn a_cube_from_a_function_holds_it_at_each_texel_centre() {
        let n = 4;
        let cube = CubeMap::from_fn(n, |d| [d.x as f32, d.y as f32, d.z as f32]).unwrap();
        assert_eq!(cube.texels.len(), texel_count(n));
        for face in 0..6 {
            for (row, col) in [(0, 0), (1, 2), (3, 3)] {
                let d = texel_dir(n, face, row, col);
                let want = [d.x as f32, d.y as f32, d.z as f32];
                assert_eq!(cube.texels[texel_index(n, face, row, col)], want);
                assert_eq!(cube.lookup(d), want);
            }
        }
    }
}
