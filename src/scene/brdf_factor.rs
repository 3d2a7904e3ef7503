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
        Taps::read(map, &self.taps(d))
    }

    /// The cells and weights a bilinear lookup at `d` reads: found once for a direction, read
    /// from every map of this size.
    pub fn taps(&self, d: Vec3) -> Taps {
        let (u, v) = Self::encode(d);
        let n = self.res;
        let coord = |x: f32| -> (usize, usize, f32) {
            let t = ((x + 1.0) * 0.5 * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            let i = (t as usize).min(n.saturating_sub(2));
            ((i), (i + 1).min(n - 1), t - i as f32)
        };
        let (i0, i1, fx) = coord(u);
        let (j0, j1, fy) = coord(v);
        Taps {
            cells: [j0 * n + i0, j0 * n + i1, j1 * n + i0, j1 * n + i1],
            fx,
            fy,
        }
    }
}

/// Where a bilinear lookup of a [`HemiOct`] map reads ([`HemiOct::taps`]): the cells at the
/// corners (row-major: the lower row's two, then the upper row's) and the weights across and up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Taps {
    cells: [usize; 4],
    fx: f32,
    fy: f32,
}

impl Taps {
    /// `map` read at these taps.
    #[inline]
    pub fn read(map: &[f32], t: &Taps) -> f32 {
        let lerp = |a: f32, b: f32, f: f32| a + (b - a) * f;
        let [a, b, c, d] = t.cells.map(|i| map[i]);
        lerp(lerp(a, b, t.fx), lerp(c, d, t.fx), t.fy)
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
        // Each term's sign is free: make its view factor's mean positive, so that the first
        // term is the lobe's positive average.
        let (mut view, mut light): (Vec<Vec<f32>>, Vec<Vec<f32>>) = (view, light);
        for (g, h) in view.iter_mut().zip(&mut light) {
            if g.iter().map(|&x| x as f64).sum::<f64>() < 0.0 {
                g.iter_mut().chain(h.iter_mut()).for_each(|x| *x = -*x);
            }
        }
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

/// The local shading frame of a unit normal `n`, as `(tangent, bitangent)`: the world's +X and −Z
/// turned by the shortest rotation that takes +Y to `n`, so that `(tangent, bitangent, n)` is
/// right-handed. A per-vertex bake takes `h_k` and the raster takes `g_k` in this frame, so both
/// sides build it here (and the GPU's WGSL with the same formula). It turns continuously with the
/// normal everywhere but at `n = −Y`, the undersides that face straight down, where it is +X and
/// +Z within 0.01 rad of the pole.
pub fn local_frame(n: Vec3) -> (Vec3, Vec3) {
    let c = 1.0 + n.y;
    let t = if c > 5e-5 {
        Vec3::new(n.y + n.z * n.z / c, -n.x, -n.x * n.z / c)
    } else {
        Vec3::X
    };
    (t, n.cross(t))
}

/// `d` in the local frame of normal `n` ([`local_frame`]), the normal along +z.
#[inline]
pub fn to_local(n: Vec3, d: Vec3) -> Vec3 {
    let (t, b) = local_frame(n);
    Vec3::new(d.dot(t), d.dot(b), d.dot(n))
}

/// Map cells per side of a bake's factor maps (the 32² octahedral maps).
pub const BAKE_MAP_RES: usize = 32;

/// The most terms K_b a material is baked with per vertex.
pub const MAX_TERMS: usize = 16;

/// The in-out factors a per-vertex bake keeps of each material: K_b per material (1 for a diffuse
/// one, whose Lambertian lobe is term 0), and for terms `1..K_b` the GGX factors `g_k` (view) and
/// `h_k` (light) on one hemi-octahedral map. A vertex's terms are the pixels
/// `v · stride + k` of the relit image, `stride` the smallest power of two that holds every
/// material's K_b, so that a tile of pixels holds whole vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct BrdfFactors {
    /// The map both factors are parameterised by.
    pub map: HemiOct,
    /// Pixels a vertex takes in the relit image: a power of two, at least every K_b.
    pub stride: usize,
    /// K_b of each material.
    pub terms: Vec<u32>,
    /// `g_k` of material `m` and term `k` (1 ≤ k < stride) at `[(m · (stride − 1) + k − 1) ·
    /// cells ..][..cells]`: singular value included, zero past the material's K_b.
    pub view: Vec<f32>,
    /// `h_k`, laid out as `view`.
    pub light: Vec<f32>,
}

impl BrdfFactors {
    /// The factors of `materials` for a per-vertex bake: each glossy material takes `max_terms`
    /// terms, or the fewest of those that bring its whole lobe within `target` (relative L2 of
    /// the luminances' lobe, see [`GgxFactors::material_error`]; 0 takes `max_terms`). `None`
    /// when no material takes more than one term: the bake is the diffuse base.
    pub fn for_materials(
        materials: &[crate::scene::Material],
        max_terms: usize,
        target: f64,
    ) -> Option<BrdfFactors> {
        let max_terms = max_terms.clamp(1, MAX_TERMS);
        let map = HemiOct { res: BAKE_MAP_RES };
        let luminance = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722)) as f64;
        let mut by_alpha: Vec<(u32, GgxFactors)> = Vec::new();
        let mut chosen: Vec<(u32, Option<usize>)> = Vec::new();
        for m in materials {
            let Some((specular, alpha)) = m.glossy_lobe().filter(|_| max_terms > 1) else {
                chosen.push((1, None));
                continue;
            };
            let slot = match by_alpha.iter().position(|(a, _)| *a == alpha.to_bits()) {
                Some(i) => i,
                None => {
                    let f = GgxFactors::new(alpha, map.res, max_terms - 1);
                    by_alpha.push((alpha.to_bits(), f));
                    by_alpha.len() - 1
                }
            };
            let f = &by_alpha[slot].1;
            let k_b = if target > 0.0 {
                f.terms_for(luminance(m.albedo()), luminance(specular), target)
            } else {
                max_terms
            }
            .min(f.terms() + 1);
            chosen.push((k_b as u32, Some(slot)));
        }
        let widest = chosen.iter().map(|c| c.0).max().unwrap_or(1) as usize;
        if widest <= 1 {
            return None;
        }
        let stride = widest.next_power_of_two();
        let cells = map.cells();
        let mut view = vec![0.0f32; materials.len() * (stride - 1) * cells];
        let mut light = view.clone();
        for (m, (k_b, slot)) in chosen.iter().enumerate() {
            let Some(f) = slot.map(|s| &by_alpha[s].1) else {
                continue;
            };
            for k in 1..*k_b as usize {
                let at = (m * (stride - 1) + k - 1) * cells;
                view[at..at + cells].copy_from_slice(&f.view[k - 1]);
                light[at..at + cells].copy_from_slice(&f.light[k - 1]);
            }
        }
        Some(BrdfFactors {
            map,
            stride,
            terms: chosen.iter().map(|c| c.0).collect(),
            view,
            light,
        })
    }

    /// K_b of material `m` (1 past the table).
    #[inline]
    pub fn terms_of(&self, m: u32) -> usize {
        self.terms.get(m as usize).map_or(1, |&k| k as usize)
    }

    fn slice<'a>(&self, table: &'a [f32], m: u32, k: usize) -> &'a [f32] {
        let cells = self.map.cells();
        let at = (m as usize * (self.stride - 1) + k - 1) * cells;
        &table[at..at + cells]
    }

    /// `g_k` of material `m` (1 ≤ k < its K_b) at a local view direction; 0 below the horizon.
    #[inline]
    pub fn view_at(&self, m: u32, k: usize, local: Vec3) -> f32 {
        if local.z <= 0.0 {
            return 0.0;
        }
        self.view_with(m, k, &self.map.taps(local))
    }

    /// `g_k` of material `m` (1 ≤ k < its K_b) read at `taps` of a direction above the horizon:
    /// one direction's taps serve every term.
    #[inline]
    pub fn view_with(&self, m: u32, k: usize, taps: &Taps) -> f32 {
        Taps::read(self.slice(&self.view, m, k), taps)
    }

    /// `h_k` of material `m` (1 ≤ k < its K_b) at a local light direction; 0 below the horizon.
    #[inline]
    pub fn light_at(&self, m: u32, k: usize, local: Vec3) -> f32 {
        if local.z <= 0.0 {
            return 0.0;
        }
        self.light_with(m, k, &self.map.taps(local))
    }

    /// `h_k` of material `m` read at `taps`, as [`BrdfFactors::view_with`].
    #[inline]
    pub fn light_with(&self, m: u32, k: usize, taps: &Taps) -> f32 {
        Taps::read(self.slice(&self.light, m, k), taps)
    }

    /// The largest `|g_k|` of material `m`: what an error in the term's response is multiplied
    /// by at most when drawn.
    pub fn view_peak(&self, m: u32, k: usize) -> f32 {
        self.slice(&self.view, m, k)
            .iter()
            .fold(0.0f32, |a, v| a.max(v.abs()))
    }

    /// What is wrong with the factors for `materials` materials, if anything: the stride a power
    /// of two from 2 to [`MAX_TERMS`], a K_b from 1 to the stride per material, tables of the
    /// right length and finite.
    pub fn problem(&self, materials: usize) -> Option<String> {
        let s = self.stride;
        if !(2..=MAX_TERMS).contains(&s) || !s.is_power_of_two() {
            return Some(format!(
                "factor stride {s}; it must be a power of two from 2 to {MAX_TERMS}"
            ));
        }
        if !(1..=64).contains(&self.map.res) {
            return Some(format!("factor map of {} cells a side", self.map.res));
        }
        if self.terms.len() != materials {
            return Some(format!(
                "{} materials' terms for {materials} materials",
                self.terms.len()
            ));
        }
        if let Some(m) = self.terms.iter().position(|&k| k == 0 || k as usize > s) {
            return Some(format!(
                "material {m} has {} terms; 1 to {s} fit",
                self.terms[m]
            ));
        }
        let len = materials * (s - 1) * self.map.cells();
        for (name, table) in [("view", &self.view), ("light", &self.light)] {
            if table.len() != len {
                return Some(format!("{name} factors hold {}, not {len}", table.len()));
            }
            if let Some(i) = table.iter().position(|v| !v.is_finite()) {
                return Some(format!("{name} factor {i} is {}", table[i]));
            }
        }
        None
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
    fn the_local_frame_is_orthonormal_right_handed_and_turns_smoothly() {
        let mut rng = crate::math::sampling::Rng::new(3, 0);
        for _ in 0..2000 {
            let (z, phi) = (
                2.0 * rng.next_f32() - 1.0,
                std::f32::consts::TAU * rng.next_f32(),
            );
            let r = (1.0 - z * z).max(0.0).sqrt();
            let n = Vec3::new(r * phi.cos(), z, r * phi.sin());
            let (t, b) = local_frame(n);
            for (x, y) in [(t, b), (t, n), (b, n)] {
                assert!(x.dot(y).abs() < 1e-5, "{n}: {x} {y}");
            }
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
            assert!((t.cross(b) - n).length() < 1e-5, "{n}");
            // A normal turned by 0.001 rad turns the frame about as little, away from −Y.
            if n.y > -0.9 {
                let m = (n + n.any_orthonormal_vector() * 1e-3).normalize();
                let (u, _) = local_frame(m);
                assert!((u - t).length() < 1e-2, "{n}: {t} -> {u}");
            }
            // The frame of +Y is the world's.
        }
        assert_eq!(local_frame(Vec3::Y), (Vec3::X, Vec3::new(0.0, 0.0, -1.0)));
        assert_eq!(local_frame(Vec3::NEG_Y).0, Vec3::X);
        let d = Vec3::new(0.3, 0.5, -0.2);
        let n = Vec3::new(0.1, 0.9, 0.3).normalize();
        assert!((to_local(n, n) - Vec3::Z).length() < 1e-6);
        assert!((to_local(n, d).length() - d.length()).abs() < 1e-6);
    }

    #[test]
    fn a_bake_keeps_factors_of_glossy_materials_only() {
        use crate::scene::Material;
        let matte = Material::Diffuse {
            albedo: Vec3::splat(0.5),
        };
        let glossy = Material::Glossy {
            albedo: Vec3::splat(0.2),
            specular: Vec3::splat(0.5),
            roughness: 0.5,
        };
        assert!(BrdfFactors::for_materials(&[matte, matte], 4, 0.0).is_none());
        assert!(BrdfFactors::for_materials(&[matte, glossy], 1, 0.0).is_none());
        let f = BrdfFactors::for_materials(&[matte, glossy], 3, 0.0).unwrap();
        assert_eq!((f.stride, f.terms.clone()), (4, vec![1, 3]));
        assert_eq!(f.problem(2), None);
        assert_eq!(f.terms_of(0), 1);
        assert_eq!(f.terms_of(7), 1);
        // The matte material's maps and the glossy one's past its K_b stay zero.
        let cells = f.map.cells();
        assert!(f.view[..3 * cells].iter().all(|&v| v == 0.0));
        assert!(f.view[5 * cells..].iter().all(|&v| v == 0.0));
        assert!(f.view[3 * cells..4 * cells].iter().any(|&v| v != 0.0));
        assert!(f.view_peak(1, 1) > 0.0);
        // An error target takes the fewest terms that reach it.
        let g = GgxFactors::new(0.25, BAKE_MAP_RES, 7);
        let target = g.material_error(0.2, 0.5, 3) * 1.001;
        let lax = BrdfFactors::for_materials(&[matte, glossy], 8, target).unwrap();
        let strict = BrdfFactors::for_materials(&[matte, glossy], 8, 0.01).unwrap();
        assert_eq!((lax.terms[1], lax.stride), (3, 4));
        assert_eq!((strict.terms[1], strict.stride), (8, 8));
        // Broken tables are named.
        let mut bad = f.clone();
        bad.terms[1] = 5;
        assert!(bad.problem(2).unwrap().contains("terms"));
        let mut bad = f.clone();
        bad.stride = 3;
        assert!(bad.problem(2).unwrap().contains("stride"));
        let mut bad = f.clone();
        bad.light.pop();
        assert!(bad.problem(2).unwrap().contains("light"));
        assert!(f.problem(3).is_some());
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
