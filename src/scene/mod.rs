//! The scene to bake: a pinhole camera, named materials and world-space geometry, read from a
//! TOML scene file and the OBJ meshes it names.
//!
//! Loading flattens every shape into what the tracer needs: world-space triangles with per-vertex
//! shading normals (quads and meshes) and analytic spheres, each with a material index. Every
//! problem in the input is reported as a [`PrtError`] naming the file, the line where the TOML
//! gives one, and the field (`shape[2].material`, with 0-based shape indices); nothing here
//! panics on bad input.

use std::collections::{BTreeMap, HashMap};
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec2, Vec3};
use serde::Deserialize;

use crate::error::{PrtError, Result};

use crate::medium::{DensityGrid, DensitySource, Medium};
pub use brdf::Lobes;
use file::Loader;
pub use file::MAX_COORDINATE;
pub use gltf::Framing;
pub use light::{Emitter, Light, LightShape};

/// Largest accepted image width or height, in pixels. A per-pixel bake beyond this is surely a
/// typo, and refusing it early avoids allocating absurd buffers.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// A ray: origin and unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
}

/// A pinhole camera looking from `eye` at `target`, with a vertical field of view.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection.
    pub eye: Vec3,
    /// A point the camera looks at; the view direction is `target - eye`.
    pub target: Vec3,
    /// Roughly upwards on the film; need not be orthogonal to the view direction.
    pub up: Vec3,
    /// Full vertical field of view, in degrees, in (0, 180).
    pub fov_y_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// Checks that the camera defines a usable projection: finite vectors, `eye != target`, `up`
    /// not parallel to the view direction, `fov_y_deg` in (0, 180) and an image size in
    /// `1..=MAX_IMAGE_SIDE`.
    pub fn validate(&self) -> Result<()> {
        match self.problem() {
            None => Ok(()),
            Some((field, message)) => Err(PrtError::invalid(format!("camera.{field}"), message)),
        }
    }

    /// The first thing wrong with the camera, as (field, message).
    fn problem(&self) -> Option<(&'static str, String)> {
        for (field, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            if !v.is_finite() {
                return Some((field, format!("must be finite, got {v}")));
            }
        }
        if !self.fov_y_deg.is_finite() || self.fov_y_deg <= 0.0 || self.fov_y_deg >= 180.0 {
            return Some((
                "fov_y_deg",
                format!(
                    "must be strictly between 0 and 180 degrees, got {}",
                    self.fov_y_deg
                ),
            ));
        }
        for (field, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 || v > MAX_IMAGE_SIDE {
                return Some((
                    field,
                    format!("must be between 1 and {MAX_IMAGE_SIDE} pixels, got {v}"),
                ));
            }
        }
        let view = self.target - self.eye;
        // Relative to the coordinates, so that a camera framing a tiny scene keeps its direction.
        let scale = self
            .eye
            .abs()
            .max_element()
            .max(self.target.abs().max_element());
        let has_direction = view.length() > 1e-6 * scale && view.normalize_or_zero() != Vec3::ZERO;
        if !has_direction {
            return Some((
                "target",
                format!("coincides with the eye {}: no view direction", self.eye),
            ));
        }
        let up = self.up.normalize_or_zero();
        if up == Vec3::ZERO {
            return Some(("up", "must not be the zero vector".to_string()));
        }
        // Below this sine of the angle between `up` and the view direction the film's
        // orientation is numerically meaningless.
        const MIN_SIN_UP_VIEW: f32 = 1e-4;
        let oblique = view.normalize().cross(up).length() > MIN_SIN_UP_VIEW;
        if !oblique {
            return Some((
                "up",
                format!("{} is parallel to the view direction {}", self.up, view),
            ));
        }
        None
    }

    /// Orthonormal camera frame: (forward, right, up on the film).
    pub fn frame(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let film_up = right.cross(forward);
        (forward, right, film_up)
    }

    /// Where `p` falls on the film, in pixels (the inverse of [`Camera::ray`]); `None` for a
    /// point at or behind the eye's plane.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let (forward, right, film_up) = self.frame();
        let d = p - self.eye;
        let depth = d.dot(forward);
        let near = 1e-6 * (1.0 + d.length());
        if depth <= near || depth.is_nan() {
            return None;
        }
        let tan_half = (self.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = self.width as f32 / self.height as f32;
        let sx = d.dot(right) / (depth * tan_half * aspect);
        let sy = d.dot(film_up) / (depth * tan_half);
        Some((
            (sx + 1.0) * 0.5 * self.width as f32,
            (1.0 - sy) * 0.5 * self.height as f32,
        ))
    }

    /// The primary ray through film position (`film_x`, `film_y`), in pixels: x grows to the
    /// right, y grows downwards, and (x + 0.5, y + 0.5) is the centre of pixel (x, y). The ray
    /// starts at the eye and has a unit direction. An invalid camera (see
    /// [`Camera::validate`]) gives non-finite directions rather than a panic.
    pub fn ray(&self, film_x: f32, film_y: f32) -> Ray {
        let (forward, right, film_up) = self.frame();
        let tan_half = (self.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = self.width as f32 / self.height as f32;
        let sx = (2.0 * film_x / self.width as f32 - 1.0) * tan_half * aspect;
        let sy = (1.0 - 2.0 * film_y / self.height as f32) * tan_half;
        Ray {
            origin: self.eye,
            dir: (forward + sx * right + sy * film_up).normalize(),
        }
    }
}

/// How a surface reflects light; the scene file's `type` key selects the variant. BRDFs are in
/// [`crate::scene::brdf`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflector.
    Diffuse {
        /// Linear RGB reflectance, each channel in [0, 1].
        albedo: Vec3,
    },
    /// A GGX microfacet lobe over a Lambertian base.
    Glossy {
        /// Reflectance of the Lambertian base.
        albedo: Vec3,
        /// Specular reflectance (scales the GGX lobe); `albedo + specular` is at most 1.
        specular: Vec3,
        /// Perceptual roughness in [0.02, 1]; the GGX width is its square.
        roughness: f32,
    },
}

impl Material {
    /// Linear RGB reflectance of the material's diffuse part.
    pub fn albedo(&self) -> Vec3 {
        match self {
            Material::Diffuse { albedo } | Material::Glossy { albedo, .. } => *albedo,
        }
    }

    /// The specular colour and GGX width (roughness²) of a glossy material.
    pub fn glossy_lobe(&self) -> Option<(Vec3, f32)> {
        match self {
            Material::Diffuse { .. } => None,
            Material::Glossy {
                specular,
                roughness,
                ..
            } => Some((*specular, roughness * roughness)),
        }
    }
}

/// A material whose colours vary over the surface: glTF's `pbrMetallicRoughness` with a
/// base-colour or metallic-roughness texture. Each factor multiplies its texture's value at the
/// hit, and [`TexturedMaterial::lobes_of`] maps the product onto this engine's lobes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexturedMaterial {
    /// Linear RGB base colour factor.
    pub base_color: Vec3,
    /// Index into [`Scene::textures`] of the sRGB base-colour texture.
    pub base_color_texture: Option<u32>,
    /// Metallic factor in [0, 1].
    pub metallic: f32,
    /// Perceptual roughness factor in [0, 1].
    pub roughness: f32,
    /// Index into [`Scene::textures`] of the linear texture whose green channel scales the
    /// roughness and blue channel the metallic factor.
    pub metallic_roughness_texture: Option<u32>,
    /// Only the diffuse lobe (what a per-vertex bake keeps).
    pub diffuse_only: bool,
}

/// Reflectance a dielectric's GGX lobe takes at normal incidence, as glTF specifies.
pub const DIELECTRIC_F0: f32 = 0.04;

/// Lowest perceptual roughness a material may have: narrower lobes than this fall between the
/// texels of any cube map the bake can afford.
pub const MIN_ROUGHNESS: f32 = 0.02;

impl TexturedMaterial {
    /// glTF's metallic-roughness parameters as lobes: specular colour `F0 = 0.04 (1 − m) + m ·
    /// base`, diffuse albedo `(1 − 0.04) (1 − m) · base` (so that the two sum to at most one),
    /// and GGX width `α = r²` with `r` raised to [`MIN_ROUGHNESS`].
    pub fn lobes_of(base: Vec3, metallic: f32, roughness: f32) -> Lobes {
        let m = metallic.clamp(0.0, 1.0);
        let base = base.clamp(Vec3::ZERO, Vec3::ONE);
        let r = roughness.clamp(MIN_ROUGHNESS, 1.0);
        Lobes {
            albedo: base * ((1.0 - DIELECTRIC_F0) * (1.0 - m)),
            specular: Vec3::splat(DIELECTRIC_F0 * (1.0 - m)) + base * m,
            alpha: r * r,
        }
    }

    /// The lobes at texture coordinate `uv`.
    pub fn lobes(&self, textures: &[texture::Texture], uv: Vec2) -> Lobes {
        let sample = |t: Option<u32>| {
            t.and_then(|i| textures.get(i as usize))
                .map(|t| t.sample(uv))
        };
        let base = self.base_color * sample(self.base_color_texture).unwrap_or(Vec3::ONE);
        let mr = sample(self.metallic_roughness_texture).unwrap_or(Vec3::ONE);
        let mut lobes = Self::lobes_of(base, self.metallic * mr.z, self.roughness * mr.y);
        if self.diffuse_only {
            lobes.specular = Vec3::ZERO;
        }
        lobes
    }

    /// The material with every texture at its mean: what messages and summaries quote.
    pub fn mean(&self, textures: &[texture::Texture]) -> Material {
        let mean = |t: Option<u32>| t.and_then(|i| textures.get(i as usize)).map(|t| t.mean());
        let base = self.base_color * mean(self.base_color_texture).unwrap_or(Vec3::ONE);
        let mr = mean(self.metallic_roughness_texture).unwrap_or(Vec3::ONE);
        let l = Self::lobes_of(base, self.metallic * mr.z, self.roughness * mr.y);
        if self.diffuse_only {
            Material::Diffuse { albedo: l.albedo }
        } else {
            Material::Glossy {
                albedo: l.albedo,
                specular: l.specular,
                roughness: l.alpha.sqrt(),
            }
        }
    }
}

/// A world-space triangle with per-vertex shading normals and texture coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Corner positions; their winding defines [`Triangle::geometric_normal`].
    pub vertices: [Vec3; 3],
    /// Unit shading normal at each corner (all equal to the geometric normal for flat shading).
    pub normals: [Vec3; 3],
    /// Texture coordinate at each corner (zero where the shape has none).
    pub uvs: [Vec2; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
}

impl Triangle {
    /// The triangle facing the other way: winding reversed and shading normals negated.
    pub fn turned(&self) -> Triangle {
        let [a, b, c] = self.vertices;
        let [na, nb, nc] = self.normals;
        let [ta, tb, tc] = self.uvs;
        Triangle {
            vertices: [a, c, b],
            normals: [-na, -nc, -nb],
            uvs: [ta, tc, tb],
            material: self.material,
        }
    }

    /// Unit normal of the triangle's plane, by right-handed winding of `vertices`; zero for a
    /// degenerate triangle (loading never produces one).
    pub fn geometric_normal(&self) -> Vec3 {
        let [a, b, c] = self.vertices;
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Area of the triangle.
    pub fn area(&self) -> f32 {
        let [a, b, c] = self.vertices;
        0.5 * (b - a).cross(c - a).length()
    }
}

/// An analytic sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre in world space.
    pub center: Vec3,
    /// Radius, > 0.
    pub radius: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// A loaded scene: camera, materials and flattened world-space geometry.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The fixed camera the scene is baked for.
    pub camera: Camera,
    /// Materials, indexed by the `material` field of triangles and spheres. A textured
    /// material holds its textures' means here; [`Scene::lobes_at`] gives its value at a hit.
    pub materials: Vec<Material>,
    /// The textures of each material, parallel to `materials`: `None` for a constant one.
    pub material_maps: Vec<Option<TexturedMaterial>>,
    /// Textures the materials read, each decoded once.
    pub textures: Vec<texture::Texture>,
    /// Name of each material, parallel to `materials` (sorted by name).
    pub material_names: Vec<String>,
    /// All quads and meshes flattened into world-space triangles.
    pub triangles: Vec<Triangle>,
    /// The triangles of each quad and mesh shape, in the scene file's order.
    pub surfaces: Vec<Range<usize>>,
    /// What each of `surfaces` is called in messages: `shape[I]`, with a mesh's path.
    pub surface_names: Vec<String>,
    /// Longest triangle edge of a per-vertex bake (`edge_length`), if the file sets one.
    pub edge_length: Option<f32>,
    /// Analytic spheres.
    pub spheres: Vec<Sphere>,
    /// A participating medium (`[medium]`), if any.
    pub medium: Option<MediumSpec>,
    /// Local lights (`[[light]]`), in the file's order: their columns follow this order.
    pub lights: Vec<Light>,
    /// The scene file this was loaded from (or named as such by [`Scene::from_toml_str`]).
    pub source_path: PathBuf,
    /// Every file the scene was read from: the scene file, then its meshes, glTF resources and
    /// density grid.
    pub input_files: Vec<PathBuf>,
    /// What its glTF files hold that the engine does not use (emission, normal maps, ...), one
    /// line each, for a warning.
    pub ignored: Vec<String>,
    content_hash: u64,
}

impl Scene {
    /// Reads and loads the scene at `path`: a TOML scene file (OBJ and glTF paths in it are
    /// relative to its folder), or a glTF file (`.gltf`, `.glb`) framed by its first camera.
    pub fn load(path: &Path) -> Result<Scene> {
        Scene::load_with(path, &Framing::default())
    }

    /// [`Scene::load`], with the glTF camera and the image size `framing` picks.
    pub fn load_with(path: &Path, framing: &Framing) -> Result<Scene> {
        if is_gltf(path) {
            return gltf::scene(path, framing);
        }
        if let Some(name) = &framing.camera {
            return Err(PrtError::invalid(
                "camera",
                format!("`{name}`: only a glTF scene has named cameras; a TOML scene has one"),
            ));
        }
        let text = crate::files::read_regular_text(path, crate::files::MAX_SCENE_BYTES, "scene")?;
        let mut scene = Loader::new(&text, path)?
            .reading_outside_folders(framing.read_outside_folder)
            .load()?;
        let (w, h) = (scene.camera.width, scene.camera.height);
        let size = (framing.width.unwrap_or(w), framing.height.unwrap_or(h));
        if size != (w, h) {
            // A scene's camera at another size is another bake: its hash says so.
            (scene.camera.width, scene.camera.height) = size;
            scene.camera.validate()?;
            let mut hasher = hash::Fnv1a(scene.content_hash);
            gltf::hash_camera(&mut hasher, &scene.camera);
            scene.content_hash = hasher.0;
        }
        Ok(scene)
    }

    /// Loads a scene from TOML text. `path_for_errors_and_relative_paths` names the file in
    /// error messages, and its folder is where relative OBJ paths are looked up; the file itself
    /// need not exist.
    pub fn from_toml_str(text: &str, path_for_errors_and_relative_paths: &Path) -> Result<Scene> {
        Loader::new(text, path_for_errors_and_relative_paths)?.load()
    }

    /// A stable 64-bit FNV-1a hash of the scene text and of the bytes of every OBJ file it
    /// loaded, in load order: the same inputs give the same hash on every run and machine, so it
    /// can key cached bakes.
    pub fn content_hash(&self) -> u64 {
        self.content_hash
    }

    /// [`Scene::content_hash`] as files record it: 16 hex digits.
    pub fn hash_hex(&self) -> String {
        format!("{:016x}", self.content_hash)
    }

    /// This scene with every glossy material at its diffuse base: what a per-vertex bake, which
    /// keeps only diffuse light, holds. Its content hash differs from this scene's, so that a
    /// bake of one is never taken for a bake of the other.
    pub fn with_diffuse_materials(&self) -> Scene {
        let mut s = self.clone();
        for m in &mut s.materials {
            *m = Material::Diffuse { albedo: m.albedo() };
        }
        for maps in s.material_maps.iter_mut().flatten() {
            maps.diffuse_only = true;
        }
        // FNV-1a over the source hash and a tag.
        let mut h = hash::Fnv1a::new();
        h.write(&self.content_hash.to_le_bytes());
        h.write(b"diffuse");
        s.content_hash = h.0;
        s
    }

    /// The lobes of material `material` at texture coordinate `uv`: the material's own for a
    /// constant one, its textures' values there for a textured one.
    #[inline]
    pub fn lobes_at(&self, material: u32, uv: Vec2) -> Lobes {
        match self.material_maps.get(material as usize).copied().flatten() {
            Some(maps) => maps.lobes(&self.textures, uv),
            None => Lobes::of(&self.materials[material as usize]),
        }
    }

    /// Whether any material reads a texture.
    pub fn is_textured(&self) -> bool {
        self.material_maps.iter().any(Option::is_some)
    }

    /// Number of triangles after flattening quads and meshes.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Axis-aligned bounds (min, max) of all geometry; (0, 0) for a scene with none.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for tri in &self.triangles {
            for v in tri.vertices {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        for s in &self.spheres {
            lo = lo.min(s.center - Vec3::splat(s.radius));
            hi = hi.max(s.center + Vec3::splat(s.radius));
        }
        if lo.cmple(hi).all() {
            (lo, hi)
        } else {
            (Vec3::ZERO, Vec3::ZERO)
        }
    }
}

/// Where a scene's medium densities come from.
#[derive(Clone, Debug, PartialEq)]
pub enum MediumSource {
    /// Evaluated at the voxel centres of the grid.
    Procedural(DensitySource),
    /// Read from a `.npy` file; another resolution resamples it trilinearly.
    Grid(DensityGrid),
}

/// The `[medium]` of a scene: how to build its density grid and its optical parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct MediumSpec {
    /// Where the densities come from.
    pub source: MediumSource,
    /// Lower corner of the medium's box, scene units.
    pub min: Vec3,
    /// Upper corner of the medium's box, scene units.
    pub max: Vec3,
    /// Voxels along the longest side of the box (others in proportion, cubic voxels).
    pub resolution: usize,
    /// sigma_t at density 1, per scene unit of length.
    pub extinction: f32,
    /// Single-scattering albedo per channel, each in [0, 1].
    pub albedo: Vec3,
    /// Henyey–Greenstein asymmetry in (-1, 1); 0 is isotropic.
    pub g: f32,
}

/// Default voxels along the longest side of a medium's box.
pub const DEFAULT_MEDIUM_RESOLUTION: usize = 64;

impl MediumSpec {
    /// The medium at the scene's resolution, or `resolution` voxels along the longest side.
    pub fn build(&self, resolution: Option<usize>) -> Result<Medium> {
        let extent = self.max - self.min;
        let grid = match (&self.source, resolution) {
            (MediumSource::Grid(g), None) => g.clone(),
            (source, r) => {
                let r = r.unwrap_or(self.resolution);
                if !(1..=512).contains(&r) {
                    return Err(PrtError::invalid(
                        "medium resolution",
                        format!("{r} voxels is outside 1 to 512"),
                    ));
                }
                let dims = crate::medium::grid_dims(extent, r);
                match source {
                    MediumSource::Procedural(src) => {
                        DensityGrid::from_fn(dims, self.min, self.max, |p| src.density(p))
                    }
                    MediumSource::Grid(g) => {
                        DensityGrid::from_fn(dims, self.min, self.max, |p| g.density(p))
                    }
                }
            }
        };
        // Thinner than 1e-3 optical depth across the whole box: nothing would show.
        let densest = grid.data.iter().copied().fold(0.0f32, f32::max);
        if densest * self.extinction * extent.length() < 1e-3 {
            return Err(PrtError::invalid(
                "medium",
                format!(
                    "practically empty (the densest voxel holds {densest:e}): is the medium's \
                     `center` inside its `bounds`, and `extinction` above 0?"
                ),
            ));
        }
        let m = Medium {
            grid,
            extinction: self.extinction,
            albedo: self.albedo,
            g: self.g,
        };
        m.validate()?;
        Ok(m)
    }
}

/// Whether `path` names a glTF file, by its extension.
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

pub mod albedo_map;
pub mod brdf;
mod diagnostics;
mod file;
pub mod gltf;
mod hash;
pub mod light;
pub mod light_mix;
mod obj;
mod refine;
pub mod tessellate;
pub mod texture;
pub mod trace;
pub mod visibility;

#[cfg(test)]
mod tests;
