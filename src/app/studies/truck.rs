//! The demo's glTF scene: a textured model from the format artists export (the Cesium Milk
//! Truck, `assets/gltf/`) on a ground quad (`assets/scenes/truck.toml`), baked (or its bake
//! reused) and relit with SH and with wavelets under sunrise and studio, onto a contact sheet
//! (`truck_sheet.png`) whose captions give each image's error against every term.

use std::path::{Path, PathBuf};

use crate::app::studies::Study;
use crate::draw::background::{composite, environment_behind};
use crate::env::envmap::{EnvMap, EnvRotation};
use crate::env::select::Weighting;
use crate::error::Result;
use crate::output::film::ToneMap;
use crate::output::metrics::relative_l2;
use crate::output::sheet::{Cell, write_sheet};
use crate::relight::{LightContext, RelightRequest, relight};

/// The environments of the sheet, one row each.
pub const TRUCK_ENVS: [&str; 2] = ["blender_sunrise", "blender_studio"];

/// What the glTF part of the demo produced.
pub struct TruckReport {
    /// The bake, `dir/truck.prt`.
    pub transport_path: PathBuf,
    /// The sheet, `dir/truck_sheet.png`.
    pub sheet_path: PathBuf,
    /// Whether the bake was reused.
    pub reused_bake: bool,
    /// Time to bake (or to load the cached bake).
    pub bake_seconds: f64,
    /// Triangles of the scene, and the texels of its textures.
    pub triangles: usize,
    /// Texels of its textures.
    pub texels: usize,
    /// Per environment, per image of the sheet: (caption, relative L2 against every term).
    pub errors: Vec<(String, Vec<(String, f64)>)>,
}

/// Bakes (or reuses) the glTF scene under `assets` into `dir/truck.prt` with `settings` (the
/// demo's) and writes its sheet, wavelets chosen by `weighting`.
pub fn run_truck(study: &mut Study, assets: &Path, weighting: Weighting) -> Result<TruckReport> {
    let (dir, settings) = (study.dir, study.settings);
    let (scene, transport_path) = study.asset_scene(assets, "truck")?;
    let detail = format!(
        "({} triangles, {} textures)",
        scene.triangle_count(),
        scene.textures.len()
    );
    let (t, reused_bake, bake_seconds) = study.bake(&transport_path, &scene, settings, &detail)?;
    let ctx = LightContext::new(&t)?;
    let top = format!("SH order {}", settings.sh_order);
    let requests = [
        (RelightRequest::Sh { order: 4 }, "SH order 4"),
        (
            RelightRequest::Sh {
                order: settings.sh_order,
            },
            top.as_str(),
        ),
        (RelightRequest::Wavelet { k: 50, weighting }, "K = 50"),
        (RelightRequest::Wavelet { k: 200, weighting }, "K = 200"),
        (RelightRequest::Full, "full"),
    ];
    let mut shots = Vec::new();
    let mut errors = Vec::new();
    for name in TRUCK_ENVS {
        let env = EnvMap::load(&assets.join(format!("envmaps/{name}.exr")))?;
        let light = ctx.prepare(&env, EnvRotation::default())?;
        let behind = environment_behind(&t.meta, &t.coverage, &env, EnvRotation::default())?;
        let (full, _) = relight(&t, &ctx, &light, &RelightRequest::Full)?;
        let tone = ToneMap::auto(&full, Some(&t.coverage));
        let mut row = Vec::new();
        for (req, caption) in &requests {
            let (img, _) = relight(&t, &ctx, &light, req)?;
            let err = relative_l2(&img, &full, Some(&t.coverage))?;
            let second = if matches!(req, RelightRequest::Full) {
                name.trim_start_matches("blender_").to_string()
            } else {
                format!("L2 error {:.1}%", 100.0 * err)
            };
            shots.push((
                composite(&img, &behind),
                tone,
                [caption.to_string(), second],
            ));
            row.push((caption.to_string(), err));
        }
        errors.push((name.to_string(), row));
    }
    let cells: Vec<Cell> = shots
        .iter()
        .map(|(image, tone, caption)| Cell {
            image,
            tone: *tone,
            caption: caption.clone(),
        })
        .collect();
    let sheet_path = dir.join("truck_sheet.png");
    write_sheet(
        &sheet_path,
        requests.len(),
        &cells,
        "glTF: the Cesium Milk Truck (CC BY 4.0) on a ground quad; SH against K wavelet terms, relative L2 against full",
    )?;
    study.log(&format!("relit the glTF scene -> {}", sheet_path.display()));
    Ok(TruckReport {
        transport_path,
        sheet_path,
        reused_bake,
        bake_seconds,
        triangles: scene.triangle_count(),
        texels: scene
            .textures
            .iter()
            .map(|t| t.width as usize * t.height as usize)
            .sum(),
        errors,
    })
}
