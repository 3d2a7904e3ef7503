//! The local lights' highlights on a glossy per-vertex bake, per pixel: for each lit light
//! column, `∫ f cos L dω` of the material's GGX lobe over the light at the pixel's point, for
//! its interpolated normal and its own direction to the eye, times the share of the light its
//! triangle's vertices see ([`crate::scene::visibility::Visibility::light_share`],
//! interpolated) and the column's weight. The light columns hold a glossy vertex's diffuse
//! response alone; this is the rest.
//!
//! A delta light (a point, a spot, a sun without a disc) is one direction. A sized one (a quad, a
//! sun's disc) is a fixed 4 x 4 grid of the light's own samples and the lobe's own directions
//! (its pattern, as the environment's lobe takes it) that reach the light, weighed by the power
//! heuristic (Veach 1997), as the bake weighs its light samples: a broad lobe under a small light
//! converges through the light's samples, a sharp lobe under a large light through its own
//! directions, which draw the light's outline in the highlight. The pattern is the same at
//! every pixel, so a highlight is smooth, not noisy.

use glam::{DVec3, Vec3};

use super::{Lobe, TapTable};
use crate::draw::shading::ViewDependent;
use crate::scene::Light;
use crate::scene::brdf::{GgxAt, ggx_pdf};
use crate::scene::light::{Emitter, emitters};

/// Samples of a sized light along each side of its grid.
pub const LIGHT_GRID: usize = 4;

/// One light column the draw lights: its emitter at unit intensity, its RGB weight (the
/// relight's [`crate::scene::light_mix::LightMix`]) and its index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LitColumn {
    /// The column's light, placed, at unit intensity.
    pub emitter: Emitter,
    /// What multiplies it: colour times intensity times the column's share of a blend.
    pub weight: Vec3,
    /// Its index among the bake's columns.
    pub column: usize,
}

/// The light columns of `lights` (a bake's, in column order) whose `weights` (one per column;
/// fewer are zero) are not zero.
pub fn lit_columns(lights: &[Light], weights: &[[f32; 3]]) -> Vec<LitColumn> {
    emitters(lights)
        .into_iter()
        .zip(weights)
        .enumerate()
        .filter(|(_, (_, w))| w.iter().any(|v| *v != 0.0))
        .map(|(column, (emitter, &w))| LitColumn {
            emitter,
            weight: Vec3::from(w),
            column,
        })
        .collect()
}

/// Another view-dependent light (SH glossy transfer's) with the local lights' highlights of
/// `lights` added, so that a glossy method toggled against the lobe keeps the lamps' highlights.
pub struct WithLights<'a, G> {
    /// The glossy light of the environment.
    pub base: G,
    /// The lobe whose local lights are added ([`Lobe::shade_lights`]).
    pub lights: Lobe<'a>,
}

impl<G: ViewDependent> ViewDependent for WithLights<'_, G> {
    /// Checks both.
    fn check(&self, vertices: usize) -> crate::error::Result<()> {
        self.base.check(vertices)?;
        self.lights.check(vertices)
    }

    /// The base's light and the local lights' highlights.
    fn shade(&self, tri: [u32; 3], b: [f64; 3], to_eye: DVec3) -> DVec3 {
        self.base.shade(tri, b, to_eye) + self.lights.shade_lights(tri, b, to_eye)
    }
}

/// A point of a triangle seen from the eye, as the lobe shades it: where it is, its unit
/// normal, its unit direction to the eye, and the lobe's width.
#[derive(Clone, Copy, Debug)]
pub(super) struct Surface {
    pub(super) p: Vec3,
    pub(super) n: Vec3,
    pub(super) v: Vec3,
    pub(super) alpha: f32,
}

/// The power heuristic's weight of a sample of density `own` against one of density `other`,
/// each already times its strategy's sample count.
#[inline]
fn mis(own: f64, other: f64) -> f64 {
    let (a, b) = (own * own, other * other);
    if a + b > 0.0 { a / (a + b) } else { 0.0 }
}

impl Lobe<'_> {
    /// The lit columns' highlight at point `at` of triangle `tri` (barycentrics `b`), per unit
    /// of specular colour, with `taps` the material's lobe directions.
    pub(super) fn local_lights(
        &self,
        tri: [u32; 3],
        b: [f64; 3],
        at: Surface,
        taps: &TapTable,
    ) -> DVec3 {
        let ggx = GgxAt::new(at.n, at.v, at.alpha);
        let mut sum = DVec3::ZERO;
        for lit in &self.lights {
            let share: f64 = (0..3)
                .map(|i| {
                    b[i] * self
                        .gloss
                        .visibility
                        .light_share(tri[i] as usize, lit.column) as f64
                })
                .sum();
            if share <= 0.0 {
                continue;
            }
            let e = &lit.emitter;
            let h = if e.is_delta() {
                e.sample(at.p, [0.5, 0.5])
                    .filter(|s| at.n.dot(s.dir) > 0.0)
                    .map_or(0.0, |s| ggx.cosine(s.dir) as f64 * s.weight as f64)
            } else {
                sized(e, at, &ggx, taps)
            };
            sum += lit.weight.as_dvec3() * (h * share);
        }
        sum
    }
}

/// `∫ f cos L dω` of sized emitter `e` at `at` (unit specular colour): its grid of samples and
/// the lobe's `taps` that reach it, under the power heuristic.
fn sized(e: &Emitter, at: Surface, ggx: &GgxAt, taps: &TapTable) -> f64 {
    let Surface { p, n, v, alpha } = at;
    let (lights, own) = ((LIGHT_GRID * LIGHT_GRID) as f64, taps.len() as f64);
    let mut acc = 0.0;
    for k in 0..LIGHT_GRID * LIGHT_GRID {
        let u = [k % LIGHT_GRID, k / LIGHT_GRID].map(|i| (i as f32 + 0.5) / LIGHT_GRID as f32);
        let Some(s) = e.sample(p, u).filter(|s| n.dot(s.dir) > 0.0) else {
            continue;
        };
        let f = ggx.cosine(s.dir) as f64;
        if f > 0.0 {
            let brdf = ggx_pdf(n, v, s.dir, alpha) as f64;
            acc += f * s.weight as f64 * mis(lights * s.pdf as f64, own * brdf) / lights;
        }
    }
    // The lobe's directions, turned into the normal's frame as the environment's lobe turns
    // them, weighed by `f cos / pdf`: `G1(l) G1(v) (v·h) / ((n·v) (n·h))`.
    let a2 = alpha * alpha;
    let g1 = |c: f32| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
    let (t, s) = n.any_orthonormal_pair();
    let nv = n.dot(v);
    for k in 0..taps.len() {
        let hz = taps.h[2][k];
        let h = t * taps.h[0][k] + s * taps.h[1][k] + n * hz;
        let d = v.dot(h);
        let l = h * (2.0 * d) - v;
        let nl = n.dot(l);
        if d <= 0.0 || nl <= 0.0 {
            continue;
        }
        let Some((_, radiance, light_pdf)) = e.hit(p, l) else {
            continue;
        };
        let weight = (g1(nl) * g1(nv) * d / (nv * hz)) as f64;
        // The lobe's density of `l`: D (n·h) / (4 v·h).
        let brdf = taps.d_nh[k] / (4.0 * d as f64);
        acc += weight * radiance as f64 * mis(own * brdf, lights * light_pdf as f64) / own;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draw::lobe::tests::glossy;
    use crate::math::cube_pyramid::CubePyramid;
    use crate::math::cubemap::CubeMap;
    use crate::scene::brdf::ggx_cosine;
    use crate::scene::visibility::Visibility;

    /// Face size of the (dark) environment and the visibility.
    const N: usize = 8;

    /// A small triangle about the origin facing +Y, its vertices' normals, and barycentrics at
    /// its centre.
    const POSITIONS: [Vec3; 3] = [
        Vec3::new(-0.01, 0.0, -0.01),
        Vec3::new(0.01, 0.0, -0.01),
        Vec3::new(0.0, 0.0, 0.01),
    ];
    const CENTRE: [f64; 3] = [1.0 / 3.0; 3];

    /// Three glossy vertices of width `alpha`, every texel open, each seeing `share` of one
    /// light column.
    fn open(alpha: f32, share: f32) -> Visibility {
        let words = Visibility::words(N);
        let lobes = vec![[1.0, 1.0, 1.0, alpha]];
        Visibility::new(N, 3, vec![0, 1, 2], vec![u32::MAX; 3 * words], lobes)
            .unwrap()
            .with_light_shares(1, vec![share; 3])
            .unwrap()
    }

    /// The lobe's light at the triangle's centre along `to_eye` from `emitter` alone (the
    /// environment dark), at unit weight.
    fn highlight(emitter: Emitter, alpha: f32, share: f32, to_eye: DVec3) -> DVec3 {
        let vis = open(alpha, share);
        let dark = CubePyramid::new(&CubeMap::constant(N, [0.0; 3]).unwrap()).unwrap();
        let normals = [Vec3::Y; 3];
        let lit = vec![LitColumn {
            emitter,
            weight: Vec3::ONE,
            column: 0,
        }];
        let lobe =
            Lobe::of_widths(glossy(&normals, &[0, 0, 0], &vis), &dark).with_lights(&POSITIONS, lit);
        lobe.check(3).unwrap();
        lobe.shade([0, 1, 2], CENTRE, to_eye)
    }

    fn centre() -> Vec3 {
        (POSITIONS[0] + POSITIONS[1] + POSITIONS[2]) / 3.0
    }

    /// GGX's `f cos` written out from its definition (Walter et al. 2007), in f64: the
    /// distribution, Smith's separable masking and `1 / (4 (n·l)(n·v))`, times `n·l`.
    fn ggx_by_hand(n: DVec3, v: DVec3, l: DVec3, alpha: f64) -> f64 {
        let h = (v + l).normalize();
        let a2 = alpha * alpha;
        let c = n.dot(h);
        let d = a2 / (std::f64::consts::PI * (c * c * (a2 - 1.0) + 1.0).powi(2));
        let g1 = |x: f64| 2.0 * x / (x + (a2 + (1.0 - a2) * x * x).sqrt());
        let (nl, nv) = (n.dot(l), n.dot(v));
        d * g1(nl) * g1(nv) / (4.0 * nl * nv) * nl
    }

    #[test]
    fn a_point_lights_highlight_is_the_lobe_towards_it_over_the_distance_squared() {
        let v = DVec3::new(0.6, 0.8, 0.0);
        let p = centre().as_dvec3();
        for (alpha, offset) in [(0.04, 0.02), (0.2, 0.3), (0.5, -0.4)] {
            // Near the mirror direction, a little off it.
            let to = DVec3::new(-0.6, 0.8, offset).normalize();
            let position = p + to * 2.0;
            let point = Emitter::Point {
                position: position.as_vec3(),
            };
            let got = highlight(point, alpha, 1.0, v);
            let l = (position - p).normalize();
            let want = ggx_by_hand(DVec3::Y, v, l, alpha as f64) / (position - p).length_squared();
            assert!(
                (got.x / want - 1.0).abs() < 1e-4,
                "α = {alpha}: {got} against {want}"
            );
            assert!(got.x == got.y && got.y == got.z);
            // A vertex that sees a quarter of the light gives a quarter of its highlight.
            let quarter = highlight(point, alpha, 0.25, v);
            assert!(
                (quarter.x / got.x - 0.25).abs() < 1e-9,
                "{quarter} against {got}"
            );
        }
        // Below the surface, or outside a spot's cone, there is none.
        let below = Emitter::Point {
            position: Vec3::new(-1.0, -0.5, 0.0),
        };
        assert_eq!(highlight(below, 0.2, 1.0, v), DVec3::ZERO);
        let away = Emitter::Spot {
            position: Vec3::new(-1.2, 1.6, 0.0),
            axis: Vec3::Y,
            cos_outer: 0.9,
            cos_inner: 0.95,
        };
        assert_eq!(highlight(away, 0.2, 1.0, v), DVec3::ZERO);
    }

    /// A square of side `size` at distance `dist` from the triangle's centre along `towards`,
    /// facing it.
    fn square(towards: DVec3, dist: f64, size: f64) -> [Vec3; 4] {
        let w = towards.normalize();
        let (a, b) = w.any_orthonormal_pair();
        let c = centre().as_dvec3() + w * dist;
        let h = 0.5 * size;
        // Wound so that the emitting side faces back along `towards`.
        [(-h, -h), (-h, h), (h, h), (h, -h)].map(|(x, y)| (c + a * x + b * y).as_vec3())
    }

    /// `∫ f cos L dω` over the quad by its area, `g²` cells, each its centre's `f cos cos_l / r²`.
    fn brute_force(corners: [Vec3; 4], v: DVec3, alpha: f32, g: usize) -> f64 {
        let [c0, c1, _, c3] = corners.map(|c| c.as_dvec3());
        let (e1, e3) = (c1 - c0, c3 - c0);
        let normal = e1.cross(e3).normalize();
        let cell = e1.cross(e3).length() / (g * g) as f64;
        let p = centre().as_dvec3();
        let mut sum = 0.0;
        for i in 0..g {
            for j in 0..g {
                let q =
                    c0 + e1 * ((i as f64 + 0.5) / g as f64) + e3 * ((j as f64 + 0.5) / g as f64);
                let d = q - p;
                let l = d.normalize();
                let cos_light = normal.dot(-l).abs();
                let f = ggx_cosine(Vec3::Y, v.as_vec3(), l.as_vec3(), alpha) as f64;
                sum += f * cos_light / d.length_squared() * cell;
            }
        }
        sum
    }

    #[test]
    fn a_quad_lights_highlight_reaches_the_brute_force_integral_over_its_area() {
        let v = DVec3::new(0.6, 0.8, 0.0);
        // The quad about the mirror direction, wholly within a sharp lobe's reach or cut by it,
        // and off to the side where a broad lobe's tail meets it.
        for (alpha, towards, size, within) in [
            (0.04, DVec3::new(-0.6, 0.8, 0.0), 1.0, 0.005),
            (0.04, DVec3::new(-0.6, 0.8, 0.12), 0.3, 0.05),
            (0.2, DVec3::new(-0.6, 0.8, 0.1), 0.5, 0.03),
            (0.5, DVec3::new(-0.2, 0.8, 0.5), 0.4, 0.03),
        ] {
            let corners = square(towards, 1.5, size);
            let got = highlight(Emitter::quad(corners), alpha, 1.0, v).x;
            let want = brute_force(corners, v, alpha, 1024);
            let e = (got / want - 1.0).abs();
            println!("α = {alpha}, towards {towards}, side {size}: {got} against {want} ({e:.4})");
            assert!(
                want > 0.0 && e < within,
                "α = {alpha}: {got} against {want}"
            );
        }
    }
}
