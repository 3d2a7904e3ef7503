//! The embedded default, end to end: the bundled demo scene and environments are written out, the
//! scene is baked (or the cached bake reused when scene and settings are unchanged), and it is
//! relit under every bundled environment with SH, wavelets at several K, and every term. The
//! result is a set of images, a labelled contact sheet, and a markdown table of error and time.
//! Then the volume path: the bundled cloud's SH self-transfer is baked and the cloud ray-marched
//! under every environment from a free camera.

use std::path::{Path, PathBuf};

use crate::app::studies::{Study, dusk, gloss_orbit, orbit, percent_cells, truck};
use crate::bake::{BakeProgress, BakeSettings, load_or_bake_logged};
use crate::draw::background::{composite, environment_behind};
use crate::env::envmap::{BUNDLED_MAPS, EnvMap, EnvRotation};
use crate::env::select::Weighting;
use crate::error::Result;
use crate::files::{Bundled, bundled};
use crate::output::film::{Image, ToneMap};
use crate::output::metrics::relative_l2;
use crate::output::sheet::{Cell, downsample, write_sheet};
use crate::relight::{LightContext, Method, RelightRequest, relight};
use crate::scene::Scene;

/// Everything the demo needs besides the environment maps (`env::envmap::BUNDLED_MAPS`, which it
/// writes to `envmaps/`), embedded so it runs from any directory.
pub const ASSETS: &[Bundled] = &[
    bundled!("scenes/demo.toml"),
    bundled!("scenes/dusk.toml"),
    bundled!("scenes/truck.toml"),
    bundled!("gltf/CesiumMilkTruck.glb"),
    bundled!("scenes/spheres.toml"),
    bundled!("scenes/teapot.toml"),
    bundled!("scenes/cloud.toml"),
    bundled!("scenes/fog.toml"),
    bundled!("meshes/bunny.obj"),
    bundled!("meshes/teapot.obj"),
    bundled!("meshes/suzanne.obj"),
];

/// SH orders the demo shows.
pub const DEMO_SH_ORDERS: [usize; 3] = [2, 4, 6];
/// Kept wavelet terms the demo shows.
pub const DEMO_TERMS: [usize; 4] = [10, 50, 200, 1000];
/// Weighting of the demo's wavelet selection.
pub const DEMO_WEIGHTING: Weighting = Weighting::Transport;

/// The demo's bake settings: the CLI defaults, whose SH order is the highest of
/// [`DEMO_SH_ORDERS`].
pub fn demo_settings() -> BakeSettings {
    BakeSettings::default()
}

/// One relit image of the demo.
#[derive(Clone, Debug)]
pub struct DemoRow {
    /// Name of the environment (its file stem, such as `blender_sunrise`).
    pub env: String,
    /// How the light was approximated.
    pub method: Method,
    /// K for wavelets, n² for SH, 6 N² for full.
    pub terms: usize,
    /// Relative L2 against `full` under the same environment.
    pub rel_l2: f64,
    /// CPU kernel time of the relight, milliseconds.
    pub relight_ms: f64,
}

/// What the demo produced.
pub struct DemoReport {
    /// Every relit image: per environment, each SH order, each K and every term.
    pub rows: Vec<DemoRow>,
    /// The per-pixel bake, `dir/demo.prt`.
    pub transport_path: PathBuf,
    /// The contact sheet, `dir/contact_sheet.png`.
    pub sheet_path: PathBuf,
    /// The markdown summary, `dir/summary.md`.
    pub table_path: PathBuf,
    /// Whether the cached bake in `transport_path` was loaded instead of baking anew.
    pub reused_bake: bool,
    /// Time to bake (or to load the cached bake).
    pub bake_seconds: f64,
    /// The volume path: transfer bake time, and per environment the march time (ms).
    pub volume_bake_seconds: f64,
    /// Per bundled environment: its name and the cloud's CPU march time, milliseconds.
    pub volume_rows: Vec<(String, f64)>,
    /// The per-vertex bake drawn from four angles, and its error against the per-pixel bake.
    pub orbit: crate::app::studies::orbit::OrbitReport,
    /// The glossy per-vertex bake (its lobe drawn per pixel), drawn from four angles and held to
    /// the path tracer from one.
    pub gloss: crate::app::studies::gloss_orbit::GlossReport,
    /// The dusk scene with its local lights.
    pub dusk: crate::app::studies::dusk::DuskReport,
    /// The glTF scene.
    pub truck: crate::app::studies::truck::TruckReport,
}

/// Writes the bundled assets under `dir/assets`, and returns that folder. A file that is there
/// already is never replaced: one that matches is left as it is, and one that differs (a
/// user's edit) is kept and named through `log`, as what the run reads in place of the bundled
/// copy.
pub fn write_assets(dir: &Path, log: &mut dyn FnMut(&str)) -> Result<PathBuf> {
    let root = dir.join("assets");
    let mut kept = Vec::new();
    for &Bundled { path, bytes } in ASSETS.iter().chain(BUNDLED_MAPS) {
        let p = root.join(path);
        if std::fs::symlink_metadata(&p).is_ok() {
            if !std::fs::read(&p).is_ok_and(|b| b == bytes) {
                kept.push(path);
            }
            continue;
        }
        let parent = p.parent().unwrap_or(&root);
        crate::files::create_folder(parent)?;
        crate::files::write_bytes_atomically(&p, bytes)?;
    }
    if !kept.is_empty() {
        log(&format!(
            "warning: {} differ from the bundled copies and are kept as they are (the run reads \
             them): {}; remove them to get the bundled ones back",
            root.display(),
            kept.join(", ")
        ));
    }
    Ok(root)
}

/// Runs the demo into `dir`. `log` receives one line per step; `progress` follows the bake.
pub fn run_demo(
    dir: &Path,
    log: &mut dyn FnMut(&str),
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<DemoReport> {
    crate::files::create_folder(dir)?;
    let assets = write_assets(dir, log)?;
    log(&format!(
        "bundled environment maps in {} (any --env also takes them by name: {})",
        assets.join("envmaps").display(),
        crate::env::envmap::bundled_names()
    ));
    let scene = Scene::load(&assets.join("scenes/demo.toml"))?;
    let settings = demo_settings();
    let transport_path = dir.join("demo.prt");
    let what = format!(
        "baking {} at {}x{}, N = {}, SH order {} ...",
        scene.source_path.display(),
        scene.camera.width,
        scene.camera.height,
        settings.cube_n,
        settings.sh_order
    );
    let (transport, reused, bake_seconds) =
        load_or_bake_logged(&transport_path, &scene, &settings, &what, log, progress)?;
    let ctx = LightContext::new(&transport)?;
    let images = dir.join("images");
    crate::files::create_folder(&images)?;
    let mut rows = Vec::new();
    let mut thumbs: Vec<(Image, ToneMap, [String; 2])> = Vec::new();
    for entry in bundled_envs(&assets) {
        let (name, env) = entry?;
        let light = ctx.prepare(&env, EnvRotation::default())?;
        // Shown and saved over the environment behind the scene; errors are taken before.
        let behind = environment_behind(
            &transport.meta,
            &transport.coverage,
            &env,
            EnvRotation::default(),
        )?;
        let shown = |img: &Image| composite(img, &behind);
        let full_req = RelightRequest::Full;
        let (full, full_stats) = relight(&transport, &ctx, &light, &full_req)?;
        let tone = ToneMap::auto(&full, Some(&transport.coverage));
        // Each request with its file label and caption.
        let mut requests: Vec<(RelightRequest, String, String)> = DEMO_SH_ORDERS
            .iter()
            .map(|&order| {
                (
                    RelightRequest::Sh { order },
                    format!("sh_order{order}"),
                    format!("SH order {order}"),
                )
            })
            .collect();
        requests.extend(DEMO_TERMS.iter().map(|&k| {
            (
                RelightRequest::Wavelet {
                    k,
                    weighting: DEMO_WEIGHTING,
                },
                format!("wavelet{k}"),
                format!("K = {k}"),
            )
        }));
        for (req, label, caption) in requests {
            let (img, stats) = relight(&transport, &ctx, &light, &req)?;
            let err = relative_l2(&img, &full, Some(&transport.coverage))?;
            let img = shown(&img);
            img.save(&images.join(format!("{name}_{label}.png")), tone)?;
            thumbs.push((
                downsample(&img, 2),
                tone,
                [caption, format!("L2 error {:.1}%", 100.0 * err)],
            ));
            rows.push(DemoRow {
                env: name.clone(),
                method: req.method(),
                terms: stats.terms,
                rel_l2: err,
                relight_ms: stats.kernel_seconds * 1e3,
            });
        }
        let full = shown(&full);
        full.save(&images.join(format!("{name}_full.png")), tone)?;
        full.save(&images.join(format!("{name}_full.exr")), tone)?;
        thumbs.push((
            downsample(&full, 2),
            tone,
            ["full".into(), short_name(&name)],
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
    let cells = cells_of(&thumbs);
    let sheet_path = dir.join("contact_sheet.png");
    write_sheet(
        &sheet_path,
        columns,
        &cells,
        &format!(
            "Cube 6x{0}x{0}: SH order n (n² terms) against K wavelet terms ({1} weighting); relative L2 error against full",
            transport.meta.identity.cube_n, DEMO_WEIGHTING
        ),
    )?;
    let sunrise = EnvMap::load(&assets.join("envmaps/blender_sunrise.exr"))?;
    let mut study = Study {
        dir,
        settings: &settings,
        log,
        progress,
    };
    let study = &mut study;
    let orbit = orbit::run_orbit(study, &scene, &transport, ("sunrise", &sunrise))?;
    let gloss = gloss_orbit::run_gloss_orbit(study, &scene, ("sunrise", &sunrise))?;
    let dusk = dusk::run_dusk(study, &assets, DEMO_WEIGHTING)?;
    let truck = truck::run_truck(study, &assets, DEMO_WEIGHTING)?;
    let (volume_bake_seconds, volume_rows) = run_volume_demo(dir, &assets, log)?;
    let report = DemoReport {
        gloss,
        dusk,
        truck,
        rows,
        transport_path,
        sheet_path,
        table_path: dir.join("summary.md"),
        reused_bake: reused,
        bake_seconds,
        volume_bake_seconds,
        volume_rows,
        orbit,
    };
    crate::files::write_bytes_atomically(&report.table_path, summary_markdown(&report).as_bytes())?;
    Ok(report)
}

/// Paths per pixel of the demo's volumetric references.
const VOLUME_REFERENCE_SAMPLES: u32 = 1024;
/// The environments the demo's cloud is path traced under, beside its march.
const VOLUME_REFERENCE_ENVS: [&str; 2] = ["blender_sunrise", "pmndrs_city_overcast"];

/// The volume half of the demo: bakes the cloud's SH self-transfer and scattered fields into
/// `dir/cloud.prtv`, marches it under every bundled environment from a three-quarter view into
/// `dir/volume/`, and under sunrise and overcast sets single scattering beside every order and
/// the volumetric path tracer.
fn run_volume_demo(
    dir: &Path,
    assets: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<(f64, Vec<(String, f64)>)> {
    use crate::volume::path_trace::{VolumeTraceSettings, path_trace_volume};
    use crate::volume::{
        MediumLook, TransferSettings, VolumeLight, VolumeView, bake_volume, render_volume,
    };
    let scene = Scene::load(&assets.join("scenes/cloud.toml"))?;
    let start = std::time::Instant::now();
    let settings = TransferSettings::default();
    let file = dir.join("cloud.prtv");
    // A volume baked by an earlier run from the same scene with the same settings is reused,
    // and so are its path-traced references.
    let earlier = crate::volume::VolumeTransfer::load(&file)
        .ok()
        .filter(|vt| {
            let m = &vt.meta;
            let s = &settings.scatter;
            m.scene_hash == scene.hash_hex()
                && m.sh_order == settings.sh_order
                && m.directions == settings.directions
                && m.scatter.as_ref().is_some_and(|f| {
                    (f.orders, f.angular, f.light, f.directions)
                        == (s.orders, s.angular, s.light, s.directions)
                })
        });
    let reused = earlier.is_some();
    let vt = match earlier {
        Some(vt) => vt,
        None => {
            let vt = bake_volume(&scene, None, &settings, &|_, _| {})?;
            vt.save(&file)?;
            vt
        }
    };
    let bake_seconds = start.elapsed().as_secs_f64();
    log(&format!(
        "{} the cloud's SH self-transfer and {} scattering orders ({:?} voxels) in \
         {bake_seconds:.2} s",
        if reused { "reused" } else { "baked" },
        vt.orders(),
        vt.meta.dims
    ));
    let out = dir.join("volume");
    crate::files::create_folder(&out)?;
    let camera = vt.camera(
        Some(glam::Vec3::new(2.1, 2.1, 2.3)),
        Some(glam::Vec3::new(0.0, 1.4, 0.0)),
        Some((256, 192)),
    )?;
    let look = MediumLook::of(&vt);
    let every = format!("{} orders + tail", vt.orders());
    let mut rows = Vec::new();
    let mut compared: Vec<(Image, ToneMap, [String; 2])> = Vec::new();
    let mut others: Vec<(Image, ToneMap, [String; 2])> = Vec::new();
    for entry in bundled_envs(assets) {
        let (name, env) = entry?;
        let cube = env.to_cube(32, EnvRotation::default())?;
        let light = VolumeLight::new(&vt, &cube, &look)?;
        let start = std::time::Instant::now();
        let img = render_volume(&vt, &light, &camera, VolumeView::Full);
        rows.push((name.clone(), start.elapsed().as_secs_f64() * 1e3));
        let tone = ToneMap::auto(&img, None);
        img.save(&out.join(format!("cloud_{name}.png")), tone)?;
        if !VOLUME_REFERENCE_ENVS.contains(&name.as_str()) {
            others.push((img, tone, [every.clone(), short_name(&name)]));
            continue;
        }
        // Single scattering and the path tracer, in the same tone map as every order.
        let once = VolumeLight::new(&vt, &cube, &MediumLook { orders: 1, ..look })?;
        let single = render_volume(&vt, &once, &camera, VolumeView::Full);
        let exr = out.join(format!("cloud_{name}_path_traced.exr"));
        let kept = Image::load_exr(&exr)
            .ok()
            .filter(|i| reused && (i.width, i.height) == (img.width, img.height));
        let (reference, noise) = match kept {
            Some(image) => (image, "kept from the last run".to_string()),
            None => {
                let traced = path_trace_volume(
                    &vt.medium(),
                    &cube,
                    &camera,
                    &VolumeTraceSettings {
                        samples: VOLUME_REFERENCE_SAMPLES,
                        ..Default::default()
                    },
                    &|_, _| {},
                )?;
                traced.image.save(&exr, tone)?;
                let noise = format!("noise {:.1}%", 100.0 * traced.relative_noise(None));
                (traced.image, noise)
            }
        };
        reference.save(&out.join(format!("cloud_{name}_path_traced.png")), tone)?;
        let e_every = crate::output::metrics::relative_l2(&img, &reference, None)?;
        let e_single = crate::output::metrics::relative_l2(&single, &reference, None)?;
        log(&format!(
            "cloud under {name}: against the path tracer ({VOLUME_REFERENCE_SAMPLES} paths, \
             {noise}), single scattering {:.1}%, {every} {:.1}%",
            100.0 * e_single,
            100.0 * e_every
        ));
        compared.push((
            single,
            tone,
            [
                format!("single, {}", short_name(&name)),
                format!("{:.0}% off", 100.0 * e_single),
            ],
        ));
        compared.push((
            img,
            tone,
            [every.clone(), format!("{:.1}% off", 100.0 * e_every)],
        ));
        compared.push((
            reference,
            tone,
            [
                "path traced".into(),
                format!("{VOLUME_REFERENCE_SAMPLES} paths"),
            ],
        ));
    }
    // Two rows of single | every order | path traced, then the other environments.
    compared.extend(others);
    let cells = cells_of(&compared);
    write_sheet(
        &dir.join("volume_sheet.png"),
        3,
        &cells,
        "Cloud: single scattering, every order, and the volumetric path tracer",
    )?;
    log(&format!(
        "marched the cloud under {} environments",
        rows.len()
    ));
    Ok((bake_seconds, rows))
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

/// The bundled environment maps, each loaded from the written assets when its turn comes, with
/// its file stem.
fn bundled_envs(assets: &Path) -> impl Iterator<Item = Result<(String, EnvMap)>> + '_ {
    BUNDLED_MAPS
        .iter()
        .map(move |m| Ok((m.stem().to_string(), EnvMap::load(&assets.join(m.path))?)))
}

/// Contact-sheet cells of images kept with their tone maps and captions.
fn cells_of(shots: &[(Image, ToneMap, [String; 2])]) -> Vec<Cell<'_>> {
    shots
        .iter()
        .map(|(image, tone, caption)| Cell {
            image,
            tone: *tone,
            caption: caption.clone(),
        })
        .collect()
}

/// The demo's `summary.md`: the relights' table, then the volume, per-vertex, glossy, local
/// lights' and glTF figures of `r`.
fn summary_markdown(r: &DemoReport) -> String {
    let mut table = markdown_table(&r.rows);
    table.push_str(&format!(
        "\nVolume (`assets/scenes/cloud.toml`, SH order 3, 512 directions): transfer baked in \
         {:.2} s; `volume/` holds the cloud marched under each environment.\n\n\
         | environment | CPU march (ms) |\n|---|---:|\n",
        r.volume_bake_seconds
    ));
    for (env, ms) in &r.volume_rows {
        table.push_str(&format!("| {env} | {ms:.1} |\n"));
    }
    table.push_str(&format!(
        "\nPer vertex (`orbit_sheet.png`), under sunrise from the scene's camera. Interpolation: \
         every term, against the per-pixel bake on its diffuse surfaces (a per-vertex bake keeps \
         only the diffuse base of the glossy teapot). Light: K = {k} against every term, per \
         vertex.\n\n| edges up to | vertices | triangles | bake (s) | interpolation | light, K = \
         {k} |\n|---:|---:|---:|---:|---:|---:|\n",
        k = crate::app::studies::orbit::ORBIT_TERMS
    ));
    for t in [&r.orbit.fine, &r.orbit.coarse] {
        table.push_str(&format!(
            "| {:.3} | {} | {} | {:.1} | {:.2}% | {:.2}% |\n",
            t.edge_length,
            t.vertices,
            t.triangles,
            t.bake_seconds,
            100.0 * t.interpolation_error,
            100.0 * t.light_error
        ));
    }
    table.push_str(&format!(
        "\nA frame at K = {} on the CPU, {} vertices: relight {:.1} ms + draw {:.1} ms = {:.1} ms.\n",
        crate::app::studies::orbit::ORBIT_TERMS,
        r.orbit.fine.vertices,
        r.orbit.relight_ms,
        r.orbit.draw_ms,
        r.orbit.frame_ms
    ));
    table.push_str(&format!(
        "\nGlossy per vertex (`gloss_sheet.png`): the same scene per vertex with its porcelain \
         teapot's visibility, the lobe drawn per pixel ({} vertices, {:.1} KB a vertex), bake \
         {:.1} s{}; from {}° round, under sunrise, against the path tracer ({} paths a \
         pixel{}), the whole image: {:.1}% with the lobe, {:.1}% for the diffuse base.\n",
        r.gloss.vertices,
        r.gloss.bytes_per_vertex / 1e3,
        r.gloss.bake_seconds,
        if r.gloss.reused_bake { " (reused)" } else { "" },
        crate::app::studies::gloss_orbit::GLOSS_REFERENCE_AZIMUTH,
        crate::app::studies::gloss_orbit::GLOSS_REFERENCE_PATHS,
        r.gloss
            .reference_noise
            .map(|n| format!(", noise {:.1}%", 100.0 * n))
            .unwrap_or_default(),
        100.0 * r.gloss.glossy_error,
        100.0 * r.gloss.diffuse_error
    ));
    table.push_str(&format!(
        "\nLocal lights (`dusk_sheet.png`): `assets/scenes/dusk.toml` under `{}` with a quad \
         panel, a spot and a lamp baked at 5 positions ({} light columns), bake {:.1} s{}; \
         adding every light to a relit image takes {:.2} ms on the CPU.\n",
        crate::app::studies::dusk::DUSK_SUN,
        r.dusk.columns,
        r.dusk.bake_seconds,
        if r.dusk.reused_bake { " (reused)" } else { "" },
        r.dusk.lights_ms
    ));
    table.push_str(&format!(
        "\nglTF (`truck_sheet.png`): `assets/scenes/truck.toml`, the Cesium Milk Truck ({} \
         triangles with the ground, {} texels of texture), bake {:.1} s{}; relative L2 against \
         every term:\n\n| environment |{}\n|---|{}\n",
        r.truck.triangles,
        r.truck.texels,
        r.truck.bake_seconds,
        if r.truck.reused_bake { " (reused)" } else { "" },
        r.truck
            .errors
            .first()
            .map(|(_, row)| row
                .iter()
                .map(|(c, _)| format!(" {c} |"))
                .collect::<String>())
            .unwrap_or_default(),
        r.truck
            .errors
            .first()
            .map(|(_, row)| "---:|".repeat(row.len()))
            .unwrap_or_default(),
    ));
    for (env, row) in &r.truck.errors {
        table.push_str(&format!(
            "| {env} |{}\n",
            percent_cells(row.iter().map(|(_, e)| *e))
        ));
    }
    table
}
