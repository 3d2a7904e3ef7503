//! Sparsity versus error: the curve of Ng et al. 2003. For every environment, the error of wavelet
//! relighting (each weighting) against the kept-term count K and of SH against its coefficient
//! count n², all against `full` (every stored term), with the relight time and the transport bytes
//! touched per point; then a CSV, log-log plots and a markdown summary of the terms each method
//! needs to reach a given error.

use crate::store::transport::Domain;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::bake::{BakeSettings, bake};
use crate::error::{PrtError, Result};
use crate::light::envmap::{EnvMap, EnvRotation};
use crate::light::select::Weighting;
use crate::output::film::Image;
use crate::output::metrics::{ErrorReport, compare, relative_l2};
use crate::output::plot::{self, PlotSpec, Series};
use crate::relight::{
    Backend, Cpu, LightContext, Method, RelightRequest, RelightStats, Terms, relight,
};
use crate::scene::Scene;
use crate::store::transport::Transport;

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
    /// SH orders n through the light ([`crate::relight::sh_light`]): the light projected to n² SH terms,
    /// relit with the full stored transport, at any order up to
    /// [`crate::math::sh::MAX_LIGHT_ORDER`].
    pub sh_light_orders: Vec<usize>,
    /// Wavelet weightings.
    pub weightings: Vec<Weighting>,
}

/// The default SH orders through the light: roughly even steps in log(n²) from 1 to 10,000 terms.
pub const SH_LIGHT_ORDERS: [usize; 14] = [1, 2, 3, 4, 6, 8, 11, 16, 22, 32, 45, 64, 80, 100];

impl BenchOptions {
    /// Default sweep for a transport: K on a 1-2-5 ladder up to every term, every baked SH order,
    /// SH through the light up to as many terms as the cube has texels, all three weightings.
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
            sh_orders: (1..=t.meta.identity.sh_order as usize).collect(),
            // No more SH terms than the cube has texels (the paper's SH(20,000) on 24,576).
            sh_light_orders: SH_LIGHT_ORDERS
                .into_iter()
                .filter(|&o| o * o <= total)
                .collect(),
            weightings: Weighting::ALL.to_vec(),
        }
    }

    /// Checks the lists against the transport.
    pub fn validate(&self, t: &Transport) -> Result<()> {
        if self.terms.is_empty() && self.sh_orders.is_empty() && self.sh_light_orders.is_empty() {
            return Err(PrtError::invalid(
                "bench",
                "no term counts and no SH orders to sweep",
            ));
        }
        for &k in &self.terms {
            crate::flags::terms(k, t.meta.identity.cube_n as usize)?;
        }
        for &o in &self.sh_orders {
            crate::flags::sh_order(o, t.meta.identity.sh_order as usize)?;
        }
        let most = crate::math::sh::MAX_LIGHT_ORDER;
        if let Some(&o) = self.sh_light_orders.iter().find(|&&o| o == 0 || o > most) {
            return Err(PrtError::invalid(
                "SH-through-light order list",
                format!("order {o}; orders go from 1 to {most}"),
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
    /// Name of the environment the point was relit under.
    pub env: String,
    /// How the light was approximated: wavelets, SH, SH through the light, or every term.
    pub method: Method,
    /// For wavelets.
    pub weighting: Option<Weighting>,
    /// Light terms: K or n².
    pub terms: usize,
    /// Error of the relit image against the relight with every stored term, over the covered
    /// pixels.
    pub error: ErrorReport,
    /// For wavelets: relative L2 of the light approximation itself, ‖L − L_K‖ / ‖L‖ over the Haar
    /// coefficients (Parseval: the same over texels). Non-increasing in K for unweighted selection.
    pub light_rel_l2: Option<f64>,
    /// Relative L2 against the brute-force reference, when one was rendered.
    pub reference_rel_l2: Option<f64>,
    /// Median CPU kernel time, milliseconds.
    pub cpu_ms: f64,
    /// Median GPU time (terms upload, kernels, readback), milliseconds, when a GPU was used.
    pub gpu_ms: Option<f64>,
    /// Transport bytes the CPU kernel read (entries, column pointers or SH rows).
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

/// Runs a relight `runs` times (at least once) and keeps the last image and statistics and the
/// median kernel time (ms).
pub(crate) fn timed_runs(
    runs: usize,
    mut run: impl FnMut() -> Result<(Image, RelightStats)>,
) -> Result<(Image, RelightStats, f64)> {
    let mut times = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs.max(1) {
        let (img, stats) = run()?;
        times.push(stats.kernel_seconds * 1e3);
        last = Some((img, stats));
    }
    times.sort_by(f64::total_cmp);
    let (img, stats) = last.ok_or_else(|| PrtError::invalid("bench", "no timing run"))?;
    Ok((img, stats, times[times.len() / 2]))
}

/// Optional extras of a sweep: the GPU kernels, and brute-force references (one per
/// environment, in order) to report every point's error against ground truth too.
#[derive(Default)]
pub struct BenchExtras<'a> {
    /// The GPU back-end, whose kernel times are reported beside the CPU's.
    pub gpu: Option<&'a dyn Backend>,
    /// Brute-force reference images, one per environment in the sweep's order; `None` reports no
    /// error against ground truth.
    pub references: Option<&'a [Image]>,
    /// The references' coverage (one value per pixel, shared by every environment). A
    /// per-vertex bake's points are drawn from its camera and compared over the pixels both the
    /// drawing and the reference cover fully; per-pixel points use the transport's coverage.
    pub reference_coverage: Option<&'a [f32]>,
    /// The camera a per-vertex bake is drawn from for the references (the references' own);
    /// `None` takes the bake's camera.
    pub camera: Option<&'a crate::scene::Camera>,
}

/// Relative L2 of a relit image against a brute-force reference. A per-vertex bake's image
/// (one colour per vertex) is drawn first from `camera` (the bake's when `None`), and compared
/// over the pixels both cover fully: so the error holds the interpolation between vertices.
fn reference_error(
    t: &Transport,
    img: &Image,
    reference: &Image,
    reference_coverage: Option<&[f32]>,
    camera: Option<&crate::scene::Camera>,
) -> Result<f64> {
    if t.domain == Domain::View {
        return relative_l2(img, reference, Some(&t.coverage));
    }
    let camera = match camera {
        Some(c) => c.clone(),
        None => crate::relight::vertex::bake_camera(t)?,
    };
    let drawn = crate::relight::vertex::draw_relit(t, img, &camera, None, 1, Default::default())?;
    let both: Vec<f32> = match reference_coverage {
        Some(c) if c.len() == drawn.coverage.len() => drawn
            .coverage
            .iter()
            .zip(c)
            .map(|(a, b)| (*a == 1.0 && *b == 1.0) as u8 as f32)
            .collect(),
        Some(c) => {
            return Err(PrtError::invalid(
                "reference coverage",
                format!("{} values for {} pixels", c.len(), drawn.coverage.len()),
            ));
        }
        None => drawn.coverage.clone(),
    };
    relative_l2(&drawn.image, reference, Some(&both))
}

/// Runs the sweep. `progress(done, total)` is called after every point.
pub fn run(
    t: &Transport,
    envs: &[(String, EnvMap)],
    opts: &BenchOptions,
    extras: &BenchExtras,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<BenchPoint>> {
    opts.validate(t)?;
    if let Some(r) = extras.references
        && r.len() != envs.len()
    {
        return Err(PrtError::invalid(
            "references",
            format!(
                "{} reference images for {} environments",
                r.len(),
                envs.len()
            ),
        ));
    }
    let ctx = LightContext::new(t)?;
    let total = envs.len()
        * (opts.terms.len() * opts.weightings.len()
            + opts.sh_orders.len()
            + opts.sh_light_orders.len()
            + 1);
    let mut points = Vec::with_capacity(total);
    let mask = Some(t.coverage.as_slice());
    for (e, (name, env)) in envs.iter().enumerate() {
        let light = ctx.prepare(env, EnvRotation::default())?;
        let reference = extras.references.map(|r| &r[e]);
        let (full, _) = relight(t, &ctx, &light, &RelightRequest::Full)?;
        // One measured point: the terms made once, then CPU (and GPU) kernel timings and every
        // error.
        let mut measure =
            |req: RelightRequest, terms: Terms, light_rel_l2: Option<f64>| -> Result<()> {
                let cpu = Cpu(t);
                let (img, stats, cpu_ms) = timed_runs(TIMING_RUNS, || cpu.relight_terms(&terms))?;
                img.check_finite("relit image")?;
                let gpu_ms = match extras.gpu {
                    Some(gpu) => Some(timed_runs(TIMING_RUNS, || gpu.relight_terms(&terms))?.2),
                    None => None,
                };
                points.push(BenchPoint {
                    env: name.clone(),
                    method: req.method(),
                    weighting: match req {
                        RelightRequest::Wavelet { weighting, .. } => Some(weighting),
                        _ => None,
                    },
                    terms: stats.terms,
                    light_rel_l2,
                    error: compare(&img, &full, mask)?,
                    reference_rel_l2: match reference {
                        Some(r) => Some(reference_error(
                            t,
                            &img,
                            r,
                            extras.reference_coverage,
                            extras.camera,
                        )?),
                        None => None,
                    },
                    cpu_ms,
                    gpu_ms,
                    bytes_touched: stats.bytes_touched,
                });
                progress(points.len(), total);
                Ok(())
            };
        let of = |req: &RelightRequest| Terms::of(t, &ctx, &light, req);
        let energy = |c: &[f32; 3]| c.iter().map(|v| (*v as f64).powi(2)).sum::<f64>();
        let total_energy: f64 = light.wavelet.coeffs.iter().map(energy).sum();
        for &weighting in &opts.weightings {
            for &k in &opts.terms {
                let req = RelightRequest::Wavelet { k, weighting };
                let terms = of(&req)?;
                let Terms::Wavelet(kept) = &terms else {
                    return Err(PrtError::invalid("bench", "wavelet terms expected"));
                };
                let kept_energy: f64 = kept.values.iter().map(energy).sum();
                let light_error = ((total_energy - kept_energy).max(0.0)
                    / total_energy.max(f64::MIN_POSITIVE))
                .sqrt();
                measure(req, terms, Some(light_error))?;
            }
        }
        for &order in &opts.sh_orders {
            let req = RelightRequest::Sh { order };
            measure(req, of(&req)?, None)?;
        }
        measure(RelightRequest::Full, of(&RelightRequest::Full)?, Some(0.0))?;
        // SH through the light: one projection, at the highest order, serves every order.
        if let Some(&most) = opts.sh_light_orders.iter().max() {
            let cube = env.to_cube(t.meta.identity.cube_n as usize, EnvRotation::default())?;
            let projected = crate::relight::sh_light::ShThroughLight::new(&cube, most)?;
            for &order in &opts.sh_light_orders {
                let terms = Terms::sh_through_light(t, &projected, order)?;
                measure(RelightRequest::ShLight { order }, terms, None)?;
            }
        }
    }
    Ok(points)
}

/// The points as CSV, one line each. Empty fields: not applicable or not measured.
pub fn csv(points: &[BenchPoint]) -> String {
    let mut s = String::from(
        "environment,method,weighting,terms,rel_l2,rel_h1,dssim,psnr_db,rmse,light_rel_l2,\
         reference_rel_l2,cpu_ms,gpu_ms,bytes_touched\n",
    );
    let opt = |v: Option<f64>| v.map(|e| format!("{e:.6e}")).unwrap_or_default();
    for p in points {
        let _ = writeln!(
            s,
            "{},{},{},{},{:.6e},{:.6e},{:.6e},{:.3},{:.6e},{},{},{:.4},{},{}",
            p.env,
            p.method,
            p.weighting.map(|w| w.name()).unwrap_or(""),
            p.terms,
            p.error.rel_l2,
            p.error.rel_h1,
            p.error.dssim,
            p.error.psnr_db,
            p.error.rmse,
            opt(p.light_rel_l2),
            opt(p.reference_rel_l2),
            p.cpu_ms,
            p.gpu_ms.map(|v| format!("{v:.4}")).unwrap_or_default(),
            p.bytes_touched
        );
    }
    s
}

/// Terms a curve needs to reach relative L2 `target`: interpolated in log-log between the last
/// point above and the first at or below it; `None` when no point reaches it. Points must be of
/// one curve.
pub fn terms_to_reach(curve: &[&BenchPoint], target: f64) -> Option<f64> {
    terms_to_reach_by(curve, target, |p| p.error.rel_l2)
}

/// An error measure of a point.
type Metric = fn(&BenchPoint) -> f64;

/// [`terms_to_reach`] for any error measure of the points (relative L2, H1, ...).
pub fn terms_to_reach_by(curve: &[&BenchPoint], target: f64, metric: Metric) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = curve.iter().map(|p| (p.terms as f64, metric(p))).collect();
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
    for p in points
        .iter()
        .filter(|p| p.env == env && p.method != Method::Full)
    {
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
         `> r` is a lower bound: SH did not reach the error with every baked order. `sh-light` \
         is SH through the light (the light projected to n² terms and relit with the full \
         transport), at orders past the baked one; its ratios are given in relative L2 and in \
         the gradient (H1) error.\n\n",
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
        let full = points
            .iter()
            .find(|p| p.env == env && p.method == Method::Full);
        if let Some(r) = full.and_then(|p| p.reference_rel_l2) {
            let _ = writeln!(
                s,
                "| (every stored term against the brute-force reference: {:.3}%) | | | |",
                100.0 * r
            );
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
        if let Some((_, sl)) = cs.iter().find(|(n, _)| n == "sh-light") {
            let most = sl.iter().map(|p| p.terms).max().unwrap_or(0) as f64;
            let best =
                |m: fn(&BenchPoint) -> f64| sl.iter().map(|p| m(p)).fold(f64::INFINITY, f64::min);
            let _ = writeln!(
                s,
                "| (SH through the light at {most} terms: {:.2}% L2, {:.2}% H1) | | | |",
                100.0 * best(|p| p.error.rel_l2),
                100.0 * best(|p| p.error.rel_h1)
            );
            let metrics: [(&str, Metric); 2] =
                [("L2", |p| p.error.rel_l2), ("H1", |p| p.error.rel_h1)];
            for (metric, f) in metrics {
                for (name, pts) in cs.iter().filter(|(n, _)| n.starts_with("wavelet")) {
                    let _ = write!(s, "| SH-light / {name} ratio, {metric} |");
                    for t in SUMMARY_TARGETS {
                        let r = match (terms_to_reach_by(sl, t, f), terms_to_reach_by(pts, t, f)) {
                            (Some(a), Some(b)) => format!("{:.1}x", a / b),
                            (None, Some(b)) => format!("> {:.1}x", most / b),
                            _ => "—".into(),
                        };
                        let _ = write!(s, " {r} |");
                    }
                    s.push('\n');
                }
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
        crate::files::write_bytes_atomically(&path, body.as_bytes())?;
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
                    dashed: name.starts_with("sh"),
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

/// One point of the compression curve: a bake at one threshold, relit with every stored term
/// under one environment, against the lossless bake.
#[derive(Clone, Debug)]
pub struct CompressionPoint {
    /// The bake's threshold ([`BakeSettings::threshold`]): the L2 error allowed per row, relative
    /// to an unshadowed row's norm.
    pub threshold: f32,
    /// Name of the environment the bakes were relit under.
    pub env: String,
    /// Stored nonzeros over the dense entry count.
    pub kept_fraction: f64,
    /// Bytes of the sparse Haar matrix (entries, scales and entry counts) per pixel.
    pub bytes_per_pixel: f64,
    /// Stored coefficients per pixel.
    pub coefficients_per_pixel: f64,
    /// Relative L2 the sparsification adds to the relit image.
    pub rel_l2: f64,
}

/// Bakes `scene` losslessly and at every threshold (other settings from `base`, SH order 1 to
/// save time), relights each with every stored term under every environment and measures the
/// error thresholding adds. `log` receives a line per bake, `progress` each bake's progress.
pub fn compression_sweep(
    scene: &Scene,
    base: &BakeSettings,
    thresholds: &[f32],
    envs: &[(String, EnvMap)],
    log: &mut dyn FnMut(&str),
    progress: &(dyn Fn(crate::bake::BakeProgress) + Sync),
) -> Result<Vec<CompressionPoint>> {
    if thresholds.is_empty() {
        return Err(PrtError::invalid("threshold list", "it is empty"));
    }
    let settings = |lossless: bool, threshold: f32| BakeSettings {
        sh_order: 1,
        lossless,
        threshold,
        ..base.clone()
    };
    for &th in thresholds {
        settings(false, th).validate()?;
    }
    log("baking the lossless reference");
    let exact = bake(scene, &settings(true, 0.0), progress)?;
    let ctx = LightContext::new(&exact)?;
    let all = |t: &Transport, light: &crate::relight::PreparedLight| -> Result<Image> {
        Ok(relight(t, &ctx, light, &RelightRequest::Full)?.0)
    };
    let lights: Vec<_> = envs
        .iter()
        .map(|(_, env)| ctx.prepare(env, EnvRotation::default()))
        .collect::<Result<_>>()?;
    let references: Vec<Image> = lights
        .iter()
        .map(|l| all(&exact, l))
        .collect::<Result<_>>()?;
    let mut points = Vec::new();
    for &th in thresholds {
        log(&format!("baking at threshold {th}"));
        let t = bake(scene, &settings(false, th), progress)?;
        let kept_fraction = t.meta.stats.nonzeros as f64 / t.meta.stats.dense_entries.max(1) as f64;
        let bytes_per_pixel = t.haar_bytes() as f64 / t.pixel_count() as f64;
        for (((name, _), light), reference) in envs.iter().zip(&lights).zip(&references) {
            points.push(CompressionPoint {
                threshold: th,
                env: name.clone(),
                kept_fraction,
                bytes_per_pixel,
                coefficients_per_pixel: t.meta.stats.nonzeros as f64 / t.pixel_count() as f64,
                rel_l2: relative_l2(&all(&t, light)?, reference, Some(&exact.coverage))?,
            });
        }
    }
    Ok(points)
}

/// Writes `compression.csv`, `compression.png` (added error against kept fraction, one curve per
/// environment, Ng et al.'s kept fraction beside them) and `compression.md` (the same as a table
/// with bytes per pixel and per coefficient). Returns the paths written.
pub fn write_compression(dir: &Path, points: &[CompressionPoint]) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| PrtError::io(dir, e))?;
    let mut text = String::from("threshold,environment,kept_fraction,bytes_per_pixel,rel_l2\n");
    for p in points {
        let _ = writeln!(
            text,
            "{},{},{:.6e},{:.2},{:.6e}",
            p.threshold, p.env, p.kept_fraction, p.bytes_per_pixel, p.rel_l2
        );
    }
    let csv_path = dir.join("compression.csv");
    crate::files::write_bytes_atomically(&csv_path, text.as_bytes())?;
    let mut envs: Vec<&str> = Vec::new();
    for p in points {
        if !envs.contains(&p.env.as_str()) {
            envs.push(&p.env);
        }
    }
    let series: Vec<Series> = envs
        .iter()
        .enumerate()
        .map(|(i, env)| Series {
            label: env.to_string(),
            points: points
                .iter()
                .filter(|p| p.env == *env)
                .map(|p| (100.0 * p.kept_fraction, p.rel_l2))
                .collect(),
            color: plot::PALETTE[i % plot::PALETTE.len()],
            dashed: false,
        })
        .collect();
    let mut series = series;
    if let Some(band) = ng_band(points) {
        series.push(band);
    }
    let png = dir.join("compression.png");
    plot::write(
        &png,
        &PlotSpec {
            title: "Error added by sparsification vs stored fraction".into(),
            x_label: "stored nonzeros (% of dense)".into(),
            y_label: "relative L2 error".into(),
            log_x: true,
            log_y: true,
            width: 800,
            height: 560,
        },
        &series,
    )?;
    let md = dir.join("compression.md");
    let table = compression_table(points, &envs);
    crate::files::write_bytes_atomically(&md, table.as_bytes())?;
    Ok(vec![csv_path, png, md])
}

/// The fraction of Haar coefficients Ng et al. 2003 (Table 1) kept at a 6x32x32 cube, in percent:
/// the outline of a band across the measured error range, drawn beside the curves. `None` when
/// there are no points.
fn ng_band(points: &[CompressionPoint]) -> Option<Series> {
    let errors = points.iter().map(|p| p.rel_l2).filter(|e| *e > 0.0);
    let lo = errors.clone().fold(f64::INFINITY, f64::min);
    let hi = errors.fold(0.0, f64::max);
    if !(lo.is_finite() && hi > 0.0) {
        return None;
    }
    Some(Series {
        label: "Ng et al. 2003, 6x32x32: 10-12% kept".into(),
        points: vec![(10.0, lo), (10.0, hi), (12.0, hi), (12.0, lo), (10.0, lo)],
        color: [120, 120, 120],
        dashed: true,
    })
}

/// The compression curve as a Markdown table: one row per threshold with the kept fraction, the
/// bytes per pixel and per stored coefficient (every place, count and scale table counted), and the
/// added error under each environment.
fn compression_table(points: &[CompressionPoint], envs: &[&str]) -> String {
    let mut text = String::from(
        "# Compression curve\n\nEach threshold is a bake of the scene, relit with every stored term \
         and compared with the lossless bake (relative L2 over covered pixels). Bytes count the \
         sparse Haar matrix as the file stores it: the strips' places and values, and each \
         (block, coefficient)'s strip count and scale code.\n\n\
         | threshold | kept | bytes / pixel | bytes / coefficient |",
    );
    for env in envs {
        let _ = write!(text, " {env} |");
    }
    text.push_str("\n|---:|---:|---:|---:|");
    text.push_str(&"---:|".repeat(envs.len()));
    text.push('\n');
    let mut thresholds: Vec<f32> = Vec::new();
    for p in points {
        if !thresholds.contains(&p.threshold) {
            thresholds.push(p.threshold);
        }
    }
    for th in thresholds {
        let row: Vec<&CompressionPoint> = points.iter().filter(|p| p.threshold == th).collect();
        let Some(first) = row.first() else { continue };
        let per_coefficient = first.bytes_per_pixel / first.coefficients_per_pixel.max(1e-30);
        let _ = write!(
            text,
            "| {th} | {:.1}% | {:.0} | {per_coefficient:.2} |",
            100.0 * first.kept_fraction,
            first.bytes_per_pixel
        );
        for env in envs {
            match row.iter().find(|p| p.env == *env) {
                Some(p) => {
                    let _ = write!(text, " {:.2}% |", 100.0 * p.rel_l2);
                }
                None => text.push_str(" — |"),
            }
        }
        text.push('\n');
    }
    text.push_str(
        "\nNg et al. 2003 (Table 1) kept 10-12% of the coefficients at 6x32x32 and 3.1-3.8% at \
         6x64x64, at 2 bytes a coefficient (an 8-bit value and an 8-bit row index in blocks of \
         256 rows).\n",
    );
    text
}
