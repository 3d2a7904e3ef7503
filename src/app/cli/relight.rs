//! `prt relight`, `prt reference` and `prt compare`: images from a transport, from the
//! brute-force reference, and their comparison.

use super::*;
use crate::relight::{Backend, LightMix, Terms};
use strum::{IntoStaticStr, VariantArray};

/// What lights an image and where it goes: `prt relight`'s and `prt reference`'s.
#[derive(Args, Debug)]
pub struct LitImage {
    /// Environment: an .exr/.hdr lat-long map, a bundled map by name (`prt env --list`),
    /// sun:ELEV,AZIM[,RADIUS], or none (the local lights alone).
    #[arg(long)]
    pub env: String,
    /// The local lights (`--light`).
    #[command(flatten)]
    pub lights: LocalLightArgs,
    /// Output image (.exr linear, .png tone-mapped).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Arguments of `prt relight`.
#[derive(Args, Debug)]
pub struct RelightArgs {
    /// Transport file.
    pub file: PathBuf,
    /// The light and the image it makes.
    #[command(flatten)]
    pub lit: LitImage,
    /// wavelet, sh, full or sh-light (SH through the light, at any --sh-order up to 142).
    #[arg(long, default_value = "wavelet", value_parser = Method::from_str)]
    pub method: Method,
    /// Kept wavelet terms K.
    #[arg(long, default_value_t = DEFAULT_TERMS)]
    pub terms: usize,
    /// Wavelet term selection: none, area or transport.
    #[arg(long, default_value = "transport", value_parser = Weighting::from_str)]
    pub weighting: Weighting,
    /// SH order: for sh, at most the baked order (default: the baked order); for sh-light, up
    /// to 142 (n² terms of the light, relit with every stored term).
    #[arg(long)]
    pub sh_order: Option<usize>,
    /// How the environment is turned.
    #[command(flatten)]
    pub turn: TurnArgs,
    /// auto (a hardware GPU when one exists, else the CPU), cpu, or gpu (wgpu on any adapter,
    /// a software one such as Mesa's lavapipe included).
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    pub device: Device,
    /// PNG exposure in stops (default: automatic).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
    /// What pixels that see no geometry show: env (the environment behind the scene, turned
    /// with it) or black.
    #[arg(long, default_value = "env", value_parser = Background::from_str)]
    pub background: Background,
    /// The camera of a per-vertex bake's still.
    #[command(flatten)]
    pub view: StillArgs,
    /// Per-vertex bakes: samples a pixel, 1 (its centre), 4 (the standard 4x rotated grid) or 16
    /// (a 4 × 4 grid, each sample in a column and a row of its own, for stills), each drawn and
    /// depth-tested on its own and the pixel their mean.
    #[arg(long, default_value_t = crate::draw::raster::DRAW_SAMPLES)]
    pub samples: u32,
    /// Per-vertex bakes with visibility: draw the glossy light by SH glossy transfer at this SH
    /// order (1 to 8; Sloan, Kautz & Snyder 2002) instead of the lobe per pixel: the light's
    /// low orders, shadowed per vertex, reflected about the view per pixel.
    #[arg(long)]
    pub sh_transfer: Option<usize>,
}

/// A camera moved from the scene's: a moved camera stays upright, its up being --up, not the
/// scene camera's.
#[derive(Args, Debug, Clone, Copy, Default)]
pub struct MovedCamera {
    /// Camera position X,Y,Z (default: the scene's camera).
    #[arg(long, value_parser = super::volume::parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<glam::Vec3>,
    /// The point the camera looks at, X,Y,Z (default: the scene's target).
    #[arg(long, value_parser = super::volume::parse_vec3, allow_hyphen_values = true)]
    pub target: Option<glam::Vec3>,
    /// The up direction X,Y,Z of a camera moved by --eye or --target (default: the world's +Y;
    /// looking straight along it, -Z).
    #[arg(long, value_parser = super::parse_up, allow_hyphen_values = true)]
    pub up: Option<glam::Vec3>,
}

/// Where a per-vertex bake is seen from (a per-pixel bake's view is fixed).
#[derive(Args, Debug, Clone, Copy, Default)]
pub struct StillArgs {
    /// Per-vertex bakes: where the camera is moved to.
    #[command(flatten)]
    pub moved: MovedCamera,
    /// Per-vertex bakes: image width (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Per-vertex bakes: image height (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
}

impl StillArgs {
    /// The camera of a still of `t` ([`crate::api::Still::camera`]).
    pub fn camera(&self, t: &Transport) -> Result<Option<crate::scene::Camera>> {
        crate::api::Still {
            eye: self.moved.eye,
            target: self.moved.target,
            up: self.moved.up,
            width: self.width,
            height: self.height,
        }
        .camera(t)
    }
}

/// Arguments of `prt reference`.
#[derive(Args, Debug)]
pub struct ReferenceArgs {
    /// Scene file: TOML, or glTF (.gltf, .glb).
    pub scene: PathBuf,
    /// The view: a glTF camera, the image size.
    #[command(flatten)]
    pub framing: FramingArgs,
    /// Where the camera is moved to: the reference of a per-vertex bake drawn with
    /// `prt relight --eye`.
    #[command(flatten)]
    pub moved: MovedCamera,
    /// The light and the image it makes, as `prt relight` takes them.
    #[command(flatten)]
    pub lit: LitImage,
    /// The sampling, as a bake of the scene would take it.
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// How the environment is turned.
    #[command(flatten)]
    pub turn: TurnArgs,
    /// What pixels that see no geometry show: env (the environment behind the scene, turned
    /// with it) or black.
    #[arg(long, default_value = "env", value_parser = Background::from_str)]
    pub background: Background,
    /// How the light is integrated: texels (every texel sample direction at every camera hit,
    /// and with --bounces the bake's own paths: the check of a bake's bookkeeping) or path (an
    /// independent path tracer with light and material sampling). Default: texels without
    /// bounces, path with them.
    #[arg(long, value_parser = Estimator::from_str)]
    pub estimator: Option<Estimator>,
    /// Paths per pixel of the path tracer.
    #[arg(long, default_value_t = 1024)]
    pub samples: u32,
    /// What lights the path tracer: map (the map's own pixels, drawn by importance: the true
    /// lighting) or cube (the bake's cube of --cube texels, to check a bake's bookkeeping).
    /// Default: map for the path tracer; the texels estimator integrates the cube's texels.
    #[arg(long, value_parser = EnvLightKind::from_str)]
    pub env_light: Option<EnvLightKind>,
}

/// How `prt reference` integrates the light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[derive(IntoStaticStr, strum::Display, VariantArray)]
#[strum(serialize_all = "lowercase")]
pub enum Estimator {
    /// Every texel sample direction; with bounces, the bake's own paths and surface cache.
    Texels,
    /// The independent path tracer of `bake::path_tracer`.
    Path,
}

crate::named!(Estimator, "estimator");

/// What lights the path tracer of `prt reference`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[derive(IntoStaticStr, strum::Display, VariantArray)]
#[strum(serialize_all = "lowercase")]
pub enum EnvLightKind {
    /// The map's own pixels: the true lighting.
    Map,
    /// The cube of --cube texels the bake is lit by: a check of the bake's bookkeeping.
    Cube,
}

crate::named!(EnvLightKind, "environment light");

pub(super) fn relight_cmd(a: RelightArgs) -> Result<()> {
    let (method, weighting, background) = (a.method, a.weighting, a.background);
    check_light_flags(a.turn.yaw, a.turn.pitch, a.exposure)?;
    let mut inputs = env_files(std::slice::from_ref(&a.lit.env));
    inputs.push(a.file.clone());
    check_image_output(&a.lit.output, &inputs)?;
    crate::draw::raster::sample_offsets(a.samples)?;
    let gpu = open_device(a.device)?;
    // The header first (the cube's size, its SH order, the lights), then the environment, so that
    // the light is prepared on a second thread while the transport loads (its resampling weights
    // read or recorded, the cube gathered, its Haar and SH coefficients taken): a fresh process
    // then spends on its light, after the load, little more than the selection of terms.
    let header = crate::store::transport::read_header_meta(&a.file)?;
    let mix = a.lit.lights.mix(&header.lights)?;
    let env = optional_env(&a.lit.env, &mix)?;
    let rotation = a.turn.rotation();
    let sizes = (
        header.identity.cube_n as usize,
        header.identity.sh_order as usize,
    );
    // The CPU product's image is made beside the load too, its pages written, when no larger than
    // the file (a header that lies about the size gets no more memory than the file's).
    let (w, h) = (header.width as usize, header.height as usize);
    let image_ahead =
        gpu.is_none() && std::fs::metadata(&a.file).is_ok_and(|m| (w * h * 12) as u64 <= m.len());
    // The time the load then waits for the light counts as the light's.
    let (t, ahead, waited) = std::thread::scope(|s| {
        if image_ahead {
            s.spawn(|| crate::output::film::Image::make_ahead(w, h));
        }
        let ahead = s.spawn(|| {
            let start = Instant::now();
            let ctx = LightContext::with_sizes(sizes.0, sizes.1)
                .map(|c| c.with_lobe(header.identity.visibility));
            let light = match (&ctx, &env) {
                (Ok(ctx), Some(env)) => Some(ctx.prepare(env, rotation)),
                _ => None,
            };
            (ctx, light, start.elapsed())
        });
        let t = Transport::load(&a.file);
        let loaded = Instant::now();
        let ahead = ahead
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (t, ahead, loaded.elapsed())
    });
    let t = t?;
    let still = a.view.camera(&t)?;
    let req = crate::api::request(&t.meta, method, a.terms, weighting, a.sh_order)?;
    note_default_terms(&req, a.terms, t.meta.identity.cube_n);
    let start = Instant::now();
    let (ctx, light, prepared_in) = ahead;
    // The header read first and the file loaded agree on the sizes but for a file replaced in
    // between; the light is then prepared again for the file loaded.
    let stored = (
        t.meta.identity.cube_n as usize,
        t.meta.identity.sh_order as usize,
    );
    let beside = sizes == stored;
    let (ctx, prepared) = match beside {
        true => (ctx?, light.transpose()?),
        false => {
            let ctx = LightContext::new(&t)?;
            let light = env.as_ref().map(|env| ctx.prepare(env, rotation));
            (ctx, light.transpose()?)
        }
    };
    let terms = match &prepared {
        Some(light) => Terms::of(&t, &ctx, light, &req)?,
        None => Terms::dark(),
    };
    let light_ms = (start.elapsed() + waited).as_secs_f64() * 1e3;
    let (img, stats) = match &gpu {
        None => crate::relight::Cpu(&t).relight_lit(&terms, &mix)?,
        Some(gpu) => relight_on_gpu(gpu, &t, &terms, &mix)?,
    };
    img.check_finite("relit image")?;
    // A per-vertex bake's image holds its vertex colours: drawn from the camera asked for.
    let drawing = Instant::now();
    let mut drawn = String::new();
    let (img, coverage) = match &still {
        Some(camera) => {
            let light = crate::relight::lobe_light(&t, &ctx, prepared.as_ref(), &req)?;
            let light = (light.as_ref(), &mix.weights[..]);
            let r = draw_still(&t, &img, light, camera, gpu.as_ref(), &a)?;
            drawn = format!(
                ", drawn {}x{} ({} sample(s) a pixel{}) in {:.1} ms",
                camera.width,
                camera.height,
                a.samples,
                r.1,
                drawing.elapsed().as_secs_f64() * 1e3
            );
            (r.0.image, r.0.coverage)
        }
        None => (img, t.coverage.clone()),
    };
    let tone = match a.exposure {
        Some(e) => ToneMap::exposure(e),
        None => ToneMap::auto(&img, Some(&coverage)),
    };
    let img = match (background, &still, &env) {
        (Background::Black, ..) | (_, _, None) => img,
        (Background::Environment, Some(camera), Some(env)) => crate::draw::background::composite(
            &img,
            &crate::draw::background::environment_behind_camera(camera, &coverage, env, rotation)?,
        ),
        (Background::Environment, None, Some(env)) => crate::draw::background::composite(
            &img,
            &crate::draw::background::environment_behind(&t.meta, &coverage, env, rotation)?,
        ),
    };
    img.save(&a.lit.output, tone)?;
    let lit = match stats.light_columns {
        0 => String::new(),
        n => format!(", {n} light column(s) added"),
    };
    // With the environment off there are no light terms: only the lights' columns are added.
    let summary = match &env {
        None => "environment off (no light terms)".to_string(),
        Some(_) => format!(
            "{method}: {} terms{}, {} nonzeros touched ({:.1} MiB), light {light_ms:.1} ms{}",
            stats.terms,
            request_detail(&req),
            stats.nonzeros_touched,
            stats.bytes_touched as f64 / 1048576.0,
            match beside {
                false => {
                    " (prepared after the load: the file changed after its header was read)".into()
                }
                true => format!(
                    " (prepared beside the load in {:.1} ms, {:.1} ms of it after the file loaded)",
                    prepared_in.as_secs_f64() * 1e3,
                    waited.as_secs_f64() * 1e3
                ),
            },
        ),
    };
    println!(
        "{summary}{lit}, kernel {:.2} ms on the {}{drawn} -> {}",
        stats.kernel_seconds * 1e3,
        match &gpu {
            Some(g) => format!("GPU ({})", g.adapter),
            None => "CPU".to_string(),
        },
        a.lit.output.display()
    );
    Ok(())
}

pub(super) fn reference_cmd(a: ReferenceArgs) -> Result<()> {
    let settings = settings_from(&a.sampling, 1, 0.0, true);
    settings.validate()?;
    let background = a.background;
    check_light_flags(a.turn.yaw, a.turn.pitch, None)?;
    let mut inputs = env_files(std::slice::from_ref(&a.lit.env));
    check_image_output(&a.lit.output, &inputs)?;
    let mut scene = a.framing.load(&a.scene)?;
    let MovedCamera { eye, target, up } = a.moved;
    if eye.is_some() || target.is_some() || up.is_some() {
        let c = &scene.camera;
        let (eye, target) = (eye.unwrap_or(c.eye), target.unwrap_or(c.target));
        scene.camera = crate::draw::vertex::moved_camera(c, eye, target, up);
    }
    scene.camera.validate()?;
    inputs.extend(scene.input_files.iter().cloned());
    check_image_output(&a.lit.output, &inputs)?;
    let mix = a.lit.lights.mix(&scene.lights)?;
    let env = optional_env(&a.lit.env, &mix)?;
    let rotation = a.turn.rotation();
    let cube = match &env {
        Some(env) => env.to_cube(settings.cube_n, rotation)?,
        None => crate::math::cubemap::CubeMap::constant(settings.cube_n, [0.0; 3])?,
    };
    let start = Instant::now();
    let rows = bar(scene.camera.height as u64, "rows");
    let estimator = a.estimator.unwrap_or(if settings.bounces > 0 {
        Estimator::Path
    } else {
        Estimator::Texels
    });
    let env_light = match (estimator, a.env_light) {
        (Estimator::Texels, Some(EnvLightKind::Map)) => {
            return Err(PrtError::invalid(
                "env-light",
                "map: the texels estimator integrates the cube's texels; take --estimator path \
                 to light the scene by the map's own pixels",
            ));
        }
        (Estimator::Texels, _) => EnvLightKind::Cube,
        (Estimator::Path, light) => light.unwrap_or(EnvLightKind::Map),
    };
    let lit = match (&env, env_light) {
        (Some(map), EnvLightKind::Map) => {
            format!("lit by the map's own {}x{} pixels", map.width, map.height)
        }
        _ => format!("lit by the cube, N = {}", settings.cube_n),
    };
    let mut noise = None;
    let r = match estimator {
        Estimator::Texels => crate::bake::reference::render_reference_lit(
            &scene,
            &cube,
            &mix,
            &settings,
            &|done, _| rows.set_position(done as u64),
        )?,
        Estimator::Path => {
            use crate::env::importance::{CubeLight, EnvLight, MapLight};
            let light: Box<dyn EnvLight> = match (&env, env_light) {
                (Some(map), EnvLightKind::Map) => Box::new(MapLight::new(map, rotation)),
                _ => Box::new(CubeLight::new(&cube)),
            };
            let p = crate::bake::path_tracer::path_trace_env(
                &scene,
                light.as_ref(),
                &mix,
                &settings,
                a.samples,
                &|done, _| rows.set_position(done as u64),
            )?;
            noise = Some(p.relative_noise(None));
            crate::bake::reference::Reference {
                image: p.image,
                coverage: p.coverage,
            }
        }
    };
    rows.finish_and_clear();
    r.image.check_finite("reference image")?;
    let tone = ToneMap::auto(&r.image, Some(&r.coverage));
    let img = match (background, &env) {
        (Background::Environment, Some(env)) => crate::draw::background::composite(
            &r.image,
            &crate::draw::background::environment_behind_camera(
                &scene.camera,
                &r.coverage,
                env,
                rotation,
            )?,
        ),
        _ => r.image,
    };
    img.save(&a.lit.output, tone)?;
    println!(
        "reference: {}x{}, {lit}, {:.1} s -> {}",
        img.width,
        img.height,
        start.elapsed().as_secs_f64(),
        a.lit.output.display()
    );
    if let Some(noise) = noise {
        println!(
            "path traced: {} paths per pixel, {} bounces; standard error {:.3}% of the image \
             (relative L2)",
            a.samples,
            settings.bounces,
            100.0 * noise
        );
    }
    Ok(())
}

pub(super) fn compare_cmd(image: PathBuf, reference: PathBuf, mask: Option<PathBuf>) -> Result<()> {
    let a = crate::output::film::Image::load_exr(&image)?;
    let r = crate::output::film::Image::load_exr(&reference)?;
    let mask = match mask {
        Some(p) => Some(Transport::load(&p)?.coverage),
        None => None,
    };
    let e = crate::output::metrics::compare(&a, &r, mask.as_deref()).map_err(|e| match e {
        PrtError::Invalid { what, message } if what == "reference" => {
            PrtError::file(&reference, message)
        }
        e => e,
    })?;
    println!(
        "rel_l2 {:.4}%  rmse {:.6}  psnr {:.2} dB  rel_h1 {:.4}%  dssim {:.6}",
        100.0 * e.rel_l2,
        e.rmse,
        e.psnr_db,
        100.0 * e.rel_h1,
        e.dssim
    );
    Ok(())
}

/// The environment of `--env`, or `None` for `none`, which needs a local light that is on.
fn optional_env(spec: &str, mix: &LightMix) -> Result<Option<EnvMap>> {
    if spec != "none" {
        return load_env(spec).map(Some);
    }
    if mix.is_dark() {
        return Err(PrtError::invalid(
            "--env",
            "none leaves nothing lit: no local light is on (bake a scene with [[light]] tables, \
             or turn one on with --light NAME=1)",
        ));
    }
    Ok(None)
}

/// What the command's line adds about `req`: the weighting of wavelet terms, or the SH light's
/// order.
fn request_detail(req: &RelightRequest) -> String {
    match req {
        RelightRequest::Wavelet { weighting, .. } => format!(" ({weighting} weighting)"),
        RelightRequest::ShLight { order } => {
            format!(" (the light through SH order {order}, relit with every stored Haar term)")
        }
        _ => String::new(),
    }
}

/// Says so where the default K is more than a small cube's terms, and every term is kept.
fn note_default_terms(req: &RelightRequest, asked: usize, cube_n: u32) {
    if let RelightRequest::Wavelet { k, .. } = *req
        && k != asked
    {
        eprintln!(
            "note: the default K = {DEFAULT_TERMS} is more than the {k} terms of N = {cube_n}: \
             every term is kept"
        );
    }
}

/// `terms` and the local lights' `mix` relit on `gpu`, the transport uploaded first (and said).
fn relight_on_gpu(
    gpu: &crate::relight::gpu::Gpu,
    t: &Transport,
    terms: &Terms,
    mix: &LightMix,
) -> Result<(crate::output::film::Image, crate::relight::RelightStats)> {
    let upload = Instant::now();
    let g = crate::relight::gpu::GpuTransport::upload(gpu, t, None)?;
    eprintln!(
        "gpu: {} ({} chunk(s), {} bytes a strip of 8 values, upload {:.0} ms)",
        gpu.adapter,
        g.chunk_count(),
        g.bytes_per_strip(),
        upload.elapsed().as_secs_f64() * 1e3
    );
    crate::relight::gpu::GpuBackend::new(gpu, &g, t)?.relight_lit(terms, mix)
}

/// Draws a per-vertex bake's relit image `img` from `camera`, with `light` (the pyramid a bake
/// with visibility draws its glossy light from, and the local light columns' weights), on `gpu`
/// where it can: with what was drawn beyond the diffuse base, for the command's line.
fn draw_still(
    t: &crate::store::transport::Transport,
    img: &crate::output::film::Image,
    (light, weights): (Option<&crate::math::cube_pyramid::CubePyramid>, &[[f32; 3]]),
    camera: &crate::scene::Camera,
    gpu: Option<&crate::relight::gpu::Gpu>,
    a: &RelightArgs,
) -> Result<(crate::draw::raster::Raster, String)> {
    let mesh = crate::draw::vertex::mesh_of(t)?;
    if let Some(order) = a.sh_transfer {
        let vis = transfer_visibility(t)?;
        // A bake with visibility is relit with the light its glossy light is drawn from.
        let light = light.ok_or_else(|| PrtError::invalid("light", "no light to draw from"))?;
        if gpu.is_some() {
            eprintln!(
                "the GPU raster draws the glossy lobe, not SH glossy transfer: drawn on the CPU"
            );
        }
        let transfer = crate::relight::sh_transfer::ShTransfer::new(vis, order)?;
        let lights = (light, weights);
        let r = crate::draw::vertex::draw_sh_glossy(
            t, img, lights, &transfer, camera, None, a.samples,
        )?;
        return Ok((r, format!(", glossy light by SH transfer at order {order}")));
    }
    let what = match &mesh.visibility {
        Some(_) => ", the glossy lobe per pixel".to_string(),
        None => String::new(),
    };
    let r = match gpu {
        None => {
            let lights = (light, weights);
            crate::draw::vertex::draw_relit_lit(t, img, lights, camera, None, a.samples)?
        }
        Some(gpu) => {
            use crate::draw::gpu::raster::{GpuMesh, GpuRaster, upload_colours};
            // A vertex's colour is its pixel of the relit image.
            let pixels = &img.pixels[..mesh.vertex_count().min(img.pixels.len())];
            let m = GpuMesh::of_bake(gpu, mesh)?;
            let c = upload_colours(gpu, pixels)?;
            let mut raster = GpuRaster::multisampled(gpu, a.samples)?;
            raster.set_light(gpu, light)?;
            raster.set_lights(
                gpu,
                &crate::draw::lobe::lit_columns(&t.meta.lights, weights),
            )?;
            raster.draw(gpu, camera, &m, &c)?
        }
    };
    Ok((r, what))
}
