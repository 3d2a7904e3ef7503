//! The CPU wavelet kernel's median time on a transport file at K = 100, 200, 1000 and every term,
//! under an environment map: many products in one process, so two builds can be timed
//! alternately, process by process, where one criterion run each would drift apart on a shared
//! machine.
//!
//! ```sh
//! cargo run --release --example kernel_medians -- prt-demo/demo.prt \
//!     prt-demo/assets/envmaps/blender_sunrise.exr
//! ```
//!
//! Prints one line: the time of the process's first product (K = 200), then the median of 300
//! products at each K (60 for every term), the terms chosen by area weighting as `cargo bench
//! --bench kernels` chooses them, then the median of 40 products at K = 100, 200 and 1000 each
//! after 256 MiB read, so that no cache holds the strips (`cold`).

use std::path::Path;
use std::time::Instant;

use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::env::select::Weighting;
use wavelet_prt::relight::LightContext;
use wavelet_prt::relight::strip_kernel::{StripPath, relight_strips};
use wavelet_prt::store::transport::Transport;

/// Bytes read between cold products, several times any last-level cache.
const EVICT_BYTES: usize = 256 << 20;
/// Cold products timed at each K.
const COLD_RUNS: usize = 40;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, env] = args.as_slice() else {
        return Err("usage: kernel_medians FILE.prt ENV.exr".into());
    };
    let t = Transport::load(Path::new(file))?;
    let env = EnvMap::load(Path::new(env))?;
    let ctx = LightContext::new(&t)?;
    let light = ctx.prepare(&env, EnvRotation::default())?;
    let c = t.coeff_count();
    let mut line = Vec::new();
    // The first product in the process, as a fresh `prt relight` runs it.
    let terms = light
        .wavelet
        .select(200, Weighting::Area, &ctx.support_area, None)?;
    let start = Instant::now();
    std::hint::black_box(relight_strips(&t, &t.strips, &terms, StripPath::Best));
    line.push(format!(
        "first K = 200: {:.3} ms",
        start.elapsed().as_secs_f64() * 1e3
    ));
    // The median of `runs` products of K terms, each after `before`.
    let median_ms =
        |k: usize, runs: usize, before: &dyn Fn()| -> Result<f64, Box<dyn std::error::Error>> {
            let terms = light
                .wavelet
                .select(k, Weighting::Area, &ctx.support_area, None)?;
            let mut ms: Vec<f64> = (0..runs)
                .map(|_| {
                    before();
                    let start = Instant::now();
                    std::hint::black_box(relight_strips(&t, &t.strips, &terms, StripPath::Best));
                    start.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            ms.sort_by(f64::total_cmp);
            Ok(ms[ms.len() / 2])
        };
    for k in [100, 200, 1000, c] {
        let runs = if k > 1000 { 60 } else { 300 };
        line.push(format!("K = {k}: {:.3} ms", median_ms(k, runs, &|| ())?));
    }
    // The same products with the caches emptied first: a new light reads strips that the last
    // one left in no cache, where the repeated products above find a K-term product's few MiB
    // in the last-level cache.
    let sweep: Vec<u64> = (0..EVICT_BYTES as u64 / 8).collect();
    let empty_caches = || {
        std::hint::black_box(sweep.iter().fold(0u64, |a, &v| a ^ v));
    };
    for k in [100, 200, 1000] {
        let cold = median_ms(k, COLD_RUNS, &empty_caches)?;
        line.push(format!("cold K = {k}: {cold:.3} ms"));
    }
    println!("{}", line.join(", "));
    Ok(())
}
