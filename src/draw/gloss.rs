//! The in-out BRDF terms of a glossy per-vertex bake as the raster draws them: each vertex's
//! responses to terms `1..K_b`, interpolated across the triangle and multiplied per pixel by
//! `g_k` of the direction to the eye ([`crate::scene::brdf_factor`]). One impl of the raster's
//! [`ViewDependent`].

use glam::{DVec3, Vec3};

use crate::draw::raster::check_colours;
use crate::draw::shading::{ViewDependent, interpolated_normal};
use crate::error::{PrtError, Result};
use crate::scene::brdf_factor::{BrdfFactors, to_local};

/// What a glossy per-vertex bake adds to a draw: each vertex's in-out BRDF responses for terms
/// `1..K_b` of its material, interpolated across the triangle and multiplied per pixel by
/// `g_k` of the direction to the eye in the frame of the interpolated normal
/// ([`crate::scene::brdf_factor`]). The responses are not multiplied by an albedo map.
#[derive(Clone, Debug)]
pub struct Gloss<'a> {
    /// Unit shading normal of each vertex.
    pub normals: &'a [Vec3],
    /// Material of each vertex.
    pub materials: &'a [u32],
    /// The factors: each material's K_b and its `g_k`.
    pub factors: &'a BrdfFactors,
    /// Vertex `v`'s response of term k at `[v · (stride − 1) + k − 1]`.
    pub terms: &'a [[f32; 3]],
}

impl ViewDependent for Gloss<'_> {
    /// Checks the factors ([`BrdfFactors::problem`]), and one normal, material and
    /// `stride − 1` finite responses per vertex of `vertices`.
    fn check(&self, vertices: usize) -> Result<()> {
        if let Some(p) = self.factors.problem(self.factors.terms.len()) {
            return Err(PrtError::invalid("BRDF factors", p));
        }
        let per = self.factors.stride - 1;
        if self.normals.len() != vertices
            || self.materials.len() != vertices
            || self.terms.len() != vertices * per
        {
            return Err(PrtError::invalid(
                "gloss",
                format!(
                    "{} normals, {} materials and {} term responses for {vertices} vertices of \
                     {per} terms",
                    self.normals.len(),
                    self.materials.len(),
                    self.terms.len()
                ),
            ));
        }
        check_colours(self.terms)
    }

    /// The glossy light of a point of triangle `tri` at barycentrics `b` (summing to 1), seen
    /// along `to_eye` (unit, from the point towards the eye).
    fn shade(&self, tri: [u32; 3], b: [f64; 3], to_eye: DVec3) -> DVec3 {
        let m = self.materials[tri[0] as usize];
        let k_b = self.factors.terms_of(m);
        if k_b <= 1 {
            return DVec3::ZERO;
        }
        let Some(n) = interpolated_normal(self.normals, tri, b) else {
            return DVec3::ZERO;
        };
        let local = to_local(n.as_vec3(), to_eye.as_vec3());
        if local.z <= 0.0 {
            return DVec3::ZERO;
        }
        // The direction's taps serve every term.
        let taps = self.factors.map.taps(local);
        let per = self.factors.stride - 1;
        (1..k_b)
            .map(|k| {
                let g = self.factors.view_with(m, k, &taps) as f64;
                let r = (0..3)
                    .map(|i| {
                        DVec3::from(self.terms[tri[i] as usize * per + k - 1].map(f64::from)) * b[i]
                    })
                    .sum::<DVec3>();
                r * g
            })
            .sum()
    }
}
