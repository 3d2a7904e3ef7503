//! Sparsity versus error: the curve of Ng et al. 2003. For every environment, the error of wavelet
//! relighting (each weighting) against the kept-term count K and of SH against its coefficient
//! count n², all against `full` (every stored term), with the relight time and the transport bytes
//! touched per point; then a CSV, log-log plots and a markdown summary of the terms each method
//! needs to reach a given error.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::envmap::{EnvMap, EnvRotation};
use crate::error::{PrtError, Result};
use crate::film::Image;
use crate::light::Weighting;
use crate::metrics::{ErrorReport, compare};
use crate::plot::{self, PlotSpec, Series};
use crate::relight::{LightContext, Method, RelightRequest, RelightStats, relight};
use crate::transport::Transport;

/// Error levels the summary reports the needed terms for.
pub const SUMMARY_TARGETS: [f64; 3] = [0.10, 0.05, 0.01];
/// Relights per point; the median time is reported.
const TIMING_RUNS: usize = 3;

/// What to sweep.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Wavelet term counts K.
    pub terms: Vec<usize>,
    /// SH orders n (n² terms).
    pub sh_orders: Vec<usize>,
    /// Wavelet weightings.
    pub weightings: Vec<Weighting>,
}

impl BenchOptions {
    /// Default sweep for a transport: K on a 1-2-5 ladder up to every term, every baked SH order,
    /// all three weightings.
    pub fn defaults_for(t: &Transport) -> Self {
        let total = t.coeff_count();
        let mut terms: Vec<usize> = [1, 2, 5]
            .iter()
            .flat_map(|m| (0..6).map(move |e| m * 10usize.pow(e)))
            .filter(|&k| k < total)
            .collect();
        terms.push(total);
        terms.sort_unstable();
        BenchOptions {
            terms,
            sh_orders: (1..=t.meta.sh_order as usize).collect(),
            weightings: Weighting::ALL.to_vec(),
        }
    }

    /// Checks the lists against the transport.
    pub fn validate(&self, t: &Transport) -> Result<()> {
        let total = t.coeff_count();
        if self.terms.is_empty() && self.sh_orders.is_empty() {
            return Err(PrtError::invalid(
                "bench",
                "no term counts and no SH orders to sweep",
            ));
        }
        if let Some(&k) = self.terms.iter().find(|&&k| k == 0 || k > total) {
            return Err(PrtError::invalid(
                "term list",
                format!("K = {k}; each K must be from 1 to 6·N² = {total}"),
            ));
        }
        let baked = t.meta.sh_order as usize;
        if let Some(&o) = self.sh_orders.iter().find(|&&o| o == 0 || o > baked) {
            return Err(PrtError::invalid(
                "SH order list",
                format!("order {o}; this transport was baked up to order {baked}"),
            ));
        }
        if !self.terms.is_empty() && self.weightings.is_empty() {
            return Err(PrtError::invalid("weighting list", "it is empty"));
        }
        Ok(())
    }
}

/// One measured point.
#[derive(Clone, Debug)]
pub struct BenchPoint {
    pub env: String,
    pub method: Method,
    /// For wavelets.
    pub weighting: Option<Weighting>,
    /// Light terms: K or n².
    pub terms: usize,
    pub error: ErrorReport,
    /// For wavelets: relative L2 of the light approximation itself, ‖L − L_K‖ / ‖L‖ over the Haar
    /// coefficients (Parseval: the same over texels). Non-increasing in K for unweighted selection.
    pub light_rel_l2: Option<f64>,
    /// Median CPU kernel time, milliseconds.
    pub cpu_ms: f64,
    pub bytes_touched: u64,
}

impl BenchPoint {
    /// The curve this point belongs to, e.g. `wavelet-area` or `sh`.
    pub fn curve(&self) -> String {
        match self.weighting {
            Some(w) => format!("{}-{}", self.method, w),
            None => self.method.to_string(),
        }
    }
}

/// Relights once per timing run and keeps the median time.
fn timed(
    t: &Transport,
    ctx: &LightContext,
    light: &crate::relight::PreparedLight,
    req: &RelightRequest,
) -> Result<(Image, RelightStats, f64)> {
    let mut times = Vec::with_capacity(TIMING_RUNS);
    let mut last = None;
    for _ in 0..TIMING_RUNS {
        let (img, stats) = relight(t, ctx, light, req)?;
        times.push(stats.kernel_seconds * 1e3);
        last = Some((img, stats));
    }
    times.sort_by(f64::total_cmp);
    let (img, stats) = last.ok_or_else(|| PrtError::invalid("bench", "no timing run"))?;
    Ok((img, stats, times[times.len() / 2]))
}

/// Runs the sweep. `progress(done, total)` is called after every point.
pub fn run(
    t: &Transport,
    envs: &[(String, EnvMap)],
    opts: &BenchOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<BenchPoint>> {
    opts.validate(t)?;
    let ctx = LightContext::new(t)?;
    let total = envs.len() * (opts.terms.len() * opts.weightings.len() + opts.sh_orders.len());
    let mut points = Vec::with_capacity(total);
    let mask = Some(t.coverage.as_slice());
    for (name, env) in envs {
        let light = ctx.prepare(env, EnvRotation::default())?;
        let full_req = RelightRequest {
            method: Method::Full,
            terms: 0,
            weighting: Weighting::Unweighted,
            sh_order: 1,
        };
        let (full, _) = relight(t, &ctx, &light, &full_req)?;
        for &w in &opts.weightings {
            for &k in &opts.terms {
                let req = RelightRequest {
                    method: Method::Wavelet,
                    terms: k,
                    weighting: w,
                    ..full_req
                };
                let (img, stats, ms) = timed(t, &ctx, &light, &req)?;
                let kept =
                    light
                        .wavelet
                        .select(k, w, &ctx.support_area, Some(&t.transport_magnitude))?;
                let energy = |c: &[f32; 3]| c.iter().map(|v| (*v as f64).powi(2)).sum::<f64>();
                let total_energy: f64 = light.wavelet.coeffs.iter().map(energy).sum();
                let kept_energy: f64 = kept.values.iter().map(energy).sum();
                points.push(BenchPoint {
                    env: name.clone(),
                    method: Method::Wavelet,
                    weighting: Some(w),
                    terms: stats.terms,
                    light_rel_l2: Some(
                        ((total_energy - kept_energy).max(0.0)
                            / total_energy.max(f64::MIN_POSITIVE))
                        .sqrt(),
                    ),
                    error: compare(&img, &full, mask)?,
                    cpu_ms: ms,
                    bytes_touched: stats.bytes_touched,
                });
                progress(points.len(), total);
            }
        }
        for &o in &opts.sh_orders {
            let req = RelightRequest {
                method: Method::Sh,
                sh_order: o,
                ..full_req
            };
            let (img, stats, ms) = timed(t, &ctx, &light, &req)?;
            points.push(BenchPoint {
                env: name.clone(),
                method: Method::Sh,
                weighting: None,
                terms: stats.terms,
                light_rel_l2: None,
                error: compare(&img, &full, mask)?,
                cpu_ms: ms,
                bytes_touched: stats.bytes_touched,
            });
            progress(points.len(), total);
        }
    }
    Ok(points)
}

/// The points as CSV, one line each.
pub fn csv(points: &[BenchPoint]) -> String {
    let mut s = String::from(
        "environment,method,weighting,terms,rel_l2,rel_h1,dssim,psnr_db,rmse,light_rel_l2,cpu_ms,bytes_touched\n",
    );
    for p in points {
        let _ = writeln!(
            s,
            "{},{},{},{},{:.6e},{:.6e},{:.6e},{:.3},{:.6e},{},{:.4},{}",
            p.env,
            p.method,
            p.weighting.map(|w| w.name()).unwrap_or(""),
            p.terms,
            p.error.rel_l2,
            p.error.rel_h1,
            p.error.dssim,
            p.error.psnr_db,
            p.error.rmse,
            p.light_rel_l2
                .map(|e| format!("{e:.6e}"))
                .unwrap_or_default(),
            p.cpu_ms,
            p.bytes_touched
        );
    }
    s
}

/// Terms a curve needs to reach relative L2 `target`: interpolated in log-log between the last
/// point above and the first at or below it; `None` when no point reaches it. Points must be of
/// one curve.
pub fn terms_to_reach(curve: &[&BenchPoint], target: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = curve
        .iter()
        .map(|p| (p.terms as f64, p.error.rel_l2))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let first = pts.iter().position(|&(_, e)| e <= target)?;
    if first == 0 {
        return Some(pts[0].0);
    }
    let ((k0, e0), (k1, e1)) = (pts[first - 1], pts[first]);
    if e1 <= 0.0 || e0 <= 0.0 || e0 == e1 {
        return Some(k1);
    }
    let f = (target.ln() - e0.ln()) / (e1.ln() - e0.ln());
    Some((k0.ln() + f * (k1.ln() - k0.ln())).exp())
}

/// Curves present in `points` for one environment, in a stable order.
fn curves<'a>(points: &'a [BenchPoint], env: &str) -> Vec<(String, Vec<&'a BenchPoint>)> {
    let mut out: Vec<(String, Vec<&BenchPoint>)> = Vec::new();
    for p in points.iter().filter(|p| p.env == env) {
        let name = p.curve();
        match out.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push(p),
            None => out.push((name, vec![p])),
        }
    }
    out
}

fn environments(points: &[BenchPoint]) -> Vec<String> {
    let mut envs: Vec<String> = Vec::new();
    for p in points {
        if !envs.contains(&p.env) {
            envs.push(p.env.clone());
        }
    }
    envs
}

/// The markdown summary: per environment and curve, the terms needed for each target error and
/// the SH-to-wavelet ratio (how many times more terms SH needs).
pub fn summary(points: &[BenchPoint]) -> String {
    let mut s = String::from("# Sparsity versus error\n\n");
    s.push_str(
        "Relative L2 error against relighting with every stored term; terms needed are \
         interpolated in log-log between measured points (— when never reached). A ratio \
         `> r` is a lower bound: SH did not reach the error with every baked order.\n\n",
    );
    let fmt = |v: Option<f64>| v.map(|k| format!("{k:.0}")).unwrap_or_else(|| "—".into());
    for env in environments(points) {
        let _ = writeln!(s, "## {env}\n");
        let _ = write!(s, "| curve |");
        for t in SUMMARY_TARGETS {
            let _ = write!(s, " terms for {:.0}% |", t * 100.0);
        }
        s.push_str("\n|---|");
        s.push_str(&"---:|".repeat(SUMMARY_TARGETS.len()));
        s.push('\n');
        let cs = curves(points, &env);
        for (name, pts) in &cs {
            let _ = write!(s, "| {name} |");
            for t in SUMMARY_TARGETS {
                let _ = write!(s, " {} |", fmt(terms_to_reach(pts, t)));
            }
            s.push('\n');
        }
        if let Some((_, sh)) = cs.iter().find(|(n, _)| n == "sh") {
            let sh_max = sh.iter().map(|p| p.terms).max().unwrap_or(0) as f64;
            let sh_best = sh
                .iter()
                .map(|p| p.error.rel_l2)
                .fold(f64::INFINITY, f64::min);
            let _ = writeln!(
                s,
                "| (SH at {sh_max} terms: {:.1}% error) | | | |",
                100.0 * sh_best
            );
            for (name, pts) in cs.iter().filter(|(n, _)| n.starts_with("wavelet")) {
                let _ = write!(s, "| SH / {name} ratio |");
                for t in SUMMARY_TARGETS {
                    let r = match (terms_to_reach(sh, t), terms_to_reach(pts, t)) {
                        (Some(a), Some(b)) => format!("{:.1}x", a / b),
                        (None, Some(b)) => format!("> {:.1}x", sh_max / b),
                        _ => "—".into(),
                    };
                    let _ = write!(s, " {r} |");
                }
                s.push('\n');
            }
        }
        s.push('\n');
    }
    s
}

/// Writes `bench.csv`, `summary.md` and per environment `error_<env>.png` (error against terms)
/// and `time_<env>.png` (relight time against terms). Returns the paths written.
pub fn write_report(dir: &Path, points: &[BenchPoint]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| PrtError::io(dir, e))?;
    let mut written = Vec::new();
    let text = |path: PathBuf, body: String| -> Result<PathBuf> {
        crate::film::write_atomically(&path, |tmp| {
            std::fs::write(tmp, &body).map_err(|e| PrtError::io(tmp, e))
        })?;
        Ok(path)
    };
    written.push(text(dir.join("bench.csv"), csv(points))?);
    written.push(text(dir.join("summary.md"), summary(points))?);
    for env in environments(points) {
        let cs = curves(points, &env);
        let series = |value: &dyn Fn(&BenchPoint) -> f64| -> Vec<Series> {
            cs.iter()
                .enumerate()
                .map(|(i, (name, pts))| Series {
                    label: name.clone(),
                    points: pts.iter().map(|p| (p.terms as f64, value(p))).collect(),
                    color: plot::PALETTE[i % plot::PALETTE.len()],
                    dashed: name == "sh",
                })
                .collect()
        };
        let spec = |title: String, y: &str| PlotSpec {
            title,
            x_label: "terms".into(),
            y_label: y.into(),
            log_x: true,
            log_y: true,
            width: 800,
            height: 560,
        };
        let p = dir.join(format!("error_{env}.png"));
        plot::write(
            &p,
            &spec(
                format!("{env}: relative L2 error vs terms"),
                "relative L2 error",
            ),
            &series(&|p| p.error.rel_l2),
        )?;
        written.push(p);
        let p = dir.join(format!("time_{env}.png"));
        plot::write(
            &p,
            &spec(format!("{env}: CPU relight time vs terms"), "ms"),
            &series(&|p| p.cpu_ms),
        )?;
        written.push(p);
    }
    Ok(written)
}
