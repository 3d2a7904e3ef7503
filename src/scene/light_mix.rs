//! The local lights at relight time: each light's switch, colour, intensity and place along its
//! path ([`LightSetting`]), turned into one RGB weight per baked column ([`LightMix`]). The image
//! is the environment's part plus `Σ weight_col ⊙ column_col`, exactly, whatever method, K or
//! SH order relights the environment.
//!
//! A light that moves is baked at each of its positions; a place between them blends the nearest
//! columns: linearly along a path (`at` = 2.25 is a quarter of the way from position 2 to 3),
//! multilinearly in a grid ([`Light::blend`]).

use glam::Vec3;

use crate::error::{PrtError, Result};
use crate::scene::light::Light;

/// How one light is relit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSetting {
    /// Whether it is on.
    pub on: bool,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Intensity, in the units of its kind (the colour multiplies it).
    pub intensity: f32,
    /// Place along each axis of its baked positions, from 0 to the axis's count − 1 (a path
    /// uses the first).
    pub at: [f32; 3],
}

impl LightSetting {
    /// The light as its scene file gives it: on, at its first position.
    pub fn of(light: &Light) -> LightSetting {
        LightSetting {
            on: true,
            color: light.color,
            intensity: light.intensity,
            at: [0.0; 3],
        }
    }

    /// The settings of every light as the scene file gives them.
    pub fn defaults(lights: &[Light]) -> Vec<LightSetting> {
        lights.iter().map(LightSetting::of).collect()
    }
}

/// One RGB weight per light column: what multiplies each column in the relit image.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightMix {
    /// Weight of each column, in column order; empty when no light is on (or the transport has
    /// none).
    pub weights: Vec<[f32; 3]>,
}

impl LightMix {
    /// No local light.
    pub fn none() -> LightMix {
        LightMix::default()
    }

    /// The weights of `lights` relit as `settings` say (one per light, in order).
    pub fn new(lights: &[Light], settings: &[LightSetting]) -> Result<LightMix> {
        if settings.len() != lights.len() {
            return Err(PrtError::invalid(
                "lights",
                format!("{} settings for {} lights", settings.len(), lights.len()),
            ));
        }
        let columns: usize = lights.iter().map(Light::columns).sum();
        let mut weights = vec![[0.0f32; 3]; columns];
        let mut first = 0;
        for (light, s) in lights.iter().zip(settings) {
            let n = light.columns();
            if let Some(a) = (0..3).find(|&a| {
                !(s.at[a].is_finite() && (0.0..=(light.grid[a] - 1) as f32).contains(&s.at[a]))
            }) {
                return Err(PrtError::invalid(
                    "light position",
                    format!(
                        "{:?} for `{}`, whose axis {a} is baked at positions 0 to {}",
                        s.at,
                        light.name,
                        light.grid[a] - 1
                    ),
                ));
            }
            let rgb = s.color * s.intensity;
            if s.on && !rgb.is_finite() {
                return Err(PrtError::invalid(
                    "light",
                    format!("`{}`: colour times intensity is {rgb}", light.name),
                ));
            }
            if s.on && rgb != Vec3::ZERO {
                for (col, share) in light.blend(s.at) {
                    let w = &mut weights[first + col];
                    for k in 0..3 {
                        w[k] += rgb[k] * share;
                    }
                }
            }
            first += n;
        }
        if weights.iter().flatten().all(|v| *v == 0.0) {
            weights.clear();
        }
        Ok(LightMix { weights })
    }

    /// Whether no light adds anything.
    pub fn is_dark(&self) -> bool {
        self.weights.iter().flatten().all(|v| *v == 0.0)
    }

    /// Columns with a nonzero weight: those a relight reads.
    pub fn lit_columns(&self) -> usize {
        self.weights
            .iter()
            .filter(|w| w.iter().any(|v| *v != 0.0))
            .count()
    }
}

/// The settings of `lights` (one per light, in order) as the scene file gives them, then each of
/// `args` applied in turn ([`apply_light_arg`]): what `--light` arguments ask for.
pub fn settings_from_args(lights: &[Light], args: &[impl AsRef<str>]) -> Result<Vec<LightSetting>> {
    let mut settings = LightSetting::defaults(lights);
    for arg in args {
        apply_light_arg(lights, &mut settings, arg.as_ref())?;
    }
    Ok(settings)
}

/// Applies one `--light` argument to `settings`: `NAME=S` relights the light at S times its
/// scene file's colour and intensity (0 turns it off), `NAME=R,G,B` gives it that colour at its
/// scene file's intensity, and `NAME@T` (with or without `=…`) places a moving light at T along
/// its baked positions.
pub fn apply_light_arg(lights: &[Light], settings: &mut [LightSetting], arg: &str) -> Result<()> {
    let bad = |why: String| PrtError::invalid("--light", format!("`{arg}`: {why}"));
    let (target, value) = match arg.split_once('=') {
        Some((t, v)) => (t, Some(v)),
        None => (arg, None),
    };
    let (name, at) = match target.split_once('@') {
        Some((n, t)) => (n, Some(t)),
        None => (target, None),
    };
    let Some(i) = lights.iter().position(|l| l.name == name) else {
        let known = crate::names::known(
            lights.iter().map(|l| l.name.as_str()),
            "the transport has no local lights",
            "its lights are",
        );
        return Err(bad(format!("no light is called `{name}`; {known}")));
    };
    if value.is_none() && at.is_none() {
        return Err(bad(
            "give NAME=SCALE, NAME=R,G,B or NAME@POSITION (X,Y,Z in a grid)".to_string(),
        ));
    }
    let number = |text: &str| -> Result<f32> {
        text.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| bad(format!("`{text}` is not a finite number >= 0")))
    };
    let light = &lights[i];
    let s = &mut settings[i];
    if let Some(t) = at {
        let parts: Vec<&str> = t.split(',').collect();
        if parts.len() > 3 {
            return Err(bad("a position has at most three coordinates".to_string()));
        }
        let mut place = [0.0f32; 3];
        for (a, part) in parts.iter().enumerate() {
            place[a] = number(part)?;
            let last = light.grid[a] - 1;
            if place[a] > last as f32 {
                return Err(bad(format!(
                    "`{name}` is baked at positions 0 to {last} along axis {a} (its grid is {:?})",
                    light.grid
                )));
            }
        }
        s.at = place;
    }
    match value.map(|v| v.split(',').collect::<Vec<_>>()).as_deref() {
        None => {}
        Some([scale]) => {
            let k = number(scale)?;
            s.on = k > 0.0;
            s.color = light.color;
            s.intensity = light.intensity * k;
        }
        Some([r, g, b]) => {
            s.color = Vec3::new(number(r)?, number(g)?, number(b)?);
            s.on = s.color != Vec3::ZERO;
        }
        Some(_) => return Err(bad("give one scale or three colour channels".to_string())),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::light::LightShape;

    fn lights() -> Vec<Light> {
        vec![
            Light {
                name: "a".into(),
                color: Vec3::new(1.0, 0.5, 0.25),
                intensity: 2.0,
                shape: LightShape::Point,
                positions: vec![Vec3::ZERO],
                grid: [1, 1, 1],
            },
            Light {
                name: "b".into(),
                color: Vec3::ONE,
                intensity: 1.0,
                shape: LightShape::Point,
                positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
                grid: [3, 1, 1],
            },
        ]
    }

    #[test]
    fn a_place_between_positions_blends_the_two_nearest_columns() {
        let l = lights();
        let mut s = LightSetting::defaults(&l);
        s[1].at = [1.25, 0.0, 0.0];
        let mix = LightMix::new(&l, &s).unwrap();
        assert_eq!(
            mix.weights,
            vec![[2.0, 1.0, 0.5], [0.0; 3], [0.75; 3], [0.25; 3]]
        );
    }

    #[test]
    fn light_arguments_scale_recolour_place_and_switch_off() {
        let l = lights();
        let mut s = LightSetting::defaults(&l);
        apply_light_arg(&l, &mut s, "a=0.5").unwrap();
        assert_eq!(s[0].intensity, 1.0);
        apply_light_arg(&l, &mut s, "b@2=0,1,0").unwrap();
        assert_eq!((s[1].at, s[1].color), ([2.0, 0.0, 0.0], Vec3::Y));
        apply_light_arg(&l, &mut s, "a=0").unwrap();
        assert!(!s[0].on);
        assert_eq!(
            LightMix::new(&l, &s).unwrap().weights,
            vec![[0.0; 3], [0.0; 3], [0.0; 3], [0.0, 1.0, 0.0]]
        );
        for bad in [
            "c=1",
            "a",
            "a=-1",
            "a=1,2",
            "b@3",
            "a=x",
            "b@1,1",
            "b@0,0,0,0",
        ] {
            assert!(apply_light_arg(&l, &mut s, bad).is_err(), "{bad}");
        }
        let e = apply_light_arg(&l, &mut s, "c=1").unwrap_err().to_string();
        assert!(e.contains("its lights are a, b"), "{e}");
    }
}
