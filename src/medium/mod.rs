//! Participating media: a density grid over an axis-aligned box (procedural ellipsoid, noise
//! cloud, or a NumPy `.npy` file), its extinction scale, single-scattering albedo and
//! Henyey–Greenstein phase, and the two marches every volume path shares: optical depth along a
//! ray (shadow rays) and the single-scattering samples of a camera ray.
//!
//! Density is stored at voxel centres and is trilinear between them, falling to zero half a
//! voxel outside the box (the lattice is padded with zeros). `sigma_t(x) = extinction · density(x)`
//! and `sigma_s = albedo · sigma_t` (see [`crate::conventions`], volumes).

pub mod sweep;
pub mod tracking;

use std::f32::consts::PI;
use std::path::Path;

use glam::Vec3;

use crate::error::{PrtError, Result};

/// Most voxels a grid may hold (a 512³ grid), checked before allocating.
pub const MAX_VOXELS: usize = 512 * 512 * 512;

/// Most optical depth the densest voxel may have across its shortest edge
/// (`extinction · density · edge`). Such a voxel passes e^-100 ≈ 4e-44 of the light, below the
/// smallest normal f32 (1.2e-38): as opaque as the marches' arithmetic can hold, so more
/// extinction would only move where light scatters within the first hundredth of a voxel, which
/// the grid does not resolve. It also bounds delta and ratio tracking
/// ([`tracking::Tracker`]), which take `extinction · densest · length` tentative steps along a
/// ray: at most 100 a voxel crossed, ~89,000 across a 512³ grid's diagonal (an extinction of
/// 1e8 in a 24-voxel fog would take 1e8 a unit, each step below f32's resolution of the distance).
pub const MAX_VOXEL_DEPTH: f32 = 100.0;

/// Voxels along each axis of a box of `extent` with `resolution` voxels along its longest side:
/// the others in proportion (cubic voxels), at least 1.
pub fn grid_dims(extent: Vec3, resolution: usize) -> [usize; 3] {
    let longest = extent.max_element();
    extent
        .to_array()
        .map(|e| ((e / longest * resolution as f32).round() as usize).max(1))
}

/// The shortest voxel edge of a box of `extent` with `resolution` voxels along its longest side
/// ([`grid_dims`]).
pub fn voxel_edge(extent: Vec3, resolution: usize) -> f32 {
    let dims = grid_dims(extent, resolution);
    (extent / Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32)).min_element()
}

/// What is wrong with `extinction` when a voxel of density `densest` whose shortest edge is
/// `edge` is deeper than [`MAX_VOXEL_DEPTH`] across it; `None` when it is not.
pub fn voxel_depth_problem(extinction: f32, densest: f32, edge: f32) -> Option<String> {
    let per_extinction = densest as f64 * edge as f64;
    let depth = extinction as f64 * per_extinction;
    (depth > MAX_VOXEL_DEPTH as f64).then(|| {
        format!(
            "{extinction} gives a voxel of density {densest} an optical depth of {depth:.3e} \
             across its shortest edge ({edge:.3e} units), above {MAX_VOXEL_DEPTH}: nothing \
             crosses such a voxel, and tracking a path through it takes ever more steps; use \
             at most {:.4e} on this grid (or a finer grid)",
            MAX_VOXEL_DEPTH as f64 / per_extinction
        )
    })
}

/// Densities at voxel centres over the box `[min, max]`, x fastest: index `(z·ny + y)·nx + x`.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityGrid {
    /// Voxels along x, y and z.
    pub dims: [usize; 3],
    /// Lower corner of the box, scene units.
    pub min: Vec3,
    /// Upper corner of the box, scene units.
    pub max: Vec3,
    /// Density at each voxel centre, `dims[0] · dims[1] · dims[2]` values, x fastest.
    pub data: Vec<f32>,
}

impl DensityGrid {
    /// A grid of `dims` voxels over `[min, max]` with the density `f` at each voxel centre.
    pub fn from_fn(dims: [usize; 3], min: Vec3, max: Vec3, f: impl Fn(Vec3) -> f32) -> Self {
        let cell = (max - min) / Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32);
        let mut data = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let p = min + cell * (Vec3::new(x as f32, y as f32, z as f32) + 0.5);
                    data.push(f(p));
                }
            }
        }
        DensityGrid {
            dims,
            min,
            max,
            data,
        }
    }

    /// Edge lengths of one voxel.
    pub fn cell(&self) -> Vec3 {
        (self.max - self.min)
            / Vec3::new(
                self.dims[0] as f32,
                self.dims[1] as f32,
                self.dims[2] as f32,
            )
    }

    /// Number of voxels, `nx · ny · nz`.
    pub fn voxel_count(&self) -> usize {
        self.dims.iter().product()
    }

    /// The largest density (0 for an empty grid).
    pub fn densest(&self) -> f32 {
        self.data.iter().copied().fold(0.0, f32::max)
    }

    #[inline]
    fn at(&self, x: isize, y: isize, z: isize) -> f32 {
        let [nx, ny, nz] = self.dims.map(|d| d as isize);
        if x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz {
            return 0.0;
        }
        self.data[((z * ny + y) * nx + x) as usize]
    }

    /// Trilinear density at `p` (zero half a voxel outside the box and beyond).
    #[inline]
    pub fn density(&self, p: Vec3) -> f32 {
        let u = (p - self.min) / self.cell() - 0.5;
        let i = Vec3::new(floor(u.x), floor(u.y), floor(u.z));
        let f = u - i;
        let (x, y, z) = (i.x as isize, i.y as isize, i.z as isize);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let [nx, ny, nz] = self.dims.map(|d| d as isize);
        if x >= 0 && y >= 0 && z >= 0 && x + 1 < nx && y + 1 < ny && z + 1 < nz {
            // All eight corners inside: straight loads (most samples of a march).
            let (sy, sz) = (nx as usize, (nx * ny) as usize);
            let b = (z as usize * ny as usize + y as usize) * nx as usize + x as usize;
            let d = &self.data;
            let c00 = lerp(d[b], d[b + 1], f.x);
            let c10 = lerp(d[b + sy], d[b + sy + 1], f.x);
            let c01 = lerp(d[b + sz], d[b + sz + 1], f.x);
            let c11 = lerp(d[b + sz + sy], d[b + sz + sy + 1], f.x);
            return lerp(lerp(c00, c10, f.y), lerp(c01, c11, f.y), f.z);
        }
        let c00 = lerp(self.at(x, y, z), self.at(x + 1, y, z), f.x);
        let c10 = lerp(self.at(x, y + 1, z), self.at(x + 1, y + 1, z), f.x);
        let c01 = lerp(self.at(x, y, z + 1), self.at(x + 1, y, z + 1), f.x);
        let c11 = lerp(self.at(x, y + 1, z + 1), self.at(x + 1, y + 1, z + 1), f.x);
        lerp(lerp(c00, c10, f.y), lerp(c01, c11, f.y), f.z)
    }

    /// The box where the density can be non-zero: the grid box grown by half a voxel.
    pub fn support(&self) -> (Vec3, Vec3) {
        let h = self.cell() * 0.5;
        (self.min - h, self.max + h)
    }

    /// Checks the grid: sizes, finite non-negative densities (naming the first bad voxel).
    pub fn validate(&self, what: &str) -> Result<()> {
        let n = self.voxel_count();
        if self.dims.contains(&0) || n > MAX_VOXELS {
            return Err(PrtError::invalid(
                what,
                format!(
                    "grid of {:?} voxels: each side must be at least 1 and the total at most {MAX_VOXELS}",
                    self.dims
                ),
            ));
        }
        if self.data.len() != n {
            return Err(PrtError::invalid(
                what,
                format!("{} densities for {n} voxels", self.data.len()),
            ));
        }
        if !(self.min.is_finite() && self.max.is_finite() && self.min.cmplt(self.max).all()) {
            return Err(PrtError::invalid(
                what,
                format!(
                    "bounds {} to {}: need finite min < max on every axis",
                    self.min, self.max
                ),
            ));
        }
        if let Some(i) = self.data.iter().position(|d| !(d.is_finite() && *d >= 0.0)) {
            let [nx, ny, _] = self.dims;
            return Err(PrtError::invalid(
                what,
                format!(
                    "density {} at voxel (x {}, y {}, z {}): densities must be finite and >= 0",
                    self.data[i],
                    i % nx,
                    (i / nx) % ny,
                    i / (nx * ny)
                ),
            ));
        }
        Ok(())
    }
}

/// `x.floor()` for |x| < 2³¹ without a library call (the baseline x86-64 target has no rounding
/// instruction, and the marches floor every sample).
#[inline]
pub fn floor(x: f32) -> f32 {
    let t = x as i32 as f32;
    if t > x { t - 1.0 } else { t }
}

/// A participating medium.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    /// Density over the medium's box.
    pub grid: DensityGrid,
    /// sigma_t at density 1, per unit length.
    pub extinction: f32,
    /// Single-scattering albedo per channel.
    pub albedo: Vec3,
    /// Henyey–Greenstein asymmetry in (-1, 1); 0 is isotropic.
    pub g: f32,
}

/// Ray parameters `[t0, t1]` where the ray `o + t d` is inside the box, if it meets it.
#[inline]
pub fn ray_box(o: Vec3, d: Vec3, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
    // A zero component gets a huge finite inverse (the GPU march does the same).
    let safe = |c: f32| {
        if c.abs() < 1e-30 {
            1e30f32.copysign(c)
        } else {
            1.0 / c
        }
    };
    let inv = Vec3::new(safe(d.x), safe(d.y), safe(d.z));
    let (a, b) = ((min - o) * inv, (max - o) * inv);
    let (lo, hi) = (a.min(b), a.max(b));
    let t0 = lo.max_element();
    let t1 = hi.min_element();
    (t1 >= t0.max(0.0) && t0.is_finite() && t1.is_finite()).then_some((t0.max(0.0), t1))
}

/// One sample of a camera ray's march: where it is, and `T · sigma_t · dt` there (the camera-ray
/// transmittance to the sample's midpoint times its extinction and length); the in-scattered
/// radiance it brings is `albedo · weight · ∫ p L tau`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarchSample {
    /// Position of the sample (the midpoint of its step), scene units.
    pub pos: Vec3,
    /// `T · sigma_t · dt`: the camera-ray transmittance to the sample's midpoint times its
    /// extinction and step length.
    pub weight: f32,
    /// `sigma_t · dt` alone (no camera-ray transmittance).
    pub sigma_dt: f32,
}

/// The Henyey–Greenstein phase function at the cosine of the scattering angle.
#[inline]
pub fn henyey_greenstein(g: f32, cos_theta: f32) -> f32 {
    let denom = 1.0 + g * g - 2.0 * g * cos_theta;
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

/// Checks a single-scattering albedo, `what` naming it: each channel in [0, 1].
pub fn check_albedo(what: &str, albedo: Vec3) -> Result<()> {
    if albedo.is_finite() && albedo.cmpge(Vec3::ZERO).all() && albedo.cmple(Vec3::ONE).all() {
        return Ok(());
    }
    Err(PrtError::invalid(
        what,
        format!("each channel must be in [0, 1], got {albedo}"),
    ))
}

/// Checks a Henyey–Greenstein asymmetry, `what` naming it: in (−1, 1).
pub fn check_g(what: &str, g: f32) -> Result<()> {
    if g.is_finite() && g.abs() < 1.0 {
        return Ok(());
    }
    Err(PrtError::invalid(
        what,
        format!("must be in (-1, 1), got {g}"),
    ))
}

/// `count` quasi-uniform unit directions (a Fibonacci sphere).
pub fn fibonacci_directions(count: usize) -> Vec<Vec3> {
    let golden = PI * (3.0 - 5f32.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f32 + 1.0) / count as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), z, r * phi.sin())
        })
        .collect()
}

impl Medium {
    /// Checks the parameters and the grid.
    pub fn validate(&self) -> Result<()> {
        self.grid.validate("medium")?;
        if !(self.extinction.is_finite() && self.extinction >= 0.0) {
            return Err(PrtError::invalid(
                "medium.extinction",
                format!("must be finite and >= 0, got {}", self.extinction),
            ));
        }
        let edge = self.grid.cell().min_element();
        if let Some(problem) = voxel_depth_problem(self.extinction, self.grid.densest(), edge) {
            return Err(PrtError::invalid("medium.extinction", problem));
        }
        check_albedo("medium.albedo", self.albedo)?;
        check_g("medium.g", self.g)
    }

    /// sigma_t at `p`.
    #[inline]
    pub fn sigma_t(&self, p: Vec3) -> f32 {
        self.extinction * self.grid.density(p)
    }

    /// March step of shadow rays: one voxel (the smallest edge).
    pub fn shadow_step(&self) -> f32 {
        self.grid.cell().min_element()
    }

    /// March step of camera rays: half a voxel.
    pub fn camera_step(&self) -> f32 {
        0.5 * self.grid.cell().min_element()
    }

    /// Optical depth along `o + t d` for `t` in `[0, t_max]` (midpoint rule, one-voxel steps).
    pub fn optical_depth(&self, o: Vec3, d: Vec3, t_max: f32) -> f32 {
        let Some((t0, steps, dt)) = self.steps_along(o, d, t_max, self.shadow_step()) else {
            return 0.0;
        };
        (0..steps)
            .map(|i| self.sigma_t(o + d * (t0 + (i as f32 + 0.5) * dt)))
            .sum::<f32>()
            * dt
    }

    /// The part of the ray `o + t d`, `t` in `[0, t_max]`, inside the grid's support, cut into
    /// equal steps no longer than `step`: where it starts, the steps and their length. `None`
    /// where the ray misses it.
    fn steps_along(&self, o: Vec3, d: Vec3, t_max: f32, step: f32) -> Option<(f32, usize, f32)> {
        let (lo, hi) = self.grid.support();
        let (t0, t1) = ray_box(o, d, lo, hi)?;
        let t1 = t1.min(t_max);
        if t1 <= t0 {
            return None;
        }
        let steps = ((t1 - t0) / step).ceil().max(1.0) as usize;
        Some((t0, steps, (t1 - t0) / steps as f32))
    }

    /// Transmittance along `o + t d` for `t` in `[0, t_max]`.
    pub fn transmittance(&self, o: Vec3, d: Vec3, t_max: f32) -> f32 {
        (-self.optical_depth(o, d, t_max)).exp()
    }

    /// The single-scattering samples of the camera ray `o + t d`, `t` in `[0, t_max]`, in
    /// half-voxel steps, stopping once the transmittance falls below 1e-4. Returns the samples
    /// and the transmittance left at `t_max` (or where the march stopped).
    pub fn march_camera(&self, o: Vec3, d: Vec3, t_max: f32, out: &mut Vec<MarchSample>) -> f32 {
        self.march_camera_with(o, d, t_max, true, out)
    }

    /// [`Medium::march_camera`], optionally without stopping early (for views that ignore the
    /// camera ray's attenuation).
    pub fn march_camera_with(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        early_exit: bool,
        out: &mut Vec<MarchSample>,
    ) -> f32 {
        out.clear();
        let Some((t0, steps, dt)) = self.steps_along(o, d, t_max, self.camera_step()) else {
            return 1.0;
        };
        let mut transmittance = 1.0f32;
        for i in 0..steps {
            let pos = o + d * (t0 + (i as f32 + 0.5) * dt);
            let sigma = self.sigma_t(pos);
            if sigma <= 0.0 {
                continue;
            }
            let half = (-0.5 * sigma * dt).exp();
            out.push(MarchSample {
                pos,
                weight: transmittance * half * sigma * dt,
                sigma_dt: sigma * dt,
            });
            transmittance *= half * half;
            if early_exit && transmittance < 1e-4 {
                return 0.0;
            }
        }
        transmittance
    }
}

/// Where a medium's densities come from.
#[derive(Clone, Debug, PartialEq)]
pub enum DensitySource {
    /// Density 1 inside the ellipsoid's inner part `r <= 1 - falloff` (r the ellipsoidal
    /// radius), then `exp(-4 (r - (1 - falloff)) / falloff)` (1/e⁴ at the surface); a falloff of 0
    /// is a hard edge.
    Ellipsoid {
        /// Centre of the ellipsoid, scene units.
        center: Vec3,
        /// Semi-axes of the ellipsoid along x, y and z, scene units.
        radii: Vec3,
        /// Share of the ellipsoidal radius over which the density falls off at the edge, in [0, 1);
        /// 0 is a hard edge.
        falloff: f32,
    },
    /// Fractal value noise inside an ellipsoid envelope (falloff 0.5): `coverage` in (0, 1] is
    /// the fraction of the noise range that holds cloud.
    Cloud {
        /// Centre of the envelope, scene units.
        center: Vec3,
        /// Semi-axes of the envelope along x, y and z, scene units.
        radii: Vec3,
        /// Seed of the noise lattice.
        seed: u64,
        /// Noise cells per scene unit of the first octave.
        frequency: f32,
        /// Octaves of the fractal sum, 1 to 8 (each twice the frequency and half the amplitude).
        octaves: u32,
        /// Fraction of the noise range that holds cloud, in (0, 1].
        coverage: f32,
    },
}

impl DensitySource {
    /// The density at `p`.
    pub fn density(&self, p: Vec3) -> f32 {
        match *self {
            DensitySource::Ellipsoid {
                center,
                radii,
                falloff,
            } => ellipsoid(p, center, radii, falloff),
            DensitySource::Cloud {
                center,
                radii,
                seed,
                frequency,
                octaves,
                coverage,
            } => {
                let envelope = ellipsoid(p, center, radii, 0.5);
                if envelope <= 1e-6 {
                    return 0.0;
                }
                let n = fbm(p * frequency, seed, octaves);
                let threshold = 1.0 - coverage;
                envelope * ((n - threshold) / coverage.max(1e-3)).clamp(0.0, 1.0)
            }
        }
    }
}

fn ellipsoid(p: Vec3, center: Vec3, radii: Vec3, falloff: f32) -> f32 {
    let r = ((p - center) / radii).length();
    let inner = 1.0 - falloff;
    if r <= inner {
        1.0
    } else if falloff <= 0.0 {
        0.0
    } else {
        (-4.0 * (r - inner) / falloff).exp()
    }
}

fn lattice(seed: u64, x: i32, y: i32, z: i32) -> f32 {
    let h = crate::math::sampling::mix64(
        seed ^ (x as u32 as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ (y as u32 as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
            ^ (z as u32 as u64).wrapping_mul(0x1656_67b1_9e37_79f9),
    );
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Smooth value noise in [0, 1).
fn value_noise(p: Vec3, seed: u64) -> f32 {
    let i = p.floor();
    let f = p - i;
    let s = f * f * (Vec3::splat(3.0) - 2.0 * f);
    let (x, y, z) = (i.x as i32, i.y as i32, i.z as i32);
    let l = |dx, dy, dz| lattice(seed, x + dx, y + dy, z + dz);
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let x00 = lerp(l(0, 0, 0), l(1, 0, 0), s.x);
    let x10 = lerp(l(0, 1, 0), l(1, 1, 0), s.x);
    let x01 = lerp(l(0, 0, 1), l(1, 0, 1), s.x);
    let x11 = lerp(l(0, 1, 1), l(1, 1, 1), s.x);
    lerp(lerp(x00, x10, s.y), lerp(x01, x11, s.y), s.z)
}

/// Fractal sum of `octaves` octaves (lacunarity 2, gain 1/2), normalised to [0, 1).
fn fbm(p: Vec3, seed: u64, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
    for o in 0..octaves.max(1) {
        sum += amp * value_noise(q, seed.wrapping_add(o as u64));
        norm += amp;
        amp *= 0.5;
        q *= 2.0;
    }
    sum / norm
}

/// Reads a density grid from a NumPy `.npy` file: a 3-D little-endian float32 or float64 array
/// in C order with shape `(nz, ny, nx)` (so x varies fastest), spanning `[min, max]`. The header
/// and the file size are checked before the data is read; NaN, infinite or negative densities are
/// errors naming the voxel.
pub fn load_npy(path: &Path, min: Vec3, max: Vec3) -> Result<DensityGrid> {
    let bytes = crate::files::read_regular(path, MAX_NPY_BYTES, "NumPy .npy grid")?;
    parse_npy(&bytes, path, min, max)
}

/// Largest `.npy` file: [`MAX_VOXELS`] float64 values and a header.
pub const MAX_NPY_BYTES: u64 = MAX_VOXELS as u64 * 8 + (1 << 20);

/// [`load_npy`] of bytes already read; `path` names them in messages.
pub fn parse_npy(bytes: &[u8], path: &Path, min: Vec3, max: Vec3) -> Result<DensityGrid> {
    let bad = |m: String| PrtError::file(path, m);
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("not a NumPy .npy file (no \\x93NUMPY magic)".into()));
    }
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(bad(format!("unsupported .npy version {v}"))),
    };
    let header = bytes
        .get(start..start + header_len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| bad("truncated or non-text .npy header".into()))?;
    let field = |key: &str| -> Option<&str> {
        let at = header.find(&format!("'{key}'"))? + key.len() + 2;
        let rest = header[at..].trim_start().strip_prefix(':')?.trim_start();
        Some(rest)
    };
    let descr = field("descr")
        .and_then(|r| r.strip_prefix('\'')?.split('\'').next())
        .ok_or_else(|| bad("the .npy header has no 'descr'".into()))?;
    let size = match descr {
        "<f4" => 4,
        "<f8" => 8,
        d => {
            return Err(bad(format!(
                "dtype {d}: expected little-endian float32 (<f4) or float64 (<f8)"
            )));
        }
    };
    if field("fortran_order").is_some_and(|r| r.starts_with("True")) {
        return Err(bad(
            "the array is in Fortran order: save it in C order (numpy.ascontiguousarray)".into(),
        ));
    }
    let shape_text = field("shape")
        .and_then(|r| r.strip_prefix('(')?.split(')').next())
        .ok_or_else(|| bad("the .npy header has no 'shape'".into()))?;
    let shape: Vec<usize> = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| bad(format!("shape ({shape_text}) is not a list of sizes")))?;
    let [nz, ny, nx] = shape[..] else {
        return Err(bad(format!(
            "shape ({shape_text}): expected a 3-D array (nz, ny, nx)"
        )));
    };
    let count = nx
        .checked_mul(ny)
        .and_then(|v| v.checked_mul(nz))
        .filter(|&c| c > 0 && c <= MAX_VOXELS)
        .ok_or_else(|| {
            bad(format!(
                "shape ({shape_text}): each side must be at least 1 and the total at most {MAX_VOXELS} voxels"
            ))
        })?;
    let data_start = start + header_len;
    if bytes.len() != data_start + count * size {
        return Err(bad(format!(
            "shape ({shape_text}) of {descr} needs {} data bytes, the file has {}",
            count * size,
            bytes.len().saturating_sub(data_start)
        )));
    }
    let raw = &bytes[data_start..];
    let data: Vec<f32> = if size == 4 {
        raw.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    } else {
        raw.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")) as f32)
            .collect()
    };
    let grid = DensityGrid {
        dims: [nx, ny, nz],
        min,
        max,
        data,
    };
    grid.validate(&path.display().to_string())?;
    Ok(grid)
}

/// Writes a density grid as a float32 `.npy` file of shape `(nz, ny, nx)` (the format
/// [`load_npy`] reads), atomically.
pub fn save_npy(path: &Path, grid: &DensityGrid) -> Result<()> {
    let [nx, ny, nz] = grid.dims;
    let mut header =
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({nz}, {ny}, {nx}), }}");
    // Pad so the data starts on a 64-byte boundary, ending with a newline.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = Vec::with_capacity(10 + header.len() + grid.data.len() * 4);
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for v in &grid.data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    crate::files::write_bytes_atomically(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Optical depth through the slab (σ = 2, 32 voxels in y) against σ times the path: the
    /// midpoint rule's one-voxel steps meet the trilinear ramps at the slab's faces, exactly when
    /// their midpoints fall symmetrically on a ramp (straight up) and otherwise off by part of one
    /// step's depth, σ · 1/32 = 0.0625.
    const SLAB_DEPTH: f32 = 0.02;
    /// The same slanted at 45°: steps cross the ramps obliquely and the path is √2 longer.
    const SLANTED_SLAB_DEPTH: f32 = 0.03;
    /// The camera march's transmittance through the slab against e^-1: half-voxel steps of the
    /// same optical depth, whose error scales by T ≈ 0.37.
    const SLAB_TRANSMITTANCE: f32 = 0.02;
    /// The camera march's weights summed through the slab against 1 − T, relative: each
    /// half-voxel step weighs σ dt e^(−σ dt / 2) where its exact share is 1 − e^(−σ dt), short
    /// by about (σ dt)² / 24 of it, ~4e-5 at σ dt = 1/32; 1% only asks that the weights account
    /// for the light the march attenuates.
    const MARCH_WEIGHT_SUM: f32 = 0.01;
    /// The Henyey–Greenstein phase integrated over 20,000 cosines by the midpoint rule (f32
    /// arguments and values, f64 sum): below 1e-6 off even for g = 0.8, so this is loose.
    const PHASE_NORMALISATION: f64 = 1e-3;
    /// A Fibonacci direction's length against 1: built from f32 sines, cosines and a square root,
    /// a few ulps.
    const FIBONACCI_UNIT_LENGTH: f32 = 1e-5;
    /// The mean of 512 Fibonacci directions: the lattice balances to ~1e-4, so this only asks
    /// that no side of the sphere is favoured.
    const FIBONACCI_MEAN: f32 = 1e-2;
    /// The ellipsoid's density at its surface against e^-4: one f32 exponential of
    /// −4 (r − 0.8) / 0.2 with r = 1, whose argument rounds by a few ulps, ~1e-8 of 0.018.
    const EDGE_DENSITY: f32 = 1e-5;

    fn slab() -> Medium {
        // Density 1 for y in [0.25, 0.75] across the box.
        let grid = DensityGrid::from_fn([8, 32, 8], Vec3::ZERO, Vec3::ONE, |p| {
            ((0.25..=0.75).contains(&p.y)) as u8 as f32
        });
        Medium {
            grid,
            extinction: 2.0,
            albedo: Vec3::ONE,
            g: 0.0,
        }
    }

    #[test]
    fn optical_depth_through_a_slab_is_sigma_times_thickness() {
        let m = slab();
        // The 16 voxels with centres from 0.266 to 0.734 hold 1; with the trilinear ramps on
        // each side the density integrates to 16 voxels, 16/32 = 0.5.
        let tau = m.optical_depth(Vec3::new(0.5, -1.0, 0.5), Vec3::Y, f32::INFINITY);
        assert!((tau - 2.0 * 0.5).abs() < SLAB_DEPTH, "tau {tau}");
        // Slanted at 45°: √2 times the path.
        let d = Vec3::new(0.0, 1.0, 1.0).normalize();
        let tau = m.optical_depth(Vec3::new(0.5, -0.2, -0.25), d, f32::INFINITY);
        assert!((tau - 2f32.sqrt()).abs() < SLANTED_SLAB_DEPTH, "tau {tau}");
        // Stopping halfway through the slab.
        let tau = m.optical_depth(Vec3::new(0.5, 0.0, 0.5), Vec3::Y, 0.5);
        assert!((tau - 0.5).abs() < SLAB_DEPTH, "tau {tau}");
    }

    #[test]
    fn camera_march_weights_sum_to_one_minus_transmittance() {
        let m = slab();
        let mut s = Vec::new();
        let t = m.march_camera(Vec3::new(0.5, -1.0, 0.5), Vec3::Y, f32::INFINITY, &mut s);
        let sum: f32 = s.iter().map(|x| x.weight).sum();
        // ∫ T sigma dt = 1 - T: the midpoint-transmittance rule keeps it to float precision
        // only approximately; half-voxel steps keep it within 1%.
        assert!(
            (sum - (1.0 - t)).abs() < MARCH_WEIGHT_SUM * (1.0 - t),
            "{sum} vs {}",
            1.0 - t
        );
        assert!((t - (-1.0f32).exp()).abs() < SLAB_TRANSMITTANCE, "T {t}");
    }

    #[test]
    fn a_voxel_deeper_than_the_limit_is_refused_with_the_largest_extinction_it_takes() {
        assert!(voxel_depth_problem(MAX_VOXEL_DEPTH, 1.0, 1.0).is_none());
        assert!(voxel_depth_problem(1e30, 0.0, 1.0).is_none());
        // The fog of the tests: 24 voxels over 1.6 units.
        let e = voxel_depth_problem(1e8, 1.0, 1.6 / 24.0).unwrap();
        assert!(e.contains("above 100") && e.contains("1.5000e3"), "{e}");
        // Products past f32's range are still refused.
        assert!(voxel_depth_problem(f32::MAX, f32::MAX, 1e9).is_some());
        // A procedural grid's voxels: 24 x 18 x 24 over the fog's box.
        let extent = Vec3::new(1.6, 1.2, 1.6);
        assert_eq!(grid_dims(extent, 24), [24, 18, 24]);
        assert!((voxel_edge(extent, 24) - 1.6 / 24.0).abs() < 1e-6);
    }

    #[test]
    fn fast_floor_is_floor() {
        for x in [
            -2.5f32,
            -2.0,
            -1e-7,
            -0.0,
            0.0,
            0.3,
            1.0,
            1.9999,
            7.5,
            -7.5,
            1e6 + 0.5,
        ] {
            assert_eq!(floor(x), x.floor(), "{x}");
        }
    }

    #[test]
    fn phase_function_integrates_to_one() {
        for g in [-0.6f32, 0.0, 0.3, 0.8] {
            let n = 20000;
            let sum: f64 = (0..n)
                .map(|i| {
                    let mu = -1.0 + 2.0 * (i as f32 + 0.5) / n as f32;
                    henyey_greenstein(g, mu) as f64
                })
                .sum::<f64>()
                * 2.0
                / n as f64
                * 2.0
                * std::f64::consts::PI;
            assert!((sum - 1.0).abs() < PHASE_NORMALISATION, "g {g}: {sum}");
        }
    }

    #[test]
    fn fibonacci_directions_are_unit_and_balanced() {
        let d = fibonacci_directions(512);
        assert!(
            d.iter()
                .all(|v| (v.length() - 1.0).abs() < FIBONACCI_UNIT_LENGTH)
        );
        let mean = d.iter().copied().sum::<Vec3>() / 512.0;
        assert!(mean.length() < FIBONACCI_MEAN, "mean {mean}");
    }

    #[test]
    fn npy_round_trip_and_bad_files() {
        let dir = std::env::temp_dir().join(format!("prt-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let grid = DensityGrid::from_fn([3, 4, 5], Vec3::ZERO, Vec3::ONE, |p| p.x + 2.0 * p.z);
        let path = dir.join("g.npy");
        save_npy(&path, &grid).unwrap();
        let back = load_npy(&path, Vec3::ZERO, Vec3::ONE).unwrap();
        assert_eq!(back, grid);
        // A NaN density names its voxel.
        let mut nan = grid.clone();
        nan.data[3 + 4 * 3] = f32::NAN;
        save_npy(&path, &nan).unwrap();
        let e = load_npy(&path, Vec3::ZERO, Vec3::ONE)
            .unwrap_err()
            .to_string();
        assert!(e.contains("(x 0, y 1, z 1)"), "{e}");
        // A truncated file is refused before its data is read.
        let mut bytes = std::fs::read(dir.join("g.npy")).unwrap();
        bytes.truncate(bytes.len() - 4);
        std::fs::write(&path, &bytes).unwrap();
        let e = load_npy(&path, Vec3::ZERO, Vec3::ONE)
            .unwrap_err()
            .to_string();
        assert!(e.contains("data bytes"), "{e}");
        // A 2-D array is the wrong shape.
        let text = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 2), }";
        let mut two = b"\x93NUMPY\x01\x00".to_vec();
        two.extend_from_slice(&(text.len() as u16).to_le_bytes());
        two.extend_from_slice(text.as_bytes());
        two.extend_from_slice(&[0u8; 16]);
        std::fs::write(&path, &two).unwrap();
        let e = load_npy(&path, Vec3::ZERO, Vec3::ONE)
            .unwrap_err()
            .to_string();
        assert!(e.contains("3-D"), "{e}");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn ellipsoid_and_cloud_densities() {
        let e = DensitySource::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::new(1.0, 0.5, 1.0),
            falloff: 0.2,
        };
        assert_eq!(e.density(Vec3::new(0.0, 0.39, 0.0)), 1.0);
        let edge = e.density(Vec3::new(0.0, 0.5, 0.0));
        assert!((edge - (-4.0f32).exp()).abs() < EDGE_DENSITY);
        let c = DensitySource::Cloud {
            center: Vec3::ZERO,
            radii: Vec3::ONE,
            seed: 3,
            frequency: 3.0,
            octaves: 4,
            coverage: 0.6,
        };
        let vals: Vec<f32> = (0..1000)
            .map(|i| {
                c.density(
                    Vec3::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32) * 0.1 - 0.45,
                )
            })
            .collect();
        assert!(vals.iter().all(|v| (0.0..=1.0).contains(v)));
        assert!(vals.contains(&0.0) && vals.iter().any(|v| *v > 0.3));
    }
}
