//! What a drawn pixel takes beside its interpolated vertex colour: the albedo map of a textured
//! mesh ([`Texturing`]), and the light a view-dependent representation adds seen from the eye
//! ([`ViewDependent`]), which both the CPU raster and its per-vertex twin ask for.

use glam::{DVec3, Vec2, Vec3};

use crate::error::{PrtError, Result};
use crate::scene::albedo_map::AlbedoMap;
use crate::scene::tessellate::VertexMesh;
use crate::scene::visibility::Visibility;

/// What a textured mesh adds to a draw: each vertex's texture coordinate and material, and the
/// albedo map each material's pixels are multiplied by.
#[derive(Clone, Debug)]
pub struct Texturing<'a> {
    /// Texture coordinate of each vertex.
    pub uvs: &'a [Vec2],
    /// Material of each vertex.
    pub materials: &'a [u32],
    /// Index into `maps` of each material's map (by material index; past its end, or `None`,
    /// the vertex colours are drawn as they are).
    pub slots: Vec<Option<u32>>,
    /// The albedo maps.
    pub maps: &'a [AlbedoMap],
}

impl<'a> Texturing<'a> {
    /// The texturing of a per-vertex bake's mesh, `None` when it has no albedo maps.
    pub fn of(mesh: &'a VertexMesh) -> Option<Texturing<'a>> {
        (!mesh.albedo_maps.is_empty()).then(|| Texturing {
            uvs: &mesh.uvs,
            materials: &mesh.materials,
            slots: mesh.map_slots(),
            maps: &mesh.albedo_maps,
        })
    }

    /// The map of vertex `v`, if its material has one.
    #[inline]
    pub fn slot(&self, v: usize) -> Option<u32> {
        self.slots
            .get(self.materials[v] as usize)
            .copied()
            .flatten()
    }

    /// Checks one coordinate and material per vertex of `vertices`, finite coordinates and slots
    /// below the map count.
    pub fn check(&self, vertices: usize) -> Result<()> {
        if self.uvs.len() != vertices || self.materials.len() != vertices {
            return Err(PrtError::invalid(
                "texturing",
                format!(
                    "{} texture coordinates and {} materials for {vertices} vertices",
                    self.uvs.len(),
                    self.materials.len()
                ),
            ));
        }
        if let Some(i) = self.uvs.iter().position(|t| !t.is_finite()) {
            return Err(PrtError::invalid(
                format!("uvs[{i}]"),
                format!("must be finite, got {}", self.uvs[i]),
            ));
        }
        if let Some(i) = self
            .slots
            .iter()
            .position(|s| s.is_some_and(|s| s as usize >= self.maps.len()))
        {
            return Err(PrtError::invalid(
                format!("slots[{i}]"),
                format!("{:?} of {} maps", self.slots[i], self.maps.len()),
            ));
        }
        Ok(())
    }
}

/// The unit normal at barycentrics `b` of triangle `tri`, its vertices' `normals` interpolated;
/// `None` where they cancel.
#[inline]
pub fn interpolated_normal(normals: &[Vec3], tri: [u32; 3], b: [f64; 3]) -> Option<DVec3> {
    (0..3)
        .map(|i| normals[tri[i] as usize].as_dvec3() * b[i])
        .sum::<DVec3>()
        .try_normalize()
}

/// What a glossy per-vertex bake adds to its mesh, and what every representation of its glossy
/// light draws with, on the CPU and the GPU: each vertex's shading normal and material, and the
/// glossy vertices' visibility bits with the materials' GGX lobes.
#[derive(Clone, Copy, Debug)]
pub struct GlossMesh<'a> {
    /// Unit shading normal of each vertex.
    pub normals: &'a [Vec3],
    /// Material of each vertex.
    pub materials: &'a [u32],
    /// The glossy vertices' visibility and the materials' lobes.
    pub visibility: &'a Visibility,
}

impl<'a> GlossMesh<'a> {
    /// The gloss of a per-vertex bake's mesh, `None` for its diffuse base (a mesh without
    /// visibility).
    pub fn of(mesh: &'a VertexMesh) -> Option<GlossMesh<'a>> {
        Some(GlossMesh {
            normals: &mesh.normals,
            materials: &mesh.materials,
            visibility: mesh.visibility.as_deref()?,
        })
    }

    /// Checks the tables against a mesh of `vertices` vertices ([`Visibility::check_draw`]).
    pub fn check(&self, vertices: usize) -> Result<()> {
        self.visibility
            .check_draw(self.normals.len(), self.materials, vertices)
    }
}

/// What a per-vertex bake stores for view-dependent shading, as the raster asks for it: the
/// light a point adds, seen from a direction, on top of its interpolated vertex colour. A new
/// representation of glossy light is an impl of this: [`crate::draw::lobe::Lobe`] (the GGX lobe
/// per pixel against the light, through the vertices' visibility) and
/// [`crate::draw::sh_gloss::ShGloss`] (SH glossy transfer) are two.
pub trait ViewDependent: Sync {
    /// Checks the tables against a mesh of `vertices` vertices.
    fn check(&self, vertices: usize) -> Result<()>;

    /// The view-dependent light of a point of triangle `tri` at barycentrics `b` (summing to 1),
    /// seen along `to_eye` (unit, from the point towards the eye).
    fn shade(&self, tri: [u32; 3], b: [f64; 3], to_eye: DVec3) -> DVec3;

    /// The vertex colours with each vertex's view-dependent light added as seen from `eye` (the
    /// direction to the eye taken at the vertex): the per-vertex evaluation that
    /// [`crate::draw::raster::rasterize_with`]'s per-pixel one is compared with. Errors as
    /// [`ViewDependent::check`] does, and unless there is one colour per position.
    fn per_vertex(
        &self,
        positions: &[Vec3],
        colours: &[[f32; 3]],
        eye: Vec3,
    ) -> Result<Vec<[f32; 3]>> {
        self.check(positions.len())?;
        if colours.len() != positions.len() {
            return Err(PrtError::invalid(
                "colours",
                format!("{} colours for {} vertices", colours.len(), positions.len()),
            ));
        }
        Ok(colours
            .iter()
            .enumerate()
            .map(|(v, c)| {
                let to_eye = (eye - positions[v]).normalize_or_zero().as_dvec3();
                let v32 = v as u32;
                let add = self.shade([v32; 3], [1.0, 0.0, 0.0], to_eye);
                std::array::from_fn(|i| (c[i] + add[i] as f32).max(0.0))
            })
            .collect())
    }
}
