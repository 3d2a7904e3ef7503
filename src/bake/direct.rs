//! A shading point's direct light per texel light: visibility x BRDF x cosine over each texel
//! of the cube, the rows the bake stores and the texel reference sums.

use super::ShadingPoint;
use crate::math::sampling::TexelSamples;
use crate::medium::Medium;
use crate::scene::brdf;
use crate::scene::trace::Tracer;

/// For every texel sample ω, adds `scale · visibility · lobe(ω) · Ω_ω` to the rows (texel
/// order): the Lambertian lobe ([`brdf::diffuse_cosine`]) to `diffuse` and, for a glossy
/// material, the GGX lobe of width `alpha` ([`brdf::ggx_cosine`]) to `glossy`. One shadow ray
/// serves both. Returns the shadow rays traced.
#[allow(clippy::too_many_arguments)]
pub fn accumulate_direct_rows(
    tracer: &Tracer,
    samples: &TexelSamples,
    sp: &ShadingPoint,
    unshadowed: bool,
    medium: Option<&Medium>,
    scale: f32,
    diffuse: &mut [f32],
    mut glossy: Option<(f32, &mut [f32])>,
) -> u64 {
    let m = samples.per_texel;
    let mut rays = 0u64;
    for (j, out) in diffuse.iter_mut().enumerate() {
        let dirs = &samples.dirs[j * m..(j + 1) * m];
        let weights = &samples.weights[j * m..(j + 1) * m];
        let (mut acc, mut acc_glossy) = (0.0f32, 0.0f32);
        for (d, w) in dirs.iter().zip(weights) {
            if sp.normal.dot(*d) <= 0.0 {
                continue;
            }
            let mut w = *w;
            if !unshadowed {
                rays += 1;
                if tracer.occluded(sp.origin, *d, f32::INFINITY) {
                    continue;
                }
                if let Some(m) = medium {
                    w *= m.transmittance(sp.origin, *d, f32::INFINITY);
                }
            }
            acc += brdf::diffuse_cosine(sp.normal, *d) * w;
            if let Some((alpha, _)) = glossy {
                acc_glossy += brdf::ggx_cosine(sp.normal, sp.view, *d, alpha) * w;
            }
        }
        *out += acc * scale;
        if let Some((_, row)) = glossy.as_mut() {
            row[j] += acc_glossy * scale;
        }
    }
    rays
}
