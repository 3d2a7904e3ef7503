//! Interreflections against answers that do not come from the bake: the white furnace inside a
//! closed sphere, the independent path tracer of `bake::path_tracer` (itself checked against the
//! texel-sum reference for direct light), and the surface cache against exact visibility.

mod common;

use common::{SPHERE_ON_PLANE, full_light, scene_from, sunny_cube};

use wavelet_prt::bake::bounce::BounceVisibility;
use wavelet_prt::bake::path_tracer::path_trace;
use wavelet_prt::bake::reference::render_reference;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::math::cubemap::CubeMap;
use wavelet_prt::output::film::Image;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::relight_wavelet;
use wavelet_prt::store::transport::Transport;

/// The path tracer's own relative noise at 2048 paths a pixel under the small sun: the check
/// against the texel sum is only as sharp as this noise, so it must stay below 2% for that check
/// to say anything.
const PATH_TRACER_NOISE: f64 = 0.02;
/// Relative L2 of the interreflected light alone, surface cache against exact visibility on the
/// same paths: the cache answers a path vertex's visibility from a cache point up to a cell
/// (eight pixel footprints here) away, a small change to the smooth indirect light; on the whole
/// image the README finds the two equally far from a path tracer (1.61%).
const CACHE_VS_EXACT_INDIRECT: f64 = 0.03;
/// Relative error of a furnace pixel of the bake against the geometric series: cosine sampling
/// keeps every path's throughput at a^k, so the bake has no path noise there and only the texel
/// quadrature of the cosine (N = 16, 4 directions a texel) remains, below 0.3%.
const FURNACE_QUADRATURE: f64 = 3e-3;
/// Standard errors by which a furnace pixel of the path tracer may stray from the series: the
/// tracer reports each pixel's own standard error, and four of them is a deviation an unbiased
/// estimator reaches only on rare draws...
const FURNACE_TRACER_SIGMAS: f64 = 4.0;
/// ...plus this much of the series' value, so that a pixel whose estimated standard error comes
/// out near 0 is still allowed the f32 rounding of its accumulated mean.
const FURNACE_TRACER_ROUNDING: f64 = 1e-4;
/// Twelve bounces of albedo 0.7 against the infinite series, relative to its limit: the missing
/// tail is a^13 of the limit, 0.97%, inside 1.4%.
const TWELVE_BOUNCE_TAIL: f64 = 0.014;
/// How many of the path tracer's relative noises a relative L2 against it may reach: an unbiased
/// tracer's relative L2 from the exact image is about its relative noise (`relative_noise`), so
/// three of them, plus each check's allowance for the other side's own error, bound the
/// comparison.
const NOISE_SIGMAS: f64 = 3.0;
/// The texel sum's own error under the small sun, beyond the tracer's noise: 64 directions a
/// texel leave a quadrature error of a few tenths of a percent at the sun's shadow edge.
const TEXEL_SUM_QUADRATURE: f64 = 4e-3;
/// The bounced bake's own error under the small sun, beyond the tracer's noise (relative L2): its
/// 256 paths a sub-sample carry Monte Carlo noise the tracer's estimate does not count, and its
/// 16 directions a texel a quadrature error at the shadow edges; 1% of the image.
const BAKE_BOUNCE_ERROR: f64 = 0.01;
/// The bounced bake's brightest red value against the path tracer's: a firefly (one path's rare
/// large throughput left in a pixel) would stand far above the reference's brightest pixel; half
/// again above it is the most this allows.
const FIREFLY_CEILING: f32 = 1.5;

fn relit(t: &Transport, cube: &CubeMap) -> Image {
    relight_wavelet(t, &full_light(cube)).unwrap().0
}

/// The camera at the centre of a closed sphere of albedo (0.3, 0.5, 0.7).
const FURNACE: &str = r#"
[camera]
eye = [0.0, 0.0, 0.0]
target = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 60.0
width = 6
height = 5

[material.wall]
type = "diffuse"
albedo = [0.3, 0.5, 0.7]

[[shape]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "wall"
"#;

const ALBEDO: [f64; 3] = [0.3, 0.5, 0.7];

/// L a (1 - a^(B+1)) / (1 - a): direct light a L and every bounce another factor a.
fn furnace_radiance(a: f64, bounces: u32, light: f64) -> f64 {
    light * a * (1.0 - a.powi(bounces as i32 + 1)) / (1.0 - a)
}

#[test]
fn white_furnace_inside_a_closed_sphere_sums_the_geometric_series() {
    // Unshadowed, every wall point receives radiance L from its whole hemisphere, and every path
    // from it lands on the wall again. With B bounces a pixel sees L a (1 - a^(B+1)) / (1 - a),
    // which tends to L a / (1 - a). Cosine sampling keeps every path's throughput at a^k, so the
    // bake has no path noise here: only the texel quadrature of the cosine, below 0.3%.
    let scene = scene_from(FURNACE, "furnace");
    let light = 2.0;
    let cube = CubeMap::constant(16, [light as f32; 3]).unwrap();
    for bounces in [0, 1, 3, 12] {
        let settings = BakeSettings {
            cube_n: 16,
            sh_order: 2,
            texel_samples: 4,
            lossless: true,
            unshadowed: true,
            bounces,
            paths: 3,
            ..BakeSettings::default()
        };
        let t = bake(&scene, &settings, &|_| {}).unwrap();
        let img = relit(&t, &cube);
        // The path tracer, independently: its own noise bounds the check.
        let traced = path_trace(&scene, &cube, &settings, 512, &|_, _| {}).unwrap();
        for (i, p) in img.pixels.iter().enumerate() {
            for k in 0..3 {
                let want = furnace_radiance(ALBEDO[k], bounces, light);
                let got = p[k] as f64;
                assert!(
                    (got - want).abs() < FURNACE_QUADRATURE * want,
                    "bake, {bounces} bounces, pixel {i}, channel {k}: {got} vs {want}"
                );
                let traced_value = traced.image.pixels[i][k] as f64;
                let sigma = traced.std_error[i][k] as f64;
                assert!(
                    (traced_value - want).abs()
                        < FURNACE_TRACER_SIGMAS * sigma + FURNACE_TRACER_ROUNDING * want,
                    "path tracer, {bounces} bounces, pixel {i}, channel {k}: {traced_value} vs \
                     {want} (standard error {sigma})"
                );
            }
        }
    }
    // Twelve bounces of albedo 0.7 are within 1.4% of the infinite series.
    let limit = light * 0.7 / 0.3;
    assert!((furnace_radiance(0.7, 12, light) - limit).abs() < TWELVE_BOUNCE_TAIL * limit);
}

/// The sphere on the ground, with a glossy sphere (roughness 0.3) when `glossy`.
fn sphere_scene(glossy: bool) -> wavelet_prt::scene::Scene {
    common::sphere_scene(
        glossy.then_some(0.3),
        if glossy { "glossy" } else { "matte" },
    )
}

#[test]
fn path_tracer_agrees_with_the_texel_sum_for_direct_light() {
    // Two different estimators of the same integral under the same piecewise-constant cube: the
    // texel sum with 64 directions per texel, and light and material sampling with MIS.
    let cube = sunny_cube();
    for glossy in [false, true] {
        let scene = sphere_scene(glossy);
        let settings = BakeSettings {
            cube_n: 16,
            texel_samples: 64,
            ..BakeSettings::default()
        };
        let sum = render_reference(&scene, &cube, &settings).unwrap();
        let traced = path_trace(&scene, &cube, &settings, 2048, &|_, _| {}).unwrap();
        let err = relative_l2(&traced.image, &sum, None).unwrap();
        let noise = traced.relative_noise(None);
        // 64 directions a texel leave a quadrature error of a few tenths of a percent at the
        // sun's shadow edge.
        assert!(
            err < NOISE_SIGMAS * noise + TEXEL_SUM_QUADRATURE,
            "glossy {glossy}: {err} against noise {noise}"
        );
        assert!(noise < PATH_TRACER_NOISE, "glossy {glossy}: noise {noise}");
    }
}

#[test]
fn one_and_two_bounce_bakes_agree_with_the_path_tracer_under_a_small_sun() {
    let cube = sunny_cube();
    for glossy in [false, true] {
        let scene = sphere_scene(glossy);
        for bounces in [1, 2] {
            let settings = BakeSettings {
                cube_n: 16,
                sh_order: 2,
                texel_samples: 16,
                lossless: true,
                bounces,
                paths: 256,
                ..BakeSettings::default()
            };
            let t = bake(&scene, &settings, &|_| {}).unwrap();
            let img = relit(&t, &cube);
            let traced = path_trace(&scene, &cube, &settings, 4096, &|_, _| {}).unwrap();
            let direct = path_trace(
                &scene,
                &cube,
                &BakeSettings {
                    bounces: 0,
                    ..settings.clone()
                },
                1024,
                &|_, _| {},
            )
            .unwrap();
            let err = relative_l2(&img, &traced.image, None).unwrap();
            let noise = traced.relative_noise(None);
            // What the bounces add must be visible above the noise, or the check says nothing.
            let added = relative_l2(&direct.image, &traced.image, None).unwrap();
            eprintln!("glossy {glossy}, {bounces} bounces: {err} (noise {noise}, added {added})");
            assert!(added > 0.05, "{added}");
            assert!(
                err < NOISE_SIGMAS * noise + BAKE_BOUNCE_ERROR,
                "glossy {glossy}, {bounces} bounces: {err} against noise {noise}"
            );
            // No fireflies: the brightest pixel is within 1.5x the reference's.
            let max = |i: &Image| i.pixels.iter().map(|p| p[0]).fold(0.0f32, f32::max);
            assert!(max(&img) < FIREFLY_CEILING * max(&traced.image));
        }
    }
}

#[test]
fn the_surface_cache_matches_exact_visibility_on_the_same_paths() {
    let scene = sphere_scene(false);
    let cube = sunny_cube();
    let settings = |visibility| BakeSettings {
        cube_n: 16,
        sh_order: 2,
        lossless: true,
        bounces: 1,
        paths: 16,
        bounce_visibility: visibility,
        // Cells of eight pixel footprints, so that vertices share cache points.
        cache_spacing: 8.0,
        ..BakeSettings::default()
    };
    let cached = bake(&scene, &settings(BounceVisibility::Cache), &|_| {}).unwrap();
    let exact = bake(&scene, &settings(BounceVisibility::Exact), &|_| {}).unwrap();
    let direct = bake(
        &scene,
        &BakeSettings {
            bounces: 0,
            ..settings(BounceVisibility::Exact)
        },
        &|_| {},
    )
    .unwrap();
    let indirect = |t: &Transport| {
        let (a, d) = (relit(t, &cube), relit(&direct, &cube));
        let mut out = a.clone();
        for (o, q) in out.pixels.iter_mut().zip(&d.pixels) {
            for k in 0..3 {
                o[k] -= q[k];
            }
        }
        out
    };
    let cache_points = cached.meta.cache_points;
    assert!(cache_points > 50, "{cache_points}");
    assert_eq!(exact.meta.cache_points, 0);
    // The interreflected light alone, cache against exact: the same paths, visibility a cell
    // away.
    let err = relative_l2(&indirect(&cached), &indirect(&exact), None).unwrap();
    assert!(
        err < CACHE_VS_EXACT_INDIRECT,
        "indirect light, cache against exact: {err}"
    );
    assert!(err > 0.0, "the cache should not be exact");
}

#[test]
fn bounces_command_writes_the_table_and_the_sheet_and_reference_picks_the_path_tracer() {
    let dir = common::temp_dir("bounces-cli");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let out = dir.join("out");
    let (code, text) = common::prt(&[
        "bounces",
        scene.to_str().unwrap(),
        "--env",
        "sun:35,60",
        "--out",
        out.to_str().unwrap(),
        "--max-bounces",
        "1",
        "--samples",
        "64",
        "--cube",
        "8",
        "--paths",
        "16",
    ]);
    assert_eq!(code, 0, "{text}");
    let table = std::fs::read_to_string(out.join("bounces.md")).unwrap();
    // A header, its rule and one row per bounce count.
    let rows: Vec<&str> = table.lines().filter(|l| l.starts_with("| ")).collect();
    assert_eq!(rows.len(), 3, "{table}");
    assert!(
        rows[1].starts_with("| 0 |") && rows[2].starts_with("| 1 |"),
        "{table}"
    );
    assert!(out.join("bounces_sheet.png").is_file());
    assert!(out.join("reference_1.exr").is_file());
    // With bounces, `prt reference` path traces and states its noise; without, it sums texels.
    let img = dir.join("ref.exr");
    let args = |b: &'static str| {
        vec![
            "reference".to_string(),
            scene.to_str().unwrap().to_string(),
            "--env".into(),
            "sun:35,60".into(),
            "-o".into(),
            img.to_str().unwrap().to_string(),
            "--cube".into(),
            "8".into(),
            "--samples".into(),
            "16".into(),
            "--bounces".into(),
            b.into(),
        ]
    };
    let run = |a: Vec<String>| common::prt(&a.iter().map(|s| s.as_str()).collect::<Vec<_>>());
    let (code, text) = run(args("1"));
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("path traced: 16 paths per pixel, 1 bounces"),
        "{text}"
    );
    let (code, text) = run(args("0"));
    assert_eq!(code, 0, "{text}");
    assert!(!text.contains("path traced"), "{text}");
}
