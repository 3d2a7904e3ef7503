//! A shading point's direct light per texel light: visibility x BRDF x cosine over each texel
//! of the cube, the rows the bake stores and the texel reference sums.
//!
//! With one direction a texel, a texel's value is its centre's: a shadow border inside a texel
//! falls wholly on one side, so a sun smaller than a texel casts as many hard copies of a shadow
//! as texels it covers, and a glossy lobe narrower than a texel is sampled at a few points. With
//! the sampling's quadrature ([`TexelSamples::refined`]) every texel is integrated instead:
//! - the clamped cosine over a texel wholly above the surface is exact, `n · ∫ ω dω / π`;
//! - a texel whose centre's visibility differs from a neighbour's traces the sub-texels in its
//!   half towards that neighbour, so shadows get penumbrae a texel wide (the light's own width
//!   at the cube's resolution). The border lies between the two centres, and the neighbour
//!   traces its own half towards this texel; the sub-texels of the other half (and of the
//!   middle row or column, which lie as far across as the centre) take the centre's visibility,
//!   which the neighbours on those sides share. A border along a texel's side costs a third of
//!   its sub-texels, one across a corner five ninths;
//! - a texel the horizon crosses, or near the mirror direction of a GGX lobe (within
//!   2·atan(3α), at most 0.5 rad), sums its lobe over the sub-texels; a texel whose centre is
//!   below the horizon is taken as open when the centre of any of its neighbours is, and dark
//!   otherwise (its rays would graze the surface, and it holds little of the cosine).
//!
//! Texels elsewhere take the visibility of their centre, so an occluder thinner than a texel
//! that no centre sees is still missed, as it is with one direction a texel.

use glam::Vec3;

use super::CentrePackets;
use super::packets::SampleRays;
use super::{ShadingPoint, Shadows};
use crate::math::sampling::TexelSamples;
use crate::math::texel_quadrature::TexelQuadrature;
use crate::scene::brdf;

/// A GGX lobe's texels are summed over their sub-texels where its distribution is above this
/// fraction of its peak: D(h)/D(0) ≈ (α²/(α² + tan²θ_h))², so out to tan θ_h = 3α, twice that
/// angle in reflected directions.
const LOBE_TAN_HALF: f32 = 3.0;
/// The widest cone about the mirror direction whose texels are summed over sub-texels
/// (radians): wider lobes are smooth across a texel.
const LOBE_CONE_MAX: f32 = 0.5;

/// What a texel's centre ray found.
#[derive(Clone, Copy, PartialEq)]
enum Centre {
    /// The texel lies wholly below the surface.
    Below,
    /// The centre is above the surface and unoccluded (or shadows are off).
    Open,
    /// The centre is above the surface and occluded.
    Blocked,
    /// The centre is below the surface, but the horizon crosses the texel.
    Horizon,
}

/// For every texel j with light on it, calls `visit(j, diffuse, ggx)` with the texel's integral
/// of visibility x lobe x cosine: the Lambertian lobe ([`brdf::diffuse_cosine`]) and, with
/// `alpha`, the GGX lobe of that width ([`brdf::ggx_cosine`]); a medium's transmittance is in
/// both. One shadow ray serves both lobes. Returns the shadow rays traced.
pub fn direct_texels(
    shadows: &Shadows,
    samples: &TexelSamples,
    sp: &ShadingPoint,
    alpha: Option<f32>,
    mut visit: impl FnMut(usize, f32, f32),
) -> u64 {
    if let Some(q) = &samples.refine {
        return integrated_texels(shadows, q, sp, alpha, visit);
    }
    let (unshadowed, medium) = (shadows.unshadowed, shadows.medium);
    let m = samples.per_texel;
    let mut shadow = SampleRays::new(shadows, samples, sp);
    // One direction a texel traced in blocks, without a lobe or a medium: the open texels alone
    // (each above the surface), their cosine as the loop below sums it from zero.
    let open = shadow
        .open_bits()
        .filter(|_| m == 1 && alpha.is_none() && medium.is_none());
    if let Some(open) = open {
        for (w, &word) in open.iter().enumerate() {
            let mut word = word;
            while word != 0 {
                let j = w * 64 + word.trailing_zeros() as usize;
                word &= word - 1;
                let acc = brdf::diffuse_cosine(sp.normal, samples.dirs[j]) * samples.weights[j];
                if acc != 0.0 {
                    visit(j, acc, 0.0);
                }
            }
        }
        return shadow.rays;
    }
    let ggx = alpha.map(|a| brdf::GgxAt::new(sp.normal, sp.view, a));
    for j in 0..samples.dirs.len() / m {
        let dirs = &samples.dirs[j * m..(j + 1) * m];
        let weights = &samples.weights[j * m..(j + 1) * m];
        let (mut acc, mut acc_glossy) = (0.0f32, 0.0f32);
        for (s, (d, w)) in dirs.iter().zip(weights).enumerate() {
            if sp.normal.dot(*d) <= 0.0 {
                continue;
            }
            let mut w = *w;
            if !shadow.open(j * m + s, *d) {
                continue;
            }
            if let Some(m) = medium.filter(|_| !unshadowed) {
                w *= m.transmittance(sp.origin, *d, f32::INFINITY);
            }
            acc += brdf::diffuse_cosine(sp.normal, *d) * w;
            if let Some(ggx) = &ggx {
                acc_glossy += ggx.cosine(*d) * w;
            }
        }
        if acc != 0.0 || acc_glossy != 0.0 {
            visit(j, acc, acc_glossy);
        }
    }
    shadow.rays
}

/// [`direct_texels`] with every texel integrated (see the module's notes).
fn integrated_texels(
    shadows: &Shadows,
    q: &TexelQuadrature,
    sp: &ShadingPoint,
    alpha: Option<f32>,
    mut visit: impl FnMut(usize, f32, f32),
) -> u64 {
    let Shadows {
        unshadowed,
        medium,
        packets,
        ..
    } = *shadows;
    let n = sp.normal;
    let mut shadow = SampleRays::one_by_one(shadows, sp);
    let centres = classify_centres(q, n, &mut shadow, packets);
    // The GGX lobe at this point, and the cone of its texels about the mirror direction, as the
    // cosine of its half-angle widened by a texel's radius.
    let lobe = alpha.map(|a| {
        let mirror = 2.0 * n.dot(sp.view) * n - sp.view;
        let cone = (2.0 * (LOBE_TAN_HALF * a).atan()).min(LOBE_CONE_MAX) + q.max_radius;
        (brdf::GgxAt::new(n, sp.view, a), mirror, cone.cos())
    });
    let transmittance = |d: Vec3| match medium {
        Some(m) if !unshadowed => m.transmittance(sp.origin, d, f32::INFINITY),
        _ => 1.0,
    };
    let ggx = |d: Vec3| lobe.as_ref().map_or(0.0, |(g, ..)| g.cosine(d));
    let borders = borders(q, &centres);
    // Without a lobe or a medium, an open texel on no border and wholly above the horizon
    // takes its exact cosine alone: the value the general path below gives it, found sooner.
    let plain = lobe.is_none() && (medium.is_none() || unshadowed);
    for (j, &centre) in centres.iter().enumerate() {
        if centre == Centre::Below {
            continue;
        }
        let c = q.centres[j];
        let horizon = n.dot(c).abs() < q.sin_radius[j];
        if plain && centre == Centre::Open && borders[j] == 0 && !horizon {
            let diffuse = n.dot(q.moments[j]).max(0.0) * std::f32::consts::FRAC_1_PI;
            if diffuse != 0.0 {
                visit(j, diffuse, 0.0);
            }
            continue;
        }
        let (subs, weights) = q.subs(j);
        if borders[j] != 0 {
            let differs: [bool; 4] = std::array::from_fn(|k| borders[j] >> k & 1 == 1);
            // The sub-texels in the half of the texel towards a side whose neighbour differs
            // trace their own rays; the others, between the centre and neighbours that agree
            // with it, take the centre's visibility (see the module notes).
            let (mut diffuse, mut glossy, mut cosine) = (0.0f32, 0.0f32, 0.0f32);
            for (s, (d, w)) in subs.iter().zip(weights).enumerate() {
                if n.dot(*d) <= 0.0 {
                    continue;
                }
                let seen = if q.towards(s, differs) {
                    shadow.open_along(*d)
                } else {
                    centre == Centre::Open
                };
                let lambert = brdf::diffuse_cosine(n, *d);
                cosine += lambert * w;
                if seen {
                    let w = w * transmittance(*d);
                    diffuse += lambert * w;
                    glossy += ggx(*d) * w;
                }
            }
            // Above the horizon the cosine over the texel is known exactly: the sub-texels
            // give the share of it that is seen, so an open texel gets the exact value.
            if !horizon && cosine > 0.0 {
                diffuse *= n.dot(q.moments[j]).max(0.0) * std::f32::consts::FRAC_1_PI / cosine;
            }
            if diffuse != 0.0 || glossy != 0.0 {
                visit(j, diffuse, glossy);
            }
            continue;
        }
        // The direction whose visibility and transmittance the texel takes.
        let towards = match centre {
            Centre::Horizon => {
                let lit = q.neighbours[j]
                    .iter()
                    .any(|&k| centres[k as usize] == Centre::Open);
                if !lit {
                    continue;
                }
                let above: Vec3 = subs.iter().filter(|d| n.dot(**d) > 0.0).copied().sum();
                if above == Vec3::ZERO {
                    continue;
                }
                above.normalize()
            }
            Centre::Blocked => continue,
            _ => c,
        };
        let in_lobe = lobe.is_some_and(|(_, mirror, cos_cone)| mirror.dot(c) > cos_cone);
        let diffuse = if horizon {
            summed(subs, weights, |d| brdf::diffuse_cosine(n, d))
        } else {
            n.dot(q.moments[j]).max(0.0) * std::f32::consts::FRAC_1_PI
        };
        let glossy = if lobe.is_none() {
            0.0
        } else if horizon || in_lobe {
            summed(subs, weights, ggx)
        } else {
            ggx(c) * q.solid_angles[j]
        };
        let t = transmittance(towards);
        if diffuse != 0.0 || glossy != 0.0 {
            visit(j, diffuse * t, glossy * t);
        }
    }
    shadow.rays
}

/// What each texel's centre ray finds from the shading point with normal `n`: the rays traced
/// block by block where `packets` are given, one by one otherwise (the same answers).
fn classify_centres(
    q: &TexelQuadrature,
    n: Vec3,
    shadow: &mut SampleRays,
    packets: Option<&CentrePackets>,
) -> Vec<Centre> {
    let side = |j: usize| {
        let up = n.dot(q.centres[j]);
        if up <= -q.sin_radius[j] {
            Some(Centre::Below)
        } else if up <= 0.0 {
            Some(Centre::Horizon)
        } else {
            None
        }
    };
    let mut centres: Vec<Centre> = (0..q.centres.len())
        .map(|j| side(j).unwrap_or(Centre::Open))
        .collect();
    let Some(packets) = packets.filter(|_| !shadow.unshadowed()) else {
        for (c, d) in centres.iter_mut().zip(&q.centres) {
            if *c == Centre::Open && !shadow.open_along(*d) {
                *c = Centre::Blocked;
            }
        }
        return centres;
    };
    let mut open = vec![0u64; q.centres.len().div_ceil(64)];
    let traced = |j: usize| centres[j] == Centre::Open;
    shadow.trace_blocks(packets, traced, &mut open);
    for (j, c) in centres.iter_mut().enumerate() {
        if *c == Centre::Open && open[j / 64] >> (j % 64) & 1 == 0 {
            *c = Centre::Blocked;
        }
    }
    centres
}

/// For each texel, the sides (bit k for side k: −s, +s, −t, +t) across which its centre's
/// traced visibility differs from its neighbour's: an open centre's sides towards blocked
/// neighbours and a blocked centre's towards open ones. Found from the blocked centres, which
/// are fewer than the texels.
fn borders(q: &TexelQuadrature, centres: &[Centre]) -> Vec<u8> {
    let mut sides = vec![0u8; centres.len()];
    for (j, _) in centres
        .iter()
        .enumerate()
        .filter(|(_, c)| **c == Centre::Blocked)
    {
        for (k, &across) in q.neighbours[j].iter().enumerate() {
            let across = across as usize;
            if centres[across] != Centre::Open {
                continue;
            }
            sides[j] |= 1 << k;
            // The neighbour's side that faces back (neighbours are mutual).
            if let Some(back) = q.neighbours[across].iter().position(|&b| b as usize == j) {
                sides[across] |= 1 << back;
            }
        }
    }
    sides
}

/// Σ f(ω) Ω over a texel's sub-texels.
fn summed(subs: &[Vec3], weights: &[f32], f: impl Fn(Vec3) -> f32) -> f32 {
    subs.iter().zip(weights).map(|(d, w)| f(*d) * w).sum()
}

/// Adds `scale` times each texel's [`direct_texels`] to the rows (texel order): the Lambertian
/// lobe to `diffuse` and, for a glossy material, the GGX lobe of width `alpha` to `glossy`.
/// Returns the shadow rays traced.
pub fn accumulate_direct_rows(
    shadows: &Shadows,
    samples: &TexelSamples,
    sp: &ShadingPoint,
    scale: f32,
    diffuse: &mut [f32],
    mut glossy: Option<(f32, &mut [f32])>,
) -> u64 {
    let alpha = glossy.as_ref().map(|(a, _)| *a);
    direct_texels(shadows, samples, sp, alpha, |j, d, g| {
        diffuse[j] += d * scale;
        if let Some((_, row)) = glossy.as_mut() {
            row[j] += g * scale;
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use crate::scene::trace::Tracer;
    use crate::test_support::CANONICAL;
    use std::path::Path;

    /// A point at the origin facing `normal`, seen from `view`.
    fn point(normal: Vec3, view: Vec3) -> ShadingPoint {
        ShadingPoint {
            origin: Vec3::new(0.0, 50.0, 0.0),
            normal,
            view,
            material: 0,
            uv: glam::Vec2::ZERO,
            unit_albedo: false,
        }
    }

    /// Each texel's (diffuse, ggx) from `samples`, unshadowed.
    fn rows(
        samples: &TexelSamples,
        sp: &ShadingPoint,
        alpha: Option<f32>,
        tracer: &Tracer,
    ) -> Vec<[f64; 2]> {
        let mut out = vec![[0.0; 2]; samples.dirs.len() / samples.per_texel];
        let open = Shadows {
            tracer,
            unshadowed: true,
            medium: None,
            packets: None,
        };
        let rays = direct_texels(&open, samples, sp, alpha, |j, d, g| {
            out[j] = [d as f64, g as f64];
        });
        assert_eq!(rays, 0, "unshadowed points trace nothing");
        out
    }

    #[test]
    fn integrated_texels_sum_the_cosine_and_a_narrow_lobe_as_a_fine_quadrature_does() {
        let scene = Scene::from_toml_str(CANONICAL, Path::new("/nonexistent/scene.toml")).unwrap();
        let tracer = Tracer::new(&scene);
        let n = 16;
        let point_sampled = TexelSamples::new(n, 1, 3);
        let integrated = TexelSamples::new(n, 1, 3).refined(9);
        let fine = TexelSamples::new(n, 256, 3);
        let normal = Vec3::new(0.2, 0.9, -0.3).normalize();
        let view = Vec3::new(-0.6, 0.5, 0.4).normalize();
        let sp = point(normal, view);
        let alpha = 0.05;
        let (p, i, f) = (
            rows(&point_sampled, &sp, Some(alpha), &tracer),
            rows(&integrated, &sp, Some(alpha), &tracer),
            rows(&fine, &sp, Some(alpha), &tracer),
        );
        // ∫ max(0, n·ω)/π dω = 1: exact over texels wholly above, sub-texels at the horizon.
        let sum = |r: &[[f64; 2]], k: usize| r.iter().map(|v| v[k]).sum::<f64>();
        assert!((sum(&i, 0) - 1.0).abs() < 2e-4, "{}", sum(&i, 0));
        // Texel by texel, the cosine and the narrow lobe: the integrated texels several times
        // closer to 256 stratified directions a texel than the centres are (the cosine: 2.4e-4
        // against 2.4e-3 summed over the texels).
        let dist = |a: &[[f64; 2]], b: &[[f64; 2]], k: usize| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x[k] - y[k]).abs())
                .sum::<f64>()
        };
        assert!(dist(&i, &f, 0) * 5.0 < dist(&p, &f, 0));
        let lobe = sum(&f, 1);
        assert!(lobe > 0.1, "{lobe}");
        let (di, dp) = (dist(&i, &f, 1) / lobe, dist(&p, &f, 1) / lobe);
        assert!(di < 0.1 && di * 4.0 < dp, "integrated {di}, centres {dp}");
        assert!((sum(&i, 1) - lobe).abs() < 0.02 * lobe);
    }

    #[test]
    fn a_shadow_border_gets_a_penumbra_a_texel_wide() {
        // A point under the edge of a large quad: half the sky is hidden, the border crosses
        // texels, and those texels see part of the sky.
        let quad = r#"[[shape]]
type = "quad"
corners = [[-100.0, 1.0, -100.0], [-100.0, 1.0, 100.0], [0.3, 1.0, 100.0], [0.3, 1.0, -100.0]]
material = "m"
"#;
        let text = &crate::test_support::grey_scene_text([0.0, 5.0, 5.0], 40.0, 4, quad);
        let scene = Scene::from_toml_str(text, Path::new("/nonexistent/scene.toml")).unwrap();
        let tracer = Tracer::new(&scene);
        let n = 16;
        let sp = ShadingPoint {
            origin: Vec3::ZERO,
            ..point(Vec3::Y, Vec3::Y)
        };
        let shadowed = |samples: &TexelSamples| {
            let mut out = vec![0.0f64; samples.dirs.len() / samples.per_texel];
            let shadows = Shadows {
                tracer: &tracer,
                unshadowed: false,
                medium: None,
                packets: None,
            };
            let rays = direct_texels(&shadows, samples, &sp, None, |j, d, _| {
                out[j] = d as f64;
            });
            (out, rays)
        };
        let open = rows(&TexelSamples::new(n, 1, 3).refined(9), &sp, None, &tracer);
        let (point, point_rays) = shadowed(&TexelSamples::new(n, 1, 3));
        let (integrated, rays) = shadowed(&TexelSamples::new(n, 1, 3).refined(9));
        let (fine, _) = shadowed(&TexelSamples::new(n, 64, 3));
        // Texels partly lit: none with centres alone, a row of them integrated.
        let partial = |r: &[f64]| {
            r.iter()
                .zip(&open)
                .filter(|(v, o)| **v > 0.05 * o[0] && **v < 0.95 * o[0])
                .count()
        };
        assert_eq!(partial(&point), 0);
        assert!(partial(&integrated) >= n, "{}", partial(&integrated));
        // The border's texels trace the third of their sub-texels towards the border (one
        // differing side: 3 rays) or five ninths (two: 5 rays), and nothing else does.
        assert!(
            rays > point_rays && rays < point_rays + 4 * 12 * n as u64,
            "{rays} {point_rays}"
        );
        let l1 = |r: &[f64]| r.iter().zip(&fine).map(|(a, b)| (a - b).abs()).sum::<f64>();
        assert!(
            l1(&integrated) * 3.0 < l1(&point),
            "{} {}",
            l1(&integrated),
            l1(&point)
        );
    }

    /// The centres traced in packets give every texel the value, and the point the ray count,
    /// that tracing them one by one gives: on the demo scene, from a grid of camera hits, with
    /// a glossy lobe and without.
    #[test]
    fn packets_of_centres_change_nothing() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/demo.toml");
        let scene = Scene::load(&path).unwrap();
        let tracer = Tracer::new(&scene);
        // Texels integrated (the quadrature's centres), and one direction a texel.
        let integrated = TexelSamples::new(32, 1, 3).refined(9);
        let q = integrated.refine.as_ref().unwrap();
        let centres = TexelSamples::new(32, 1, 3);
        let sets = [
            (&integrated, CentrePackets::new(q.n, &q.centres)),
            (&centres, CentrePackets::new(32, &centres.dirs)),
        ];
        let texels = |samples, packets: Option<&CentrePackets>, sp: &ShadingPoint, alpha| {
            let shadows = Shadows {
                tracer: &tracer,
                unshadowed: false,
                medium: None,
                packets,
            };
            let mut out = Vec::new();
            let rays = direct_texels(&shadows, samples, sp, alpha, |j, d, g| {
                out.push((j, d.to_bits(), g.to_bits()));
            });
            (out, rays)
        };
        let cam = &scene.camera;
        let (mut points, mut shadowed) = (0, 0);
        for y in 0..8 {
            for x in 0..8 {
                let fx = (x as f32 + 0.5) * cam.width as f32 / 8.0;
                let ray = cam.ray(fx, (y as f32 + 0.5) * cam.height as f32 / 8.0);
                let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
                    continue;
                };
                let sp = super::super::shading_point(&tracer, &hit, ray.dir);
                let alpha = (x % 2 == 0).then_some(0.1);
                for (samples, packets) in &sets {
                    let alone = texels(samples, None, &sp, alpha);
                    let together = texels(samples, Some(packets), &sp, alpha);
                    assert_eq!(together, alone, "pixel ({x}, {y})");
                    assert!(alone.1 > 0);
                }
                points += 1;
                let alone = texels(&integrated, None, &sp, alpha);
                let open = alone.0.iter().filter(|v| v.1 != 0).count();
                shadowed += usize::from(open < 2900);
            }
        }
        // Points in shadow and in the open both, for the packets' two ways out.
        assert!(
            points > 40 && shadowed > 5 && shadowed < points,
            "{points} {shadowed}"
        );
    }
}
