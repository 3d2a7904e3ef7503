//! `prt brdf` and `prt gloss`: the in-out factorisation of GGX lobes (its error against the number
//! of terms per roughness, as a table and a plot), and glossy per-vertex bakes against the path
//! tracer.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::error::{PrtError, Result};
use crate::output::plot::{self, PlotSpec, Series};
use crate::scene::brdf_factor::GgxFactors;

/// Arguments of `prt brdf`.
#[derive(Args, Debug)]
pub struct BrdfArgs {
    /// Output directory for brdf_factors.md and brdf_factors.png.
    #[arg(long)]
    pub out: PathBuf,
    /// GGX roughnesses (α = roughness²), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.05,0.1,0.2,0.3,0.5")]
    pub roughness: Vec<f32>,
    /// GGX terms kept per lobe (K_b is one more, for the Lambertian term).
    #[arg(long, default_value_t = 16)]
    pub terms: usize,
    /// Cells per side of the hemi-octahedral maps of view and light directions.
    #[arg(long, default_value_t = 32)]
    pub resolution: usize,
}

/// Relative errors the table gives the fewest terms for.
const TARGETS: [f64; 3] = [0.1, 0.05, 0.02];

pub(super) fn brdf_cmd(a: BrdfArgs) -> Result<()> {
    if !(4..=64).contains(&a.resolution) {
        return Err(PrtError::invalid(
            "--resolution",
            format!("{}; it goes from 4 to 64", a.resolution),
        ));
    }
    if !(1..=64).contains(&a.terms) {
        return Err(PrtError::invalid(
            "--terms",
            format!("{}; it goes from 1 to 64", a.terms),
        ));
    }
    if a.roughness.is_empty() || a.roughness.iter().any(|r| !(0.02..=1.0).contains(r)) {
        return Err(PrtError::invalid(
            "--roughness",
            format!("{:?}; each must be from 0.02 to 1", a.roughness),
        ));
    }
    crate::files::check_output_folder(&a.out)?;
    crate::files::create_folder(&a.out)?;
    let mut all = Vec::new();
    for &r in &a.roughness {
        let start = Instant::now();
        let f = GgxFactors::new(r * r, a.resolution, a.terms);
        eprintln!(
            "roughness {r}: {} terms in {:.1} s, {:.2}% left by 4",
            f.terms(),
            start.elapsed().as_secs_f64(),
            100.0 * f.error(4.min(f.terms()))
        );
        all.push((r, f));
    }
    let mut md = format!(
        "In-out factorisation of the cosine-weighted GGX lobe, `{0}×{0}` hemi-octahedral maps of \
         view and light directions, each light cell averaged over 4×4 directions, the error \
         weighted by solid angle. Relative L2 of the lobe with k GGX terms (a material's K_b is \
         k + 1, its Lambertian term exact).\n\n| k |",
        a.resolution
    );
    for (r, _) in &all {
        md += &format!(" roughness {r} |");
    }
    md += "\n|---:|";
    md += &"---:|".repeat(all.len());
    md += "\n";
    for k in 1..=a.terms {
        md += &format!("| {k} |");
        for (_, f) in &all {
            md += &format!(" {:.2}% |", 100.0 * f.error(k));
        }
        md += "\n";
    }
    md += "\nFewest GGX terms to reach an error (more than kept: `>`):\n\n| error |";
    for (r, _) in &all {
        md += &format!(" roughness {r} |");
    }
    md += "\n|---:|";
    md += &"---:|".repeat(all.len());
    md += "\n";
    for t in TARGETS {
        md += &format!("| {}% |", 100.0 * t);
        for (_, f) in &all {
            match (0..=f.terms()).find(|&k| f.error(k) <= t) {
                Some(k) => md += &format!(" {k} |"),
                None => md += &format!(" > {} |", f.terms()),
            }
        }
        md += "\n";
    }
    let table = a.out.join("brdf_factors.md");
    crate::files::write_bytes_atomically(&table, md.as_bytes())?;
    let series: Vec<Series> = all
        .iter()
        .enumerate()
        .map(|(i, (r, f))| Series {
            label: format!("roughness {r}"),
            points: (1..=f.terms())
                .map(|k| (k as f64, f.error(k).max(1e-6)))
                .collect(),
            color: plot::PALETTE[i % plot::PALETTE.len()],
            dashed: false,
        })
        .collect();
    let figure = a.out.join("brdf_factors.png");
    plot::write(
        &figure,
        &PlotSpec {
            title: "GGX lobe factorised into in-out terms".into(),
            x_label: "GGX terms k".into(),
            y_label: "relative L2 of the lobe".into(),
            log_x: false,
            log_y: true,
            width: 720,
            height: 440,
        },
        &series,
    )?;
    println!("wrote {} and {}", table.display(), figure.display());
    Ok(())
}

/// Arguments of `prt gloss`.
#[derive(Args, Debug)]
pub struct GlossArgs {
    /// Scene file with glossy materials (TOML).
    pub scene: PathBuf,
    /// Environment: an .exr/.hdr lat-long map, or sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output directory for gloss.md, gloss.csv, gloss_error.png, the bakes (`bakes/`, reused
    /// when the scene is unchanged) and the compared images (`images/`).
    #[arg(long)]
    pub out: PathBuf,
    /// Counts of in-out terms K_b to bake, comma-separated: 1 is the diffuse base, 0 the glossy
    /// vertices' visibility with the lobe drawn per pixel from the light (`prt bake
    /// --visibility`).
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8")]
    pub brdf_terms: Vec<u32>,
    /// Tessellations, as multiples of the scene's default edge length, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub edge_factors: Vec<f32>,
    /// A camera position X,Y,Z; give the flag once per camera. Default: the scene's camera
    /// turned 60°, 180° and 300° about its target. Every camera stays upright (see --up).
    #[arg(long = "eye", value_parser = super::volume::parse_vec3, allow_hyphen_values = true)]
    pub eyes: Vec<glam::Vec3>,
    /// The point the cameras look at, X,Y,Z (default: the scene's target).
    #[arg(long, value_parser = super::volume::parse_vec3, allow_hyphen_values = true)]
    pub target: Option<glam::Vec3>,
    /// The cameras' up direction X,Y,Z (default: the world's +Y; looking straight along it,
    /// -Z).
    #[arg(long, value_parser = super::parse_up, allow_hyphen_values = true)]
    pub up: Option<glam::Vec3>,
    /// Paths a pixel of the path tracer.
    #[arg(long, default_value_t = 1024)]
    pub paths: u32,
    /// Samples a pixel of the drawings compared with it.
    #[arg(long, default_value_t = 4)]
    pub samples: u32,
    /// Light terms K, comma-separated: each one's error against every term, and a frame's time.
    #[arg(long, value_delimiter = ',', default_value = "100,200")]
    pub terms: Vec<usize>,
    /// Side of the timed frames, pixels (one sample a pixel).
    #[arg(long, default_value_t = 512)]
    pub frame_side: u32,
    /// Where frames are timed beside the CPU: auto (a hardware GPU when one exists), cpu, or
    /// gpu (any adapter, a software one included).
    #[arg(long, value_enum, default_value_t = super::Device::Auto)]
    pub device: super::Device,
    /// SH orders, comma-separated, at which each bake with visibility (0 in --brdf-terms) is
    /// also drawn by SH glossy transfer (Sloan, Kautz & Snyder 2002), beside the lobe per pixel.
    #[arg(long, value_delimiter = ',')]
    pub sh_transfer: Vec<usize>,
    /// Roughnesses, comma-separated (for example 0.1,0.2,0.35,0.5,0.7): every glossy material
    /// takes each in turn, each run's files go into `roughness_R/`, and roughness.md,
    /// roughness.csv and roughness.png set each method's error against roughness.
    #[arg(long, value_delimiter = ',')]
    pub roughness: Vec<f32>,
}

/// Azimuths of `prt gloss`'s default cameras about the scene's target, degrees.
const DEFAULT_AZIMUTHS: [f32; 3] = [60.0, 180.0, 300.0];

pub(super) fn gloss_cmd(a: GlossArgs) -> Result<()> {
    crate::files::check_output_folder(&a.out)?;
    let scene = crate::scene::Scene::load(&a.scene)?;
    crate::files::guard_inputs(&scene.input_files);
    crate::app::studies::gloss_bench::glossy_materials(&scene)?;
    let mut cameras = match a.eyes.is_empty() {
        true => crate::app::studies::gloss_bench::turned_cameras(&scene, &DEFAULT_AZIMUTHS),
        false => a
            .eyes
            .iter()
            .map(|&eye| crate::scene::Camera {
                eye,
                ..scene.camera.clone()
            })
            .collect(),
    };
    for c in &mut cameras {
        let target = a.target.unwrap_or(c.target);
        *c = crate::draw::vertex::moved_camera(c, c.eye, target, a.up);
    }
    let opts = crate::app::studies::gloss_bench::GlossBenchOptions {
        brdf_terms: a.brdf_terms,
        edge_factors: a.edge_factors,
        cameras,
        paths: a.paths,
        samples: a.samples,
        light_terms: a.terms,
        frame_side: a.frame_side,
        runs: 5,
        bake: crate::bake::BakeSettings::default(),
        sh_orders: a.sh_transfer,
    };
    opts.validate()?;
    let env = super::load_env(&a.env)?;
    crate::files::check_folder_outputs(&a.out, &["gloss.md", "gloss.csv", "gloss_error.png"])?;
    for r in &a.roughness {
        crate::app::studies::gloss_sweep::with_roughness(&scene, *r)?;
    }
    let name = std::path::Path::new(&a.env)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(&a.env)
        .to_string();
    let gpu = super::open_device(a.device)?;
    if let Some(g) = &gpu {
        eprintln!("gpu: {}", g.adapter);
    }
    crate::files::create_folder(&a.out)?;
    let start = Instant::now();
    let bar = super::progress_bar(0);
    let progress = super::bake_progress(&bar, Instant::now());
    let mut log = |line: &str| bar.suspend(|| eprintln!("{line}"));
    let (text, files) = match a.roughness.is_empty() {
        true => {
            let report = crate::app::studies::gloss_bench::run(
                &a.out,
                &scene,
                (&name, &env),
                &opts,
                gpu.as_ref(),
                &mut log,
                &progress,
            )?;
            let text = crate::app::studies::gloss_bench::markdown(&report, &opts);
            (text, report.files)
        }
        false => {
            use crate::app::studies::gloss_sweep::{sweep, sweep_markdown};
            let report = sweep(
                &a.out,
                &scene,
                (&name, &env),
                (&opts, &a.roughness),
                gpu.as_ref(),
                &mut log,
                &progress,
            )?;
            (sweep_markdown(&report), report.files)
        }
    };
    bar.finish_and_clear();
    print!("{text}");
    println!("\nin {:.0} s; wrote", start.elapsed().as_secs_f64());
    for f in &files {
        println!("  {}", f.display());
    }
    Ok(())
}
