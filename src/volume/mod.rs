//! Volumetric SH self-transfer (Sloan, Kautz & Snyder 2002, section 7): for every voxel of a
//! medium, `T_i(x) = ∫ tau(x, w) Y_i(w) dw`, the transmittance from x out of the medium towards
//! each direction projected onto SH, so that any environment relights the medium by ray marching
//! (`render.rs`, `gpu.rs`) with a free camera.
//!
//! The optical depth towards a direction is not marched per voxel: [`crate::medium::sweep::Sweeper`] sweeps the grid
//! once per direction, slice by slice from the side the light comes from. Each voxel takes the
//! optical depth of the point one slice upstream (bilinear in the previous slice, the same weights
//! for the whole slice) plus the trapezoid of the density over that step. The projection uses D
//! quasi-uniform directions (a Fibonacci sphere) with a control variate: the exact projection of
//! `tau = 1` (`2√π` in band 0) plus the quadrature of `tau − 1`, so empty space is exact.

mod file;
#[cfg(feature = "gpu")]
pub mod gpu;
mod light;
pub mod path_trace;
pub mod render;
pub mod scatter;

use glam::Vec3;
use rayon::prelude::*;

use crate::error::{PrtError, Result};
use crate::medium::sweep::Sweeper;
use crate::medium::{Medium, fibonacci_directions};
use crate::store::transport::CameraMeta;

pub use file::{MAX_VOLUME_BYTES, ScatterMeta, VolumeMeta, VolumeTransfer, is_volume_file};
pub use light::{MediumLook, VolumeLight};
pub use render::{PhaseLight, VolumeView, render_volume};
pub use scatter::{ScatterFields, ScatterSettings};

/// The format name in a volume transfer file's metadata.
pub const FORMAT_NAME: &str = crate::store::container::VOLUME.name;
/// Version of the volume file layout: 2 adds the fields of the higher scattering orders. Files of
/// version 1 (single scattering) are read; any other version is refused.
pub const FORMAT_VERSION: u32 = 2;
/// Highest SH order of a transfer bake.
pub const MAX_TRANSFER_ORDER: usize = 8;

/// Settings of a transfer bake; the defaults are the command line's.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferSettings {
    /// SH order n (n² coefficients per voxel).
    pub sh_order: usize,
    /// Directions D of the projection.
    pub directions: usize,
    /// The higher scattering orders (`orders: 1` bakes single scattering alone).
    pub scatter: ScatterSettings,
}

impl Default for TransferSettings {
    fn default() -> Self {
        TransferSettings {
            sh_order: 3,
            directions: 512,
            scatter: ScatterSettings::default(),
        }
    }
}

impl TransferSettings {
    /// Checks the SH order (1 to [`MAX_TRANSFER_ORDER`]) and the directions (16 to 65536).
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_TRANSFER_ORDER).contains(&self.sh_order) {
            return Err(PrtError::invalid(
                "SH order",
                format!("{} is outside 1 to {MAX_TRANSFER_ORDER}", self.sh_order),
            ));
        }
        if !(16..=65536).contains(&self.directions) {
            return Err(PrtError::invalid(
                "directions",
                format!("{} is outside 16 to 65536", self.directions),
            ));
        }
        self.scatter.validate()
    }
}

/// Bytes a voxel takes at the peak of [`bake_volume`]: its density (4), the transfer (4 n²), a
/// sweeper's three layouts (24) and a batch of eight transmittance grids (32); with higher orders,
/// the stored fields, the current one and the next (4 a² l² each, a² and l² the field's and the
/// light's SH terms), and a batch of eight gathered sources and their results (64 l²). Counted
/// from the buffers, not measured.
fn bake_bytes_per_voxel(settings: &TransferSettings) -> u64 {
    let base = 4 + 4 * settings.sh_order.pow(2) as u64 + 24 + 32;
    let s = &settings.scatter;
    let passes = s.orders.saturating_sub(1) as u64;
    if passes == 0 {
        return base;
    }
    let l2 = s.light.pow(2) as u64;
    base + 4 * s.angular.pow(2) as u64 * l2 * (passes + 2) + 64 * l2
}

/// Bakes the SH self-transfer of `scene`'s medium at its resolution (or `resolution` voxels along
/// the longest side), with the scene's camera as the default view.
pub fn bake_volume(
    scene: &crate::scene::Scene,
    resolution: Option<usize>,
    settings: &TransferSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VolumeTransfer> {
    let spec = scene.medium.as_ref().ok_or_else(|| {
        PrtError::file(
            &scene.source_path,
            "the scene has no [medium] to bake (see docs/guide/media.md)",
        )
    })?;
    let medium = spec.build(resolution)?;
    settings.validate()?;
    let voxels = medium.grid.voxel_count() as u64;
    let per_voxel = bake_bytes_per_voxel(settings);
    crate::files::check_memory(
        "--grid/medium.resolution",
        &format!("the volume bake of {voxels} voxels ({per_voxel} bytes a voxel)"),
        voxels.saturating_mul(per_voxel),
    )?;
    // Progress over both parts, in directions swept.
    let first = settings.directions;
    let total = first + settings.scatter.sweeps();
    let transfer = bake_transfer(&medium, settings, &|done, _| progress(done, total))?;
    let scatter = if settings.scatter.orders > 1 {
        Some(scatter::bake_scatter(
            &medium,
            &settings.scatter,
            &|done, _| progress(first + done, total),
        )?)
    } else {
        None
    };
    let cam = &scene.camera;
    Ok(VolumeTransfer {
        meta: VolumeMeta {
            dims: medium.grid.dims,
            min: medium.grid.min.to_array(),
            max: medium.grid.max.to_array(),
            extinction: medium.extinction,
            albedo: medium.albedo.to_array(),
            g: medium.g,
            sh_order: settings.sh_order,
            directions: settings.directions,
            camera: CameraMeta {
                eye: cam.eye.to_array(),
                target: cam.target.to_array(),
                up: cam.up.to_array(),
                fov_y_deg: cam.fov_y_deg,
            },
            width: cam.width,
            height: cam.height,
            scene_hash: scene.hash_hex(),
            scatter: scatter.as_ref().map(|s| ScatterMeta {
                orders: s.orders(),
                angular: s.angular,
                light: s.light,
                directions: s.directions,
                tail_ratio: s.tail_ratio,
            }),
        },
        density: medium.grid.data,
        transfer,
        scatter,
    })
}

/// Bakes the SH self-transfer of `medium` (see the module docs), calling `progress(done, total)`
/// after each batch of directions.
pub fn bake_transfer(
    medium: &Medium,
    settings: &TransferSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<f32>> {
    settings.validate()?;
    medium.validate()?;
    let order = settings.sh_order;
    let n2 = order * order;
    let voxels = medium.grid.voxel_count();
    let sweeper = Sweeper::new(medium);
    let dirs = fibonacci_directions(settings.directions);
    let weight = 4.0 * std::f64::consts::PI / dirs.len() as f64;
    let what = format!("the transfer of {voxels} voxels at SH order {order}");
    let mut acc = crate::files::try_filled("--grid/medium.resolution", &what, voxels * n2, 0.0f32)?;
    let mut done = 0;
    project_transmittance(
        &sweeper,
        &dirs,
        n2,
        |d| {
            crate::math::sh::eval_vec(order, d.as_dvec3())
                .into_iter()
                .map(|y| (y * weight) as f32)
                .collect()
        },
        &mut acc,
        |n| {
            done += n;
            progress(done, dirs.len());
        },
    );
    // The exact projection of tau = 1.
    let dc = 2.0 * std::f32::consts::PI.sqrt();
    for v in acc.chunks_exact_mut(n2) {
        v[0] += dc;
    }
    Ok(acc)
}

/// Directions grouped by their sweep axis, x then y then z.
pub(crate) fn group_by_axis(dirs: &[Vec3]) -> Vec<(usize, Vec<Vec3>)> {
    (0..3)
        .map(|axis| {
            let group = dirs
                .iter()
                .copied()
                .filter(|d| Sweeper::axis_of(*d) == axis)
                .collect();
            (axis, group)
        })
        .collect()
}

/// Adds `Σ_d (tau(x, d) − 1) · w(d)` over `dirs` to `acc`, `per` values a voxel in global order:
/// one transmittance sweep per direction, grouped by sweep axis, each batch of eight sharing one
/// pass over the accumulator. `weights(d)` gives `w(d)` (`per` values, quadrature weight
/// included); `tick(n)` follows each batch of `n` directions. The projections of the
/// self-transfer and of the scattered fields' order 0 both add the exact projection of `tau = 1`
/// to this.
pub(crate) fn project_transmittance(
    sweeper: &Sweeper,
    dirs: &[Vec3],
    per: usize,
    weights: impl Fn(Vec3) -> Vec<f32>,
    acc: &mut [f32],
    mut tick: impl FnMut(usize),
) {
    const BATCH: usize = 8;
    let voxels = sweeper.voxel_count();
    for (axis, group) in group_by_axis(dirs) {
        let local = sweeper.local_of_global(axis);
        for batch in group.chunks(BATCH) {
            let fields: Vec<Vec<f32>> = batch
                .par_iter()
                .map(|d| {
                    let mut t = vec![0.0f32; voxels];
                    sweeper.sweep(*d, &mut t, |tau| (-tau).exp() - 1.0);
                    t
                })
                .collect();
            let basis: Vec<Vec<f32>> = batch.iter().map(|d| weights(*d)).collect();
            acc.par_chunks_mut(per * 1024)
                .enumerate()
                .for_each(|(chunk, out)| {
                    for (k, coeffs) in out.chunks_exact_mut(per).enumerate() {
                        let l = local[chunk * 1024 + k] as usize;
                        for (field, y) in fields.iter().zip(&basis) {
                            let t = field[l];
                            if t != 0.0 {
                                for (o, yi) in coeffs.iter_mut().zip(y) {
                                    *o += t * yi;
                                }
                            }
                        }
                    }
                });
            tick(batch.len());
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
