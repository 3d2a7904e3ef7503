//! The in-out BRDF terms of a glossy vertex in a per-vertex bake: besides its diffuse row, term k
//! (1 ≤ k < K_b) is the row `∫ V(ω) h_k(ω in the vertex's frame)` over each texel, with the
//! material's specular colour as its weight, stored at pixel `v · stride + k`
//! ([`crate::scene::brdf_factor::BrdfFactors`]). The raster multiplies each term's response by
//! `g_k` of the direction to the eye, per pixel. One shadow ray serves the diffuse row and every
//! term.

use glam::Vec3;

use super::packets::SampleRays;
use super::{ShadingPoint, Shadows};
use crate::math::sampling::TexelSamples;
use crate::scene::brdf;
use crate::scene::brdf_factor::{BrdfFactors, local_frame};

/// For every texel sample ω above the vertex's horizon and not occluded, adds
/// `scale · Ω_ω · cos θ / π` to `diffuse` and `scale · Ω_ω · h_k(ω)` to `terms[k − 1]` for each
/// of the material's terms k ≥ 1 (texel order). A medium's transmittance is not taken. Returns
/// the shadow rays traced.
pub fn accumulate_term_rows(
    shadows: &Shadows,
    samples: &TexelSamples,
    sp: &ShadingPoint,
    factors: &BrdfFactors,
    scale: f32,
    diffuse: &mut [f32],
    terms: &mut [Vec<f32>],
) -> u64 {
    let m = samples.per_texel;
    let k_b = factors.terms_of(sp.material);
    let (t, b) = local_frame(sp.normal);
    let mut acc = vec![0.0f32; k_b];
    let mut shadow = SampleRays::new(shadows, samples, sp);
    for (j, out) in diffuse.iter_mut().enumerate() {
        let dirs = &samples.dirs[j * m..(j + 1) * m];
        let weights = &samples.weights[j * m..(j + 1) * m];
        acc.fill(0.0);
        for (s, (d, w)) in dirs.iter().zip(weights).enumerate() {
            if sp.normal.dot(*d) <= 0.0 || !shadow.open(j * m + s, *d) {
                continue;
            }
            acc[0] += brdf::diffuse_cosine(sp.normal, *d) * w;
            // Above the horizon (tested above): the direction's taps serve every term.
            let taps = factors
                .map
                .taps(Vec3::new(d.dot(t), d.dot(b), d.dot(sp.normal)));
            for (k, a) in acc.iter_mut().enumerate().skip(1) {
                *a += factors.light_with(sp.material, k, &taps) * w;
            }
        }
        *out += acc[0] * scale;
        for (row, a) in terms.iter_mut().zip(&acc[1..]) {
            row[j] += a * scale;
        }
    }
    shadow.rays
}

/// The factors whose terms vertex `sp` is baked with, when its material takes more than its
/// diffuse term: none for a textured vertex (baked white, its albedo map applied by the raster).
pub fn factors_of<'a>(
    factors: Option<&'a BrdfFactors>,
    sp: &ShadingPoint,
) -> Option<&'a BrdfFactors> {
    factors.filter(|f| !sp.unit_albedo && f.terms_of(sp.material) > 1)
}
