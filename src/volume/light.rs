//! What a medium is relit with at run time: the light (an environment's phase-light table for
//! single scattering, and its SH applied to the fields of the higher orders) and the look the
//! viewer's sliders set (albedo, Henyey–Greenstein g, scattering orders), none of which needs a
//! new bake. Extinction stays baked: the transfer and every scattered field depend on it.

use glam::Vec3;

use super::VolumeTransfer;
use super::render::PhaseLight;
use super::scatter::{ScatterLight, light_sh};
use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;

/// The run-time look of a medium.
#[derive(Clone, Debug, PartialEq)]
pub struct MediumLook {
    /// SH order of the single scattering (at most the baked one).
    pub sh_order: usize,
    /// Single-scattering albedo per channel: order k is scaled by `albedo^k`.
    pub albedo: Vec3,
    /// Henyey–Greenstein asymmetry. Exact for single scattering and for the last scattering of
    /// every higher order; the inner scatterings of orders 2 and above keep the baked g.
    pub g: f32,
    /// Scattering orders drawn, 1 to the file's.
    pub orders: usize,
    /// Whether the orders beyond the last drawn one are added by their geometric tail.
    pub tail: bool,
}

impl MediumLook {
    /// The file's own look: its SH order, albedo and g, every baked order and the tail.
    pub fn of(vt: &VolumeTransfer) -> MediumLook {
        MediumLook {
            sh_order: vt.meta.sh_order,
            albedo: Vec3::from(vt.meta.albedo),
            g: vt.meta.g,
            orders: vt.orders(),
            tail: vt.scatter.is_some(),
        }
    }

    /// Checks the look against the file it relights.
    pub fn validate(&self, vt: &VolumeTransfer) -> Result<()> {
        crate::flags::sh_order(self.sh_order, vt.meta.sh_order)?;
        crate::medium::check_albedo("albedo", self.albedo)?;
        crate::medium::check_g("g", self.g)?;
        if !(1..=vt.orders()).contains(&self.orders) {
            return Err(PrtError::invalid(
                "orders",
                format!(
                    "{}; the file holds scattering orders 1 to {} (bake more with prt volume \
                     bake --orders)",
                    self.orders,
                    vt.orders()
                ),
            ));
        }
        Ok(())
    }
}

/// A medium's light under one environment and look.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeLight {
    /// Lighting times phase, per view direction: single scattering.
    pub phase: PhaseLight,
    /// Albedo per channel.
    pub albedo: Vec3,
    /// Henyey–Greenstein asymmetry.
    pub g: f32,
    /// The scattered radiance of orders 2 and above, per voxel, when drawn.
    pub scatter: Option<ScatterLight>,
}

impl VolumeLight {
    /// The light of `vt` under `cube` with `look`.
    pub fn new(vt: &VolumeTransfer, cube: &CubeMap, look: &MediumLook) -> Result<VolumeLight> {
        look.validate(vt)?;
        Ok(VolumeLight {
            phase: PhaseLight::new(cube, look.sh_order, look.g),
            albedo: look.albedo,
            g: look.g,
            scatter: scattered(vt, cube, look),
        })
    }

    /// This light (made from `cube`) in another look: the phase table is kept when the SH order
    /// and g are the same, so an albedo or orders change only re-applies the scattered fields.
    pub fn with_look(
        self,
        vt: &VolumeTransfer,
        cube: &CubeMap,
        look: &MediumLook,
    ) -> Result<VolumeLight> {
        if self.phase.order != look.sh_order || self.g != look.g {
            return VolumeLight::new(vt, cube, look);
        }
        look.validate(vt)?;
        Ok(VolumeLight {
            phase: self.phase,
            albedo: look.albedo,
            g: look.g,
            scatter: scattered(vt, cube, look),
        })
    }

    /// Single scattering alone under `cube`, with the file's albedo and `g` (the light of a
    /// version 1 file, and of tests that turn `g`).
    pub fn single(cube: &CubeMap, order: usize, albedo: Vec3, g: f32) -> VolumeLight {
        VolumeLight {
            phase: PhaseLight::new(cube, order, g),
            albedo,
            g,
            scatter: None,
        }
    }
}

/// The scattered light of orders 2 and above under `cube` in `look`, when drawn.
fn scattered(vt: &VolumeTransfer, cube: &CubeMap, look: &MediumLook) -> Option<ScatterLight> {
    let fields = vt.scatter.as_ref().filter(|_| look.orders > 1)?;
    Some(ScatterLight::new(
        fields,
        &light_sh(cube, fields.light),
        look.albedo,
        look.orders,
        look.tail,
    ))
}
