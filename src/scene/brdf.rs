//! Reflectance of the materials of [`crate::scene::Material`], written as the factor that
//! multiplies a light sample's solid angle: `f(l, v) · max(0, n·l)` per unit of the lobe's colour.
//! The bake and the brute-force reference both integrate these, so they agree by construction;
//! the tests hold the lobes to energy bounds.

use glam::Vec3;

/// Lambertian: `(1/π) · max(0, n·l)`.
#[inline]
pub fn diffuse_cosine(n: Vec3, l: Vec3) -> f32 {
    n.dot(l).max(0.0) * std::f32::consts::FRAC_1_PI
}

/// GGX (Trowbridge–Reitz) microfacet lobe with the separable Smith shadowing term, per unit of
/// specular colour: `D(h) · G1(l) · G1(v) / (4 (n·l)(n·v)) · (n·l)`. `alpha` is the GGX width
/// (perceptual roughness squared); `v` points from the surface towards the viewer.
#[inline]
pub fn ggx_cosine(n: Vec3, v: Vec3, l: Vec3, alpha: f32) -> f32 {
    let (nl, nv) = (n.dot(l), n.dot(v));
    if nl <= 0.0 || nv <= 0.0 {
        return 0.0;
    }
    let h = (l + v).normalize_or_zero();
    let nh = n.dot(h).max(0.0);
    let a2 = alpha * alpha;
    let d = a2 / (std::f32::consts::PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let g1 = |c: f32| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
    d * g1(nl) * g1(nv) / (4.0 * nv)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Directional albedo ∫ f cos dω of a lobe for view `v` about normal +Z, by a fine
    /// midpoint rule in (cos θ, φ), refined where a narrow lobe needs it.
    fn albedo(lobe: impl Fn(Vec3) -> f32) -> f64 {
        let (nt, np) = (2000, 720);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let ct = (i as f64 + 0.5) / nt as f64;
            let st = (1.0 - ct * ct).sqrt();
            for j in 0..np {
                let p = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / np as f64;
                let l = Vec3::new((st * p.cos()) as f32, (st * p.sin()) as f32, ct as f32);
                sum += lobe(l) as f64;
            }
        }
        sum * 2.0 * std::f64::consts::PI / (nt * np) as f64
    }

    #[test]
    fn lambertian_lobe_integrates_to_one() {
        let e = albedo(|l| diffuse_cosine(Vec3::Z, l));
        assert!((e - 1.0).abs() < 1e-4, "{e}");
    }

    #[test]
    fn ggx_lobe_keeps_energy_in_bounds() {
        // A white furnace for the lobe: it never reflects more than it receives, and a smooth
        // lobe seen head-on loses almost nothing (Smith shadowing costs energy as roughness
        // grows, a known property of single-scattering GGX).
        for roughness in [0.25f32, 0.5, 0.8] {
            let alpha = roughness * roughness;
            for view_deg in [0.0f32, 45.0, 75.0] {
                let t = view_deg.to_radians();
                let v = Vec3::new(t.sin(), 0.0, t.cos());
                let e = albedo(|l| ggx_cosine(Vec3::Z, v, l, alpha));
                assert!(
                    e <= 1.0 + 2e-3,
                    "roughness {roughness}, view {view_deg}: {e}"
                );
                assert!(e > 0.3, "roughness {roughness}, view {view_deg}: {e}");
                // Head-on, a microfacet normal more than 45° off n reflects below the horizon;
                // for GGX that happens with probability α²/(1 + α²) (0.4% at roughness 0.5, 50%
                // at 1), which bounds the albedo from above.
                if view_deg < 60.0 {
                    let lost = alpha * alpha / (1.0 + alpha * alpha);
                    // Shadowing (G <= 1) takes at most a quarter of the rest at these roughnesses.
                    let floor = 0.75 * (1.0 - lost) as f64;
                    assert!(
                        e > floor,
                        "roughness {roughness}, view {view_deg}: {e} < {floor}"
                    );
                    if view_deg == 0.0 {
                        assert!(e <= 1.0 - lost as f64 + 1e-3, "{e} above {}", 1.0 - lost);
                    }
                }
            }
        }
    }

    #[test]
    fn ggx_at_roughness_one_seen_head_on_reflects_one_minus_ln_two() {
        // With alpha = 1, D = 1/π and G1(c) = 2c / (1 + c); seen along n, l = reflect(n, h) has
        // cos θl = 2 cos² θh − 1, and ∫ D G1(l) (n·h) dω_h over cos θh in [1/√2, 1] gives
        // 2 ∫ (2c² − 1)/c dc = 1 − ln 2.
        let e = albedo(|l| ggx_cosine(Vec3::Z, Vec3::Z, l, 1.0));
        let want = 1.0 - std::f64::consts::LN_2;
        assert!((e - want).abs() < 1e-3, "{e} vs {want}");
    }

    #[test]
    fn ggx_is_reciprocal_and_peaks_at_the_mirror_direction() {
        let n = Vec3::Z;
        let v = Vec3::new(0.6, 0.0, 0.8);
        let l = Vec3::new(-0.3, 0.4, (1.0f32 - 0.25).sqrt());
        let alpha = 0.3;
        // f(l, v) cos(l) / cos(l) = f(v, l) cos(v) / cos(v).
        let f_lv = ggx_cosine(n, v, l, alpha) / n.dot(l);
        let f_vl = ggx_cosine(n, l, v, alpha) / n.dot(v);
        assert!((f_lv - f_vl).abs() < 1e-5 * f_lv.abs(), "{f_lv} vs {f_vl}");
        let mirror = Vec3::new(-0.6, 0.0, 0.8);
        assert!(ggx_cosine(n, v, mirror, alpha) > ggx_cosine(n, v, l, alpha));
        assert_eq!(ggx_cosine(n, v, -mirror, alpha), 0.0);
    }
}
