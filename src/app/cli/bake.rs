//! `prt bake`, `prt merge`, `prt paper` and `prt demo`: making transport files.

use super::*;
use crate::store::transport::BakeDomain;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Arguments of `prt bake`.
#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Scene file: TOML, or glTF (.gltf, .glb).
    pub scene: PathBuf,
    /// Output transport file (.prt).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The view: a glTF camera, the image size.
    #[command(flatten)]
    pub framing: FramingArgs,
    /// How the transport is sampled.
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// SH order of the SH transport (n² coefficients, 1 to 10).
    #[arg(long, default_value_t = BakeSettings::default().sh_order)]
    pub sh_order: usize,
    /// L2 error allowed per transport row when dropping small Haar coefficients, relative to an
    /// unshadowed row's norm.
    #[arg(long, default_value_t = BakeSettings::default().threshold, conflicts_with = "lossless")]
    pub threshold: f32,
    /// Keep every coefficient in 32-bit floats.
    #[arg(long)]
    pub lossless: bool,
    /// How the threshold weighs coefficients: l2 (the row's L2 error), area (support solid
    /// angle), sun (the error at any one texel) or absolute (drop |v| < threshold · norm).
    #[arg(long, default_value_t = BakeSettings::default().budget, conflicts_with = "lossless")]
    pub budget: crate::store::budget::Budget,
    /// Stored values: q8 (8-bit integers against per-column scales) or q16.
    #[arg(long, default_value_t = BakeSettings::default().quantization, conflicts_with = "lossless")]
    pub quantization: crate::store::quant::Quantization,
    /// Bake only shard I of COUNT (bands of tile rows), e.g. 0/4; join them with `prt merge`.
    #[arg(long, value_name = "I/COUNT")]
    pub shard: Option<String>,
    /// Bake one row per mesh vertex instead of one per pixel, so that the camera can move
    /// (`prt relight --eye`, the viewer's orbit). Glossy materials keep their visibility, and
    /// their lobe is drawn per pixel (see --visibility).
    #[arg(long)]
    pub per_vertex: bool,
    /// Longest triangle edge of a per-vertex bake, in scene units: longer edges of quads,
    /// spheres and meshes are split. Default: the scene's `edge_length`, else 1/160 of the
    /// diagonal of its bounds.
    #[arg(long, requires = "per_vertex")]
    pub edge_length: Option<f32>,
    /// Per-vertex bakes: spend the vertices where shadows fall (as many as the uniform
    /// tessellation at --edge-length makes, more across shadow borders and fewer where the light
    /// is even); false splits every edge alike.
    #[arg(long, default_value_t = BakeSettings::default().refine_shadows, action = clap::ArgAction::Set, requires = "per_vertex")]
    pub refine_shadows: bool,
    /// Per-vertex bakes: store which cube texels each glossy vertex sees (a bit a texel, 6N²/8
    /// bytes a glossy vertex), so that its GGX lobe is drawn per pixel from the light itself,
    /// for the pixel's own direction to the camera, however sharp the lobe. Default: true for a
    /// scene with glossy materials; false keeps their diffuse base alone.
    #[arg(long, action = clap::ArgAction::Set, requires = "per_vertex")]
    pub visibility: Option<bool>,
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

pub(super) fn bake_cmd(a: BakeArgs) -> Result<()> {
    let mut settings = settings_from(&a.sampling, a.sh_order, a.threshold, a.lossless);
    settings.budget = a.budget;
    settings.quantization = a.quantization;
    settings.shard = a.shard.as_deref().map(parse_shard).transpose()?;
    settings.validate()?;
    crate::files::check_output(&a.output, &["prt"], "a transport file", &[])?;
    let scene = a.framing.load(&a.scene)?;
    warn_of_doubled_shadows(&scene);
    let mesh = if a.per_vertex {
        let edge = a
            .edge_length
            .unwrap_or_else(|| crate::scene::tessellate::VertexMesh::default_edge_length(&scene));
        settings.domain = BakeDomain::Vertices { edge_length: edge };
        settings.refine_shadows = a.refine_shadows;
        settings.visibility = a
            .visibility
            .unwrap_or_else(|| crate::api::glossy_visibility(&scene));
        settings.validate()?;
        say_glossy_choice(&scene, &settings);
        for name in crate::scene::tessellate::inward_surfaces(&scene) {
            eprintln!(
                "warning: {}: its normals point into the closed mesh (faces wound inward); the \
                 per-vertex bake turns them outward",
                crate::files::printable(name)
            );
        }
        Some(crate::scene::tessellate::VertexMesh::tessellate(
            &scene, edge,
        )?)
    } else {
        None
    };
    let inputs: Vec<&std::path::Path> = scene.input_files.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(&a.output, &["prt"], "a transport file", &inputs)?;
    // A run killed while writing left its temporary file; this one takes its place.
    crate::files::remove_stale_partials(&a.output);
    // Resuming: a finished output of this very bake (or shard) is kept, not redone.
    if crate::api::already_baked(&a.output, &scene, &settings).is_some() {
        eprintln!(
            "{} already holds this bake (same scene and settings): kept",
            a.output.display()
        );
        return Ok(());
    }
    let (w, h) = match &mesh {
        Some(m) => (m.vertex_count(), 1),
        None => (scene.camera.width as usize, scene.camera.height as usize),
    };
    let worst = worst_case_bytes(w, h, &settings);
    let at = describe_domain(mesh.as_ref(), &settings, [w, h]);
    eprintln!(
        "baking {} ({}, {}{}) {at}, N = {}, SH order {}, {} samples/texel",
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
        settings.texel_samples
    );
    eprintln!(
        "output: at most {:.1} MiB if every coefficient were kept{}; tiles are written as they \
         are finished, so memory holds only those under way",
        worst as f64 / 1048576.0,
        if settings.lossless {
            " (lossless keeps them all)"
        } else {
            ""
        }
    );
    let start = Instant::now();
    let bar = progress_bar(w * h);
    let edge_pixels = AtomicUsize::new(0);
    let show = bake_progress(&bar, start);
    let meta = crate::bake::bake_to_file(&scene, &settings, &a.output, &|p: BakeProgress| {
        edge_pixels.store(p.edge_pixels, Ordering::Relaxed);
        show(p)
    })?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    print_info(&a.output, &meta);
    warn_if_no_pixel_sees_the_scene(&meta);
    println!(
        "bake time     {seconds:.1} s, written ({:.2} M shadow rays/s)",
        meta.stats.shadow_rays as f64 / seconds.max(1e-9) / 1e6
    );
    if meta.identity.edge_spp > 0 {
        let edges = edge_pixels.into_inner();
        let pixels = scene.camera.width as usize * scene.camera.height as usize;
        println!(
            "edge pixels   {edges} of {pixels} ({:.1}%) took {} samples",
            100.0 * edges as f64 / pixels as f64,
            meta.identity.edge_spp
        );
    }
    Ok(())
}

/// Says what a per-vertex bake with `settings` keeps of `scene`'s glossy materials: their
/// visibility (and what it leaves out), or their diffuse base alone (and which materials lose a
/// highlight or light by it).
fn say_glossy_choice(scene: &crate::scene::Scene, settings: &BakeSettings) {
    let named = |keep: fn(&crate::scene::Material) -> bool| -> Vec<&str> {
        scene
            .materials
            .iter()
            .zip(&scene.material_names)
            .filter(|(m, _)| keep(m))
            .map(|(_, n)| n.as_str())
            .collect()
    };
    let glossy = named(|m| m.glossy_lobe().is_some());
    // Those whose highlight the diffuse base drops, and the rough ones whose lobe it drops
    // with much of their light.
    let shiny = named(drops_visible_gloss);
    let darkened = named(drops_rough_light);
    if !glossy.is_empty() && settings.visibility {
        eprintln!(
            "the glossy material(s) {} keep their visibility ({} bytes a vertex): their lobe \
             is drawn per pixel from the light (--visibility false keeps their diffuse base \
             alone)",
            glossy.join(", "),
            4 * crate::scene::visibility::Visibility::words(settings.cube_n)
        );
        if !scene.lights.is_empty() {
            eprintln!(
                "the local lights' columns are diffuse at every vertex; each glossy vertex \
                 keeps the share of each light it sees ({} bytes a vertex), and their \
                 highlights are drawn per pixel",
                4 * crate::scene::light::emitters(&scene.lights).len()
            );
        }
    } else {
        if !shiny.is_empty() {
            eprintln!(
                "warning: per vertex, the glossy material(s) {} keep only their diffuse base: \
                 a glossy lobe depends on the direction to the camera, which moves \
                 (--visibility true draws it per pixel)",
                shiny.join(", ")
            );
        }
        if !darkened.is_empty() {
            eprintln!(
                "warning: per vertex, the rough material(s) {} keep only their diffuse base, \
                 without the specular reflectance of their lobe (more than {} of the light): \
                 they come out darker (--visibility true draws their lobe per pixel)",
                darkened.join(", "),
                ROUGH_SPECULAR_NOTED
            );
        }
    }
}

/// `n` and the noun `one` or `many`, as the count asks.
fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// What a bake with `settings` makes rows for, as its first line says: the mesh's vertices,
/// triangles, edges and albedo maps, or the view's size and sub-samples.
fn describe_domain(
    mesh: Option<&crate::scene::tessellate::VertexMesh>,
    settings: &BakeSettings,
    [w, h]: [usize; 2],
) -> String {
    match (mesh, settings.domain) {
        (Some(m), BakeDomain::Vertices { edge_length: edge }) => format!(
            "per vertex: {}{} vertices, {} triangles, {}edges up to {edge:.4}{}{}; spp does not \
             apply",
            if settings.refines_shadows() {
                "at most "
            } else {
                ""
            },
            m.vertex_count(),
            m.triangles.len(),
            if settings.refines_shadows() {
                "as many as "
            } else {
                ""
            },
            if settings.refines_shadows() {
                " make, spent where shadows fall"
            } else {
                ""
            },
            match m.albedo_maps.len() {
                0 => String::new(),
                n => format!(
                    ", {} of {:.1} M texels with their mip levels",
                    plural(n, "albedo map", "albedo maps"),
                    m.albedo_maps.iter().map(|a| a.texel_count()).sum::<usize>() as f64 / 1e6
                ),
            }
        ),
        _ => format!("at {w}x{h}, {} spp", settings.spp),
    }
}

/// Perceptual roughness from which a GGX lobe is as broad as it gets: it hardly depends on the
/// direction to the camera, and a per-vertex bake that drops it loses no highlight.
const FULL_ROUGHNESS: f32 = 0.99;

/// Largest specular reflectance (any channel) of a rough lobe that a per-vertex bake's diffuse
/// base drops without a word: a dielectric's 0.04 darkens a surface by a few percent.
const ROUGH_SPECULAR_NOTED: f32 = 0.1;

/// Whether a per-vertex bake's diffuse base drops a highlight of `m` that shows: a specular
/// lobe narrower than [`FULL_ROUGHNESS`].
fn drops_visible_gloss(m: &crate::scene::Material) -> bool {
    match *m {
        crate::scene::Material::Glossy {
            specular,
            roughness,
            ..
        } => specular.max_element() > 0.0 && roughness < FULL_ROUGHNESS,
        crate::scene::Material::Diffuse { .. } => false,
    }
}

/// Whether a per-vertex bake's diffuse base drops a rough lobe of `m` that holds more than
/// [`ROUGH_SPECULAR_NOTED`] of the light (a rough metal would come out black).
fn drops_rough_light(m: &crate::scene::Material) -> bool {
    match *m {
        crate::scene::Material::Glossy {
            specular,
            roughness,
            ..
        } => specular.max_element() > ROUGH_SPECULAR_NOTED && roughness >= FULL_ROUGHNESS,
        crate::scene::Material::Diffuse { .. } => false,
    }
}

/// Most spacing of a moving light's neighbouring positions, as a share of its height above the
/// surface below them, before its shadows double: a relight between two positions blends the
/// shadows cast from both, whose edges lie apart by about the spacing times the occluder's
/// height over the light's, which shows as two shadows once the spacing is half the height.
const SHADOW_DOUBLING_SPACING: f32 = 0.5;

/// Warns of each moving light whose neighbouring positions lie more than
/// [`SHADOW_DOUBLING_SPACING`] times its height above the nearest surface below them apart
/// (the lower of the two positions' heights; a position above nothing is not judged).
fn warn_of_doubled_shadows(scene: &Scene) {
    let moving: Vec<&crate::scene::Light> = scene
        .lights
        .iter()
        .filter(|l| l.positions.len() > 1)
        .collect();
    if moving.is_empty() {
        return;
    }
    let tracer = crate::scene::trace::Tracer::new(scene);
    let height = |p: glam::Vec3| {
        tracer
            .closest_hit(p, glam::Vec3::NEG_Y, f32::INFINITY)
            .map(|h| h.t)
    };
    for light in moving {
        let n = light.positions.len();
        let grid = match light.grid.iter().product::<usize>() == n {
            true => light.grid,
            false => [n, 1, 1],
        };
        let heights: Vec<Option<f32>> = light.positions.iter().map(|&p| height(p)).collect();
        // The neighbours along each axis of the grid (x varying fastest), the worst pair kept as
        // (spacing, height).
        let strides = [1, grid[0], grid[0] * grid[1]];
        let mut worst: Option<(f32, f32)> = None;
        for i in 0..n {
            for (&stride, &count) in strides.iter().zip(&grid) {
                let j = i + stride;
                if (i / stride) % count + 1 >= count || j >= n {
                    continue;
                }
                let (Some(a), Some(b)) = (heights[i], heights[j]) else {
                    continue;
                };
                let (spacing, h) = (light.positions[i].distance(light.positions[j]), a.min(b));
                let worse = worst.is_none_or(|(s, wh)| spacing * wh > s * h);
                if spacing > SHADOW_DOUBLING_SPACING * h && worse {
                    worst = Some((spacing, h));
                }
            }
        }
        if let Some((spacing, h)) = worst {
            eprintln!(
                "warning: light `{}` moves in steps of up to {spacing:.3} at {h:.3} above the \
                 surface below it: a relight between two positions blends the shadows of both, \
                 which show double once the step passes {SHADOW_DOUBLING_SPACING} times the \
                 height; bake its positions at most {:.3} apart",
                crate::files::printable(&light.name),
                SHADOW_DOUBLING_SPACING * h
            );
        }
    }
}

pub(super) fn merge_cmd(shards: Vec<PathBuf>, output: PathBuf) -> Result<()> {
    let progress = bar(0, "bytes read");
    let meta = crate::api::merge(&shards, &output, &|read, total| {
        progress.set_length(total);
        progress.set_position(read);
    })?;
    progress.finish_and_clear();
    print_info(&output, &meta);
    warn_if_no_pixel_sees_the_scene(&meta);
    Ok(())
}

/// Warns on stderr when a whole view's bake holds no rows: no pixel of the camera sees the
/// scene, so every relight shows the environment alone. (One shard's band may see nothing.)
fn warn_if_no_pixel_sees_the_scene(m: &crate::store::transport::TransportMeta) {
    if m.stats.rows == 0
        && matches!(m.identity.domain, BakeDomain::View)
        && m.identity.shard.is_none()
    {
        eprintln!(
            "warning: no pixel of the camera sees the scene: the bake holds no rows, so a relight \
             shows the environment alone; aim the camera (eye {:?}, target {:?}, fov_y_deg {}) \
             at the scene",
            m.camera.eye, m.camera.target, m.camera.fov_y_deg
        );
    }
}

/// A progress bar for each bake of a study, in turn (a study bakes a view, then its mesh's
/// vertices): a bake whose size is not the bar's gets a bar of its own, and a bar is cleared
/// when its bake is done.
fn bar_per_bake(bar: &Mutex<Option<ProgressBar>>) -> impl Fn(BakeProgress) + Sync + '_ {
    move |p: BakeProgress| {
        if p.pixels_total == 0 {
            return;
        }
        let mut guard = bar.lock().unwrap_or_else(|e| e.into_inner());
        if guard
            .as_ref()
            .is_none_or(|b| b.length() != Some(p.pixels_total as u64))
        {
            *guard = Some(progress_bar(p.pixels_total));
        }
        let Some(b) = guard.as_mut() else { return };
        b.set_position(p.pixels_done as u64);
        if p.pixels_done == p.pixels_total {
            b.finish_and_clear();
            *guard = None;
        }
    }
}

/// Runs a study that bakes into the folder `out` (checked first), its log on stderr and a bar
/// per bake; returns its report and the seconds it took.
fn study<R>(
    out: &Path,
    run: impl FnOnce(&Path, &mut dyn FnMut(&str), &(dyn Fn(BakeProgress) + Sync)) -> Result<R>,
) -> Result<(R, f64)> {
    crate::files::check_output_folder(out)?;
    let start = Instant::now();
    let bar = Mutex::new(None);
    let report = run(out, &mut |line| eprintln!("{line}"), &bar_per_bake(&bar))?;
    Ok((report, start.elapsed().as_secs_f64()))
}

pub(super) fn paper(out: PathBuf) -> Result<()> {
    let (report, seconds) = study(&out, |out, log, progress| {
        crate::app::studies::paper::run_paper(out, &Default::default(), log, progress)
    })?;
    println!(
        "everything in {seconds:.1} s\nreport   {}\npicture  {}",
        report.markdown.display(),
        report.picture.display()
    );
    Ok(())
}

pub(super) fn demo(out: PathBuf) -> Result<()> {
    let (report, seconds) = study(&out, crate::app::studies::demo::run_demo)?;
    println!(
        "{}",
        crate::app::studies::demo::markdown_table(&report.rows)
    );
    println!(
        "bake {} ({:.1} s); everything in {:.1} s",
        if report.reused_bake { "reused" } else { "done" },
        report.bake_seconds,
        seconds
    );
    println!("contact sheet  {}", report.sheet_path.display());
    println!("table          {}", report.table_path.display());
    println!("transport      {}", report.transport_path.display());
    let o = &report.orbit;
    println!(
        "orbit          {} ({} vertices baked in {:.1} s, {:.1}% from the per-pixel bake; {} \
         vertices, {:.1}%; a frame at K = {} in {:.1} ms on the CPU)",
        o.sheet_path.display(),
        o.fine.vertices,
        o.fine.bake_seconds,
        100.0 * o.fine.interpolation_error,
        o.coarse.vertices,
        100.0 * o.coarse.interpolation_error,
        crate::app::studies::orbit::ORBIT_TERMS,
        o.frame_ms,
    );
    let s = &report.gloss;
    println!(
        "glossy orbit   {} ({} vertices with visibility baked in {:.1} s{}; the lobe per pixel \
         {:.1}% from the path tracer, {:.1}% for the diffuse base)",
        s.sheet_path.display(),
        s.vertices,
        s.bake_seconds,
        if s.reused_bake { ", reused" } else { "" },
        100.0 * s.glossy_error,
        100.0 * s.diffuse_error,
    );
    let d = &report.dusk;
    println!(
        "local lights   {} ({} light columns baked in {:.1} s{}; every light added in {:.2} ms \
         on the CPU)",
        d.sheet_path.display(),
        d.columns,
        d.bake_seconds,
        if d.reused_bake { ", reused" } else { "" },
        d.lights_ms
    );
    let g = &report.truck;
    println!(
        "glTF           {} ({} triangles, textured; baked in {:.1} s{})",
        g.sheet_path.display(),
        g.triangles,
        g.bake_seconds,
        if g.reused_bake { ", reused" } else { "" },
    );
    println!(
        "volume         {} (SH self-transfer and scattering orders ready in {:.2} s; images in {})",
        out.join("volume_sheet.png").display(),
        report.volume_bake_seconds,
        out.join("volume").display()
    );
    Ok(())
}
