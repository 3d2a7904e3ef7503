//! The demo's orbit: the demo scene baked per vertex (at the default edge length, and at twice
//! it), relit under one environment and drawn from four camera angles around it, then compared
//! from the scene's own camera with the per-pixel bake: what interpolating between vertices
//! costs at each tessellation, apart from the light's approximation. Also times a frame as the
//! viewer makes it: relight at K terms, then draw.

use crate::app::studies::Study;
use crate::store::transport::BakeDomain;
use std::path::PathBuf;
use std::time::Instant;

use crate::bake::BakeSettings;
use crate::draw::vertex::{bake_camera, compose, orbit};
use crate::env::envmap::{EnvMap, EnvRotation};
use crate::error::{PrtError, Result};
use crate::output::film::{Image, ToneMap};
use crate::output::metrics::relative_l2;
use crate::output::sheet::{cells_at, write_sheet};
use crate::relight::{LightContext, PreparedLight, RelightRequest, relight};
use crate::scene::Scene;
use crate::scene::tessellate::VertexMesh;
use crate::store::transport::Transport;

/// Kept terms of the orbit's frames, as in the viewer's first frame.
pub const ORBIT_TERMS: usize = 100;
/// Azimuths of the orbit sheet's four views, degrees about +Y from the scene's camera.
pub const ORBIT_AZIMUTHS: [f32; 4] = [0.0, 90.0, 180.0, 270.0];

/// The coarser tessellation's edge length, as a multiple of the default.
pub const COARSE_EDGE_FACTOR: f32 = 2.0;

/// One tessellation of the orbit: its size, bake and errors.
#[derive(Clone, Debug)]
pub struct Tessellation {
    /// Vertices of the tessellation: the bake's rows.
    pub vertices: usize,
    /// Triangles of the tessellation.
    pub triangles: usize,
    /// Longest triangle edge allowed, in scene units.
    pub edge_length: f32,
    /// Time to bake (or to load the cached bake), seconds.
    pub bake_seconds: f64,
    /// Whether the cached bake was loaded instead of baking anew.
    pub reused_bake: bool,
    /// From the scene's camera, every term: the per-vertex image against the per-pixel one, over
    /// the pixels both cover with one diffuse row (glossy surfaces left out), relative L2.
    pub interpolation_error: f64,
    /// Relative L2 of [`ORBIT_TERMS`] terms against every term, per vertex.
    pub light_error: f64,
}

/// What the orbit produced.
pub struct OrbitReport {
    /// The default tessellation (drawn around the orbit and timed).
    pub fine: Tessellation,
    /// At [`COARSE_EDGE_FACTOR`] times the default edge length.
    pub coarse: Tessellation,
    /// Median over a few frames at [`ORBIT_TERMS`] terms, on the CPU: the relight, the
    /// drawing, and both.
    pub relight_ms: f64,
    /// Median time to draw the relit vertices, milliseconds.
    pub draw_ms: f64,
    /// Median time of a whole frame, relight and drawing, milliseconds.
    pub frame_ms: f64,
    /// The orbit sheet, `dir/orbit_sheet.png`.
    pub sheet_path: PathBuf,
}

/// One tessellation measured: the bake, its light under the orbit's environment, the relight at
/// [`ORBIT_TERMS`] terms, and the image of every term from the scene's camera over the
/// environment.
struct Measured {
    tess: Tessellation,
    t: Transport,
    ctx: LightContext,
    light: crate::relight::PreparedLight,
    k_img: Image,
    shown: Image,
}

/// Bakes (or reuses) `scene` per vertex at edge length `edge` into `path`.
fn bake_vertices(
    study: &mut Study,
    name: &str,
    scene: &Scene,
    edge: f32,
) -> Result<(Transport, bool, f64)> {
    let settings = BakeSettings {
        domain: BakeDomain::Vertices { edge_length: edge },
        ..study.settings.clone()
    };
    let detail = format!("per vertex (edges up to {edge:.3})");
    study.bake(&study.dir.join(name), scene, &settings, &detail)
}

/// Bakes (or reuses) `scene` per vertex into `dir/demo_vertices.prt` with `settings` at the
/// default edge length, relights it under `env`, writes `dir/orbit_sheet.png`, and compares it
/// with `per_pixel`, the same scene's per-pixel bake.
pub fn run_orbit(
    study: &mut Study,
    scene: &Scene,
    per_pixel: &Transport,
    env: (&str, &EnvMap),
) -> Result<OrbitReport> {
    let dir = study.dir;
    let edge = VertexMesh::default_edge_length(scene);
    let (name, env) = env;
    let rotation = EnvRotation::default();
    let full_req = RelightRequest::Full;
    let k_req = RelightRequest::Wavelet {
        k: ORBIT_TERMS,
        // The demo's weighting.
        weighting: crate::env::select::Weighting::Transport,
    };
    // The per-pixel bake from the scene's camera, every term, to compare with.
    let pixel_ctx = LightContext::new(per_pixel)?;
    let pixel_light = pixel_ctx.prepare(env, rotation)?;
    let (pixel_full, _) = relight(per_pixel, &pixel_ctx, &pixel_light, &full_req)?;
    // Pixels of glossy surfaces hold a second (GGX) row per pixel; a per-vertex bake keeps only
    // their diffuse base, so they are left out of the comparison.
    let rows = rows_per_pixel(per_pixel);
    // One tessellation: baked, relit with every term and with K, drawn from the scene's camera.
    let mut measure = |file: &str, edge: f32| -> Result<Measured> {
        let (t, reused_bake, bake_seconds) = bake_vertices(study, file, scene, edge)?;
        let pv = t
            .meta
            .per_vertex
            .clone()
            .ok_or_else(|| PrtError::invalid("orbit", "the bake is not per vertex"))?;
        let ctx = LightContext::new(&t)?;
        let light = ctx.prepare(env, rotation)?;
        let (full, _) = relight(&t, &ctx, &light, &full_req)?;
        let (k_img, _) = relight(&t, &ctx, &light, &k_req)?;
        let camera = bake_camera(&t)?;
        let drawn = crate::draw::vertex::draw_relit(&t, &full, None, &camera, None, 1)?;
        let both: Vec<f32> = drawn
            .coverage
            .iter()
            .zip(&per_pixel.coverage)
            .zip(&rows)
            .map(|((a, b), &r)| (*a == 1.0 && *b == 1.0 && r == 1) as u8 as f32)
            .collect();
        let tess = Tessellation {
            vertices: pv.vertices as usize,
            triangles: pv.triangles as usize,
            edge_length: t.meta.identity.domain.edge_length().unwrap_or_default(),
            bake_seconds,
            reused_bake,
            interpolation_error: relative_l2(&drawn.image, &pixel_full, Some(&both))?,
            light_error: relative_l2(&k_img, &full, Some(&t.coverage))?,
        };
        let shown = compose(drawn, &camera, Some((env, rotation)))?.image;
        Ok(Measured {
            tess,
            t,
            ctx,
            light,
            k_img,
            shown,
        })
    };
    let Measured {
        tess: fine,
        t,
        ctx,
        light,
        k_img,
        shown: fine_shown,
    } = measure("demo_vertices.prt", edge)?;
    let Measured {
        tess: coarse,
        shown: coarse_shown,
        ..
    } = measure("demo_vertices_coarse.prt", edge * COARSE_EDGE_FACTOR)?;
    let camera = bake_camera(&t)?;
    let draw = |relit: &Image, camera: &crate::scene::Camera, samples: u32| {
        crate::draw::vertex::draw_relit(&t, relit, None, camera, None, samples)
    };
    let (ms, k_img) = timed_frames(&t, (&ctx, &light), &k_req, &camera, k_img)?;
    let tone = ToneMap::auto(&pixel_full, Some(&per_pixel.coverage));
    let mut shots: Vec<(Image, [String; 2])> = Vec::new();
    for az in ORBIT_AZIMUTHS {
        let cam = orbit(&camera, az, 0.0);
        // Drawn as `prt relight` and the GPU display draw: antialiased.
        let shot = compose(
            draw(&k_img, &cam, crate::draw::raster::DRAW_SAMPLES)?,
            &cam,
            Some((env, rotation)),
        )?;
        shots.push((
            shot.image,
            [format!("K = {ORBIT_TERMS}, turned {az}°"), name.to_string()],
        ));
    }
    let behind = crate::draw::background::environment_behind(
        &per_pixel.meta,
        &per_pixel.coverage,
        env,
        rotation,
    )?;
    let pixel_shown = crate::draw::background::composite(&pixel_full, &behind);
    shots.push((
        pixel_shown,
        ["per pixel, every term".into(), "the scene's camera".into()],
    ));
    for (tess, shown) in [(&fine, fine_shown), (&coarse, coarse_shown)] {
        shots.push((
            shown,
            [
                format!("per vertex, {} vertices", tess.vertices),
                format!("L2 {:.1}% vs per pixel", 100.0 * tess.interpolation_error),
            ],
        ));
    }
    let cells = cells_at(&shots, tone);
    let sheet_path = dir.join("orbit_sheet.png");
    write_sheet(
        &sheet_path,
        4,
        &cells,
        &format!(
            "Per-vertex transport ({} vertices): one relight, any camera",
            fine.vertices
        ),
    )?;
    study.log(&format!(
        "drew the per-vertex bake from {} angles; a frame at K = {ORBIT_TERMS} takes {:.1} ms",
        ORBIT_AZIMUTHS.len(),
        ms[2]
    ));
    Ok(OrbitReport {
        fine,
        coarse,
        relight_ms: ms[0],
        draw_ms: ms[1],
        frame_ms: ms[2],
        sheet_path,
    })
}

/// Frames as the viewer makes them on the CPU, five of them: `t` relit at `k_req` under `light`,
/// then drawn from `camera` at the pixel centres. The median milliseconds of the relight, the
/// draw and the frame, and the last image relit (`k_img` without frames).
fn timed_frames(
    t: &Transport,
    (ctx, light): (&LightContext, &PreparedLight),
    k_req: &RelightRequest,
    camera: &crate::scene::Camera,
    mut k_img: Image,
) -> Result<([f64; 3], Image)> {
    let mut times = [Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..5 {
        let t0 = Instant::now();
        let (img, _) = relight(t, ctx, light, k_req)?;
        let t1 = Instant::now();
        let raster = crate::draw::vertex::draw_relit(t, &img, None, camera, None, 1)?;
        let t2 = Instant::now();
        for (v, d) in times.iter_mut().zip([t1 - t0, t2 - t1, t2 - t0]) {
            v.push(d.as_secs_f64() * 1e3);
        }
        drop(raster);
        k_img = img;
    }
    Ok((times.map(super::median), k_img))
}

/// How many rows each pixel of a per-pixel bake keeps (two on a glossy surface).
fn rows_per_pixel(t: &Transport) -> Vec<u32> {
    let mut rows = vec![0u32; t.coverage.len()];
    for &p in &t.row_pixel {
        rows[p as usize] += 1;
    }
    rows
}
