//! What the relighting commands share of their flags: the kept wavelet terms when none are asked
//! for, and the local lights (`--light`), taken alike by `prt relight`, `prt reference` and
//! `prt view --screenshot`.

use super::*;
use crate::relight::{LightMix, LightSetting};
use crate::scene::Light;

pub use crate::api::DEFAULT_TERMS;

/// The local lights a relight is asked for.
#[derive(Args, Debug, Clone, Default)]
pub struct LocalLightArgs {
    /// A local light, relit as given (repeatable): NAME=SCALE (its scene file's colour and
    /// intensity times SCALE; 0 turns it off), NAME=R,G,B (that colour at its intensity), or
    /// NAME@POS (a moving light at POS along its baked positions, between two blending them),
    /// as NAME@POS=… with either. Lights not named shine as the scene file says.
    #[arg(long = "light", value_name = "NAME=VALUE")]
    pub lights: Vec<String>,
}

impl LocalLightArgs {
    /// Whether no `--light` was given.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// The settings of `lights` (one per light, in order) after the `--light` arguments.
    pub fn settings(&self, lights: &[Light]) -> Result<Vec<LightSetting>> {
        crate::scene::light_mix::settings_from_args(lights, &self.lights)
    }

    /// The weights of the baked columns of `lights` after the `--light` arguments.
    pub fn mix(&self, lights: &[Light]) -> Result<LightMix> {
        LightMix::new(lights, &self.settings(lights)?)
    }
}
