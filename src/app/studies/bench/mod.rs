//! Sparsity versus error: the curve of Ng et al. 2003. For every environment, the error of wavelet
//! relighting (each weighting) against the kept-term count K and of SH against its coefficient
//! count n², all against `full` (every stored term), with the relight time (after an untimed
//! warm-up) and the transport bytes touched per point; then a CSV, log-log plots (the error plot
//! with a line at each summary error, labelled with the terms each curve needs) and a markdown
//! summary of the terms each method needs to reach a given error.

use crate::store::transport::Domain;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::bake::{BakeSettings, bake};
use crate::env::envmap::{EnvMap, EnvRotation};
use crate::env::select::Weighting;
use crate::error::{PrtError, Result};
use crate::output::film::Image;
use crate::output::metrics::{ErrorReport, compare, relative_l2};
use crate::output::plot::{self, Corner, Figure, Level, Look, Marker, PALETTE, PlotSpec, Series};
use crate::relight::{
    Backend, Cpu, LightContext, Method, RelightRequest, RelightStats, Terms, relight,
};
use crate::scene::Scene;
use crate::store::transport::Transport;

mod compression;
pub use compression::{CompressionPoint, compression_sweep, write_compression};

/// Error levels the summary reports the needed terms for.
pub const SUMMARY_TARGETS: [f64; 3] = [0.10, 0.05, 0.01];
/// Timed relights per point, after one untimed; the median time is reported.
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
    /// Median CPU kernel time after a warm-up relight, milliseconds.
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

/// [`timed_runs`] after one untimed call, so that a cold first call (caches, buffers made on
/// first use) is not timed.
pub(crate) fn warm_runs(
    runs: usize,
    mut run: impl FnMut() -> Result<(Image, RelightStats)>,
) -> Result<(Image, RelightStats, f64)> {
    run()?;
    timed_runs(runs, run)
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
/// (one colour per vertex, its diffuse base) is drawn first from `camera` (the bake's when
/// `None`), and compared
/// over the pixels both cover fully: so the error holds the interpolation between vertices.
fn reference_error(
    t: &Transport,
    img: &Image,
    reference: &Image,
    reference_coverage: Option<&[f32]>,
    camera: Option<&crate::scene::Camera>,
) -> Result<f64> {
    if t.attached.domain == Domain::View {
        return relative_l2(img, reference, Some(&t.coverage));
    }
    let camera = match camera {
        Some(c) => c.clone(),
        None => crate::draw::vertex::bake_camera(t)?,
    };
    // The reference is the scene made diffuse: the bake's diffuse base is what it holds to it.
    let colours = crate::draw::vertex::vertex_colours(t, img)?;
    let drawn = crate::draw::vertex::draw(t, colours, &camera, None, 1)?;
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
                let (img, stats, cpu_ms) = warm_runs(TIMING_RUNS, || cpu.relight_terms(&terms))?;
                img.check_finite("relit image")?;
                let gpu_ms = match extras.gpu {
                    Some(gpu) => Some(warm_runs(TIMING_RUNS, || gpu.relight_terms(&terms))?.2),
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

/// The relative L2 error of a point.
const REL_L2: Metric = |p| p.error.rel_l2;

/// What a curve needs to reach an error: its name, the terms (`None`: never reached) and the
/// most terms it was measured at.
pub type Reach<'a> = (&'a str, Option<f64>, f64);

/// The [`Reach`] of a curve for `target` by `metric`.
fn reach<'a>(name: &'a str, curve: &[&BenchPoint], target: f64, metric: Metric) -> Reach<'a> {
    let most = curve.iter().map(|p| p.terms).max().unwrap_or(0) as f64;
    (name, terms_to_reach_by(curve, target, metric), most)
}

/// How the terms SH (or SH through the light) needs for an error compare with a wavelet
/// curve's, in words: how many times as many it needs ("at least" where it never reached the
/// error: a lower bound), or that it wins where it needs fewer. Where the measured terms cannot
/// tell, it says only which curve did not reach the error.
pub fn ratio_words(sh: Reach, wavelet: Reach) -> String {
    let ((s, sk, s_most), (w, wk, w_most)) = (sh, wavelet);
    let times = |r: f64| match r < 10.0 {
        true => format!("{r:.1}×"),
        false => format!("{r:.0}×"),
    };
    match (sk, wk) {
        (Some(a), Some(b)) if (a / b - 1.0).abs() < 0.05 => {
            format!("{s} and {w} need as many terms")
        }
        (Some(a), Some(b)) if a > b => format!("{s} needs {} as many terms as {w}", times(a / b)),
        (Some(a), Some(b)) => format!("{s} wins: {w} needs {} as many terms", times(b / a)),
        (None, Some(b)) if s_most >= b => {
            let at_least = times(s_most / b);
            format!("{s} needs at least {at_least} as many terms as {w}")
        }
        (None, Some(_)) => format!("{s} does not reach it in {s_most:.0} terms"),
        (Some(a), None) if a <= w_most => {
            format!("{s} wins: {w} does not reach it in {w_most:.0} terms")
        }
        (Some(_), None) => format!("{w} does not reach it in {w_most:.0} terms"),
        (None, None) => "—".into(),
    }
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
         interpolated in log-log between measured points (— when never reached). A ratio row \
         says how many times a wavelet curve's terms SH needs (\"at least\" where SH did not \
         reach the error with every baked order: a lower bound), or that SH wins where it needs \
         fewer. `sh-light` is SH through the light (the light projected to n² terms and relit \
         with the full transport), at orders past the baked one; its ratios are given in \
         relative L2 and in the gradient (H1) error.\n\n",
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
                    let words =
                        ratio_words(reach("SH", sh, t, REL_L2), reach(name, pts, t, REL_L2));
                    let _ = write!(s, " {words} |");
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
                        let (a, b) = (reach("SH-light", sl, t, f), reach(name, pts, t, f));
                        let _ = write!(s, " {} |", ratio_words(a, b));
                    }
                    s.push('\n');
                }
            }
        }
        s.push('\n');
    }
    s
}

/// A curve's colour and look: every curve its own colour and marker. Baked SH, which SH through
/// the light matches at low orders, is dashed and narrower, and drawn after it.
fn look_of(name: &str) -> ([u8; 3], Look) {
    let look = Look::new;
    match name {
        "wavelet-none" => (PALETTE[0], look(2, None, Marker::Circle, 3, true)),
        "wavelet-area" => (PALETTE[2], look(2, None, Marker::Triangle, 4, true)),
        "wavelet-transport" => (PALETTE[4], look(2, None, Marker::Diamond, 4, true)),
        "sh" => (PALETTE[1], look(2, Some((6, 3)), Marker::Square, 3, true)),
        "sh-light" => (PALETTE[3], look(4, None, Marker::Circle, 6, false)),
        _ => (PALETTE[6], look(2, Some((2, 2)), Marker::Cross, 4, true)),
    }
}

/// The curves as series of `value` against terms, each in its look, baked SH last.
fn curve_series(cs: &[(String, Vec<&BenchPoint>)], value: Metric) -> (Vec<Series>, Vec<Look>) {
    let mut order: Vec<&(String, Vec<&BenchPoint>)> = cs.iter().collect();
    order.sort_by_key(|(name, _)| name == "sh");
    order
        .into_iter()
        .map(|(name, pts)| {
            let (color, look) = look_of(name);
            let points = pts.iter().map(|p| (p.terms as f64, value(p))).collect();
            let series = Series::new(name.clone(), points, color, look.dash.is_some());
            (series, look)
        })
        .unzip()
}

/// The error plot of `env`: every curve in its own look; each curve's error against the
/// brute-force reference where it was measured (its colour, hollow markers, dotted) and that of
/// every stored term; a level at each [`SUMMARY_TARGETS`] error.
pub fn error_plot(points: &[BenchPoint], env: &str) -> (Vec<Series>, Figure) {
    let cs = curves(points, env);
    let (mut series, mut looks) = curve_series(&cs, REL_L2);
    for (name, pts) in &cs {
        let measured: Vec<(f64, f64)> = pts
            .iter()
            .filter_map(|p| Some((p.terms as f64, p.reference_rel_l2?)))
            .collect();
        if !measured.is_empty() {
            let (color, look) = look_of(name);
            let label = format!("{name} vs reference");
            series.push(Series::new(label, measured, color, true));
            looks.push(Look::new(
                1,
                Some((2, 3)),
                look.marker,
                look.size + 1,
                false,
            ));
        }
    }
    let full = points
        .iter()
        .find(|p| p.env == env && p.method == Method::Full);
    if let Some(p) = full
        && let Some(r) = p.reference_rel_l2
    {
        let label = "every stored term vs reference".to_string();
        series.push(Series::new(
            label,
            vec![(p.terms as f64, r)],
            [40, 40, 40],
            false,
        ));
        looks.push(Look::new(0, None, Marker::Cross, 5, true));
    }
    let levels = SUMMARY_TARGETS.iter().map(|&t| level(&cs, t)).collect();
    let legend = Corner::LowerLeft;
    let figure = Figure {
        looks,
        levels,
        legend,
    };
    (series, figure)
}

/// The level at error `target`: the terms each curve needs, as the summary's table has them
/// (`> n` where a curve never gets there in its n terms), a tick where each crosses it, and in
/// words how SH and SH through the light compare with the wavelet curve needing the fewest.
fn level(cs: &[(String, Vec<&BenchPoint>)], target: f64) -> Level {
    let (mut wavelets, mut others, mut marks) = (Vec::new(), Vec::new(), Vec::new());
    for (name, pts) in cs {
        let (_, k, most) = reach(name, pts, target, REL_L2);
        let needs = k.map_or_else(|| format!("> {most:.0}"), |k| format!("{k:.0}"));
        match name.strip_prefix("wavelet-") {
            Some(w) => wavelets.push(format!("{w} {needs}")),
            None => others.push(format!("{name} {needs}")),
        }
        marks.extend(k.map(|k| (k, look_of(name).0)));
    }
    if !wavelets.is_empty() {
        others.insert(0, format!("wavelet {}", wavelets.join(", ")));
    }
    // One line a level: the terms each curve needs. The ratios are the summary's; on the plot
    // they would hide the curves.
    let lines = vec![format!(
        "terms for {:.0}%: {}",
        100.0 * target,
        others.join("; ")
    )];
    let y = target;
    Level { y, lines, marks }
}

/// Writes `bench.csv`, `summary.md` and per environment `error_<env>.png` (error against terms,
/// [`error_plot`]) and `time_<env>.png` (relight time against terms). Returns the paths written.
pub fn write_report(dir: &Path, points: &[BenchPoint]) -> Result<Vec<PathBuf>> {
    crate::files::create_folder(dir)?;
    let mut written = Vec::new();
    let text = |path: PathBuf, body: String| -> Result<PathBuf> {
        crate::files::write_bytes_atomically(&path, body.as_bytes())?;
        Ok(path)
    };
    written.push(text(dir.join("bench.csv"), csv(points))?);
    written.push(text(dir.join("summary.md"), summary(points))?);
    for env in environments(points) {
        let spec = |title: String, y: &str| PlotSpec {
            title,
            x_label: "terms".into(),
            y_label: y.into(),
            log_x: true,
            log_y: true,
            width: 800,
            height: 560,
        };
        let path = dir.join(format!("error_{env}.png"));
        let (series, figure) = error_plot(points, &env);
        let title = format!("{env}: relative L2 error vs terms");
        plot::write_figure(&path, &spec(title, "relative L2 error"), &series, &figure)?;
        written.push(path);
        let path = dir.join(format!("time_{env}.png"));
        let (series, looks) = curve_series(&curves(points, &env), |p| p.cpu_ms);
        let figure = Figure {
            looks,
            levels: Vec::new(),
            legend: Corner::UpperLeft,
        };
        let title = format!("{env}: CPU relight time vs terms (median of {TIMING_RUNS}, warm)");
        plot::write_figure(&path, &spec(title, "ms"), &series, &figure)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Interpolated terms against their exact value on a curve whose error is exactly c / K:
    /// logarithms and exponentials of f64, a few ulps.
    const INTERPOLATED: f64 = 1e-9;

    /// Points of one curve: (terms, relative L2, error against the reference).
    fn curve(
        env: &str,
        method: Method,
        weighting: Option<Weighting>,
        pts: &[(usize, f64, Option<f64>)],
    ) -> Vec<BenchPoint> {
        pts.iter()
            .map(|&(terms, rel_l2, reference_rel_l2)| BenchPoint {
                env: env.into(),
                method,
                weighting,
                terms,
                error: ErrorReport {
                    rel_l2,
                    rmse: 0.0,
                    psnr_db: 0.0,
                    rel_h1: rel_l2,
                    dssim: 0.0,
                },
                light_rel_l2: None,
                reference_rel_l2,
                cpu_ms: 1.0,
                gpu_ms: None,
                bytes_touched: 0,
            })
            .collect()
    }

    /// A sweep of one environment: wavelets at error c / K (c = 2: 5% at K = 40), SH above 10%
    /// to its 16 terms, SH through the light at 5% with 9 terms, every term; with `reference`,
    /// each point's error against it 1% above.
    fn sweep(env: &str, c: f64, reference: bool) -> Vec<BenchPoint> {
        let r = |e: f64| reference.then_some(e + 0.01);
        let wavelet = [10usize, 100, 1000].map(|k| (k, c / k as f64, r(c / k as f64)));
        let mut points = curve(env, Method::Wavelet, Some(Weighting::Unweighted), &wavelet);
        let sh = [(1, 0.5), (4, 0.3), (9, 0.2), (16, 0.15)].map(|(k, e)| (k, e, r(e)));
        points.extend(curve(env, Method::Sh, None, &sh));
        points.extend(curve(env, Method::Full, None, &[(1000, 0.0, r(0.0))]));
        let light = [(4, 0.1), (9, 0.05), (16, 0.03)].map(|(k, e)| (k, e, r(e)));
        points.extend(curve(env, Method::ShLight, None, &light));
        points
    }

    #[test]
    fn the_terms_for_an_error_are_interpolated_in_log_log() {
        let points = sweep("sun", 2.0, false);
        let w: Vec<&BenchPoint> = points
            .iter()
            .filter(|p| p.method == Method::Wavelet)
            .collect();
        // 2 / K = 5% at K = 40, between the measured 10 and 100.
        let k = terms_to_reach(&w, 0.05).unwrap();
        assert!((k - 40.0).abs() < INTERPOLATED * 40.0, "{k}");
        // Already below at the first point: its terms; below every point: never.
        assert_eq!(terms_to_reach(&w, 0.5), Some(10.0));
        assert_eq!(terms_to_reach(&w, 1e-4), None);
    }

    #[test]
    fn ratios_say_who_needs_more_terms() {
        let w = ("wavelet-none", Some(40.0), 1000.0);
        assert_eq!(
            ratio_words(("SH", Some(160.0), 400.0), w),
            "SH needs 4.0× as many terms as wavelet-none"
        );
        // Not reached in 400 terms: a lower bound.
        assert_eq!(
            ratio_words(("SH", None, 400.0), w),
            "SH needs at least 10× as many terms as wavelet-none"
        );
        // Not reached in 16 terms where wavelets need 40: no bound under 1 that reads as a win.
        assert_eq!(
            ratio_words(("SH", None, 16.0), w),
            "SH does not reach it in 16 terms"
        );
        assert_eq!(
            ratio_words(("SH", Some(8.0), 16.0), w),
            "SH wins: wavelet-none needs 5.0× as many terms"
        );
        assert_eq!(
            ratio_words(("SH", Some(41.0), 64.0), w),
            "SH and wavelet-none need as many terms"
        );
        assert_eq!(
            ratio_words(("SH", Some(8.0), 16.0), ("wavelet-none", None, 10.0)),
            "SH wins: wavelet-none does not reach it in 10 terms"
        );
        assert_eq!(ratio_words(("SH", None, 16.0), ("w", None, 10.0)), "—");
    }

    #[test]
    fn the_summary_words_its_ratios() {
        // sun: wavelets need 40 terms for 5%, SH never gets there in 16 (once printed `> 0.4x`);
        // sky: wavelets need 10, so SH needs at least 1.6 times as many.
        let points = [sweep("sun", 2.0, false), sweep("sky", 0.2, false)].concat();
        let text = summary(&points);
        let rows: Vec<&str> = text
            .lines()
            .filter(|l| l.starts_with("| SH / wavelet-none ratio |"))
            .collect();
        assert_eq!(rows.len(), 2, "{text}");
        assert!(
            !rows[0].contains("0.4") && !rows[0].contains("wins"),
            "{}",
            rows[0]
        );
        assert!(
            rows[0].contains("| SH does not reach it in 16 terms |"),
            "{}",
            rows[0]
        );
        let at_least = "| SH needs at least 1.6× as many terms as wavelet-none |";
        assert!(rows[1].contains(at_least), "{}", rows[1]);
        // SH through the light reaches 5% with 9 terms: it wins.
        let light = text
            .lines()
            .find(|l| l.starts_with("| SH-light / wavelet-none ratio, L2 |"))
            .expect(&text);
        let wins = "| SH-light wins: wavelet-none needs 4.4× as many terms |";
        assert!(light.contains(wins), "{light}");
        assert!(!text.contains("> 0."), "{text}");
    }

    #[test]
    fn the_error_plot_draws_every_curve_apart_and_the_reference_where_measured() {
        let labels = |points: &[BenchPoint]| -> Vec<String> {
            let (series, figure) = error_plot(points, "sun");
            assert_eq!(figure.looks.len(), series.len());
            series.into_iter().map(|s| s.label).collect()
        };
        // Baked SH after SH through the light, which it matches at low orders.
        assert_eq!(
            labels(&sweep("sun", 2.0, false)),
            ["wavelet-none", "sh-light", "sh"]
        );
        let (series, figure) = error_plot(&sweep("sun", 2.0, true), "sun");
        let names: Vec<&str> = series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(
            names,
            [
                "wavelet-none",
                "sh-light",
                "sh",
                "wavelet-none vs reference",
                "sh vs reference",
                "sh-light vs reference",
                "every stored term vs reference"
            ]
        );
        assert_eq!(series[3].points[0], (10.0, 2.0 / 10.0 + 0.01));
        assert_eq!(series[3].points.len(), 3);
        assert_eq!(series[6].points, [(1000.0, 0.01)]);
        // Baked SH narrower than SH through the light; every curve its colour and marker.
        assert!(figure.looks[2].width < figure.looks[1].width);
        let all = [
            "wavelet-none",
            "wavelet-area",
            "wavelet-transport",
            "sh",
            "sh-light",
        ]
        .map(look_of);
        for (i, (color, look)) in all.iter().enumerate() {
            for (other, other_look) in &all[i + 1..] {
                assert_ne!(color, other);
                let same = look.marker == other_look.marker && look.filled == other_look.filled;
                assert!(!same, "{look:?} and {other_look:?}");
            }
        }
        // A level at each of the summary's errors, with the terms its table has.
        let ys: Vec<f64> = figure.levels.iter().map(|l| l.y).collect();
        assert_eq!(ys, SUMMARY_TARGETS);
        let five = &figure.levels[1];
        assert_eq!(
            five.lines,
            ["terms for 5%: wavelet none 40; sh > 16; sh-light 9"]
        );
        // Ticks where the wavelets and SH through the light cross it; SH never does.
        assert_eq!(five.marks.len(), 2);
        assert!((five.marks[0].0 - 40.0).abs() < INTERPOLATED * 40.0);
        assert_eq!(five.marks[1].1, look_of("sh-light").0);
    }

    #[test]
    fn a_cold_first_call_is_not_timed() {
        let mut calls = 0;
        let (_, _, ms) = warm_runs(2, || {
            calls += 1;
            let kernel_seconds = if calls == 1 { 8.0 } else { 0.25 };
            let stats = RelightStats {
                kernel_seconds,
                ..Default::default()
            };
            Ok((Image::new(1, 1), stats))
        })
        .unwrap();
        assert_eq!(calls, 3);
        assert_eq!(ms, 250.0);
    }
}
