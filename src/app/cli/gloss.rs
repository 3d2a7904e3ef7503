//! `prt gloss`: glossy per-vertex bakes against the path tracer, by each way of drawing their
//! highlights, and their error against roughness.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use std::str::FromStr;

use crate::app::studies::gloss_bench::GlossMethod;
use crate::error::Result;

/// Arguments of `prt gloss`.
#[derive(Args, Debug)]
pub struct GlossArgs {
    /// Scene file with glossy materials (TOML).
    pub scene: PathBuf,
    /// Environment: an .exr/.hdr lat-long map, a bundled map by name (`prt env --list`), or
    /// sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output directory for gloss.md, gloss.csv, gloss_error.png, the bakes (`bakes/`, reused
    /// when the scene is unchanged) and the compared images (`images/`).
    #[arg(long)]
    pub out: PathBuf,
    /// The ways of drawing the glossy light to compare, comma-separated: `base` (the diffuse
    /// base alone) and `lobe` (the glossy vertices' visibility, the lobe drawn per pixel from
    /// the light: `prt bake --per-vertex`'s default).
    #[arg(long, value_delimiter = ',', default_value = "base,lobe", value_parser = GlossMethod::from_str)]
    pub methods: Vec<GlossMethod>,
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
    /// Samples a pixel of the drawings compared with it: 1, 4 (as the viewer draws) or 16 (a
    /// still's; a highlight or an edge smaller than a pixel then reaches the pixel's mean).
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
    /// SH orders, comma-separated, at which each bake with visibility (`lobe` in --methods) is
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
        methods: a.methods,
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
    crate::files::check_output_folder(&a.out)?;
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
