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

use glam::{Mat3, Vec3};
use serde::Deserialize;

use crate::error::{PrtError, Result};
use crate::medium::{DensityGrid, DensitySource, Medium};

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
        let scale = 1.0
            + self
                .eye
                .abs()
                .max_element()
                .max(self.target.abs().max_element());
        let has_direction = view.length() > 1e-6 * scale;
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
/// [`crate::brdf`].
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

/// A world-space triangle with per-vertex shading normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Corner positions; their winding defines [`Triangle::geometric_normal`].
    pub vertices: [Vec3; 3],
    /// Unit shading normal at each corner (all equal to the geometric normal for flat shading).
    pub normals: [Vec3; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
}

impl Triangle {
    /// Unit normal of the triangle's plane, by right-handed winding of `vertices`; zero for a
    /// degenerate triangle (loading never produces one).
    pub fn geometric_normal(&self) -> Vec3 {
        let [a, b, c] = self.vertices;
        (b - a).cross(c - a).normalize_or_zero()
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
    /// Materials, indexed by the `material` field of triangles and spheres.
    pub materials: Vec<Material>,
    /// Name of each material, parallel to `materials` (sorted by name).
    pub material_names: Vec<String>,
    /// All quads and meshes flattened into world-space triangles.
    pub triangles: Vec<Triangle>,
    /// Analytic spheres.
    pub spheres: Vec<Sphere>,
    /// A participating medium (`[medium]`), if any.
    pub medium: Option<MediumSpec>,
    /// The scene file this was loaded from (or named as such by [`Scene::from_toml_str`]).
    pub source_path: PathBuf,
    /// Every file the scene was read from: the scene file, then its meshes and density grid.
    pub input_files: Vec<PathBuf>,
    content_hash: u64,
}

impl Scene {
    /// Reads and loads the scene file at `path`; OBJ paths in it are relative to its folder.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = crate::files::read_regular_text(path, crate::files::MAX_SCENE_BYTES, "scene")?;
        Scene::from_toml_str(&text, path)
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

// ---------------------------------------------------------------------------------------------
// Scene file schema. Shapes and materials are flat structs with a `type` key rather than serde
// tagged enums: tagged enums buffer their content, which loses the spans toml needs to point at
// the offending line. Which keys apply to which type is checked by hand instead.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    camera: CameraFile,
    #[serde(default)]
    material: BTreeMap<String, MaterialFile>,
    #[serde(default)]
    shape: Vec<ShapeFile>,
    medium: Option<MediumFile>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Debug)]
#[serde(rename_all = "lowercase")]
enum MediumKind {
    Ellipsoid,
    Cloud,
    Grid,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MediumFile {
    r#type: MediumKind,
    bounds: [[f32; 3]; 2],
    resolution: Option<usize>,
    extinction: f32,
    albedo: Option<[f32; 3]>,
    g: Option<f32>,
    center: Option<[f32; 3]>,
    radii: Option<[f32; 3]>,
    falloff: Option<f32>,
    seed: Option<u64>,
    frequency: Option<f32>,
    octaves: Option<u32>,
    coverage: Option<f32>,
    path: Option<String>,
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
    pub source: MediumSource,
    pub min: Vec3,
    pub max: Vec3,
    /// Voxels along the longest side of the box (others in proportion, cubic voxels).
    pub resolution: usize,
    pub extinction: f32,
    pub albedo: Vec3,
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
                let longest = extent.max_element();
                let dims = extent
                    .to_array()
                    .map(|e| ((e / longest * r as f32).round() as usize).max(1));
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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    eye: [f32; 3],
    target: [f32; 3],
    up: [f32; 3],
    fov_y_deg: f32,
    width: u32,
    height: u32,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum MaterialKind {
    Diffuse,
    Glossy,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialFile {
    r#type: MaterialKind,
    albedo: Option<[f32; 3]>,
    specular: Option<[f32; 3]>,
    roughness: Option<f32>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Debug)]
#[serde(rename_all = "lowercase")]
enum ShapeKind {
    Quad,
    Sphere,
    Mesh,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShapeFile {
    r#type: ShapeKind,
    material: String,
    corners: Option<[[f32; 3]; 4]>,
    center: Option<[f32; 3]>,
    radius: Option<f32>,
    path: Option<String>,
    scale: Option<f32>,
    rotate_y_deg: Option<f32>,
    translate: Option<[f32; 3]>,
    smooth_normals: Option<bool>,
}

impl ShapeFile {
    /// The optional keys present in this table, for checking they suit its type.
    fn present_keys(&self) -> [(&'static str, bool); 8] {
        [
            ("corners", self.corners.is_some()),
            ("center", self.center.is_some()),
            ("radius", self.radius.is_some()),
            ("path", self.path.is_some()),
            ("scale", self.scale.is_some()),
            ("rotate_y_deg", self.rotate_y_deg.is_some()),
            ("translate", self.translate.is_some()),
            ("smooth_normals", self.smooth_normals.is_some()),
        ]
    }
}

impl ShapeKind {
    fn name(self) -> &'static str {
        match self {
            ShapeKind::Quad => "quad",
            ShapeKind::Sphere => "sphere",
            ShapeKind::Mesh => "mesh",
        }
    }

    fn allowed_keys(self) -> &'static [&'static str] {
        match self {
            ShapeKind::Quad => &["corners"],
            ShapeKind::Sphere => &["center", "radius"],
            ShapeKind::Mesh => &[
                "path",
                "scale",
                "rotate_y_deg",
                "translate",
                "smooth_normals",
            ],
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Where each key of the TOML document is, so that any error can name a field and a line.

struct SpanEntry {
    path: String,
    /// The key (or, for an array element, the element itself): what a line number points at.
    key: Range<usize>,
    value: Range<usize>,
}

struct SourceMap {
    file: PathBuf,
    entries: Vec<SpanEntry>,
    by_path: HashMap<String, usize>,
    line_starts: Vec<usize>,
}

impl SourceMap {
    /// Parses `text` for its key spans; a TOML syntax error comes back as a scene error.
    fn new(text: &str, file: &Path) -> Result<SourceMap> {
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        let (table, errors) = toml::de::DeTable::parse_recoverable(text);
        let mut map = SourceMap {
            file: file.to_path_buf(),
            entries: Vec::new(),
            by_path: HashMap::new(),
            line_starts,
        };
        map.collect_table(table.get_ref(), "");
        if let Some(err) = errors.first() {
            let span = err.span();
            let field = span
                .as_ref()
                .and_then(|s| map.field_at(s.start))
                .unwrap_or_else(|| "(syntax)".to_string());
            return Err(PrtError::Scene {
                path: map.file.clone(),
                line: span.map(|s| map.line_at(s.start)),
                field,
                message: err.message().trim().to_string(),
            });
        }
        Ok(map)
    }

    fn collect_table(&mut self, table: &toml::de::DeTable<'_>, prefix: &str) {
        for (key, value) in table.iter() {
            let path = if prefix.is_empty() {
                key.get_ref().to_string()
            } else {
                format!("{prefix}.{}", key.get_ref())
            };
            self.push(path.clone(), key.span(), value.span());
            self.collect_value(value.get_ref(), &path);
        }
    }

    fn collect_value(&mut self, value: &toml::de::DeValue<'_>, path: &str) {
        if let Some(table) = value.as_table() {
            self.collect_table(table, path);
        } else if let Some(array) = value.as_array() {
            for (i, element) in array.iter().enumerate() {
                let element_path = format!("{path}[{i}]");
                self.push(element_path.clone(), element.span(), element.span());
                self.collect_value(element.get_ref(), &element_path);
            }
        }
    }

    fn push(&mut self, path: String, key: Range<usize>, value: Range<usize>) {
        self.by_path.insert(path.clone(), self.entries.len());
        self.entries.push(SpanEntry { path, key, value });
    }

    /// 1-based line of a byte offset.
    fn line_at(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&start| start <= offset)
    }

    /// The innermost field whose key or value covers `offset`.
    fn field_at(&self, offset: usize) -> Option<String> {
        let covers = |r: &Range<usize>| r.start <= offset && (offset < r.end || r.is_empty());
        self.entries
            .iter()
            .flat_map(|e| [(e, &e.key), (e, &e.value)])
            .filter(|(_, r)| covers(r))
            .min_by_key(|(e, r)| (r.len(), std::cmp::Reverse(e.path.len())))
            .map(|(e, _)| e.path.clone())
    }

    /// Line of `field`, or of the nearest enclosing field present in the file (a defaulted key
    /// has no line of its own).
    fn line_of(&self, field: &str) -> Option<usize> {
        let mut path = field;
        loop {
            if let Some(&i) = self.by_path.get(path) {
                return Some(self.line_at(self.entries[i].key.start));
            }
            let cut = path.rfind(['.', '['])?;
            path = &path[..cut];
        }
    }

    fn error(&self, field: &str, message: impl Into<String>) -> PrtError {
        PrtError::Scene {
            path: self.file.clone(),
            line: self.line_of(field),
            field: field.to_string(),
            message: message.into(),
        }
    }

    /// Turns a schema error from serde (unknown key, wrong type, missing key) into a scene
    /// error naming the field.
    fn schema_error(&self, err: &toml::de::Error) -> PrtError {
        let message = err.message().trim().to_string();
        // An error spanning from the top of the document is about the document itself (a
        // missing top-level table), not about the first key in it.
        let located = err
            .span()
            .filter(|s| s.start > 0)
            .and_then(|s| self.field_at(s.start));
        // A missing key is reported at its table; name the key itself.
        let missing = message
            .strip_prefix("missing field `")
            .and_then(|rest| rest.split('`').next());
        let field = match (located, missing) {
            (Some(table), Some(key)) => format!("{table}.{key}"),
            (None, Some(key)) => key.to_string(),
            (Some(field), None) => field,
            (None, None) => "(document)".to_string(),
        };
        PrtError::Scene {
            path: self.file.clone(),
            line: err.span().map(|s| self.line_at(s.start)),
            field,
            message,
        }
    }
}

// ---------------------------------------------------------------------------------------------

/// 64-bit FNV-1a, written out so the hash never changes with a dependency's version.
struct Fnv1a(u64);

impl Fnv1a {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    fn new() -> Self {
        Fnv1a(Self::OFFSET)
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(Self::PRIME);
        }
    }

    /// Hashes a length-prefixed chunk, so that moving bytes from one input to the next changes
    /// the hash.
    fn write_chunk(&mut self, bytes: &[u8]) {
        self.write(&(bytes.len() as u64).to_le_bytes());
        self.write(bytes);
    }
}

fn kind_name(k: &MaterialKind) -> &'static str {
    match k {
        MaterialKind::Diffuse => "diffuse",
        MaterialKind::Glossy => "glossy",
    }
}

fn finite3(map: &SourceMap, field: &str, v: [f32; 3]) -> Result<Vec3> {
    let v = Vec3::from_array(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(map.error(field, format!("must be finite, got {v}")))
    }
}

/// Largest coordinate of a point in a scene (camera, shapes, medium), in scene units. The BVH
/// builder and the ray tests multiply and sum extents, which overflow f32 near 1e19; at 1e9 an
/// f32 still resolves 64 units, far beyond any scene that makes sense.
pub const MAX_COORDINATE: f32 = 1e9;

/// [`finite3`] for a position or size: finite and within ±[`MAX_COORDINATE`].
fn position3(map: &SourceMap, field: &str, v: [f32; 3]) -> Result<Vec3> {
    let v = finite3(map, field, v)?;
    if v.abs().max_element() > MAX_COORDINATE {
        return Err(map.error(
            field,
            format!("{v} lies beyond ±{MAX_COORDINATE:e} scene units"),
        ));
    }
    Ok(v)
}

struct Loader<'a> {
    text: &'a str,
    map: SourceMap,
    base_dir: PathBuf,
    hasher: Fnv1a,
    /// OBJ files already read, by resolved path, so a mesh used twice is parsed once.
    obj_cache: HashMap<PathBuf, (Vec<u8>, ObjData)>,
    /// Files read besides the scene text (meshes, a grid), in load order.
    inputs: Vec<PathBuf>,
}

impl<'a> Loader<'a> {
    fn new(text: &'a str, path: &Path) -> Result<Self> {
        let map = SourceMap::new(text, path)?;
        let base_dir = match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => PathBuf::from("."),
        };
        Ok(Loader {
            text,
            map,
            base_dir,
            hasher: Fnv1a::new(),
            obj_cache: HashMap::new(),
            inputs: Vec::new(),
        })
    }

    fn load(mut self) -> Result<Scene> {
        let file: SceneFile = toml::from_str(self.text).map_err(|e| self.map.schema_error(&e))?;
        self.hasher.write_chunk(self.text.as_bytes());

        let camera = self.camera(&file.camera)?;

        let mut materials = Vec::with_capacity(file.material.len());
        let mut material_names = Vec::with_capacity(file.material.len());
        for (name, m) in &file.material {
            materials.push(self.material(name, m)?);
            material_names.push(name.clone());
        }

        let medium = match &file.medium {
            Some(m) => Some(self.medium(m)?),
            None => None,
        };
        if file.shape.is_empty() && medium.is_none() {
            return Err(self.map.error(
                "shape",
                "the scene has no shapes and no medium; add a [[shape]] or a [medium]",
            ));
        }
        let mut triangles = Vec::new();
        let mut spheres = Vec::new();
        for (i, shape) in file.shape.iter().enumerate() {
            let field = |key: &str| format!("shape[{i}].{key}");
            let material = material_names
                .iter()
                .position(|n| *n == shape.material)
                .ok_or_else(|| {
                    let known = if material_names.is_empty() {
                        "none are defined".to_string()
                    } else {
                        format!("defined: {}", material_names.join(", "))
                    };
                    self.map.error(
                        &field("material"),
                        format!("unknown material `{}` ({known})", shape.material),
                    )
                })? as u32;
            for (key, present) in shape.present_keys() {
                if present && !shape.r#type.allowed_keys().contains(&key) {
                    return Err(self.map.error(
                        &field(key),
                        format!("`{key}` does not apply to a {}", shape.r#type.name()),
                    ));
                }
            }
            let require = |key: &str, present: bool| {
                if present {
                    Ok(())
                } else {
                    Err(self.map.error(
                        &field(key),
                        format!("a {} needs `{key}`", shape.r#type.name()),
                    ))
                }
            };
            match shape.r#type {
                ShapeKind::Sphere => {
                    require("center", shape.center.is_some())?;
                    require("radius", shape.radius.is_some())?;
                    let center = position3(
                        &self.map,
                        &field("center"),
                        shape.center.unwrap_or_default(),
                    )?;
                    let radius = shape.radius.unwrap_or_default();
                    if !(radius.is_finite() && radius > 0.0 && radius <= MAX_COORDINATE) {
                        return Err(self.map.error(
                            &field("radius"),
                            format!("must be a number > 0 and <= {MAX_COORDINATE:e}, got {radius}"),
                        ));
                    }
                    spheres.push(Sphere {
                        center,
                        radius,
                        material,
                    });
                }
                ShapeKind::Quad => {
                    require("corners", shape.corners.is_some())?;
                    let mut c = [Vec3::ZERO; 4];
                    for (k, corner) in shape.corners.unwrap_or_default().iter().enumerate() {
                        c[k] = position3(&self.map, &field("corners"), *corner)?;
                    }
                    let before = triangles.len();
                    for [a, b, d] in [[c[0], c[1], c[2]], [c[0], c[2], c[3]]] {
                        if let Some(tri) = flat_triangle([a, b, d], material) {
                            triangles.push(tri);
                        }
                    }
                    if triangles.len() == before {
                        return Err(self.map.error(&field("corners"), "the quad has zero area"));
                    }
                }
                ShapeKind::Mesh => {
                    require("path", shape.path.is_some())?;
                    let mesh = self.mesh(i, shape, material)?;
                    triangles.extend(mesh);
                }
            }
        }

        Ok(Scene {
            camera,
            materials,
            material_names,
            triangles,
            spheres,
            medium,
            source_path: self.map.file.clone(),
            input_files: std::iter::once(self.map.file.clone())
                .chain(self.inputs)
                .collect(),
            content_hash: self.hasher.0,
        })
    }

    fn camera(&self, c: &CameraFile) -> Result<Camera> {
        let camera = Camera {
            eye: position3(&self.map, "camera.eye", c.eye)?,
            target: position3(&self.map, "camera.target", c.target)?,
            up: finite3(&self.map, "camera.up", c.up)?,
            fov_y_deg: c.fov_y_deg,
            width: c.width,
            height: c.height,
        };
        match camera.problem() {
            None => Ok(camera),
            Some((field, message)) => Err(self.map.error(&format!("camera.{field}"), message)),
        }
    }

    fn material(&self, name: &str, m: &MaterialFile) -> Result<Material> {
        let field = |key: &str| format!("material.{name}.{key}");
        let reflectance = |key: &str, value: Option<[f32; 3]>| -> Result<Vec3> {
            let Some(v) = value else {
                return Err(self.map.error(
                    &field(key),
                    format!("a {} material needs `{key}`", kind_name(&m.r#type)),
                ));
            };
            let v = finite3(&self.map, &field(key), v)?;
            if !(v.cmpge(Vec3::ZERO).all() && v.cmple(Vec3::ONE).all()) {
                return Err(self.map.error(
                    &field(key),
                    format!("each channel must be in [0, 1], got {v}"),
                ));
            }
            Ok(v)
        };
        match m.r#type {
            MaterialKind::Diffuse => {
                for (key, set) in [
                    ("specular", m.specular.is_some()),
                    ("roughness", m.roughness.is_some()),
                ] {
                    if set {
                        return Err(self.map.error(
                            &field(key),
                            "only a glossy material has it (set type = \"glossy\")",
                        ));
                    }
                }
                Ok(Material::Diffuse {
                    albedo: reflectance("albedo", m.albedo)?,
                })
            }
            MaterialKind::Glossy => {
                let albedo = reflectance("albedo", m.albedo)?;
                let specular = reflectance("specular", m.specular)?;
                if (albedo + specular).cmpgt(Vec3::ONE).any() {
                    return Err(self.map.error(
                        &field("specular"),
                        format!(
                            "albedo + specular must be at most 1 per channel (energy), got {}",
                            albedo + specular
                        ),
                    ));
                }
                let roughness = m.roughness.ok_or_else(|| {
                    self.map
                        .error(&field("roughness"), "a glossy material needs `roughness`")
                })?;
                if !(0.02..=1.0).contains(&roughness) {
                    return Err(self.map.error(
                        &field("roughness"),
                        format!("it must be in [0.02, 1], got {roughness}"),
                    ));
                }
                Ok(Material::Glossy {
                    albedo,
                    specular,
                    roughness,
                })
            }
        }
    }

    fn medium(&mut self, m: &MediumFile) -> Result<MediumSpec> {
        let field = |key: &str| format!("medium.{key}");
        let min = position3(&self.map, "medium.bounds", m.bounds[0])?;
        let max = position3(&self.map, "medium.bounds", m.bounds[1])?;
        if !min.cmplt(max).all() {
            return Err(self.map.error(
                "medium.bounds",
                format!("[min, max] needs min < max on every axis, got {min} and {max}"),
            ));
        }
        let resolution = m.resolution.unwrap_or(DEFAULT_MEDIUM_RESOLUTION);
        if !(1..=512).contains(&resolution) {
            return Err(self.map.error(
                &field("resolution"),
                format!("must be 1 to 512 voxels, got {resolution}"),
            ));
        }
        if !(m.extinction.is_finite() && m.extinction >= 0.0) {
            return Err(self.map.error(
                &field("extinction"),
                format!("must be finite and >= 0, got {}", m.extinction),
            ));
        }
        let albedo = finite3(&self.map, &field("albedo"), m.albedo.unwrap_or([0.95; 3]))?;
        if !(albedo.cmpge(Vec3::ZERO).all() && albedo.cmple(Vec3::ONE).all()) {
            return Err(self.map.error(
                &field("albedo"),
                format!("each channel must be in [0, 1], got {albedo}"),
            ));
        }
        let g = m.g.unwrap_or(0.0);
        if !(g.is_finite() && g.abs() < 1.0) {
            return Err(self
                .map
                .error(&field("g"), format!("must be in (-1, 1), got {g}")));
        }
        let present = [
            ("center", m.center.is_some()),
            ("radii", m.radii.is_some()),
            ("falloff", m.falloff.is_some()),
            ("seed", m.seed.is_some()),
            ("frequency", m.frequency.is_some()),
            ("octaves", m.octaves.is_some()),
            ("coverage", m.coverage.is_some()),
            ("path", m.path.is_some()),
        ];
        let (kind, allowed): (&str, &[&str]) = match m.r#type {
            MediumKind::Ellipsoid => ("ellipsoid", &["center", "radii", "falloff"]),
            MediumKind::Cloud => (
                "cloud",
                &[
                    "center",
                    "radii",
                    "seed",
                    "frequency",
                    "octaves",
                    "coverage",
                ],
            ),
            MediumKind::Grid => ("grid", &["path"]),
        };
        if m.r#type == MediumKind::Grid && m.resolution.is_some() {
            return Err(self.map.error(
                "medium.resolution",
                "a grid medium has its file's resolution (`prt volume bake --grid N` resamples it)",
            ));
        }
        for (key, set) in present {
            if set && !allowed.contains(&key) {
                return Err(self.map.error(
                    &field(key),
                    format!("`{key}` does not apply to a {kind} medium"),
                ));
            }
        }
        let center = position3(
            &self.map,
            &field("center"),
            m.center.unwrap_or(((min + max) * 0.5).to_array()),
        )?;
        let radii = position3(
            &self.map,
            &field("radii"),
            m.radii.unwrap_or(((max - min) * 0.5).to_array()),
        )?;
        if !radii.cmpgt(Vec3::ZERO).all() {
            return Err(self
                .map
                .error(&field("radii"), format!("must be > 0, got {radii}")));
        }
        let source = match m.r#type {
            MediumKind::Ellipsoid => {
                let falloff = m.falloff.unwrap_or(0.3);
                if !(0.0..1.0).contains(&falloff) {
                    return Err(self.map.error(
                        &field("falloff"),
                        format!("must be in [0, 1), got {falloff}"),
                    ));
                }
                MediumSource::Procedural(DensitySource::Ellipsoid {
                    center,
                    radii,
                    falloff,
                })
            }
            MediumKind::Cloud => {
                let frequency = m.frequency.unwrap_or(3.0);
                let coverage = m.coverage.unwrap_or(0.6);
                let octaves = m.octaves.unwrap_or(4);
                if !(frequency.is_finite() && frequency > 0.0) {
                    return Err(self
                        .map
                        .error(&field("frequency"), format!("must be > 0, got {frequency}")));
                }
                if !(coverage > 0.0 && coverage <= 1.0) {
                    return Err(self.map.error(
                        &field("coverage"),
                        format!("must be in (0, 1], got {coverage}"),
                    ));
                }
                if !(1..=8).contains(&octaves) {
                    return Err(self
                        .map
                        .error(&field("octaves"), format!("must be 1 to 8, got {octaves}")));
                }
                MediumSource::Procedural(DensitySource::Cloud {
                    center,
                    radii,
                    seed: m.seed.unwrap_or(1),
                    frequency,
                    octaves,
                    coverage,
                })
            }
            MediumKind::Grid => {
                let rel = m.path.as_deref().ok_or_else(|| {
                    self.map
                        .error("medium.path", "a grid medium needs `path` (a .npy file)")
                })?;
                let path = self.base_dir.join(rel);
                let bytes = crate::files::read_regular(
                    &path,
                    crate::medium::MAX_NPY_BYTES,
                    "NumPy .npy grid",
                )
                .map_err(|e| self.map.error("medium.path", e.to_string()))?;
                let grid = crate::medium::parse_npy(&bytes, &path, min, max)
                    .map_err(|e| self.map.error("medium.path", e.to_string()))?;
                self.hasher.write_chunk(&bytes);
                self.inputs.push(path);
                MediumSource::Grid(grid)
            }
        };
        Ok(MediumSpec {
            source,
            min,
            max,
            resolution,
            extinction: m.extinction,
            albedo,
            g,
        })
    }

    fn mesh(&mut self, index: usize, shape: &ShapeFile, material: u32) -> Result<Vec<Triangle>> {
        let field = |key: &str| format!("shape[{index}].{key}");
        let scale = shape.scale.unwrap_or(1.0);
        if !(scale.is_finite() && scale > 0.0) {
            return Err(self.map.error(
                &field("scale"),
                format!("must be a finite number > 0, got {scale}"),
            ));
        }
        let rotate_y_deg = shape.rotate_y_deg.unwrap_or(0.0);
        if !rotate_y_deg.is_finite() {
            return Err(self.map.error(
                &field("rotate_y_deg"),
                format!("must be finite, got {rotate_y_deg}"),
            ));
        }
        let translate = position3(
            &self.map,
            &field("translate"),
            shape.translate.unwrap_or_default(),
        )?;
        let rel = shape.path.as_deref().unwrap_or_default();
        let path = self.base_dir.join(rel);
        if !self.obj_cache.contains_key(&path) {
            let bytes = crate::files::read_regular(&path, crate::files::MAX_MESH_BYTES, "mesh")?;
            let obj = parse_obj(&bytes, &path)?;
            self.obj_cache.insert(path.clone(), (bytes, obj));
            self.inputs.push(path.clone());
        }
        let (bytes, obj) = &self.obj_cache[&path];
        self.hasher.write_chunk(bytes);

        let transform = MeshTransform {
            scale,
            rotation: Mat3::from_rotation_y(rotate_y_deg.to_radians()),
            translate,
        };
        // Every vertex a face uses, placed in the scene, within the coordinate limit (checked
        // before triangles are built: an overflowing one would only look like zero area).
        if let Some(v) = obj
            .triangles
            .iter()
            .flat_map(|t| t.positions)
            .map(|i| transform.point(obj.positions[i as usize]))
            .find(|v| !(v.is_finite() && v.abs().max_element() <= MAX_COORDINATE))
        {
            return Err(self.map.error(
                &field("scale"),
                format!("the placed mesh reaches {v}, beyond ±{MAX_COORDINATE:e} scene units"),
            ));
        }
        let triangles = mesh_triangles(
            obj,
            &transform,
            shape.smooth_normals.unwrap_or(false),
            material,
        );
        if triangles.is_empty() {
            return Err(self.map.error(
                &field("path"),
                format!("{} has no triangles with non-zero area", path.display()),
            ));
        }
        Ok(triangles)
    }
}

/// A flat-shaded triangle, or `None` when it has no area (it could never be hit, and has no
/// normal).
fn flat_triangle(vertices: [Vec3; 3], material: u32) -> Option<Triangle> {
    let [a, b, c] = vertices;
    let n = (b - a).cross(c - a).normalize_or_zero();
    (n != Vec3::ZERO).then_some(Triangle {
        vertices,
        normals: [n; 3],
        material,
    })
}

// ---------------------------------------------------------------------------------------------
// OBJ reading: only what shading needs (positions, normals, faces); texture coordinates,
// groups and materials are skipped.

#[derive(Clone, Copy, Debug, PartialEq)]
struct ObjTriangle {
    positions: [u32; 3],
    /// Indices into `ObjData::normals`, when every corner of the face named one.
    normals: Option<[u32; 3]>,
}

#[derive(Debug, Default)]
struct ObjData {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    triangles: Vec<ObjTriangle>,
}

/// Resolves a 1-based (or negative, relative to the end) OBJ index against `count` elements
/// defined so far.
fn obj_index(token: &str, count: usize, what: &str) -> std::result::Result<u32, String> {
    let i: i64 = token
        .parse()
        .map_err(|_| format!("bad {what} index `{token}`"))?;
    let resolved = match i {
        0 => return Err(format!("{what} index 0 (OBJ indices start at 1)")),
        i if i > 0 => i - 1,
        i => count as i64 + i,
    };
    if resolved < 0 || resolved >= count as i64 || resolved > i64::from(u32::MAX) {
        return Err(format!(
            "{what} index {i} out of range ({count} defined so far)"
        ));
    }
    Ok(resolved as u32)
}

fn obj_vec3<'t>(
    fields: &mut impl Iterator<Item = &'t str>,
    what: &str,
) -> std::result::Result<Vec3, String> {
    let mut v = [0.0f32; 3];
    for c in &mut v {
        let token = fields
            .next()
            .ok_or_else(|| format!("{what} needs 3 coordinates"))?;
        *c = token
            .parse()
            .map_err(|_| format!("bad {what} coordinate `{token}`"))?;
        if !c.is_finite() {
            return Err(format!("{what} coordinate `{token}` is not finite"));
        }
    }
    Ok(Vec3::from_array(v))
}

/// Parses OBJ text: `v`, `vn` and `f` (polygons fan-triangulated; `v`, `v/vt`, `v//vn` and
/// `v/vt/vn` corners; negative indices). Errors name the file and line.
fn parse_obj(bytes: &[u8], path: &Path) -> Result<ObjData> {
    let text = String::from_utf8_lossy(bytes);
    let mut obj = ObjData::default();
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    for (line_index, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or_default();
        let mut fields = line.split_whitespace();
        let Some(tag) = fields.next() else { continue };
        let outcome = match tag {
            "v" => obj_vec3(&mut fields, "vertex").map(|p| obj.positions.push(p)),
            "vn" => obj_vec3(&mut fields, "normal").map(|n| obj.normals.push(n)),
            "f" => {
                corners.clear();
                let parsed: std::result::Result<(), String> = fields.try_for_each(|corner| {
                    let mut parts = corner.split('/');
                    let v = obj_index(
                        parts.next().unwrap_or_default(),
                        obj.positions.len(),
                        "vertex",
                    )?;
                    let _texture = parts.next();
                    let n = match parts.next() {
                        Some(t) if !t.is_empty() => {
                            Some(obj_index(t, obj.normals.len(), "normal")?)
                        }
                        _ => None,
                    };
                    corners.push((v, n));
                    Ok(())
                });
                parsed.and_then(|()| {
                    if corners.len() < 3 {
                        return Err(format!(
                            "a face needs at least 3 corners, got {}",
                            corners.len()
                        ));
                    }
                    for k in 1..corners.len() - 1 {
                        let tri = [corners[0], corners[k], corners[k + 1]];
                        let normals = match tri.map(|(_, n)| n) {
                            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                            _ => None,
                        };
                        obj.triangles.push(ObjTriangle {
                            positions: tri.map(|(v, _)| v),
                            normals,
                        });
                    }
                    Ok(())
                })
            }
            _ => Ok(()),
        };
        if let Err(message) = outcome {
            return Err(PrtError::file(
                path,
                format!("line {}: {message}", line_index + 1),
            ));
        }
    }
    Ok(obj)
}

/// Object-to-world transform of a mesh: `translate * rotate_y * scale`.
struct MeshTransform {
    scale: f32,
    rotation: Mat3,
    translate: Vec3,
}

impl MeshTransform {
    fn point(&self, p: Vec3) -> Vec3 {
        self.translate + self.rotation * (self.scale * p)
    }
}

/// World-space triangles of a mesh, with shading normals chosen as the module documents:
/// welded area-weighted normals when `smooth`, else the file's `vn` where a face has them, else
/// the geometric normal. Triangles without area are dropped.
fn mesh_triangles(
    obj: &ObjData,
    transform: &MeshTransform,
    smooth: bool,
    material: u32,
) -> Vec<Triangle> {
    let world: Vec<Vec3> = obj.positions.iter().map(|&p| transform.point(p)).collect();

    // Welding is by exact object-space position, because OBJ exporters duplicate vertices
    // along patch seams (the teapot) and those copies must share one normal.
    let smooth_normals: Vec<Vec3> = if smooth {
        let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
        let welded: Vec<u32> = obj
            .positions
            .iter()
            .map(|p| {
                // Adding 0.0 turns -0.0 into 0.0 so both weld together.
                let key = (*p + Vec3::ZERO).to_array().map(f32::to_bits);
                let next = weld.len() as u32;
                *weld.entry(key).or_insert(next)
            })
            .collect();
        let mut sums = vec![Vec3::ZERO; weld.len()];
        for tri in &obj.triangles {
            let [a, b, c] = tri.positions.map(|i| world[i as usize]);
            // The unnormalised cross product is twice the area: area weighting for free.
            let n = (b - a).cross(c - a);
            for i in tri.positions {
                sums[welded[i as usize] as usize] += n;
            }
        }
        welded
            .iter()
            .map(|&w| sums[w as usize].normalize_or_zero())
            .collect()
    } else {
        Vec::new()
    };

    let mut out = Vec::with_capacity(obj.triangles.len());
    for tri in &obj.triangles {
        let vertices = tri.positions.map(|i| world[i as usize]);
        let Some(mut t) = flat_triangle(vertices, material) else {
            continue;
        };
        let geometric = t.normals[0];
        let pick = |n: Vec3| if n == Vec3::ZERO { geometric } else { n };
        if smooth {
            t.normals = tri.positions.map(|i| pick(smooth_normals[i as usize]));
        } else if let Some(ns) = tri.normals {
            t.normals = ns
                .map(|i| pick((transform.rotation * obj.normals[i as usize]).normalize_or_zero()));
        }
        out.push(t);
    }
    out
}

#[cfg(test)]
pub(crate) mod test_support {
    //! Helpers shared by the tests of this crate's modules.

    use glam::Vec3;
    use std::path::PathBuf;

    /// Asserts |a - b| <= tol, printing both values (and what was compared) on failure.
    #[track_caller]
    pub fn assert_close(what: &str, a: f32, b: f32, tol: f32) {
        assert!(
            (a - b).abs() <= tol,
            "{what}: got {a}, expected {b} (|diff| = {} > tol {tol})",
            (a - b).abs()
        );
    }

    /// Asserts every component of `a - b` is within `tol`, printing both on failure.
    #[track_caller]
    pub fn assert_vec_close(what: &str, a: Vec3, b: Vec3, tol: f32) {
        assert!(
            (a - b).abs().max_element() <= tol,
            "{what}: got {a}, expected {b} (max |diff| = {} > tol {tol})",
            (a - b).abs().max_element()
        );
    }

    /// A fresh, empty folder for one test's files.
    pub fn temp_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("wavelet-prt-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create temp dir");
        dir
    }

    /// Small deterministic generator (SplitMix64) so random tests repeat exactly.
    pub struct Rng(pub u64);

    impl Rng {
        pub fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }

        /// Uniform in [0, 1).
        pub fn f32(&mut self) -> f32 {
            (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
        }

        /// Uniform in [lo, hi).
        pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.f32()
        }

        /// Uniform on the unit sphere.
        pub fn unit_vector(&mut self) -> Vec3 {
            let z = self.range(-1.0, 1.0);
            let phi = self.range(0.0, std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        }
    }

    /// The canonical scene of the scene-file documentation, without the mesh.
    pub const CANONICAL: &str = r#"[camera]
eye = [0.0, 1.5, 4.0]
target = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
width = 256
height = 256

[material.ground]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[material.clay]
type = "diffuse"
albedo = [0.8, 0.3, 0.2]

[[shape]]
type = "quad"
corners = [[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]
material = "ground"

[[shape]]
type = "sphere"
center = [0.0, 0.6, 0.0]
radius = 0.6
material = "clay"
"#;
}

#[cfg(test)]
mod tests {
    use super::test_support::*;
    use super::*;

    /// Direction comparisons: f32 normalisation and trigonometry are good to a few ulps.
    const DIR_TOL: f32 = 1e-5;
    /// Positions after a scale/rotate/translate of values around 1-5.
    const POS_TOL: f32 = 1e-5;

    fn canonical() -> Scene {
        Scene::from_toml_str(CANONICAL, Path::new("/nonexistent/scene.toml"))
            .expect("canonical scene parses")
    }

    fn load_err(text: &str) -> String {
        let err = Scene::from_toml_str(text, Path::new("/scenes/test.toml"))
            .expect_err("the scene should be rejected");
        err.to_string()
    }

    /// The 1-based line of the first line of `text` that contains `needle`.
    fn line_of(text: &str, needle: &str) -> usize {
        text.lines()
            .position(|l| l.contains(needle))
            .unwrap_or_else(|| panic!("`{needle}` not in text"))
            + 1
    }

    #[track_caller]
    fn assert_mentions(message: &str, parts: &[&str]) {
        for part in parts {
            assert!(
                message.contains(part),
                "error message lacks `{part}`: {message}"
            );
        }
    }

    #[test]
    fn canonical_scene_parses() {
        let s = canonical();
        assert_eq!(s.camera.width, 256);
        assert_eq!(s.camera.height, 256);
        assert_eq!(s.material_names, vec!["clay", "ground"]);
        assert_eq!(s.triangle_count(), 2);
        assert_eq!(s.spheres.len(), 1);
        let clay = s.material_names.iter().position(|n| n == "clay").unwrap() as u32;
        let ground = s.material_names.iter().position(|n| n == "ground").unwrap() as u32;
        assert_eq!(s.spheres[0].material, clay);
        assert!(s.triangles.iter().all(|t| t.material == ground));
        assert_eq!(
            s.materials[clay as usize],
            Material::Diffuse {
                albedo: Vec3::new(0.8, 0.3, 0.2)
            }
        );
        // Quad split along c0-c2 into (c0,c1,c2) and (c0,c2,c3).
        assert_eq!(
            s.triangles[1].vertices,
            [
                Vec3::new(-2.0, 0.0, -2.0),
                Vec3::new(2.0, 0.0, 2.0),
                Vec3::new(2.0, 0.0, -2.0)
            ]
        );
        let (lo, hi) = s.bounds();
        assert_vec_close("bounds min", lo, Vec3::new(-2.0, 0.0, -2.0), 0.0);
        assert_vec_close("bounds max", hi, Vec3::new(2.0, 1.2, 2.0), 1e-6);
        assert!(s.camera.validate().is_ok());
    }

    #[test]
    fn central_ray_points_at_target() {
        let cam = canonical().camera;
        let forward = (cam.target - cam.eye).normalize();
        // Even size: no pixel is centred, so average the four around the film centre.
        let (cx, cy) = (cam.width / 2, cam.height / 2);
        let mut sum = Vec3::ZERO;
        for (x, y) in [(cx - 1, cy - 1), (cx, cy - 1), (cx - 1, cy), (cx, cy)] {
            let r = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            assert_eq!(r.origin, cam.eye);
            assert_close("|dir|", r.dir.length(), 1.0, DIR_TOL);
            sum += r.dir;
        }
        assert_vec_close("central direction", sum.normalize(), forward, DIR_TOL);
    }

    #[test]
    fn pixel_zero_looks_up_left_and_fov_is_vertical() {
        let mut cam = canonical().camera;
        cam.width = 320;
        cam.height = 200;
        let forward = (cam.target - cam.eye).normalize();
        let right = forward.cross(cam.up).normalize();
        let film_up = right.cross(forward);
        let d = cam.ray(0.5, 0.5).dir;
        assert!(d.dot(right) < 0.0, "pixel (0,0) should look left: {d}");
        assert!(d.dot(film_up) > 0.0, "pixel (0,0) should look up: {d}");
        // The top edge of the film, mid-width, is half the vertical fov above the view axis.
        let top = cam.ray(cam.width as f32 * 0.5, 0.0).dir;
        let half = (cam.fov_y_deg * 0.5).to_radians();
        assert_close("top-edge angle", top.dot(forward).acos(), half, 1e-4);
        assert!(top.dot(film_up) > 0.0);
        // The horizontal extent follows the aspect ratio.
        let side = cam.ray(0.0, cam.height as f32 * 0.5).dir;
        let expected = (half.tan() * 320.0 / 200.0).atan();
        assert_close("left-edge angle", side.dot(forward).acos(), expected, 1e-4);
    }

    #[test]
    fn fnv1a_matches_reference_vectors() {
        let mut h = Fnv1a::new();
        assert_eq!(h.0, 0xcbf2_9ce4_8422_2325);
        h.write(b"a");
        assert_eq!(h.0, 0xaf63_dc4c_8601_ec8c);
        let mut h = Fnv1a::new();
        h.write(b"foobar");
        assert_eq!(h.0, 0x8594_4171_f739_67e8);
    }

    fn mesh_scene(obj_name: &str, extra: &str) -> String {
        format!(
            r#"[camera]
eye = [0.0, 1.0, 5.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 45.0
width = 8
height = 8

[material.m]
type = "diffuse"
albedo = [0.5, 0.5, 0.5]

[[shape]]
type = "mesh"
path = "{obj_name}"
material = "m"
{extra}
"#
        )
    }

    fn load_mesh(dir: &str, obj: &str, extra: &str) -> Scene {
        let dir = temp_dir(dir);
        std::fs::write(dir.join("m.obj"), obj).unwrap();
        let text = mesh_scene("m.obj", extra);
        std::fs::write(dir.join("scene.toml"), &text).unwrap();
        Scene::load(&dir.join("scene.toml")).expect("mesh scene loads")
    }

    #[test]
    fn obj_vertex_normals_are_used() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 0 -1\nvn 0 1 1\nvn 0 1 1\nvn 1 1 0\nf 1//1 2//2 3//3\n";
        let s = load_mesh("vn", obj, "");
        assert_eq!(s.triangle_count(), 1);
        let t = s.triangles[0];
        let tilted = Vec3::new(0.0, 1.0, 1.0).normalize();
        assert_vec_close("n0", t.normals[0], tilted, DIR_TOL);
        assert_vec_close("n1", t.normals[1], tilted, DIR_TOL);
        assert_vec_close(
            "n2",
            t.normals[2],
            Vec3::new(1.0, 1.0, 0.0).normalize(),
            DIR_TOL,
        );
        assert_vec_close("geometric", t.geometric_normal(), Vec3::Y, DIR_TOL);
    }

    #[test]
    fn obj_without_normals_is_flat() {
        // A quad face (fan-triangulated) given with negative indices and v/vt corners.
        let obj = "# square\nv 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nf -4/1 -3/1 -2/1 -1/1\n";
        let s = load_mesh("flat", obj, "");
        assert_eq!(s.triangle_count(), 2);
        for t in &s.triangles {
            let ng = t.geometric_normal();
            assert_vec_close("geometric", ng, Vec3::Y, DIR_TOL);
            assert_eq!(t.normals, [ng; 3]);
        }
        assert_eq!(s.triangles[1].vertices[2], Vec3::new(0.0, 0.0, -1.0));
    }

    #[test]
    fn smooth_normals_weld_and_weight_by_area() {
        // Two roof slopes sharing the ridge (0,1,0)-(0,1,-1), each with its own copy of the
        // ridge vertices; the right slope is longer, so it carries more area.
        let obj = "\
v 0 1 0\nv -1 0 0\nv 0 1 -1\n\
v 0 1 0\nv 0 1 -1\nv 3 0 0\n\
vn 0 0 1\nvn 0 0 1\nvn 0 0 1\n\
f 1//1 3//3 2//2\nf 4//1 6//3 5//2\n";
        let s = load_mesh("smooth", obj, "smooth_normals = true");
        let [left, right] = [s.triangles[0], s.triangles[1]];
        let cross = |t: &Triangle| {
            let [a, b, c] = t.vertices;
            (b - a).cross(c - a)
        };
        let weighted = (cross(&left) + cross(&right)).normalize();
        let unweighted = (left.geometric_normal() + right.geometric_normal()).normalize();
        assert!(
            (weighted - unweighted).length() > 0.05,
            "test geometry must tell area weighting apart"
        );
        assert!(left.geometric_normal().y > 0.0 && right.geometric_normal().y > 0.0);
        // Ridge corners are shared (welded), the outer corners keep their face normal.
        assert_vec_close("weighted normal", weighted, Vec3::Y, DIR_TOL);
        assert_vec_close("left ridge", left.normals[0], weighted, DIR_TOL);
        assert_vec_close("left ridge 2", left.normals[1], weighted, DIR_TOL);
        assert_vec_close("right ridge", right.normals[0], weighted, DIR_TOL);
        assert_vec_close("right ridge 2", right.normals[2], weighted, DIR_TOL);
        assert_vec_close(
            "left eave",
            left.normals[2],
            left.geometric_normal(),
            DIR_TOL,
        );
        assert_vec_close(
            "right eave",
            right.normals[1],
            right.geometric_normal(),
            DIR_TOL,
        );
    }

    #[test]
    fn mesh_transform_places_vertices() {
        let obj = "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n";
        let s = load_mesh(
            "transform",
            obj,
            "scale = 2.0\nrotate_y_deg = 90.0\ntranslate = [0.0, 0.0, 5.0]",
        );
        let [a, b, c] = s.triangles[0].vertices;
        // Right-handed +90 degrees about +Y takes +X to -Z and +Z to +X.
        assert_vec_close("x vertex", a, Vec3::new(0.0, 0.0, 3.0), POS_TOL);
        assert_vec_close("y vertex", b, Vec3::new(0.0, 2.0, 5.0), POS_TOL);
        assert_vec_close("z vertex", c, Vec3::new(2.0, 0.0, 5.0), POS_TOL);
    }

    #[test]
    fn vertex_normals_follow_the_rotation() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 1 0 0\nf 1//1 2//1 3//1\n";
        let s = load_mesh("vn-rot", obj, "rotate_y_deg = 90.0\nscale = 3.0");
        assert_vec_close(
            "rotated normal",
            s.triangles[0].normals[0],
            -Vec3::Z,
            DIR_TOL,
        );
    }

    #[test]
    fn content_hash_tracks_scene_and_obj_bytes() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let a = load_mesh("hash-a", obj, "");
        let b = load_mesh("hash-b", obj, "");
        assert_eq!(a.content_hash(), b.content_hash(), "same inputs, same hash");
        let c = load_mesh("hash-c", &format!("{obj}# edited\n"), "");
        assert_ne!(a.content_hash(), c.content_hash(), "OBJ bytes must count");
        let d = load_mesh("hash-d", obj, "scale = 1.0");
        assert_ne!(a.content_hash(), d.content_hash(), "scene text must count");
    }

    #[test]
    fn malformed_obj_names_file_and_line() {
        let dir = temp_dir("bad-obj");
        std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap();
        let text = mesh_scene("m.obj", "");
        let err = Scene::from_toml_str(&text, &dir.join("scene.toml"))
            .unwrap_err()
            .to_string();
        assert_mentions(&err, &["m.obj", "line 4", "out of range"]);

        std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 zero 0\n").unwrap();
        let err = Scene::from_toml_str(&text, &dir.join("scene.toml"))
            .unwrap_err()
            .to_string();
        assert_mentions(&err, &["m.obj", "line 2", "`zero`"]);

        std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 0 0\nf 1 2\n").unwrap();
        let err = Scene::from_toml_str(&text, &dir.join("scene.toml"))
            .unwrap_err()
            .to_string();
        assert_mentions(&err, &["m.obj", "line 3", "3 corners"]);
    }

    #[test]
    fn mesh_without_triangles_is_rejected() {
        let dir = temp_dir("empty-obj");
        // Only a degenerate face: no triangle with area.
        std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
        let text = mesh_scene("m.obj", "");
        let err = Scene::from_toml_str(&text, &dir.join("scene.toml"))
            .unwrap_err()
            .to_string();
        assert_mentions(
            &err,
            &[
                "shape[0].path",
                "no triangles",
                &format!(":{}", line_of(&text, "path =")),
            ],
        );
    }

    #[test]
    fn missing_obj_is_an_io_error_naming_it() {
        let dir = temp_dir("missing-obj");
        let text = mesh_scene("nowhere/bunny.obj", "");
        let err = Scene::from_toml_str(&text, &dir.join("scene.toml")).unwrap_err();
        assert!(matches!(err, PrtError::Io { .. }), "{err:?}");
        assert_mentions(&err.to_string(), &["nowhere/bunny.obj"]);
    }

    #[test]
    fn unknown_material_names_the_shape_field() {
        let text = CANONICAL.replace("material = \"clay\"", "material = \"cley\"");
        let err = load_err(&text);
        let line = line_of(&text, "\"cley\"");
        assert_mentions(
            &err,
            &["shape[1].material", "cley", &format!("test.toml:{line}:")],
        );
    }

    #[test]
    fn degenerate_cameras_are_rejected() {
        let eye_is_target =
            CANONICAL.replace("target = [0.0, 0.5, 0.0]", "target = [0.0, 1.5, 4.0]");
        let err = load_err(&eye_is_target);
        assert_mentions(
            &err,
            &[
                "camera.target",
                &format!(":{}:", line_of(&eye_is_target, "target =")),
            ],
        );

        let up_parallel = CANONICAL.replace("up = [0.0, 1.0, 0.0]", "up = [0.0, -1.0, -4.0]");
        let err = load_err(&up_parallel);
        assert_mentions(
            &err,
            &[
                "camera.up",
                "parallel",
                &format!(":{}:", line_of(&up_parallel, "up =")),
            ],
        );

        for fov in ["0.0", "180.0", "-5.0", "nan"] {
            let text = CANONICAL.replace("fov_y_deg = 40.0", &format!("fov_y_deg = {fov}"));
            assert_mentions(&load_err(&text), &["camera.fov_y_deg", ":5:"]);
        }

        let mut cam = canonical().camera;
        cam.up = Vec3::ZERO;
        assert_mentions(&cam.validate().unwrap_err().to_string(), &["camera.up"]);
    }

    #[test]
    fn image_size_is_bounded() {
        let err = load_err(&CANONICAL.replace("width = 256", "width = 0"));
        assert_mentions(&err, &["camera.width", ":6:"]);
        let err = load_err(&CANONICAL.replace("height = 256", "height = 16385"));
        assert_mentions(&err, &["camera.height", ":7:", "16384"]);
        let err = load_err(&CANONICAL.replace("width = 256", "width = -3"));
        assert_mentions(&err, &["camera.width", ":6:"]);
    }

    #[test]
    fn unknown_fields_are_typos() {
        let text = CANONICAL.replace("albedo = [0.8, 0.3, 0.2]", "albdo = [0.8, 0.3, 0.2]");
        let err = load_err(&text);
        assert_mentions(
            &err,
            &[
                "material.clay.albdo",
                &format!(":{}:", line_of(&text, "albdo")),
            ],
        );

        let text = CANONICAL.replace("radius = 0.6", "radius = 0.6\nradus = 0.6");
        let err = load_err(&text);
        assert_mentions(
            &err,
            &["shape[1].radus", &format!(":{}:", line_of(&text, "radus"))],
        );

        let text = format!("{CANONICAL}\n[fog]\ndensity = 1.0\n");
        let err = load_err(&text);
        assert_mentions(&err, &["`fog`", &format!(":{}:", line_of(&text, "[fog]"))]);

        let text = format!("{CANONICAL}\n[medium]\ndensity = 1.0\n");
        let err = load_err(&text);
        assert_mentions(
            &err,
            &[
                "medium.density",
                &format!(":{}:", line_of(&text, "density")),
            ],
        );

        // A key that exists, but for another shape type.
        let text = CANONICAL.replace("radius = 0.6", "radius = 0.6\nscale = 2.0");
        let err = load_err(&text);
        assert_mentions(
            &err,
            &[
                "shape[1].scale",
                "sphere",
                &format!(":{}:", line_of(&text, "scale")),
            ],
        );
    }

    #[test]
    fn schema_errors_name_field_and_line() {
        let text = CANONICAL.replace("radius = 0.6\n", "");
        assert_mentions(
            &load_err(&text),
            &[
                "shape[1].radius",
                &format!(":{}:", line_of(&text, "[[shape]]") + 5),
            ],
        );

        let text = CANONICAL.replace("type = \"sphere\"", "type = \"sphre\"");
        assert_mentions(&load_err(&text), &["shape[1].type", "sphre"]);

        let text = CANONICAL.replace(
            "type = \"diffuse\"\nalbedo = [0.8, 0.3",
            "type = \"shiny\"\nalbedo = [0.8, 0.3",
        );
        assert_mentions(&load_err(&text), &["material.clay.type", "shiny"]);

        let text = CANONICAL.replace(
            "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
            "type = \"glossy\"\nalbedo = [0.8, 0.3, 0.2]\nspecular = [0.5, 0.5, 0.5]\nroughness = 0.3",
        );
        assert_mentions(&load_err(&text), &["material.clay.specular", "at most 1"]);
        let text = CANONICAL.replace(
            "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
            "type = \"glossy\"\nalbedo = [0.4, 0.3, 0.2]\nspecular = [0.5, 0.5, 0.5]",
        );
        assert_mentions(&load_err(&text), &["material.clay.roughness"]);
        let text = CANONICAL.replace(
            "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
            "type = \"diffuse\"\nalbedo = [0.4, 0.3, 0.2]\nroughness = 0.5",
        );
        assert_mentions(&load_err(&text), &["material.clay.roughness", "glossy"]);

        let text = CANONICAL.replace("eye = [0.0, 1.5, 4.0]", "eye = [0.0, 1.5]");
        assert_mentions(&load_err(&text), &["camera.eye", ":2:"]);

        let text = CANONICAL.replace("width = 256", "width = 256 256");
        assert_mentions(&load_err(&text), &[":6:"]);
    }

    #[test]
    fn bad_numbers_are_rejected() {
        let text = CANONICAL.replace("radius = 0.6", "radius = -0.6");
        assert_mentions(
            &load_err(&text),
            &[
                "shape[1].radius",
                &format!(":{}:", line_of(&text, "radius")),
            ],
        );
        let text = CANONICAL.replace("radius = 0.6", "radius = 0.0");
        assert_mentions(&load_err(&text), &["shape[1].radius"]);
        let text = CANONICAL.replace("center = [0.0, 0.6, 0.0]", "center = [0.0, inf, 0.0]");
        assert_mentions(&load_err(&text), &["shape[1].center", "finite"]);
        let text = CANONICAL.replace("eye = [0.0, 1.5, 4.0]", "eye = [0.0, 1.5, 1e39]");
        assert_mentions(&load_err(&text), &["camera.eye", "finite"]);
        let text = CANONICAL.replace("albedo = [0.8, 0.3, 0.2]", "albedo = [0.8, 1.3, 0.2]");
        assert_mentions(&load_err(&text), &["material.clay.albedo", "[0, 1]"]);
        let text = CANONICAL.replace("albedo = [0.8, 0.3, 0.2]", "albedo = [0.8, -0.1, 0.2]");
        assert_mentions(&load_err(&text), &["material.clay.albedo"]);
        let text = CANONICAL.replace(
            "[2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]",
            "[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0]]",
        );
        assert_mentions(&load_err(&text), &["shape[0].corners", "zero area"]);
    }

    #[test]
    fn scene_without_shapes_is_rejected() {
        let text = CANONICAL.split("[[shape]]").next().unwrap();
        assert_mentions(&load_err(text), &["`shape`", "no shapes"]);
    }
}
