//! Zonal harmonic coefficients of any kernel symmetric about +z, by quadrature: what a glossy
//! lobe, taken as symmetric about its reflection direction, convolves a light with
//! ([`crate::math::sh::convolve`] and the Funk–Hecke factors it applies).

use std::f64::consts::PI;

/// Quadrature steps over the polar angle: a GGX lobe of α = 0.01 is a few degrees wide, and
/// 65,536 steps put over a hundred in it.
pub const ZONAL_STEPS: usize = 1 << 16;

/// Per-band coefficients `z_l = ∫ k(ω·z) Y_l^0(ω) dω`, l = 0..order−1, of the kernel `k` of the
/// cosine to +z, by the midpoint rule over the polar angle in `steps` steps (the convention of
/// [`crate::math::sh::clamped_cosine_zonal`]).
pub fn zonal_of(order: usize, steps: usize, k: impl Fn(f64) -> f64) -> Vec<f64> {
    let mut z = vec![0.0; order];
    let dtheta = PI / steps as f64;
    let mut legendre = vec![0.0; order];
    for s in 0..steps {
        let theta = (s as f64 + 0.5) * dtheta;
        let t = theta.cos();
        let weight = k(t) * theta.sin() * dtheta;
        if weight == 0.0 {
            continue;
        }
        // P_l(t) by the three-term recurrence.
        for l in 0..order {
            legendre[l] = match l {
                0 => 1.0,
                1 => t,
                l => {
                    ((2 * l - 1) as f64 * t * legendre[l - 1] - (l - 1) as f64 * legendre[l - 2])
                        / l as f64
                }
            };
            z[l] += weight * legendre[l];
        }
    }
    z.iter()
        .enumerate()
        .map(|(l, s)| 2.0 * PI * ((2 * l + 1) as f64 / (4.0 * PI)).sqrt() * s)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::sh::{clamped_cosine_zonal, henyey_greenstein_zonal};

    #[test]
    fn the_quadrature_gives_the_closed_forms() {
        let cosine = zonal_of(8, ZONAL_STEPS, |t| t.max(0.0));
        for (a, b) in cosine.iter().zip(clamped_cosine_zonal(8)) {
            assert!((a - b).abs() < 1e-6, "{a} {b}");
        }
        let g = 0.6;
        let hg = zonal_of(8, ZONAL_STEPS, |t| {
            (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * t).powf(1.5))
        });
        for (a, b) in hg.iter().zip(henyey_greenstein_zonal(8, g)) {
            assert!((a - b).abs() < 1e-6, "{a} {b}");
        }
    }
}
