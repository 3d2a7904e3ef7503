//! SH lighting at any order, through the light: the way Ng et al. 2003 evaluated SH with up to
//! 20,000 terms. The cube light is projected onto SH up to order n and reconstructed on the cube
//! texels, and the full stored transport relights it: T·P_n(L). No SH transport is needed, so the
//! order is bounded by the light alone ([`crate::math::sh::MAX_LIGHT_ORDER`]), not by the bake.
//!
//! The cube light is piecewise constant over texels, and a transport entry answers a texel's
//! average radiance, so both steps integrate over texels: the projection is
//! `L_lm = Σ_t L_t ∫_t Y_lm dω` and the reconstruction is the texel average
//! `P_n(L)_t = Σ_lm L_lm ∫_t Y_lm dω / Ω_t`. Each integral is a sum over `SUBSAMPLES`² sub-texels
//! (their exact solid angles, the basis at their centres). Per texel and band the reconstruction
//! is stored as a band sum, so every lower order is a prefix sum and a sweep over orders costs one
//! projection.
//!
//! Against the baked SH path (per-pixel SH transport dotted with the light's SH) the two agree
//! where both exist up to the texel discretisation: the bake evaluates the basis at its texel
//! sample directions, this route averages it over the texel, and the light's coefficients come
//! from the cube here and from the lat-long map there.

use rayon::prelude::*;

use crate::error::{PrtError, Result};
use crate::math::cubemap::{CubeMap, texel_count, texel_dir, texel_solid_angle};
use crate::math::sh::{MAX_LIGHT_ORDER, coeff_count, eval};

/// Sub-texels per texel side for the basis integrals.
pub const SUBSAMPLES: usize = 2;

/// A cube light projected onto SH up to `max_order`, ready to give its reconstruction at any
/// order up to that.
#[derive(Clone, Debug)]
pub struct ShThroughLight {
    /// Cube face size N.
    pub n: usize,
    /// Highest order projected.
    pub max_order: usize,
    /// SH coefficients of the light, `max_order`² of them.
    pub coeffs: Vec<[f64; 3]>,
    /// Per texel, per band l: that band's part of the texel average, `max_order` per texel.
    bands: Vec<[f64; 3]>,
}

/// The sub-texels of texel `t` of an N cube: (direction, exact solid angle).
fn sub_texels(n: usize, t: usize) -> impl Iterator<Item = (glam::DVec3, f64)> {
    let (face, row, col) = (t / (n * n), (t / n) % n, t % n);
    let fine = n * SUBSAMPLES;
    (0..SUBSAMPLES * SUBSAMPLES).map(move |k| {
        let (r, c) = (
            row * SUBSAMPLES + k / SUBSAMPLES,
            col * SUBSAMPLES + k % SUBSAMPLES,
        );
        (texel_dir(fine, face, r, c), texel_solid_angle(fine, r, c))
    })
}

impl ShThroughLight {
    /// Projects `cube` onto SH of orders 1 ..= `max_order` (at most
    /// [`crate::math::sh::MAX_LIGHT_ORDER`]).
    pub fn new(cube: &CubeMap, max_order: usize) -> Result<Self> {
        if !(1..=MAX_LIGHT_ORDER).contains(&max_order) {
            return Err(PrtError::invalid(
                "SH order through the light",
                format!("{max_order} is outside 1..={MAX_LIGHT_ORDER}"),
            ));
        }
        let n = cube.n;
        if cube.texels.len() != texel_count(n) {
            return Err(PrtError::invalid(
                "cube map",
                format!("{} texels for N = {n}", cube.texels.len()),
            ));
        }
        let count = coeff_count(max_order);
        // L_lm = Σ_t L_t ∫_t Y_lm, one accumulator per thread.
        let coeffs = (0..texel_count(n))
            .into_par_iter()
            .fold(
                || (vec![[0.0f64; 3]; count], vec![0.0f64; count]),
                |(mut acc, mut y), t| {
                    let l = cube.texels[t].map(f64::from);
                    if l == [0.0; 3] {
                        return (acc, y);
                    }
                    for (d, w) in sub_texels(n, t) {
                        eval(max_order, d, &mut y);
                        for (a, yi) in acc.iter_mut().zip(&y) {
                            let f = yi * w;
                            for c in 0..3 {
                                a[c] += l[c] * f;
                            }
                        }
                    }
                    (acc, y)
                },
            )
            .map(|(acc, _)| acc)
            .reduce(|| vec![[0.0f64; 3]; count], crate::math::sh::add_rgb);
        // Band sums of the texel averages.
        let mut bands = vec![[0.0f64; 3]; texel_count(n) * max_order];
        bands.par_chunks_mut(max_order).enumerate().for_each_init(
            || vec![0.0f64; count],
            |y, (t, out)| {
                let mut area = 0.0;
                for (d, w) in sub_texels(n, t) {
                    eval(max_order, d, y);
                    area += w;
                    for (l, band) in out.iter_mut().enumerate() {
                        let mut sum = [0.0f64; 3];
                        for i in l * l..(l + 1) * (l + 1) {
                            for c in 0..3 {
                                sum[c] += coeffs[i][c] * y[i];
                            }
                        }
                        for c in 0..3 {
                            band[c] += sum[c] * w;
                        }
                    }
                }
                for band in out.iter_mut() {
                    for v in band.iter_mut() {
                        *v /= area;
                    }
                }
            },
        );
        Ok(ShThroughLight {
            n,
            max_order,
            coeffs,
            bands,
        })
    }

    /// The light reconstructed from its first `order`² SH terms, as texel averages. Ringing may
    /// make some texels negative; they are kept, as the SH path keeps them.
    pub fn cube(&self, order: usize) -> Result<CubeMap> {
        if !(1..=self.max_order).contains(&order) {
            return Err(PrtError::invalid(
                "SH order through the light",
                format!(
                    "{order} is outside 1..={} (the order projected)",
                    self.max_order
                ),
            ));
        }
        let texels = self
            .bands
            .chunks(self.max_order)
            .map(|b| {
                let mut v = [0.0f64; 3];
                for band in &b[..order] {
                    for c in 0..3 {
                        v[c] += band[c];
                    }
                }
                v.map(|x| x as f32)
            })
            .collect();
        Ok(CubeMap { n: self.n, texels })
    }
}
