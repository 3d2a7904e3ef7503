//! The glossy per-vertex figures (`prt gloss`): a scene baked per vertex by each way of drawing
//! its glossy light ([`GlossMethod`], and SH glossy transfer beside the lobe) at each
//! tessellation, drawn from cameras the bake never saw and held to the independent path tracer,
//! with the two other errors apart: the interpolation between vertices (the diffuse base drawn
//! against the brute force of the scene made diffuse, which no glossy method touches) and the
//! light's K terms (against every term, per vertex). With them, the file's bytes a vertex, the
//! bake's time, and a frame's time at each K on the CPU and, when given one, the GPU.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::gloss_sh::{ShInputs, ShTransferRow};
use super::median;
use crate::bake::path_tracer::path_trace_from;
use crate::bake::reference::{Reference, render_reference_with};
use crate::bake::{BakeProgress, BakeSettings, load_or_bake_logged};
use crate::draw::raster::{DrawOptions, rasterize_with};
use crate::draw::vertex::{draw, draw_relit, vertex_colours};
use crate::env::envmap::{EnvMap, EnvRotation};
use crate::env::importance::MapLight;
use crate::env::select::Weighting;
use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;
use crate::output::film::{Image, ToneMap};
use crate::output::metrics::relative_l2;
use crate::output::plot::{self, PALETTE, PlotSpec};
use crate::relight::gpu::Gpu;
use crate::relight::sh_transfer::MAX_TRANSFER_ORDER;
use crate::relight::{Backend, Cpu, LightContext, RelightRequest, Terms, lobe_light, relight};
use crate::scene::tessellate::VertexMesh;
use crate::scene::{Camera, Scene};
use crate::store::transport::{BakeDomain, Transport};

mod report;
use report::error_series;
pub use report::{csv, markdown};

/// A way of drawing a glossy per-vertex bake's highlights, each a bake of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[derive(strum::IntoStaticStr, strum::Display, strum::VariantArray)]
#[strum(serialize_all = "kebab-case")]
pub enum GlossMethod {
    /// The diffuse base alone: the glossy lobes left out (`prt bake --visibility false`).
    Base,
    /// The glossy vertices' visibility, the lobe drawn per pixel from the light (`prt bake
    /// --per-vertex`'s default); SH glossy transfer draws the same bake.
    Lobe,
}

crate::named!(GlossMethod, "gloss method");

impl GlossMethod {
    /// Its name in the reports.
    pub fn label(self) -> &'static str {
        match self {
            GlossMethod::Base => "diffuse base",
            GlossMethod::Lobe => "visibility (the lobe per pixel)",
        }
    }
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct GlossBenchOptions {
    /// The methods, each baked at each tessellation.
    pub methods: Vec<GlossMethod>,
    /// Tessellations, as multiples of the scene's default edge length.
    pub edge_factors: Vec<f32>,
    /// The cameras the bakes are drawn from (none of them the bake's: a per-vertex bake has no
    /// view).
    pub cameras: Vec<Camera>,
    /// Paths a pixel of the path tracer.
    pub paths: u32,
    /// Samples a pixel of the drawings compared with it.
    pub samples: u32,
    /// Light terms K whose error and frame time are measured.
    pub light_terms: Vec<usize>,
    /// Side of the timed frames (square, one sample a pixel), pixels.
    pub frame_side: u32,
    /// Frames timed per point; the median is reported.
    pub runs: usize,
    /// The bakes' settings but for their tessellation and visibility (`prt bake`'s defaults from
    /// the command line); the references take their cube and camera sub-samples.
    pub bake: BakeSettings,
    /// SH orders at which each bake with visibility ([`GlossMethod::Lobe`]) is also drawn by SH
    /// glossy transfer ([`super::gloss_sh`]).
    pub sh_orders: Vec<usize>,
}

/// A frame's median times, milliseconds: the relight (its kernel alone on a GPU) and the
/// drawing (on a GPU: the colours uploaded, drawn and read back).
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameTime {
    /// The relight.
    pub relight_ms: f64,
    /// The drawing.
    pub draw_ms: f64,
}

/// One bake: its tessellation and method, its cost, and its errors.
#[derive(Clone, Debug)]
pub struct GlossBakeRow {
    /// Edge length as a multiple of the default.
    pub edge_factor: f32,
    /// Longest edge, scene units.
    pub edge_length: f32,
    /// How its glossy light is drawn.
    pub method: GlossMethod,
    /// Vertices.
    pub vertices: usize,
    /// The file's bytes.
    pub bytes: u64,
    /// Time to bake (or to load the kept bake), seconds.
    pub bake_seconds: f64,
    /// Whether the bake was kept from an earlier run.
    pub reused: bool,
    /// Per camera: every light term, against the path tracer (relative L2 over the image).
    pub error: Vec<f64>,
    /// Per camera: the same over the pixels that the drawing and the scene both cover whole,
    /// the outline left out (where a pixel is partly covered, and a grazing highlight in it is
    /// caught or missed by the drawing's few samples).
    pub inside: Vec<f64>,
    /// Per camera: the same over the pixels that the glossy materials alone cover whole (a
    /// glossy teapot's, without the ground it stands on), where the methods part; `None` where
    /// the camera sees no such pixel.
    pub glossy: Vec<Option<f64>>,
    /// Per K of [`GlossBenchOptions::light_terms`]: K terms against every term, per vertex.
    pub light_error: Vec<f64>,
    /// Per K: a CPU frame.
    pub cpu: Vec<FrameTime>,
    /// Per K: a GPU frame, when a GPU was given.
    pub gpu: Option<Vec<FrameTime>>,
}

impl GlossBakeRow {
    /// The row of bake `t` at edge factor `factor` by `method`, its file of `bytes`, baked in
    /// `seconds` or `reused`, nothing measured yet.
    fn new(
        t: &Transport,
        (factor, method): (f32, GlossMethod),
        bytes: u64,
        (bake_seconds, reused): (f64, bool),
    ) -> GlossBakeRow {
        GlossBakeRow {
            edge_factor: factor,
            edge_length: t.meta.identity.domain.edge_length().unwrap_or_default(),
            method,
            vertices: t
                .meta
                .per_vertex
                .as_ref()
                .map_or(0, |p| p.vertices as usize),
            bytes,
            bake_seconds,
            reused,
            error: Vec::new(),
            inside: Vec::new(),
            glossy: Vec::new(),
            light_error: Vec::new(),
            cpu: Vec::new(),
            gpu: None,
        }
    }
}

/// One camera: its path-traced reference and the interpolation error at each tessellation.
#[derive(Clone, Debug)]
pub struct GlossCameraRow {
    /// Where it is.
    pub eye: [f32; 3],
    /// What it looks at.
    pub target: [f32; 3],
    /// The path tracer's own noise, relative L2.
    pub noise: f64,
    /// Per tessellation: the diffuse base drawn against the brute force of the scene made
    /// diffuse, over the pixels both cover whole.
    pub interpolation: Vec<f64>,
}

/// Everything measured.
#[derive(Clone, Debug)]
pub struct GlossBenchReport {
    /// The scene's glossy materials: name, roughness.
    pub glossy: Vec<(String, f32)>,
    /// The environment's name.
    pub env: String,
    /// Every bake, tessellation by tessellation, the methods in the order given.
    pub bakes: Vec<GlossBakeRow>,
    /// Every camera.
    pub cameras: Vec<GlossCameraRow>,
    /// The GPU's name, when one was given.
    pub gpu: Option<String>,
    /// The bakes with visibility drawn by SH glossy transfer, at each order.
    pub sh: Vec<ShTransferRow>,
    /// What was written.
    pub files: Vec<PathBuf>,
}

impl GlossBenchOptions {
    /// The relights of [`GlossBenchOptions::light_terms`]: K transport-weighted wavelet terms.
    pub fn light_requests(&self) -> Vec<RelightRequest> {
        self.light_terms
            .iter()
            .map(|&k| RelightRequest::Wavelet {
                k,
                weighting: Weighting::Transport,
            })
            .collect()
    }

    /// Checks the lists.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, why: String| Err(PrtError::invalid(what, why));
        let mut methods = self.methods.clone();
        methods.dedup();
        if self.methods.is_empty() || methods.len() != self.methods.len() {
            return bad(
                "--methods",
                format!("{:?}; give each method once", self.methods),
            );
        }
        let mut seen = self.edge_factors.clone();
        seen.sort_by(f32::total_cmp);
        seen.dedup();
        if seen.len() != self.edge_factors.len() {
            return bad(
                "--edge-factors",
                format!("{:?} names one twice", self.edge_factors),
            );
        }
        if self.edge_factors.is_empty()
            || self
                .edge_factors
                .iter()
                .any(|f| !(f.is_finite() && (0.25..=16.0).contains(f)))
        {
            return bad(
                "--edge-factors",
                format!("{:?}; each must be from 0.25 to 16", self.edge_factors),
            );
        }
        if self.cameras.is_empty() || self.cameras.len() > PALETTE.len() {
            return bad(
                "--eye",
                format!(
                    "{} cameras; give from 1 to {}",
                    self.cameras.len(),
                    PALETTE.len()
                ),
            );
        }
        for c in &self.cameras {
            c.validate()?;
        }
        if self.light_terms.is_empty() {
            return bad("--terms", "no light term counts".into());
        }
        for &k in &self.light_terms {
            crate::flags::terms(k, self.bake.cube_n)?;
        }
        if self.runs == 0 {
            return bad("runs", "no frames to time".into());
        }
        if let Some(o) = self
            .sh_orders
            .iter()
            .find(|o| !(1..=MAX_TRANSFER_ORDER).contains(o))
        {
            return bad(
                "--sh-transfer",
                format!("order {o}; each must be from 1 to {MAX_TRANSFER_ORDER}"),
            );
        }
        if !self.sh_orders.is_empty() && !self.methods.contains(&GlossMethod::Lobe) {
            return bad(
                "--sh-transfer",
                "SH glossy transfer draws the bakes with visibility: add `lobe` to --methods"
                    .into(),
            );
        }
        crate::draw::raster::sample_offsets(self.samples)?;
        crate::flags::within("--paths", self.paths, 1..=1 << 20, "")?;
        crate::flags::within("--frame-side", self.frame_side, 16..=4096, " pixels")?;
        self.bake.validate()
    }
}

/// The name and roughness of each of `scene`'s glossy materials; an error when it has none
/// (every method would draw its diffuse base).
pub fn glossy_materials(scene: &Scene) -> Result<Vec<(String, f32)>> {
    let glossy: Vec<(String, f32)> = scene
        .materials
        .iter()
        .zip(&scene.material_names)
        .filter_map(|(m, name)| Some((name.clone(), m.glossy_lobe()?.1.sqrt())))
        .collect();
    if glossy.is_empty() {
        return Err(PrtError::invalid(
            "scene",
            format!(
                "{} has no glossy material: every method draws its diffuse base",
                scene.source_path.display()
            ),
        ));
    }
    Ok(glossy)
}

/// A relative error that can be reported: finite (a reference dark over the compared pixels
/// has none).
fn reportable(e: f64, what: impl FnOnce() -> String) -> Result<f64> {
    match e.is_finite() {
        true => Ok(e),
        false => Err(PrtError::invalid(
            "gloss",
            format!("{}: the reference is dark where compared", what()),
        )),
    }
}

/// The scene's camera turned about its target to `azimuths_deg` (see
/// [`crate::draw::vertex::orbit`]): default cameras that the bake never saw.
pub fn turned_cameras(scene: &Scene, azimuths_deg: &[f32]) -> Vec<Camera> {
    azimuths_deg
        .iter()
        .map(|&az| crate::draw::vertex::orbit(&scene.camera, az, 0.0))
        .collect()
}

/// Runs the measurements on `scene` under `env` (named `env_name`) and writes `gloss.md`,
/// `gloss.csv`, `gloss_error.png`, the bakes (`bakes/`, reused on the next run when the scene and
/// settings are unchanged) and every compared image (`images/`) into `dir`.
pub fn run(
    dir: &Path,
    scene: &Scene,
    env: (&str, &EnvMap),
    opts: &GlossBenchOptions,
    gpu: Option<&Gpu>,
    log: &mut dyn FnMut(&str),
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<GlossBenchReport> {
    opts.validate()?;
    let (env_name, env) = env;
    let glossy = glossy_materials(scene)?;
    let images = dir.join("images");
    crate::files::create_folder(&images)?;
    let bakes_dir = dir.join("bakes");
    crate::files::create_folder(&bakes_dir)?;
    let rotation = EnvRotation::default();
    // Per-vertex bakes take texel centres, and so does the brute force their interpolation is
    // measured against.
    let base = BakeSettings {
        domain: BakeDomain::View,
        edge_texel_samples: 0,
        ..opts.bake.clone()
    };
    let cube = env.to_cube(base.cube_n, rotation)?;

    let (references, mut cameras) = references(scene, env, (&base, &cube), opts, &images, log)?;

    let default_edge = VertexMesh::default_edge_length(scene);
    let k_reqs = opts.light_requests();
    let mut bakes = Vec::new();
    let mut sh = Vec::new();
    let sh_references: Vec<(Image, ToneMap)> = match opts.sh_orders.is_empty() {
        true => Vec::new(),
        false => references
            .iter()
            .map(|(traced, _, tone)| (traced.clone(), *tone))
            .collect(),
    };
    for &factor in &opts.edge_factors {
        for (b, &method) in opts.methods.iter().enumerate() {
            let settings = BakeSettings {
                domain: BakeDomain::Vertices {
                    edge_length: default_edge * factor,
                },
                visibility: method == GlossMethod::Lobe,
                ..base.clone()
            };
            let path = bakes_dir.join(format!("edges{factor}_{method}.prt"));
            let what = format!("baking with edges of {factor}x the default, {method} ...");
            let (t, reused, bake_seconds) =
                load_or_bake_logged(&path, scene, &settings, &what, log, progress)?;
            let ctx = LightContext::new(&t)?;
            let light = ctx.prepare(env, rotation)?;
            let (full, _) = relight(&t, &ctx, &light, &RelightRequest::Full)?;
            let full_light = lobe_light(&t, &ctx, Some(&light), &RelightRequest::Full)?;
            let bytes = std::fs::metadata(&path).map_or(0, |m| m.len());
            let mut row = GlossBakeRow::new(&t, (factor, method), bytes, (bake_seconds, reused));
            for (i, (cam, (traced, brute, tone))) in
                opts.cameras.iter().zip(&references).enumerate()
            {
                let drawn = draw_relit(&t, &full, full_light.as_ref(), cam, None, opts.samples)?;
                row.error.push(reportable(
                    relative_l2(&drawn.image, traced, None)?,
                    || format!("camera {}", i + 1),
                )?);
                row.inside.push(reportable(
                    relative_l2(
                        &drawn.image,
                        traced,
                        Some(&whole_in_both(&drawn.coverage, &brute.coverage)),
                    )?,
                    || format!("camera {}, within the outline", i + 1),
                )?);
                let glossy = glossy_pixels(&t, scene, cam, opts.samples, &brute.coverage)?;
                row.glossy.push(match glossy.contains(&1.0) {
                    true => Some(reportable(
                        relative_l2(&drawn.image, traced, Some(&glossy))?,
                        || format!("camera {}, on the glossy pixels", i + 1),
                    )?),
                    false => None,
                });
                drawn.image.save(
                    &images.join(format!("camera{}_edges{factor}_{method}.exr", i + 1)),
                    *tone,
                )?;
                // The interpolation: once per tessellation (every method's bake has the same
                // diffuse base).
                if b == 0 {
                    let base = draw(&t, vertex_colours(&t, &full)?, cam, None, opts.samples)?;
                    let both = whole_in_both(&base.coverage, &brute.coverage);
                    cameras[i].interpolation.push(reportable(
                        relative_l2(&base.image, &brute.image, Some(&both))?,
                        || format!("camera {}: the diffuse brute force", i + 1),
                    )?);
                }
            }
            if let Some(full_light) = full_light.as_ref().filter(|_| method == GlossMethod::Lobe) {
                let inputs = ShInputs {
                    t: &t,
                    ctx: &ctx,
                    light: &light,
                    full: &full,
                    full_light,
                    references: &sh_references,
                    edge_factor: factor,
                    cameras: &opts.cameras,
                    samples: opts.samples,
                    frame: [opts.frame_side as usize, opts.runs, opts.light_terms[0]],
                };
                sh.extend(super::gloss_sh::measure_orders(
                    &inputs,
                    &opts.sh_orders,
                    &images,
                    log,
                )?);
            }
            frames(&t, (&ctx, &light, &full), &k_reqs, (opts, gpu), &mut row)?;
            log(&format!(
                "edges {factor}x, {method}: {} vertices, {:.1} KB a vertex; against the path \
                 tracer {}",
                row.vertices,
                row.bytes as f64 / row.vertices.max(1) as f64 / 1e3,
                super::percents(&row.error)
            ));
            bakes.push(row);
        }
    }
    let mut report = GlossBenchReport {
        glossy,
        env: env_name.to_string(),
        bakes,
        cameras,
        gpu: gpu.map(|g| g.adapter.clone()),
        sh,
        files: Vec::new(),
    };
    report.files = write_report(dir, &report, opts)?;
    Ok(report)
}

/// A mask of the pixels whose samples all fall on triangles of glossy materials when the bake
/// `t` of `scene` is drawn from `cam` with `samples` a pixel, and that `reference` (a coverage)
/// covers whole.
fn glossy_pixels(
    t: &Transport,
    scene: &Scene,
    cam: &Camera,
    samples: u32,
    reference: &[f32],
) -> Result<Vec<f32>> {
    let mesh = t
        .mesh()
        .ok_or_else(|| PrtError::invalid("gloss", "a bake without vertices"))?;
    let flags: Vec<[f32; 3]> = mesh
        .materials
        .iter()
        .map(|&m| {
            let glossy = scene
                .materials
                .get(m as usize)
                .is_some_and(|m| m.glossy_lobe().is_some());
            [glossy as u8 as f32; 3]
        })
        .collect();
    let options = DrawOptions::samples(samples);
    let share = rasterize_with(cam, &mesh.positions, &mesh.triangles, &flags, options)?;
    // A triangle's three vertices share its material, so its share is 1 up to rounding.
    let mut mask = whole_in_both(&share.coverage, reference);
    for (m, p) in mask.iter_mut().zip(&share.image.pixels) {
        *m *= (p[0] > 0.999) as u8 as f32;
    }
    Ok(mask)
}

/// A mask of the pixels that coverages `a` and `b` both cover whole.
fn whole_in_both(a: &[f32], b: &[f32]) -> Vec<f32> {
    a.iter()
        .zip(b)
        .map(|(a, b)| (*a == 1.0 && *b == 1.0) as u8 as f32)
        .collect()
}

/// Per camera, the path tracer's image, the diffuse brute force and the tone; and the cameras'
/// rows.
type References = (Vec<(Image, Reference, ToneMap)>, Vec<GlossCameraRow>);

/// Each camera's references and row: the path tracer lit by the map's own pixels (its image
/// saved into `images`) and the brute force of the scene made diffuse under `cube` with the
/// per-pixel settings `base`.
fn references(
    scene: &Scene,
    env: &EnvMap,
    (base, cube): (&BakeSettings, &CubeMap),
    opts: &GlossBenchOptions,
    images: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<References> {
    let rotation = EnvRotation::default();
    let diffuse_scene = scene.with_diffuse_materials();
    let mut references = Vec::new();
    let mut cameras = Vec::new();
    // The path tracer is lit by the map's own pixels: the true lighting, with no cube between it
    // and the image.
    let light = MapLight::new(env, rotation);
    for (i, cam) in opts.cameras.iter().enumerate() {
        log(&format!(
            "camera {}: path tracing ({} paths a pixel) and the diffuse brute force ...",
            i + 1,
            opts.paths
        ));
        let traced = path_trace_from(scene, cam, &light, base, opts.paths)?;
        let tone = ToneMap::auto(&traced.image, None);
        traced.image.save(
            &images.join(format!("camera{}_path_traced.exr", i + 1)),
            tone,
        )?;
        let mut diffuse = diffuse_scene.clone();
        diffuse.camera = cam.clone();
        let brute = render_reference_with(&diffuse, cube, base, &|_, _| {})?;
        cameras.push(GlossCameraRow {
            eye: cam.eye.to_array(),
            target: cam.target.to_array(),
            noise: traced.relative_noise(None),
            interpolation: Vec::new(),
        });
        references.push((traced.image, brute, tone));
    }
    Ok((references, cameras))
}

/// Writes `gloss.md`, `gloss.csv` and `gloss_error.png` of `report` into `dir`, and says where.
fn write_report(
    dir: &Path,
    report: &GlossBenchReport,
    opts: &GlossBenchOptions,
) -> Result<Vec<PathBuf>> {
    let files = vec![
        dir.join("gloss.md"),
        dir.join("gloss.csv"),
        dir.join("gloss_error.png"),
    ];
    crate::files::write_bytes_atomically(&files[0], markdown(report, opts).as_bytes())?;
    crate::files::write_bytes_atomically(&files[1], csv(report).as_bytes())?;
    // Near and fast is the lower left, where no method reaches: the legend sits there.
    plot::write_figure(
        &files[2],
        &PlotSpec {
            title: format!(
                "Glossy per-vertex bakes under {}: error against the frame's time",
                report.env
            ),
            x_label: format!(
                "CPU frame at K = {}, {}² pixels (relight and draw), milliseconds",
                opts.light_terms[0], opts.frame_side
            ),
            y_label: "relative L2 against the path tracer, mean over the cameras".into(),
            log_x: true,
            log_y: false,
            width: 720,
            height: 440,
        },
        &error_series(report),
        &plot::Figure {
            legend: plot::Corner::LowerLeft,
            ..Default::default()
        },
    )?;
    Ok(files)
}

/// Each K of `reqs` on bake `t` relit under `light` (its image with every term `full`): the
/// K terms' error against every term, and a CPU frame (and a GPU one, given a GPU) at the
/// options' frame side, into `row`.
fn frames(
    t: &Transport,
    (ctx, light, full): (&LightContext, &crate::relight::PreparedLight, &Image),
    k_reqs: &[RelightRequest],
    (opts, gpu): (&GlossBenchOptions, Option<&Gpu>),
    row: &mut GlossBakeRow,
) -> Result<()> {
    let frame_cam = Camera {
        width: opts.frame_side,
        height: opts.frame_side,
        ..opts.cameras[0].clone()
    };
    for req in k_reqs {
        let (k_img, _) = relight(t, ctx, light, req)?;
        row.light_error.push(reportable(
            relative_l2(&k_img, full, Some(&t.coverage))?,
            || "the light's K terms".to_string(),
        )?);
        let mut times = Vec::new();
        for _ in 0..opts.runs {
            let t0 = Instant::now();
            let terms = Terms::of(t, ctx, light, req)?;
            let (img, _) = Cpu(t).relight_terms(&terms)?;
            let lobe = lobe_light(t, ctx, Some(light), req)?;
            let t1 = Instant::now();
            draw_relit(t, &img, lobe.as_ref(), &frame_cam, None, 1)?;
            times.push([t0, t1, Instant::now()]);
        }
        row.cpu.push(FrameTime {
            relight_ms: median(times.iter().map(|t| ms(t[0], t[1])).collect()),
            draw_ms: median(times.iter().map(|t| ms(t[1], t[2])).collect()),
        });
    }
    if let Some(gpu) = gpu {
        row.gpu = Some(gpu_frames(gpu, t, ctx, light, k_reqs, &frame_cam, opts)?);
    }
    Ok(())
}

fn ms(a: Instant, b: Instant) -> f64 {
    (b - a).as_secs_f64() * 1e3
}

/// A GPU frame at each K: the kernel's own time, then the colours (and a lobe's light) uploaded,
/// drawn and read back.
fn gpu_frames(
    gpu: &Gpu,
    t: &Transport,
    ctx: &LightContext,
    light: &crate::relight::PreparedLight,
    reqs: &[RelightRequest],
    camera: &Camera,
    opts: &GlossBenchOptions,
) -> Result<Vec<FrameTime>> {
    use crate::draw::gpu::raster::{GpuMesh, GpuRaster, upload_colours};
    let resident = crate::relight::gpu::GpuTransport::upload(gpu, t, None)?;
    let backend = crate::relight::gpu::GpuBackend::new(gpu, &resident, t)?;
    let mesh = crate::draw::vertex::mesh_of(t)?;
    let m = GpuMesh::of_bake(gpu, mesh)?;
    let mut raster = GpuRaster::multisampled(gpu, 1)?;
    reqs.iter()
        .map(|req| {
            let terms = Terms::of(t, ctx, light, req)?;
            let mut kernel = Vec::new();
            let mut drawing = Vec::new();
            // One frame first, unmeasured: pipelines and buffers are made on first use.
            for run in 0..=opts.runs {
                let (img, stats) = backend.relight_terms(&terms)?;
                let t0 = Instant::now();
                let pixels = &img.pixels[..mesh.vertex_count().min(img.pixels.len())];
                let c = upload_colours(gpu, pixels)?;
                // A bake with visibility draws its lobe from the request's light, built on the
                // CPU and uploaded with the colours.
                raster.set_light(gpu, lobe_light(t, ctx, Some(light), req)?.as_ref())?;
                raster.draw(gpu, camera, &m, &c)?;
                if run > 0 {
                    kernel.push(stats.kernel_seconds * 1e3);
                    drawing.push(ms(t0, Instant::now()));
                }
            }
            Ok(FrameTime {
                relight_ms: median(kernel),
                draw_ms: median(drawing),
            })
        })
        .collect()
}
