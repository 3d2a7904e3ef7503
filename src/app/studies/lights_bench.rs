//! The local lights' figures (`prt lights`): each kind of light against the independent path
//! tracer with what it adds to a bake, a moving light's error between baked positions against
//! their spacing, and a scene of many small quad lights, timed as the viewer relights it. All of
//! it on the dusk scene's geometry (`assets/scenes/dusk.toml`, its own lights taken out).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::bake::path_tracer::path_trace_env;
use crate::bake::{BakeSettings, bake};
use crate::env::importance::CubeLight;
use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;
use crate::output::film::{Image, ToneMap};
use crate::output::metrics::relative_l2;
use crate::output::plot::{self, PlotSpec, Series};
use crate::relight::{Backend, Cpu, LightMix, LightSetting, Terms};
use crate::scene::Scene;
use crate::scene::light::LightKind;
use crate::store::transport::Transport;

/// What to measure.
#[derive(Clone, Debug)]
pub struct LightsBenchOptions {
    /// Image side of the path-traced comparisons (square).
    pub side: u32,
    /// Paths per pixel of the path tracer.
    pub paths: u32,
    /// Spacings of the moving light's baked positions, scene units.
    pub spacings: Vec<f32>,
    /// Quads along each side of the many-lights grid (its square is the light count).
    pub grid: usize,
    /// Image side of the many-lights scene (square).
    pub many_side: u32,
    /// Samples per shading point of each of the grid's small quads.
    pub grid_light_samples: u32,
    /// Relights per timing; the median is reported.
    pub runs: usize,
}

impl Default for LightsBenchOptions {
    fn default() -> Self {
        LightsBenchOptions {
            side: 96,
            paths: 2048,
            spacings: vec![0.05, 0.1, 0.2, 0.4, 0.8],
            grid: 16,
            many_side: 256,
            grid_light_samples: 4,
            runs: 9,
        }
    }
}

/// One kind of light against the path tracer.
#[derive(Clone, Debug)]
pub struct KindRow {
    /// The kind, as the scene file names it.
    pub kind: String,
    /// Relative L2 of the bake's column, relit, against the path tracer.
    pub rel_l2: f64,
    /// The path tracer's own noise (relative L2 of its standard error).
    pub noise: f64,
    /// Shadow rays the light adds, per pixel.
    pub rays_per_pixel: f64,
}

/// A moving light's error halfway between two baked positions.
#[derive(Clone, Copy, Debug)]
pub struct SpacingRow {
    /// Distance between the baked positions.
    pub spacing: f32,
    /// Relative L2 of the blend of the two against the light baked halfway.
    pub rel_l2: f64,
}

/// The many-lights scene's figures.
#[derive(Clone, Debug)]
pub struct ManyLights {
    /// Lights (each a small quad).
    pub lights: usize,
    /// Image size.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// The bake's seconds, and those of the same scene without its lights.
    pub bake_seconds: [f64; 2],
    /// Median milliseconds: every light added; one light's change (its column alone); the
    /// environment's K = 200 product; a viewer frame (the product and every light).
    pub ms: [f64; 4],
    /// Bytes of the light columns.
    pub column_bytes: usize,
}

/// Everything `prt lights` measured.
pub struct LightsReport {
    /// Each kind of light.
    pub kinds: Vec<KindRow>,
    /// The moving light, per spacing.
    pub spacings: Vec<SpacingRow>,
    /// The many-lights scene.
    pub many: ManyLights,
    /// The files written.
    pub files: Vec<PathBuf>,
}

/// The dusk scene's text without its lights, at `side` x `side` pixels.
fn base_scene(assets: &Path, side: u32) -> Result<String> {
    let path = assets.join("scenes/dusk.toml");
    let text = std::fs::read_to_string(&path).map_err(|e| PrtError::io(&path, e))?;
    let cut = text.find("[[light]]").unwrap_or(text.len());
    let text = text[..cut]
        .replace("width = 256", &format!("width = {side}"))
        .replace("height = 256", &format!("height = {side}"));
    Ok(text)
}

/// Writes `text` beside the bundled scenes (so their mesh paths resolve) and loads it.
fn scene_at(assets: &Path, name: &str, text: &str) -> Result<Scene> {
    let path = assets.join("scenes").join(name);
    crate::files::write_bytes_atomically(&path, text.as_bytes())?;
    Scene::load(&path)
}

fn timed_bake(scene: &Scene, settings: &BakeSettings) -> Result<(Transport, f64)> {
    let start = Instant::now();
    let t = bake(scene, settings, &|_| {})?;
    Ok((t, start.elapsed().as_secs_f64()))
}

fn median_ms(runs: usize, mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    let mut times = Vec::with_capacity(runs);
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        f()?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

/// The lights of each kind the comparison bakes, one at a time.
const KINDS: [(LightKind, &str); 4] = [
    (
        LightKind::Point,
        "position = [0.3, 1.1, 0.6]\nintensity = 1.5",
    ),
    (
        LightKind::Spot,
        "position = [2.6, 2.8, 1.9]\ndirection = [-1.45, -2.5, -1.7]\ncone_deg = 20.0\nfalloff_deg = 6.0\nintensity = 14.0",
    ),
    (
        LightKind::Directional,
        "direction = [-0.5, -0.6, -0.62]\nangle_deg = 4.0\nintensity = 2.0",
    ),
    (
        LightKind::Quad,
        "corners = [[-2.0, 2.2, -0.7], [-0.6, 2.2, -0.7], [-0.6, 2.2, 0.7], [-2.0, 2.2, 0.7]]\nintensity = 5.0",
    ),
];

/// Runs every measurement, writing the scenes under `dir/assets` and `lights.md`,
/// `lights.csv` and `moving_light.png` into `dir`; `log` follows the steps.
pub fn run(
    dir: &Path,
    opts: &LightsBenchOptions,
    log: &mut dyn FnMut(&str),
) -> Result<LightsReport> {
    crate::files::create_folder(dir)?;
    let assets = crate::app::studies::demo::write_assets(dir, log)?;
    let base = base_scene(&assets, opts.side)?;
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 2,
        ..BakeSettings::default()
    };
    // Each kind against the path tracer, and what it adds to the bake.
    let plain = bake(
        &scene_at(&assets, "bench_none.toml", &base)?,
        &settings,
        &|_| {},
    )?;
    let mut kinds = Vec::new();
    for (kind, keys) in KINDS {
        let text = format!("{base}\n\n[[light]]\nname = \"{kind}\"\ntype = \"{kind}\"\n{keys}\n");
        let scene = scene_at(&assets, &format!("bench_{kind}.toml"), &text)?;
        log(&format!(
            "{kind} light: baking, then path tracing {} paths a pixel",
            opts.paths
        ));
        let t = bake(&scene, &settings, &|_| {})?;
        let defaults = LightSetting::defaults(&scene.lights);
        let mix = LightMix::new(&scene.lights, &defaults)?;
        let (img, _) = Cpu(&t).relight_lit(&Terms::dark(), &mix)?;
        let black = CubeMap::constant(8, [0.0; 3])?;
        let traced = path_trace_env(
            &scene,
            &CubeLight::new(&black),
            &mix,
            &settings,
            opts.paths,
            &|_, _| {},
        )?;
        let pixels = t.pixel_count() as f64;
        kinds.push(KindRow {
            kind: kind.to_string(),
            rel_l2: relative_l2(&img, &traced.image, None)?,
            noise: traced.relative_noise(None),
            rays_per_pixel: (t.meta.stats.shadow_rays as f64 - plain.meta.stats.shadow_rays as f64)
                / pixels,
        });
        let tone = ToneMap::auto(&traced.image, None);
        img.save(&dir.join(format!("{kind}_bake.png")), tone)?;
        traced
            .image
            .save(&dir.join(format!("{kind}_path_traced.png")), tone)?;
    }
    // The moving light: the blend halfway between two baked positions against the light baked
    // there, with the same samples.
    let mut spacings = Vec::new();
    for &s in &opts.spacings {
        let path: Vec<[f32; 3]> = [-0.5 * s, 0.0, 0.5 * s]
            .iter()
            .map(|x| [x - 0.2, 0.55, -0.2])
            .collect();
        let text = format!(
            "{base}\n\n[[light]]\nname = \"lamp\"\ntype = \"point\"\npositions = {path:?}\nintensity = 1.0\n"
        );
        let scene = scene_at(&assets, "bench_moving.toml", &text)?;
        let t = bake(&scene, &settings, &|_| {})?;
        let mut blended = Image::new(t.meta.width as usize, t.meta.height as usize);
        let mut there = blended.clone();
        for (p, (b, h)) in blended.pixels.iter_mut().zip(&mut there.pixels).enumerate() {
            *b = std::array::from_fn(|k| {
                0.5 * (t.attached.lights.value(0, k, p) + t.attached.lights.value(2, k, p))
            });
            *h = std::array::from_fn(|k| t.attached.lights.value(1, k, p));
        }
        let rel_l2 = relative_l2(&blended, &there, None)?;
        log(&format!(
            "moving light, spacing {s}: {:.2}% halfway",
            100.0 * rel_l2
        ));
        spacings.push(SpacingRow { spacing: s, rel_l2 });
    }
    let many = many_lights(&assets, opts, log)?;
    let mut files = vec![
        dir.join("lights.md"),
        dir.join("lights.csv"),
        dir.join("moving_light.png"),
    ];
    let report = LightsReport {
        kinds,
        spacings,
        many,
        files: Vec::new(),
    };
    crate::files::write_bytes_atomically(&files[0], markdown(&report, opts).as_bytes())?;
    crate::files::write_bytes_atomically(&files[1], csv(&report).as_bytes())?;
    plot::write(
        &files[2],
        &PlotSpec {
            title: "A moving light between baked positions: relative L2 halfway".into(),
            x_label: "spacing of the baked positions (scene units; the light is 0.55 above the \
                      ground)"
                .into(),
            y_label: "relative L2 against the light baked there".into(),
            log_x: true,
            log_y: true,
            width: 720,
            height: 440,
        },
        &[Series {
            label: "point light".into(),
            points: report
                .spacings
                .iter()
                .map(|r| (r.spacing as f64, r.rel_l2.max(1e-9)))
                .collect(),
            color: plot::PALETTE[0],
            dashed: false,
        }],
    )?;
    files.extend(KINDS.iter().flat_map(|(k, _)| {
        [
            dir.join(format!("{k}_bake.png")),
            dir.join(format!("{k}_path_traced.png")),
        ]
    }));
    Ok(LightsReport { files, ..report })
}

/// The dusk geometry at `many_side`² under a `grid` x `grid` array of small quads, baked at the CLI's
/// defaults (the quads at `grid_light_samples`), and relit as the viewer does.
fn many_lights(
    assets: &Path,
    opts: &LightsBenchOptions,
    log: &mut dyn FnMut(&str),
) -> Result<ManyLights> {
    let base = base_scene(assets, opts.many_side)?;
    let n = opts.grid.max(1);
    let mut text = base.clone();
    let step = 4.8 / n as f32;
    for i in 0..n {
        for j in 0..n {
            let (x, z) = (
                -2.4 + (i as f32 + 0.5) * step,
                -2.4 + (j as f32 + 0.5) * step,
            );
            let h = 0.06;
            write!(
                text,
                "\n[[light]]\nname = \"q{i}_{j}\"\ntype = \"quad\"\ncorners = [[{:.3}, 2.6, {:.3}], [{:.3}, 2.6, {:.3}], [{:.3}, 2.6, {:.3}], [{:.3}, 2.6, {:.3}]]\nintensity = {:.3}\ncolor = [{:.2}, {:.2}, {:.2}]\n",
                x - h, z - h, x + h, z - h, x + h, z + h, x - h, z + h,
                40.0 / (n * n) as f32 * 16.0,
                0.6 + 0.4 * (i as f32 / n as f32),
                0.8,
                0.6 + 0.4 * (j as f32 / n as f32),
            )
            .map_err(|e| PrtError::invalid("lights bench", e.to_string()))?;
        }
    }
    let settings = BakeSettings {
        light_samples: opts.grid_light_samples,
        ..BakeSettings::default()
    };
    log(&format!(
        "{} lights: baking at {}² ...",
        n * n,
        opts.many_side
    ));
    let scene = scene_at(assets, "bench_many.toml", &text)?;
    let (t, seconds) = timed_bake(&scene, &settings)?;
    log("the same scene without its lights ...");
    let (_, plain) = timed_bake(&scene_at(assets, "bench_many_none.toml", &base)?, &settings)?;
    let lights = &t.meta.lights;
    let defaults = LightSetting::defaults(lights);
    let all = LightMix::new(lights, &defaults)?;
    let mut one = LightMix {
        weights: vec![[0.0; 3]; all.weights.len()],
    };
    one.weights[n * n / 2] = [0.5, 0.4, 0.3];
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let mut image = Image::new(w, h);
    let all_ms = median_ms(opts.runs, || {
        crate::relight::columns::add_columns(&t.attached.lights, &all.weights, &mut image.pixels);
        Ok(())
    })?;
    let one_ms = median_ms(opts.runs, || {
        crate::relight::columns::add_columns(&t.attached.lights, &one.weights, &mut image.pixels);
        Ok(())
    })?;
    let (_, terms) =
        crate::app::studies::dusk::dusk_terms(&t, crate::app::studies::demo::DEMO_WEIGHTING)?;
    let env_ms = median_ms(opts.runs, || Cpu(&t).relight_terms(&terms).map(|_| ()))?;
    let frame_ms = median_ms(opts.runs, || Cpu(&t).relight_lit(&terms, &all).map(|_| ()))?;
    Ok(ManyLights {
        lights: n * n,
        width: w,
        height: h,
        bake_seconds: [seconds, plain],
        ms: [all_ms, one_ms, env_ms, frame_ms],
        column_bytes: t.attached.lights.bytes(),
    })
}

/// The report as markdown.
pub fn markdown(r: &LightsReport, opts: &LightsBenchOptions) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Local lights\n\nEach kind of light alone on the dusk scene's geometry ({0}x{0}, its \
         own lights taken out), baked at the default light samples and relit with the \
         environment off, against the path tracer ({1} paths a pixel, next-event estimation and \
         BRDF sampling by MIS). The bake's cost is the shadow rays the light adds to the same \
         bake without it.\n\n| light | relative L2 | path tracer's noise | shadow rays a pixel \
         |\n|---|---:|---:|---:|",
        opts.side, opts.paths
    );
    for k in &r.kinds {
        let _ = writeln!(
            s,
            "| {} | {:.3}% | {:.2}% | {:.1} |",
            k.kind,
            100.0 * k.rel_l2,
            100.0 * k.noise,
            k.rays_per_pixel
        );
    }
    let _ = writeln!(
        s,
        "\nA moving point light 0.55 above the ground, halfway between two baked positions: the \
         blend of their columns against the light baked there (`moving_light.png`).\n\n| \
         spacing | relative L2 |\n|---:|---:|"
    );
    for p in &r.spacings {
        let _ = writeln!(s, "| {} | {:.3}% |", p.spacing, 100.0 * p.rel_l2);
    }
    let m = &r.many;
    let rate = |ms: f64| 1e3 / ms.max(1e-9);
    let _ = writeln!(
        s,
        "\n{} small quad lights over the dusk geometry at {}x{} (N = 32, the CLI's defaults, \
         {} light samples each): baked in {:.1} s against {:.1} s without them; the columns \
         take {:.1} MiB. CPU medians of {} runs:\n\n| relight | ms | per second |\n|---|---:|---:|\n\
         | every light added | {:.2} | {:.0} |\n| one light changed (its column alone) | {:.3} | \
         {:.0} |\n| the environment, K = 200 | {:.2} | {:.0} |\n| a frame: K = 200 and every \
         light | {:.2} | {:.0} |",
        m.lights,
        m.width,
        m.height,
        opts.grid_light_samples,
        m.bake_seconds[0],
        m.bake_seconds[1],
        m.column_bytes as f64 / 1048576.0,
        opts.runs,
        m.ms[0],
        rate(m.ms[0]),
        m.ms[1],
        rate(m.ms[1]),
        m.ms[2],
        rate(m.ms[2]),
        m.ms[3],
        rate(m.ms[3]),
    );
    s
}

/// The report's figures as CSV rows: `section,name,value`.
pub fn csv(r: &LightsReport) -> String {
    let mut s = String::from("section,name,value\n");
    for k in &r.kinds {
        let _ = writeln!(s, "kind_rel_l2,{},{}", k.kind, k.rel_l2);
        let _ = writeln!(s, "kind_noise,{},{}", k.kind, k.noise);
        let _ = writeln!(s, "kind_rays_per_pixel,{},{}", k.kind, k.rays_per_pixel);
    }
    for p in &r.spacings {
        let _ = writeln!(s, "moving_rel_l2,{},{}", p.spacing, p.rel_l2);
    }
    let m = &r.many;
    for (name, v) in [
        "all_lights_ms",
        "one_light_ms",
        "environment_k200_ms",
        "frame_ms",
    ]
    .iter()
    .zip(m.ms)
    {
        let _ = writeln!(s, "many_lights,{name},{v}");
    }
    s
}
