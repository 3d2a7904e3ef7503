//! The sparsity-versus-error sweep on a tiny scene: error falls as terms grow, every term gives
//! zero error, the CSV and plots are well formed, and bad lists are clear errors.

mod common;

use common::{SAME_SUM, SAME_VALUE};

use std::path::PathBuf;
use wavelet_prt::store::transport::BakeDomain;

use wavelet_prt::app::studies::bench::{
    BenchExtras, BenchOptions, SUMMARY_TARGETS, compression_sweep, csv, error_plot, run, summary,
    terms_to_reach, write_compression, write_report,
};
use wavelet_prt::bake::reference::render_reference;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation, SunSky};
use wavelet_prt::env::select::Weighting;
use wavelet_prt::relight::Method;
use wavelet_prt::store::transport::Transport;

/// The brute-force reference and the relight of a lossless bake with every term: the same texel
/// sums, one through the f32 Haar rows and the tiled kernel, so they agree to float rounding.
const REFERENCE_MATCH: f64 = 1e-4;
/// Relative L2 a bake with 8-bit values and no thresholding adds: at most half a step (1/254 of a
/// column's largest value after the row scale) per value, summed over the columns a pixel sees.
/// Measured 0.70% with texels integrated, 0.45% with one direction a texel; the bound is 1.4x
/// the larger.
const Q8_ONLY: f64 = 1e-2;
/// Bytes per coefficient as the compression table prints them, with two decimals: rounding moves
/// the value by at most 0.005, and a little more covers the float that was rounded.
const PRINTED_TWO_DECIMALS: f64 = 0.006;
/// Relative rise of the light's K-term error from one K to the next that is still "not rising":
/// the error is √((total − kept) / total) of f64 energy sums, the kept ones summed in the order
/// of the selection, so rounding alone may move it by a few ulps...
const LIGHT_ERROR_ROUNDING_REL: f64 = 1e-6;
/// ...and absolute, for errors near 0, where the difference of two nearly equal sums is all
/// rounding.
const LIGHT_ERROR_ROUNDING_ABS: f64 = 1e-9;
/// SH relighting through the light against the baked SH path, relative difference of their image
/// errors at the same order: at N = 8 the two differ by the texel averages of the basis against
/// its values at the texel samples, a small change to the error, within 2% of it.
const SH_LIGHT_VS_BAKED: f64 = 0.02;

fn tiny_transport(name: &str) -> Transport {
    let scene = common::scene_from(common::SPHERE_ON_PLANE, &format!("bench-{name}"));
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 4,
        lossless: true,
        ..BakeSettings::default()
    };
    bake(&scene, &settings, &|_| {}).unwrap()
}

fn out_dir() -> PathBuf {
    std::env::temp_dir().join(format!("prt-bench-out-{}", std::process::id()))
}

#[test]
fn sweep_is_monotone_exact_at_all_terms_and_well_reported() {
    let t = tiny_transport("sweep");
    let envs = vec![
        (
            "sun".to_string(),
            SunSky::new(30.0, 40.0, 3.0, 3.0).to_latlong(256, 128, 2),
        ),
        ("sky".to_string(), EnvMap::constant(64, 32, [1.0, 0.9, 0.8])),
    ];
    let opts = BenchOptions::defaults_for(&t);
    assert_eq!(*opts.terms.last().unwrap(), 384);
    assert_eq!(opts.sh_orders, vec![1, 2, 3, 4]);
    // Through the light: no more SH terms than the 384 texels.
    assert_eq!(opts.sh_light_orders, vec![1, 2, 3, 4, 6, 8, 11, 16]);
    // The brute-force references of the same scene under both environments.
    let scene = common::scene_from(common::SPHERE_ON_PLANE, "bench-reference");
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 4,
        lossless: true,
        ..BakeSettings::default()
    };
    let references: Vec<_> = envs
        .iter()
        .map(|(_, env)| {
            let cube = env.to_cube(8, EnvRotation::default()).unwrap();
            render_reference(&scene, &cube, &settings).unwrap()
        })
        .collect();
    let extras = BenchExtras {
        gpu: None,
        references: Some(&references),
        reference_coverage: None,
        camera: None,
    };
    let mut calls = 0;
    let points = run(&t, &envs, &opts, &extras, &mut |_, _| calls += 1).unwrap();
    // Every wavelet K and weighting, every SH order, full, and SH through the light, per
    // environment.
    let expected = 2 * (opts.terms.len() * 3 + 4 + 1 + 8);
    assert_eq!(points.len(), expected);
    assert_eq!(calls, expected);
    for env in ["sun", "sky"] {
        // Unweighted selection is the best K-term light: its error never rises with K. (The
        // image error need not be monotone term by term: a kept coefficient can cancel against a
        // missing one.)
        let mut curve: Vec<_> = points
            .iter()
            .filter(|p| p.env == env && p.weighting == Some(Weighting::Unweighted))
            .collect();
        curve.sort_by_key(|p| p.terms);
        for w in curve.windows(2) {
            let (a, b) = (w[0].light_rel_l2.unwrap(), w[1].light_rel_l2.unwrap());
            assert!(
                b <= a * (1.0 + LIGHT_ERROR_ROUNDING_REL) + LIGHT_ERROR_ROUNDING_ABS,
                "{env}: K = {} light error {b} after K = {} light error {a}",
                w[1].terms,
                w[0].terms,
            );
        }
        // The image error falls overall: far below its one-term value at 100 terms.
        let at = |k: usize| curve.iter().find(|p| p.terms == k).unwrap().error.rel_l2;
        assert!(
            at(100) < 0.2 * at(1),
            "K = 100: {}, K = 1: {}",
            at(100),
            at(1)
        );
        // Every term: the same product as full.
        for p in points.iter().filter(|p| p.env == env && p.terms == 384) {
            assert!(
                p.error.rel_l2 < SAME_VALUE,
                "{env} {}: {}",
                p.curve(),
                p.error.rel_l2
            );
        }
        assert!(curve[0].error.rel_l2 > 0.01, "one term should not be exact");
        // A lossless bake relit with every term is the brute-force reference.
        let full = points
            .iter()
            .find(|p| p.env == env && p.method == Method::Full)
            .unwrap();
        assert!(
            full.reference_rel_l2.unwrap() < REFERENCE_MATCH,
            "{:?}",
            full.reference_rel_l2
        );
    }
    // The sun needs far fewer wavelet terms than SH coefficients for 5% error... or SH never
    // gets there at order 4.
    let sun_w: Vec<_> = points
        .iter()
        .filter(|p| p.env == "sun" && p.weighting == Some(Weighting::Unweighted))
        .collect();
    assert!(terms_to_reach(&sun_w, 0.05).is_some());
    let sh: Vec<_> = points
        .iter()
        .filter(|p| p.env == "sun" && p.method == Method::Sh)
        .collect();
    assert_eq!(sh.len(), 4);
    // SH through the light: the baked path's numbers where both exist (N = 8: texel averages of
    // the basis against its values at the texel samples), and far better at 256 terms.
    let light: Vec<_> = points
        .iter()
        .filter(|p| p.env == "sun" && p.method == Method::ShLight)
        .collect();
    assert_eq!(light.len(), 8);
    assert!(light.iter().all(|p| p.curve() == "sh-light"));
    for (a, b) in sh.iter().zip(&light) {
        assert_eq!(a.terms, b.terms);
        let d = (a.error.rel_l2 - b.error.rel_l2).abs();
        assert!(
            d < SH_LIGHT_VS_BAKED * a.error.rel_l2,
            "{} terms: {} vs {}",
            a.terms,
            a.error.rel_l2,
            b.error.rel_l2
        );
    }
    assert!(light[7].error.rel_l2 < 0.5 * light[3].error.rel_l2);

    let text = csv(&points);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), expected + 1);
    let columns = lines[0].split(',').count();
    assert!(lines.iter().all(|l| l.split(',').count() == columns));
    let text = summary(&points);
    assert!(
        text.contains("## sun") && text.contains("brute-force reference"),
        "{text}"
    );
    for metric in ["L2", "H1"] {
        assert!(
            text.contains(&format!("| SH-light / wavelet-none ratio, {metric} |")),
            "{text}"
        );
    }
    // Every ratio in words, never a bare bound such as `> 0.4x`.
    for row in text.lines().filter(|l| l.starts_with("| SH")) {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        for cell in &cells[2..cells.len() - 1] {
            assert!(
                *cell == "—" || (cell.contains("terms") && !cell.starts_with('>')),
                "{row}"
            );
        }
    }
    // The error plot: each curve's error against the reference where it was measured, every
    // stored term's, and a labelled level at each of the summary's errors.
    let (series, figure) = error_plot(&points, "sun");
    assert_eq!(figure.looks.len(), series.len());
    let against = series
        .iter()
        .find(|s| s.label == "wavelet-none vs reference")
        .unwrap();
    assert_eq!(against.points.len(), opts.terms.len());
    assert!(
        series
            .iter()
            .any(|s| s.label == "every stored term vs reference")
    );
    assert_eq!(figure.levels.len(), SUMMARY_TARGETS.len());
    assert!(
        figure
            .levels
            .iter()
            .all(|l| l.lines[0].starts_with("terms for "))
    );

    let dir = out_dir();
    let written = write_report(&dir, &points).unwrap();
    assert_eq!(written.len(), 2 + 2 * 2);
    for p in &written {
        let len = std::fs::metadata(p).unwrap().len();
        assert!(len > 100, "{} is {len} bytes", p.display());
    }
    let png = image::open(dir.join("error_sun.png")).unwrap().to_rgb8();
    let distinct: std::collections::HashSet<[u8; 3]> = png.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 4, "the plot is nearly blank");
}

#[test]
fn bad_lists_are_clear_errors() {
    let t = tiny_transport("lists");
    let base = BenchOptions::defaults_for(&t);
    for (opts, needle) in [
        (
            BenchOptions {
                terms: vec![0, 10],
                ..base.clone()
            },
            "K = 0",
        ),
        (
            BenchOptions {
                terms: vec![385],
                ..base.clone()
            },
            "K = 385",
        ),
        (
            BenchOptions {
                sh_orders: vec![5],
                ..base.clone()
            },
            "SH order: 5",
        ),
        (
            BenchOptions {
                terms: vec![],
                sh_orders: vec![],
                sh_light_orders: vec![],
                ..base.clone()
            },
            "nothing",
        ),
        (
            BenchOptions {
                sh_light_orders: vec![4, 143],
                ..base.clone()
            },
            "order 143",
        ),
    ] {
        let e = opts.validate(&t).unwrap_err().to_string();
        assert!(e.contains(needle) || e.contains("no term counts"), "{e}");
    }
}

#[test]
fn compression_curve_trades_size_for_error() {
    let scene = common::scene_from(common::SPHERE_ON_PLANE, "bench-compression");
    let envs = vec![(
        "sun".to_string(),
        SunSky::new(30.0, 40.0, 3.0, 3.0).to_latlong(256, 128, 2),
    )];
    let base = BakeSettings {
        cube_n: 8,
        ..BakeSettings::default()
    };
    let mut lines = 0;
    let curve = compression_sweep(
        &scene,
        &base,
        &[0.0, 0.05, 0.3],
        &envs,
        &mut |_| lines += 1,
        &|_| {},
    )
    .unwrap();
    assert_eq!(curve.len(), 3);
    assert_eq!(lines, 4);
    // No thresholding: only 8-bit quantisation, at most half a step (1/254 of a column's largest
    // value after the row scale) per value; under a sun a pixel sees a few columns, about 0.4%.
    assert!(curve[0].rel_l2 < Q8_ONLY, "{:?}", curve[0]);
    // Higher thresholds keep fewer coefficients and cost more error.
    assert!(curve[2].kept_fraction < curve[1].kept_fraction);
    assert!(curve[1].kept_fraction < curve[0].kept_fraction);
    assert!(curve[2].rel_l2 > curve[0].rel_l2);
    let dir = out_dir().join("compression");
    let written = write_compression(&dir, &curve).unwrap();
    let csv = std::fs::read_to_string(&written[0]).unwrap();
    assert_eq!(csv.lines().count(), 4);
    assert!(std::fs::metadata(&written[1]).unwrap().len() > 100);
    // The table: a row per threshold whose bytes per coefficient follow from the point's own
    // size and count: for 8-bit values in strips, at least 9/8 bytes (a full strip, 8 values and
    // its place byte) and, with their tables at N = 8, under 4.
    let md = std::fs::read_to_string(&written[2]).unwrap();
    let row = md.lines().find(|l| l.starts_with("| 0.05 |")).expect(&md);
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let per_coefficient: f64 = cells[4].parse().unwrap();
    let expected = curve[1].bytes_per_pixel / curve[1].coefficients_per_pixel;
    assert!(
        (per_coefficient - expected).abs() < PRINTED_TWO_DECIMALS,
        "{row} vs {expected}"
    );
    assert!((1.125..4.0).contains(&per_coefficient), "{row}");
    assert!(cells[5].ends_with('%'), "{row}");
    let e = compression_sweep(&scene, &base, &[], &envs, &mut |_| {}, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("empty"));
}

#[test]
fn paper_run_writes_every_table_and_the_picture_row() {
    // The paper-scale run at a toy size: two scenes at two cubes, the sweep at the larger.
    use wavelet_prt::app::studies::paper::{PaperOptions, run_paper};
    let dir = common::temp_dir("paper");
    let opts = PaperOptions {
        size: 24,
        cubes: vec![4, 8],
    };
    let report = run_paper(&dir, &opts, &mut |_| {}, &|_| {}).unwrap();
    let text = std::fs::read_to_string(&report.markdown).unwrap();
    assert!(report.picture.is_file());
    let rows = |prefix: &str| text.lines().filter(|l| l.starts_with(prefix)).count();
    // Table 1: two scenes at two cubes; then per scene three environments, twice.
    assert_eq!(rows("| diffuse | 6x"), 2, "{text}");
    assert_eq!(rows("| glossy teapot | 6x"), 2, "{text}");
    assert_eq!(rows("| diffuse | blender_"), 4, "{text}");
    assert_eq!(
        rows("| glossy teapot | pmndrs_city_overcast |"),
        2,
        "{text}"
    );
    assert!(text.contains("at 24² with the default"), "{text}");
    assert!(text.contains("SH against wavelets at 6x8x8"), "{text}");
    let comparison: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("| diffuse | blender_sunrise |"))
        .collect();
    // W(200) and SH(200) exist; SH(2,000) and SH(20,000) do not fit 384 texels.
    assert_eq!(comparison[0].matches('—').count(), 4, "{}", comparison[0]);
    // The relight rates, W(100) and W(200) each a time and a rate, from their own relights.
    assert!(text.contains("median of 15 relights"), "{text}");
    let rates: Vec<f64> = comparison[1]
        .split('|')
        .skip(3)
        .filter_map(|c| c.trim().parse().ok())
        .collect();
    assert_eq!(rates.len(), 4, "{}", comparison[1]);
    for pair in rates.chunks(2) {
        let (ms, hz) = (pair[0], pair[1]);
        // Both printed to one decimal.
        assert!(
            hz > 0.0 && (ms - 1000.0 / hz).abs() <= 0.051,
            "{}",
            comparison[1]
        );
    }
    // Every bake is kept for the viewer and the bench.
    assert!(dir.join("diffuse_8.prt").is_file() && dir.join("glossy_teapot_4.prt").is_file());
}

/// The bench of a per-vertex bake of `text` at edge length `edge` under `env`, against the
/// per-pixel brute-force reference of the scene at its diffuse base: (the error of every term
/// against the reference, its error against every term).
fn per_vertex_bench(text: &str, name: &str, edge: f32, env: &EnvMap) -> (f64, f64) {
    use wavelet_prt::bake::reference::render_reference_with;
    let scene = common::scene_from(text, name);
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        domain: BakeDomain::Vertices { edge_length: edge },
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let cube = env.to_cube(8, EnvRotation::default()).unwrap();
    // The per-vertex bake takes texel centres, as `prt bench` has its reference do.
    let per_pixel = BakeSettings {
        domain: BakeDomain::View,
        edge_texel_samples: 0,
        ..settings
    };
    let r = render_reference_with(
        &scene.with_diffuse_materials(),
        &cube,
        &per_pixel,
        &|_, _| {},
    )
    .unwrap();
    let opts = BenchOptions {
        terms: vec![8],
        weightings: vec![Weighting::Transport],
        sh_orders: vec![1],
        sh_light_orders: Vec::new(),
    };
    let references = [r.image];
    let extras = BenchExtras {
        gpu: None,
        references: Some(&references),
        reference_coverage: Some(&r.coverage),
        camera: None,
    };
    let envs = [("env".to_string(), env.clone())];
    let points = run(&t, &envs, &opts, &extras, &mut |_, _| {}).unwrap();
    let full = points.iter().find(|p| p.method == Method::Full).unwrap();
    (full.reference_rel_l2.unwrap(), full.error.rel_l2)
}

#[test]
fn a_per_vertex_bench_measures_the_interpolation_against_the_per_pixel_reference() {
    let sun = SunSky::new(35.0, 20.0, 3.0, 3.0).to_latlong(256, 128, 2);
    // Nothing shadows an open plane under distant light: every vertex has the same light, and
    // interpolating it loses nothing.
    let plane = common::plane_from_above(24, 16, [0.6, 0.5, 0.4], 2.0);
    let (flat, light) = per_vertex_bench(&plane, "bench-pv-plane", 1.0, &sun);
    assert!(flat < SAME_SUM, "flat plane: {flat}");
    assert_eq!(light, 0.0);
    // A sphere's shadow on the ground falls between vertices: finer edges follow it better.
    let (coarse, _) = per_vertex_bench(common::SPHERE_ON_PLANE, "bench-pv-coarse", 0.8, &sun);
    let (fine, _) = per_vertex_bench(common::SPHERE_ON_PLANE, "bench-pv-fine", 0.1, &sun);
    assert!(
        fine > 1e-3,
        "a shadow is not exact at any tessellation: {fine}"
    );
    assert!(coarse > 1.5 * fine, "coarse {coarse} against fine {fine}");
}
