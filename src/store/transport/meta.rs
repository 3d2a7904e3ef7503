//! Everything a transport file says besides its arrays: the image and camera, the bake's
//! identity (every choice that decides the stored values) and the bake's figures.
//!
//! In memory the metadata is structured ([`TransportMeta`] holds a [`BakeIdentity`]); in the
//! file it is one flat JSON object whose fields are listed in [`super`]'s documentation. The
//! private [`MetaFile`] is that flat form, so the file's layout stays what readers outside this
//! crate (Python, older builds) expect, whatever the types here become.

use serde::{Deserialize, Serialize};
use strum::{IntoStaticStr, VariantArray};

use glam::Vec3;

use crate::names::Named;
use crate::scene::light::{Light, LightKind, LightShape};
use crate::store::budget::Budget;
use crate::store::quant::Quantization;

/// Camera of the baked view, as written in the file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraMeta {
    /// Position of the eye (world units).
    pub eye: [f32; 3],
    /// Point the camera looks at.
    pub target: [f32; 3],
    /// Up direction.
    pub up: [f32; 3],
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
}

/// Figures of a bake.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BakeStats {
    /// Transport rows.
    pub rows: u64,
    /// Stored nonzero Haar coefficients.
    pub nonzeros: u64,
    /// rows x 6 N², what a dense matrix would hold.
    pub dense_entries: u64,
    /// Sum over rows of the squared norm of what thresholding and quantisation changed, over the
    /// sum of squared norms: the relative L2 (squared) the storage removed from the transport.
    pub dropped_energy_fraction: f64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
}

/// Where the visibility of an interreflection vertex comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[derive(Serialize, Deserialize, IntoStaticStr, strum::Display, VariantArray)]
#[serde(rename_all = "kebab-case")]
#[strum(serialize_all = "kebab-case")]
pub enum BounceVisibility {
    /// One bit per texel sample at surface cache points a few pixel footprints apart.
    #[default]
    Cache,
    /// 6 N² shadow rays traced at every vertex.
    Exact,
}

crate::named!(BounceVisibility, "bounce visibility");

/// How a bake's interreflections were estimated: next-event estimation into the row at every
/// path vertex (see `bake::bounce`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndirectSettings {
    /// Where each vertex's visibility came from.
    pub visibility: BounceVisibility,
    /// Width of a cache cell in pixel footprints at the view's median depth.
    pub cache_spacing: f32,
}

/// What a bake's rows belong to. In a settings file: `"view"`, or per vertex
/// `{"vertices": {"edge_length": 0.05}}` (JSON; in TOML `[domain.vertices]` and its
/// `edge_length`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BakeDomain {
    /// The pixels of the scene camera's view.
    View,
    /// The vertices of the scene tessellated to this longest edge (scene units), each vertex
    /// "pixel" `v` of an image [`super::TILE`] wide (see [`PerVertexMeta`]).
    Vertices {
        /// The longest edge the tessellation allowed; refined at shadow edges
        /// ([`BakeIdentity::refine_shadows`]), the length whose uniform tessellation sets its
        /// vertex count.
        edge_length: f32,
    },
}

impl BakeDomain {
    /// The tessellation's longest edge of a per-vertex bake; `None` for a view.
    pub fn edge_length(self) -> Option<f32> {
        match self {
            BakeDomain::Vertices { edge_length } => Some(edge_length),
            BakeDomain::View => None,
        }
    }
}

/// How a transport was baked: every choice its file records that decides the stored values, in
/// the form they are stored. The bake's settings give it for a scene
/// (`bake::BakeSettings::identity`, where the rules live: a lossless bake stores threshold 0,
/// texel samples are a square, and so on) and a file is reused for a bake exactly when its
/// identity is equal. Its fields twin `bake::BakeSettings`' by design, in the form a file
/// stores them (the store cannot see the bake's settings).
#[derive(Clone, Debug, PartialEq)]
pub struct BakeIdentity {
    /// FNV-1a hash of the scene text and its meshes, hex (`Scene::hash_hex`).
    pub scene_hash: String,
    /// Cube face size N of the texel lights.
    pub cube_n: u32,
    /// SH order of the SH transport (n² coefficients a row).
    pub sh_order: u32,
    /// Sub-pixel samples per pixel (per vertex: 1).
    pub spp: u32,
    /// Sub-pixel samples of the pixels whose corners see different things (0: every pixel took
    /// `spp`).
    pub edge_spp: u32,
    /// Shadow-ray directions per texel light (a square).
    pub texel_samples: u32,
    /// Sub-texels of a texel integrated rather than sampled at its centre (a square; 0: every
    /// texel took its centre's value, as every file before this setting).
    pub edge_texel_samples: u32,
    /// Whether a shadow-border texel traced only its sub-texels towards the border (false:
    /// every sub-texel, as files before this rule did, or no sub-texels at all).
    pub edge_texels_towards: bool,
    /// Whether visibility was ignored.
    pub unshadowed: bool,
    /// Seed of every random choice.
    pub seed: u64,
    /// Thresholding parameter (0 = keep every nonzero); its meaning is `budget`'s.
    pub threshold: f32,
    /// How the thresholding budget weighs coefficients.
    pub budget: Budget,
    /// How the kept values are stored.
    pub quantization: Quantization,
    /// `[index, count]` for one shard of a sharded bake (it holds only its band of tile rows);
    /// `None` for a whole bake or a merge of all shards.
    pub shard: Option<[u32; 2]>,
    /// Interreflection bounces baked in (0: direct light only).
    pub bounces: u32,
    /// Paths per camera sub-sample for the interreflections (0 without them).
    pub paths: u32,
    /// How the interreflections were estimated; `None` without them, and in files baked before
    /// next-event estimation, whose paths each brought the light of the one texel they left by.
    pub indirect: Option<IndirectSettings>,
    /// What the rows belong to.
    pub domain: BakeDomain,
    /// Samples per point of each sized light (quad, sun disc), a square; 0 without sized
    /// lights.
    pub light_samples: u32,
    /// Whether a per-vertex bake's tessellation was refined at shadow edges within the uniform
    /// one's vertex count (false: uniform, as in every file before it; always false for a view).
    pub refine_shadows: bool,
    /// Whether a per-vertex bake stores its glossy vertices' visibility (format version 9;
    /// always false for a view and before).
    pub visibility: bool,
}

/// How many vertices and triangles a per-vertex bake's mesh has, and the image it is drawn at:
/// vertex `v` is "pixel" `v` of an image [`super::TILE`] wide, so a tile is a block of
/// [`super::TILE`]² consecutive vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct PerVertexMeta {
    /// Vertices of the mesh (the image's first pixels; the rest of its last row is empty).
    pub vertices: u32,
    /// Triangles of the mesh.
    pub triangles: u32,
    /// Width and height of the scene camera's image: the size a still is drawn at unless asked
    /// otherwise.
    pub image: [u32; 2],
    /// Materials of the scene, which `mesh_material` and `albedo_map_material` index (0 in
    /// files written before it was recorded: their indices are checked against the tables).
    pub materials: u32,
    /// Albedo maps of the mesh's textured materials (format version 5; 0 before).
    pub albedo_maps: u32,
}

/// Everything about a transport file but its arrays.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "MetaFile", into = "MetaFile")]
pub struct TransportMeta {
    /// Width of the image the rows light (per vertex: [`super::TILE`]).
    pub width: u32,
    /// Height of that image.
    pub height: u32,
    /// Pixels on a side of a tile.
    pub tile: u32,
    /// The scene file as given to the bake.
    pub scene_path: String,
    /// The scene camera.
    pub camera: CameraMeta,
    /// How it was baked.
    pub identity: BakeIdentity,
    /// Surface cache points of the interreflections over the whole image (0 without them, and
    /// for exact visibility).
    pub cache_points: u64,
    /// The mesh of a per-vertex bake (`identity.domain` is [`BakeDomain::Vertices`] exactly
    /// when this is present).
    pub per_vertex: Option<PerVertexMeta>,
    /// Derived from the tables (see [`super::TransportWriter::finish`]): the same for a bake and a
    /// merge.
    pub stats: BakeStats,
    /// The scene's local lights, in column order (each takes one column per position), with the
    /// colour and intensity the scene file gives them.
    pub lights: Vec<Light>,
}

impl TransportMeta {
    /// Light columns the file holds: one per light and position.
    pub fn light_columns(&self) -> usize {
        self.lights.iter().map(Light::columns).sum()
    }
}

/// The metadata as the file holds it: one flat object, in this order.
#[derive(Clone, Serialize, Deserialize)]
pub(super) struct MetaFile {
    width: u32,
    height: u32,
    tile: u32,
    cube_n: u32,
    sh_order: u32,
    scene_hash: String,
    scene_path: String,
    camera: CameraMeta,
    spp: u32,
    #[serde(default, skip_serializing_if = "is_zero")]
    edge_spp: u32,
    texel_samples: u32,
    #[serde(default, skip_serializing_if = "is_zero")]
    edge_texel_samples: u32,
    #[serde(default, skip_serializing_if = "is_false")]
    edge_texels_towards: bool,
    unshadowed: bool,
    seed: u64,
    threshold: f32,
    #[serde(default)]
    budget: Budget,
    quantization: Quantization,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    shard: Option<[u32; 2]>,
    #[serde(default)]
    bounces: u32,
    #[serde(default)]
    paths: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    indirect: Option<IndirectFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    per_vertex: Option<PerVertexFile>,
    #[serde(default, skip_serializing_if = "is_zero")]
    light_samples: u32,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    lights: Vec<LightMetaFile>,
    stats: BakeStats,
}

/// A light as the file holds it: the scene file's keys, angles in degrees, and the quad's corners
/// relative to its position.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LightMetaFile {
    name: String,
    r#type: String,
    color: [f32; 3],
    intensity: f32,
    positions: Vec<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    direction: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    cone_deg: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    falloff_deg: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    angle_deg: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    corners: Option<[[f32; 3]; 4]>,
    /// The grid of `positions` (x fastest); absent for a path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    grid: Option<[u32; 3]>,
}

impl From<&Light> for LightMetaFile {
    fn from(l: &Light) -> Self {
        let mut f = LightMetaFile {
            name: l.name.clone(),
            r#type: l.shape.kind().name().to_string(),
            color: l.color.to_array(),
            intensity: l.intensity,
            positions: l.positions.iter().map(|p| p.to_array()).collect(),
            direction: None,
            cone_deg: None,
            falloff_deg: None,
            angle_deg: None,
            corners: None,
            grid: (l.grid[1] * l.grid[2] > 1).then(|| l.grid.map(|n| n as u32)),
        };
        match l.shape {
            LightShape::Point => {}
            LightShape::Spot {
                direction,
                cone,
                falloff,
            } => {
                f.direction = Some(direction.to_array());
                f.cone_deg = Some(cone.to_degrees());
                f.falloff_deg = Some(falloff.to_degrees());
            }
            LightShape::Directional { direction, angle } => {
                f.direction = Some(direction.to_array());
                f.angle_deg = Some(angle.to_degrees());
            }
            LightShape::Quad { corners } => f.corners = Some(corners.map(|c| c.to_array())),
        }
        f
    }
}

impl LightMetaFile {
    /// The light, if the file's form is one this build writes (the loader then checks its
    /// numbers, [`Light::problem`]).
    fn light(&self) -> Option<Light> {
        let v = Vec3::from_array;
        let kind: LightKind = self.r#type.parse().ok()?;
        let shape = match (kind, self.direction, self.corners) {
            (LightKind::Point, None, None) => LightShape::Point,
            (LightKind::Spot, Some(d), None) => LightShape::Spot {
                direction: v(d),
                cone: self.cone_deg?.to_radians(),
                falloff: self.falloff_deg?.to_radians(),
            },
            (LightKind::Directional, Some(d), None) => LightShape::Directional {
                direction: v(d),
                angle: self.angle_deg?.to_radians(),
            },
            (LightKind::Quad, None, Some(c)) => LightShape::Quad { corners: c.map(v) },
            _ => return None,
        };
        Some(Light {
            name: self.name.clone(),
            color: v(self.color),
            intensity: self.intensity,
            shape,
            positions: self.positions.iter().copied().map(v).collect(),
            grid: match self.grid {
                Some(g) => g.map(|n| n as usize),
                None => [self.positions.len(), 1, 1],
            },
        })
    }
}

/// `indirect` as the file holds it.
#[derive(Clone, Serialize, Deserialize)]
struct IndirectFile {
    visibility: BounceVisibility,
    cache_spacing: f32,
    cache_points: u64,
}

/// `per_vertex` as the file holds it.
#[derive(Clone, Serialize, Deserialize)]
struct PerVertexFile {
    edge_length: f32,
    vertices: u32,
    triangles: u32,
    image: [u32; 2],
    #[serde(default, skip_serializing_if = "is_zero")]
    materials: u32,
    #[serde(default, skip_serializing_if = "is_zero")]
    albedo_maps: u32,
    /// Pixels a vertex took in files of versions 6 to 9 baked with in-out BRDF terms: read to
    /// refuse them, never written.
    #[serde(default = "one", skip_serializing)]
    brdf_stride: u32,
    #[serde(default, skip_serializing_if = "is_false")]
    refine_shadows: bool,
    #[serde(default, skip_serializing_if = "is_false")]
    visibility: bool,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

fn is_false(v: &bool) -> bool {
    !*v
}

fn one() -> u32 {
    1
}

impl TryFrom<MetaFile> for TransportMeta {
    type Error = String;

    fn try_from(f: MetaFile) -> Result<Self, String> {
        if let Some(p) = f.per_vertex.as_ref().filter(|p| p.brdf_stride > 1) {
            return Err(format!(
                "per_vertex.brdf_stride {}: the file keeps in-out BRDF terms, which this build \
                 no longer draws (the GGX lobe is drawn per pixel from the glossy vertices' \
                 visibility); bake the scene again with `prt bake SCENE -o FILE --per-vertex`",
                p.brdf_stride
            ));
        }
        let lights = f
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let light = l
                    .light()
                    .ok_or_else(|| format!("lights[{i}]: not a light this build writes"))?;
                match light.problem() {
                    Some(p) => Err(format!("lights[{i}] ({}): {p}", light.name.escape_debug())),
                    None => Ok(light),
                }
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(TransportMeta {
            width: f.width,
            height: f.height,
            tile: f.tile,
            scene_path: f.scene_path,
            camera: f.camera,
            identity: BakeIdentity {
                scene_hash: f.scene_hash,
                cube_n: f.cube_n,
                sh_order: f.sh_order,
                spp: f.spp,
                edge_spp: f.edge_spp,
                texel_samples: f.texel_samples,
                edge_texel_samples: f.edge_texel_samples,
                edge_texels_towards: f.edge_texels_towards,
                unshadowed: f.unshadowed,
                seed: f.seed,
                threshold: f.threshold,
                budget: f.budget,
                quantization: f.quantization,
                shard: f.shard,
                bounces: f.bounces,
                paths: f.paths,
                indirect: f.indirect.as_ref().map(|i| IndirectSettings {
                    visibility: i.visibility,
                    cache_spacing: i.cache_spacing,
                }),
                domain: match &f.per_vertex {
                    Some(p) => BakeDomain::Vertices {
                        edge_length: p.edge_length,
                    },
                    None => BakeDomain::View,
                },
                light_samples: f.light_samples,
                refine_shadows: f.per_vertex.as_ref().is_some_and(|p| p.refine_shadows),
                visibility: f.per_vertex.as_ref().is_some_and(|p| p.visibility),
            },
            cache_points: f.indirect.as_ref().map_or(0, |i| i.cache_points),
            per_vertex: f.per_vertex.map(|p| PerVertexMeta {
                vertices: p.vertices,
                triangles: p.triangles,
                image: p.image,
                materials: p.materials,
                albedo_maps: p.albedo_maps,
            }),
            stats: f.stats,
            lights,
        })
    }
}

impl From<TransportMeta> for MetaFile {
    fn from(m: TransportMeta) -> Self {
        let id = m.identity;
        MetaFile {
            width: m.width,
            height: m.height,
            tile: m.tile,
            cube_n: id.cube_n,
            sh_order: id.sh_order,
            scene_hash: id.scene_hash,
            scene_path: m.scene_path,
            camera: m.camera,
            spp: id.spp,
            edge_spp: id.edge_spp,
            texel_samples: id.texel_samples,
            edge_texel_samples: id.edge_texel_samples,
            edge_texels_towards: id.edge_texels_towards,
            unshadowed: id.unshadowed,
            seed: id.seed,
            threshold: id.threshold,
            budget: id.budget,
            quantization: id.quantization,
            shard: id.shard,
            bounces: id.bounces,
            paths: id.paths,
            indirect: id.indirect.map(|i| IndirectFile {
                visibility: i.visibility,
                cache_spacing: i.cache_spacing,
                cache_points: m.cache_points,
            }),
            per_vertex: match (id.domain, m.per_vertex) {
                (BakeDomain::Vertices { edge_length }, Some(p)) => Some(PerVertexFile {
                    edge_length,
                    vertices: p.vertices,
                    triangles: p.triangles,
                    image: p.image,
                    materials: p.materials,
                    albedo_maps: p.albedo_maps,
                    brdf_stride: 1,
                    refine_shadows: id.refine_shadows,
                    visibility: id.visibility,
                }),
                _ => None,
            },
            light_samples: id.light_samples,
            lights: m.lights.iter().map(LightMetaFile::from).collect(),
            stats: m.stats,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file's metadata text, per vertex with interreflection settings (which no real bake
    /// has together, but every nested field is then present).
    const TEXT: &str = r#"{"width":16,"height":3,"tile":16,"cube_n":8,"sh_order":3,"scene_hash":"00000000000000ab","scene_path":"s.toml","camera":{"eye":[0.0,1.0,2.0],"target":[0.0,0.0,0.0],"up":[0.0,1.0,0.0],"fov_y_deg":45.0},"spp":1,"edge_spp":4,"texel_samples":4,"unshadowed":false,"seed":7,"threshold":0.01,"budget":"l2","quantization":"q8","shard":[1,2],"bounces":1,"paths":64,"indirect":{"visibility":"exact","cache_spacing":4.0,"cache_points":0},"per_vertex":{"edge_length":0.25,"vertices":40,"triangles":60,"image":[64,48]},"stats":{"rows":40,"nonzeros":100,"dense_entries":15360,"dropped_energy_fraction":0.0,"shadow_rays":5}}"#;

    #[test]
    fn the_file_form_survives_a_round_trip_byte_for_byte() {
        let meta: TransportMeta = serde_json::from_str(TEXT).expect("parses");
        assert_eq!(serde_json::to_string(&meta).expect("writes"), TEXT);
        assert_eq!(
            meta.identity.domain,
            BakeDomain::Vertices { edge_length: 0.25 }
        );
        assert_eq!(
            meta.identity.indirect,
            Some(IndirectSettings {
                visibility: BounceVisibility::Exact,
                cache_spacing: 4.0
            })
        );
        assert_eq!(meta.identity.shard, Some([1, 2]));
        assert_eq!(meta.per_vertex.as_ref().map(|p| p.vertices), Some(40));
    }

    #[test]
    fn the_material_count_is_written_and_absent_in_older_files() {
        let old: TransportMeta = serde_json::from_str(TEXT).expect("parses");
        assert_eq!(old.per_vertex.as_ref().map(|p| p.materials), Some(0));
        let mut meta = old;
        meta.per_vertex.as_mut().expect("per vertex").materials = 2;
        let text = serde_json::to_string(&meta).expect("writes");
        assert!(text.contains(r#""image":[64,48],"materials":2"#), "{text}");
        let back: TransportMeta = serde_json::from_str(&text).expect("parses");
        assert_eq!(back, meta);
    }

    #[test]
    fn the_border_rule_is_written_when_used_and_absent_in_older_files() {
        let old: TransportMeta = serde_json::from_str(TEXT).expect("parses");
        assert!(!old.identity.edge_texels_towards, "absent: every sub-texel");
        let mut meta = old.clone();
        meta.identity.edge_texel_samples = 9;
        meta.identity.edge_texels_towards = true;
        let text = serde_json::to_string(&meta).expect("writes");
        assert!(
            text.contains(r#""edge_texel_samples":9,"edge_texels_towards":true"#),
            "{text}"
        );
        let back: TransportMeta = serde_json::from_str(&text).expect("parses");
        assert_eq!(back, meta);
        // A file of the other rule is another bake.
        let mut other = back.identity.clone();
        other.edge_texels_towards = false;
        assert_ne!(back.identity, other);
    }

    #[test]
    fn a_view_bake_writes_neither_nested_object_nor_zero_edge_samples() {
        let mut meta: TransportMeta = serde_json::from_str(TEXT).expect("parses");
        meta.identity.domain = BakeDomain::View;
        meta.per_vertex = None;
        meta.identity.indirect = None;
        meta.identity.edge_spp = 0;
        let text = serde_json::to_string(&meta).expect("writes");
        for absent in [
            "per_vertex",
            "indirect",
            "edge_spp",
            "cache_points",
            "edge_texels_towards",
        ] {
            assert!(!text.contains(absent), "{absent} written in {text}");
        }
        let back: TransportMeta = serde_json::from_str(&text).expect("parses");
        assert_eq!(back, meta);
    }
}
