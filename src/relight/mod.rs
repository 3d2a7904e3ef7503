//! Relighting a baked view: the light pipeline (environment -> cube map -> Haar -> K best terms, or
//! SH projection) and the CPU kernels (rayon over tile rows): the tiled sparse wavelet product, the
//! SH dot product and `full` (every term). The GPU kernels live in [`crate::relight::gpu`] behind the same
//! inputs.

pub mod background;
pub mod gpu;
pub mod sh_light;

use std::str::FromStr;
use std::time::Instant;

use rayon::prelude::*;

use crate::error::{PrtError, Result};
use crate::light::envmap::{EnvMap, EnvRotation};
use crate::light::select::{SparseLight, TexelShBasis, WaveletLight, Weighting};
use crate::math::haar::support_solid_angles;
use crate::math::sh;
use crate::output::film::Image;
use crate::store::quant::{BLOCK_ROWS, scale_of};
use crate::store::transport::{TILE, Transport, Values, tile_grid};

/// Which approximation of the light relights the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// K Haar terms of the light (Ng et al. 2003).
    Wavelet,
    /// SH light of order n against the SH transport.
    Sh,
    /// Every Haar term: the stored transport times the whole cube-map light.
    Full,
}

impl FromStr for Method {
    type Err = PrtError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "wavelet" => Ok(Method::Wavelet),
            "sh" => Ok(Method::Sh),
            "full" => Ok(Method::Full),
            _ => Err(PrtError::invalid(
                "method",
                format!("`{s}`; expected wavelet, sh or full"),
            )),
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Method::Wavelet => "wavelet",
            Method::Sh => "sh",
            Method::Full => "full",
        })
    }
}

/// What a relight did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelightStats {
    /// Light terms used (K, n², or 6 N²).
    pub terms: usize,
    /// Transport values read.
    pub nonzeros_touched: u64,
    /// Transport bytes read (entries, column pointers or SH rows).
    pub bytes_touched: u64,
    /// Wall time of the kernel alone, seconds.
    pub kernel_seconds: f64,
}

/// A light prepared for one transport: the Haar coefficients of the cube map at the file's N and
/// its SH projection, ready for any K, weighting or order.
#[derive(Clone, Debug)]
pub struct PreparedLight {
    /// All Haar coefficients.
    pub wavelet: WaveletLight,
    /// SH coefficients at the transport's order.
    pub sh: Vec<[f64; 3]>,
}

/// What the light side needs from a transport, computed once per file: support areas, the SH
/// basis at the file's N.
#[derive(Clone, Debug)]
pub struct LightContext {
    /// Cube face size.
    pub n: usize,
    /// SH order of the file.
    pub sh_order: usize,
    /// Support solid angle of every Haar coefficient.
    pub support_area: Vec<f32>,
    /// Tabulated SH basis at the texel centres.
    pub basis: TexelShBasis,
}

impl LightContext {
    /// For a transport.
    pub fn new(t: &Transport) -> Result<Self> {
        Self::with_sizes(t.meta.cube_n as usize, t.meta.sh_order as usize)
    }

    /// For a cube of face size `n` and SH order `sh_order`, without a transport (benchmarks,
    /// tools that only prepare lights).
    pub fn with_sizes(n: usize, sh_order: usize) -> Result<Self> {
        crate::math::cubemap::validate_n(n)?;
        Ok(LightContext {
            n,
            sh_order,
            support_area: support_solid_angles(n).iter().map(|&a| a as f32).collect(),
            basis: TexelShBasis::new(n, sh_order)?,
        })
    }

    /// Prepares `env` turned by `rotation`: for wavelets the turned map is resampled to the
    /// file's cube and transformed (a rotation does not map Haar coefficients to Haar
    /// coefficients); for SH the unturned cube is projected once and its coefficient vector
    /// rotated band by band, which is exact for the projected light.
    pub fn prepare(&self, env: &EnvMap, rotation: EnvRotation) -> Result<PreparedLight> {
        if rotation == EnvRotation::default() {
            let cube = env.to_cube(self.n, rotation)?;
            let light = PreparedLight {
                wavelet: WaveletLight::from_cube(&cube).map_err(|e| named(e, env))?,
                sh: self.basis.project_light(&cube)?,
            };
            return light.checked(env);
        }
        let unturned = self.prepare_sh(env)?;
        self.prepare_turned(env, &unturned, rotation)
    }

    /// The SH light of the unturned environment, to be reused for many rotations.
    pub fn prepare_sh(&self, env: &EnvMap) -> Result<Vec<[f64; 3]>> {
        self.basis
            .project_light(&env.to_cube(self.n, EnvRotation::default())?)
    }

    /// [`LightContext::prepare`] with the unturned SH light already computed.
    pub fn prepare_turned(
        &self,
        env: &EnvMap,
        unturned_sh: &[[f64; 3]],
        rotation: EnvRotation,
    ) -> Result<PreparedLight> {
        let cube = env.to_cube(self.n, rotation)?;
        let sh = if rotation == EnvRotation::default() {
            unturned_sh.to_vec()
        } else {
            sh::Rotation::new(self.sh_order, rotation.world_from_map())?.apply_rgb(unturned_sh)
        };
        PreparedLight {
            wavelet: WaveletLight::from_cube(&cube).map_err(|e| named(e, env))?,
            sh,
        }
        .checked(env)
    }
}

/// An error about "environment" as one about the map's file (or procedural source).
fn named(e: PrtError, env: &EnvMap) -> PrtError {
    match e {
        PrtError::Invalid { what, message } if what == "environment" => {
            PrtError::file(&env.source, message)
        }
        e => e,
    }
}

impl PreparedLight {
    /// The light itself, or an error when a coefficient does not fit the kernels' 32-bit floats
    /// (a map so bright that relighting would write infinities and NaN).
    fn checked(self, env: &EnvMap) -> Result<Self> {
        if let Some(c) = self
            .sh
            .iter()
            .flatten()
            .find(|c| !c.is_finite() || c.abs() > f32::MAX as f64)
        {
            return Err(PrtError::file(
                &env.source,
                format!(
                    "an SH coefficient of its light is {c:.3e}, beyond 32-bit floats: the map is \
                     far too bright (scale it down)"
                ),
            ));
        }
        Ok(self)
    }
}

/// What to relight with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelightRequest {
    pub method: Method,
    /// Kept terms for [`Method::Wavelet`].
    pub terms: usize,
    pub weighting: Weighting,
    /// SH order for [`Method::Sh`] (at most the baked order).
    pub sh_order: usize,
}

/// Relights on the CPU.
pub fn relight(
    t: &Transport,
    ctx: &LightContext,
    light: &PreparedLight,
    req: &RelightRequest,
) -> Result<(Image, RelightStats)> {
    if ctx.n != t.meta.cube_n as usize || light.wavelet.n != ctx.n {
        return Err(PrtError::invalid(
            "light",
            format!(
                "prepared for a cube of N = {} but the transport was baked with N = {}",
                light.wavelet.n, t.meta.cube_n
            ),
        ));
    }
    let (image, stats) = match req.method {
        Method::Wavelet | Method::Full => relight_wavelet(t, &select_light(t, ctx, light, req)?)?,
        Method::Sh => {
            let sh = light_sh_order(&light.sh, req.sh_order, t.meta.sh_order as usize)?;
            relight_sh(t, &sh)?
        }
    };
    // Inputs are finite (loading checks the file, preparing the light its range), but their
    // products may still overflow f32: an error, never an image with infinities or NaN.
    image.check_finite("relit image")?;
    Ok((image, stats))
}

/// The Haar terms a wavelet or full request keeps: the K best by its weighting, or all of them.
pub fn select_light(
    t: &Transport,
    ctx: &LightContext,
    light: &PreparedLight,
    req: &RelightRequest,
) -> Result<SparseLight> {
    match req.method {
        Method::Full => Ok(SparseLight {
            indices: (0..light.wavelet.coeffs.len() as u32).collect(),
            values: light.wavelet.coeffs.clone(),
        }),
        _ => light.wavelet.select(
            req.terms,
            req.weighting,
            &ctx.support_area,
            Some(&t.transport_magnitude),
        ),
    }
}

/// Transport values the sparse product reads for `light`: the lengths of its kept columns in
/// every block.
pub fn nonzeros_touched(t: &Transport, light: &SparseLight) -> u64 {
    let c = t.coeff_count();
    (0..t.block_count())
        .map(|b| {
            let ptr = &t.col_ptr[b * (c + 1)..(b + 1) * (c + 1)];
            light
                .indices
                .iter()
                .map(|&j| (ptr[j as usize + 1] - ptr[j as usize]) as u64)
                .sum::<u64>()
        })
        .sum()
}

/// The first `order²` SH coefficients, checked against the baked order.
pub fn light_sh_order(sh: &[[f64; 3]], order: usize, baked: usize) -> Result<Vec<[f64; 3]>> {
    crate::flags::sh_order(order, baked)?;
    sh.get(..order * order)
        .map(<[_]>::to_vec)
        .ok_or_else(|| PrtError::invalid("SH light", format!("fewer than {order}² coefficients")))
}

/// Widens a stored value (an integer, or a lossless float) to f32; the column's scale is applied
/// to the light term instead, once per block and column.
trait StoredValue: Copy + Send + Sync {
    fn f32(self) -> f32;
}
impl StoredValue for f32 {
    #[inline(always)]
    fn f32(self) -> f32 {
        self
    }
}
impl StoredValue for i8 {
    #[inline(always)]
    fn f32(self) -> f32 {
        self as f32
    }
}
impl StoredValue for i16 {
    #[inline(always)]
    fn f32(self) -> f32 {
        self as f32
    }
}

/// The tiled sparse product: for every block of every tile, every kept light term's column adds
/// `integer · (scale · L)` to its rows; the rows then add `weight ⊙ sum` to their pixels. Checks
/// that the light fits the transport (N, index range).
pub fn relight_wavelet(t: &Transport, light: &SparseLight) -> Result<(Image, RelightStats)> {
    let c = t.coeff_count();
    if light.indices.iter().any(|&j| j as usize >= c) || light.indices.len() != light.values.len() {
        return Err(PrtError::invalid(
            "light",
            format!("its coefficients do not fit a transport with 6·N² = {c} coefficients"),
        ));
    }
    let start = Instant::now();
    let (image, touched) = match &t.values {
        Values::Q8(v) => wavelet_kernel(t, light, v),
        Values::Q16(v) => wavelet_kernel(t, light, v),
        Values::F32(v) => wavelet_kernel(t, light, v),
    };
    let stats = RelightStats {
        terms: light.len(),
        nonzeros_touched: touched,
        bytes_touched: touched * (1 + t.values.value_bytes() as u64)
            + t.block_count() as u64 * light.len() as u64 * 9,
        kernel_seconds: start.elapsed().as_secs_f64(),
    };
    Ok((image, stats))
}

/// One block's accumulators: a row index is a byte, so indexing needs no bounds check.
type BlockAcc = [[f32; 4]; BLOCK_ROWS];

/// Entries widened to f32 together before they are scattered.
const CHUNK: usize = 32;

fn wavelet_kernel<V: StoredValue>(
    t: &Transport,
    light: &SparseLight,
    values: &[V],
) -> (Image, u64) {
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let (tx, _) = tile_grid(w, h);
    let c = t.coeff_count();
    let mut image = Image::new(w, h);
    let touched: u64 = image
        .pixels
        .par_chunks_mut(w * TILE)
        .enumerate()
        .map_init(
            || Box::new([[0.0f32; 4]; BLOCK_ROWS]),
            |acc: &mut Box<BlockAcc>, (ty, band)| {
                let mut touched = 0u64;
                let y0 = ty * TILE * w;
                for tile in ty * tx..(ty + 1) * tx {
                    for b in t.blocks(tile) {
                        let (r0, r1) = (
                            t.block_row_start[b] as usize,
                            t.block_row_start[b + 1] as usize,
                        );
                        acc[..r1 - r0].fill([0.0; 4]);
                        let base = t.block_entry_start[b] as usize;
                        let ptr = &t.col_ptr[b * (c + 1)..(b + 1) * (c + 1)];
                        let codes = &t.col_scale[b * c..(b + 1) * c];
                        for (&j, l) in light.indices.iter().zip(&light.values) {
                            let j = j as usize;
                            let (e0, e1) = (base + ptr[j] as usize, base + ptr[j + 1] as usize);
                            if e0 == e1 {
                                continue;
                            }
                            touched += (e1 - e0) as u64;
                            // Four lanes (the last unused) so one vector op updates a row.
                            let s = scale_of(codes[j]);
                            let l = [l[0] * s, l[1] * s, l[2] * s, 0.0];
                            // Widen a chunk of values at once (a vector conversion), then
                            // scatter: one row update per entry with no scalar conversion.
                            let rows = t.entry_row[e0..e1].chunks(CHUNK);
                            for (rows, vals) in rows.zip(values[e0..e1].chunks(CHUNK)) {
                                let mut wide = [0.0f32; CHUNK];
                                for (w, &v) in wide.iter_mut().zip(vals) {
                                    *w = v.f32();
                                }
                                for (&r, &v) in rows.iter().zip(&wide) {
                                    let a = &mut acc[r as usize];
                                    for k in 0..4 {
                                        a[k] += v * l[k];
                                    }
                                }
                            }
                        }
                        for (r, a) in acc[..r1 - r0].iter().enumerate() {
                            let p = t.row_pixel[r0 + r] as usize - y0;
                            let wgt = t.row_weight[r0 + r];
                            let s = t.row_scale[r0 + r];
                            let px = &mut band[p];
                            for k in 0..3 {
                                px[k] += wgt[k] * (a[k] * s);
                            }
                        }
                    }
                }
                touched
            },
        )
        .sum();
    (image, touched)
}

/// SH relighting: every row's SH transport (its first `sh.len()` coefficients) dotted with the SH
/// light.
pub fn relight_sh(t: &Transport, sh: &[[f64; 3]]) -> Result<(Image, RelightStats)> {
    let stride = t.sh_count();
    let count = sh.len();
    if count == 0 || count > stride {
        return Err(PrtError::invalid(
            "SH light",
            format!("{count} coefficients for a transport baked with {stride}"),
        ));
    }
    let start = Instant::now();
    let light: Vec<[f32; 3]> = sh.iter().map(|c| c.map(|v| v as f32)).collect();
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let (tx, _) = tile_grid(w, h);
    let mut image = Image::new(w, h);
    image
        .pixels
        .par_chunks_mut(w * TILE)
        .enumerate()
        .for_each(|(ty, band)| {
            let rows = t.tile_row_start[ty * tx] as usize..t.tile_row_start[(ty + 1) * tx] as usize;
            let y0 = ty * TILE * w;
            for r in rows {
                let coeffs = &t.sh[r * stride..r * stride + count];
                let mut a = [0.0f32; 3];
                for (tc, l) in coeffs.iter().zip(&light) {
                    a[0] += tc * l[0];
                    a[1] += tc * l[1];
                    a[2] += tc * l[2];
                }
                let wgt = t.row_weight[r];
                let px = &mut band[t.row_pixel[r] as usize - y0];
                for k in 0..3 {
                    px[k] += wgt[k] * a[k];
                }
            }
        });
    let rows = t.row_pixel.len() as u64;
    let stats = RelightStats {
        terms: count,
        nonzeros_touched: rows * count as u64,
        bytes_touched: rows * count as u64 * 4,
        kernel_seconds: start.elapsed().as_secs_f64(),
    };
    Ok((image, stats))
}

/// The slow twin of the wavelet kernel: rebuilds every row densely and takes plain dot products.
/// For tests and checks only.
pub fn relight_dense_reference(t: &Transport, light: &SparseLight) -> Image {
    let (w, h) = (t.meta.width as usize, t.meta.height as usize);
    let c = t.coeff_count();
    let mut dense_light = vec![[0.0f64; 3]; c];
    for (&j, l) in light.indices.iter().zip(&light.values) {
        dense_light[j as usize] = l.map(|v| v as f64);
    }
    let mut image = Image::new(w, h);
    for b in 0..t.block_count() {
        let r0 = t.block_row_start[b] as usize;
        let rows = t.block_row_start[b + 1] as usize - r0;
        let mut dense = vec![vec![0.0f64; c]; rows];
        // Column by column, as stored; `j` indexes the stored columns and each dense row.
        #[allow(clippy::needless_range_loop)]
        for j in 0..c {
            for e in t.block_column(b, j) {
                dense[t.entry_row[e] as usize][j] = t.value(b, j, e) as f64;
            }
        }
        for (r, row) in dense.iter().enumerate() {
            let mut a = [0.0f64; 3];
            for (v, l) in row.iter().zip(&dense_light) {
                for k in 0..3 {
                    a[k] += v * l[k];
                }
            }
            let wgt = t.row_weight[r0 + r];
            let px = &mut image.pixels[t.row_pixel[r0 + r] as usize];
            for k in 0..3 {
                px[k] += (wgt[k] as f64 * a[k]) as f32;
            }
        }
    }
    image
}
