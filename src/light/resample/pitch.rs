//! Pitch without weights of its own. Recording the splat under a pitch takes 80 ms at N = 32 for a
//! 1024 x 512 map and 264 ms at N = 64, and every pitch of a drag is new, so a pitch drag cost 30
//! and 56 times a yaw drag. Where the map's cells are no larger than the
//! smallest texels, a pitched light is instead splatted at the centres of sub-cells:
//! - each cell of the world grid (world = R_x(pitch) · R_y(yaw) · map, see
//!   [`crate::conventions`]) is cut into q x q sub-cells no wider than half the smallest texel;
//! - each takes the turned map's mean over it, as the yaw's shift gives it (exact: the map is
//!   constant over a cell, see the module notes of [`super`]);
//! - and gives its power whole to the texel its centre lands in under the pitch.
//!
//! As in the exact splat, a texel's radiance is the power it received over the solid angle it
//! received, and one factor per channel restores the map's power, so a constant map stays
//! constant and no power is lost.
//!
//! Where the exact splat cuts cells along texel borders down to a band of texel_min / 16, this
//! moves whole sub-cells, a band of up to texel_min / 2: the two differ where a border crosses a
//! feature no larger than a few cells, such as a small sun, by the share of it in the band.
//! Measured against the exact splat over the cube, on a 1024 x 512 map (the `light::resample`
//! test `a_pitch_splatted_at_cell_centres_stays_near_the_exact_splat`): at most 3.6% at N = 8 to
//! 32 and 5.3% at N = 64 with a 2 x 2-pixel sun, where the recorded weights of a fractional yaw
//! differ by 1.5% and 4.7%; 4.3e-4 on a smooth map. A map whose cells are larger than the
//! smallest texels (a small map, or N above 64 for a 1024 x 512 one) records weights for the
//! pitch as before, as does any splat that leaves a texel without a cell.
//!
//! On the 2-core machine (`cargo bench --bench light`, blender_sunrise, one run, the README's
//! table): a pitch drag prepares a light in 6.05 ms at N = 32 and 20.3 ms at N = 64, against 80.3
//! and 264 ms through weights recorded for each pitch, and 2.72 and 4.70 ms for a yaw drag.
//!
//! Pitch 0 keeps the recorded weights, exact to the band of the recorded splat: a light that
//! leaves pitch 0 steps by the difference above (on a small sun crossing a texel border, a few
//! percent of that texel).

use std::f64::consts::{PI, TAU};

use glam::DVec3;
use rayon::prelude::*;

use super::{EnvRotation, yaw_shift};
use crate::error::Result;
use crate::math::cubemap::{
    CubeMap, dir_to_texel, solid_angles, splat_limits, splat_radiance, texel_count,
};

/// Whether a `width` x `height` map's cells are small enough, against a cube of face `n`, to be
/// splatted at their centres: none larger than the smallest texel.
pub(super) fn splats_at_centres(width: usize, height: usize, n: usize) -> bool {
    let (texel_min, _) = splat_limits(n, width, height);
    (PI / height as f64).max(TAU / width as f64) <= texel_min
}

/// Row bands per thread.
const BANDS_PER_THREAD: usize = 2;
/// Most sub-cells along each side of a cell.
const MAX_SPLIT: usize = 4;

/// Sub-cells along each side of a cell, so that none is wider than half the smallest texel: the
/// band along texel borders where power may go to the wrong side. (A quarter halves the band but
/// not the error against the exact splat, which has a band of its own, at four times the work:
/// measured 3.0% against 3.6% at N = 32 on a map with a small sun.)
fn split(width: usize, height: usize, n: usize) -> usize {
    let (texel_min, _) = splat_limits(n, width, height);
    let cell = (PI / height as f64).max(TAU / width as f64);
    ((cell / (texel_min / 2.0)).ceil() as usize).clamp(1, MAX_SPLIT)
}

/// The share of each of a cell's `q` sub-columns that lies in the cell's last fraction `f`, where
/// a yaw of a fraction f of a cell puts the next map cell (see the module notes of [`super`]).
fn tail_shares(q: usize, f: f64) -> Vec<f64> {
    (0..q)
        .map(|i| {
            let (a, b) = (i as f64 / q as f64, (i + 1) as f64 / q as f64);
            (b - (1.0 - f)).clamp(0.0, b - a) * q as f64
        })
        .collect()
}

/// `pixels` (a `width` x `height` lat-long map) turned by `rotation` and splatted at the centres
/// of the world cells' sub-cells into a cube of face `n`; `None` when a texel received nothing
/// (the caller then records weights for the pitch).
pub(super) fn splat(
    width: usize,
    height: usize,
    pixels: &[[f32; 3]],
    n: usize,
    rotation: EnvRotation,
) -> Result<Option<CubeMap>> {
    let (whole, f) = yaw_shift(width, rotation.yaw_deg)?;
    let q = split(width, height, n);
    let sub_columns: Vec<(f64, f64)> = (0..width * q)
        .map(|x| (TAU * (x as f64 + 0.5) / (width * q) as f64).sin_cos())
        .collect();
    let tail = tail_shares(q, f);
    let count = texel_count(n);
    let (sin_p, cos_p) = rotation.pitch_deg.to_radians().sin_cos();
    // A few bands a thread, each scattering into a cube of its own.
    let bands = (rayon::current_num_threads() * BANDS_PER_THREAD).clamp(1, height);
    let (power, received) = (0..bands)
        .into_par_iter()
        .map(|band| {
            let mut power = vec![[0.0f64; 3]; count];
            let mut received = vec![0.0f64; count];
            for y in band * height / bands..(band + 1) * height / bands {
                let row = &pixels[y * width..(y + 1) * width];
                for j in 0..q {
                    let v0 = PI * (y * q + j) as f64 / (height * q) as f64;
                    let v1 = PI * (y * q + j + 1) as f64 / (height * q) as f64;
                    // The sub-cell's exact solid angle, and its centre's direction turned by
                    // R_x(pitch): (sin u sin v, cos v, −cos u sin v) goes to
                    // (sin u sin v, c cos v + s cos u sin v, s cos v − c cos u sin v).
                    let omega = TAU / (width * q) as f64 * (v0.cos() - v1.cos());
                    let (sin_v, cos_v) = (0.5 * (v0 + v1)).sin_cos();
                    let (y0, y1) = (cos_p * cos_v, sin_p * sin_v);
                    let (z0, z1) = (sin_p * cos_v, cos_p * sin_v);
                    for x in 0..width {
                        // World cell x holds the turned map's cell x + whole, and its last
                        // fraction f the next cell (see the module notes of `super`).
                        let a = row[(x + whole) % width].map(|v| v as f64 * omega);
                        let b = match f {
                            0.0 => [0.0; 3],
                            _ => row[(x + whole + 1) % width].map(|v| v as f64 * omega),
                        };
                        for (i, &t) in tail.iter().enumerate() {
                            let (sin_u, cos_u) = sub_columns[x * q + i];
                            let d = DVec3::new(sin_u * sin_v, y0 + y1 * cos_u, z0 - z1 * cos_u);
                            let texel = dir_to_texel(n, d);
                            for c in 0..3 {
                                power[texel][c] += a[c] + t * (b[c] - a[c]);
                            }
                            received[texel] += omega;
                        }
                    }
                }
            }
            (power, received)
        })
        .reduce(
            || (vec![[0.0f64; 3]; count], vec![0.0f64; count]),
            |(mut pa, mut ra), (pb, rb)| {
                for (a, b) in pa.iter_mut().zip(&pb) {
                    for c in 0..3 {
                        a[c] += b[c];
                    }
                }
                for (a, b) in ra.iter_mut().zip(&rb) {
                    *a += b;
                }
                (pa, ra)
            },
        );
    if received.contains(&0.0) {
        return Ok(None);
    }
    // The map's exact power: each row's turned means keep its sum.
    let want: [f64; 3] = std::array::from_fn(|c| power.iter().map(|p| p[c]).sum());
    Ok(Some(splat_radiance(
        n,
        power.iter().copied().zip(received.iter().copied()),
        want,
        &solid_angles(n),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_next_cell_fills_the_last_sub_columns_first() {
        let near = |got: Vec<f64>, want: &[f64]| {
            assert!(
                got.len() == want.len() && got.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
                "{got:?} against {want:?}"
            )
        };
        near(tail_shares(1, 0.3), &[0.3]);
        near(tail_shares(4, 0.0), &[0.0; 4]);
        near(tail_shares(4, 0.25), &[0.0, 0.0, 0.0, 1.0]);
        near(tail_shares(4, 0.375), &[0.0, 0.0, 0.5, 1.0]);
        // Every share together is the fraction.
        for q in 1..=MAX_SPLIT {
            for f in [0.1, 0.5, 0.9] {
                let sum: f64 = tail_shares(q, f).iter().sum::<f64>() / q as f64;
                assert!((sum - f).abs() < 1e-12, "q = {q}, f = {f}: {sum}");
            }
        }
    }
}
