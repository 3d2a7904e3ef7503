//! glTF 2.0 scenes, `.gltf` (with external or embedded buffers) and `.glb`: the node hierarchy
//! with its transforms, indexed triangle meshes with normals and `TEXCOORD_0`, perspective
//! cameras, `KHR_lights_punctual` lights, and `pbrMetallicRoughness` materials with their
//! base-colour and metallic-roughness textures.
//!
//! The `gltf` crate parses and validates the JSON (every index in range). Everything that
//! touches binary data is checked here before it is read: each buffer holds the bytes it
//! declares, each view lies inside its buffer, each accessor inside its view, each index names a
//! vertex, and every image's size is known before it is decoded. Errors name the file, the glTF
//! object (`meshes[3].primitives[1]`, accessor 7) and the field. What a file has that this engine
//! does not use (emission, normal maps, ...) is listed once, for one warning per file.

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};

use super::texture::Texture;
use super::{Material, TexturedMaterial, Triangle};
use crate::error::{PrtError, Result};
use crate::scene::light::Light;

/// Largest glTF file, and largest external buffer or image it names.
pub const MAX_GLTF_BYTES: u64 = 2 << 30;

/// Largest number of triangles one file may produce (after instancing): 64 M triangles of
/// 120 bytes each is already 7.7 GB.
const MAX_TRIANGLES: usize = 64 << 20;

/// Lumens per watt at 555 nm, by which glTF's photometric light units (candela, lux) become
/// this engine's radiometric ones (W/sr, W/m²), as Blender's exporter converts them.
pub const LUMENS_PER_WATT: f32 = 683.0;

/// A perspective camera found in the file, placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfCamera {
    /// The camera's name, or `camera N` for an unnamed one.
    pub name: String,
    /// Where the node puts it.
    pub eye: Vec3,
    /// Unit view direction (the node's −Z).
    pub forward: Vec3,
    /// Unit up direction (the node's +Y).
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
    /// Width over height, when the file gives it.
    pub aspect: Option<f32>,
}

/// One material of the file as this engine holds it.
pub(super) struct GltfMaterial {
    pub(super) name: String,
    pub(super) material: Material,
    pub(super) maps: Option<TexturedMaterial>,
}

/// Everything a glTF file contributes to a scene. Material indices of the triangles and texture
/// indices of the materials are local to it.
pub(super) struct GltfData {
    pub(super) triangles: Vec<Triangle>,
    /// Triangle range and name (`mesh 2 (Box) primitive 0 at node 4`) of each placed primitive.
    pub(super) surfaces: Vec<(std::ops::Range<usize>, String)>,
    pub(super) materials: Vec<GltfMaterial>,
    pub(super) textures: Vec<Texture>,
    pub(super) cameras: Vec<GltfCamera>,
    pub(super) lights: Vec<Light>,
    /// What the file has that is not used, one line each.
    pub(super) ignored: BTreeSet<String>,
    /// Every file read: the glTF, then its external buffers and images (on the first placement
    /// only).
    pub(super) files: Vec<PathBuf>,
    /// FNV-1a over the bytes of every file read, in order: the scene's content hash takes it.
    pub(super) hash: u64,
    /// The file's canonical path, which names it however a scene spells it.
    pub(super) key: PathBuf,
    /// Whether this is the file's first placement in the scene: later ones bring no materials
    /// or textures, and their triangles name the first placement's materials.
    pub(super) first_placement: bool,
}

/// Largest number of texels the textures of one file may decode to (768 MiB of RGB).
pub const MAX_TEXELS: u64 = 1 << 28;

/// The glTF files of one scene: each read, parsed and decoded once however many shapes name
/// it, and all of them held together to the limits of one file, so that neither many files nor
/// one file named many times can multiply the work or the memory.
pub(in crate::scene) struct GltfFiles {
    /// Bytes the scene's glTF files and their resources may still take, all together.
    bytes_left: u64,
    /// Texels the scene's textures may still decode to.
    texels_left: u64,
    /// Triangle corners the scene's primitives may still make, counting every instance and the
    /// triangles without area, so that instancing cannot multiply the work without end.
    corners_left: u64,
    /// Whether a URI may name a file outside its glTF file's folder.
    outside_folder: bool,
    /// Every file read, by canonical path: a resource shared by several files is read once.
    bytes: HashMap<PathBuf, std::sync::Arc<[u8]>>,
    /// Every glTF file parsed, by canonical path.
    parsed: HashMap<PathBuf, GltfFile>,
}

impl GltfFiles {
    /// No file read yet; URIs may leave their file's folder only when `outside_folder` is set.
    pub(in crate::scene) fn new(outside_folder: bool) -> GltfFiles {
        GltfFiles {
            bytes_left: MAX_GLTF_BYTES,
            texels_left: MAX_TEXELS,
            corners_left: 3 * MAX_TRIANGLES as u64,
            outside_folder,
            bytes: HashMap::new(),
            parsed: HashMap::new(),
        }
    }

    /// The glTF file at `path` placed with `placement`: its default scene (or its first, or
    /// every root node when it names none). The file is read and parsed on its first placement;
    /// later ones reuse its buffers, materials and textures, and return no materials or textures
    /// of their own (their triangles' material indices are the first placement's).
    pub(in crate::scene) fn place(&mut self, path: &Path, placement: Mat4) -> Result<GltfData> {
        let key = std::fs::canonicalize(path).map_err(|e| PrtError::io(path, e))?;
        let first = !self.parsed.contains_key(&key);
        let mut file = match self.parsed.remove(&key) {
            Some(file) => file,
            None => self.open(path, &key)?,
        };
        let placed = file.place(path, placement, self);
        self.parsed.insert(key.clone(), file);
        let mut data = placed?;
        data.key = key;
        data.first_placement = first;
        Ok(data)
    }

    /// Reads, parses and checks the glTF file at `path` (canonically `key`) and its buffers.
    fn open(&mut self, path: &Path, key: &Path) -> Result<GltfFile> {
        let limit = self.bytes_left;
        let bytes = crate::files::read_regular(path, limit, "glTF file")?;
        self.bytes_left -= bytes.len() as u64;
        let mut hasher = crate::scene::hash::Fnv1a::new();
        hasher.write_chunk(&bytes);
        // A GLB header whose length is below the header's own 12 bytes underflows in the crate.
        if bytes.starts_with(b"glTF")
            && bytes
                .get(8..12)
                .is_none_or(|l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]) < 12)
        {
            return Err(PrtError::file(
                path,
                "not a usable glTF 2.0 file: the GLB header's length is shorter than the header",
            ));
        }
        let gltf = parse(&bytes)
            .map_err(|e| PrtError::file(path, format!("not a usable glTF 2.0 file: {e}")))?;
        drop(bytes);
        let mut file = GltfFile {
            doc: gltf.document,
            st: FileState {
                base: key.parent().map(Path::to_path_buf).unwrap_or_default(),
                buffers: Vec::new(),
                files_read: HashMap::new(),
                hasher,
                material_index: HashMap::new(),
                texture_index: HashMap::new(),
                ignored: BTreeSet::new(),
                files: vec![path.to_path_buf()],
            },
        };
        let mut reader = Reader::new(path, &file.doc, &mut file.st, self);
        reader.check_extensions()?;
        let blob: Option<std::sync::Arc<[u8]>> = gltf.blob.as_deref().map(std::sync::Arc::from);
        reader.load_buffers(blob)?;
        let ignored = std::mem::take(&mut reader.out.ignored);
        let files = std::mem::take(&mut reader.out.files);
        file.st.ignored.extend(ignored);
        file.st.files.extend(files);
        Ok(file)
    }
}

/// A glTF file parsed, with its buffers read and what its placements have made so far.
struct GltfFile {
    doc: gltf::Document,
    st: FileState,
}

/// What a glTF file's placements share and add to.
struct FileState {
    /// The file's folder, canonical: its URIs may name files in it and below.
    base: PathBuf,
    /// Each buffer's bytes, at least its declared length (the GLB chunk and files read once,
    /// shared by every buffer that names them).
    buffers: Vec<std::sync::Arc<[u8]>>,
    /// This file's resources already read, by canonical path.
    files_read: HashMap<PathBuf, std::sync::Arc<[u8]>>,
    /// The content hash of everything read.
    hasher: crate::scene::hash::Fnv1a,
    /// This engine's material of each glTF material (`None`: the default material).
    material_index: HashMap<Option<usize>, u32>,
    /// This engine's texture of each (glTF image, sampler, encoding).
    texture_index: HashMap<(usize, Option<usize>, bool), u32>,
    /// What the file has that is not used, found on reading it.
    ignored: BTreeSet<String>,
    /// The files read for the first placement: the glTF, then its external resources.
    files: Vec<PathBuf>,
}

impl GltfFile {
    fn place(&mut self, path: &Path, placement: Mat4, files: &mut GltfFiles) -> Result<GltfData> {
        let mut reader = Reader::new(path, &self.doc, &mut self.st, files);
        reader.walk(placement)?;
        if reader.out.triangles.is_empty() {
            return Err(reader.error("meshes", "the scene has no triangles with non-zero area"));
        }
        if reader.duplicates > 0 {
            reader.out.ignored.insert(format!(
                "{} triangles that repeat another exactly (each is made once)",
                reader.duplicates
            ));
        }
        let mut out = reader.out;
        out.hash = self.st.hasher.0;
        out.ignored.extend(self.st.ignored.iter().cloned());
        let mut files = std::mem::take(&mut self.st.files);
        files.append(&mut out.files);
        out.files = files;
        Ok(out)
    }
}

/// Reads the glTF file at `path` alone, placing its default scene with `placement`
/// (see [`GltfFiles::place`]).
pub(super) fn read(path: &Path, placement: Mat4, outside_folder: bool) -> Result<GltfData> {
    GltfFiles::new(outside_folder).place(path, placement)
}

/// Parses and validates a glTF document. The `gltf` crate's validation itself looks up each
/// primitive's `POSITION` accessor without checking its index, so those are checked first.
fn parse(bytes: &[u8]) -> std::result::Result<gltf::Gltf, String> {
    use gltf::json::validation::Validate;
    let gltf = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())?;
    let root = gltf.document.as_json();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= root.accessors.len() {
                    return Err(format!(
                        "meshes[{m}].primitives[{p}].attributes: {semantic:?} names accessor {}, \
                         but there are {}",
                        index.value(),
                        root.accessors.len()
                    ));
                }
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        errors.push(format!("{}: {error}", path()))
    });
    if let Some(i) = root
        .images
        .iter()
        .position(|im| im.uri.is_none() && (im.buffer_view.is_none() || im.mime_type.is_none()))
    {
        errors.push(format!(
            "images[{i}]: needs a uri, or a bufferView and a mimeType"
        ));
    }
    for (i, im) in root.images.iter().enumerate() {
        if im.buffer_view.is_some() && im.mime_type.is_none() {
            errors.push(format!("images[{i}]: a bufferView needs a mimeType"));
        }
    }
    if errors.is_empty() {
        Ok(gltf)
    } else {
        Err(format!("invalid glTF: {}", errors.join("; ")))
    }
}

struct Reader<'a> {
    path: &'a Path,
    doc: &'a gltf::Document,
    /// What the file's placements share.
    st: &'a mut FileState,
    /// The scene's limits and its files.
    limits: &'a mut GltfFiles,
    /// Names the lights have taken.
    light_names: std::collections::HashSet<String>,
    /// Each triangle made, by a hash of its bits: the index of the first with that hash.
    seen_triangles: HashMap<u64, usize>,
    /// Triangles left out for repeating another exactly.
    duplicates: usize,
    out: GltfData,
}

impl<'a> Reader<'a> {
    fn new(
        path: &'a Path,
        doc: &'a gltf::Document,
        st: &'a mut FileState,
        limits: &'a mut GltfFiles,
    ) -> Self {
        Reader {
            path,
            doc,
            st,
            limits,
            light_names: Default::default(),
            seen_triangles: HashMap::new(),
            duplicates: 0,
            out: GltfData {
                triangles: Vec::new(),
                surfaces: Vec::new(),
                materials: Vec::new(),
                textures: Vec::new(),
                cameras: Vec::new(),
                lights: Vec::new(),
                ignored: BTreeSet::new(),
                files: Vec::new(),
                hash: 0,
                key: PathBuf::new(),
                first_placement: true,
            },
        }
    }

    /// Refuses a file that requires an extension this engine lacks, and notes what it has
    /// that is not used.
    fn check_extensions(&mut self) -> Result<()> {
        for ext in self.doc.extensions_required() {
            if ext != "KHR_lights_punctual" {
                return Err(self.error(
                    "extensionsRequired",
                    format!("needs the extension {ext}, which is not supported"),
                ));
            }
        }
        let json = self.doc.as_json();
        for (what, present) in [
            (
                "animation (nodes keep their rest pose)",
                !json.animations.is_empty(),
            ),
            (
                "skins (meshes keep their bind pose)",
                !json.skins.is_empty(),
            ),
            (
                "vertex colours (COLOR_0)",
                json.meshes.iter().flat_map(|m| &m.primitives).any(|p| {
                    p.attributes.keys().any(|k| {
                        matches!(
                            k,
                            gltf::json::validation::Checked::Valid(gltf::Semantic::Colors(_))
                        )
                    })
                }),
            ),
            (
                "morph targets",
                json.meshes
                    .iter()
                    .flat_map(|m| &m.primitives)
                    .any(|p| p.targets.is_some()),
            ),
        ] {
            if present {
                self.out.ignored.insert(what.to_string());
            }
        }
        for ext in self.doc.extensions_used() {
            if ext != "KHR_lights_punctual" {
                self.out.ignored.insert(format!("the extension {ext}"));
            }
        }
        Ok(())
    }
}

impl Reader<'_> {
    pub(super) fn error(&self, field: impl Into<String>, message: impl Into<String>) -> PrtError {
        PrtError::Scene {
            path: self.path.to_path_buf(),
            line: None,
            field: field.into(),
            message: message.into(),
        }
    }

    /// The bytes a URI names: a base64 `data:` URI, or a file in the glTF's folder or below
    /// (read once however many buffers, images and files name it). The path is decoded, then
    /// resolved with its links and `..`; one that lands outside the folder is refused unless
    /// the scene was loaded with [`Framing::read_outside_folder`].
    pub(super) fn uri_bytes(&mut self, uri: &str, field: &str) -> Result<std::sync::Arc<[u8]>> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((_, data)) = rest.split_once(";base64,") else {
                return Err(self.error(field, "a data URI must be base64 (`;base64,`)"));
            };
            let bytes = decode_base64(data)
                .ok_or_else(|| self.error(field, "the data URI is not valid base64"))?;
            return Ok(bytes.into());
        }
        let relative = percent_decode(uri)
            .filter(|r| !r.contains('\0'))
            .ok_or_else(|| self.error(field, format!("`{}` is not a valid URI", printable(uri))))?;
        if relative.contains("://") || Path::new(&relative).is_absolute() {
            return Err(self.error(
                field,
                format!(
                    "`{}`: only data URIs and paths relative to the file are read",
                    printable(uri)
                ),
            ));
        }
        let named = self.st.base.join(&relative);
        let path = std::fs::canonicalize(&named).map_err(|e| {
            self.error(
                field,
                format!("`{}` names {}: {e}", printable(uri), named.display()),
            )
        })?;
        if !self.limits.outside_folder && !path.starts_with(&self.st.base) {
            return Err(self.error(
                field,
                format!(
                    "`{}` resolves to {}, outside the folder of the glTF file ({}): a glTF \
                     file reads only files in its own folder and below, links followed; pass \
                     --read-outside-folder to read it anyway",
                    printable(uri),
                    path.display(),
                    self.st.base.display()
                ),
            ));
        }
        if let Some(bytes) = self.st.files_read.get(&path) {
            return Ok(bytes.clone());
        }
        let bytes = match self.limits.bytes.get(&path) {
            Some(bytes) => bytes.clone(),
            None => {
                let bytes = crate::files::read_regular(
                    &path,
                    self.limits.bytes_left,
                    "scene's glTF files and their resources",
                )?;
                self.limits.bytes_left -= bytes.len() as u64;
                let bytes: std::sync::Arc<[u8]> = bytes.into();
                self.limits.bytes.insert(path.clone(), bytes.clone());
                bytes
            }
        };
        self.st.hasher.write_chunk(&bytes);
        self.st.files_read.insert(path.clone(), bytes.clone());
        self.out.files.push(path);
        Ok(bytes)
    }

    fn load_buffers(&mut self, blob: Option<std::sync::Arc<[u8]>>) -> Result<()> {
        for buffer in self.doc.buffers() {
            let i = buffer.index();
            let field = format!("buffers[{i}]");
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => blob.clone().ok_or_else(|| {
                    self.error(&field, "refers to a GLB binary chunk the file lacks")
                })?,
                gltf::buffer::Source::Uri(uri) => self.uri_bytes(uri, &format!("{field}.uri"))?,
            };
            if data.len() < buffer.length() {
                return Err(self.error(
                    format!("{field}.byteLength"),
                    format!(
                        "declares {} bytes but holds {}",
                        buffer.length(),
                        data.len()
                    ),
                ));
            }
            self.st.buffers.push(data);
        }
        for view in self.doc.views() {
            let end = view.offset().checked_add(view.length());
            let held = self.st.buffers[view.buffer().index()].len();
            if end.is_none_or(|e| e > held) {
                return Err(self.error(
                    format!("bufferViews[{}]", view.index()),
                    format!(
                        "bytes {} + {} run past the end of buffer {} ({held} bytes)",
                        view.offset(),
                        view.length(),
                        view.buffer().index()
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// A name from the file, with control characters replaced, for messages.
fn printable(text: &str) -> String {
    crate::files::printable(text)
}

mod accessors;
mod framing;
mod materials;
mod mesh;
mod nodes;
mod uri;

use uri::{decode_base64, percent_decode};

pub use framing::{DEFAULT_WIDTH, Framing};
pub(super) use framing::{hash_camera, scene};
