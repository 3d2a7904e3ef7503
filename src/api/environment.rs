//! An environment ready to light with: a lat-long map made from a file, a bundled name, the
//! procedural sun or an array of pixels, checked once and shared by its clones.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::env::envmap::{EnvMap, check_env_size};
use crate::error::{PrtError, Result};

/// What messages call an environment made from an array.
const ARRAY: &str = "array";

/// Numbers the environments, so that a [`Relighter`](super::Relighter) knows one it has prepared.
static NEXT_ENVIRONMENT: AtomicU64 = AtomicU64::new(0);

/// A lat-long environment map ready to light with: loaded, checked, and shared by its clones.
/// A [`Relighter`](super::Relighter) prepares each environment once per rotation, so relight many times with the
/// same value (or its clones) rather than making it again.
#[derive(Clone, Debug)]
pub struct Environment {
    pub(super) map: Arc<EnvMap>,
    pub(super) id: u64,
}

impl Environment {
    /// A map already made (its pixels as they are).
    pub fn from_map(map: EnvMap) -> Environment {
        Environment {
            map: Arc::new(map),
            id: NEXT_ENVIRONMENT.fetch_add(1, Ordering::Relaxed),
        }
    }

    /// An OpenEXR or Radiance HDR lat-long file. NaN or infinite pixels are an error; negative
    /// ones (lossy compression leaves a few) are clamped to 0 ([`EnvMap::negatives_clamped`]).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Environment> {
        EnvMap::load(path.as_ref()).map(Environment::from_map)
    }

    /// What `--env` takes: a file, a map bundled in the binary by name (`blender_sunrise`), or
    /// the procedural sun and sky as `sun:ELEV,AZIM[,RADIUS]`.
    pub fn from_spec(spec: &str) -> Result<Environment> {
        EnvMap::from_spec(spec).map(Environment::from_map)
    }

    /// The procedural sun and sky with the sun `elevation_deg` above the horizon (-90 to 90)
    /// and `azimuth_deg` round from −Z towards +X, as `sun:ELEV,AZIM` gives it.
    pub fn sun(elevation_deg: f64, azimuth_deg: f64) -> Result<Environment> {
        // Rust writes an f64 so that it reads back the same.
        Environment::from_spec(&format!("sun:{elevation_deg},{azimuth_deg}"))
    }

    /// A lat-long map of `width` x `height` pixels, rows from the zenith down, linear RGB
    /// radiance. Checked as a file is (sizes from 1 to [`crate::env::envmap::MAX_ENV_SIDE`],
    /// finite values, some light), with `width · height` pixels, none of them negative.
    pub fn from_array(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Result<Environment> {
        check_env_size(Path::new(ARRAY), width, height)?;
        if pixels.len() != width * height {
            return Err(PrtError::file(
                ARRAY,
                format!(
                    "{} pixels for a {width} x {height} map, which takes {}",
                    pixels.len(),
                    width * height
                ),
            ));
        }
        let negative = pixels.iter().enumerate().find_map(|(i, p)| {
            let c = p.iter().position(|v| *v < 0.0)?;
            Some((i, c, p[c]))
        });
        if let Some((i, c, v)) = negative {
            return Err(PrtError::file(
                ARRAY,
                format!(
                    "pixel (x = {}, y = {}) channel {} is {v}: radiance must not be negative",
                    i % width,
                    i / width,
                    ["R", "G", "B"][c]
                ),
            ));
        }
        let map = EnvMap::from_pixels(width, height, pixels, ARRAY)?;
        let power: f64 = map.power().iter().sum();
        if power.is_nan() || power <= 0.0 {
            return Err(PrtError::file(
                ARRAY,
                format!(
                    "the map's power (Σ L Ω over its pixels) is {power:.4e}: it lights nothing"
                ),
            ));
        }
        Ok(Environment::from_map(map))
    }

    /// The map.
    pub fn map(&self) -> &EnvMap {
        &self.map
    }

    /// Where it came from: a file, a bundled map, the sun's description or "array".
    pub fn source(&self) -> &str {
        &self.map.source
    }
}
