//! The `prt` command line: argument parsing, progress bars and printing. Everything else is the
//! library; this module is the only place that writes to the terminal.

use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use crate::background::Background;
use crate::bake::{BakeProgress, BakeSettings, bake, worst_case_bytes};
use crate::envmap::{EnvMap, EnvRotation};
use crate::error::{PrtError, Result};
use crate::film::ToneMap;
use crate::light::{WaveletLight, Weighting};
use crate::relight::{LightContext, Method, RelightRequest, relight};
use crate::scene::Scene;
use crate::transport::Transport;

/// All-frequency relighting: bake a view, relight it under any HDR environment with Haar wavelets
/// or spherical harmonics.
#[derive(Parser, Debug)]
#[command(name = "prt", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Bake the demo scene and relight it under every bundled environment (the main job).
    Demo {
        /// Output directory (the bake is cached there).
        #[arg(long, default_value = "prt-demo")]
        out: PathBuf,
    },
    /// Bake a scene's per-pixel transport into a file.
    Bake(BakeArgs),
    /// Join the shards of a sharded bake into one transport file.
    Merge {
        /// Shard files, in any order.
        #[arg(required = true, num_args = 1..)]
        shards: Vec<PathBuf>,
        /// Output transport file (.prt).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Print a transport or volume file's metadata and statistics.
    Info {
        /// Transport (.prt) or volume (.prtv) file.
        file: PathBuf,
    },
    /// Relight a baked view under an environment.
    Relight(RelightArgs),
    /// Render the brute-force reference (no matrix) under an environment's cube map.
    Reference(ReferenceArgs),
    /// Describe an environment map: size, power, SH coefficients, Haar energy compaction.
    Env(EnvArgs),
    /// Sweep error against kept terms for SH and wavelets; write a CSV, plots and a summary.
    Bench(BenchArgs),
    /// Open the interactive viewer (SH versus wavelet, kept terms, environments, rotation), or
    /// with --screenshot render the image it would show to a PNG and exit.
    View(ViewArgs),
    /// Participating media: bake SH self-transfer over a grid, relight it by ray marching.
    #[command(subcommand)]
    Volume(VolumeCommand),
    /// Compare two linear EXR images: relative L2, RMSE, PSNR, gradient error, 1 - SSIM.
    Compare {
        /// Image to judge (.exr).
        image: PathBuf,
        /// Reference image (.exr).
        reference: PathBuf,
        /// Only count the pixels a transport file's view covers.
        #[arg(long)]
        mask: Option<PathBuf>,
    },
}

#[derive(Subcommand, Debug)]
pub enum VolumeCommand {
    /// Bake the SH self-transfer of a scene's [medium] into a volume file (.prtv).
    Bake(VolumeBakeArgs),
    /// Relight a volume file under an environment by ray marching, from any camera.
    Render(VolumeRenderArgs),
}

#[derive(Args, Debug)]
pub struct VolumeBakeArgs {
    /// Scene file (TOML) with a [medium].
    pub scene: PathBuf,
    /// Output volume file (.prtv).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Voxels along the longest side of the medium's box (default: the scene's resolution,
    /// 64 unless it says otherwise; a .npy grid keeps its own unless this is given).
    #[arg(long)]
    pub grid: Option<usize>,
    /// SH order n of the transfer (n² coefficients per voxel, 1 to 8).
    #[arg(long, default_value_t = 3)]
    pub sh_order: usize,
    /// Directions D of the projection (a Fibonacci sphere).
    #[arg(long, default_value_t = 512)]
    pub directions: usize,
}

#[derive(Args, Debug)]
pub struct VolumeRenderArgs {
    /// Volume file (.prtv).
    pub file: PathBuf,
    /// Environment: an .exr/.hdr lat-long map, or sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output image (.exr linear, .png tone-mapped).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Camera position X,Y,Z (default: the scene's camera).
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true)]
    pub eye: Option<glam::Vec3>,
    /// Point the camera looks at, X,Y,Z (default: the scene's target).
    #[arg(long, value_parser = parse_vec3, allow_negative_numbers = true)]
    pub target: Option<glam::Vec3>,
    /// Image width (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
    /// full, inscatter, transmittance or dc (the self-shadow map).
    #[arg(long, default_value = "full")]
    pub view: String,
    /// SH order to relight with (default: the baked order).
    #[arg(long)]
    pub sh_order: Option<usize>,
    /// Environment yaw, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub yaw: f64,
    /// Environment pitch, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pitch: f64,
    /// Cube face size the environment is resampled to for the light.
    #[arg(long, default_value_t = 32)]
    pub cube: usize,
    /// cpu or gpu.
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// Exposure in stops for a .png (default automatic).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
}

fn parse_vec3(s: &str) -> std::result::Result<glam::Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("`{s}`: expected X,Y,Z"))?;
    match v[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => {
            Ok(glam::Vec3::new(x, y, z))
        }
        _ => Err(format!("`{s}`: expected three finite numbers X,Y,Z")),
    }
}

/// Options shared by the bake and the reference: how the transport is sampled.
#[derive(Args, Debug, Clone)]
pub struct SamplingArgs {
    /// Cube face size N of the texel lights (power of two).
    #[arg(long, default_value_t = 32)]
    pub cube: usize,
    /// Sub-pixel samples per pixel.
    #[arg(long, default_value_t = 1)]
    pub spp: u32,
    /// Shadow-ray directions per texel (rounded up to a square).
    #[arg(long, default_value_t = 1)]
    pub texel_samples: u32,
    /// Ignore visibility (no shadows).
    #[arg(long)]
    pub unshadowed: bool,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Interreflection bounces added to the direct light (path traced, binned by the texel each
    /// path leaves through).
    #[arg(long, default_value_t = 0)]
    pub bounces: u32,
    /// Paths per camera sub-sample for --bounces.
    #[arg(long, default_value_t = 64)]
    pub paths: u32,
}

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Output transport file (.prt).
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// SH order of the SH transport (n² coefficients, 1 to 10).
    #[arg(long, default_value_t = 6)]
    pub sh_order: usize,
    /// L2 error allowed per transport row when dropping small Haar coefficients, relative to an
    /// unshadowed row's norm.
    #[arg(long, default_value_t = 0.01, conflicts_with = "lossless")]
    pub threshold: f32,
    /// Keep every coefficient in 32-bit floats.
    #[arg(long)]
    pub lossless: bool,
    /// How the threshold weighs coefficients: l2 (the row's L2 error), area (support solid
    /// angle), sun (the error at any one texel) or absolute (drop |v| < threshold · norm).
    #[arg(long, default_value = "l2", conflicts_with = "lossless")]
    pub budget: crate::budget::Budget,
    /// Stored values: q8 (8-bit integers against per-column scales) or q16.
    #[arg(long, default_value = "q8", conflicts_with = "lossless")]
    pub quantization: crate::quant::Quantization,
    /// Bake only shard I of COUNT (bands of tile rows), e.g. 0/4; join them with `prt merge`.
    #[arg(long, value_name = "I/COUNT")]
    pub shard: Option<String>,
}

#[derive(Args, Debug)]
pub struct RelightArgs {
    /// Transport file.
    pub file: PathBuf,
    /// Environment: an .exr/.hdr lat-long map, or sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output image (.exr linear, .png tone-mapped).
    #[arg(short, long)]
    pub output: PathBuf,
    /// wavelet, sh or full.
    #[arg(long, default_value = "wavelet")]
    pub method: String,
    /// Kept wavelet terms K.
    #[arg(long, default_value_t = 200)]
    pub terms: usize,
    /// Wavelet term selection: none, area or transport.
    #[arg(long, default_value = "transport")]
    pub weighting: String,
    /// SH order (at most the baked order; default: the baked order).
    #[arg(long)]
    pub sh_order: Option<usize>,
    /// Turn the environment about +Y, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub yaw: f64,
    /// Turn the environment about +X after the yaw, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pitch: f64,
    /// cpu or gpu (wgpu; a software adapter such as Mesa's lavapipe works too).
    #[arg(long, default_value = "cpu")]
    pub device: String,
    /// PNG exposure in stops (default: automatic).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
    /// What pixels that see no geometry show: env (the environment behind the scene, turned
    /// with it) or black.
    #[arg(long, default_value = "env")]
    pub background: String,
}

#[derive(Args, Debug)]
pub struct ReferenceArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Environment: an .exr/.hdr lat-long map, or sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output image (.exr linear, .png tone-mapped).
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// Turn the environment about +Y, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub yaw: f64,
    /// Turn the environment about +X after the yaw, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pitch: f64,
    /// What pixels that see no geometry show: env (the environment behind the scene, turned
    /// with it) or black.
    #[arg(long, default_value = "env")]
    pub background: String,
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Transport file.
    pub file: PathBuf,
    /// Environments (.exr/.hdr files or sun:ELEV,AZIM[,RADIUS]), one or more.
    #[arg(long, required = true, num_args = 1..)]
    pub env: Vec<String>,
    /// Output directory for bench.csv, summary.md and the plots.
    #[arg(long)]
    pub out: PathBuf,
    /// Wavelet term counts, comma-separated (default: 1, 2, 5, 10, ... up to 6·N²).
    #[arg(long, value_delimiter = ',')]
    pub terms: Option<Vec<usize>>,
    /// SH orders, comma-separated (default: 1 to the baked order).
    #[arg(long, value_delimiter = ',')]
    pub sh_orders: Option<Vec<usize>>,
    /// SH orders through the light, comma-separated, up to 128: the light projected to n² terms
    /// and relit with the full transport (default: 1, 2, 3, 4, 6, ... 100; `none` for none).
    #[arg(long, value_delimiter = ',')]
    pub sh_light_orders: Option<Vec<String>>,
    /// Weightings, comma-separated (default: none,area,transport).
    #[arg(long, value_delimiter = ',')]
    pub weightings: Option<Vec<String>>,
    /// auto (the GPU when an adapter exists), cpu, or gpu: times the GPU kernels beside the CPU.
    #[arg(long, default_value = "auto")]
    pub device: String,
    /// Also render the brute-force reference of the scene and report every point against it.
    #[arg(long)]
    pub reference: bool,
    /// Thresholds for the compression curve, comma-separated: the scene is baked at each and
    /// the error sparsification adds is measured.
    #[arg(long, value_delimiter = ',')]
    pub compression: Option<Vec<f32>>,
    /// Scene file for --reference and --compression (default: the one the file was baked from).
    #[arg(long)]
    pub scene: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Transport file (.prt), or a volume file (.prtv) for the volume path.
    pub file: PathBuf,
    /// Extra environments (.exr/.hdr or sun:ELEV,AZIM), besides the bundled ones.
    #[arg(long, num_args = 1..)]
    pub env: Vec<String>,
    /// Render one frame to this PNG without opening a window, then exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// wavelet, sh or full (with --screenshot).
    #[arg(long)]
    pub method: Option<String>,
    /// Kept wavelet terms K (with --screenshot).
    #[arg(long)]
    pub terms: Option<usize>,
    /// none, area or transport (with --screenshot).
    #[arg(long)]
    pub weighting: Option<String>,
    /// SH order (with --screenshot).
    #[arg(long)]
    pub sh_order: Option<usize>,
    /// Environment yaw, degrees (with --screenshot).
    #[arg(long, allow_negative_numbers = true)]
    pub yaw: Option<f64>,
    /// Environment pitch, degrees (with --screenshot).
    #[arg(long, allow_negative_numbers = true)]
    pub pitch: Option<f64>,
    /// Exposure in stops (with --screenshot; default automatic).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
    /// SH and wavelet side by side (with --screenshot).
    #[arg(long)]
    pub compare: bool,
    /// SH and wavelet as one image split at this fraction of the width, SH on the left
    /// (with --screenshot; implies --compare).
    #[arg(long)]
    pub split: Option<f32>,
    /// Display curve after the exposure: clip, reinhard or aces (with --screenshot).
    #[arg(long)]
    pub tone: Option<String>,
    /// Add the error heat map against full beside each image (with --screenshot).
    #[arg(long)]
    pub error_map: bool,
}

#[derive(Args, Debug)]
pub struct EnvArgs {
    /// Environment: an .exr/.hdr lat-long map, or sun:ELEV,AZIM[,RADIUS].
    pub env: String,
    /// Cube face size for the Haar statistics.
    #[arg(long, default_value_t = 32)]
    pub cube: usize,
    /// SH order of the printed coefficients.
    #[arg(long, default_value_t = 3)]
    pub sh: usize,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs the command line; returns the process exit code.
pub fn main() -> i32 {
    let cli = Cli::parse();
    match run(cli.command) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            1
        }
    }
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Demo { out } => demo(out),
        Command::Bake(a) => bake_cmd(a),
        Command::Info { file } => info(file),
        Command::Merge { shards, output } => merge_cmd(shards, output),
        Command::Relight(a) => relight_cmd(a),
        Command::Reference(a) => reference_cmd(a),
        Command::Env(a) => env_cmd(a),
        Command::Bench(a) => bench_cmd(a),
        Command::View(a) => view_cmd(a),
        Command::Volume(VolumeCommand::Bake(a)) => volume_bake_cmd(a),
        Command::Volume(VolumeCommand::Render(a)) => volume_render_cmd(a),
        Command::Compare {
            image,
            reference,
            mask,
        } => compare_cmd(image, reference, mask),
    }
}

fn load_env(spec: &str) -> Result<EnvMap> {
    let env = EnvMap::from_spec(spec)?;
    if env.negatives_clamped > 0 {
        // Lossy HDR encoders leave slightly negative samples; radiance cannot be negative.
        eprintln!(
            "note: {}: {} slightly negative samples (the lowest {:.2e}) read as 0",
            env.source, env.negatives_clamped, env.lowest_negative
        );
    }
    Ok(env)
}

/// The files among environment specs (not the procedural `sun:` ones), for the output checks.
fn env_files(specs: &[String]) -> Vec<PathBuf> {
    specs
        .iter()
        .filter(|s| !s.starts_with("sun:"))
        .map(PathBuf::from)
        .collect()
}

/// Image outputs: `.exr` (linear) or `.png` (tone-mapped), none of `inputs`.
fn check_image_output(output: &std::path::Path, inputs: &[PathBuf]) -> Result<()> {
    let inputs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(
        output,
        &["exr", "png"],
        "an image (.exr linear, .png tone-mapped)",
        &inputs,
    )
}

/// The flags every relighting command shares, checked before any work.
fn check_light_flags(yaw: f64, pitch: f64, exposure: Option<f32>) -> Result<()> {
    crate::flags::angle("yaw", yaw)?;
    crate::flags::angle("pitch", pitch)?;
    if let Some(e) = exposure {
        crate::flags::exposure(e)?;
    }
    Ok(())
}

/// A progress bar over `total` `unit`s with the elapsed time, the rate to three significant
/// digits, a message and the time left.
fn bar(total: u64, unit: &str) -> ProgressBar {
    let bar = ProgressBar::new(total);
    let template = format!(
        "{{elapsed_precise}} [{{bar:30}}] {{pos}}/{{len}} {unit}  {{rate}}  {{msg}}  ETA {{eta}}"
    );
    bar.set_style(
        ProgressStyle::with_template(&template)
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .with_key(
                "rate",
                |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                    let _ = write!(w, "{}/s", three_significant(s.per_sec()));
                },
            )
            .progress_chars("=> "),
    );
    bar
}

/// `x` to three significant digits with a k, M or G suffix: 16,694.7 is "16.7k".
pub fn three_significant(x: f64) -> String {
    if !(x.is_finite() && x > 0.0) {
        return "0".into();
    }
    let (v, suffix) = match x {
        x if x >= 1e9 => (x / 1e9, "G"),
        x if x >= 1e6 => (x / 1e6, "M"),
        x if x >= 1e3 => (x / 1e3, "k"),
        x => (x, ""),
    };
    let decimals = if v >= 99.95 {
        0
    } else if v >= 9.995 {
        1
    } else {
        2
    };
    format!("{v:.decimals$}{suffix}")
}

fn progress_bar(total: usize) -> ProgressBar {
    bar(total as u64, "px")
}

/// The bake's own progress as a bar: pixels, shadow rays per second, the medium's first stage.
fn bake_progress(bar: &ProgressBar, start: Instant) -> impl Fn(BakeProgress) + Sync + '_ {
    move |p: BakeProgress| {
        if p.medium_texels[1] > 0 {
            bar.set_message(format!(
                "medium rows: {}/{} texel lights",
                p.medium_texels[0], p.medium_texels[1]
            ));
            return;
        }
        bar.set_length(p.pixels_total as u64);
        bar.set_position(p.pixels_done as u64);
        let secs = start.elapsed().as_secs_f64().max(1e-3);
        bar.set_message(format!(
            "{} shadow rays/s",
            three_significant(p.shadow_rays as f64 / secs)
        ));
    }
}

fn bake_with_progress(scene: &Scene, settings: &BakeSettings) -> Result<Transport> {
    let (w, h) = (scene.camera.width as usize, scene.camera.height as usize);
    let bar = progress_bar(w * h);
    let t = bake(scene, settings, &bake_progress(&bar, Instant::now()))?;
    bar.finish_and_clear();
    Ok(t)
}

fn settings_from(
    s: &SamplingArgs,
    sh_order: usize,
    threshold: f32,
    lossless: bool,
) -> BakeSettings {
    BakeSettings {
        cube_n: s.cube,
        sh_order,
        spp: s.spp,
        texel_samples: s.texel_samples,
        threshold,
        lossless,
        unshadowed: s.unshadowed,
        seed: s.seed,
        shard: None,
        bounces: s.bounces,
        paths: s.paths,
        ..BakeSettings::default()
    }
}

fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Parses `I/COUNT`.
fn parse_shard(s: &str) -> Result<[u32; 2]> {
    let bad = || PrtError::invalid("shard", format!("`{s}`; expected I/COUNT, e.g. 0/4"));
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    Ok([
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    ])
}

fn bake_cmd(a: BakeArgs) -> Result<()> {
    let mut settings = settings_from(&a.sampling, a.sh_order, a.threshold, a.lossless);
    settings.budget = a.budget;
    settings.quantization = a.quantization;
    settings.shard = a.shard.as_deref().map(parse_shard).transpose()?;
    settings.validate()?;
    crate::files::check_output(&a.output, &["prt"], "a transport file", &[])?;
    let scene = Scene::load(&a.scene)?;
    let inputs: Vec<&std::path::Path> = scene.input_files.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(&a.output, &["prt"], "a transport file", &inputs)?;
    // A run killed while writing left its temporary file; this one takes its place.
    crate::files::remove_stale_partials(&a.output);
    // Resuming: a finished output of this very bake (or shard) is kept, not redone.
    if crate::bake::load_if_baked_with(&a.output, &scene, &settings).is_some() {
        eprintln!(
            "{} already holds this bake (same scene and settings): kept",
            a.output.display()
        );
        return Ok(());
    }
    let (w, h) = (scene.camera.width as usize, scene.camera.height as usize);
    let worst = worst_case_bytes(w, h, &settings);
    let plural =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    eprintln!(
        "baking {} ({}, {}{}) at {w}x{h}, N = {}, SH order {}, {} spp, {} samples/texel",
        a.scene.display(),
        plural(scene.triangle_count(), "triangle", "triangles"),
        plural(scene.spheres.len(), "sphere", "spheres"),
        if scene.medium.is_some() {
            ", a medium"
        } else {
            ""
        },
        settings.cube_n,
        settings.sh_order,
        settings.spp,
        settings.texel_samples
    );
    eprintln!(
        "memory: at most {:.1} MiB if every coefficient were kept{}",
        worst as f64 / 1048576.0,
        if settings.lossless {
            " (lossless keeps them all)"
        } else {
            ""
        }
    );
    if let Some(avail) = available_memory_bytes() {
        // Lossless bakes keep everything; thresholded ones typically keep a few percent.
        let expected = if settings.lossless { worst } else { worst / 5 };
        if expected > avail {
            return Err(PrtError::invalid(
                "bake",
                format!(
                    "it needs about {:.1} GiB but {:.1} GiB are available: lower the resolution, --cube or raise --threshold",
                    expected as f64 / (1u64 << 30) as f64,
                    avail as f64 / (1u64 << 30) as f64
                ),
            ));
        }
    }
    let start = Instant::now();
    let t = bake_with_progress(&scene, &settings)?;
    let seconds = start.elapsed().as_secs_f64();
    t.save(&a.output)?;
    print_info(&a.output, &t.meta);
    println!(
        "bake time     {seconds:.1} s ({:.2} M shadow rays/s)",
        t.meta.stats.shadow_rays as f64 / seconds.max(1e-9) / 1e6
    );
    Ok(())
}

fn merge_cmd(shards: Vec<PathBuf>, output: PathBuf) -> Result<()> {
    let inputs: Vec<&std::path::Path> = shards.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(&output, &["prt"], "a transport file", &inputs)?;
    let total: u64 = shards
        .iter()
        .map(|p| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0))
        .sum();
    let progress = bar(total, "bytes read");
    let mut loaded = Vec::with_capacity(shards.len());
    let mut before = 0;
    for p in &shards {
        progress.set_message(p.display().to_string());
        loaded.push(Transport::load_with_progress(p, &|read, _| {
            progress.set_position(before + read)
        })?);
        before += std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    }
    progress.set_message(format!("merging and writing {}", output.display()));
    let names: Vec<String> = shards.iter().map(|p| p.display().to_string()).collect();
    let t = Transport::merge_named(&loaded, &names)?;
    t.save(&output)?;
    progress.finish_and_clear();
    print_info(&output, &t.meta);
    Ok(())
}

fn print_info(path: &std::path::Path, m: &crate::transport::TransportMeta) {
    let s = &m.stats;
    let bytes = std::fs::metadata(path).map(|x| x.len()).unwrap_or(0);
    let dense_bytes = s.dense_entries as f64 * 4.0;
    println!("file          {}", path.display());
    println!("scene         {} (hash {})", m.scene_path, m.scene_hash);
    println!(
        "image         {} x {} ({} tiles of {}²)",
        m.width,
        m.height,
        {
            let (tx, ty) = crate::transport::tile_grid(m.width as usize, m.height as usize);
            tx * ty
        },
        m.tile
    );
    println!(
        "cube          N = {} ({} coefficients per row)",
        m.cube_n,
        6 * m.cube_n as usize * m.cube_n as usize
    );
    println!(
        "SH order      {} ({} coefficients per row)",
        m.sh_order,
        (m.sh_order as usize).pow(2)
    );
    println!(
        "sampling      {} spp, {} samples/texel, seed {}{}",
        m.spp,
        m.texel_samples,
        m.seed,
        if m.unshadowed { ", unshadowed" } else { "" }
    );
    println!(
        "sparsify      threshold {} ({} budget, {} values)",
        m.threshold, m.budget, m.quantization
    );
    println!("rows          {}", s.rows);
    println!(
        "nonzeros      {} ({:.2}% of dense)",
        s.nonzeros,
        100.0 * s.nonzeros as f64 / s.dense_entries.max(1) as f64
    );
    println!(
        "size          {:.2} MiB file, {:.2}% of the dense f32 matrix, {:.1} bytes/pixel",
        bytes as f64 / 1048576.0,
        100.0 * bytes as f64 / dense_bytes.max(1.0),
        bytes as f64 / (m.width as usize * m.height as usize).max(1) as f64
    );
    println!(
        "dropped       {:.3}% of transport energy (relative L2 {:.3}%)",
        100.0 * s.dropped_energy_fraction,
        100.0 * s.dropped_energy_fraction.sqrt()
    );
    println!("shadow rays   {}", s.shadow_rays);
    if let Some([i, n]) = m.shard {
        println!("shard         {i}/{n} (join all {n} with `prt merge`)");
    }
}

fn info(file: PathBuf) -> Result<()> {
    if crate::volume::is_volume_file(&file) {
        let v = crate::volume::VolumeTransfer::load(&file)?;
        let m = &v.meta;
        let [nx, ny, nz] = m.dims;
        println!("file          {} (volume transfer)", file.display());
        println!(
            "grid          {nx} x {ny} x {nz} voxels over {:?} to {:?}",
            m.min, m.max
        );
        println!(
            "medium        extinction {}, albedo {:?}, g {}",
            m.extinction, m.albedo, m.g
        );
        println!(
            "transfer      SH order {} ({} coefficients per voxel), {} directions",
            m.sh_order,
            v.sh_count(),
            m.directions
        );
        println!(
            "default view  eye {:?}, target {:?}, {} x {}",
            m.camera.eye, m.camera.target, m.width, m.height
        );
        return Ok(());
    }
    // The header holds everything printed; the small tables are read and checked, the entries
    // and values are not.
    let meta = crate::transport::read_summary(&file)?;
    print_info(&file, &meta);
    Ok(())
}

fn relight_cmd(a: RelightArgs) -> Result<()> {
    let method: Method = a.method.parse()?;
    let weighting: Weighting = a.weighting.parse()?;
    let background: Background = a.background.parse()?;
    check_light_flags(a.yaw, a.pitch, a.exposure)?;
    let mut inputs = env_files(std::slice::from_ref(&a.env));
    inputs.push(a.file.clone());
    check_image_output(&a.output, &inputs)?;
    let gpu = match a.device.as_str() {
        "cpu" => None,
        "gpu" => Some(crate::gpu::Gpu::new()?),
        other => {
            return Err(PrtError::invalid(
                "device",
                format!("`{other}`; expected cpu or gpu"),
            ));
        }
    };
    let t = Transport::load(&a.file)?;
    if let Some(o) = a.sh_order {
        crate::flags::sh_order(o, t.meta.sh_order as usize)?;
    }
    if method == Method::Wavelet {
        crate::flags::terms(a.terms, t.meta.cube_n as usize)?;
    }
    let env = load_env(&a.env)?;
    let ctx = LightContext::new(&t)?;
    let start = Instant::now();
    let rotation = EnvRotation {
        yaw_deg: a.yaw,
        pitch_deg: a.pitch,
    };
    let light = ctx.prepare(&env, rotation)?;
    let light_ms = start.elapsed().as_secs_f64() * 1e3;
    let req = RelightRequest {
        method,
        terms: a.terms,
        weighting,
        sh_order: a.sh_order.unwrap_or(t.meta.sh_order as usize),
    };
    let (img, stats) = match &gpu {
        None => relight(&t, &ctx, &light, &req)?,
        Some(gpu) => {
            let upload = Instant::now();
            let g = crate::gpu::GpuTransport::upload(gpu, &t, None)?;
            eprintln!(
                "gpu: {} ({} chunk(s), {} bytes per nonzero, upload {:.0} ms)",
                gpu.adapter,
                g.chunk_count(),
                g.bytes_per_nonzero(),
                upload.elapsed().as_secs_f64() * 1e3
            );
            match method {
                Method::Sh => g.relight_sh(
                    gpu,
                    &crate::relight::light_sh_order(
                        &light.sh,
                        req.sh_order,
                        t.meta.sh_order as usize,
                    )?,
                )?,
                _ => {
                    let sparse = crate::relight::select_light(&t, &ctx, &light, &req)?;
                    let (img, mut stats) = g.relight_wavelet(gpu, &sparse)?;
                    stats.nonzeros_touched = crate::relight::nonzeros_touched(&t, &sparse);
                    stats.bytes_touched = stats.nonzeros_touched * g.bytes_per_nonzero()
                        + (t.tile_count() * sparse.len() * 8) as u64;
                    (img, stats)
                }
            }
        }
    };
    img.check_finite("relit image")?;
    let tone = match a.exposure {
        Some(e) => ToneMap::exposure(e),
        None => ToneMap::auto(&img, Some(&t.coverage)),
    };
    let img = match background {
        Background::Environment => crate::background::composite(
            &img,
            &crate::background::environment_behind(&t.meta, &t.coverage, &env, rotation)?,
        ),
        Background::Black => img,
    };
    img.save(&a.output, tone)?;
    println!(
        "{method}: {} terms{}, {} nonzeros touched ({:.1} MiB), light {:.1} ms, kernel {:.2} ms on the {} -> {}",
        stats.terms,
        if method == Method::Wavelet {
            format!(" ({weighting} weighting)")
        } else {
            String::new()
        },
        stats.nonzeros_touched,
        stats.bytes_touched as f64 / 1048576.0,
        light_ms,
        stats.kernel_seconds * 1e3,
        a.device,
        a.output.display()
    );
    Ok(())
}

fn reference_cmd(a: ReferenceArgs) -> Result<()> {
    let settings = settings_from(&a.sampling, 1, 0.0, true);
    settings.validate()?;
    let background: Background = a.background.parse()?;
    check_light_flags(a.yaw, a.pitch, None)?;
    let mut inputs = env_files(std::slice::from_ref(&a.env));
    check_image_output(&a.output, &inputs)?;
    let scene = Scene::load(&a.scene)?;
    inputs.extend(scene.input_files.iter().cloned());
    check_image_output(&a.output, &inputs)?;
    let env = load_env(&a.env)?;
    let rotation = EnvRotation {
        yaw_deg: a.yaw,
        pitch_deg: a.pitch,
    };
    let cube = env.to_cube(settings.cube_n, rotation)?;
    let start = Instant::now();
    let rows = bar(scene.camera.height as u64, "rows");
    let r = crate::reference::render_reference_with(&scene, &cube, &settings, &|done, _| {
        rows.set_position(done as u64)
    })?;
    rows.finish_and_clear();
    r.image.check_finite("reference image")?;
    let tone = ToneMap::auto(&r.image, Some(&r.coverage));
    let img = match background {
        Background::Environment => crate::background::composite(
            &r.image,
            &crate::background::environment_behind_camera(
                &scene.camera,
                &r.coverage,
                &env,
                rotation,
            )?,
        ),
        Background::Black => r.image,
    };
    img.save(&a.output, tone)?;
    println!(
        "reference: {}x{}, N = {}, {:.1} s -> {}",
        img.width,
        img.height,
        settings.cube_n,
        start.elapsed().as_secs_f64(),
        a.output.display()
    );
    Ok(())
}

fn env_cmd(a: EnvArgs) -> Result<()> {
    let env = load_env(&a.env)?;
    let power = env.power();
    let sh = env.project_sh(a.sh, EnvRotation::default())?;
    let cube = env.to_cube(a.cube, EnvRotation::default())?;
    let light = WaveletLight::from_cube(&cube)?;
    let energy: Vec<f64> = light
        .coeffs
        .iter()
        .map(|c| c.iter().map(|v| (*v as f64).powi(2)).sum())
        .collect();
    let total: f64 = energy.iter().sum();
    let mut sorted = energy.clone();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let ks: Vec<usize> = [1, 10, 50, 200, 1000]
        .into_iter()
        .filter(|&k| k <= sorted.len())
        .collect();
    let captured: Vec<(usize, f64)> = ks
        .iter()
        .map(|&k| {
            (
                k,
                sorted[..k].iter().sum::<f64>() / total.max(f64::MIN_POSITIVE),
            )
        })
        .collect();
    if a.json {
        let obj = serde_json::json!({
            "source": env.source,
            "width": env.width,
            "height": env.height,
            "negatives_clamped": env.negatives_clamped,
            "power": power,
            "sh_order": a.sh,
            "sh": sh,
            "cube_n": a.cube,
            "haar_energy_captured": captured.iter().map(|(k, f)| serde_json::json!({"k": k, "fraction": f})).collect::<Vec<_>>(),
        });
        println!("{obj}");
        return Ok(());
    }
    println!("environment   {}", env.source);
    println!("size          {} x {}", env.width, env.height);
    println!(
        "power         R {:.4}  G {:.4}  B {:.4}  (Σ L Ω)",
        power[0], power[1], power[2]
    );
    println!("SH order {}    L_i = ∫ L Y_i dω, index l(l+1)+m:", a.sh);
    for (i, c) in sh.iter().enumerate() {
        let l = (i as f64).sqrt() as usize;
        let m = i as i64 - (l * (l + 1)) as i64;
        println!(
            "  l={l} m={m:+}  {:>12.5} {:>12.5} {:>12.5}",
            c[0], c[1], c[2]
        );
    }
    println!("Haar energy captured by the best K terms (N = {}):", a.cube);
    for (k, f) in captured {
        println!("  K = {k:>5}  {:.4}%", 100.0 * f);
    }
    Ok(())
}

fn bench_cmd(a: BenchArgs) -> Result<()> {
    let t = Transport::load(&a.file)?;
    let mut opts = crate::bench::BenchOptions::defaults_for(&t);
    if let Some(k) = a.terms {
        opts.terms = k;
    }
    if let Some(o) = a.sh_light_orders {
        opts.sh_light_orders = if o.iter().any(|v| v == "none") {
            Vec::new()
        } else {
            o.iter()
                .map(|v| {
                    v.trim().parse().map_err(|_| {
                        PrtError::invalid(
                            "--sh-light-orders",
                            format!("'{v}' is not an order (or `none`)"),
                        )
                    })
                })
                .collect::<Result<_>>()?
        };
    }
    if let Some(o) = a.sh_orders {
        opts.sh_orders = o;
    }
    if let Some(w) = a.weightings {
        opts.weightings = w.iter().map(|s| s.parse()).collect::<Result<_>>()?;
    }
    opts.validate(&t)?;
    let mut envs = Vec::new();
    for spec in &a.env {
        let name: String = std::path::Path::new(spec)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or(spec)
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        envs.push((name, load_env(spec)?));
    }
    let points_bar = bar(0, "points");
    let gpu = match a.device.as_str() {
        "cpu" => None,
        "gpu" => Some(crate::gpu::Gpu::new()?),
        "auto" => crate::gpu::Gpu::new()
            .map_err(|e| eprintln!("note: timing the CPU only: {e}"))
            .ok(),
        other => {
            return Err(PrtError::invalid(
                "device",
                format!("`{other}`; expected auto, cpu or gpu"),
            ));
        }
    };
    let device = match &gpu {
        Some(g) => {
            eprintln!("gpu: {}", g.adapter);
            Some((g, crate::gpu::GpuTransport::upload(g, &t, None)?))
        }
        None => None,
    };
    let settings = BakeSettings {
        cube_n: t.meta.cube_n as usize,
        sh_order: t.meta.sh_order as usize,
        spp: t.meta.spp,
        texel_samples: t.meta.texel_samples,
        threshold: t.meta.threshold,
        budget: t.meta.budget,
        quantization: match t.meta.quantization {
            crate::quant::Quantization::F32 => crate::quant::Quantization::Q8,
            q => q,
        },
        lossless: true,
        unshadowed: t.meta.unshadowed,
        seed: t.meta.seed,
        shard: None,
        bounces: t.meta.bounces,
        paths: t.meta.paths.max(1),
    };
    let scene = if a.reference || a.compression.is_some() {
        let path = a
            .scene
            .clone()
            .unwrap_or_else(|| PathBuf::from(&t.meta.scene_path));
        let scene = Scene::load(&path)?;
        if format!("{:016x}", scene.content_hash()) != t.meta.scene_hash {
            return Err(PrtError::invalid(
                "scene",
                format!(
                    "{} is not the scene {} was baked from (content hash differs)",
                    path.display(),
                    a.file.display()
                ),
            ));
        }
        Some(scene)
    } else {
        None
    };
    let references = match (&scene, a.reference) {
        (Some(scene), true) => {
            let mut refs = Vec::new();
            let rows = bar(
                (envs.len() * scene.camera.height as usize) as u64,
                "reference rows",
            );
            for (i, (name, env)) in envs.iter().enumerate() {
                rows.set_message(format!("brute force under {name}"));
                let cube = env.to_cube(settings.cube_n, EnvRotation::default())?;
                let before = (i * scene.camera.height as usize) as u64;
                let r = crate::reference::render_reference_with(
                    scene,
                    &cube,
                    &settings,
                    &|done, _| rows.set_position(before + done as u64),
                )?;
                refs.push(r.image);
            }
            rows.finish_and_clear();
            Some(refs)
        }
        _ => None,
    };
    let extras = crate::bench::BenchExtras {
        gpu: device.as_ref().map(|(g, gt)| (*g, gt)),
        references: references.as_deref(),
    };
    let points = crate::bench::run(&t, &envs, &opts, &extras, &mut |done, total| {
        points_bar.set_length(total as u64);
        points_bar.set_position(done as u64);
    })?;
    points_bar.finish_and_clear();
    let mut written = crate::bench::write_report(&a.out, &points)?;
    if let (Some(scene), Some(thresholds)) = (&scene, &a.compression) {
        let sweep = progress_bar(0);
        let progress = bake_progress(&sweep, Instant::now());
        let curve = crate::bench::compression_sweep(
            scene,
            &settings,
            thresholds,
            &envs,
            &mut |l| sweep.println(l),
            &progress,
        )?;
        sweep.finish_and_clear();
        written.extend(crate::bench::write_compression(&a.out, &curve)?);
    }
    println!("{}", crate::bench::summary(&points));
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn view_cmd(a: ViewArgs) -> Result<()> {
    use crate::viewer::{Engine, env_entries, screenshot};
    let err = |m: String| PrtError::invalid("viewer", m);
    let Some(out) = a.screenshot.clone() else {
        if a.method.is_some()
            || a.terms.is_some()
            || a.compare
            || a.error_map
            || a.split.is_some()
            || a.tone.is_some()
        {
            return Err(PrtError::invalid(
                "viewer",
                "--method, --terms, ... apply to --screenshot only",
            ));
        }
        if !a.file.exists() {
            return Err(PrtError::io(
                &a.file,
                std::io::Error::from(std::io::ErrorKind::NotFound),
            ));
        }
        return crate::viewer::run(&a.file, &a.env).map_err(|e| {
            let text = e.to_string();
            if text.contains("DISPLAY") {
                PrtError::invalid(
                    "display",
                    "no display to open a window on (neither WAYLAND_DISPLAY nor DISPLAY is \
                     set): use --screenshot OUT.png to render the view to a file",
                )
            } else {
                err(text)
            }
        });
    };
    let mut inputs = env_files(&a.env);
    inputs.push(a.file.clone());
    let inputs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(
        &out,
        &["png"],
        "a tone-mapped PNG (`prt relight -o IMG.exr` writes linear radiance)",
        &inputs,
    )?;
    check_light_flags(a.yaw.unwrap_or(0.0), a.pitch.unwrap_or(0.0), a.exposure)?;
    if let Some(f) = a.split {
        crate::flags::fraction("split", f)?;
    }
    if crate::volume::is_volume_file(&a.file) {
        if a.method.is_some()
            || a.terms.is_some()
            || a.weighting.is_some()
            || a.compare
            || a.error_map
            || a.split.is_some()
        {
            return Err(PrtError::invalid(
                "viewer",
                "--method, --terms, --weighting, --compare, --split and --error-map apply to \
                 transport files; for a volume's views and cameras use `prt volume render`",
            ));
        }
        return volume_screenshot_cmd(&a, &out);
    }
    let (entries, sun, selected) = env_entries(&a.env);
    let transport = Transport::load(&a.file)?;
    let mut engine = Engine::from_transport(&a.file, transport, entries).map_err(err)?;
    let mut state = engine.initial_state(selected, sun);
    if let Some(r) = crate::viewer::cli_sun_radius(&a.env) {
        state.sun_radius = r;
    }
    state.compare = a.compare || a.split.is_some();
    state.error_map = a.error_map;
    if let Some(f) = a.split {
        state.layout = crate::viewer::Layout::Split;
        state.split = f;
    }
    if let Some(t) = &a.tone {
        state.tone = parse_tone(t)?;
    }
    if let Some(m) = &a.method {
        state.method = m.parse()?;
    }
    // Given flags are checked as `relight` checks them; only the defaults are fitted to the file.
    let limits = engine.limits();
    if let Some(k) = a.terms {
        crate::flags::terms(k, engine.transport.meta.cube_n as usize)?;
        state.terms = k;
    }
    if let Some(w) = &a.weighting {
        state.weighting = w.parse()?;
    }
    if let Some(o) = a.sh_order {
        crate::flags::sh_order(o, limits.sh_order)?;
        state.sh_order = o;
    }
    if let Some(y) = a.yaw {
        state.yaw = y;
    }
    if let Some(p) = a.pitch {
        state.pitch = p;
    }
    state.exposure = match a.exposure {
        Some(e) => e,
        None => engine.auto_exposure(&state).map_err(err)?,
    };
    let r = screenshot(&mut engine, &state, &out).map_err(err)?;
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    for p in &r.panes {
        let l = &p.linear;
        println!(
            "{}: {} terms, {:.2} M nonzeros touched, relight {:.2} ms, relative L2 vs full {:.4}",
            l.title,
            l.terms,
            l.nonzeros_touched as f64 * 1e-6,
            l.relight_seconds * 1e3,
            l.rel_l2
        );
    }
    println!("wrote {}", out.display());
    Ok(())
}

/// `prt view FILE.prtv --screenshot OUT.png`: the volume window's first frame.
fn volume_screenshot_cmd(a: &ViewArgs, out: &std::path::Path) -> Result<()> {
    use crate::viewer::{VolumeEngine, VolumeState, env_entries, volume_screenshot};
    let err = |m: String| PrtError::invalid("viewer", m);
    let vt = crate::volume::VolumeTransfer::load(&a.file)?;
    let (entries, sun, selected) = env_entries(&a.env);
    let mut state = VolumeState::initial(&vt);
    state.env = selected;
    (state.sun_elev, state.sun_azim) = sun;
    if let Some(r) = crate::viewer::cli_sun_radius(&a.env) {
        state.sun_radius = r;
    }
    if let Some(y) = a.yaw {
        state.yaw = y;
    }
    if let Some(p) = a.pitch {
        state.pitch = p;
    }
    if let Some(o) = a.sh_order {
        crate::flags::sh_order(o, vt.meta.sh_order)?;
        state.sh_order = o;
    }
    if let Some(t) = &a.tone {
        state.tone = parse_tone(t)?;
    }
    let mut engine = VolumeEngine::new(vt, entries);
    state.exposure = match a.exposure {
        Some(e) => e,
        None => {
            let f = engine.render(&state).map_err(err)?;
            ToneMap::auto(&f.image, None).exposure
        }
    };
    let f = volume_screenshot(&mut engine, &state, out).map_err(err)?;
    println!(
        "volume {} view, SH order {}: march {:.1} ms on {}",
        state.view.name(),
        state.sh_order,
        f.march_seconds * 1e3,
        f.device
    );
    println!("wrote {}", out.display());
    Ok(())
}

fn parse_tone(t: &str) -> Result<crate::film::ToneCurve> {
    Ok(match t.to_ascii_lowercase().as_str() {
        "clip" => crate::film::ToneCurve::Clip,
        "reinhard" => crate::film::ToneCurve::Reinhard,
        "aces" => crate::film::ToneCurve::Aces,
        _ => {
            return Err(PrtError::invalid(
                "viewer",
                format!("--tone {t}: expected clip, reinhard or aces"),
            ));
        }
    })
}

fn volume_bake_cmd(a: VolumeBakeArgs) -> Result<()> {
    use crate::volume::{TransferSettings, bake_volume};
    crate::files::check_output(&a.output, &["prtv"], "a volume file", &[])?;
    let scene = Scene::load(&a.scene)?;
    let inputs: Vec<&std::path::Path> = scene.input_files.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(&a.output, &["prtv"], "a volume file", &inputs)?;
    let settings = TransferSettings {
        sh_order: a.sh_order,
        directions: a.directions,
    };
    settings.validate()?;
    let bar = ProgressBar::new(settings.directions as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} directions  ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    let start = Instant::now();
    let vt = bake_volume(&scene, a.grid, &settings, &|done, _| {
        bar.set_position(done as u64)
    })?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    vt.save(&a.output)?;
    let [nx, ny, nz] = vt.meta.dims;
    println!(
        "baked {nx}x{ny}x{nz} voxels x {} directions at SH order {} in {seconds:.2} s ({:.1} M voxel-directions/s)",
        settings.directions,
        settings.sh_order,
        (vt.voxel_count() * settings.directions) as f64 / seconds / 1e6
    );
    println!("wrote {}", a.output.display());
    Ok(())
}

fn volume_render_cmd(a: VolumeRenderArgs) -> Result<()> {
    use crate::volume::{PhaseLight, VolumeTransfer, VolumeView, render_volume};
    let view: VolumeView = a.view.parse()?;
    check_light_flags(a.yaw, a.pitch, a.exposure)?;
    let mut inputs = env_files(std::slice::from_ref(&a.env));
    inputs.push(a.file.clone());
    check_image_output(&a.output, &inputs)?;
    let vt = VolumeTransfer::load(&a.file)?;
    let size = match (a.width, a.height) {
        (None, None) => None,
        (w, h) => Some((w.unwrap_or(vt.meta.width), h.unwrap_or(vt.meta.height))),
    };
    let camera = vt.camera(a.eye, a.target, size)?;
    let order = a.sh_order.unwrap_or(vt.meta.sh_order);
    crate::flags::sh_order(order, vt.meta.sh_order)?;
    crate::cubemap::validate_n(a.cube)?;
    let env = load_env(&a.env)?;
    let start = Instant::now();
    let cube = env.to_cube(
        a.cube,
        EnvRotation {
            yaw_deg: a.yaw,
            pitch_deg: a.pitch,
        },
    )?;
    let light = PhaseLight::new(&cube, order, vt.meta.g);
    let light_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    let (img, device) = match a.device.as_str() {
        "cpu" => (render_volume(&vt, &light, &camera, view), "cpu".to_string()),
        "gpu" => {
            let gpu = crate::gpu::Gpu::new()?;
            let mut gv = crate::volume::gpu::GpuVolume::new(&gpu, &vt)?;
            let (img, _) = gv.render(&gpu, &light, &camera, view)?;
            (img, gpu.adapter.clone())
        }
        other => {
            return Err(PrtError::invalid(
                "device",
                format!("`{other}`; expected cpu or gpu"),
            ));
        }
    };
    let march_ms = start.elapsed().as_secs_f64() * 1e3;
    img.check_finite("volume image")?;
    let tone = match a.exposure {
        Some(e) => ToneMap::exposure(e),
        None => ToneMap::auto(&img, None),
    };
    img.save(&a.output, tone)?;
    println!(
        "{}x{} {} view at SH order {order} on {device}: environment to light {light_ms:.0} ms, march {march_ms:.1} ms",
        camera.width,
        camera.height,
        view.name()
    );
    println!("wrote {}", a.output.display());
    Ok(())
}

fn compare_cmd(image: PathBuf, reference: PathBuf, mask: Option<PathBuf>) -> Result<()> {
    let a = crate::film::Image::load_exr(&image)?;
    let r = crate::film::Image::load_exr(&reference)?;
    let mask = match mask {
        Some(p) => Some(Transport::load(&p)?.coverage),
        None => None,
    };
    let e = crate::metrics::compare(&a, &r, mask.as_deref())?;
    println!(
        "rel_l2 {:.6}  rmse {:.6}  psnr {:.2} dB  rel_h1 {:.6}  dssim {:.6}",
        e.rel_l2, e.rmse, e.psnr_db, e.rel_h1, e.dssim
    );
    Ok(())
}

fn demo(out: PathBuf) -> Result<()> {
    let start = Instant::now();
    let bar = std::sync::Mutex::new(None::<ProgressBar>);
    let report =
        crate::demo::run_demo(&out, &mut |line| eprintln!("{line}"), &|p: BakeProgress| {
            let mut guard = bar.lock().unwrap_or_else(|e| e.into_inner());
            let b = guard.get_or_insert_with(|| progress_bar(p.pixels_total));
            b.set_position(p.pixels_done as u64);
            if p.pixels_done == p.pixels_total {
                b.finish_and_clear();
            }
        })?;
    println!("{}", crate::demo::markdown_table(&report.rows));
    println!(
        "bake {} ({:.1} s); everything in {:.1} s",
        if report.reused_bake { "reused" } else { "done" },
        report.bake_seconds,
        start.elapsed().as_secs_f64()
    );
    println!("contact sheet  {}", report.sheet_path.display());
    println!("table          {}", report.table_path.display());
    println!("transport      {}", report.transport_path.display());
    println!(
        "volume         {} (SH self-transfer baked in {:.2} s; images in {})",
        out.join("volume_sheet.png").display(),
        report.volume_bake_seconds,
        out.join("volume").display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::three_significant;

    #[test]
    fn rates_have_three_significant_digits() {
        for (x, want) in [
            (16_694.735_2, "16.7k"),
            (1234.0, "1.23k"),
            (523.4, "523"),
            (52.34, "52.3"),
            (5.234, "5.23"),
            (12_860_000.0, "12.9M"),
            (0.0, "0"),
            (f64::NAN, "0"),
        ] {
            assert_eq!(three_significant(x), want, "{x}");
        }
    }
}
