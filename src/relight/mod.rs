//! Relighting a baked view. A request ([`RelightRequest`]: a method and its parameters) under a
//! prepared light ([`prepare`]) becomes its light terms ([`Terms::of`]), and a [`Backend`] runs
//! them: the CPU kernels ([`cpu`]) or the wgpu kernels ([`gpu`]), with the same inputs, the same
//! image and the same statistics. SH through the light ([`sh_light`]) completes the methods; what
//! draws a relit image ([`crate::draw`]) is a stage of its own.

pub mod columns;
pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod lobe_light;
pub mod prepare;
pub mod sh_light;
pub mod sh_transfer;
pub mod strip_kernel;

pub use crate::scene::light_mix::{LightMix, LightSetting};
pub use cpu::{relight_dense_reference, relight_sh, relight_wavelet};
pub use lobe_light::lobe_light;
pub use prepare::{LightContext, PreparedLight};

use crate::env::select::{SparseLight, WaveletLight, Weighting};
use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;
use crate::output::film::Image;
use crate::store::transport::Transport;

/// Which approximation of the light relights the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[derive(strum::IntoStaticStr, strum::Display, strum::VariantArray)]
#[strum(serialize_all = "kebab-case")]
pub enum Method {
    /// K Haar terms of the light (Ng et al. 2003).
    Wavelet,
    /// SH light of order n against the SH transport.
    Sh,
    /// Every Haar term: the stored transport times the whole cube-map light.
    Full,
    /// SH through the light: the light projected onto SH of order n (any order up to
    /// [`crate::math::sh::MAX_LIGHT_ORDER`]), reconstructed on the texels and relit with every
    /// stored term, as Ng et al. 2003 evaluated SH with up to 20,000 terms ([`sh_light`]).
    ShLight,
}

crate::named!(Method, "method");

/// What a relight did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RelightStats {
    /// Light terms used (K, n², or 6 N²).
    pub terms: usize,
    /// Stored transport entries the product reads (for SH, the values of the rows' SH terms).
    pub nonzeros_touched: u64,
    /// Transport bytes read: the strips and their slots, or the SH rows.
    pub bytes_touched: u64,
    /// Wall time of the kernel alone, seconds.
    pub kernel_seconds: f64,
    /// Local light columns added (those with a nonzero weight).
    pub light_columns: usize,
}

/// What to relight with: a method and the parameters it takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RelightRequest {
    /// The K best Haar terms of the light by a weighting (Ng et al. 2003).
    Wavelet {
        /// Terms kept, 1 to 6 N².
        k: usize,
        /// How the terms are ranked.
        weighting: Weighting,
    },
    /// The light's SH of this order against the baked SH transport (at most the baked order).
    Sh {
        /// SH order n (n² terms).
        order: usize,
    },
    /// SH through the light: the light reconstructed from its SH of this order, relit with
    /// every stored Haar term ([`sh_light`]; any order up to
    /// [`crate::math::sh::MAX_LIGHT_ORDER`]).
    ShLight {
        /// SH order n (n² terms).
        order: usize,
    },
    /// Every Haar term: the stored transport times the whole cube-map light.
    Full,
}

impl RelightRequest {
    /// The request of `method` with the parameters a command line or a window holds for every
    /// method: K and the weighting go to wavelets, the order to both SH methods.
    pub fn new(method: Method, k: usize, weighting: Weighting, order: usize) -> RelightRequest {
        match method {
            Method::Wavelet => RelightRequest::Wavelet { k, weighting },
            Method::Sh => RelightRequest::Sh { order },
            Method::ShLight => RelightRequest::ShLight { order },
            Method::Full => RelightRequest::Full,
        }
    }

    /// Its method.
    pub fn method(&self) -> Method {
        match self {
            RelightRequest::Wavelet { .. } => Method::Wavelet,
            RelightRequest::Sh { .. } => Method::Sh,
            RelightRequest::ShLight { .. } => Method::ShLight,
            RelightRequest::Full => Method::Full,
        }
    }
}

/// The light terms a request relights with, whatever the device: the one place where a method
/// becomes its terms.
#[derive(Clone, Debug, PartialEq)]
pub enum Terms {
    /// Haar terms of the light: the K best ([`RelightRequest::Wavelet`]) or all
    /// ([`RelightRequest::Full`]).
    Wavelet(SparseLight),
    /// Every Haar term of the light reconstructed from its first `order`² SH coefficients
    /// ([`RelightRequest::ShLight`]): relit as wavelet terms, counted as `order`² terms.
    ShLight {
        /// The reconstructed light's Haar terms.
        haar: SparseLight,
        /// The SH order it was reconstructed from.
        order: usize,
    },
    /// The first n² SH coefficients of the light ([`RelightRequest::Sh`]).
    Sh(Vec<[f64; 3]>),
}

impl Terms {
    /// The terms of `req` from `light`, prepared for `t` (checked: same N, K and order in range).
    pub fn of(
        t: &Transport,
        ctx: &LightContext,
        light: &PreparedLight,
        req: &RelightRequest,
    ) -> Result<Terms> {
        if ctx.n != t.meta.identity.cube_n as usize || light.wavelet.n != ctx.n {
            return Err(PrtError::invalid(
                "light",
                format!(
                    "prepared for a cube of N = {} but the transport was baked with N = {}",
                    light.wavelet.n, t.meta.identity.cube_n
                ),
            ));
        }
        Ok(match *req {
            RelightRequest::Wavelet { k, weighting } => Terms::Wavelet(light.wavelet.select(
                k,
                weighting,
                &ctx.support_area,
                Some(&t.transport_magnitude),
            )?),
            RelightRequest::Full => Terms::Wavelet(SparseLight {
                indices: (0..light.wavelet.coeffs.len() as u32).collect(),
                values: light.wavelet.coeffs.clone(),
            }),
            RelightRequest::Sh { order } => Terms::Sh(light_sh_order(
                &light.sh,
                order,
                t.meta.identity.sh_order as usize,
            )?),
            RelightRequest::ShLight { order } => {
                let projected = sh_light::ShThroughLight::new(&light.wavelet.to_cube()?, order)?;
                Terms::sh_through_light(t, &projected, order)?
            }
        })
    }

    /// The terms of SH through the light at `order` for `t`, from a projection made once for
    /// many orders (up to its `max_order`).
    pub fn sh_through_light(
        t: &Transport,
        projected: &sh_light::ShThroughLight,
        order: usize,
    ) -> Result<Terms> {
        if projected.n != t.meta.identity.cube_n as usize {
            return Err(PrtError::invalid(
                "SH light",
                format!(
                    "projected from an N = {} cube, the transport has N = {}",
                    projected.n, t.meta.identity.cube_n
                ),
            ));
        }
        let all = WaveletLight::from_cube(&projected.cube(order)?)?;
        Ok(Terms::ShLight {
            haar: SparseLight {
                indices: (0..all.coeffs.len() as u32).collect(),
                values: all.coeffs,
            },
            order,
        })
    }

    /// The environment switched off: one Haar term of value 0, so that a relight adds the local
    /// lights alone through the same kernels.
    pub fn dark() -> Terms {
        Terms::Wavelet(SparseLight {
            indices: vec![0],
            values: vec![[0.0; 3]],
        })
    }

    /// The light these terms stand for on an N-cube, as texels: the inverse Haar transform of
    /// the kept terms (the others zero), or the SH coefficients' sum at each texel centre. What
    /// a glossy lobe drawn per pixel reads ([`crate::draw::lobe`]), so that K and SH against
    /// wavelets act on highlights as on the diffuse light.
    pub fn cube(&self, n: usize) -> Result<CubeMap> {
        crate::math::cubemap::validate_n(n)?;
        match self {
            Terms::Wavelet(light) | Terms::ShLight { haar: light, .. } => {
                let mut coeffs = vec![[0.0f32; 3]; crate::math::cubemap::texel_count(n)];
                for (&i, v) in light.indices.iter().zip(&light.values) {
                    let slot = coeffs.get_mut(i as usize).ok_or_else(|| {
                        PrtError::invalid("light", format!("term {i} of an N = {n} cube"))
                    })?;
                    *slot = *v;
                }
                WaveletLight { n, coeffs }.to_cube()
            }
            Terms::Sh(sh) => {
                let order = crate::math::sh::order_from_len(sh.len())?;
                let mut basis = vec![0.0; sh.len()];
                CubeMap::from_fn(n, |d| {
                    crate::math::sh::eval(order, d, &mut basis);
                    let mut c = [0.0f64; 3];
                    for (y, s) in basis.iter().zip(sh) {
                        for k in 0..3 {
                            c[k] += y * s[k];
                        }
                    }
                    c.map(|v| v as f32)
                })
            }
        }
    }

    /// How many light terms these stand for: K, n², or 6 N².
    pub fn count(&self) -> usize {
        match self {
            Terms::Wavelet(light) => light.indices.len(),
            Terms::ShLight { order, .. } => order * order,
            Terms::Sh(sh) => sh.len(),
        }
    }
}

/// A device that relights a transport: it takes the same terms and returns the same image and
/// the same statistics (terms, transport values and bytes read, kernel time) as every other.
/// The CPU kernels are [`Cpu`]; the wgpu kernels are [`gpu::GpuBackend`].
pub trait Backend {
    /// The transport it relights.
    fn transport(&self) -> &Transport;
    /// What to call it in reports: `cpu`, or the GPU adapter.
    fn name(&self) -> String;
    /// Relights with the environment's `terms` plus the local lights of `lights` (one weight per
    /// light column of the transport, or none) and reads the image back.
    fn relight_lit(&self, terms: &Terms, lights: &LightMix) -> Result<(Image, RelightStats)>;

    /// Relights with `terms` alone and reads the image back.
    fn relight_terms(&self, terms: &Terms) -> Result<(Image, RelightStats)> {
        self.relight_lit(terms, &LightMix::none())
    }

    /// Relights `req` under a prepared light: [`Backend::relight_with`] without local lights.
    fn relight(
        &self,
        ctx: &LightContext,
        light: &PreparedLight,
        req: &RelightRequest,
    ) -> Result<(Image, RelightStats)> {
        self.relight_with(ctx, light, req, &LightMix::none())
    }

    /// Relights `req` under a prepared light, plus the local lights of `lights`: [`Terms::of`],
    /// then the kernels. Inputs are finite (loading checks the file, preparing the light its
    /// range), but their products may still overflow f32: that is an error, never an image with
    /// infinities or NaN.
    fn relight_with(
        &self,
        ctx: &LightContext,
        light: &PreparedLight,
        req: &RelightRequest,
        lights: &LightMix,
    ) -> Result<(Image, RelightStats)> {
        let terms = Terms::of(self.transport(), ctx, light, req)?;
        let (image, stats) = self.relight_lit(&terms, lights)?;
        image.check_finite("relit image")?;
        Ok((image, stats))
    }
}

/// Checks that `lights` has a weight for every light column of `t` (or none at all).
pub fn check_mix(t: &Transport, lights: &LightMix) -> Result<()> {
    let columns = t.meta.light_columns();
    if !lights.weights.is_empty() && lights.weights.len() != columns {
        return Err(PrtError::invalid(
            "lights",
            format!(
                "{} light weights for a transport with {columns} light columns",
                lights.weights.len()
            ),
        ));
    }
    if !lights.weights.iter().flatten().all(|v| v.is_finite()) {
        return Err(PrtError::invalid("lights", "a light weight is not finite"));
    }
    Ok(())
}

/// The CPU kernels of [`cpu`] as a [`Backend`].
pub struct Cpu<'a>(pub &'a Transport);

impl Backend for Cpu<'_> {
    fn transport(&self) -> &Transport {
        self.0
    }
    fn name(&self) -> String {
        "cpu".into()
    }
    fn relight_lit(&self, terms: &Terms, lights: &LightMix) -> Result<(Image, RelightStats)> {
        check_mix(self.0, lights)?;
        let (mut image, stats) = match terms {
            Terms::Wavelet(light) | Terms::ShLight { haar: light, .. } => {
                relight_wavelet(self.0, light)?
            }
            Terms::Sh(sh) => relight_sh(self.0, sh)?,
        };
        let start = std::time::Instant::now();
        columns::add_columns(&self.0.attached.lights, &lights.weights, &mut image.pixels);
        Ok((
            image,
            RelightStats {
                terms: terms.count(),
                kernel_seconds: stats.kernel_seconds + start.elapsed().as_secs_f64(),
                light_columns: lights.lit_columns(),
                ..stats
            },
        ))
    }
}

/// Relights on the CPU: [`Backend::relight`] of [`Cpu`].
pub fn relight(
    t: &Transport,
    ctx: &LightContext,
    light: &PreparedLight,
    req: &RelightRequest,
) -> Result<(Image, RelightStats)> {
    Cpu(t).relight(ctx, light, req)
}

/// The first `order²` SH coefficients, checked against the baked order.
pub fn light_sh_order(sh: &[[f64; 3]], order: usize, baked: usize) -> Result<Vec<[f64; 3]>> {
    crate::flags::sh_order(order, baked)?;
    sh.get(..order * order)
        .map(<[_]>::to_vec)
        .ok_or_else(|| PrtError::invalid("SH light", format!("fewer than {order}² coefficients")))
}
