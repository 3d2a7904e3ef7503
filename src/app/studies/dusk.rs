//! The demo's local lights: the demo scene at dusk (`assets/scenes/dusk.toml`: a low sun, a
//! warm panel, a cool spot and a lamp that moves along a path) is baked (or its bake reused),
//! relit with the lights on, off and alone, and with the lamp moved along its path, onto a
//! contact sheet (`dusk_sheet.png`).

use std::path::{Path, PathBuf};

use crate::app::studies::Study;
use crate::draw::background::{composite, environment_behind};
use crate::env::envmap::{EnvMap, EnvRotation, EnvSpec};
use crate::env::select::Weighting;
use crate::error::Result;
use crate::output::film::{Image, ToneMap};
use crate::output::sheet::{Cell, downsample, write_sheet};
use crate::relight::{Backend, Cpu, LightContext, LightMix, LightSetting, RelightRequest, Terms};
use crate::store::transport::Transport;

/// The environment of the dusk scene: a sun 4° above the horizon, in the west.
pub const DUSK_SUN: &str = "sun:4,250";

/// What the dusk part of the demo produced.
pub struct DuskReport {
    /// The bake, `dir/dusk.prt`.
    pub transport_path: PathBuf,
    /// The sheet, `dir/dusk_sheet.png`.
    pub sheet_path: PathBuf,
    /// Whether the bake was reused.
    pub reused_bake: bool,
    /// Time to bake (or to load the cached bake).
    pub bake_seconds: f64,
    /// Light columns in the bake.
    pub columns: usize,
    /// The CPU time of adding every light to a relit image, milliseconds (median of the sheet's
    /// relights).
    pub lights_ms: f64,
}

/// Bakes (or reuses) the dusk scene under `assets` into `dir/dusk.prt` with `settings` (the
/// demo's) and writes its sheet, the environment relit with K = 200 terms chosen by
/// The dusk's sun and sky, and its light as the dusk's sheet relights it: the 200 wavelet terms
/// `weighting` keeps.
pub fn dusk_terms(t: &Transport, weighting: Weighting) -> Result<(EnvMap, Terms)> {
    let env = EnvSpec::parse(DUSK_SUN)?.load()?;
    let ctx = LightContext::new(t)?;
    let light = ctx.prepare(&env, EnvRotation::default())?;
    let terms = Terms::of(
        t,
        &ctx,
        &light,
        &RelightRequest::Wavelet { k: 200, weighting },
    )?;
    Ok((env, terms))
}

/// `weighting`.
pub fn run_dusk(study: &mut Study, assets: &Path, weighting: Weighting) -> Result<DuskReport> {
    let (dir, settings) = (study.dir, study.settings);
    let (scene, transport_path) = study.asset_scene(assets, "dusk")?;
    let detail = format!("with its {} local lights", scene.lights.len());
    let (t, reused_bake, bake_seconds) = study.bake(&transport_path, &scene, settings, &detail)?;
    let (env, terms) = dusk_terms(&t, weighting)?;
    let behind = environment_behind(&t.meta, &t.coverage, &env, EnvRotation::default())?;
    let lights = &t.meta.lights;
    let defaults = LightSetting::defaults(lights);
    let only = |name: &str, at: f32| -> Vec<LightSetting> {
        let at = [at, 0.0, 0.0];
        lights
            .iter()
            .zip(&defaults)
            .map(|(l, s)| LightSetting {
                on: l.name == name,
                at: if l.name == name { at } else { s.at },
                ..*s
            })
            .collect()
    };
    let off: Vec<LightSetting> = defaults
        .iter()
        .map(|s| LightSetting { on: false, ..*s })
        .collect();
    let lamp_last = lights
        .iter()
        .find(|l| l.name == "lamp")
        .map_or(0.0, |l| (l.columns() - 1) as f32);
    // (environment on, settings, caption).
    let shots: Vec<(bool, Vec<LightSetting>, [String; 2])> = vec![
        (true, off, ["env only".into(), "K = 200".into()]),
        (
            true,
            defaults.clone(),
            ["env + lights".into(), "all three".into()],
        ),
        (
            false,
            defaults.clone(),
            ["lights only".into(), "env off".into()],
        ),
        (
            false,
            only("spot", 0.0),
            ["spot solo".into(), String::new()],
        ),
        (
            false,
            only("lamp", 0.0),
            ["lamp at 0".into(), "baked".into()],
        ),
        (
            false,
            only("lamp", 1.5),
            ["lamp at 1.5".into(), "blended".into()],
        ),
        (
            false,
            only("lamp", lamp_last - 1.0),
            [format!("lamp at {}", lamp_last - 1.0), "baked".into()],
        ),
        (
            false,
            only("lamp", lamp_last),
            [format!("lamp at {lamp_last}"), "baked".into()],
        ),
    ];
    let dark = Terms::dark();
    let mut images = Vec::with_capacity(shots.len());
    for (environment, settings, caption) in shots {
        let mix = LightMix::new(lights, &settings)?;
        let (img, _) = Cpu(&t).relight_lit(if environment { &terms } else { &dark }, &mix)?;
        let img = if environment {
            composite(&img, &behind)
        } else {
            img
        };
        images.push((environment, downsample(&img, 2), caption));
    }
    // What adding every light costs, apart from the environment's product.
    let all = LightMix::new(lights, &defaults)?;
    let mut scratch = Image::new(t.meta.width as usize, t.meta.height as usize);
    let mut times: Vec<f64> = (0..5)
        .map(|_| {
            let start = std::time::Instant::now();
            crate::relight::columns::add_columns(
                &t.attached.lights,
                &all.weights,
                &mut scratch.pixels,
            );
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    // One exposure for the images with the environment, one for the lights alone.
    let lit = ToneMap::auto(&images[1].1, None);
    let alone = ToneMap::auto(&images[2].1, None);
    let cells: Vec<Cell> = images
        .iter()
        .map(|(environment, image, caption)| Cell {
            image,
            tone: if *environment { lit } else { alone },
            caption: caption.clone(),
        })
        .collect();
    let sheet_path = dir.join("dusk_sheet.png");
    write_sheet(
        &sheet_path,
        4,
        &cells,
        &format!("Dusk ({DUSK_SUN}): lights on, off, alone; the lamp moved (2 exposures)"),
    )?;
    study.log(&format!("relit the dusk scene -> {}", sheet_path.display()));
    Ok(DuskReport {
        transport_path,
        sheet_path,
        reused_bake,
        bake_seconds,
        columns: t.meta.light_columns(),
        lights_ms: times.get(times.len() / 2).copied().unwrap_or(0.0) * 1e3,
    })
}
