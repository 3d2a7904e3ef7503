//! Criterion benchmarks of light preparation (environment -> cube map -> Haar, and the SH light)
//! on blender_sunrise at N = 32 and 64, SH order 8 (the demo bake's), before and after the cached
//! resampling of [`wavelet_prt::env::resample`]:
//!
//! - `exact_prepare`: what `LightContext::prepare` did before, the direct splat for the unturned
//!   cube (SH) and for the turned one (wavelets);
//! - `first_prepare`: the same through the fast path with an empty weight cache and the disk
//!   off (weights recorded);
//! - `fresh_prepare`: a fresh process's first call with the disk on: the unturned weights read
//!   from the file an earlier process wrote (`resample::use_disk`);
//! - `yaw_drag`: cached weights, a new yaw every iteration, the map's unturned SH light kept
//!   from one iteration to the next as the viewer keeps it (`LightContext::prepare_turned`);
//! - `map_switch`: cached weights, alternating between two bundled maps of the same size, each at
//!   a new yaw;
//! - `pitch_drag`: a new pitch every iteration, splatted at sub-cell centres
//!   (`resample::pitch`), the unturned SH light kept as in `yaw_drag`;
//! - `pitched_yaw_drag`: a new yaw every iteration at a pitch of 30°, the same path;
//! - `pitch_drag_recorded`: a new pitch every iteration through weights recorded for it, as every
//!   pitch was prepared before (the cube by `resample_latlong_recorded`, then as `prepare`);
//! - `cube_gather`: one cached cube at a fractional yaw, the resampling alone.
//!
//! Before timing, it prints how far the fast cubes are from the exact splat on blender_sunrise
//! (relative L2 over the cube, median and worst over 24 yaws 15° apart): the pitch's splat at
//! sub-cell centres at pitch −20°, and the recorded weights of the same yaws unpitched.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::env::resample;
use wavelet_prt::env::select::WaveletLight;
use wavelet_prt::math::sh;
use wavelet_prt::relight::{LightContext, PreparedLight};

/// SH order of the demo bake.
const SH_ORDER: usize = 8;
/// The yaw of the first-call and exact benchmarks, a fraction of a pixel off the grid.
const YAW: f64 = 37.0;

fn load(name: &str) -> EnvMap {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/envmaps")
        .join(name);
    EnvMap::load(&path).expect("bundled map")
}

/// `LightContext::prepare` as it was before the cached resampling: the direct splat for both
/// cubes (the SH projection and Haar transform are today's, a small part of the time).
fn exact_prepare(ctx: &LightContext, env: &EnvMap, rotation: EnvRotation) -> PreparedLight {
    let unturned = env.to_cube_exact(ctx.n, EnvRotation::default()).unwrap();
    let unturned_sh = ctx.basis.project_light(&unturned).unwrap();
    let cube = env.to_cube_exact(ctx.n, rotation).unwrap();
    PreparedLight {
        wavelet: WaveletLight::from_cube(&cube).unwrap(),
        sh: sh::Rotation::new(ctx.sh_order, rotation.world_from_map())
            .unwrap()
            .apply_rgb(&unturned_sh),
        lobe: None,
    }
}

/// The accuracy of the pitched and the yawed fast cubes against the exact splat (see the
/// module notes).
fn accuracy(env: &EnvMap) {
    for n in [32, 64] {
        let (mut pitched, mut yawed) = (Vec::new(), Vec::new());
        for k in 0..24 {
            let yaw = k as f64 * 15.0 + 0.37;
            for (pitch, errors) in [(-20.0, &mut pitched), (0.0, &mut yawed)] {
                let r = EnvRotation::new(yaw, pitch);
                let exact = env.to_cube_exact(n, r).unwrap();
                errors.push(env.to_cube(n, r).unwrap().relative_l2(&exact));
            }
        }
        for e in [&mut pitched, &mut yawed] {
            e.sort_by(f64::total_cmp);
        }
        eprintln!(
            "N = {n}, against the exact splat: pitch -20 median {:.2}% worst {:.2}%; \
             unpitched median {:.2}% worst {:.2}%",
            100.0 * pitched[12],
            100.0 * pitched[23],
            100.0 * yawed[12],
            100.0 * yawed[23]
        );
    }
}

fn prepare(c: &mut Criterion) {
    let sunrise = load("blender_sunrise.exr");
    let city = load("blender_city.exr");
    assert_eq!(
        (sunrise.width, sunrise.height),
        (city.width, city.height),
        "the map switch needs two maps of one size"
    );
    accuracy(&sunrise);
    let mut g = c.benchmark_group("light_prepare");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for n in [32, 64] {
        let ctx = LightContext::with_sizes(n, SH_ORDER).unwrap();
        let rotation = EnvRotation::yaw(YAW);
        g.bench_with_input(BenchmarkId::new("exact_prepare", n), &n, |b, _| {
            b.iter(|| exact_prepare(&ctx, black_box(&sunrise), rotation))
        });
        // The first call of a process: with the disk off the weights are recorded; with it on
        // (the default) they are read from the file the previous process left.
        resample::use_disk(false);
        g.bench_with_input(BenchmarkId::new("first_prepare", n), &n, |b, _| {
            b.iter(|| {
                resample::clear_cache();
                ctx.prepare(black_box(&sunrise), rotation).unwrap()
            })
        });
        resample::use_disk(true);
        resample::clear_cache();
        ctx.prepare(&sunrise, rotation).unwrap();
        g.bench_with_input(BenchmarkId::new("fresh_prepare", n), &n, |b, _| {
            b.iter(|| {
                resample::clear_cache();
                ctx.prepare(black_box(&sunrise), rotation).unwrap()
            })
        });
        let unturned_sh = ctx.prepare_sh(&sunrise).unwrap();
        let mut yaw = YAW;
        g.bench_with_input(BenchmarkId::new("yaw_drag", n), &n, |b, _| {
            b.iter(|| {
                yaw += 1.37;
                ctx.prepare_turned(black_box(&sunrise), &unturned_sh, EnvRotation::yaw(yaw))
                    .unwrap()
            })
        });
        let mut i = 0usize;
        g.bench_with_input(BenchmarkId::new("map_switch", n), &n, |b, _| {
            b.iter(|| {
                i += 1;
                let env = if i.is_multiple_of(2) { &sunrise } else { &city };
                ctx.prepare(black_box(env), EnvRotation::yaw(YAW + i as f64))
                    .unwrap()
            })
        });
        let mut pitch = 0.0;
        g.bench_with_input(BenchmarkId::new("pitch_drag", n), &n, |b, _| {
            b.iter(|| {
                pitch += 0.73;
                let rotation = EnvRotation::new(YAW, pitch);
                ctx.prepare_turned(black_box(&sunrise), &unturned_sh, rotation)
                    .unwrap()
            })
        });
        let mut yaw = YAW;
        g.bench_with_input(BenchmarkId::new("pitched_yaw_drag", n), &n, |b, _| {
            b.iter(|| {
                yaw += 1.37;
                let rotation = EnvRotation::new(yaw, 30.0);
                ctx.prepare_turned(black_box(&sunrise), &unturned_sh, rotation)
                    .unwrap()
            })
        });
        let mut pitch = 0.0;
        g.bench_with_input(BenchmarkId::new("pitch_drag_recorded", n), &n, |b, &n| {
            b.iter(|| {
                pitch += 0.73;
                let rotation = EnvRotation::new(YAW, pitch);
                let cube =
                    resample::resample_latlong_recorded(black_box(sunrise.latlong()), n, rotation)
                        .unwrap();
                PreparedLight {
                    wavelet: WaveletLight::from_cube(&cube).unwrap(),
                    sh: sh::Rotation::new(ctx.sh_order, rotation.world_from_map())
                        .unwrap()
                        .apply_rgb(&unturned_sh),
                    lobe: None,
                }
            })
        });
        g.bench_with_input(BenchmarkId::new("cube_gather", n), &n, |b, &n| {
            b.iter(|| sunrise.to_cube(n, black_box(rotation)).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, prepare);
criterion_main!(benches);
