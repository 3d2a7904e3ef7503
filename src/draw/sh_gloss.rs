//! The glossy light of a per-vertex bake with visibility by SH glossy transfer (Sloan, Kautz &
//! Snyder 2002): each vertex's transferred radiance ([`ShTransfer`]) interpolated across the
//! triangle, and per pixel the material's GGX lobe, taken as symmetric about the reflection of
//! the direction to the eye, convolved with it there (Funk–Hecke). One impl of the raster's
//! [`ViewDependent`]: the low-frequency twin of [`crate::draw::lobe`], fast and small, which
//! blurs sharp lights by construction.

use glam::{DVec3, Vec3};

use crate::draw::shading::{GlossMesh, ViewDependent, interpolated_normal};
use crate::error::Result;
use crate::math::cube_pyramid::CubePyramid;
use crate::math::sh;
use crate::math::zonal::{ZONAL_STEPS, zonal_of};
use crate::relight::sh_transfer::{MAX_TRANSFER_ORDER, ShTransfer, pyramid_sh};
use crate::scene::brdf::ggx_cosine;

/// The Funk–Hecke factor of each band to `order` of a GGX lobe of width `alpha` at normal
/// incidence, per unit of specular colour: what a light's band is scaled by when the lobe,
/// symmetric about its reflection direction, reflects it.
pub fn ggx_bands(alpha: f32, order: usize) -> Vec<f64> {
    let z = zonal_of(order, ZONAL_STEPS, |t| {
        let l = Vec3::new((1.0 - t * t).max(0.0).sqrt() as f32, 0.0, t as f32);
        ggx_cosine(Vec3::Z, Vec3::Z, l, alpha) as f64
    });
    z.iter()
        .enumerate()
        .map(|(l, z)| (4.0 * std::f64::consts::PI / (2 * l + 1) as f64).sqrt() * z)
        .collect()
}

/// What a glossy bake with visibility draws by SH glossy transfer under one light.
#[derive(Clone, Debug)]
pub struct ShGloss<'a> {
    /// The mesh's normals, materials and visibility (whose rows the transfer was made from).
    pub gloss: GlossMesh<'a>,
    order: usize,
    /// Per material, its specular colour and its lobe's band factors (`None`: diffuse).
    bands: Vec<Option<(DVec3, Vec<f64>)>>,
    /// Per visibility row, its transferred radiance (n² RGB coefficients).
    transferred: Vec<[f32; 3]>,
    /// The light's coefficients, what a vertex without bits receives (unshadowed).
    light: Vec<[f32; 3]>,
}

impl<'a> ShGloss<'a> {
    /// The glossy light of a mesh's vertices under `light` through `transfer` (made from the
    /// mesh's visibility).
    pub fn new(gloss: GlossMesh<'a>, transfer: &ShTransfer, light: &CubePyramid) -> ShGloss<'a> {
        let visibility = gloss.visibility;
        let order = transfer.order;
        let light = pyramid_sh(light, order);
        let bands = (0..visibility.lobes.len() as u32)
            .map(|m| {
                visibility
                    .lobe(m)
                    .map(|(s, alpha)| (s.as_dvec3(), ggx_bands(alpha, order)))
            })
            .collect();
        ShGloss {
            gloss,
            order,
            bands,
            transferred: transfer.transferred(&light),
            light,
        }
    }

    /// Vertex `v`'s transferred radiance.
    fn coefficients(&self, v: u32) -> &[[f32; 3]] {
        let nn = self.order * self.order;
        match self.gloss.visibility.row_index(v as usize) {
            Some(r) => &self.transferred[r as usize * nn..(r as usize + 1) * nn],
            None => &self.light,
        }
    }
}

impl ViewDependent for ShGloss<'_> {
    /// Checks the mesh's tables ([`GlossMesh::check`]).
    fn check(&self, vertices: usize) -> Result<()> {
        self.gloss.check(vertices)
    }

    /// The lobe about the reflection of `to_eye` in the interpolated normal, convolved with the
    /// transferred radiance interpolated at `b`.
    fn shade(&self, tri: [u32; 3], b: [f64; 3], to_eye: DVec3) -> DVec3 {
        let m = self.gloss.materials[tri[0] as usize];
        let Some(Some((specular, bands))) = self.bands.get(m as usize) else {
            return DVec3::ZERO;
        };
        let Some(n) = interpolated_normal(self.gloss.normals, tri, b) else {
            return DVec3::ZERO;
        };
        let nv = n.dot(to_eye);
        if nv <= 0.0 {
            return DVec3::ZERO;
        }
        let r = (n * (2.0 * nv) - to_eye).normalize();
        let mut y = [0.0f64; MAX_TRANSFER_ORDER * MAX_TRANSFER_ORDER];
        sh::eval(self.order, r, &mut y);
        let corners = tri.map(|v| self.coefficients(v));
        let mut sum = DVec3::ZERO;
        for (l, factor) in bands.iter().enumerate().take(self.order) {
            let mut band = DVec3::ZERO;
            for (k, yk) in y.iter().enumerate().take((l + 1) * (l + 1)).skip(l * l) {
                let c: DVec3 = (0..3)
                    .map(|i| Vec3::from(corners[i][k]).as_dvec3() * b[i])
                    .sum();
                band += c * *yk;
            }
            sum += band * *factor;
        }
        *specular * sum
    }
}

#[cfg(test)]
mod tests;
