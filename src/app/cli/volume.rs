//! `prt volume bake`, `prt volume render` and `prt volume reference`: the SH self-transfer of a
//! medium, its ray march, and the volumetric path tracer that holds both.

use super::*;
use crate::volume::ScatterSettings;

/// Arguments of `prt volume bake`.
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
    /// Scattering orders N baked (1: single scattering only); the orders beyond N are
    /// extrapolated at run time.
    #[arg(long, default_value_t = ScatterSettings::default().orders)]
    pub orders: usize,
    /// Directions of each gather of the higher orders.
    #[arg(long, default_value_t = ScatterSettings::default().directions)]
    pub scatter_directions: usize,
    /// SH order of the higher orders' field in direction (1 to 3).
    #[arg(long, default_value_t = ScatterSettings::default().angular)]
    pub scatter_order: usize,
    /// SH order of the light the higher orders respond to (1 to 6).
    #[arg(long, default_value_t = ScatterSettings::default().light)]
    pub scatter_light_order: usize,
}

/// Where a volume is seen from: the scene's camera, moved and resized.
#[derive(Args, Debug)]
pub struct VolumeCameraArgs {
    /// Camera position X,Y,Z (default: the scene's camera).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<glam::Vec3>,
    /// Point the camera looks at, X,Y,Z (default: the scene's target).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<glam::Vec3>,
    /// Image width (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
}

impl VolumeCameraArgs {
    /// The image size asked for, each side defaulting to `width` × `height`; `None` when
    /// neither was given.
    fn size(&self, width: u32, height: u32) -> Option<(u32, u32)> {
        match (self.width, self.height) {
            (None, None) => None,
            (w, h) => Some((w.unwrap_or(width), h.unwrap_or(height))),
        }
    }

    /// Refuses a `camera`-sized `what` ("volume reference") larger than the memory this process
    /// can have, before any work, naming the flags when they set the size.
    fn check_memory(&self, what: &str, camera: &crate::scene::Camera) -> Result<()> {
        let field = match (self.width, self.height) {
            (None, None) => "camera.width/height",
            _ => "--width/--height",
        };
        let (w, h) = (camera.width, camera.height);
        crate::files::check_memory(
            field,
            &format!("a {w} x {h} {what} ({VOLUME_BYTES_PER_PIXEL} bytes a pixel)"),
            w as u64 * h as u64 * VOLUME_BYTES_PER_PIXEL,
        )
    }
}

/// Bytes a pixel of a volume image takes at the peak of `prt volume render`, `reference` and
/// `prt view FILE.prtv --screenshot`: the reference's radiance, standard error and coverage
/// ([`crate::volume::path_trace::TRACE_BYTES_PER_PIXEL`], 28), or the march's image and a GPU's
/// readback (12 + 16), then the automatic exposure's luminances or the PNG's bytes (4 at most).
/// Counted from the buffers, not measured.
pub(super) const VOLUME_BYTES_PER_PIXEL: u64 = 32;

/// Arguments of `prt volume render`.
#[derive(Args, Debug)]
pub struct VolumeRenderArgs {
    /// Volume file (.prtv).
    pub file: PathBuf,
    /// Environment: an .exr/.hdr lat-long map, a bundled map by name (`prt env --list`), or
    /// sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output image (.exr linear, .png tone-mapped).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The camera, moved and resized from the scene's.
    #[command(flatten)]
    pub view_camera: VolumeCameraArgs,
    /// full, inscatter, transmittance or dc (the self-shadow map).
    #[arg(long, default_value = "full", value_parser = VolumeView::from_str)]
    pub view: VolumeView,
    /// SH order to relight with (default: the baked order).
    #[arg(long)]
    pub sh_order: Option<usize>,
    /// Scattering orders to draw, 1 to the file's (default: all it holds, and the tail beyond).
    #[arg(long)]
    pub orders: Option<usize>,
    /// Draw only the baked orders, without the geometric tail of the ones beyond.
    #[arg(long)]
    pub no_tail: bool,
    /// Albedo R,G,B in place of the baked one (order k scales by albedo^k; no new bake).
    #[arg(long, value_parser = parse_vec3)]
    pub albedo: Option<glam::Vec3>,
    /// Henyey–Greenstein g in place of the baked one (exact for single scattering and the last
    /// scattering of higher orders).
    #[arg(long, allow_negative_numbers = true)]
    pub g: Option<f32>,
    /// How the environment is turned.
    #[command(flatten)]
    pub turn: TurnArgs,
    /// Cube face size the environment is resampled to for the light.
    #[arg(long, default_value_t = 32)]
    pub cube: usize,
    /// auto (a hardware GPU when one exists, else the CPU), cpu, or gpu (any adapter, a
    /// software one included).
    #[arg(long, value_enum, default_value_t = Device::Auto)]
    pub device: Device,
    /// Exposure in stops for a .png (default automatic).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
}

/// Arguments of `prt volume reference`.
#[derive(Args, Debug)]
pub struct VolumeReferenceArgs {
    /// Scene file (TOML) with a [medium], or a volume file (.prtv), whose density grid and
    /// default view it takes (none of its transfer).
    pub file: PathBuf,
    /// Environment: an .exr/.hdr lat-long map, a bundled map by name (`prt env --list`), or
    /// sun:ELEV,AZIM[,RADIUS].
    #[arg(long)]
    pub env: String,
    /// Output image (.exr linear, .png tone-mapped).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Paths per pixel.
    #[arg(long, default_value_t = 256)]
    pub samples: u32,
    /// Most scattering events on a path (1 is single scattering; default: every order).
    #[arg(long)]
    pub max_order: Option<u32>,
    /// Voxels along the longest side of a scene's medium (as `prt volume bake --grid`).
    #[arg(long)]
    pub grid: Option<usize>,
    /// Albedo R,G,B in place of the medium's (as the viewer's slider sets it).
    #[arg(long, value_parser = parse_vec3)]
    pub albedo: Option<glam::Vec3>,
    /// The camera, moved and resized from the scene's.
    #[command(flatten)]
    pub view_camera: VolumeCameraArgs,
    /// How the environment is turned.
    #[command(flatten)]
    pub turn: TurnArgs,
    /// Cube face size the environment is resampled to (as `prt volume render`'s light).
    #[arg(long, default_value_t = 32)]
    pub cube: usize,
    /// Seed of the paths.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Exposure in stops for a .png (default automatic).
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f32>,
}

/// Arguments of `prt volume orders`.
#[derive(Args, Debug)]
pub struct VolumeOrdersArgs {
    /// Scene file (TOML) with a [medium]; its camera is the view.
    pub scene: PathBuf,
    /// Environments (each an .exr/.hdr lat-long map, a bundled map by name or
    /// sun:ELEV,AZIM[,RADIUS]); give it once per environment.
    #[arg(long, required = true)]
    pub env: Vec<String>,
    /// Output directory for volume_orders.md.
    #[arg(long)]
    pub out: PathBuf,
    /// Grid sizes, voxels along the longest side.
    #[arg(long, value_delimiter = ',', default_values_t = [32usize, 64, 128])]
    pub grids: Vec<usize>,
    /// Scattering-order counts N to bake at each grid.
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 2, 4, 8])]
    pub orders: Vec<usize>,
    /// Albedos to set at run time, each against the path tracer at that albedo.
    #[arg(long, value_delimiter = ',', default_values_t = [0.5f32, 0.8, 0.99])]
    pub albedos: Vec<f32>,
    /// Paths per pixel of the path-traced references.
    #[arg(long, default_value_t = 8192)]
    pub samples: u32,
    /// Cube face size the environments are resampled to.
    #[arg(long, default_value_t = 32)]
    pub cube: usize,
}

pub(super) fn volume_orders_cmd(a: VolumeOrdersArgs) -> Result<()> {
    use crate::app::studies::volume_orders::{OrdersStudy, run_orders_study};
    crate::math::cubemap::validate_n(a.cube)?;
    let scene = crate::scene::Scene::load(&a.scene)?;
    crate::files::guard_inputs(&scene.input_files);
    let envs = a
        .env
        .iter()
        .map(|e| {
            let name = Path::new(e)
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or(e)
                .to_string();
            Ok((name, load_env(e)?))
        })
        .collect::<Result<Vec<_>>>()?;
    let study = OrdersStudy {
        scene,
        envs,
        grids: a.grids.clone(),
        orders: a.orders.clone(),
        albedos: a.albedos.clone(),
        samples: a.samples,
        cube: a.cube,
    };
    study.validate()?;
    crate::files::check_output_folder(&a.out)?;
    crate::files::check_folder_outputs(&a.out, &["volume_orders.md"])?;
    let report = run_orders_study(&study, &a.out, &mut |line| println!("{line}"))?;
    let path = a.out.join("volume_orders.md");
    crate::files::write_atomically(&path, |mut f| {
        use std::io::Write;
        f.write_all(report.as_bytes())
            .map_err(|e| PrtError::io(&path, e))
    })?;
    println!("{report}");
    println!("wrote {}", path.display());
    Ok(())
}

pub(super) fn parse_vec3(s: &str) -> std::result::Result<glam::Vec3, String> {
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

pub(super) fn volume_bake_cmd(a: VolumeBakeArgs) -> Result<()> {
    use crate::volume::{TransferSettings, bake_volume};
    crate::files::check_output(&a.output, &["prtv"], "a volume file", &[])?;
    let scene = Scene::load(&a.scene)?;
    let inputs: Vec<&std::path::Path> = scene.input_files.iter().map(PathBuf::as_path).collect();
    crate::files::check_output(&a.output, &["prtv"], "a volume file", &inputs)?;
    let settings = TransferSettings {
        sh_order: a.sh_order,
        directions: a.directions,
        scatter: ScatterSettings {
            orders: a.orders,
            angular: a.scatter_order,
            light: a.scatter_light_order,
            directions: a.scatter_directions,
        },
    };
    settings.validate()?;
    let sweeps = settings.directions + settings.scatter.sweeps();
    let bar = ProgressBar::new(sweeps as u64);
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
    let orders = match &vt.meta.scatter {
        Some(s) => format!(
            ", scattering orders 1 to {} (tail ratio {:.3})",
            s.orders, s.tail_ratio
        ),
        None => ", single scattering".into(),
    };
    println!(
        "baked {nx}x{ny}x{nz} voxels x {} directions at SH order {}{orders} in {seconds:.2} s ",
        settings.directions, settings.sh_order,
    );
    println!("wrote {}", a.output.display());
    Ok(())
}

pub(super) fn volume_render_cmd(a: VolumeRenderArgs) -> Result<()> {
    use crate::volume::{MediumLook, VolumeLight, VolumeTransfer, render_volume};
    let view = a.view;
    check_light_flags(a.turn.yaw, a.turn.pitch, a.exposure)?;
    let mut inputs = env_files(std::slice::from_ref(&a.env));
    inputs.push(a.file.clone());
    check_image_output(&a.output, &inputs)?;
    let vt = VolumeTransfer::load(&a.file)?;
    let c = &a.view_camera;
    let camera = vt.camera(c.eye, c.target, c.size(vt.meta.width, vt.meta.height))?;
    c.check_memory("volume image", &camera)?;
    let order = a.sh_order.unwrap_or(vt.meta.sh_order);
    let file_look = MediumLook::of(&vt);
    let look = MediumLook {
        sh_order: order,
        albedo: a.albedo.unwrap_or(file_look.albedo),
        g: a.g.unwrap_or(file_look.g),
        orders: a.orders.unwrap_or(file_look.orders),
        tail: file_look.tail && !a.no_tail,
    };
    look.validate(&vt)?;
    crate::math::cubemap::validate_n(a.cube)?;
    let env = load_env(&a.env)?;
    let start = Instant::now();
    let cube = env.to_cube(a.cube, a.turn.rotation())?;
    let light = VolumeLight::new(&vt, &cube, &look)?;
    let light_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    let (img, device) = match open_device(a.device)? {
        None => (render_volume(&vt, &light, &camera, view), "cpu".to_string()),
        Some(gpu) => {
            let mut gv = crate::volume::gpu::GpuVolume::new(&gpu, &vt)?;
            let (img, _) = gv.render(&gpu, &light, &camera, view)?;
            (img, gpu.adapter.clone())
        }
    };
    let march_ms = start.elapsed().as_secs_f64() * 1e3;
    img.check_finite("volume image")?;
    let tone = match a.exposure {
        Some(e) => ToneMap::exposure(e),
        None => ToneMap::auto(&img, None),
    };
    img.save(&a.output, tone)?;
    let orders = match (look.orders, look.tail) {
        (1, _) => "single scattering".to_string(),
        (n, true) => format!("orders 1 to {n} and the tail"),
        (n, false) => format!("orders 1 to {n}"),
    };
    println!(
        "{}x{} {} view at SH order {order}, {orders}, on {device}: environment to light {light_ms:.0} ms, march {march_ms:.1} ms",
        camera.width,
        camera.height,
        view.name()
    );
    println!("wrote {}", a.output.display());
    Ok(())
}

pub(super) fn volume_reference_cmd(a: VolumeReferenceArgs) -> Result<()> {
    use crate::volume::path_trace::{VolumeTraceSettings, path_trace_volume};
    use crate::volume::{VolumeTransfer, is_volume_file};
    check_light_flags(a.turn.yaw, a.turn.pitch, a.exposure)?;
    let mut inputs = env_files(std::slice::from_ref(&a.env));
    inputs.push(a.file.clone());
    check_image_output(&a.output, &inputs)?;
    let c = &a.view_camera;
    let (mut medium, camera) = if is_volume_file(&a.file) {
        if a.grid.is_some() {
            return Err(PrtError::invalid(
                "--grid",
                "a volume file keeps the grid it was baked on; give the scene to resample",
            ));
        }
        let vt = VolumeTransfer::load(&a.file)?;
        let camera = vt.camera(c.eye, c.target, c.size(vt.meta.width, vt.meta.height))?;
        c.check_memory("volume reference", &camera)?;
        (vt.medium(), camera)
    } else {
        let scene = Scene::load(&a.file)?;
        let spec = scene
            .medium
            .as_ref()
            .ok_or_else(|| PrtError::file(&a.file, "the scene has no [medium] to trace"))?;
        let mut camera = scene.camera.clone();
        if c.eye.is_some() || c.target.is_some() {
            let (eye, target) = (
                c.eye.unwrap_or(camera.eye),
                c.target.unwrap_or(camera.target),
            );
            camera = crate::draw::vertex::moved_camera(&camera, eye, target, None);
        }
        if let Some((w, h)) = c.size(camera.width, camera.height) {
            (camera.width, camera.height) = (w, h);
        }
        camera.validate()?;
        c.check_memory("volume reference", &camera)?;
        (spec.build(a.grid)?, camera)
    };
    if let Some(albedo) = a.albedo {
        medium.albedo = albedo;
    }
    crate::math::cubemap::validate_n(a.cube)?;
    let env = load_env(&a.env)?;
    let cube = env.to_cube(a.cube, a.turn.rotation())?;
    let settings = VolumeTraceSettings {
        samples: a.samples,
        max_order: a.max_order,
        seed: a.seed,
    };
    let start = Instant::now();
    let rows = bar(camera.height as u64, "rows");
    let traced = path_trace_volume(&medium, &cube, &camera, &settings, &|done, _| {
        rows.set_position(done as u64)
    })?;
    rows.finish_and_clear();
    traced.image.check_finite("volume reference image")?;
    let tone = match a.exposure {
        Some(e) => ToneMap::exposure(e),
        None => ToneMap::auto(&traced.image, None),
    };
    traced.image.save(&a.output, tone)?;
    let orders = match a.max_order {
        Some(m) => format!("up to {m} scattering events"),
        None => "every scattering order".into(),
    };
    println!(
        "volume reference: {}x{}, {} paths per pixel, {orders}, {:.1} s; standard error {:.3}% \
         of the image (relative L2)",
        camera.width,
        camera.height,
        a.samples,
        start.elapsed().as_secs_f64(),
        100.0 * traced.relative_noise(None)
    );
    println!("wrote {}", a.output.display());
    Ok(())
}
