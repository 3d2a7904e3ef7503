//! The scattering-order study behind `prt volume orders`: how close the SH march comes to the
//! volumetric path tracer as scattering orders are added, what each order costs to bake and to
//! store at several grid sizes, and how well the run-time albedo holds against a path tracer
//! run at that albedo.

use std::path::Path;
use std::time::Instant;

use glam::Vec3;

use crate::env::envmap::{EnvMap, EnvRotation};
use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;
use crate::output::film::Image;
use crate::output::metrics::relative_l2;
use crate::scene::{Camera, MediumSpec, Scene};
use crate::volume::path_trace::{VolumeTraceSettings, path_trace_volume};
use crate::volume::{
    MediumLook, ScatterSettings, TransferSettings, VolumeLight, VolumeTransfer, VolumeView,
    bake_volume, render_volume,
};

/// What the study sweeps.
#[derive(Clone, Debug)]
pub struct OrdersStudy {
    /// Scene with a `[medium]`, loaded; its camera is the view.
    pub scene: Scene,
    /// Environments, each with its name (a file name or a spec) and map.
    pub envs: Vec<(String, EnvMap)>,
    /// Grid sizes (voxels along the longest side).
    pub grids: Vec<usize>,
    /// Scattering-order counts N baked at each grid.
    pub orders: Vec<usize>,
    /// Albedos the run-time slider is set to, against the path tracer at each.
    pub albedos: Vec<f32>,
    /// Paths per pixel of every reference.
    pub samples: u32,
    /// Cube face size the environments are resampled to (as `prt volume render`'s).
    pub cube: usize,
}

impl OrdersStudy {
    /// Checks, before any work, that there is something to sweep and a medium to sweep it in.
    pub fn validate(&self) -> Result<()> {
        if self.envs.is_empty() || self.grids.is_empty() || self.orders.is_empty() {
            return Err(PrtError::invalid(
                "volume orders",
                "it needs at least one environment, grid and order count",
            ));
        }
        self.medium().map(|_| ())
    }

    /// The scene's medium, or the error that it has none.
    fn medium(&self) -> Result<&MediumSpec> {
        self.scene.medium.as_ref().ok_or_else(|| {
            PrtError::file(
                &self.scene.source_path,
                "the scene has no [medium] to study",
            )
        })
    }
}

/// One bake's figures.
struct BakeRow {
    grid: usize,
    dims: [usize; 3],
    orders: usize,
    seconds: f64,
    bytes: u64,
    tail_ratio: f32,
    /// Per environment: relative L2 against the path tracer, with the tail and without.
    errors: Vec<(f64, f64)>,
}

/// One run-time albedo's figures.
struct AlbedoRow {
    albedo: f32,
    /// Per environment: every order, single scattering, the reference's noise.
    errors: Vec<(f64, f64, f64)>,
}

/// The references of one grid: the path-traced image and its noise, per environment.
struct References {
    images: Vec<(Image, f64)>,
    seconds: f64,
}

fn trace_all(
    study: &OrdersStudy,
    cubes: &[CubeMap],
    medium: &crate::medium::Medium,
    camera: &Camera,
    log: &mut dyn FnMut(&str),
) -> Result<References> {
    let start = Instant::now();
    let mut images = Vec::new();
    for ((name, _), cube) in study.envs.iter().zip(cubes) {
        let traced = path_trace_volume(
            medium,
            cube,
            camera,
            &VolumeTraceSettings {
                samples: study.samples,
                ..Default::default()
            },
            &|_, _| {},
        )?;
        let noise = traced.relative_noise(None);
        log(&format!(
            "  path traced under {name}: {} paths per pixel, noise {:.2}%",
            study.samples,
            100.0 * noise
        ));
        images.push((traced.image, noise));
    }
    Ok(References {
        images,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The relative L2 of `vt` relit by `light` from its own camera against `reference`.
fn error(vt: &VolumeTransfer, light: &VolumeLight, reference: &Image) -> Result<f64> {
    let camera = vt.camera(None, None, None)?;
    relative_l2(
        &render_volume(vt, light, &camera, VolumeView::Full),
        reference,
        None,
    )
}

/// Runs the study, writing its bakes into `scratch` (each removed once measured) and calling
/// `log` as it goes; returns the markdown report.
pub fn run_orders_study(
    study: &OrdersStudy,
    scratch: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    study.validate()?;
    let scene = &study.scene;
    let spec = study.medium()?;
    // Each environment resampled once, for the references and every march alike.
    let cubes = study
        .envs
        .iter()
        .map(|(_, env)| env.to_cube(study.cube, EnvRotation::default()))
        .collect::<Result<Vec<CubeMap>>>()?;
    let mut bakes = Vec::new();
    let mut reference_seconds = Vec::new();
    for &grid in &study.grids {
        let medium = spec.build(Some(grid))?;
        log(&format!("grid {grid}: {:?} voxels", medium.grid.dims));
        let refs = trace_all(study, &cubes, &medium, &scene.camera, log)?;
        reference_seconds.push((grid, refs.seconds));
        for &orders in &study.orders {
            let settings = TransferSettings {
                scatter: ScatterSettings {
                    orders,
                    ..ScatterSettings::default()
                },
                ..TransferSettings::default()
            };
            let start = Instant::now();
            let vt = bake_volume(scene, Some(grid), &settings, &|_, _| {})?;
            let seconds = start.elapsed().as_secs_f64();
            let path = scratch.join(format!("orders_g{grid}_n{orders}.prtv"));
            vt.save(&path)?;
            let bytes = crate::files::file_len(&path)?;
            std::fs::remove_file(&path).map_err(|e| PrtError::io(&path, e))?;
            let mut errors = Vec::new();
            for (cube, (reference, _)) in cubes.iter().zip(&refs.images) {
                let look = MediumLook::of(&vt);
                let light = VolumeLight::new(&vt, cube, &look)?;
                let with = error(&vt, &light, reference)?;
                let without = if orders > 1 {
                    let bare = MediumLook {
                        tail: false,
                        ..look
                    };
                    error(&vt, &light.with_look(&vt, cube, &bare)?, reference)?
                } else {
                    with
                };
                errors.push((with, without));
            }
            log(&format!(
                "  {orders} orders: baked in {seconds:.1} s, {:.1} MiB, errors {}",
                bytes as f64 / (1 << 20) as f64,
                errors
                    .iter()
                    .map(|(w, _)| format!("{:.2}%", 100.0 * w))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            bakes.push(BakeRow {
                grid,
                dims: vt.meta.dims,
                orders,
                seconds,
                bytes,
                tail_ratio: vt.meta.scatter.as_ref().map_or(0.0, |s| s.tail_ratio),
                errors,
            });
        }
    }
    // The albedo slider, on the scene's own grid and the default bake.
    let medium = spec.build(None)?;
    let vt = bake_volume(scene, None, &TransferSettings::default(), &|_, _| {})?;
    let mut albedos = Vec::new();
    for &a in &study.albedos {
        let albedo = Vec3::splat(a);
        log(&format!("albedo {a}"));
        let refs = trace_all(
            study,
            &cubes,
            &crate::medium::Medium {
                albedo,
                ..medium.clone()
            },
            &scene.camera,
            log,
        )?;
        let mut errors = Vec::new();
        for (cube, (reference, noise)) in cubes.iter().zip(&refs.images) {
            let look = MediumLook {
                albedo,
                ..MediumLook::of(&vt)
            };
            let light = VolumeLight::new(&vt, cube, &look)?;
            let every = error(&vt, &light, reference)?;
            let once = MediumLook { orders: 1, ..look };
            let single = error(&vt, &light.with_look(&vt, cube, &once)?, reference)?;
            errors.push((every, single, *noise));
        }
        albedos.push(AlbedoRow { albedo: a, errors });
    }
    Ok(report(
        study,
        scene,
        &vt,
        &bakes,
        &albedos,
        &reference_seconds,
    ))
}

fn report(
    study: &OrdersStudy,
    scene: &Scene,
    vt: &VolumeTransfer,
    bakes: &[BakeRow],
    albedos: &[AlbedoRow],
    reference_seconds: &[(usize, f64)],
) -> String {
    let names: Vec<&str> = study.envs.iter().map(|(n, _)| n.as_str()).collect();
    let defaults = ScatterSettings::default();
    let mut s = format!(
        "Medium of `{}` (extinction {}, albedo {:?}, g {}), seen from its camera ({}x{}), lit by \
         {} (cube {}x{}x{}). Each bake is SH order {} single scattering with N − 1 scattered \
         fields (SH {} in direction, light SH {}, {} directions per gather); the march draws \
         orders 1 to N and the geometric tail of the rest. Errors are relative L2 against the \
         volumetric path tracer on the same grid ({} paths per pixel, every order).\n\n",
        scene.source_path.display(),
        vt.meta.extinction,
        vt.meta.albedo,
        vt.meta.g,
        scene.camera.width,
        scene.camera.height,
        names.join(" and "),
        6,
        study.cube,
        study.cube,
        TransferSettings::default().sh_order,
        defaults.angular,
        defaults.light,
        defaults.directions,
        study.samples,
    );
    s.push_str("| grid | voxels | orders N | bake (s) | file (MiB) | tail ratio |");
    for n in &names {
        s.push_str(&format!(" {n}: with tail | without |"));
    }
    s.push_str("\n|---:|---|---:|---:|---:|---:|");
    for _ in &names {
        s.push_str("---:|---:|");
    }
    s.push('\n');
    for b in bakes {
        s.push_str(&format!(
            "| {} | {}x{}x{} | {} | {:.2} | {:.1} | {:.3} |",
            b.grid,
            b.dims[0],
            b.dims[1],
            b.dims[2],
            b.orders,
            b.seconds,
            b.bytes as f64 / (1 << 20) as f64,
            b.tail_ratio
        ));
        for (with, without) in &b.errors {
            if b.orders > 1 {
                s.push_str(&format!(
                    " {:.2}% | {:.2}% |",
                    100.0 * with,
                    100.0 * without
                ));
            } else {
                s.push_str(&format!(" {:.2}% | |", 100.0 * with));
            }
        }
        s.push('\n');
    }
    s.push_str("\nPath-traced references per grid (all environments): ");
    s.push_str(
        &reference_seconds
            .iter()
            .map(|(g, t)| format!("grid {g} {t:.0} s"))
            .collect::<Vec<_>>()
            .join(", "),
    );
    s.push_str(&format!(
        ".\n\nThe albedo set at run time on the default bake (grid {:?}, baked at albedo {:?}), \
         against the path tracer run at that albedo:\n\n| albedo |",
        vt.meta.dims, vt.meta.albedo
    ));
    for n in &names {
        s.push_str(&format!(
            " {n}: every order | single scattering | reference noise |"
        ));
    }
    s.push_str("\n|---:|");
    for _ in &names {
        s.push_str("---:|---:|---:|");
    }
    s.push('\n');
    for a in albedos {
        s.push_str(&format!("| {} |", a.albedo));
        for (every, single, noise) in &a.errors {
            s.push_str(&format!(
                " {:.2}% | {:.2}% | {:.2}% |",
                100.0 * every,
                100.0 * single,
                100.0 * noise
            ));
        }
        s.push('\n');
    }
    s
}
