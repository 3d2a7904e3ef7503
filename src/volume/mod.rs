//! Volumetric SH self-transfer (Sloan, Kautz & Snyder 2002, section 7): for every voxel of a
//! medium, `T_i(x) = ∫ tau(x, w) Y_i(w) dw`, the transmittance from x out of the medium towards
//! each direction projected onto SH, so that any environment relights the medium by ray marching
//! (`render.rs`, `gpu.rs`) with a free camera.
//!
//! The optical depth towards a direction is not marched per voxel: [`Sweeper`] sweeps the grid
//! once per direction, slice by slice from the side the light comes from. Each voxel takes the
//! optical depth of the point one slice upstream (bilinear in the previous slice, the same weights
//! for the whole slice) plus the trapezoid of the density over that step. The projection uses D
//! quasi-uniform directions (a Fibonacci sphere) with a control variate: the exact projection of
//! `tau = 1` (`2√π` in band 0) plus the quadrature of `tau − 1`, so empty space is exact.

pub mod gpu;
pub mod render;
pub mod wavelet;

use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;
use safetensors::tensor::Dtype;
use serde::{Deserialize, Serialize};

use crate::error::{PrtError, Result};
use crate::medium::{DensityGrid, Medium, fibonacci_directions};
use crate::transport::{CameraMeta, Tensor, check_meta_seal, checksum, seal_meta, write_tensors};

pub use render::{PhaseLight, VolumeView, render_volume};

/// The format name in a volume transfer file's metadata.
pub const FORMAT_NAME: &str = "wavelet-prt volume";
pub const FORMAT_VERSION: u32 = 1;
/// Highest SH order of a transfer bake.
pub const MAX_TRANSFER_ORDER: usize = 8;

/// Settings of a transfer bake; the defaults are the command line's.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferSettings {
    /// SH order n (n² coefficients per voxel).
    pub sh_order: usize,
    /// Directions D of the projection.
    pub directions: usize,
}

impl Default for TransferSettings {
    fn default() -> Self {
        TransferSettings {
            sh_order: 3,
            directions: 512,
        }
    }
}

impl TransferSettings {
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
        Ok(())
    }
}

/// The grid in the layout of one sweep axis `a`: slices along `a`, rows along `b`, `c` fastest.
struct AxisLayout {
    axes: [usize; 3],
    n: [usize; 3],
    /// sigma_t at the voxel centres, in this layout.
    sigma: Vec<f32>,
    /// Local index of every voxel, by global index.
    local_of_global: Vec<u32>,
}

/// Optical depth of a whole grid towards one direction at a time (see the module docs).
pub struct Sweeper {
    dims: [usize; 3],
    cell: Vec3,
    min: Vec3,
    layouts: [AxisLayout; 3],
}

/// Optical depth at voxel centres towards one direction, in the layout of its sweep axis.
pub struct DepthGrid<'a> {
    sweeper: &'a Sweeper,
    axis: usize,
    pub tau: Vec<f32>,
}

impl Sweeper {
    pub fn new(medium: &Medium) -> Sweeper {
        let g = &medium.grid;
        let dims = g.dims;
        let layouts = [0usize, 1, 2].map(|a| {
            let (b, c) = match a {
                0 => (1, 2),
                1 => (0, 2),
                _ => (0, 1),
            };
            let n = [dims[a], dims[b], dims[c]];
            let mut sigma = vec![0.0f32; g.voxel_count()];
            let mut local_of_global = vec![0u32; g.voxel_count()];
            for z in 0..dims[2] {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        let p = [x, y, z];
                        let global = (z * dims[1] + y) * dims[0] + x;
                        let local = (p[a] * n[1] + p[b]) * n[2] + p[c];
                        sigma[local] = medium.extinction * g.data[global];
                        local_of_global[global] = local as u32;
                    }
                }
            }
            AxisLayout {
                axes: [a, b, c],
                n,
                sigma,
                local_of_global,
            }
        });
        Sweeper {
            dims,
            cell: g.cell(),
            min: g.min,
            layouts,
        }
    }

    /// The sweep axis of `dir`: its largest component.
    pub fn axis_of(dir: Vec3) -> usize {
        let a = dir.abs();
        if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        }
    }

    /// Optical depth from every voxel centre out of the medium along `dir` (unit).
    pub fn depth(&self, dir: Vec3) -> DepthGrid<'_> {
        let axis = Self::axis_of(dir);
        let mut tau = vec![0.0f32; self.layouts[axis].sigma.len()];
        self.sweep(dir, &mut tau, |t| t);
        DepthGrid {
            sweeper: self,
            axis,
            tau,
        }
    }

    /// Transmittance `exp(−tau)` from every voxel centre out of the medium along `dir`.
    pub fn transmittance(&self, dir: Vec3) -> DepthGrid<'_> {
        let axis = Self::axis_of(dir);
        let mut tau = vec![0.0f32; self.layouts[axis].sigma.len()];
        self.sweep(dir, &mut tau, |t| (-t).exp());
        DepthGrid {
            sweeper: self,
            axis,
            tau,
        }
    }

    /// Where `p` falls in each axis layout: the base index of its trilinear cell and the
    /// fractions along (a, b, c), clamped to the edge voxels. Locating march samples once makes
    /// every later read of a grid ([`DepthGrid::at_located`]) eight loads and seven lerps.
    pub fn locate(&self, p: Vec3) -> [Located; 3] {
        let u = (p - self.min) / self.cell - 0.5;
        std::array::from_fn(|axis| {
            let layout = &self.layouts[axis];
            let [a, b, c] = layout.axes;
            let [na, nb, nc] = layout.n;
            let coord = |v: f32, n: usize| -> (usize, f32) {
                if n < 2 {
                    return (0, 0.0);
                }
                let v = v.clamp(0.0, (n - 1) as f32);
                let i = (v as usize).min(n - 2);
                (i, v - i as f32)
            };
            let (ia, fa) = coord(u[a], na);
            let (ib, fb) = coord(u[b], nb);
            let (ic, fc) = coord(u[c], nc);
            Located {
                base: ((ia * nb + ib) * nc + ic) as u32,
                frac: [fa, fb, fc],
            }
        })
    }

    /// Sweeps `dir`, writing `f(tau)` per voxel into `out` (the layout of `dir`'s axis).
    fn sweep(&self, dir: Vec3, out: &mut [f32], f: impl Fn(f32) -> f32) {
        let layout = &self.layouts[Self::axis_of(dir)];
        let [a, b, c] = layout.axes;
        let [na, nb, nc] = layout.n;
        let h = self.cell[a] / dir[a].abs();
        // The upstream point's offset in cells along b and c. Very flat voxels (a box far
        // longer than its grid is fine) can put it many grids away: beyond one grid it only
        // reads the empty padding, so it is cut there (and the padding stays small).
        let offset = |o: f32, n: usize| -> (f32, f32) {
            let limit = n as f32 + 1.0;
            if o.abs() <= limit {
                (o.floor(), o - o.floor())
            } else if o > limit {
                (limit, 0.0)
            } else {
                (-limit - 1.0, 0.0)
            }
        };
        let (fb, wb) = offset(h * dir[b] / self.cell[b], nb);
        let (fc, wc) = offset(h * dir[c] / self.cell[c], nc);
        let (ib, ic) = (fb as isize, fc as isize);
        let pad = [ib, ib + 1, ic, ic + 1]
            .iter()
            .map(|v| v.unsigned_abs())
            .max()
            .unwrap_or(1);
        let (pb, pc) = (nb + 2 * pad, nc + 2 * pad);
        let mut up = vec![0.0f32; pb * pc];
        let mut next = vec![0.0f32; pb * pc];
        let hh = 0.5 * h;
        let slices: Box<dyn Iterator<Item = usize>> = if dir[a] > 0.0 {
            Box::new((0..na).rev())
        } else {
            Box::new(0..na)
        };
        for s in slices {
            let sig = &layout.sigma[s * nb * nc..(s + 1) * nb * nc];
            let dst = &mut out[s * nb * nc..(s + 1) * nb * nc];
            for jb in 0..nb {
                let r0 = (jb as isize + pad as isize + ib) as usize;
                let (row0, row1) = (
                    &up[r0 * pc..(r0 + 1) * pc],
                    &up[(r0 + 1) * pc..(r0 + 2) * pc],
                );
                let base = (pad as isize + ic) as usize;
                let next_row = &mut next[(jb + pad) * pc + pad..(jb + pad) * pc + pad + nc];
                for jc in 0..nc {
                    let k = base + jc;
                    let u = (1.0 - wb) * ((1.0 - wc) * row0[k] + wc * row0[k + 1])
                        + wb * ((1.0 - wc) * row1[k] + wc * row1[k + 1]);
                    let sg = hh * sig[jb * nc + jc];
                    let tau = u + sg;
                    next_row[jc] = tau + sg;
                    dst[jb * nc + jc] = f(tau);
                }
            }
            std::mem::swap(&mut up, &mut next);
        }
    }
}

/// A point located in one axis layout (see [`Sweeper::locate`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Located {
    base: u32,
    frac: [f32; 3],
}

impl DepthGrid<'_> {
    /// The grid's value at a point located by [`Sweeper::locate`] (its entry for this grid's
    /// axis), trilinear like [`DepthGrid::at`].
    #[inline]
    pub fn at_located(&self, loc: &[Located; 3]) -> f32 {
        let l = &loc[self.axis];
        let [_, nb, nc] = self.sweeper.layouts[self.axis].n;
        // Steps to the next voxel along a, b and c (0 along a side of one voxel).
        let sa = if self.sweeper.layouts[self.axis].n[0] > 1 {
            nb * nc
        } else {
            0
        };
        let sb = if nb > 1 { nc } else { 0 };
        let sc = usize::from(nc > 1);
        let t = &self.tau;
        let i = l.base as usize;
        let [fa, fb, fc] = l.frac;
        let lerp = |x: f32, y: f32, w: f32| x + (y - x) * w;
        let p00 = lerp(t[i], t[i + sc], fc);
        let p01 = lerp(t[i + sb], t[i + sb + sc], fc);
        let p10 = lerp(t[i + sa], t[i + sa + sc], fc);
        let p11 = lerp(t[i + sa + sb], t[i + sa + sb + sc], fc);
        lerp(lerp(p00, p01, fb), lerp(p10, p11, fb), fa)
    }

    /// Optical depth at `p`, trilinear between voxel centres, clamped to the edge voxels.
    #[inline]
    pub fn at(&self, p: Vec3) -> f32 {
        let s = self.sweeper;
        let layout = &s.layouts[self.axis];
        let u = (p - s.min) / s.cell - 0.5;
        let [a, b, c] = layout.axes;
        let [na, nb, nc] = layout.n;
        let coord = |v: f32, n: usize| -> (usize, usize, f32) {
            let v = v.clamp(0.0, (n - 1) as f32);
            let i = (v as usize).min(n.saturating_sub(2));
            let i1 = (i + 1).min(n - 1);
            (i, i1, v - i as f32)
        };
        let (a0, a1, fa) = coord(u[a], na);
        let (b0, b1, fb) = coord(u[b], nb);
        let (c0, c1, fc) = coord(u[c], nc);
        let t = &self.tau;
        let at = |i: usize, j: usize, k: usize| t[(i * nb + j) * nc + k];
        let lerp = |x: f32, y: f32, w: f32| x + (y - x) * w;
        let p00 = lerp(at(a0, b0, c0), at(a0, b0, c1), fc);
        let p01 = lerp(at(a0, b1, c0), at(a0, b1, c1), fc);
        let p10 = lerp(at(a1, b0, c0), at(a1, b0, c1), fc);
        let p11 = lerp(at(a1, b1, c0), at(a1, b1, c1), fc);
        lerp(lerp(p00, p01, fb), lerp(p10, p11, fb), fa)
    }

    /// Optical depth at voxel `(x, y, z)`.
    pub fn voxel(&self, x: usize, y: usize, z: usize) -> f32 {
        let d = self.sweeper.dims;
        let g = (z * d[1] + y) * d[0] + x;
        self.tau[self.sweeper.layouts[self.axis].local_of_global[g] as usize]
    }
}

/// Metadata of a volume transfer file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumeMeta {
    pub dims: [usize; 3],
    pub min: [f32; 3],
    pub max: [f32; 3],
    pub extinction: f32,
    pub albedo: [f32; 3],
    pub g: f32,
    pub sh_order: usize,
    pub directions: usize,
    /// The scene's camera and image size: the default view of `prt volume render`.
    pub camera: CameraMeta,
    pub width: u32,
    pub height: u32,
    /// Hash of the scene the medium came from.
    pub scene_hash: String,
}

/// The one metadata entry of a volume file (`meta_checksum` follows in the text, as in a
/// transport file).
#[derive(Serialize, Deserialize)]
struct FileHeader {
    format: String,
    format_version: u32,
    /// Of the tensors, `density` then `transfer`.
    checksum: String,
    meta: VolumeMeta,
}

/// Largest volume file: [`crate::medium::MAX_VOXELS`] voxels of density and order-8 transfer,
/// and a header.
pub const MAX_VOLUME_BYTES: u64 =
    crate::medium::MAX_VOXELS as u64 * 4 * (1 + (MAX_TRANSFER_ORDER * MAX_TRANSFER_ORDER) as u64)
        + (16 << 20);

/// A medium and its SH self-transfer.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeTransfer {
    pub meta: VolumeMeta,
    /// Densities, x fastest (the grid of [`VolumeTransfer::medium`]).
    pub density: Vec<f32>,
    /// `n²` SH coefficients per voxel, voxel-major.
    pub transfer: Vec<f32>,
}

impl VolumeTransfer {
    pub fn sh_count(&self) -> usize {
        self.meta.sh_order * self.meta.sh_order
    }

    pub fn voxel_count(&self) -> usize {
        self.meta.dims.iter().product()
    }

    /// The medium the transfer was baked for.
    pub fn medium(&self) -> Medium {
        Medium {
            grid: DensityGrid {
                dims: self.meta.dims,
                min: Vec3::from(self.meta.min),
                max: Vec3::from(self.meta.max),
                data: self.density.clone(),
            },
            extinction: self.meta.extinction,
            albedo: Vec3::from(self.meta.albedo),
            g: self.meta.g,
        }
    }

    /// The transfer vector at `p`, trilinear between voxel centres and clamped to the edge
    /// voxels, into `out` (`n²` values).
    pub fn transfer_at(&self, p: Vec3, out: &mut [f32]) {
        let n = self.sh_count();
        let d = self.meta.dims;
        let (min, max) = (Vec3::from(self.meta.min), Vec3::from(self.meta.max));
        let cell = (max - min) / Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
        let u = (p - min) / cell - 0.5;
        let axis = |v: f32, n: usize| -> (usize, usize, f32) {
            let v = v.clamp(0.0, (n - 1) as f32);
            let i = (v as usize).min(n.saturating_sub(2));
            (i, (i + 1).min(n - 1), v - i as f32)
        };
        let (x0, x1, fx) = axis(u.x, d[0]);
        let (y0, y1, fy) = axis(u.y, d[1]);
        let (z0, z1, fz) = axis(u.z, d[2]);
        out[..n].fill(0.0);
        for (z, wz) in [(z0, 1.0 - fz), (z1, fz)] {
            for (y, wy) in [(y0, 1.0 - fy), (y1, fy)] {
                for (x, wx) in [(x0, 1.0 - fx), (x1, fx)] {
                    let w = wx * wy * wz;
                    if w == 0.0 {
                        continue;
                    }
                    let v = (z * d[1] + y) * d[0] + x;
                    for (o, t) in out.iter_mut().zip(&self.transfer[v * n..(v + 1) * n]) {
                        *o += w * t;
                    }
                }
            }
        }
    }

    /// Writes the file atomically: safetensors with `density` `[nz, ny, nx]` and `transfer`
    /// `[voxels, n²]` (f32), and one metadata entry `meta` (JSON).
    pub fn save(&self, path: &Path) -> Result<()> {
        let [nx, ny, nz] = self.meta.dims;
        let tensors = vec![
            (
                "density",
                Tensor::new(Dtype::F32, vec![nz, ny, nx], &self.density),
            ),
            (
                "transfer",
                Tensor::new(
                    Dtype::F32,
                    vec![self.voxel_count(), self.sh_count()],
                    &self.transfer,
                ),
            ),
        ];
        let sum = checksum(tensors.iter().map(|(_, t)| t.bytes));
        let header = FileHeader {
            format: FORMAT_NAME.into(),
            format_version: FORMAT_VERSION,
            checksum: format!("{sum:016x}"),
            meta: self.meta.clone(),
        };
        let json = serde_json::to_string(&header)
            .map_err(|e| PrtError::file(path, format!("metadata: {e}")))?;
        crate::files::write_atomically(path, |tmp| write_tensors(tmp, tensors, seal_meta(json)))
    }

    /// Reads and validates a volume transfer file: every field of the metadata (the grid, the
    /// medium, the default view) before the tensors are sized by it.
    pub fn load(path: &Path) -> Result<VolumeTransfer> {
        let bad = |m: String| PrtError::file(path, m);
        let bytes = crate::files::read_regular(path, MAX_VOLUME_BYTES, "volume")?;
        let (_, md) = safetensors::SafeTensors::read_metadata(&bytes)
            .map_err(|e| bad(format!("not a volume transfer file: {e}")))?;
        let json = md
            .metadata()
            .as_ref()
            .and_then(|m| m.get("meta"))
            .ok_or_else(|| bad("no `meta` entry: not a volume transfer file".into()))?;
        let format = serde_json::from_str::<serde_json::Value>(json)
            .ok()
            .and_then(|v| v.get("format")?.as_str().map(str::to_string))
            .unwrap_or_default();
        if format == crate::transport::FORMAT_NAME {
            return Err(bad(
                "a transport file (from `prt bake`), not a volume file: relight it with \
                 `prt relight` or `prt view`"
                    .into(),
            ));
        }
        check_meta_seal(json).map_err(bad)?;
        let header: FileHeader =
            serde_json::from_str(json).map_err(|e| bad(format!("metadata: {e}")))?;
        if header.format != FORMAT_NAME {
            return Err(bad(format!(
                "format `{}`, expected `{FORMAT_NAME}`",
                header.format
            )));
        }
        if header.format_version != FORMAT_VERSION {
            return Err(bad(format!(
                "format version {}, this build reads {FORMAT_VERSION}",
                header.format_version
            )));
        }
        let m = &header.meta;
        if !(1..=MAX_TRANSFER_ORDER).contains(&m.sh_order) {
            return Err(bad(format!("SH order {} out of range", m.sh_order)));
        }
        let voxels = m.dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        if voxels.is_none_or(|v| v == 0 || v > crate::medium::MAX_VOXELS) {
            return Err(bad(format!("grid {:?} out of range", m.dims)));
        }
        let st = safetensors::SafeTensors::deserialize(&bytes)
            .map_err(|e| bad(format!("not a valid safetensors file: {e}")))?;
        let tensor = |name: &str, len: usize| -> Result<Vec<f32>> {
            let t = st
                .tensor(name)
                .map_err(|_| bad(format!("tensor `{name}` is missing")))?;
            if t.dtype() != Dtype::F32 || t.data().len() != len * 4 {
                return Err(bad(format!(
                    "tensor `{name}`: expected {len} f32 values, got {:?} of {} bytes",
                    t.dtype(),
                    t.data().len()
                )));
            }
            Ok(t.data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect())
        };
        let v = voxels.unwrap_or(0);
        let density = tensor("density", v)?;
        let transfer = tensor("transfer", v * m.sh_order * m.sh_order)?;
        let sum = checksum([
            bytemuck::cast_slice::<f32, u8>(&density),
            bytemuck::cast_slice::<f32, u8>(&transfer),
        ]);
        if format!("{sum:016x}") != header.checksum {
            return Err(bad("checksum mismatch: the file is damaged".into()));
        }
        if let Some(i) = transfer.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!(
                "tensor `transfer`: value {} of voxel {} is not finite",
                transfer[i],
                i / (m.sh_order * m.sh_order)
            )));
        }
        if !(16..=65536).contains(&m.directions) {
            return Err(bad(format!(
                "metadata: {} directions, outside 16 to 65536",
                m.directions
            )));
        }
        let vt = VolumeTransfer {
            meta: header.meta,
            density,
            transfer,
        };
        vt.medium()
            .validate()
            .map_err(|e| bad(format!("medium: {e}")))?;
        // The default view is what `prt view` and `prt volume render` use unless told otherwise.
        vt.camera(None, None, None)
            .map_err(|e| bad(format!("metadata, the default view: {e}")))?;
        Ok(vt)
    }
}

/// Whether `path` is a volume transfer file (by its header, not its name).
pub fn is_volume_file(path: &Path) -> bool {
    use std::io::Read;
    let Ok((mut f, _)) = crate::files::open_regular(path, u64::MAX, "volume") else {
        return false;
    };
    let mut len = [0u8; 8];
    if f.read_exact(&mut len).is_err() {
        return false;
    }
    let n = u64::from_le_bytes(len).min(1 << 20) as usize;
    let mut header = vec![0u8; n];
    f.read_exact(&mut header).is_ok() && String::from_utf8_lossy(&header).contains(FORMAT_NAME)
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
            "the scene has no [medium] to bake (see the README's volume section)",
        )
    })?;
    let medium = spec.build(resolution)?;
    let transfer = bake_transfer(&medium, settings, progress)?;
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
            scene_hash: format!("{:016x}", scene.content_hash()),
        },
        density: medium.grid.data,
        transfer,
    })
}

impl VolumeTransfer {
    /// The baked view's camera, optionally moved to `eye` looking at `target` and resized.
    pub fn camera(
        &self,
        eye: Option<Vec3>,
        target: Option<Vec3>,
        size: Option<(u32, u32)>,
    ) -> Result<crate::scene::Camera> {
        let c = &self.meta.camera;
        let (width, height) = size.unwrap_or((self.meta.width, self.meta.height));
        let (eye, target) = (
            eye.unwrap_or(Vec3::from(c.eye)),
            target.unwrap_or(Vec3::from(c.target)),
        );
        // Looking along the baked up vector (straight down, say), take the other horizontal.
        let mut up = Vec3::from(c.up);
        if (target - eye).normalize_or_zero().cross(up).length() < 1e-3 {
            up = Vec3::Z;
        }
        let cam = crate::scene::Camera {
            eye,
            target,
            up,
            fov_y_deg: c.fov_y_deg,
            width,
            height,
        };
        cam.validate()?;
        Ok(cam)
    }
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
    let mut acc = vec![0.0f32; voxels * n2];
    // Directions grouped by sweep axis; batches of B share one pass over the accumulator.
    const BATCH: usize = 8;
    let mut done = 0;
    for axis in 0..3 {
        let group: Vec<Vec3> = dirs
            .iter()
            .copied()
            .filter(|d| Sweeper::axis_of(*d) == axis)
            .collect();
        let local = &sweeper.layouts[axis].local_of_global;
        for batch in group.chunks(BATCH) {
            let fields: Vec<Vec<f32>> = batch
                .par_iter()
                .map(|d| {
                    let mut t = vec![0.0f32; voxels];
                    sweeper.sweep(*d, &mut t, |tau| (-tau).exp() - 1.0);
                    t
                })
                .collect();
            let basis: Vec<Vec<f32>> = batch
                .iter()
                .map(|d| {
                    crate::sh::eval_vec(order, d.as_dvec3())
                        .into_iter()
                        .map(|y| (y * weight) as f32)
                        .collect()
                })
                .collect();
            acc.par_chunks_mut(n2 * 1024)
                .enumerate()
                .for_each(|(chunk, out)| {
                    for (k, coeffs) in out.chunks_exact_mut(n2).enumerate() {
                        let g = chunk * 1024 + k;
                        let l = local[g] as usize;
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
            done += batch.len();
            progress(done, dirs.len());
        }
    }
    // The exact projection of tau = 1.
    let dc = 2.0 * std::f32::consts::PI.sqrt();
    for v in acc.chunks_exact_mut(n2) {
        v[0] += dc;
    }
    Ok(acc)
}

#[cfg(test)]
mod tests;
