//! `prt bounces` and `prt lights`, the sweeps held against the path tracer. `prt bounces`: the
//! interreflections of a scene, bounce by bounce, against the independent path tracer. Bakes the scene with 0 to B bounces at the given sampling, relights each with every
//! term, path traces the reference at each bounce count, and writes a contact sheet (bakes over
//! references) and a markdown table of time, size and error.

use super::*;
use crate::bake::path_tracer::path_trace;
use crate::output::metrics::compare;
use crate::output::sheet::{Cell, write_sheet};

/// Arguments of `prt bounces`.
#[derive(Args, Debug)]
pub struct BouncesArgs {
    /// Scene file: TOML, or glTF (.gltf, .glb).
    pub scene: PathBuf,
    /// The view: a glTF camera, the image size.
    #[command(flatten)]
    pub framing: FramingArgs,
    /// Environment: an .exr/.hdr lat-long map, a bundled map by name (`prt env --list`), or
    /// sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output directory for bounces.md, bounces_sheet.png and the images.
    #[arg(long)]
    pub out: PathBuf,
    /// Most bounces: bakes are made with 0, 1, ... up to this many.
    #[arg(long, default_value_t = 2)]
    pub max_bounces: u32,
    /// Paths per pixel of the path-traced references.
    #[arg(long, default_value_t = 4096)]
    pub samples: u32,
    /// Sampling of the bakes; --bounces is ignored (every count up to --max-bounces is baked).
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// How the environment is turned.
    #[command(flatten)]
    pub turn: TurnArgs,
}

/// One bounce count's figures.
struct Row {
    bounces: u32,
    bake_seconds: f64,
    file_bytes: u64,
    nonzero_fraction: f64,
    cache_points: u64,
    rel_l2: f64,
    rel_h1: f64,
    reference_seconds: f64,
    reference_noise: f64,
    /// The brightest covered pixel over the reference's brightest (largest channel).
    peak_ratio: f64,
}

/// The largest channel value over the covered pixels.
fn peak(img: &crate::output::film::Image, coverage: &[f32]) -> f64 {
    img.pixels
        .iter()
        .zip(coverage)
        .filter(|(_, c)| **c > 0.0)
        .map(|(p, _)| p.iter().fold(0.0f32, |a, &b| a.max(b)) as f64)
        .fold(0.0, f64::max)
}

pub(super) fn bounces_cmd(a: BouncesArgs) -> Result<()> {
    if a.max_bounces > 16 {
        return Err(PrtError::invalid(
            "--max-bounces",
            format!("{}; it goes up to 16", a.max_bounces),
        ));
    }
    check_light_flags(a.turn.yaw, a.turn.pitch, None)?;
    let scene = a.framing.load(&a.scene)?;
    let env = load_env(&a.env)?;
    crate::files::check_output_folder(&a.out)?;
    crate::files::check_folder_outputs(&a.out, &["bounces.md", "bounces_sheet.png"])?;
    let defaults = BakeSettings::default();
    let base = settings_from(&a.sampling, defaults.sh_order, defaults.threshold, false);
    BakeSettings {
        bounces: a.max_bounces,
        ..base.clone()
    }
    .validate()?;
    let cube = env.to_cube(base.cube_n, a.turn.rotation())?;
    let dir = &a.out;
    crate::files::create_folder(dir)?;
    let full = |t: &Transport| -> Result<crate::output::film::Image> {
        let ctx = LightContext::new(t)?;
        let light = ctx.prepare(&env, a.turn.rotation())?;
        Ok(relight(t, &ctx, &light, &RelightRequest::Full)?.0)
    };
    let mut rows = Vec::new();
    let mut shots = Vec::new();
    let mut coverage = None;
    for bounces in 0..=a.max_bounces {
        let settings = BakeSettings {
            bounces,
            ..base.clone()
        };
        eprintln!("baking with {bounces} bounces");
        let start = Instant::now();
        let t = bake_with_progress(
            &scene,
            &settings,
            (scene.camera.width * scene.camera.height) as usize,
        )?;
        let bake_seconds = start.elapsed().as_secs_f64();
        let path = dir.join(format!("bounces_{bounces}.prt"));
        t.save(&path)?;
        let file_bytes = crate::files::file_len(&path)?;
        let img = full(&t)?;
        eprintln!("path tracing the reference with {bounces} bounces");
        let start = Instant::now();
        let rows_bar = bar(scene.camera.height as u64, "rows");
        let traced = path_trace(&scene, &cube, &settings, a.samples, &|done, _| {
            rows_bar.set_position(done as u64)
        })?;
        rows_bar.finish_and_clear();
        let reference_seconds = start.elapsed().as_secs_f64();
        let mask: Vec<bool> = t.coverage.iter().map(|&c| c > 0.0).collect();
        let e = compare(&img, &traced.image, Some(&t.coverage))?;
        let tone = ToneMap::auto(&traced.image, Some(&t.coverage));
        img.save(&dir.join(format!("bake_{bounces}.exr")), tone)?;
        traced
            .image
            .save(&dir.join(format!("reference_{bounces}.exr")), tone)?;
        let row = Row {
            bounces,
            bake_seconds,
            file_bytes,
            nonzero_fraction: t.meta.stats.nonzeros as f64
                / t.meta.stats.dense_entries.max(1) as f64,
            cache_points: t.meta.cache_points,
            rel_l2: e.rel_l2,
            rel_h1: e.rel_h1,
            reference_seconds,
            reference_noise: traced.relative_noise(Some(&mask)),
            peak_ratio: peak(&img, &t.coverage) / peak(&traced.image, &t.coverage).max(1e-30),
        };
        println!(
            "{bounces} bounces: bake {:.1} s, {:.1} MiB; against the path tracer L2 {:.2}%, H1 \
             {:.2}%, brightest pixel {:.2}x the reference's (reference noise {:.2}%, {:.1} s)",
            row.bake_seconds,
            row.file_bytes as f64 / 1048576.0,
            100.0 * row.rel_l2,
            100.0 * row.rel_h1,
            row.peak_ratio,
            100.0 * row.reference_noise,
            row.reference_seconds
        );
        coverage.get_or_insert(t.coverage.clone());
        shots.push((img, traced.image, row.rel_l2, row.reference_noise));
        rows.push(row);
    }
    // One tone map for the whole sheet (the brightest reference's), so the rows compare.
    let tone = shots
        .last()
        .map(|(_, r, ..)| ToneMap::auto(r, coverage.as_deref()))
        .expect("at least one bounce count");
    let name = |b: u32| match b {
        0 => "direct".to_string(),
        1 => "1 bounce".to_string(),
        b => format!("{b} bounces"),
    };
    let mut cells: Vec<Cell> = shots
        .iter()
        .enumerate()
        .map(|(b, (img, _, err, _))| Cell {
            image: img,
            tone,
            caption: [
                format!("{}: bake", name(b as u32)),
                format!("L2 {:.1}% vs ref.", 100.0 * err),
            ],
        })
        .collect();
    cells.extend(shots.iter().enumerate().map(|(b, (_, r, _, noise))| Cell {
        image: r,
        tone,
        caption: [
            format!("{}: ref.", name(b as u32)),
            format!("noise {:.2}%", 100.0 * noise),
        ],
    }));
    let sheet = dir.join("bounces_sheet.png");
    write_sheet(
        &sheet,
        shots.len(),
        &cells,
        &format!("Bakes, every term / path traced, {} spp", a.samples),
    )?;
    let table = markdown(&rows, &a, &base);
    let table_path = dir.join("bounces.md");
    crate::files::write_bytes_atomically(&table_path, table.as_bytes())?;
    println!("wrote {} and {}", sheet.display(), table_path.display());
    Ok(())
}

fn markdown(rows: &[Row], a: &BouncesArgs, base: &BakeSettings) -> String {
    let mut s = format!(
        "Scene `{}` under `{}`, cube 6x{}x{}, {} spp ({} at edge pixels), {} paths per sample, \
         cache spacing {} px \
         ({} visibility). Each bake is relit with every term and compared with the path tracer \
         at the same bounce count ({} paths per pixel) over the covered pixels.\n\n\
         | bounces | bake (s) | file (MiB) | nonzeros | cache points | L2 vs path traced | H1 vs \
         path traced | brightest pixel / reference's | reference noise | reference (s) |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        a.scene.display(),
        a.env,
        base.cube_n,
        base.cube_n,
        base.spp,
        base.stored_edge_spp().max(base.spp),
        base.paths,
        base.cache_spacing,
        base.bounce_visibility,
        a.samples
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {:.1} | {:.1} | {:.2}% | {} | {:.2}% | {:.2}% | {:.2} | {:.2}% | {:.1} |\n",
            r.bounces,
            r.bake_seconds,
            r.file_bytes as f64 / 1048576.0,
            100.0 * r.nonzero_fraction,
            r.cache_points,
            100.0 * r.rel_l2,
            100.0 * r.rel_h1,
            r.peak_ratio,
            100.0 * r.reference_noise,
            r.reference_seconds
        ));
    }
    s
}

/// Arguments of `prt lights`.
#[derive(Args, Debug)]
pub struct LightsArgs {
    /// Output directory for lights.md, lights.csv, moving_light.png and the images.
    #[arg(long)]
    pub out: PathBuf,
    /// Image side of the comparisons with the path tracer.
    #[arg(long, default_value_t = 96)]
    pub side: u32,
    /// Paths per pixel of the path tracer.
    #[arg(long, default_value_t = 2048)]
    pub samples: u32,
    /// Quad lights along each side of the many-lights grid (their square is the count).
    #[arg(long, default_value_t = 16)]
    pub grid: usize,
    /// Image side of the many-lights scene.
    #[arg(long, default_value_t = 256)]
    pub many_side: u32,
}

pub(super) fn lights_cmd(a: LightsArgs) -> Result<()> {
    crate::files::check_output_folder(&a.out)?;
    crate::flags::within("--side", a.side, 8..=1024, " pixels")?;
    crate::flags::within("--samples", a.samples, 1..=1 << 20, "")?;
    crate::flags::within("--grid", a.grid, 1..=64, "")?;
    crate::flags::within("--many-side", a.many_side, 8..=2048, " pixels")?;
    let opts = crate::app::studies::lights_bench::LightsBenchOptions {
        side: a.side,
        paths: a.samples,
        grid: a.grid,
        many_side: a.many_side,
        ..Default::default()
    };
    let start = Instant::now();
    let report =
        crate::app::studies::lights_bench::run(&a.out, &opts, &mut |line| eprintln!("{line}"))?;
    print!(
        "{}",
        crate::app::studies::lights_bench::markdown(&report, &opts)
    );
    println!("\nin {:.0} s; wrote", start.elapsed().as_secs_f64());
    for f in &report.files {
        println!("  {}", f.display());
    }
    Ok(())
}
