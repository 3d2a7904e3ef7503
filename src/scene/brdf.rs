//! Reflectance of the materials of [`crate::scene::Material`], written as the factor that
//! multiplies a light sample's solid angle: `f(l, v) · max(0, n·l)` per unit of the lobe's colour.
//! The bake and the brute-force reference both integrate these, so they agree by construction;
//! the tests hold the lobes to energy bounds.

use glam::{DVec3, Vec3};

/// Lambertian: `(1/π) · max(0, n·l)`.
#[inline]
pub fn diffuse_cosine(n: Vec3, l: Vec3) -> f32 {
    n.dot(l).max(0.0) * std::f32::consts::FRAC_1_PI
}

/// GGX (Trowbridge–Reitz) microfacet lobe with the separable Smith shadowing term, per unit of
/// specular colour: `D(h) · G1(l) · G1(v) / (4 (n·l)(n·v)) · (n·l)`. `alpha` is the GGX width
/// (perceptual roughness squared); `v` points from the surface towards the viewer. Evaluated in
/// f64 with `ggx_d`, so it stays finite down to the narrowest lobe a material may have.
#[inline]
pub fn ggx_cosine(n: Vec3, v: Vec3, l: Vec3, alpha: f32) -> f32 {
    GgxAt::new(n, v, alpha).cosine(l)
}

/// [`ggx_cosine`] at one point seen from one direction, with what does not depend on the light's
/// direction worked out once: a bake evaluates the lobe towards thousands of texels from each
/// point. The same numbers, to the bit, as [`ggx_cosine`] (which is this, made for one call).
#[derive(Clone, Copy, Debug)]
pub struct GgxAt {
    n: DVec3,
    v: DVec3,
    nv: f64,
    a2: f64,
    /// `G1(v)`.
    g1_v: f64,
}

impl GgxAt {
    /// The lobe of width `alpha` at a point with unit normal `n`, seen along `v` (towards the
    /// viewer).
    #[inline]
    pub fn new(n: Vec3, v: Vec3, alpha: f32) -> GgxAt {
        let (n, v) = (n.as_dvec3(), v.as_dvec3());
        let nv = n.dot(v);
        let a2 = (alpha as f64).powi(2);
        GgxAt {
            n,
            v,
            nv,
            a2,
            g1_v: smith_g1(a2, nv),
        }
    }

    /// `f(l, v) · max(0, n·l)` towards the unit direction `l`, per unit of specular colour.
    #[inline]
    pub fn cosine(&self, l: Vec3) -> f32 {
        self.cosine_f64(l.as_dvec3()) as f32
    }

    /// [`GgxAt::cosine`] towards many unit directions, given by coordinate (`x[i]`, `y[i]`,
    /// `z[i]`), into `out[i]`: the same numbers to the bit, in a loop without branches that
    /// the compiler runs several directions at a time.
    #[inline(always)]
    pub fn cosines(&self, [x, y, z]: [&[f32]; 3], out: &mut [f32]) {
        for (((o, &x), &y), &z) in out.iter_mut().zip(x).zip(y).zip(z) {
            *o = self.cosine_f64(Vec3::new(x, y, z).as_dvec3()) as f32;
        }
    }

    /// The lobe towards `l` in f64, worked out whatever the direction and then zeroed below
    /// the surface, so that it has no branch.
    #[inline(always)]
    fn cosine_f64(&self, l: DVec3) -> f64 {
        let nl = self.n.dot(l);
        let d = ggx_d(self.n, l + self.v, self.a2);
        let value = d * smith_g1(self.a2, nl) * self.g1_v / (4.0 * self.nv);
        if nl > 0.0 && self.nv > 0.0 {
            value
        } else {
            0.0
        }
    }
}

/// Smith's separable shadowing term of a GGX lobe with `a2 = α²`, for a direction at cosine `c`
/// to the normal.
#[inline]
fn smith_g1(a2: f64, c: f64) -> f64 {
    2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt())
}

/// A cosine-distributed direction about `n` from two uniform numbers: pdf `max(0, n·l) / π`.
#[inline]
pub fn sample_cosine(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let (t, b) = n.any_orthonormal_pair();
    let (r, phi) = (u1.sqrt(), 2.0 * std::f32::consts::PI * u2);
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize()
}

/// The GGX distribution of microfacet normals, `D(h) = α² / (π (α² cos²θh + sin²θh)²)`, for a
/// half vector `h` of any length about unit `n` (0 below the surface or for `h = 0`), with
/// `a2 = α²`. The sine comes from `|n × h|`, not as `1 − cos²θh`: at roughness 0.02
/// (α² = 1.6e-7, under 3 ulps of 1 in f32) that difference rounds to 0 and D to infinity.
/// Worked out whatever `h`, then zeroed where it does not hold, without a branch.
#[inline(always)]
fn ggx_d(n: DVec3, h: DVec3, a2: f64) -> f64 {
    let c = n.dot(h);
    let den = (a2 * c * c + n.cross(h).length_squared()) / h.length_squared();
    if c > 0.0 && den > 0.0 {
        a2 / (std::f64::consts::PI * den * den)
    } else {
        0.0
    }
}

/// A direction reflected about a microfacet normal drawn from `D(h) (n·h)`; its density over
/// directions is [`ggx_pdf`]. `None` when it points below the surface.
#[inline]
pub fn sample_ggx(n: Vec3, v: Vec3, alpha: f32, u1: f32, u2: f32) -> Option<Vec3> {
    let (local, _) = ggx_half_vector(alpha, u1, u2);
    let (t, b) = n.any_orthonormal_pair();
    let (n, v) = (n.as_dvec3(), v.as_dvec3());
    let h = t.as_dvec3() * local.x + b.as_dvec3() * local.y + n * local.z;
    let l = h * (2.0 * v.dot(h)) - v;
    (n.dot(l) > 0.0).then(|| l.normalize().as_vec3())
}

/// The microfacet normal [`sample_ggx`] draws from two uniform numbers, in the frame of the
/// normal (x and y along [`Vec3::any_orthonormal_pair`], z the normal), and `D(h)` there.
#[inline]
pub fn ggx_half_vector(alpha: f32, u1: f32, u2: f32) -> (DVec3, f64) {
    // cos²θh = (1 − u) / (1 − u + α² u) and sin²θh = α² u / (1 − u + α² u), neither taken as a
    // difference of numbers near 1, in f64.
    let (a2, u) = ((alpha as f64).powi(2), (u1 as f64).clamp(0.0, 1.0));
    let den = (1.0 - u) + a2 * u;
    let (cos2, sin2) = if den > 0.0 {
        ((1.0 - u) / den, a2 * u / den)
    } else {
        (1.0, 0.0)
    };
    let (ct, st) = (cos2.sqrt(), sin2.sqrt());
    let phi = std::f64::consts::TAU * u2 as f64;
    let d = a2 / (std::f64::consts::PI * (a2 * cos2 + sin2).powi(2));
    (DVec3::new(st * phi.cos(), st * phi.sin(), ct), d)
}

/// Density over directions of [`sample_ggx`]: `D(h) (n·h) / (4 |v·h|)`, in f64 as
/// [`ggx_cosine`].
#[inline]
pub fn ggx_pdf(n: Vec3, v: Vec3, l: Vec3, alpha: f32) -> f32 {
    let (n, v, l) = (n.as_dvec3(), v.as_dvec3(), l.as_dvec3());
    let h = l + v;
    let len = h.length();
    if len <= 0.0 || n.dot(l) <= 0.0 {
        return 0.0;
    }
    let (vh, nh) = (v.dot(h).abs() / len, n.dot(h) / len);
    if vh <= 0.0 || nh <= 0.0 {
        return 0.0;
    }
    (ggx_d(n, h, (alpha as f64).powi(2)) * nh / (4.0 * vh)) as f32
}

/// A material's lobes at a shading point, for tracing paths: evaluation, and sampling by a
/// mixture of cosine and GGX importance (one-sample multiple importance sampling with the
/// balance heuristic, so the weight is `f cos` over the mixture's density and stays bounded
/// where either lobe dominates).
#[derive(Clone, Copy, Debug)]
pub struct Lobes {
    /// Linear RGB reflectance of the Lambertian lobe.
    pub albedo: Vec3,
    /// Linear RGB reflectance of the GGX lobe; zero for a diffuse material.
    pub specular: Vec3,
    /// GGX width; unused when `specular` is zero.
    pub alpha: f32,
}

/// [`Lobes`] at one point seen from one direction ([`Lobes::at`]): [`Lobes::eval_cosine`] for many
/// light directions, with the GGX lobe's share of the work that does not depend on them done once.
#[derive(Clone, Copy, Debug)]
pub struct LobesAt {
    albedo: Vec3,
    specular: Vec3,
    n: Vec3,
    ggx: Option<GgxAt>,
}

impl LobesAt {
    /// `f(l, v) · max(0, n·l)` per colour channel.
    #[inline]
    pub fn eval_cosine(&self, l: Vec3) -> Vec3 {
        let mut f = self.albedo * diffuse_cosine(self.n, l);
        if let Some(g) = &self.ggx {
            f += self.specular * g.cosine(l);
        }
        f
    }
}

/// A sampled direction, `f cos / pdf` per colour channel, and the pdf.
#[derive(Clone, Copy, Debug)]
pub struct LobeSample {
    /// The sampled direction, unit length, above the surface.
    pub dir: Vec3,
    /// `f cos / pdf` per colour channel.
    pub weight: Vec3,
    /// Density of the sampling mixture at `dir`, per steradian.
    pub pdf: f32,
}

impl Lobes {
    /// The lobes of a material.
    pub fn of(m: &crate::scene::Material) -> Lobes {
        let (specular, alpha) = m.glossy_lobe().unwrap_or((Vec3::ZERO, 1.0));
        Lobes {
            albedo: m.albedo(),
            specular,
            alpha,
        }
    }

    /// Probability of drawing from the GGX lobe: its share of the reflectance (largest channel).
    #[inline]
    fn glossy_share(&self) -> f32 {
        let (a, s) = (self.albedo.max_element(), self.specular.max_element());
        if s <= 0.0 { 0.0 } else { s / (a + s) }
    }

    /// `f(l, v) · max(0, n·l)` per colour channel.
    #[inline]
    pub fn eval_cosine(&self, n: Vec3, v: Vec3, l: Vec3) -> Vec3 {
        self.at(n, v).eval_cosine(l)
    }

    /// These lobes at a point with unit normal `n` seen along `v`, for many directions.
    #[inline]
    pub fn at(&self, n: Vec3, v: Vec3) -> LobesAt {
        LobesAt {
            albedo: self.albedo,
            specular: self.specular,
            n,
            ggx: (self.specular != Vec3::ZERO).then(|| GgxAt::new(n, v, self.alpha)),
        }
    }

    /// Density over directions of [`Lobes::sample`].
    #[inline]
    pub fn pdf(&self, n: Vec3, v: Vec3, l: Vec3) -> f32 {
        let q = self.glossy_share();
        let mut p = (1.0 - q) * diffuse_cosine(n, l);
        if q > 0.0 {
            p += q * ggx_pdf(n, v, l, self.alpha);
        }
        p
    }

    /// Draws a direction from three uniform numbers; `None` when the draw leaves the upper
    /// hemisphere (the path ends: that probability carries no light).
    #[inline]
    pub fn sample(&self, n: Vec3, v: Vec3, u: [f32; 3]) -> Option<LobeSample> {
        let q = self.glossy_share();
        let dir = if u[0] < q {
            sample_ggx(n, v, self.alpha, u[1], u[2])?
        } else {
            sample_cosine(n, u[1], u[2])
        };
        let pdf = self.pdf(n, v, dir);
        if pdf <= 1e-12 || n.dot(dir) <= 1e-6 {
            return None;
        }
        Some(LobeSample {
            dir,
            weight: self.eval_cosine(n, v, dir) / pdf,
            pdf,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Lambertian lobe's albedo by the midpoint rule of `albedo`: the integrand is linear in
    /// cos θ and constant in φ, which the rule integrates exactly, so only the f32 evaluation of
    /// 1.44 million samples (summed in f64) remains.
    const LAMBERT_QUADRATURE: f64 = 1e-4;
    /// GGX at roughness one, seen head-on, by the 2000 x 720 midpoint rule of `albedo` against
    /// the closed form 1 − ln 2: the lobe is broad and smooth at α = 1, so the rule's error is
    /// small; this leaves room for it and for the lobe's f32 evaluation.
    const GGX_CLOSED_FORM: f64 = 1e-3;
    /// The GGX density integrated by `albedo` against the share of 200,000 draws kept: the share
    /// is binomial, with a standard deviation of at most √(0.25 / 200,000) ≈ 1.1e-3, so this is
    /// about 4.5 of them, plus the quadrature's small error.
    const KEPT_SHARE_NOISE: f64 = 5e-3;
    /// How far a GGX lobe's albedo by `albedo` may rise above 1 in the white furnace: the lobe
    /// never reflects more than it receives, but the 2000 x 720 midpoint rule errs on a lobe as
    /// narrow as roughness 0.25 (α = 0.0625); this is the slack the check gives it.
    const FURNACE_QUADRATURE: f64 = 2e-3;
    /// The same rule's slack over the head-on albedo's bound 1 − α²/(1 + α²), at roughness 0.25,
    /// 0.5 and 0.8.
    const HEAD_ON_BOUND_QUADRATURE: f64 = 1e-3;
    /// f(l, v) against f(v, l) at one pair of directions, relative: the same f32 expression with
    /// the two directions swapped, so a few ulps of rounding.
    const RECIPROCITY_F32: f32 = 1e-5;
    /// The mixture's density evaluated at a drawn direction against the density the draw
    /// reported, relative: `sample` reports `pdf` of the same direction, so at most rounding.
    const DRAWN_PDF_F32: f32 = 1e-5;
    /// The mean of f cos / pdf over 400,000 draws against the quadrature's albedo, relative: the
    /// weights' spread over √400,000 ≈ 632 (Monte Carlo noise) plus the quadrature's own error...
    const SAMPLED_ALBEDO_NOISE: f64 = 6e-3;
    /// ...with the albedo taken at least this large, so that a dim lobe is still allowed
    /// `SAMPLED_ALBEDO_NOISE` of it as an absolute bound.
    const SAMPLED_ALBEDO_FLOOR: f64 = 0.1;

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

    /// The GGX lobe written with early returns, as a branch for each case that gives 0: the
    /// slow twin of [`GgxAt::cosines`] and its branch-free arithmetic.
    fn ggx_with_branches(n: Vec3, v: Vec3, l: Vec3, alpha: f32) -> f32 {
        let (n, v, l) = (n.as_dvec3(), v.as_dvec3(), l.as_dvec3());
        let (nv, nl, a2) = (n.dot(v), n.dot(l), (alpha as f64).powi(2));
        if nl <= 0.0 || nv <= 0.0 {
            return 0.0;
        }
        let h = l + v;
        let c = n.dot(h);
        if c <= 0.0 {
            return 0.0;
        }
        let den = (a2 * c * c + n.cross(h).length_squared()) / h.length_squared();
        if den <= 0.0 {
            return 0.0;
        }
        let d = a2 / (std::f64::consts::PI * den * den);
        (d * smith_g1(a2, nl) * smith_g1(a2, nv) / (4.0 * nv)) as f32
    }

    /// Many directions at once give each direction's lobe to the bit, as the formula with
    /// branches does: above and below the surface, at the mirror direction, straight back
    /// along the view (h = 0), for views above, at and below the horizon, from the narrowest
    /// lobe to the widest.
    #[test]
    fn lobes_in_bulk_equal_the_lobe_with_branches() {
        let mut rng = crate::test_support::Rng::new(5);
        let n = Vec3::new(0.3, 0.9, -0.2).normalize();
        for alpha in [4e-4f32, 0.0625, 0.3, 1.0] {
            for view in 0..40 {
                let v = if view == 0 {
                    n.any_orthonormal_vector()
                } else {
                    rng.unit_vector()
                };
                let mirror = (n * (2.0 * n.dot(v)) - v).normalize();
                let mut dirs: Vec<Vec3> = (0..200).map(|_| rng.unit_vector()).collect();
                dirs.extend([mirror, -v, n, -n]);
                let coords: [Vec<f32>; 3] =
                    std::array::from_fn(|k| dirs.iter().map(|d| d[k]).collect());
                let mut bulk = vec![f32::NAN; dirs.len()];
                let ggx = GgxAt::new(n, v, alpha);
                ggx.cosines([&coords[0], &coords[1], &coords[2]], &mut bulk);
                for (l, got) in dirs.iter().zip(&bulk) {
                    let want = ggx_with_branches(n, v, *l, alpha);
                    assert_eq!(got.to_bits(), want.to_bits(), "α {alpha}, v {v}, l {l}");
                    assert_eq!(ggx.cosine(*l).to_bits(), want.to_bits());
                }
            }
        }
    }

    #[test]
    fn lambertian_lobe_integrates_to_one() {
        let e = albedo(|l| diffuse_cosine(Vec3::Z, l));
        assert!((e - 1.0).abs() < LAMBERT_QUADRATURE, "{e}");
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
                    e <= 1.0 + FURNACE_QUADRATURE,
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
                        assert!(
                            e <= 1.0 - lost as f64 + HEAD_ON_BOUND_QUADRATURE,
                            "{e} above {}",
                            1.0 - lost
                        );
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
        assert!((e - want).abs() < GGX_CLOSED_FORM, "{e} vs {want}");
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
        assert!(
            (f_lv - f_vl).abs() < RECIPROCITY_F32 * f_lv.abs(),
            "{f_lv} vs {f_vl}"
        );
        let mirror = Vec3::new(-0.6, 0.0, 0.8);
        assert!(ggx_cosine(n, v, mirror, alpha) > ggx_cosine(n, v, l, alpha));
        assert_eq!(ggx_cosine(n, v, -mirror, alpha), 0.0);
    }

    #[test]
    fn lobe_sampling_is_unbiased_for_the_directional_albedo() {
        // E[f cos / pdf] over the mixture's draws equals ∫ f cos dω, the quadrature's value, for
        // a matte and two glossy materials, seen head-on and at a grazing angle. (The quadrature
        // resolves lobes down to roughness 0.3; a narrower one falls between its rings.)
        use crate::math::sampling::Rng;
        for (base, specular, roughness) in
            [(0.7f32, 0.0f32, 1.0f32), (0.5, 0.4, 0.4), (0.2, 0.7, 0.3)]
        {
            let lobes = Lobes {
                albedo: Vec3::splat(base),
                specular: Vec3::splat(specular),
                alpha: roughness * roughness,
            };
            for view_deg in [0.0f32, 70.0] {
                let t = view_deg.to_radians();
                let v = Vec3::new(t.sin(), 0.0, t.cos());
                let want = albedo(|l| lobes.eval_cosine(Vec3::Z, v, l).x);
                let mut rng = Rng::new(3, view_deg as u64);
                let count = 400_000;
                let mut sum = 0.0f64;
                for _ in 0..count {
                    let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                    if let Some(s) = lobes.sample(Vec3::Z, v, u) {
                        sum += s.weight.x as f64;
                        let p = lobes.pdf(Vec3::Z, v, s.dir);
                        assert!((p - s.pdf).abs() <= DRAWN_PDF_F32 * p, "{p} vs {}", s.pdf);
                    }
                }
                let got = sum / count as f64;
                assert!(
                    (got - want).abs() < SAMPLED_ALBEDO_NOISE * want.max(SAMPLED_ALBEDO_FLOOR),
                    "albedo {base}, specular {specular}, roughness {roughness}, view \
                     {view_deg}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn the_narrowest_lobe_samples_and_evaluates_to_finite_values() {
        // Roughness 0.02 (α² = 1.6e-7): head-on views, views along an axis, grazing views and
        // random ones, for a pure GGX lobe and a glTF dielectric's; every value finite, and the
        // head-on mirror's sampled albedo about one (Smith shadowing is nil there).
        use crate::math::sampling::Rng;
        let alpha = crate::scene::MIN_ROUGHNESS * crate::scene::MIN_ROUGHNESS;
        let pure = Lobes {
            albedo: Vec3::ZERO,
            specular: Vec3::ONE,
            alpha,
        };
        let dielectric = crate::scene::TexturedMaterial::lobes_of(Vec3::splat(0.5), 0.0, 0.0);
        assert_eq!(dielectric.alpha, alpha);
        let mut dirs = crate::test_support::Rng::new(11);
        let mut rng = Rng::new(7, 0);
        let (mut head_on, mut head_on_draws) = (0.0f64, 0usize);
        for k in 0..2000 {
            let n = if k < 4 {
                Vec3::Z
            } else {
                dirs.unit_vector().normalize()
            };
            let v = match k % 4 {
                0 | 1 => n,
                2 => {
                    let (t, _) = n.any_orthonormal_pair();
                    (t + n * 1e-4).normalize()
                }
                _ => {
                    let d = dirs.unit_vector().normalize();
                    if d.dot(n) < 0.0 { -d } else { d }
                }
            };
            for lobes in [pure, dielectric] {
                for _ in 0..50 {
                    let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                    let l = dirs.unit_vector().normalize();
                    let (f, p) = (lobes.eval_cosine(n, v, l), lobes.pdf(n, v, l));
                    assert!(
                        f.is_finite() && p.is_finite(),
                        "f {f}, pdf {p} at {n} {v} {l}"
                    );
                    let Some(s) = lobes.sample(n, v, u) else {
                        continue;
                    };
                    assert!(
                        s.dir.is_finite() && s.weight.is_finite() && s.pdf.is_finite(),
                        "{s:?} at {n} {v}"
                    );
                    if k % 4 < 2 && lobes.albedo == Vec3::ZERO {
                        head_on += s.weight.x as f64;
                        head_on_draws += 1;
                    }
                }
            }
        }
        let mean = head_on / head_on_draws as f64;
        assert!(
            (mean - 1.0).abs() < 1e-2,
            "{mean} over {head_on_draws} draws"
        );
    }

    #[test]
    fn ggx_pdf_integrates_to_the_share_of_draws_above_the_surface() {
        // The density of sample_ggx integrates to one over the sphere of reflected directions;
        // over the upper hemisphere it gives the fraction of draws that are kept.
        use crate::math::sampling::Rng;
        let (n, alpha) = (Vec3::Z, 0.3f32);
        let v = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let integral = albedo(|l| ggx_pdf(n, v, l, alpha));
        let mut rng = Rng::new(5, 0);
        let count = 200_000;
        let kept = (0..count)
            .filter(|_| sample_ggx(n, v, alpha, rng.next_f32(), rng.next_f32()).is_some())
            .count() as f64
            / count as f64;
        assert!(
            (integral - kept).abs() < KEPT_SHARE_NOISE,
            "{integral} vs {kept}"
        );
    }
}
