//! The scene file: its TOML schema, and the loader that flattens shapes into what the tracer
//! needs, naming the line and field of every problem through [`super::diagnostics`].

use super::diagnostics::SourceMap;
use super::hash::Fnv1a;
use super::obj::{MeshTransform, ObjData, flat_triangle, mesh_triangles, parse_obj};
use super::*;
use glam::Mat4;

/// The optional keys of a table, each with whether the table has it, for checking they suit its
/// type: `present!(self; corners radius)`. A key's name is its field's.
macro_rules! present {
    ($table:expr; $($key:ident)+) => {
        [$((stringify!($key), $table.$key.is_some())),+]
    };
}

mod lights;
mod medium;
mod numbers;

use medium::MediumFile;
pub use numbers::MAX_COORDINATE;
use numbers::{finite3, numbers, position3, some_numbers, some_points};

// ---------------------------------------------------------------------------------------------
// Scene file schema. Shapes and materials are flat structs with a `type` key rather than serde
// tagged enums: tagged enums buffer their content, which loses the spans toml needs to point at
// the offending line. Which keys apply to which type is checked by hand instead.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    /// Longest triangle edge of a per-vertex bake.
    edge_length: Option<f32>,
    camera: CameraFile,
    #[serde(default)]
    material: BTreeMap<String, MaterialFile>,
    #[serde(default)]
    shape: Vec<ShapeFile>,
    medium: Option<MediumFile>,
    #[serde(default)]
    light: Vec<lights::LightFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    #[serde(deserialize_with = "numbers")]
    eye: [f32; 3],
    #[serde(deserialize_with = "numbers")]
    target: [f32; 3],
    #[serde(deserialize_with = "numbers")]
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
    #[serde(default, deserialize_with = "some_numbers")]
    albedo: Option<[f32; 3]>,
    #[serde(default, deserialize_with = "some_numbers")]
    specular: Option<[f32; 3]>,
    roughness: Option<f32>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Debug)]
#[serde(rename_all = "lowercase")]
enum ShapeKind {
    Quad,
    Sphere,
    Mesh,
    Gltf,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShapeFile {
    r#type: ShapeKind,
    material: Option<String>,
    #[serde(default, deserialize_with = "some_points")]
    corners: Option<[[f32; 3]; 4]>,
    #[serde(default, deserialize_with = "some_numbers")]
    center: Option<[f32; 3]>,
    radius: Option<f32>,
    path: Option<String>,
    scale: Option<f32>,
    rotate_y_deg: Option<f32>,
    #[serde(default, deserialize_with = "some_numbers")]
    translate: Option<[f32; 3]>,
    smooth_normals: Option<bool>,
}

impl ShapeFile {
    /// The optional keys present in this table, for checking they suit its type.
    fn present_keys(&self) -> [(&'static str, bool); 9] {
        present!(self; material corners center radius path scale rotate_y_deg translate
            smooth_normals)
    }
}

impl ShapeKind {
    fn name(self) -> &'static str {
        match self {
            ShapeKind::Quad => "quad",
            ShapeKind::Sphere => "sphere",
            ShapeKind::Mesh => "mesh",
            ShapeKind::Gltf => "gltf",
        }
    }

    fn allowed_keys(self) -> &'static [&'static str] {
        match self {
            ShapeKind::Quad => &["material", "corners"],
            ShapeKind::Sphere => &["material", "center", "radius"],
            // A glTF file brings its own materials.
            ShapeKind::Gltf => &["path", "scale", "rotate_y_deg", "translate"],
            ShapeKind::Mesh => &[
                "material",
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

fn kind_name(k: &MaterialKind) -> &'static str {
    match k {
        MaterialKind::Diffuse => "diffuse",
        MaterialKind::Glossy => "glossy",
    }
}

pub(super) struct Loader<'a> {
    text: &'a str,
    map: SourceMap,
    base_dir: PathBuf,
    hasher: Fnv1a,
    /// OBJ files already read, by resolved path, so a mesh used twice is parsed once.
    obj_cache: HashMap<PathBuf, (Vec<u8>, ObjData)>,
    /// Files read besides the scene text (meshes, a grid), in load order.
    inputs: Vec<PathBuf>,
    /// The scene's glTF files, each read once, held together to one file's limits.
    gltf_files: super::gltf::GltfFiles,
    /// The first material and texture of each glTF file placed, by its canonical path.
    gltf_offsets: HashMap<PathBuf, (u32, u32)>,
}

/// What a scene is built from as its shapes are read: materials (a glTF file's added after the
/// scene file's own), textures, lights, triangles and spheres, and the named surfaces.
#[derive(Default)]
struct Built {
    materials: Vec<Material>,
    material_maps: Vec<Option<TexturedMaterial>>,
    material_names: Vec<String>,
    textures: Vec<texture::Texture>,
    lights: Vec<Light>,
    /// glTF features the loader passes over, by name.
    ignored: std::collections::BTreeSet<String>,
    /// A glTF file's surfaces, moved to `surfaces` once its shape is read.
    surfaces_from_gltf: Vec<(std::ops::Range<usize>, String)>,
    triangles: Vec<Triangle>,
    spheres: Vec<Sphere>,
    surfaces: Vec<std::ops::Range<usize>>,
    surface_names: Vec<String>,
}

impl<'a> Loader<'a> {
    pub(super) fn new(text: &'a str, path: &Path) -> Result<Self> {
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
            gltf_files: super::gltf::GltfFiles::new(false),
            gltf_offsets: HashMap::new(),
        })
    }

    /// Lets the scene's glTF files read outside their own folders
    /// ([`crate::scene::Framing::read_outside_folder`]).
    pub(super) fn reading_outside_folders(mut self, allowed: bool) -> Self {
        self.gltf_files = super::gltf::GltfFiles::new(allowed);
        self
    }

    pub(super) fn load(mut self) -> Result<Scene> {
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
        if let Some(e) = file.edge_length
            && !(e.is_finite() && e > 0.0 && e <= MAX_COORDINATE)
        {
            return Err(self.map.error(
                "edge_length",
                format!("must be a length > 0 and <= {MAX_COORDINATE:e}, got {e}"),
            ));
        }
        let lights = self.lights(&file.light)?;
        let mut b = Built {
            material_maps: vec![None; materials.len()],
            materials,
            material_names,
            lights,
            ..Built::default()
        };
        for (i, shape) in file.shape.iter().enumerate() {
            self.shape(i, shape, &mut b)?;
        }

        Ok(Scene {
            camera,
            material_maps: b.material_maps,
            materials: b.materials,
            material_names: b.material_names,
            textures: b.textures,
            triangles: b.triangles,
            surfaces: b.surfaces,
            surface_names: b.surface_names,
            edge_length: file.edge_length,
            spheres: b.spheres,
            medium,
            lights: b.lights,
            source_path: self.map.file.clone(),
            input_files: std::iter::once(self.map.file.clone())
                .chain(self.inputs)
                .collect(),
            ignored: b.ignored.into_iter().collect(),
            content_hash: self.hasher.0,
        })
    }

    /// Adds shape `i` of the scene file to what the scene is `b`uilding from.
    fn shape(&mut self, i: usize, shape: &ShapeFile, b: &mut Built) -> Result<()> {
        let first_triangle = b.triangles.len();
        let field = |key: &str| format!("shape[{i}].{key}");
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
        if shape.r#type != ShapeKind::Gltf {
            require("material", shape.material.is_some())?;
        }
        let material = match &shape.material {
            Some(name) => self.material_index(&b.material_names, name, &field("material"))?,
            None => 0,
        };
        match shape.r#type {
            ShapeKind::Gltf => {
                require("path", shape.path.is_some())?;
                let data = self.gltf(i, shape)?;
                let (first_material, first_texture) = if data.first_placement {
                    let first = (b.materials.len() as u32, b.textures.len() as u32);
                    self.gltf_offsets.insert(data.key.clone(), first);
                    first
                } else {
                    self.gltf_offsets
                        .get(&data.key)
                        .copied()
                        .unwrap_or_default()
                };
                for m in data.materials {
                    b.materials.push(m.material);
                    b.material_maps.push(m.maps.map(|mut maps| {
                        for t in [
                            &mut maps.base_color_texture,
                            &mut maps.metallic_roughness_texture,
                        ] {
                            *t = t.map(|t| t + first_texture);
                        }
                        maps
                    }));
                    b.material_names.push(format!(
                        "{}:{}",
                        shape.path.as_deref().unwrap_or_default(),
                        m.name
                    ));
                }
                b.textures.extend(data.textures);
                for l in data.lights {
                    if b.lights.iter().any(|k: &Light| k.name == l.name) {
                        return Err(self.map.error(
                            &field("path"),
                            format!("its light `{}` has the name of another light", l.name),
                        ));
                    }
                    b.lights.push(l);
                    let columns: usize = b.lights.iter().map(Light::columns).sum();
                    if columns > crate::scene::light::MAX_LIGHT_COLUMNS {
                        return Err(self.map.error(
                            &field("path"),
                            format!(
                                "its lights take the scene past {} light columns",
                                crate::scene::light::MAX_LIGHT_COLUMNS
                            ),
                        ));
                    }
                }
                b.ignored.extend(data.ignored);
                for (range, name) in data.surfaces {
                    let offset = b.triangles.len();
                    b.surfaces_from_gltf.push((
                        range.start + offset..range.end + offset,
                        format!("shape[{i}] {name}"),
                    ));
                }
                b.triangles.extend(data.triangles.into_iter().map(|mut t| {
                    t.material += first_material;
                    t
                }));
            }
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
                b.spheres.push(Sphere {
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
                let before = b.triangles.len();
                for corners in [[c[0], c[1], c[2]], [c[0], c[2], c[3]]] {
                    if let Some(tri) = flat_triangle(corners, material) {
                        b.triangles.push(tri);
                    }
                }
                if b.triangles.len() == before {
                    return Err(self.map.error(&field("corners"), "the quad has zero area"));
                }
            }
            ShapeKind::Mesh => {
                require("path", shape.path.is_some())?;
                let mesh = self.mesh(i, shape, material)?;
                b.triangles.extend(mesh);
            }
        }
        if shape.r#type == ShapeKind::Gltf {
            for (range, name) in b.surfaces_from_gltf.drain(..) {
                b.surfaces.push(range);
                b.surface_names.push(name);
            }
        } else if b.triangles.len() > first_triangle {
            b.surfaces.push(first_triangle..b.triangles.len());
            b.surface_names.push(match &shape.path {
                Some(p) => format!("shape[{i}] ({p})"),
                None => format!("shape[{i}]"),
            });
        }
        Ok(())
    }

    /// The index of material `name`, or an error listing those defined.
    fn material_index(&self, names: &[String], name: &str, field: &str) -> Result<u32> {
        names
            .iter()
            .position(|n| n == name)
            .map(|i| i as u32)
            .ok_or_else(|| {
                let known = crate::names::known(
                    names.iter().map(String::as_str),
                    "none are defined",
                    "defined:",
                );
                self.map
                    .error(field, format!("unknown material `{name}` ({known})"))
            })
    }

    /// A `type = "gltf"` shape's file, placed by the shape's transform.
    fn gltf(&mut self, index: usize, shape: &ShapeFile) -> Result<super::gltf::GltfData> {
        let transform = self.transform(index, shape)?;
        let placement = Mat4::from_translation(transform.translate)
            * Mat4::from_mat3(transform.rotation)
            * Mat4::from_scale(Vec3::splat(transform.scale));
        let path = self
            .base_dir
            .join(shape.path.as_deref().unwrap_or_default());
        let data = self.gltf_files.place(&path, placement)?;
        self.hasher.write(&data.hash.to_le_bytes());
        self.inputs.extend(data.files.iter().cloned());
        Ok(data)
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

    /// A mesh or glTF shape's placement: `scale`, `rotate_y_deg`, `translate`.
    fn transform(&self, index: usize, shape: &ShapeFile) -> Result<MeshTransform> {
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
        Ok(MeshTransform {
            scale,
            rotation: Mat3::from_rotation_y(rotate_y_deg.to_radians()),
            translate,
        })
    }

    fn mesh(&mut self, index: usize, shape: &ShapeFile, material: u32) -> Result<Vec<Triangle>> {
        let field = |key: &str| format!("shape[{index}].{key}");
        let transform = self.transform(index, shape)?;
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
