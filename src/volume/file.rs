//! The volume transfer file (`.prtv`): a medium's density grid, its SH self-transfer and the
//! baked view, in a safetensors container (see [`crate::store::container`]) validated before
//! anything is sliced or allocated.

use std::path::Path;

use glam::Vec3;
use safetensors::tensor::Dtype;
use serde::{Deserialize, Serialize};

use crate::error::{PrtError, Result};
use crate::medium::{DensityGrid, Medium};
use crate::store::container::{self, Tensor, check_meta_seal, checksum};
use crate::store::transport::CameraMeta;

use super::scatter::{ScatterFields, ScatterSettings};
use super::{FORMAT_NAME, FORMAT_VERSION, MAX_TRANSFER_ORDER};

/// Metadata of a volume transfer file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumeMeta {
    /// Voxels along x, y and z.
    pub dims: [usize; 3],
    /// Lower corner of the medium's box, scene units.
    pub min: [f32; 3],
    /// Upper corner of the medium's box, scene units.
    pub max: [f32; 3],
    /// sigma_t at density 1, per scene unit of length.
    pub extinction: f32,
    /// Single-scattering albedo per channel.
    pub albedo: [f32; 3],
    /// Henyey–Greenstein asymmetry in (-1, 1); 0 is isotropic.
    pub g: f32,
    /// SH order n of the transfer (n² coefficients per voxel).
    pub sh_order: usize,
    /// Directions D of the projection.
    pub directions: usize,
    /// The scene's camera and image size: the default view of `prt volume render`.
    pub camera: CameraMeta,
    /// Image width of the default view, pixels.
    pub width: u32,
    /// Image height of the default view, pixels.
    pub height: u32,
    /// Hash of the scene the medium came from.
    pub scene_hash: String,
    /// The baked fields of scattering orders 2 and above (absent: single scattering only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scatter: Option<ScatterMeta>,
}

/// How the fields of the higher scattering orders were baked (see [`super::scatter`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScatterMeta {
    /// Scattering orders N the file holds, single scattering included (at least 2).
    pub orders: usize,
    /// SH order of the fields in direction.
    pub angular: usize,
    /// SH order of the light the fields respond to.
    pub light: usize,
    /// Directions of each gather.
    pub directions: usize,
    /// Ratio of each order to the one before, beyond the last, in [0, 1).
    pub tail_ratio: f32,
}

/// The tensors of a volume file (`scatter` only with higher orders).
const TENSOR_NAMES: [&str; 3] = ["density", "transfer", "scatter"];

/// The one metadata entry of a volume file (`meta_checksum` follows in the text, as in a
/// transport file).
#[derive(Serialize, Deserialize)]
struct FileHeader {
    format: String,
    format_version: u32,
    /// Of the tensors in the order of their names: `density`, `scatter` (when present) and
    /// `transfer`.
    checksum: String,
    meta: VolumeMeta,
}

/// Largest volume file: 16 GiB, checked before reading (a 512³ grid at order 8 holds 8.6 GB of
/// transfer; the scattered fields are bounded by the same size).
pub const MAX_VOLUME_BYTES: u64 = 16 << 30;

/// A medium and its SH self-transfer.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeTransfer {
    /// The grid, the medium's optical parameters and the bake's settings.
    pub meta: VolumeMeta,
    /// Densities, x fastest (the grid of [`VolumeTransfer::medium`]).
    pub density: Vec<f32>,
    /// `n²` SH coefficients per voxel, voxel-major.
    pub transfer: Vec<f32>,
    /// The fields of scattering orders 2 and above, when baked.
    pub scatter: Option<ScatterFields>,
}

impl VolumeTransfer {
    /// SH coefficients per voxel, n².
    pub fn sh_count(&self) -> usize {
        self.meta.sh_order * self.meta.sh_order
    }

    /// Number of voxels, `nx · ny · nz`.
    pub fn voxel_count(&self) -> usize {
        self.meta.dims.iter().product()
    }

    /// Scattering orders the file holds, single scattering included.
    pub fn orders(&self) -> usize {
        self.scatter.as_ref().map_or(1, ScatterFields::orders)
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
        let corners = trilinear_corners(&self.meta, p);
        trilinear_at(&corners, &self.transfer, self.sh_count(), out);
    }

    /// Writes the file atomically: safetensors with `density` `[nz, ny, nx]` and `transfer`
    /// `[voxels, n²]` (f32) and, with higher orders, `scatter` `[orders − 1, voxels, angular² ·
    /// light²]` (f16, so a loaded file's fields are the baked ones rounded to half precision),
    /// and one metadata entry `meta` (JSON).
    pub fn save(&self, path: &Path) -> Result<()> {
        let [nx, ny, nz] = self.meta.dims;
        // The scattered fields in half precision: smooth, positive radiance that 11 bits of
        // mantissa hold to 5e-4, at half the bytes.
        let scatter: Vec<u16> = self
            .scatter
            .iter()
            .flat_map(|s| s.fields.iter().flatten())
            .map(|&v| half::f16::from_f32(v).to_bits())
            .collect();
        // In the order of their names, as the checksum takes them.
        let mut tensors = vec![(
            "density",
            Tensor::new(Dtype::F32, vec![nz, ny, nx], &self.density),
        )];
        if let Some(s) = &self.scatter {
            tensors.push((
                "scatter",
                Tensor::new(
                    Dtype::F16,
                    vec![s.fields.len(), self.voxel_count(), s.per_voxel()],
                    &scatter,
                ),
            ));
        }
        tensors.push((
            "transfer",
            Tensor::new(
                Dtype::F32,
                vec![self.voxel_count(), self.sh_count()],
                &self.transfer,
            ),
        ));
        container::save(path, tensors, |checksum| {
            serde_json::to_string(&FileHeader {
                format: FORMAT_NAME.into(),
                format_version: FORMAT_VERSION,
                checksum,
                meta: self.meta.clone(),
            })
        })
    }

    /// Reads and validates a volume transfer file: every field of the metadata (the grid, the
    /// medium, the default view) before the tensors are sized by it.
    pub fn load(path: &Path) -> Result<VolumeTransfer> {
        let bad = |m: String| PrtError::file(path, m);
        let bytes = crate::files::read_regular(path, MAX_VOLUME_BYTES, "volume")?;
        let (header, scatter_tensor) = header_of(path, &bytes)?;
        let m = &header.meta;
        let voxels = m.dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
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
        if let Some(sm) = &m.scatter {
            check_scatter_meta(sm).map_err(bad)?;
        } else if scatter_tensor {
            return Err(bad(
                "tensor `scatter` without its metadata `scatter`: the header was edited".into(),
            ));
        }
        let density = tensor("density", v)?;
        let transfer = tensor("transfer", v * m.sh_order * m.sh_order)?;
        let scatter_bytes: &[u8] = match &m.scatter {
            None => &[],
            Some(sm) => {
                let len = (sm.orders - 1) * v * sm.angular.pow(2) * sm.light.pow(2);
                let t = st
                    .tensor("scatter")
                    .map_err(|_| bad("tensor `scatter` is missing".into()))?;
                if t.dtype() != Dtype::F16 || t.data().len() != len * 2 {
                    return Err(bad(format!(
                        "tensor `scatter`: expected {len} f16 values, got {:?} of {} bytes",
                        t.dtype(),
                        t.data().len()
                    )));
                }
                t.data()
            }
        };
        let scatter: Vec<f32> = scatter_bytes
            .chunks_exact(2)
            .map(|c| half::f16::from_bits(u16::from_le_bytes([c[0], c[1]])).to_f32())
            .collect();
        let mut parts = vec![bytemuck::cast_slice::<f32, u8>(&density)];
        if m.scatter.is_some() {
            parts.push(scatter_bytes);
        }
        parts.push(bytemuck::cast_slice::<f32, u8>(&transfer));
        let sum = checksum(parts);
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
        if let Some(i) = scatter.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!(
                "tensor `scatter`: value {} at {i} is not finite",
                scatter[i]
            )));
        }
        let scatter = m.scatter.as_ref().map(|sm| {
            let per = sm.angular.pow(2) * sm.light.pow(2);
            ScatterFields {
                angular: sm.angular,
                light: sm.light,
                directions: sm.directions,
                tail_ratio: sm.tail_ratio,
                fields: scatter.chunks_exact(v * per).map(<[f32]>::to_vec).collect(),
            }
        });
        let vt = VolumeTransfer {
            meta: header.meta,
            density,
            transfer,
            scatter,
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

/// A volume file's header, read from `bytes` (the file at `path`) and checked: its container,
/// format and version, tensor names, SH order and grid; and whether it holds a `scatter` tensor.
fn header_of(path: &Path, bytes: &[u8]) -> Result<(FileHeader, bool)> {
    let bad = |m: String| PrtError::file(path, m);
    let (_, md) = safetensors::SafeTensors::read_metadata(bytes).map_err(|e| {
        bad(container::what_else(path, container::VOLUME)
            .unwrap_or(format!("not a volume transfer file: {e}")))
    })?;
    let json = md
        .metadata()
        .as_ref()
        .and_then(|m| m.get("meta"))
        .ok_or_else(|| bad("no `meta` entry: not a volume transfer file".into()))?;
    let format = serde_json::from_str::<serde_json::Value>(json)
        .ok()
        .and_then(|v| v.get("format")?.as_str().map(str::to_string));
    if let Some(e) = container::other_format(path, format.as_deref(), container::VOLUME) {
        return Err(e);
    }
    if let Some(entries) = md.metadata() {
        container::check_metadata_entries(entries.keys()).map_err(bad)?;
    }
    check_meta_seal(json).map_err(bad)?;
    let header: FileHeader =
        serde_json::from_str(json).map_err(|e| bad(format!("metadata: {e}")))?;
    container::check_known_keys(json, &header).map_err(bad)?;
    let names = md.tensors();
    if let Some(name) = names.keys().find(|k| !TENSOR_NAMES.contains(&k.as_str())) {
        return Err(bad(format!(
            "unknown tensor `{}`: a volume file holds {}",
            crate::files::printable(name),
            TENSOR_NAMES.join(" and ")
        )));
    }
    if header.format != FORMAT_NAME {
        return Err(bad(format!(
            "format `{}`, expected `{FORMAT_NAME}`",
            header.format
        )));
    }
    // Version 1 files hold single scattering only and read as they are.
    if header.format_version != FORMAT_VERSION && header.format_version != 1 {
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
    Ok((header, names.contains_key("scatter")))
}

/// The eight voxels around `p` in `meta`'s grid and their trilinear weights, between voxel
/// centres and clamped to the edge voxels (weights of 0 included).
pub fn trilinear_corners(meta: &VolumeMeta, p: Vec3) -> [(usize, f32); 8] {
    let d = meta.dims;
    let (min, max) = (Vec3::from(meta.min), Vec3::from(meta.max));
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
    std::array::from_fn(|k| {
        let (z, wz) = if k & 4 == 0 { (z0, 1.0 - fz) } else { (z1, fz) };
        let (y, wy) = if k & 2 == 0 { (y0, 1.0 - fy) } else { (y1, fy) };
        let (x, wx) = if k & 1 == 0 { (x0, 1.0 - fx) } else { (x1, fx) };
        ((z * d[1] + y) * d[0] + x, wx * wy * wz)
    })
}

/// `stride` values per voxel of `data` at the `corners` of a point, into `out`.
pub fn trilinear_at(corners: &[(usize, f32); 8], data: &[f32], stride: usize, out: &mut [f32]) {
    let n = stride;
    out[..n].fill(0.0);
    for &(v, w) in corners {
        if w == 0.0 {
            continue;
        }
        for (o, t) in out.iter_mut().zip(&data[v * n..(v + 1) * n]) {
            *o += w * t;
        }
    }
}

/// Checks the scattered fields' metadata before their tensor is sized by it.
fn check_scatter_meta(sm: &ScatterMeta) -> std::result::Result<(), String> {
    let settings = ScatterSettings {
        orders: sm.orders,
        angular: sm.angular,
        light: sm.light,
        directions: sm.directions,
    };
    settings
        .validate()
        .map_err(|e| format!("metadata `scatter`: {e}"))?;
    if sm.orders < 2 {
        return Err(format!(
            "metadata `scatter`: {} orders; a file with scattered fields holds at least 2",
            sm.orders
        ));
    }
    if !(sm.tail_ratio.is_finite() && (0.0..1.0).contains(&sm.tail_ratio)) {
        return Err(format!(
            "metadata `scatter`: tail ratio {} is outside [0, 1)",
            sm.tail_ratio
        ));
    }
    Ok(())
}

/// Whether `path` is a volume transfer file (by its header, not its name).
pub fn is_volume_file(path: &Path) -> bool {
    container::sniff(path) == Some(container::VOLUME)
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
        let moved = eye.is_some() || target.is_some();
        let (eye, target) = (
            eye.unwrap_or(Vec3::from(c.eye)),
            target.unwrap_or(Vec3::from(c.target)),
        );
        // A moved camera keeps the world's up, as every moved camera does; the baked one its own
        // (looking along it, straight down say, the other horizontal).
        let up = if moved {
            crate::draw::vertex::upright(target - eye, crate::draw::vertex::WORLD_UP)
        } else {
            let up = Vec3::from(c.up);
            if (target - eye).normalize_or_zero().cross(up).length() < 1e-3 {
                Vec3::Z
            } else {
                up
            }
        };
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
