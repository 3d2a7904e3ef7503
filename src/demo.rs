//! The embedded default, end to end: the bundled demo scene and environments are written out, the
//! scene is baked (or the cached bake reused when scene and settings are unchanged), and it is
//! relit under every bundled environment with SH, wavelets at several K, and every term. The
//! result is a set of images, a labelled contact sheet, and a markdown table of error and time.

use std::path::{Path, PathBuf};

use crate::bake::{BakeProgress, BakeSettings, bake, load_if_baked_with};
use crate::envmap::{EnvMap, EnvRotation};
use crate::error::{PrtError, Result};
use crate::film::{Image, ToneMap};
use crate::light::Weighting;
use crate::metrics::relative_l2;
use crate::relight::{LightContext, Method, RelightRequest, relight};
use crate::scene::Scene;
use crate::sheet::{Cell, downsample, write_sheet};

/// A file bundled into the binary: its path under the demo's `assets/` and its bytes.
pub struct Asset {
    pub path: &'static str,
    pub bytes: &'static [u8],
}

macro_rules! asset {
    ($p:literal) => {
        Asset {
            path: $p,
            bytes: include_bytes!(concat!("../assets/", $p)),
        }
    };
}

/// Everything the demo needs, embedded so it runs from any directory.
pub const ASSETS: &[Asset] = &[
    asset!("scenes/demo.toml"),
    asset!("scenes/spheres.toml"),
    asset!("meshes/bunny.obj"),
    asset!("meshes/teapot.obj"),
    asset!("meshes/suzanne.obj"),
    asset!("envmaps/blender_sunrise.exr"),
    asset!("envmaps/blender_city.exr"),
    asset!("envmaps/blender_interior.exr"),
    asset!("envmaps/blender_night.exr"),
    asset!("envmaps/blender_studio.exr"),
    asset!("envmaps/pmndrs_city_overcast.exr"),
];

/// SH orders the demo shows.
pub const DEMO_SH_ORDERS: [usize; 3] = [2, 4, 8];
/// Kept wavelet terms the demo shows.
pub const DEMO_TERMS: [usize; 4] = [10, 50, 200, 1000];
/// Weighting of the demo's wavelet selection.
pub const DEMO_WEIGHTING: Weighting = Weighting::Area;

/// The demo's bake settings: the CLI defaults with SH up to order 8.
pub fn demo_settings() -> BakeSettings {
    BakeSettings {
        sh_order: 8,
        ..BakeSettings::default()
    }
}

/// One relit image of the demo.
#[derive(Clone, Debug)]
pub struct DemoRow {
    pub env: String,
    pub method: Method,
    /// K for wavelets, n² for SH, 6 N² for full.
    pub terms: usize,
    /// Relative L2 against `full` under the same environment.
    pub rel_l2: f64,
    pub relight_ms: f64,
}

/// What the demo produced.
pub struct DemoReport {
    pub rows: Vec<DemoRow>,
    pub transport_path: PathBuf,
    pub sheet_path: PathBuf,
    pub table_path: PathBuf,
    pub reused_bake: bool,
    /// Time to bake (or to load the cached bake).
    pub bake_seconds: f64,
}

/// Writes the bundled assets under `dir/assets` (leaving files that already match).
pub fn write_assets(dir: &Path) -> Result<PathBuf> {
    let root = dir.join("assets");
    for a in ASSETS {
        let p = root.join(a.path);
        if std::fs::read(&p).is_ok_and(|b| b == a.bytes) {
            continue;
        }
        let parent = p.parent().unwrap_or(&root);
        std::fs::create_dir_all(parent).map_err(|e| PrtError::io(parent, e))?;
        crate::film::write_atomically(&p, |tmp| {
            std::fs::write(tmp, a.bytes).map_err(|e| PrtError::io(tmp, e))
        })?;
    }
    Ok(root)
}

/// Runs the demo into `dir`. `log` receives one line per step; `progress` follows the bake.
pub fn run_demo(
    dir: &Path,
    log: &mut dyn FnMut(&str),
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<DemoReport> {
    std::fs::create_dir_all(dir).map_err(|e| PrtError::io(dir, e))?;
    let assets = write_assets(dir)?;
    let scene = Scene::load(&assets.join("scenes/demo.toml"))?;
    let settings = demo_settings();
    let transport_path = dir.join("demo.prt");
    let bake_start = std::time::Instant::now();
    let (transport, reused) = match load_if_baked_with(&transport_path, &scene, &settings) {
        Some(t) => {
            log(&format!(
                "reusing the bake in {} (scene and settings unchanged)",
                transport_path.display()
            ));
            (t, true)
        }
        None => {
            log(&format!(
                "baking {} at {}x{}, N = {}, SH order {} ...",
                scene.source_path.display(),
                scene.camera.width,
                scene.camera.height,
                settings.cube_n,
                settings.sh_order
            ));
            let t = bake(&scene, &settings, progress)?;
            t.save(&transport_path)?;
            (t, false)
        }
    };
    let bake_seconds = bake_start.elapsed().as_secs_f64();
    let ctx = LightContext::new(&transport)?;
    let images = dir.join("images");
    std::fs::create_dir_all(&images).map_err(|e| PrtError::io(&images, e))?;
    let mut rows = Vec::new();
    let mut thumbs: Vec<(Image, ToneMap, [String; 2])> = Vec::new();
    for a in ASSETS.iter().filter(|a| a.path.starts_with("envmaps/")) {
        let name = Path::new(a.path)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("env")
            .to_string();
        let env = EnvMap::load(&assets.join(a.path))?;
        let light = ctx.prepare(&env, EnvRotation::default())?;
        let full_req = RelightRequest {
            method: Method::Full,
            terms: 0,
            weighting: DEMO_WEIGHTING,
            sh_order: settings.sh_order,
        };
        let (full, full_stats) = relight(&transport, &ctx, &light, &full_req)?;
        let tone = ToneMap::auto(&full, Some(&transport.coverage));
        let mut requests: Vec<RelightRequest> = DEMO_SH_ORDERS
            .iter()
            .map(|&o| RelightRequest {
                method: Method::Sh,
                sh_order: o,
                ..full_req
            })
            .collect();
        requests.extend(DEMO_TERMS.iter().map(|&k| RelightRequest {
            method: Method::Wavelet,
            terms: k,
            ..full_req
        }));
        for req in &requests {
            let (img, stats) = relight(&transport, &ctx, &light, req)?;
            let err = relative_l2(&img, &full, Some(&transport.coverage))?;
            let label = match req.method {
                Method::Sh => format!("sh{}", req.sh_order),
                _ => format!("wavelet{}", req.terms),
            };
            img.save(&images.join(format!("{name}_{label}.png")), tone)?;
            thumbs.push((
                downsample(&img, 2),
                tone,
                [
                    match req.method {
                        Method::Sh => format!("SH N={}", req.sh_order),
                        _ => format!("WAV K={}", req.terms),
                    },
                    format!("ERR {:.1}%", 100.0 * err),
                ],
            ));
            rows.push(DemoRow {
                env: name.clone(),
                method: req.method,
                terms: stats.terms,
                rel_l2: err,
                relight_ms: stats.kernel_seconds * 1e3,
            });
        }
        full.save(&images.join(format!("{name}_full.png")), tone)?;
        full.save(&images.join(format!("{name}_full.exr")), tone)?;
        thumbs.push((
            downsample(&full, 2),
            tone,
            ["FULL".into(), short_name(&name).to_uppercase()],
        ));
        rows.push(DemoRow {
            env: name.clone(),
            method: Method::Full,
            terms: full_stats.terms,
            rel_l2: 0.0,
            relight_ms: full_stats.kernel_seconds * 1e3,
        });
        log(&format!("relit under {name}"));
    }
    let columns = DEMO_SH_ORDERS.len() + DEMO_TERMS.len() + 1;
    let cells: Vec<Cell> = thumbs
        .iter()
        .map(|(image, tone, caption)| Cell {
            image,
            tone: *tone,
            caption: caption.clone(),
        })
        .collect();
    let sheet_path = dir.join("contact_sheet.png");
    write_sheet(
        &sheet_path,
        columns,
        &cells,
        &format!(
            "N={}: SH ORDER N VS K WAVELET TERMS ({} WEIGHTING), REL. L2 ERROR VS FULL",
            transport.meta.cube_n, DEMO_WEIGHTING
        ),
    )?;
    let table_path = dir.join("summary.md");
    let table = markdown_table(&rows);
    crate::film::write_atomically(&table_path, |tmp| {
        std::fs::write(tmp, &table).map_err(|e| PrtError::io(tmp, e))
    })?;
    Ok(DemoReport {
        rows,
        transport_path,
        sheet_path,
        table_path,
        reused_bake: reused,
        bake_seconds,
    })
}

/// A name that fits under a thumbnail: `blender_sunrise` -> `sunrise`.
fn short_name(name: &str) -> String {
    let s = name
        .trim_start_matches("blender_")
        .trim_start_matches("pmndrs_city_");
    s.chars().take(10).collect()
}

/// The demo's results as a markdown table.
pub fn markdown_table(rows: &[DemoRow]) -> String {
    let mut s = String::from(
        "| environment | method | terms | rel. L2 vs full | relight (ms) |\n|---|---|---:|---:|---:|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {:.2}% | {:.2} |\n",
            r.env,
            r.method,
            r.terms,
            100.0 * r.rel_l2,
            r.relight_ms
        ));
    }
    s
}
