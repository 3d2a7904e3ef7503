//! The settings of a bake, their checks, and what follows from them alone: whether a file
//! already holds this bake (so it can be reused) and how large its output can grow.

use super::*;
use crate::flags::within;
use crate::store::transport::{BakeDomain, BakeIdentity, IndirectSettings};

/// The most camera sub-samples a pixel may take ([`BakeSettings::spp`] and
/// [`BakeSettings::edge_spp`]).
pub const MAX_SPP: u32 = 4096;

/// Settings of a bake; the defaults are the command line's.
///
/// They read from and write to TOML or JSON (serde): a key left out takes its default, an
/// unknown key is an error, and ranges are checked when baking ([`BakeSettings::validate`]).
/// The keys are the fields, each the `prt bake` flag of that name with `_` for `-`
/// (`sh_order` is `--sh-order`), and the values are written as the flags take them
/// (`"l2"`, `"q8"`, `"cache"`), except:
///
/// - `cube_n` is `--cube` (`cube` is also accepted);
/// - `shard` is `[I, COUNT]` for `--shard I/COUNT`;
/// - `domain` is `"view"`, or `{"vertices": {"edge_length": E}}` for `--per-vertex
///   --edge-length E` (in TOML, `[domain.vertices]` with `edge_length = E`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BakeSettings {
    /// Cube face size N of the texel lights.
    #[serde(alias = "cube")]
    pub cube_n: usize,
    /// SH order of the SH transport (n² coefficients). The default, 6, is also the highest order
    /// the demo shows beside the wavelets.
    pub sh_order: usize,
    /// Sub-pixel samples per pixel.
    pub spp: u32,
    /// Sub-pixel samples of an edge pixel, one whose corners see different things (see
    /// [`EdgeMap`]); 0 (or no more than `spp`) samples every pixel alike.
    pub edge_spp: u32,
    /// Shadow-ray directions per texel (rounded up to a square).
    pub texel_samples: u32,
    /// With one direction a texel, the sub-texels (rounded up to a square) of a texel that
    /// needs more than its centre: a shadow border, the horizon, a narrow glossy lobe; the
    /// cosine over any other texel is then exact ([`TexelSamples::refined`]). 0 or 1: every
    /// texel takes its centre's value, as a per-vertex bake's do.
    pub edge_texel_samples: u32,
    /// Error allowed per row when dropping small Haar coefficients, relative to the L2 norm of
    /// an unshadowed row (0 keeps all). One absolute budget for every row spends it where the
    /// image is bright: shadowed rows become sparser than lit ones. The default, 0.005, brings
    /// the demo's bake relit with every term to 1.2% of the path tracer under a low sun; at 0.01
    /// the rows' dropped terms added up on the open ground to 1.7% (see docs/guide/baking.md).
    pub threshold: f32,
    /// How the thresholding budget weighs coefficients.
    pub budget: Budget,
    /// How kept values are stored (unless `lossless`).
    pub quantization: Quantization,
    /// Keep every coefficient in 32-bit floats (for checks against the reference).
    pub lossless: bool,
    /// Ignore visibility (no shadows).
    pub unshadowed: bool,
    /// Seed of every random choice.
    pub seed: u64,
    /// `[index, count]`: bake only shard `index` of `count` (bands of tile rows).
    pub shard: Option<[u32; 2]>,
    /// Interreflection bounces added to the direct light (0: direct only).
    pub bounces: u32,
    /// Paths traced per camera sub-sample for the interreflections.
    pub paths: u32,
    /// Where the visibility of the interreflections' path vertices comes from.
    pub bounce_visibility: bounce::BounceVisibility,
    /// Width of a surface cache cell, in pixel footprints at the view's median depth.
    pub cache_spacing: f32,
    /// What the rows belong to: the pixels of the camera's view, or the vertices of the scene
    /// tessellated to a longest edge ([`crate::scene::tessellate`]).
    pub domain: BakeDomain,
    /// Samples per shading point of each sized local light (a quad, a sun disc), rounded up to a
    /// square: a stratified grid over the light.
    pub light_samples: u32,
    /// Whether a per-vertex bake spends its vertices where shadows fall
    /// ([`crate::scene::tessellate::VertexMesh::tessellate_refined`]): as many as the uniform
    /// tessellation at the edge length makes (which `false` keeps), more of them across shadow
    /// borders and fewer where the light is even. An unshadowed bake is tessellated uniformly.
    /// Off by default: on the tests' sphere on a ground it puts twice the vertices along the
    /// shadow's edge, yet the drawn image is no closer to the per-pixel bake (3.75% against
    /// 3.68% at equal vertex counts), so it is not yet the better choice.
    pub refine_shadows: bool,
    /// Whether a per-vertex bake stores which cube texels each glossy vertex sees
    /// ([`crate::scene::visibility::Visibility`]), so that its glossy lobe is drawn per pixel from
    /// the light itself ([`crate::draw::lobe`]) rather than left out.
    pub visibility: bool,
}

impl Default for BakeSettings {
    fn default() -> Self {
        BakeSettings {
            cube_n: 32,
            sh_order: 6,
            spp: 1,
            edge_spp: 4,
            texel_samples: 1,
            edge_texel_samples: 9,
            threshold: 0.005,
            budget: Budget::L2,
            quantization: Quantization::Q8,
            lossless: false,
            unshadowed: false,
            seed: 1,
            shard: None,
            bounces: 0,
            paths: 256,
            bounce_visibility: bounce::BounceVisibility::Cache,
            cache_spacing: 4.0,
            domain: BakeDomain::View,
            light_samples: 64,
            refine_shadows: false,
            visibility: false,
        }
    }
}

impl BakeSettings {
    /// Checks ranges before any work.
    pub fn validate(&self) -> Result<()> {
        validate_n(self.cube_n)?;
        if self.cube_n > 128 {
            return Err(PrtError::invalid(
                "cube size",
                format!(
                    "N = {}: per-pixel rows above N = 128 are not supported",
                    self.cube_n
                ),
            ));
        }
        within("SH order", self.sh_order, 1..=10, "")?;
        within("spp", self.spp, 1..=MAX_SPP, "")?;
        if self.edge_spp > MAX_SPP {
            return Err(PrtError::invalid(
                "edge spp",
                format!("{}; it must be from 0 (off) to {MAX_SPP}", self.edge_spp),
            ));
        }
        within("texel samples", self.texel_samples, 1..=256, "")?;
        // 64 sub-texels (8 x 8) hold 100 MB of directions and weights at N = 128.
        within("edge texel samples", self.edge_texel_samples, 0..=64, "")?;
        within("light samples", self.light_samples, 1..=1024, "")?;
        if let Some([i, count]) = self.shard
            && (count == 0 || i >= count)
        {
            return Err(PrtError::invalid(
                "shard",
                format!("{i}/{count}; it must be I/COUNT with 0 <= I < COUNT"),
            ));
        }
        if self.bounces > 16 || (self.bounces > 0 && !(1..=65536).contains(&self.paths)) {
            return Err(PrtError::invalid(
                "interreflections",
                format!(
                    "{} bounces with {} paths; bounces go up to 16, paths from 1 to 65536",
                    self.bounces, self.paths
                ),
            ));
        }
        within(
            "cache spacing",
            self.cache_spacing,
            0.25..=256.0,
            " pixel footprints",
        )?;
        if let BakeDomain::Vertices { edge_length: e } = self.domain {
            if !(e.is_finite() && e > 0.0) {
                return Err(PrtError::invalid(
                    "edge length",
                    format!("{e}; it must be a finite length > 0 (scene units)"),
                ));
            }
            if self.bounces > 0 {
                return Err(PrtError::invalid(
                    "per-vertex bake",
                    "interreflections are baked per pixel only; bake per vertex with \
                     --bounces 0",
                ));
            }
        }
        if !(0.0..1.0).contains(&self.threshold) {
            return Err(PrtError::invalid(
                "threshold",
                format!("{}; it must be in [0, 1)", self.threshold),
            ));
        }
        Ok(())
    }

    /// The edge samples as a file records them: 0 where they add nothing to `spp`, and in a
    /// per-vertex bake, which has no pixels.
    pub fn stored_edge_spp(&self) -> u32 {
        if self.edge_spp > self.spp && self.domain == BakeDomain::View {
            self.edge_spp
        } else {
            0
        }
    }

    /// The threshold, budget and quantisation as a file records them: a lossless bake keeps
    /// every value in 32-bit floats, so its threshold is 0 and its budget, which only weighs
    /// what a threshold drops, the default.
    pub fn storage(&self) -> (f32, Budget, Quantization) {
        if self.lossless {
            (0.0, Budget::default(), Quantization::F32)
        } else {
            (self.threshold, self.budget, self.quantization)
        }
    }

    /// Checks what depends on the scene as well as the settings, before any work: a scene with a
    /// medium is baked per pixel, lit by its environment only.
    pub fn validate_for(&self, scene: &Scene) -> Result<()> {
        self.validate()?;
        if scene.medium.is_some() && self.domain != BakeDomain::View {
            return Err(PrtError::invalid(
                "per-vertex bake",
                "a scene with a [medium] is baked per pixel only (the medium lies between the \
                 camera and every surface)",
            ));
        }
        if scene.medium.is_some() && !scene.lights.is_empty() {
            return Err(PrtError::invalid(
                "lights",
                "local lights are not baked through a medium yet; light a scene with a [medium] \
                 by its environment only (remove its [[light]] tables)",
            ));
        }
        Ok(())
    }

    /// Whether the bake's mesh is refined at shadow edges: a per-vertex bake, with shadows, with
    /// `refine_shadows`.
    pub fn refines_shadows(&self) -> bool {
        self.refine_shadows
            && !self.unshadowed
            && matches!(self.domain, BakeDomain::Vertices { .. })
    }

    /// The edge texel samples as a file records them and the bake uses them: a square, or 0
    /// where texels are not refined (more than one direction a texel, at most one sub-texel
    /// asked for, or a per-vertex bake, whose glossy terms' rows take texel centres).
    pub fn stored_edge_texel_samples(&self) -> u32 {
        let side = TexelSamples::grid_side(self.edge_texel_samples as usize) as u32;
        let per_vertex = matches!(self.domain, BakeDomain::Vertices { .. });
        if self.texel_samples > 1 || self.edge_texel_samples <= 1 || per_vertex {
            0
        } else {
            side * side
        }
    }

    /// What a file baked from `scene` with these settings records about how it was baked
    /// (checked first, see [`BakeSettings::validate_for`]). This is the one place the settings
    /// are put in their stored form: the storage ([`BakeSettings::storage`]) and edge samples
    /// ([`BakeSettings::stored_edge_spp`]) as recorded, texel samples rounded up to a square
    /// (the sampler's grid), paths and the interreflections' settings absent without bounces.
    pub fn identity(&self, scene: &Scene) -> Result<BakeIdentity> {
        self.validate_for(scene)?;
        let side = TexelSamples::grid_side(self.texel_samples as usize) as u32;
        let (threshold, budget, quantization) = self.storage();
        Ok(BakeIdentity {
            scene_hash: scene.hash_hex(),
            cube_n: self.cube_n as u32,
            sh_order: self.sh_order as u32,
            spp: self.spp,
            edge_spp: self.stored_edge_spp(),
            texel_samples: side * side,
            edge_texel_samples: self.stored_edge_texel_samples(),
            // The only rule this build bakes by (`bake::direct`); files of the older one, with
            // every sub-texel of a border traced, are other bakes.
            edge_texels_towards: self.stored_edge_texel_samples() > 0,
            unshadowed: self.unshadowed,
            seed: self.seed,
            threshold,
            budget,
            quantization,
            shard: self.shard,
            bounces: self.bounces,
            paths: if self.bounces > 0 { self.paths } else { 0 },
            indirect: (self.bounces > 0).then_some(IndirectSettings {
                visibility: self.bounce_visibility,
                cache_spacing: self.cache_spacing,
            }),
            domain: self.domain,
            light_samples: if scene.lights.iter().any(|l| l.shape.is_sized()) {
                let side = TexelSamples::grid_side(self.light_samples as usize) as u32;
                side * side
            } else {
                0
            },
            refine_shadows: self.refines_shadows(),
            visibility: self.visibility && matches!(self.domain, BakeDomain::Vertices { .. }),
        })
    }

    /// The settings that bake `meta`'s file again: [`BakeSettings::identity`] of them is the
    /// file's identity (for the scene it was baked from). What a file does not record (the
    /// interreflections' settings of a file baked before they were recorded) takes the defaults;
    /// a file whose border texels traced every sub-texel (no `edge_texels_towards`) is baked
    /// again by today's rule, so its identity then differs in that field alone.
    pub fn from_meta(meta: &TransportMeta) -> BakeSettings {
        let id = &meta.identity;
        let defaults = BakeSettings::default();
        let lossless = id.quantization == Quantization::F32 && id.threshold == 0.0;
        BakeSettings {
            cube_n: id.cube_n as usize,
            sh_order: id.sh_order as usize,
            spp: id.spp,
            edge_spp: id.edge_spp,
            texel_samples: id.texel_samples,
            edge_texel_samples: id.edge_texel_samples,
            threshold: id.threshold,
            budget: id.budget,
            quantization: if lossless {
                defaults.quantization
            } else {
                id.quantization
            },
            lossless,
            unshadowed: id.unshadowed,
            seed: id.seed,
            shard: id.shard,
            bounces: id.bounces,
            paths: if id.bounces > 0 {
                id.paths
            } else {
                defaults.paths
            },
            bounce_visibility: id
                .indirect
                .map_or(defaults.bounce_visibility, |i| i.visibility),
            cache_spacing: id
                .indirect
                .map_or(defaults.cache_spacing, |i| i.cache_spacing),
            domain: id.domain,
            light_samples: if id.light_samples > 0 {
                id.light_samples
            } else {
                defaults.light_samples
            },
            refine_shadows: match id.domain {
                BakeDomain::View => defaults.refine_shadows,
                BakeDomain::Vertices { .. } => id.refine_shadows,
            },
            visibility: id.visibility,
        }
    }
}

/// The transport at `path` when it exists, loads, and was baked from this scene with these
/// settings (its [`BakeIdentity`] is theirs); `None` otherwise. Lets callers reuse a cached
/// bake.
pub fn load_if_baked_with(
    path: &std::path::Path,
    scene: &Scene,
    settings: &BakeSettings,
) -> Option<Transport> {
    let meta = crate::store::transport::read_header_meta(path).ok()?;
    if meta.identity != settings.identity(scene).ok()? {
        return None;
    }
    let t = Transport::load(path).ok()?;
    // A glossy bake with lights from before the vertices' light shares were kept draws no
    // highlight of its lights: it is made again.
    let vis = t.mesh().and_then(|m| m.visibility.as_deref());
    if vis.is_some_and(|v| v.columns < t.meta.light_columns()) {
        return None;
    }
    Some(t)
}

/// The transport at `path` when it holds this bake ([`load_if_baked_with`]); otherwise, after
/// `starting()`, `scene` baked with `settings` and saved there. Returns it and whether it was
/// reused: the demo's bakes, which a second run takes from the first.
pub fn load_or_bake(
    path: &std::path::Path,
    scene: &Scene,
    settings: &BakeSettings,
    starting: &mut dyn FnMut(),
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<(Transport, bool)> {
    if let Some(mut t) = load_if_baked_with(path, scene, settings) {
        // A file of an older format is written again in this one, so later runs read it
        // without converting it; where it cannot be (a folder that is read only), it is read as
        // it is, as before. Version 7's slots are made whole where this version stores them so
        // (versions 3 to 6 are made into strips as they load); should that fail, the strips
        // stay as they were read, which every product reads as well.
        let version = crate::store::transport::read_format_version(path).ok();
        if version.is_some_and(|v| v < crate::store::transport::FORMAT_VERSION) {
            if version == Some(7) {
                t.make_slots_whole().ok();
            }
            t.save(path).ok();
        }
        return Ok((t, true));
    }
    starting();
    let t = bake(scene, settings, progress)?;
    t.save(path)?;
    Ok((t, false))
}

/// [`load_or_bake`] for the demo's bakes: logs `what` before baking, or that the file was
/// reused. Returns the transport, whether it was reused and the seconds it took.
pub fn load_or_bake_logged(
    path: &std::path::Path,
    scene: &Scene,
    settings: &BakeSettings,
    what: &str,
    log: &mut dyn FnMut(&str),
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<(Transport, bool, f64)> {
    let start = std::time::Instant::now();
    let (t, reused) = load_or_bake(path, scene, settings, &mut || log(what), progress)?;
    if reused {
        log(&format!(
            "reusing the bake in {} (scene and settings unchanged)",
            path.display()
        ));
    }
    Ok((t, reused, start.elapsed().as_secs_f64()))
}

/// Bytes a bake's output will take at most (every coefficient kept), to warn or refuse up front.
pub fn worst_case_bytes(width: usize, height: usize, settings: &BakeSettings) -> u64 {
    let c = texel_count(settings.cube_n) as u64;
    let value = settings.storage().2.value_bytes() as u64;
    (width * height) as u64 * c * (1 + value)
}
