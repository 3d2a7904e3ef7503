//! The studies: the demo and its scenes ([`demo`], with [`orbit`], [`gloss_orbit`], [`dusk`] and
//! [`truck`]), the error, time and storage sweeps ([`bench`](mod@bench), [`gloss_bench`], [`lights_bench`],
//! [`volume_orders`]) and the paper's measurements ([`paper`]): each bakes, relights and measures
//! through the library, and writes its tables, plots and sheets.

use std::path::{Path, PathBuf};

use crate::bake::{BakeProgress, BakeSettings, load_or_bake_logged};
use crate::error::Result;
use crate::scene::Scene;
use crate::store::transport::Transport;

pub mod bench;
pub mod demo;
pub mod dusk;
pub mod gloss_bench;
pub mod gloss_orbit;
pub mod gloss_sh;
pub mod gloss_sweep;
pub mod lights_bench;
pub mod orbit;
pub mod paper;
pub mod truck;
pub mod volume_orders;

/// What the studies of a run share: the folder their outputs go into, the settings their bakes
/// start from, where they say what they do, and their bakes' progress.
pub struct Study<'a> {
    /// The folder of the outputs (bakes reused from it when their scene and settings match).
    pub dir: &'a Path,
    /// The settings the bakes start from.
    pub settings: &'a BakeSettings,
    /// Where a study says what it does, a line at a time.
    pub log: &'a mut dyn FnMut(&str),
    /// The bakes' progress.
    pub progress: &'a (dyn Fn(BakeProgress) + Sync),
}

impl Study<'_> {
    /// Says `line`.
    pub fn log(&mut self, line: &str) {
        (self.log)(line)
    }

    /// The bundled scene `assets/scenes/NAME.toml`, and where the folder keeps its bake,
    /// `NAME.prt`.
    pub fn asset_scene(&self, assets: &Path, name: &str) -> Result<(Scene, PathBuf)> {
        let scene = Scene::load(&assets.join(format!("scenes/{name}.toml")))?;
        Ok((scene, self.dir.join(format!("{name}.prt"))))
    }

    /// Bakes `scene` with `settings` into `path`, saying first "baking SCENE `detail` ...", or
    /// reuses the file where it holds that bake (and says so). Returns the transport, whether it
    /// was reused, and the seconds taken.
    pub fn bake(
        &mut self,
        path: &Path,
        scene: &Scene,
        settings: &BakeSettings,
        detail: &str,
    ) -> Result<(Transport, bool, f64)> {
        let what = format!("baking {} {detail} ...", scene.source_path.display());
        load_or_bake_logged(path, scene, settings, &what, self.log, self.progress)
    }
}

/// The median of `v` (0 when empty).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Relative errors as the cells of a Markdown table row, percentages with two decimals, each
/// cell ` 1.23% |`.
pub fn percent_cells(errors: impl IntoIterator<Item = f64>) -> String {
    errors
        .into_iter()
        .map(|e| format!(" {:.2}% |", 100.0 * e))
        .collect()
}

/// Relative errors as percentages, one decimal, comma-separated.
pub fn percents(errors: &[f64]) -> String {
    errors
        .iter()
        .map(|e| format!("{:.1}%", 100.0 * e))
        .collect::<Vec<_>>()
        .join(", ")
}
