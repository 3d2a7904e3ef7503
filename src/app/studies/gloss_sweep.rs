//! `prt gloss --roughness R1,R2,…`: the glossy figures across a roughness sweep. Every glossy
//! material of the scene takes each roughness in turn and `prt gloss` runs on it
//! ([`super::gloss_bench::run`], its files in `roughness_R/`); the sweep then sets each method's
//! error against the path tracer (the mean and the worst over the cameras) against roughness:
//! the diffuse base, the lobe per pixel from visibility and SH glossy transfer at each order, in `roughness.md`, `roughness.csv` and `roughness.png`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::gloss_bench::{GlossBenchOptions, GlossBenchReport, run};
use crate::bake::BakeProgress;
use crate::env::envmap::EnvMap;
use crate::error::{PrtError, Result};
use crate::output::plot::{self, PALETTE, PlotSpec, Series};
use crate::relight::gpu::Gpu;
use crate::scene::{Material, Scene};

/// The roughnesses a sweep may take (the materials' own bounds).
const ROUGHNESS: std::ops::RangeInclusive<f32> = 0.02..=1.0;

/// One method's errors across the sweep.
#[derive(Clone, Debug)]
pub struct SweepCurve {
    /// The method: `diffuse base`, `visibility (the lobe per pixel)` or `SH transfer, order n`.
    pub method: String,
    /// Per roughness: the mean and the worst error over the cameras (of the first tessellation).
    pub errors: Vec<[f64; 2]>,
}

/// The sweep's figures.
#[derive(Clone, Debug)]
pub struct SweepReport {
    /// The roughnesses, in the order run.
    pub roughness: Vec<f32>,
    /// Every method's curve.
    pub curves: Vec<SweepCurve>,
    /// What was written.
    pub files: Vec<PathBuf>,
}

/// `scene` with every glossy material at roughness `r`; an error where it has none.
pub fn with_roughness(scene: &Scene, r: f32) -> Result<Scene> {
    if !ROUGHNESS.contains(&r) {
        return Err(PrtError::invalid(
            "--roughness",
            format!("{r}; each must be from 0.02 to 1"),
        ));
    }
    let mut out = scene.clone();
    let mut any = false;
    for m in &mut out.materials {
        if let Material::Glossy { roughness, .. } = m {
            *roughness = r;
            any = true;
        }
    }
    if !any {
        return Err(PrtError::invalid(
            "scene",
            "no glossy material to sweep the roughness of",
        ));
    }
    Ok(out)
}

/// The mean and the worst of `errors`.
fn mean_worst(errors: &[f64]) -> [f64; 2] {
    let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
    [mean, errors.iter().copied().fold(0.0, f64::max)]
}

/// Each method's errors in one run's report, at its first tessellation.
fn methods(r: &GlossBenchReport) -> Vec<(String, [f64; 2])> {
    let Some(first) = r.bakes.first().map(|b| b.edge_factor) else {
        return Vec::new();
    };
    let mut out: Vec<(String, [f64; 2])> = r
        .bakes
        .iter()
        .filter(|b| b.edge_factor == first)
        .map(|b| (b.method.label().to_string(), mean_worst(&b.error)))
        .collect();
    out.extend(r.sh.iter().filter(|s| s.edge_factor == first).map(|s| {
        (
            format!("SH transfer, order {}", s.order),
            mean_worst(&s.error),
        )
    }));
    out
}

/// Runs `prt gloss` with `opts` on `scene` at each of `roughness` into `dir/roughness_R/`, then
/// writes the sweep's table, CSV and plot into `dir`.
pub fn sweep(
    dir: &Path,
    scene: &Scene,
    env: (&str, &EnvMap),
    (opts, roughness): (&GlossBenchOptions, &[f32]),
    gpu: Option<&Gpu>,
    log: &mut dyn FnMut(&str),
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<SweepReport> {
    opts.validate()?;
    if roughness.is_empty() {
        return Err(PrtError::invalid("--roughness", "no roughness to sweep"));
    }
    let scenes = roughness
        .iter()
        .map(|&r| with_roughness(scene, r))
        .collect::<Result<Vec<_>>>()?;
    let mut curves: Vec<SweepCurve> = Vec::new();
    for (k, (r, s)) in roughness.iter().zip(&scenes).enumerate() {
        log(&format!("roughness {r} ..."));
        let sub = dir.join(format!("roughness_{r}"));
        crate::files::create_folder(&sub)?;
        let report = run(&sub, s, env, opts, gpu, log, progress)?;
        for (method, e) in methods(&report) {
            match curves.iter_mut().find(|c| c.method == method) {
                Some(c) => c.errors.push(e),
                None if k == 0 => curves.push(SweepCurve {
                    method,
                    errors: vec![e],
                }),
                None => {}
            }
        }
    }
    let mut report = SweepReport {
        roughness: roughness.to_vec(),
        curves,
        files: vec![
            dir.join("roughness.md"),
            dir.join("roughness.csv"),
            dir.join("roughness.png"),
        ],
    };
    crate::files::write_bytes_atomically(&report.files[0], sweep_markdown(&report).as_bytes())?;
    crate::files::write_bytes_atomically(&report.files[1], sweep_csv(&report).as_bytes())?;
    let series: Vec<Series> = report
        .curves
        .iter()
        .enumerate()
        .map(|(i, c)| {
            Series::new(
                c.method.clone(),
                report
                    .roughness
                    .iter()
                    .zip(&c.errors)
                    .map(|(r, e)| (*r as f64, e[0]))
                    .collect(),
                PALETTE[i % PALETTE.len()],
                c.method.starts_with("SH"),
            )
        })
        .collect();
    plot::write(
        &report.files[2],
        &PlotSpec {
            title: format!(
                "Glossy per-vertex methods under {}: error against roughness",
                env.0
            ),
            x_label: "GGX roughness (α = roughness²)".into(),
            y_label: "relative L2 against the path tracer, mean over the cameras".into(),
            log_x: false,
            log_y: false,
            width: 720,
            height: 440,
        },
        &series,
    )?;
    report.files.extend(
        roughness
            .iter()
            .map(|r| dir.join(format!("roughness_{r}/gloss.md"))),
    );
    Ok(report)
}

/// The sweep as markdown: a row per method, the mean (worst) error per roughness.
pub fn sweep_markdown(r: &SweepReport) -> String {
    let mut s = String::from(
        "# Glossy methods across roughness\n\nRelative L2 against the path tracer lit by the \
         map itself, the mean over the cameras (the worst in brackets); each roughness's own \
         report in `roughness_R/gloss.md`.\n\n| method |",
    );
    for x in &r.roughness {
        let _ = write!(s, " {x} |");
    }
    let _ = writeln!(s, "\n|---|{}", "---:|".repeat(r.roughness.len()));
    for c in &r.curves {
        let _ = write!(s, "| {} |", c.method);
        for e in &c.errors {
            let _ = write!(s, " {:.1}% ({:.1}%) |", 100.0 * e[0], 100.0 * e[1]);
        }
        s.push('\n');
    }
    s
}

/// The sweep as CSV: one line per method and roughness.
pub fn sweep_csv(r: &SweepReport) -> String {
    let mut s = String::from("method,roughness,mean_rel_l2,worst_rel_l2\n");
    for c in &r.curves {
        for (x, e) in r.roughness.iter().zip(&c.errors) {
            let _ = writeln!(s, "{},{x},{:.6},{:.6}", c.method, e[0], e[1]);
        }
    }
    s
}
