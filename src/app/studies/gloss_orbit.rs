//! The demo's glossy orbit: the demo scene baked per vertex with its porcelain teapot's
//! visibility (`--visibility`), relit once and drawn from four angles with the GGX lobe per
//! pixel, its highlights following the camera, beside the diffuse base (the same bake's vertex
//! colours alone) and the independent path tracer from one of those angles
//! (`gloss_sheet.png`), with both errors against it.

use std::path::PathBuf;

use crate::app::studies::Study;
use crate::app::studies::orbit::ORBIT_AZIMUTHS;
use crate::bake::BakeSettings;
use crate::bake::path_tracer::path_trace_from;
use crate::draw::background::{composite, environment_behind_camera};
use crate::draw::raster::DRAW_SAMPLES;
use crate::draw::vertex::{bake_camera, compose, draw, draw_relit, orbit};
use crate::env::envmap::{EnvMap, EnvRotation};
use crate::env::importance::MapLight;
use crate::error::{PrtError, Result};
use crate::output::film::{Image, ToneMap};
use crate::output::metrics::relative_l2;
use crate::output::sheet::{cells_at, write_sheet};
use crate::relight::{Backend, Cpu, LightContext, RelightRequest, Terms, lobe_light};
use crate::scene::tessellate::VertexMesh;
use crate::scene::{Camera, Scene};
use crate::store::transport::BakeDomain;

/// What the glossy orbit's glossy materials keep, as its captions say it.
pub const GLOSS_METHOD: &str = "visibility, lobe per pixel";
/// The angle of the orbit the path tracer renders, degrees about +Y from the scene's camera: the
/// second of [`ORBIT_AZIMUTHS`].
pub const GLOSS_REFERENCE_AZIMUTH: f32 = ORBIT_AZIMUTHS[1];
/// Paths a pixel of that reference.
pub const GLOSS_REFERENCE_PATHS: u32 = 512;

/// What the glossy orbit produced.
pub struct GlossReport {
    /// The bake, `dir/demo_glossy.prt`.
    pub transport_path: PathBuf,
    /// The sheet, `dir/gloss_sheet.png`.
    pub sheet_path: PathBuf,
    /// Whether the bake was reused.
    pub reused_bake: bool,
    /// Time to bake (or to load the cached bake), seconds.
    pub bake_seconds: f64,
    /// Vertices of the bake.
    pub vertices: usize,
    /// The file's size over its vertices, bytes.
    pub bytes_per_vertex: f64,
    /// The path tracer's own noise (relative L2), or `None` when its image was kept from the
    /// last run.
    pub reference_noise: Option<f64>,
    /// Every term with the lobe drawn per pixel, against the path tracer, relative L2 over the
    /// image.
    pub glossy_error: f64,
    /// The diffuse base (the vertex colours alone) against the path tracer.
    pub diffuse_error: f64,
}

/// Bakes (or reuses) `scene` per vertex at its default edge length with its glossy vertices'
/// visibility into `dir/demo_glossy.prt` (`settings` otherwise, the demo's per-pixel ones),
/// relights it under `env` with every term, and writes `dir/gloss_sheet.png`.
pub fn run_gloss_orbit(
    study: &mut Study,
    scene: &Scene,
    env: (&str, &EnvMap),
) -> Result<GlossReport> {
    let (dir, settings) = (study.dir, study.settings);
    let (name, env) = env;
    let rotation = EnvRotation::default();
    let glossy_settings = BakeSettings {
        domain: BakeDomain::Vertices {
            edge_length: VertexMesh::default_edge_length(scene),
        },
        visibility: true,
        ..settings.clone()
    };
    let transport_path = dir.join("demo_glossy.prt");
    let detail = "per vertex with its glossy materials' visibility";
    let (t, reused_bake, bake_seconds) =
        study.bake(&transport_path, scene, &glossy_settings, detail)?;
    let ctx = LightContext::new(&t)?;
    let light = ctx.prepare(env, rotation)?;
    let terms = Terms::of(&t, &ctx, &light, &RelightRequest::Full)?;
    let (full, _) = Cpu(&t).relight_terms(&terms)?;
    let lobe = lobe_light(&t, &ctx, Some(&light), &RelightRequest::Full)?;
    let camera = bake_camera(&t)?;
    let behind = Some((env, rotation));
    // Every angle drawn once, the reference's kept unlit behind for the errors.
    let mut shots: Vec<(Image, [String; 2])> = Vec::new();
    let mut glossy = None;
    for az in ORBIT_AZIMUTHS {
        let cam = orbit(&camera, az, 0.0);
        let drawn = draw_relit(&t, &full, lobe.as_ref(), &cam, None, DRAW_SAMPLES)?;
        if az == GLOSS_REFERENCE_AZIMUTH {
            glossy = Some(drawn.clone());
        }
        shots.push((
            compose(drawn, &cam, behind)?.image,
            [
                format!("{GLOSS_METHOD}, turned {az}°"),
                format!("every term, {name}"),
            ],
        ));
    }
    let glossy = glossy.ok_or_else(|| {
        PrtError::invalid(
            "gloss orbit",
            "the reference's angle is not one of the orbit's",
        )
    })?;

    // One angle against the path tracer, the background black in all three.
    let cam = orbit(&camera, GLOSS_REFERENCE_AZIMUTH, 0.0);
    let colours = crate::draw::vertex::vertex_colours(&t, &full)?;
    let diffuse = draw(&t, colours, &cam, None, DRAW_SAMPLES)?;
    let (reference, reference_noise) = path_traced_reference(study, scene, env, &cam, reused_bake)?;
    let glossy_error = relative_l2(&glossy.image, &reference, None)?;
    let diffuse_error = relative_l2(&diffuse.image, &reference, None)?;
    // The environment behind, where the raster from the same camera draws nothing.
    let reference_shown = composite(
        &reference,
        &environment_behind_camera(&cam, &glossy.coverage, env, rotation)?,
    );
    let tone = ToneMap::auto(&reference, None);
    let az = GLOSS_REFERENCE_AZIMUTH;
    let noise = match reference_noise {
        Some(n) => format!("noise {:.1}%", 100.0 * n),
        None => "kept from the last run".to_string(),
    };
    shots.extend([
        (
            compose(diffuse, &cam, behind)?.image,
            [
                format!("diffuse base, turned {az}°"),
                format!("L2 {:.1}% vs path traced", 100.0 * diffuse_error),
            ],
        ),
        (
            compose(glossy, &cam, behind)?.image,
            [
                format!("{GLOSS_METHOD}, turned {az}°"),
                format!("L2 {:.1}% vs path traced", 100.0 * glossy_error),
            ],
        ),
        (
            reference_shown,
            [
                format!("path traced, turned {az}°"),
                format!("{GLOSS_REFERENCE_PATHS} paths, {noise}"),
            ],
        ),
    ]);
    let cells = cells_at(&shots, tone);
    let sheet_path = dir.join("gloss_sheet.png");
    let vertices = t
        .meta
        .per_vertex
        .as_ref()
        .map_or(0, |p| p.vertices as usize);
    write_sheet(
        &sheet_path,
        4,
        &cells,
        &format!(
            "Glossy per-vertex transport ({vertices} vertices, {GLOSS_METHOD}): the highlights \
             follow the camera"
        ),
    )?;
    study.log(&format!(
        "drew the glossy per-vertex bake from {} angles; from {az}° round, against the path \
         tracer: {:.1}% with the lobe per pixel, {:.1}% for the diffuse base",
        ORBIT_AZIMUTHS.len(),
        100.0 * glossy_error,
        100.0 * diffuse_error
    ));
    let bytes = std::fs::metadata(&transport_path).map_or(0, |m| m.len());
    Ok(GlossReport {
        transport_path,
        sheet_path,
        reused_bake,
        bake_seconds,
        vertices,
        bytes_per_vertex: bytes as f64 / vertices.max(1) as f64,
        reference_noise,
        glossy_error,
        diffuse_error,
    })
}

/// The demo's glossy reference from `cam`: the path tracer lit by the map's own pixels (an
/// earlier demo's reference, lit by the cube, had another name and is not taken for this one),
/// kept in the study's folder and taken again where the bake was `reused`, with its noise when
/// traced now.
fn path_traced_reference(
    study: &mut Study,
    scene: &Scene,
    env: &EnvMap,
    cam: &Camera,
    reused: bool,
) -> Result<(Image, Option<f64>)> {
    let exr = study.dir.join("gloss_path_traced_map.exr");
    let kept = Image::load_exr(&exr)
        .ok()
        .filter(|i| reused && (i.width, i.height) == (cam.width as usize, cam.height as usize));
    Ok(match kept {
        Some(image) => (image, None),
        None => {
            study.log(&format!(
                "path tracing the demo from {GLOSS_REFERENCE_AZIMUTH}° round \
                 ({GLOSS_REFERENCE_PATHS} paths a pixel) ..."
            ));
            let light = MapLight::new(env, EnvRotation::default());
            let traced =
                path_trace_from(scene, cam, &light, study.settings, GLOSS_REFERENCE_PATHS)?;
            traced
                .image
                .save(&exr, ToneMap::auto(&traced.image, None))?;
            let noise = traced.relative_noise(None);
            (traced.image, Some(noise))
        }
    })
}
