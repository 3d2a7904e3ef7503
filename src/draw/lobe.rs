//! The glossy lobe of a per-vertex bake evaluated per pixel: for the pixel's interpolated normal
//! and its own direction to the eye, `∫ L(ω) V(ω) f(ω, v) cos θ dω` of the material's GGX lobe,
//! against the pyramid of the light the relight used and the vertices' visibility bits
//! ([`Visibility`]) interpolated across the triangle. One impl of the raster's
//! [`ViewDependent`].
//!
//! The integral is taken by filtered importance sampling (Colbert & Křivánek 2007): a fixed set of
//! `M` stratified directions drawn from the lobe, each reading the light and the visible share at
//! the pyramid level whose node is about its footprint `1 / (M · pdf)`, between two levels
//! linearly. A sharp lobe reads single texels (the light is a cube of constant texels, so it is
//! then the integral itself, sampled); a broad one reads coarse nodes, which carry its tail,
//! bilinearly between the nodes about the direction ([`CubePyramid::bilinear`]) so that a bright
//! light's coarse nodes spread as tents about it, not as squares. The pattern is the same at
//! every pixel, so a highlight is smooth, not noisy.

use glam::{DVec3, Vec3};

use crate::draw::shading::{GlossMesh, ViewDependent, interpolated_normal};
use crate::error::{PrtError, Result};
use crate::math::cube_pyramid::{CubePyramid, FacePoint};
use crate::math::cubemap::texel_count;
use crate::scene::brdf::ggx_half_vector;
use crate::scene::visibility::{Visibility, open_shares};

pub mod lights;
pub use lights::{LitColumn, lit_columns};

/// Lobe directions a pixel takes unless asked otherwise. Against the brute-force integral over
/// the same texels of a smooth light with half the sky shut (the tests), 32 directions are
/// within 3.1%, 2.5% and 5.5% at α = 0.04, 0.2 and 0.5, 64 within 1.2%, 2.7% and 2.5%, 128
/// within 0.6%, 1.4% and 1.3%; a light of one texel 40 times the rest is sampled worse (5–16%
/// at 128 directions for the broad lobes, 56% at 64 for α = 0.5), as the lobe alone steers the
/// directions.
pub const DEFAULT_LOBE_SAMPLES: usize = 64;

/// Lobe directions a pixel takes for a GGX lobe of width `alpha`: [`DEFAULT_LOBE_SAMPLES`] below
/// α = 0.1 (roughness 0.32), twice that below α = 0.2 (roughness 0.45), four times beyond. A
/// broad lobe steered by itself alone misses a small bright light between its directions: the
/// glossy sphere at roughness 0.5 under the studio was 13.5–13.8% from the path tracer with 64
/// directions and 7.8–8.7% with 256, while a sharp one is within 1.2% of the brute-force
/// integral at 64 (the tests) and its frame would only slow.
pub fn lobe_samples_for(alpha: f32) -> usize {
    match alpha {
        a if a < 0.1 => DEFAULT_LOBE_SAMPLES,
        a if a < 0.2 => 2 * DEFAULT_LOBE_SAMPLES,
        _ => 4 * DEFAULT_LOBE_SAMPLES,
    }
}

/// Lobe directions a pixel takes for each material of a bake with visibility, as its lobe's
/// width asks ([`lobe_samples_for`]); 0 for a diffuse material. A sharp material keeps its few
/// directions beside a broad one, on the CPU and the GPU alike.
pub fn lobe_samples(visibility: &Visibility) -> Vec<usize> {
    (0..visibility.lobes.len() as u32)
        .map(|m| {
            visibility
                .lobe(m)
                .map_or(0, |(_, alpha)| lobe_samples_for(alpha))
        })
        .collect()
}

/// The fixed pattern of `m` points in the unit square: rows stratified in `u1`, the base-2
/// radical inverse in `u2` (a Hammersley set).
pub fn lobe_pattern(m: usize) -> Vec<[f32; 2]> {
    (0..m)
        .map(|i| {
            let u2 = (i as u32).reverse_bits() as f64 / 4_294_967_296.0;
            [((i as f64 + 0.5) / m as f64) as f32, u2 as f32]
        })
        .collect()
}

/// What a glossy per-vertex bake with visibility adds to a draw: each glossy vertex's
/// visibility with the materials' GGX lobes, and the light's pyramid.
#[derive(Clone, Debug)]
pub struct Lobe<'a> {
    /// The mesh's normals, materials and visibility.
    pub gloss: GlossMesh<'a>,
    /// The light, as the relight used it.
    pub light: &'a CubePyramid,
    /// Per material, the half vectors of its pattern ([`lobe_pattern`]) for its α (`None` for a
    /// diffuse material).
    taps: Vec<Option<TapTable>>,
    /// Each vertex's position, where local lights are drawn (empty without them).
    positions: &'a [Vec3],
    /// The local light columns whose highlights are drawn ([`Lobe::with_lights`]).
    lights: Vec<LitColumn>,
}

/// The taps of one GGX width, a table a component, so that a pixel's first pass over them (the
/// half vector turned into the pixel's frame, the direction it reflects the eye to, its weight)
/// runs several side by side.
#[derive(Clone, Debug, Default)]
struct TapTable {
    /// The half vectors' x, y and z in the frame of the normal.
    h: [Vec<f32>; 3],
    /// `D(h) (n·h)` of each.
    d_nh: Vec<f64>,
}

impl TapTable {
    fn of(taps: &[Tap]) -> TapTable {
        TapTable {
            h: [0, 1, 2].map(|k| taps.iter().map(|t| t.h[k]).collect()),
            d_nh: taps.iter().map(|t| t.d_nh).collect(),
        }
    }

    fn len(&self) -> usize {
        self.d_nh.len()
    }
}

/// Taps a pixel turns at once, in its first pass ([`TapTable`]).
const TAP_BLOCK: usize = 64;

/// One direction of the pattern for one GGX width: the half vector in the frame of the normal
/// (x and y along [`Vec3::any_orthonormal_pair`], z the normal), as
/// [`crate::scene::brdf::sample_ggx`] draws it, and `D(h) (n·h)`, which its density over
/// directions divides by `4 (v·h)`.
#[derive(Clone, Copy, Debug)]
struct Tap {
    h: Vec3,
    d_nh: f64,
}

/// The taps of `pattern` for GGX width `alpha`, in f64 as [`crate::scene::brdf`] evaluates.
fn taps(alpha: f32, pattern: &[[f32; 2]]) -> Vec<Tap> {
    pattern
        .iter()
        .map(|&[u1, u2]| {
            let (h, d) = ggx_half_vector(alpha, u1, u2);
            Tap {
                h: h.as_vec3(),
                d_nh: d * h.z,
            }
        })
        .collect()
}

/// The taps of [`lobe_pattern`]`(samples)` for GGX width `alpha` as the GPU raster reads them:
/// the half vector in the normal's frame, then `D(h) (n·h)`.
pub fn lobe_taps(alpha: f32, samples: usize) -> Vec<[f32; 4]> {
    taps(alpha, &lobe_pattern(samples))
        .iter()
        .map(|t| [t.h.x, t.h.y, t.h.z, t.d_nh as f32])
        .collect()
}

impl<'a> Lobe<'a> {
    /// The lobe of a mesh's vertices under `light`, with `samples` directions a pixel for every
    /// material.
    pub fn new(gloss: GlossMesh<'a>, light: &'a CubePyramid, samples: usize) -> Lobe<'a> {
        let counts = vec![samples; gloss.visibility.lobes.len()];
        Lobe::with_counts(gloss, light, &counts)
    }

    /// The lobe of a mesh's vertices under `light`, each material with the directions its
    /// width asks for ([`lobe_samples`]): what a draw takes.
    pub fn of_widths(gloss: GlossMesh<'a>, light: &'a CubePyramid) -> Lobe<'a> {
        let counts = lobe_samples(gloss.visibility);
        Lobe::with_counts(gloss, light, &counts)
    }

    /// The lobe with `counts[m]` directions a pixel for material m.
    fn with_counts(gloss: GlossMesh<'a>, light: &'a CubePyramid, counts: &[usize]) -> Lobe<'a> {
        let visibility = gloss.visibility;
        let taps = (0..visibility.lobes.len() as u32)
            .zip(counts)
            .map(|(m, &k)| {
                visibility
                    .lobe(m)
                    .map(|(_, alpha)| TapTable::of(&taps(alpha, &lobe_pattern(k))))
            })
            .collect();
        Lobe {
            gloss,
            light,
            taps,
            positions: &[],
            lights: Vec::new(),
        }
    }

    /// The lobe with the highlights of local light columns `lights` too, at the mesh's vertex
    /// `positions` ([`lights`]).
    pub fn with_lights(self, positions: &'a [Vec3], lights: Vec<LitColumn>) -> Lobe<'a> {
        Lobe {
            positions,
            lights,
            ..self
        }
    }

    /// Whether no local light's highlight is drawn.
    pub fn is_unlit(&self) -> bool {
        self.lights.is_empty()
    }

    /// `light · open share` about the lobe direction `l` at fractional level `x` (clamped to the
    /// pyramids' levels), between the two levels about it: the light of the texel that holds
    /// `l`, or above the texels bilinear within a level; the open share of the node that holds
    /// `l`.
    #[inline]
    fn read(&self, l: DVec3, x: f64, rows: &[Option<&[u32]>; 3], b: [f64; 3]) -> DVec3 {
        let (nl, nv) = (self.light.n, self.gloss.visibility.n);
        let at_l = FacePoint::of(l);
        let ml = at_l.morton(nl);
        let mv = if nv == nl { ml } else { at_l.morton(nv) };
        let top = self.light.levels.len() - 1;
        let x = x.clamp(0.0, top as f64);
        // x is not negative, so truncation is its floor (without a call to the C library's).
        let lo = x as usize;
        let at = |level: usize| {
            // The texels are the light itself, constant over each; a coarser node's mean is
            // the light filtered by the node, read about `l` itself.
            let light = match level {
                0 => self.light.mean(ml, 0),
                _ => self.light.bilinear(at_l, level),
            };
            let light = DVec3::from(light.map(f64::from));
            // The visibility cube may be coarser or finer than the light's: its level is the
            // one of the same texel size.
            let vl = (level + nv.trailing_zeros() as usize)
                .saturating_sub(nl.trailing_zeros() as usize)
                .min(nv.trailing_zeros() as usize);
            let shares = open_shares(rows, mv, vl);
            let open: f64 = (0..3).map(|i| b[i] * shares[i] as f64).sum();
            light * open
        };
        let f = x - lo as f64;
        if f > 0.0 && lo < top {
            at(lo) * (1.0 - f) + at(lo + 1) * f
        } else {
            at(lo)
        }
    }
}

impl ViewDependent for Lobe<'_> {
    /// Checks the mesh's tables ([`GlossMesh::check`]) and the lobe's directions.
    fn check(&self, vertices: usize) -> Result<()> {
        self.gloss.check(vertices)?;
        if !self.lights.is_empty() && self.positions.len() != vertices {
            let positions = self.positions.len();
            let why = format!("{positions} positions for the local lights of {vertices} vertices");
            return Err(PrtError::invalid("gloss", why));
        }
        if self.taps.iter().flatten().any(|t| t.len() == 0) {
            return Err(PrtError::invalid(
                "gloss",
                "a glossy material without lobe directions",
            ));
        }
        Ok(())
    }

    /// The glossy light of a point of triangle `tri` at barycentrics `b`, seen along `to_eye`:
    /// each tap's direction `l = 2 (v·h) h − v` weighed by `f cos / pdf`, which for GGX is
    /// `G1(l) G1(v) (v·h) / ((n·v) (n·h))`.
    fn shade(&self, tri: [u32; 3], b: [f64; 3], to_eye: DVec3) -> DVec3 {
        let Some(at) = self.point(tri, b, to_eye) else {
            return DVec3::ZERO;
        };
        let Point {
            specular,
            alpha,
            taps,
            n,
            v,
            nv,
        } = at;
        let rows = tri.map(|v| self.gloss.visibility.row(v as usize));
        let a2 = alpha * alpha;
        let g1 = |c: f32| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
        let g1v = g1(nv);
        let (t, s) = n.any_orthonormal_pair();
        let count = taps.len() as f64;
        // A level-0 node's mean solid angle; a level-k node is 4^k of them.
        let texel = 4.0 * std::f64::consts::PI / texel_count(self.light.n) as f64;
        let mut sum = DVec3::ZERO;
        let mut l = [Vec3::ZERO; TAP_BLOCK];
        let (mut weight, mut vh) = ([0.0f32; TAP_BLOCK], [0.0f32; TAP_BLOCK]);
        for start in (0..taps.len()).step_by(TAP_BLOCK) {
            let end = (start + TAP_BLOCK).min(taps.len());
            let [hx, hy, hz] = [0, 1, 2].map(|k| &taps.h[k][start..end]);
            // The block's directions side by side; a tap whose half vector faces away from the
            // eye, or whose direction lies below the surface, weighs nothing.
            for i in 0..end - start {
                let h = t * hx[i] + s * hy[i] + n * hz[i];
                let d = v.dot(h);
                let li = h * (2.0 * d) - v;
                let nl = n.dot(li);
                let w = g1(nl) * g1v * d / (nv * hz[i]);
                (l[i], vh[i]) = (li, d);
                weight[i] = if d > 0.0 && nl > 0.0 { w } else { 0.0 };
            }
            for i in 0..end - start {
                if weight[i] == 0.0 {
                    continue;
                }
                // The footprint 1 / (M · pdf), pdf = D (n·h) / (4 v·h).
                let footprint = 4.0 * vh[i] as f64 / (count * taps.d_nh[start + i]);
                let x = 0.5 * (footprint / texel).log2();
                sum += self.read(l[i].as_dvec3(), x, &rows, b) * weight[i] as f64;
            }
        }
        let env = specular.as_dvec3() * sum / count;
        if self.lights.is_empty() {
            return env;
        }
        env + self.lights_at(&at, tri, b)
    }
}

/// What the lobe's light at a point of a triangle starts from ([`Lobe::point`]).
#[derive(Clone, Copy)]
struct Point<'t> {
    /// The material's specular colour and GGX width, and its taps.
    specular: Vec3,
    alpha: f32,
    taps: &'t TapTable,
    /// The unit interpolated normal, the unit direction to the eye, and their cosine.
    n: Vec3,
    v: Vec3,
    nv: f32,
}

impl Lobe<'_> {
    /// The lobe at a point of triangle `tri` at barycentrics `b` seen along `to_eye`: `None`
    /// where it has no glossy light (a diffuse material, a normal that vanishes, the eye below
    /// the surface).
    #[inline(always)]
    fn point(&self, tri: [u32; 3], b: [f64; 3], to_eye: DVec3) -> Option<Point<'_>> {
        let m = self.gloss.materials[tri[0] as usize];
        let (specular, alpha) = self.gloss.visibility.lobe(m)?;
        let taps = self.taps.get(m as usize)?.as_ref()?;
        let n = interpolated_normal(self.gloss.normals, tri, b)?.as_vec3();
        let v = to_eye.as_vec3();
        let nv = n.dot(v);
        (nv > 0.0).then_some(Point {
            specular,
            alpha,
            taps,
            n,
            v,
            nv,
        })
    }

    /// The local lights' highlights alone at a point of triangle `tri` at barycentrics `b`
    /// seen along `to_eye`, without the environment's lobe: what another glossy method (SH
    /// glossy transfer) adds them with ([`lights::WithLights`]).
    pub fn shade_lights(&self, tri: [u32; 3], b: [f64; 3], to_eye: DVec3) -> DVec3 {
        match self.point(tri, b, to_eye) {
            Some(at) if !self.lights.is_empty() => self.lights_at(&at, tri, b),
            _ => DVec3::ZERO,
        }
    }

    /// The local lights' highlights at point `at` of triangle `tri` (barycentrics `b`).
    fn lights_at(&self, at: &Point, tri: [u32; 3], b: [f64; 3]) -> DVec3 {
        let p = (0..3)
            .map(|i| self.positions[tri[i] as usize].as_dvec3() * b[i])
            .sum::<DVec3>()
            .as_vec3();
        let surface = lights::Surface {
            p,
            n: at.n,
            v: at.v,
            alpha: at.alpha,
        };
        at.specular.as_dvec3() * self.local_lights(tri, b, surface, at.taps)
    }
}

#[cfg(test)]
pub(crate) mod tests;
