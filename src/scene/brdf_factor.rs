//! The in-out factorisation of a material's BRDF: `ρ(ωi, ωo) cos θi ≈ Σ_k g_k(ωo) h_k(ωi)` in the
//! local shading frame (normal +z), the separable form that lets a per-vertex bake keep glossy
//! light under a moving camera (Liu et al. 2004; Wang, Tran & Luebke 2004).
//!
//! Both directions are parameterised by a hemi-octahedral map of `res × res` cells. The GGX lobe
//! is sampled into a matrix over (view cell, light cell), each entry the lobe at the view cell's
//! centre averaged over 4 × 4 light directions inside the light cell, and weighted by the square
//! roots of both cells' solid angles, so that the truncated SVD ([`crate::math::svd`]) minimises
//! the L2 error over the sphere of directions rather than over the map. The factors are the
//! singular vectors with that weight divided out: `g_k` carries the singular value.
//!
//! A material's Lambertian lobe is rank 1 (it does not depend on ωo), so it is kept exact as one
//! term of its own; a glossy material's K_b terms are that term and K_b − 1 GGX terms. The factor
//! error of K_b terms follows from the singular values (Eckart–Young) without rebuilding.

use glam::Vec3;
use rayon::prelude::*;

use crate::math::svd;
use crate::scene::brdf::ggx_cosine;

/// Light directions averaged per light cell, per side.
const SUPERSAMPLE: usize = 4;

/// A hemi-octahedral map of the directions with z ≥ 0: cell (i, j) of `res × res`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HemiOct {
    /// Cells per side.
    pub res: usize,
}

impl HemiOct {
    /// The direction at map coordinates `(u, v)` in [-1, 1]².
    pub fn decode(u: f32, v: f32) -> Vec3 {
        let (x, y) = ((u + v) * 0.5, (u - v) * 0.5);
        Vec3::new(x, y, (1.0 - x.abs() - y.abs()).max(0.0)).normalize()
    }

    /// The map coordinates in [-1, 1]² of `d` (its z clamped to the upper hemisphere).
    pub fn encode(d: Vec3) -> (f32, f32) {
        let d = Vec3::new(d.x, d.y, d.z.max(0.0));
        let p = d / (d.x.abs() + d.y.abs() + d.z).max(1e-20);
        (p.x + p.y, p.x - p.y)
    }

    /// Cells in the map.
    pub fn cells(&self) -> usize {
        self.res * self.res
    }

    /// The map coordinates of point `(a, b)` of cell `c`, `a` and `b` in [0, 1].
    fn at(&self, c: usize, a: f32, b: f32) -> (f32, f32) {
        let (i, j) = (c % self.res, c / self.res);
        let s = 2.0 / self.res as f32;
        (-1.0 + (i as f32 + a) * s, -1.0 + (j as f32 + b) * s)
    }

    /// The direction at the centre of cell `c`.
    pub fn centre(&self, c: usize) -> Vec3 {
        let (u, v) = self.at(c, 0.5, 0.5);
        Self::decode(u, v)
    }

    /// The solid angle of cell `c`: its corners' two spherical triangles (Van Oosterom &
    /// Strackee 1983), summed over 2 × 2 sub-cells.
    pub fn solid_angle(&self, c: usize) -> f64 {
        let tri = |a: Vec3, b: Vec3, c: Vec3| -> f64 {
            let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
            let num = a.dot(b.cross(c)).abs();
            let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
            2.0 * num.atan2(den)
        };
        let mut sum = 0.0;
        for (a0, b0) in [(0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5)] {
            let corner = |da: f32, db: f32| {
                let (u, v) = self.at(c, a0 + da, b0 + db);
                Self::decode(u, v)
            };
            let (p00, p10, p01, p11) = (
                corner(0.0, 0.0),
                corner(0.5, 0.0),
                corner(0.0, 0.5),
                corner(0.5, 0.5),
            );
            sum += tri(p00, p10, p11) + tri(p00, p11, p01);
        }
        sum
    }

    /// Bilinear lookup of `map` (one value per cell, cell centres at the samples) at `d`.
    pub fn lookup(&self, map: &[f32], d: Vec3) -> f32 {
        let (u, v) = Self::encode(d);
        let n = self.res;
        let coord = |x: f32| -> (usize, usize, f32) {
            let t = ((x + 1.0) * 0.5 * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            let i = (t as usize).min(n.saturating_sub(2));
            ((i), (i + 1).min(n - 1), t - i as f32)
        };
        let (i0, i1, fx) = coord(u);
        let (j0, j1, fy) = coord(v);
        let at = |i: usize, j: usize| map[j * n + i];
        let lerp = |a: f32, b: f32, f: f32| a + (b - a) * f;
        lerp(
            lerp(at(i0, j0), at(i1, j0), fx),
            lerp(at(i0, j1), at(i1, j1), fx),
            fy,
        )
    }
}

/// The cosine-weighted GGX lobe of width `alpha` over (view cell, light cell) of `map`, each
/// entry at the view cell's centre and averaged over the light cell's 4 × 4 directions, row-major
/// by view cell; and the Lambertian lobe `cos θi / π` per light cell, averaged the same way.
fn sampled(map: HemiOct, alpha: f32) -> (Vec<f64>, Vec<f64>) {
    let cells = map.cells();
    let lights: Vec<Vec<Vec3>> = (0..cells)
        .map(|c| {
            (0..SUPERSAMPLE * SUPERSAMPLE)
                .map(|s| {
                    let a = ((s % SUPERSAMPLE) as f32 + 0.5) / SUPERSAMPLE as f32;
                    let b = ((s / SUPERSAMPLE) as f32 + 0.5) / SUPERSAMPLE as f32;
                    let (u, v) = map.at(c, a, b);
                    HemiOct::decode(u, v)
                })
                .collect()
        })
        .collect();
    let inv = 1.0 / (SUPERSAMPLE * SUPERSAMPLE) as f64;
    let diffuse = lights
        .iter()
        .map(|dirs| {
            dirs.iter().map(|d| d.z.max(0.0) as f64).sum::<f64>()
                * inv
                * std::f64::consts::FRAC_1_PI
        })
        .collect();
    let lobe = (0..cells)
        .into_par_iter()
        .flat_map_iter(|o| {
            let view = map.centre(o);
            lights.iter().map(move |dirs| {
                dirs.iter()
                    .map(|l| ggx_cosine(Vec3::Z, view, *l, alpha) as f64)
                    .sum::<f64>()
                    * inv
            })
        })
        .collect();
    (lobe, diffuse)
}

/// The factorisation of the cosine-weighted GGX lobe of one width.
#[derive(Clone, Debug)]
pub struct GgxFactors {
    /// GGX width α (roughness²).
    pub alpha: f32,
    /// The map both directions are parameterised by.
    pub map: HemiOct,
    /// Singular values, largest first.
    pub values: Vec<f64>,
    /// `g_k` over the view map, singular value included.
    pub view: Vec<Vec<f32>>,
    /// `h_k` over the light map.
    pub light: Vec<Vec<f32>>,
    /// The weighted lobe's squared norm: the sum of all its squared singular values.
    energy: f64,
    /// Its inner product with the Lambertian lobe `cos θi / π`, and that lobe's squared norm.
    with_diffuse: f64,
    diffuse_energy: f64,
}

impl GgxFactors {
    /// Factorises the lobe of width `alpha` on `res × res` maps, keeping `terms` terms.
    pub fn new(alpha: f32, res: usize, terms: usize) -> GgxFactors {
        let map = HemiOct { res };
        let cells = map.cells();
        let omega: Vec<f64> = (0..cells).map(|c| map.solid_angle(c)).collect();
        let root: Vec<f64> = omega.iter().map(|o| o.sqrt()).collect();
        let (lobe, diffuse) = sampled(map, alpha);
        let (mut energy, mut with_diffuse, mut diffuse_energy) = (0.0, 0.0, 0.0);
        let mut matrix = vec![0.0f64; cells * cells];
        for o in 0..cells {
            for i in 0..cells {
                let w = root[o] * root[i];
                let (f, d) = (lobe[o * cells + i] * w, diffuse[i] * w);
                matrix[o * cells + i] = f;
                energy += f * f;
                with_diffuse += f * d;
                diffuse_energy += d * d;
            }
        }
        let svd = svd::leading(&matrix, cells, cells, terms, 7);
        let view = svd
            .left
            .iter()
            .zip(&svd.values)
            .map(|(u, s)| {
                u.iter()
                    .zip(&root)
                    .map(|(x, r)| (x * s / r) as f32)
                    .collect()
            })
            .collect();
        let light = svd
            .right
            .iter()
            .map(|v| v.iter().zip(&root).map(|(x, r)| (x / r) as f32).collect())
            .collect();
        GgxFactors {
            alpha,
            map,
            values: svd.values,
            view,
            light,
            energy,
            with_diffuse,
            diffuse_energy,
        }
    }

    /// Terms kept.
    pub fn terms(&self) -> usize {
        self.values.len()
    }

    /// The lobe's relative L2 error with its first `k` terms (1 with none).
    pub fn error(&self, k: usize) -> f64 {
        let kept: f64 = self.values.iter().take(k).map(|s| s * s).sum();
        ((self.energy - kept).max(0.0) / self.energy.max(1e-300)).sqrt()
    }

    /// The relative L2 error of a material's whole lobe `albedo · cos/π + specular · GGX` (two
    /// scalar weights, e.g. luminances) with `k_b` terms: the Lambertian term exact and
    /// `k_b − 1` GGX terms.
    pub fn material_error(&self, albedo: f64, specular: f64, k_b: usize) -> f64 {
        if k_b == 0 {
            return 1.0;
        }
        let whole = albedo * albedo * self.diffuse_energy
            + 2.0 * albedo * specular * self.with_diffuse
            + specular * specular * self.energy;
        let left = specular * specular * self.error(k_b - 1).powi(2) * self.energy;
        (left / whole.max(1e-300)).sqrt()
    }

    /// The fewest terms K_b (at most the terms kept plus the Lambertian one) that bring a
    /// material's lobe within `target` relative error.
    pub fn terms_for(&self, albedo: f64, specular: f64, target: f64) -> usize {
        (1..=self.terms() + 1)
            .find(|&k| self.material_error(albedo, specular, k) <= target)
            .unwrap_or(self.terms() + 1)
    }

    /// The lobe rebuilt from its first `k` terms at a view and light direction of the local
    /// frame (normal +z).
    pub fn eval(&self, k: usize, view: Vec3, light: Vec3) -> f32 {
        if view.z <= 0.0 || light.z <= 0.0 {
            return 0.0;
        }
        (0..k.min(self.terms()))
            .map(|j| self.map.lookup(&self.view[j], view) * self.map.lookup(&self.light[j], light))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_map_covers_the_hemisphere_once() {
        let map = HemiOct { res: 16 };
        let total: f64 = (0..map.cells()).map(|c| map.solid_angle(c)).sum();
        assert!((total - 2.0 * std::f64::consts::PI).abs() < 1e-4, "{total}");
        for c in 0..map.cells() {
            let d = map.centre(c);
            assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-5);
            let (u, v) = HemiOct::encode(d);
            let back = HemiOct::decode(u, v);
            assert!((back - d).length() < 1e-5, "cell {c}");
        }
    }

    #[test]
    fn a_diffuse_material_is_exact_with_one_term() {
        let f = GgxFactors::new(0.3 * 0.3, 8, 4);
        assert_eq!(f.material_error(0.8, 0.0, 1), 0.0);
        assert_eq!(f.terms_for(0.8, 0.0, 1e-6), 1);
    }

    #[test]
    fn the_error_falls_with_the_terms_and_rougher_lobes_need_fewer() {
        let f = GgxFactors::new(0.3 * 0.3, 8, 8);
        for k in 1..=8 {
            assert!(
                f.error(k) < f.error(k - 1),
                "{k}: {} {}",
                f.error(k),
                f.error(k - 1)
            );
        }
        let rough = GgxFactors::new(0.8 * 0.8, 8, 8);
        for k in 1..=8 {
            assert!(rough.error(k) < f.error(k), "{k}");
        }
        // A glossy material's whole lobe: its Lambertian term alone leaves the GGX lobe's part.
        assert!(f.material_error(0.5, 0.5, 1) > f.material_error(0.5, 0.5, 5));
        assert!(f.material_error(0.5, 0.5, 1) < 1.0);
    }

    #[test]
    fn the_stored_factors_rebuild_the_lobe_to_the_stated_error() {
        // At the cell centres the bilinear lookups return the stored samples, so the rebuilt
        // lobe's solid-angle-weighted error against the sampled lobe is the stated one
        // (Eckart–Young): this checks the singular values, the vectors and the weights divided
        // out of them together.
        let alpha = 0.5 * 0.5;
        let f = GgxFactors::new(alpha, 8, 6);
        let map = f.map;
        let cells = map.cells();
        let (lobe, _) = sampled(map, alpha);
        for k in [1, 3, 6] {
            let (mut err, mut norm) = (0.0f64, 0.0f64);
            for o in 0..cells {
                for i in 0..cells {
                    let (v, l) = (map.centre(o), map.centre(i));
                    let w = map.solid_angle(o) * map.solid_angle(i);
                    let want = lobe[o * cells + i];
                    err += w * (f.eval(k, v, l) as f64 - want).powi(2);
                    norm += w * want * want;
                }
            }
            let rebuilt = (err / norm).sqrt();
            assert!(
                (rebuilt - f.error(k)).abs() < 1e-4,
                "{k} terms: rebuilt {rebuilt}, stated {}",
                f.error(k)
            );
        }
    }
}
