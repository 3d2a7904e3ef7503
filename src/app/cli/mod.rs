//! The `prt` command line: argument parsing, progress bars and printing. Everything else is the
//! library; this module is the only place that writes to the terminal.
// The doc comments of the arguments are the help a terminal shows: brackets in them
// (`sun:ELEV,AZIM[,RADIUS]`, a scene file's `[medium]` table) are text, not links.
#![allow(rustdoc::broken_intra_doc_links)]

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use crate::bake::bounce::BounceVisibility;
use crate::bake::{BakeProgress, BakeSettings, bake, worst_case_bytes};
use crate::draw::background::Background;
use crate::env::envmap::{EnvMap, EnvRotation, EnvSpec};
use crate::env::select::{WaveletLight, Weighting};
use crate::error::{PrtError, Result};
use crate::output::film::{ToneCurve, ToneMap};
use crate::relight::{LightContext, Method, RelightRequest, relight};
use crate::scene::Scene;
use crate::store::transport::Transport;
use crate::volume::VolumeView;

mod bake;
mod bench;
mod bounces;
mod env;
mod gloss;
mod info;
mod relight;
mod relight_flags;
mod view;
mod volume;

pub use bake::BakeArgs;
use bake::{bake_cmd, demo, merge_cmd, paper};
pub use bench::BenchArgs;
use bench::bench_cmd;
pub use bounces::BouncesArgs;
pub use bounces::LightsArgs;
use bounces::{bounces_cmd, lights_cmd};
pub use env::EnvArgs;
use env::env_cmd;
pub use gloss::GlossArgs;
use gloss::gloss_cmd;
use info::{info, print_info};
pub use relight::{ReferenceArgs, RelightArgs};
use relight::{compare_cmd, reference_cmd, relight_cmd};
pub use relight_flags::{DEFAULT_TERMS, LocalLightArgs};
pub use view::ViewArgs;
use view::view_cmd;
pub use volume::{
    VolumeBakeArgs, VolumeCameraArgs, VolumeOrdersArgs, VolumeReferenceArgs, VolumeRenderArgs,
};
use volume::{volume_bake_cmd, volume_orders_cmd, volume_reference_cmd, volume_render_cmd};

/// All-frequency relighting: bake a view, relight it under any HDR environment with Haar wavelets
/// or spherical harmonics.
#[derive(Parser, Debug)]
#[command(name = "prt", version, about, long_about = None)]
pub struct Cli {
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// The commands of `prt`.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Bake the demo scene and relight it under every bundled environment (the main job).
    Demo {
        /// Output directory (the bake is cached there); default prt-demo, or prt-paper with
        /// --paper.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Ng et al. 2003 at its own scale instead: 512² bakes at cubes 4 to 64, SH against
        /// wavelets up to 20,164 terms, relight rates, pictures; writes ng2003.md (about 14 minutes,
        /// 2.2 GB of memory and 5.2 GB of bakes on 2 cores).
        #[arg(long)]
        paper: bool,
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
    /// Bake a scene with 0 to B interreflection bounces and compare each with the path tracer:
    /// a contact sheet and a table of time, size and error.
    Bounces(BouncesArgs),
    /// Glossy per-vertex bakes against the path tracer: the diffuse base, the lobe per pixel
    /// and SH glossy transfer at each tessellation, drawn from cameras the bake never saw, with
    /// the interpolation and the light's terms apart, the bytes a vertex, the bake and frame
    /// times.
    Gloss(GlossArgs),
    /// The local lights' figures: each kind against the path tracer and its bake cost, a
    /// moving light's error against the spacing of its positions, and many lights timed.
    Lights(LightsArgs),
    /// Open the interactive viewer (SH versus wavelet, kept terms, environments, rotation), or
    /// with --screenshot render the image it would show to a PNG and exit.
    View(ViewArgs),
    /// Participating media: bake SH self-transfer and higher scattering orders over a grid,
    /// relight it by ray marching, path trace it for reference.
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

/// The commands of `prt volume`.
#[derive(Subcommand, Debug)]
pub enum VolumeCommand {
    /// Bake the SH self-transfer of a scene's [medium] and its higher scattering orders into a
    /// volume file (.prtv).
    Bake(VolumeBakeArgs),
    /// Relight a volume file under an environment by ray marching, from any camera.
    Render(VolumeRenderArgs),
    /// Path trace a medium under an environment (delta tracking, no transfer data): the
    /// reference its bakes are held to.
    Reference(VolumeReferenceArgs),
    /// Study scattering orders: error against the path tracer, bake time and size per order
    /// count and grid, and the run-time albedo against the path tracer at that albedo.
    Orders(VolumeOrdersArgs),
}

/// Which view of a scene: a glTF file's camera, and the image size.
#[derive(Args, Debug, Clone, Default)]
pub struct FramingArgs {
    /// The glTF camera to use, by name (default: the file's first; without one, a camera that
    /// frames the whole scene from the front).
    #[arg(long)]
    pub camera: Option<String>,
    /// Image width in pixels (default: the scene file's; 256 for a glTF file).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene file's; for a glTF file, the width over the
    /// camera's aspect ratio).
    #[arg(long)]
    pub height: Option<u32>,
    /// Let glTF files read buffers and images outside their own folder (by default a URI that
    /// resolves outside it, through `..` or a link, is refused).
    #[arg(long)]
    pub read_outside_folder: bool,
}

impl FramingArgs {
    /// Loads the scene at `path` framed as asked, saying which files besides it were read and
    /// warning once of what its glTF files hold that is not used. Every file read is guarded:
    /// no output of the command may replace it.
    pub(super) fn load(&self, path: &Path) -> Result<Scene> {
        let framing = crate::scene::Framing {
            camera: self.camera.clone(),
            width: self.width,
            height: self.height,
            read_outside_folder: self.read_outside_folder,
        };
        let scene = Scene::load_with(path, &framing)?;
        crate::files::guard_inputs(&scene.input_files);
        let mut read: Vec<&Path> = Vec::new();
        for f in scene.input_files.iter().skip(1) {
            if !read.contains(&f.as_path()) {
                read.push(f);
            }
        }
        if !read.is_empty() {
            let list: Vec<String> = read.iter().map(|f| f.display().to_string()).collect();
            eprintln!(
                "note: {}: read {}",
                path.display(),
                crate::files::printable(&list.join(", "))
            );
        }
        if !scene.ignored.is_empty() {
            eprintln!(
                "note: {}: not used: {}",
                path.display(),
                crate::files::printable(&scene.ignored.join("; "))
            );
        }
        Ok(scene)
    }
}

/// Options shared by the bake and the reference: how the transport is sampled.
#[derive(Args, Debug, Clone)]
pub struct SamplingArgs {
    /// Cube face size N of the texel lights (power of two).
    #[arg(long, default_value_t = BakeSettings::default().cube_n)]
    pub cube: usize,
    /// Sub-pixel samples per pixel.
    #[arg(long, default_value_t = BakeSettings::default().spp)]
    pub spp: u32,
    /// Sub-pixel samples of the pixels whose corners see different things (silhouettes,
    /// material edges, creases, sharp shadow borders): antialiasing where it shows, `--spp`
    /// elsewhere. 0 (or no more than --spp): off.
    #[arg(long, default_value_t = BakeSettings::default().edge_spp)]
    pub edge_spp: u32,
    /// Shadow-ray directions per texel (rounded up to a square).
    #[arg(long, default_value_t = BakeSettings::default().texel_samples)]
    pub texel_samples: u32,
    /// With one direction a texel, the sub-texels (rounded up to a square, at most 64) of each
    /// texel that needs more than its centre: a shadow border (those towards it traced, for
    /// penumbrae), the horizon or a narrow glossy lobe (summed); the cosine over every other
    /// texel is exact. 0: every texel takes its centre's value (as in a per-vertex bake,
    /// whatever this says).
    #[arg(long, default_value_t = BakeSettings::default().edge_texel_samples)]
    pub edge_texel_samples: u32,
    /// Samples per shading point of each quad light or sun disc (rounded up to a square: a
    /// stratified grid over the light, for smooth penumbrae).
    #[arg(long, default_value_t = BakeSettings::default().light_samples)]
    pub light_samples: u32,
    /// Ignore visibility (no shadows).
    #[arg(long)]
    pub unshadowed: bool,
    /// Seed of every random choice.
    #[arg(long, default_value_t = BakeSettings::default().seed)]
    pub seed: u64,
    /// Interreflection bounces added to the direct light: paths from each camera hit, every
    /// vertex they reach adding its own direct row to the pixel's (next-event estimation into
    /// every texel; see --bounce-visibility). Through a [medium], paths also start at
    /// collisions along the camera ray, and a collision counts as a bounce.
    #[arg(long, default_value_t = BakeSettings::default().bounces)]
    pub bounces: u32,
    /// Paths per camera sub-sample for --bounces.
    #[arg(long, default_value_t = BakeSettings::default().paths)]
    pub paths: u32,
    /// Visibility at the bounces' path vertices: cache (bits at surface points a few pixels
    /// apart) or exact (6 N² shadow rays at every vertex).
    #[arg(
        long,
        default_value_t = BakeSettings::default().bounce_visibility,
        value_parser = BounceVisibility::from_str
    )]
    pub bounce_visibility: BounceVisibility,
    /// Width of a surface cache cell, in pixel footprints at the view's median depth.
    #[arg(long, default_value_t = BakeSettings::default().cache_spacing)]
    pub cache_spacing: f32,
}

/// Runs the command line; returns the process exit code.
pub fn main() -> i32 {
    let cli = Cli::parse();
    remove_temporary_files_on_interrupt();
    match run(cli.command) {
        Ok(()) => 0,
        Err(e) => {
            // Messages quote names and strings read from files: their control characters are
            // escaped (the lines of a message kept), so a crafted file cannot drive the terminal.
            let text: Vec<String> = e
                .to_string()
                .split('\n')
                .map(crate::files::printable)
                .collect();
            eprintln!("error: {}", text.join("\n"));
            1
        }
    }
}

/// On SIGINT (Ctrl-C), SIGTERM or SIGHUP, removes the temporary files of the writes in progress
/// ([`crate::files::remove_partials_in_progress`]; spill files never stay) and exits with 128 +
/// the signal's number, as the default action would end the process.
fn remove_temporary_files_on_interrupt() {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
            return;
        };
        std::thread::spawn(move || {
            if let Some(signal) = signals.forever().next() {
                crate::files::remove_partials_in_progress();
                std::process::exit(128 + signal);
            }
        });
    }
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Demo { out, paper: false } => demo(out.unwrap_or_else(|| "prt-demo".into())),
        Command::Demo { out, paper: true } => paper(out.unwrap_or_else(|| "prt-paper".into())),
        Command::Bake(a) => bake_cmd(a),
        Command::Info { file } => info(file),
        Command::Merge { shards, output } => merge_cmd(shards, output),
        Command::Relight(a) => relight_cmd(a),
        Command::Reference(a) => reference_cmd(a),
        Command::Env(a) => env_cmd(a),
        Command::Bench(a) => bench_cmd(a),
        Command::Bounces(a) => bounces_cmd(a),
        Command::Lights(a) => lights_cmd(a),
        Command::Gloss(a) => gloss_cmd(a),
        Command::View(a) => view_cmd(a),
        Command::Volume(VolumeCommand::Bake(a)) => volume_bake_cmd(a),
        Command::Volume(VolumeCommand::Render(a)) => volume_render_cmd(a),
        Command::Volume(VolumeCommand::Reference(a)) => volume_reference_cmd(a),
        Command::Volume(VolumeCommand::Orders(a)) => volume_orders_cmd(a),
        Command::Compare {
            image,
            reference,
            mask,
        } => compare_cmd(image, reference, mask),
    }
}

/// Below this share of a map's power (Σ |L| Ω) its negative samples are the noise of a lossy
/// encoder and are read as 0 without a word; the bundled maps hold at most 0.0037%.
const NEGATIVE_NOTE_SHARE: f64 = 1e-3;

/// The environment of an `--env` spec: a map file, a bundled map by name or the procedural sun.
/// `none` is refused: the commands that can relight without an environment handle it before
/// they get here. A file is guarded, so that no output of the command replaces it.
fn load_env(spec: &str) -> Result<EnvMap> {
    if spec == "none" {
        return Err(PrtError::invalid(
            "--env",
            "none: this command needs an environment, a map file or sun:ELEVATION,AZIMUTH \
             (`--env none`, the local lights alone, is for `prt relight` and `prt view` of a \
             bake with lights)",
        ));
    }
    let env = EnvMap::from_spec(spec)?;
    crate::files::guard_inputs(&env_files(&[spec.to_string()]));
    // Radiance cannot be negative; a map whose negative samples matter is said once per map,
    // however often a command loads it.
    static NOTED: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let mut noted = NOTED.lock().unwrap_or_else(|e| e.into_inner());
    if env.negative_share() > NEGATIVE_NOTE_SHARE && !noted.contains(&env.source) {
        noted.push(env.source.clone());
        eprintln!(
            "note: {}: {} of its {} samples are negative (the lowest {:.2e}, {:.2}% of the map's \
             power) and read as 0",
            crate::files::printable(&env.source),
            env.negatives_clamped,
            3 * env.pixels.len(),
            env.lowest_negative,
            100.0 * env.negative_share()
        );
    }
    Ok(env)
}

/// The files among environment specs (not the procedural `sun:` ones, nor the maps bundled in
/// the binary), for the output checks.
fn env_files(specs: &[String]) -> Vec<PathBuf> {
    specs
        .iter()
        .filter_map(|s| match EnvSpec::parse(s) {
            Ok(EnvSpec::File(p)) if crate::env::envmap::bundled_map(&p).is_none() => Some(p),
            _ => None,
        })
        .collect()
}

/// The scene a transport file was baked from: `given` (`--scene`) when there is one, else the
/// path the bake recorded, from the working folder or, failing that, beside the transport file
/// (as recorded, then by its file name).
fn bake_scene_path(file: &Path, recorded: &str, given: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = given {
        return Ok(p.to_path_buf());
    }
    let recorded = PathBuf::from(recorded);
    let folder = file.parent().unwrap_or(Path::new(""));
    let mut candidates = vec![recorded.clone()];
    if recorded.is_relative() {
        candidates.push(folder.join(&recorded));
    }
    if let Some(name) = recorded.file_name() {
        candidates.push(folder.join(name));
    }
    candidates.into_iter().find(|p| p.is_file()).ok_or_else(|| {
        PrtError::invalid(
            "scene",
            format!(
                "{} was baked from {}, which is neither in the working folder nor beside the \
                 file: give the scene with --scene",
                file.display(),
                recorded.display()
            ),
        )
    })
}

/// An up direction X,Y,Z: three finite numbers, not all zero.
fn parse_up(s: &str) -> std::result::Result<glam::Vec3, String> {
    let up = volume::parse_vec3(s)?;
    match up.length() > 0.0 {
        true => Ok(up),
        false => Err(format!(
            "`{s}`: an up direction must not be the zero vector"
        )),
    }
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

/// The glossy vertices' visibility that `--sh-transfer` draws from; for a bake without it, an
/// error that says how to bake one.
fn transfer_visibility(
    t: &crate::store::transport::Transport,
) -> Result<&crate::scene::visibility::Visibility> {
    let mesh = crate::draw::vertex::mesh_of(t)?;
    mesh.visibility.as_deref().ok_or_else(|| {
        PrtError::invalid(
            "--sh-transfer",
            "SH glossy transfer draws a per-vertex bake with visibility (a glossy scene's \
             `prt bake --per-vertex` keeps it by default)",
        )
    })
}

fn progress_bar(total: usize) -> ProgressBar {
    bar(total as u64, "px")
}

/// The bake's own progress as a bar: pixels, shadow rays per second, the medium's first stage.
fn bake_progress(bar: &ProgressBar, start: Instant) -> impl Fn(BakeProgress) + Sync + '_ {
    move |p: BakeProgress| {
        if p.cache_points[1] > 0 {
            bar.set_message(format!(
                "surface cache: {}/{} points",
                p.cache_points[0], p.cache_points[1]
            ));
            return;
        }
        if p.medium_light[1] > 0 {
            bar.set_message(format!(
                "medium: what its points see, {}/{} passes over the texel lights",
                p.medium_light[0], p.medium_light[1]
            ));
            return;
        }
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

/// Bakes with a progress bar over `rows`, the pixels or vertices the bake makes rows for.
fn bake_with_progress(scene: &Scene, settings: &BakeSettings, rows: usize) -> Result<Transport> {
    let bar = progress_bar(rows);
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
        edge_spp: s.edge_spp,
        texel_samples: s.texel_samples,
        edge_texel_samples: s.edge_texel_samples,
        light_samples: s.light_samples,
        threshold,
        lossless,
        unshadowed: s.unshadowed,
        seed: s.seed,
        shard: None,
        bounces: s.bounces,
        paths: s.paths,
        bounce_visibility: s.bounce_visibility,
        cache_spacing: s.cache_spacing,
        ..BakeSettings::default()
    }
}

/// How the environment is turned, for every command that lights with one.
#[derive(Args, Clone, Copy, Debug)]
pub struct TurnArgs {
    /// Turn the environment about +Y, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub yaw: f64,
    /// Turn the environment about +X after the yaw, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub pitch: f64,
}

impl TurnArgs {
    /// The environment rotation these flags give (yaw, then pitch, degrees).
    pub fn rotation(&self) -> EnvRotation {
        EnvRotation::new(self.yaw, self.pitch)
    }
}

/// Where a command's kernels run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, strum::Display)]
#[strum(serialize_all = "lowercase")]
pub enum Device {
    /// A hardware GPU when one exists, else the CPU: a software adapter (Mesa's lavapipe) is
    /// slower than the CPU kernels, so it is never taken unasked.
    Auto,
    /// The CPU kernels (rayon).
    Cpu,
    /// The wgpu kernels on whatever adapter exists, a software one included (said in one line).
    Gpu,
}

/// The GPU a command runs its kernels on, `None` for the CPU (see [`Device`]).
fn open_device(device: Device) -> Result<Option<crate::relight::gpu::Gpu>> {
    use crate::relight::gpu::Gpu;
    Ok(match device {
        Device::Cpu => None,
        Device::Auto => Gpu::hardware().ok(),
        Device::Gpu => {
            let gpu = Gpu::new()?;
            if gpu.software {
                eprintln!(
                    "note: {} is a software adapter: the GPU kernels run on the CPU, as a check \
                     of them, slower than --device cpu",
                    gpu.adapter
                );
            }
            Some(gpu)
        }
    })
}

fn parse_tone(t: &str) -> Result<crate::output::film::ToneCurve> {
    Ok(match t.to_ascii_lowercase().as_str() {
        "clip" => crate::output::film::ToneCurve::Clip,
        "reinhard" => crate::output::film::ToneCurve::Reinhard,
        "aces" => crate::output::film::ToneCurve::Aces,
        _ => {
            return Err(PrtError::invalid(
                "viewer",
                format!("--tone {t}: expected clip, reinhard or aces"),
            ));
        }
    })
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
