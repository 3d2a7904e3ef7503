//! Preparing a light for one transport: the environment turned and resampled to the file's cube,
//! its Haar coefficients (ready for any K and weighting) and its SH projection (ready for any
//! order up to the file's), computed once per light and reused by every request.

use crate::env::envmap::{EnvMap, EnvRotation};
use crate::env::select::WaveletLight;
use crate::error::{PrtError, Result};
use crate::math::haar::support_solid_angles;
use crate::math::sh;
use crate::math::texel_sh::TexelShBasis;
use crate::store::transport::Transport;

/// A light prepared for one transport: the Haar coefficients of the cube map at the file's N and
/// its SH projection, ready for any K, weighting or order.
#[derive(Clone, Debug)]
pub struct PreparedLight {
    /// All Haar coefficients.
    pub wavelet: WaveletLight,
    /// SH coefficients at the transport's order.
    pub sh: Vec<[f64; 3]>,
    /// All Haar coefficients on the glossy lobe's finer cube, where the context asks for one
    /// ([`LightContext::lobe_n`]).
    pub lobe: Option<WaveletLight>,
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
    /// The face size of the cube a glossy lobe's light is prepared on besides
    /// ([`crate::relight::lobe_light()`]): for a transport that keeps visibility.
    pub lobe_n: Option<usize>,
    /// Support solid angle of every Haar coefficient of that cube (empty without it).
    pub lobe_support: Vec<f32>,
}

impl LightContext {
    /// For a transport.
    pub fn new(t: &Transport) -> Result<Self> {
        Ok(Self::with_sizes(
            t.meta.identity.cube_n as usize,
            t.meta.identity.sh_order as usize,
        )?
        .with_lobe(t.meta.identity.visibility))
    }

    /// This context, preparing each light on the glossy lobe's finer cube besides
    /// ([`crate::relight::lobe_light::LOBE_N`], or the transport's N if finer) where `visibility`
    /// says the transport draws lobes.
    pub fn with_lobe(mut self, visibility: bool) -> Self {
        self.lobe_n = visibility.then(|| crate::relight::lobe_light::LOBE_N.max(self.n));
        self.lobe_support = match self.lobe_n {
            Some(n) => support_solid_angles(n).iter().map(|&a| a as f32).collect(),
            None => Vec::new(),
        };
        self
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
            lobe_n: None,
            lobe_support: Vec::new(),
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
                lobe: self.prepare_lobe(env, rotation)?,
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
            lobe: self.prepare_lobe(env, rotation)?,
        }
        .checked(env)
    }

    /// The Haar coefficients of `env` turned by `rotation` on the lobe's cube, if any.
    fn prepare_lobe(&self, env: &EnvMap, rotation: EnvRotation) -> Result<Option<WaveletLight>> {
        self.lobe_n
            .map(|n| WaveletLight::from_cube(&env.to_cube(n, rotation)?).map_err(|e| named(e, env)))
            .transpose()
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
