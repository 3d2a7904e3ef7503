//! `prt bench`: the sparsity-versus-error sweeps, with the references and the compression curve.

use super::*;
use crate::store::transport::{BakeDomain, Domain};

/// Arguments of `prt bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Transport file.
    pub file: PathBuf,
    /// Environments (.exr/.hdr files, bundled maps by name or sun:ELEV,AZIM[,RADIUS]), one or
    /// more.
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
    /// SH orders through the light, comma-separated, up to 142: the light projected to n² terms
    /// and relit with the full transport (default: 1, 2, 3, 4, 6, ... 100; `none` for none).
    #[arg(long, value_delimiter = ',')]
    pub sh_light_orders: Option<Vec<String>>,
    /// Weightings, comma-separated (default: none,area,transport).
    #[arg(long, value_delimiter = ',')]
    pub weightings: Option<Vec<String>>,
    /// Where the kernels are timed beside the CPU: auto (a hardware GPU when one exists, else
    /// the CPU only), cpu (the CPU only), or gpu (any adapter, a software one included).
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    pub device: Device,
    /// Also render the brute-force reference of the scene and report every point against it.
    #[arg(long)]
    pub reference: bool,
    /// Thresholds for the compression curve, comma-separated: the scene is baked at each and
    /// the error sparsification adds is measured.
    #[arg(long, value_delimiter = ',')]
    pub compression: Option<Vec<f32>>,
    /// Scene file for --reference and --compression (default: the one the file was baked from,
    /// from the working folder or beside the file).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// The camera a per-vertex bake is drawn from and its reference rendered from (`--eye`,
    /// `--target`, `--up`, `--width`, `--height`; default: the scene's).
    #[command(flatten)]
    pub view: super::relight::StillArgs,
}

/// Camera sub-samples a pixel of a textured scene's reference takes for a per-vertex bake.
const TEXTURED_REFERENCE_SPP: u32 = 16;

pub(super) fn bench_cmd(a: BenchArgs) -> Result<()> {
    let t = Transport::load(&a.file)?;
    crate::files::guard_inputs(&[&a.file]);
    let mut opts = crate::app::studies::bench::BenchOptions::defaults_for(&t);
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
    let still = a.view.camera(&t)?;
    let mut envs = Vec::new();
    for spec in &a.env {
        envs.push((env_name(spec), load_env(spec)?));
    }
    crate::files::check_output_folder(&a.out)?;
    crate::files::check_folder_outputs(
        &a.out,
        &[
            "bench.csv",
            "summary.md",
            "compression.csv",
            "compression.png",
            "compression.md",
        ],
    )?;
    let points_bar = bar(0, "points");
    let gpu = open_device(a.device)?;
    let device = match &gpu {
        Some(g) => {
            eprintln!("gpu: {}", g.adapter);
            Some((g, crate::relight::gpu::GpuTransport::upload(g, &t, None)?))
        }
        None => None,
    };
    // The settings of the file's own bake, whole (the reference and the sweep cover the image).
    let settings = BakeSettings {
        shard: None,
        ..BakeSettings::from_meta(&t.meta)
    };
    let scene = if a.reference || a.compression.is_some() {
        let path = bake_scene_path(&a.file, &t.meta.scene_path, a.scene.as_deref())?;
        // The bake's image size, which a glTF scene takes from its command line (a per-vertex
        // bake's is its scene camera's, not its vertex image's).
        let [width, height] = t
            .meta
            .per_vertex
            .as_ref()
            .map_or([t.meta.width, t.meta.height], |pv| pv.image);
        let framing = crate::scene::Framing {
            camera: None,
            width: Some(width),
            height: Some(height),
            ..Default::default()
        };
        let scene = Scene::load_with(&path, &framing)?;
        crate::files::guard_inputs(&scene.input_files);
        if scene.hash_hex() != t.meta.identity.scene_hash {
            return Err(PrtError::invalid(
                "scene",
                format!(
                    "{} is not the scene {} was baked from (content hash differs): give that \
                     scene with --scene",
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
        (Some(scene), true) => Some(brute_force_references(
            &t,
            scene,
            &settings,
            still.as_ref(),
            &envs,
        )?),
        _ => None,
    };
    let backend = match &device {
        Some((g, gt)) => Some(crate::relight::gpu::GpuBackend::new(g, gt, &t)?),
        None => None,
    };
    let extras = crate::app::studies::bench::BenchExtras {
        gpu: backend.as_ref().map(|b| b as &dyn crate::relight::Backend),
        references: references.as_ref().map(|(r, _)| r.as_slice()),
        reference_coverage: references.as_ref().map(|(_, c)| c.as_slice()),
        camera: still.as_ref(),
    };
    let points = crate::app::studies::bench::run(&t, &envs, &opts, &extras, &mut |done, total| {
        points_bar.set_length(total as u64);
        points_bar.set_position(done as u64);
    })?;
    points_bar.finish_and_clear();
    let mut written = crate::app::studies::bench::write_report(&a.out, &points)?;
    if let (Some(scene), Some(thresholds)) = (&scene, &a.compression) {
        let sweep = progress_bar(0);
        let progress = bake_progress(&sweep, Instant::now());
        let curve = crate::app::studies::bench::compression_sweep(
            scene,
            &settings,
            thresholds,
            &envs,
            &mut |l| sweep.suspend(|| eprintln!("{l}")),
            &progress,
        )?;
        sweep.finish_and_clear();
        written.extend(crate::app::studies::bench::write_compression(
            &a.out, &curve,
        )?);
    }
    println!("{}", crate::app::studies::bench::summary(&points));
    if let Some(pv) = &t.meta.per_vertex {
        println!(
            "per vertex ({} vertices, edges up to {:.3}): the reference error is taken on the \
             image drawn from the bake's camera, so that of every stored term is the \
             interpolation between vertices; `rel_l2` (against every term, per vertex) is the \
             light's approximation",
            pv.vertices,
            t.meta.identity.domain.edge_length().unwrap_or_default()
        );
    }
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// The brute-force references of bake `t` of `scene` (with its own `settings`) under each of
/// `envs`, and their coverage. A per-vertex bake holds the diffuse light at its vertices: its
/// reference is the per-pixel brute force of the same scene, seen from `still` where given,
/// with glossy materials at their diffuse base.
fn brute_force_references(
    t: &Transport,
    scene: &Scene,
    settings: &BakeSettings,
    still: Option<&crate::scene::Camera>,
    envs: &[(String, crate::env::envmap::EnvMap)],
) -> Result<(Vec<crate::output::film::Image>, Vec<f32>)> {
    let diffuse;
    let (scene, settings) = match &t.attached.domain {
        Domain::Mesh(_) => {
            let mut d = scene.with_diffuse_materials();
            if let Some(c) = still {
                d.camera = c.clone();
            }
            diffuse = d;
            // The raster filters textures by their mip levels; against one sample a
            // pixel (which aliases a minified texture) the error would be the
            // reference's, so a textured scene's reference takes 16 a pixel.
            let spp = match diffuse.is_textured() {
                true => settings.spp.max(TEXTURED_REFERENCE_SPP),
                false => settings.spp,
            };
            (
                &diffuse,
                BakeSettings {
                    domain: BakeDomain::View,
                    spp,
                    ..settings.clone()
                },
            )
        }
        Domain::View => (scene, settings.clone()),
    };
    let mut refs = Vec::new();
    let mut coverage = Vec::new();
    let rows = bar(
        (envs.len() * scene.camera.height as usize) as u64,
        "reference rows",
    );
    for (i, (name, env)) in envs.iter().enumerate() {
        rows.set_message(format!("brute force under {name}"));
        let cube = env.to_cube(settings.cube_n, EnvRotation::default())?;
        let before = (i * scene.camera.height as usize) as u64;
        let r =
            crate::bake::reference::render_reference_with(scene, &cube, &settings, &|done, _| {
                rows.set_position(before + done as u64)
            })?;
        refs.push(r.image);
        coverage = r.coverage;
    }
    rows.finish_and_clear();
    Ok((refs, coverage))
}

/// The name of an environment given as `spec`, for file names: its file stem, every character
/// but letters, digits, `_` and `-` turned into `_`.
fn env_name(spec: &str) -> String {
    std::path::Path::new(spec)
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
        .collect()
}
