//! Criterion benchmarks of the hot kernels: SH projection, cube resampling, Haar and K-term
//! selection, and the CPU relight (sparse wavelet product at several K, SH dot products), with the
//! machine's streaming read bandwidth measured in the same run so relight throughput can be
//! quoted as a fraction of it.
//!
//! `relight_gpu` runs the wgpu kernels when an adapter exists.
//!
//! `volume` times the SH self-transfer bake of a 64³ noise cloud with 512 directions at orders 3
//! and 6, and the CPU ray march of a 512² frame (and the GPU march when an adapter exists).
//!
//! The relight benchmarks bake the demo scene once (256², N = 32) into `target/bench-cache/`;
//! set `PRT_BENCH_SIZE=512` for a 512² bake.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use wavelet_prt::app::studies::demo::write_assets;
use wavelet_prt::bake::{BakeSettings, bake, load_if_baked_with};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::env::select::{WaveletLight, Weighting};
use wavelet_prt::math::haar;
use wavelet_prt::relight::strip_kernel::{CachedPanels, StripPath, relight_strips};
use wavelet_prt::relight::{LightContext, light_sh_order, relight_sh, relight_wavelet};
use wavelet_prt::scene::Scene;
use wavelet_prt::store::transport::Transport;

fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets")
}

fn sunrise() -> EnvMap {
    EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).expect("bundled map")
}

fn spherical(c: &mut Criterion) {
    let env = sunrise();
    let mut g = c.benchmark_group("environment");
    g.sample_size(10).measurement_time(Duration::from_secs(3));
    g.bench_function("sh_projection_1024x512_order10", |b| {
        b.iter(|| env.project_sh(10, EnvRotation::default()).unwrap())
    });
    for n in [32, 64] {
        g.bench_with_input(BenchmarkId::new("cube_resample", n), &n, |b, &n| {
            b.iter(|| env.to_cube(n, EnvRotation::default()).unwrap())
        });
    }
    let cube = env.to_cube(64, EnvRotation::default()).unwrap();
    let area: Vec<f32> = haar::support_solid_angles(64)
        .iter()
        .map(|&a| a as f32)
        .collect();
    g.bench_function("haar_6x64x64_rgb", |b| {
        b.iter(|| WaveletLight::from_cube(black_box(&cube)).unwrap())
    });
    let light = WaveletLight::from_cube(&cube).unwrap();
    for w in [Weighting::Unweighted, Weighting::Area] {
        g.bench_with_input(BenchmarkId::new("select_k200_6x64x64", w), &w, |b, &w| {
            b.iter(|| light.select(200, w, &area, None).unwrap())
        });
    }
    g.finish();
}

/// The demo scene baked at the benchmark size, cached between runs.
fn transport() -> Transport {
    let size: u32 = std::env::var("PRT_BENCH_SIZE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(256);
    let cache = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-cache");
    std::fs::create_dir_all(&cache).unwrap();
    let path = cache.join(format!("demo{size}.prt"));
    let root = write_assets(&cache, &mut |l| eprintln!("{l}")).unwrap();
    let text = std::fs::read_to_string(root.join("scenes/demo.toml")).unwrap();
    let text = text
        .replace("width = 256", &format!("width = {size}"))
        .replace("height = 256", &format!("height = {size}"));
    let scene_path = root.join(format!("scenes/demo{size}.toml"));
    std::fs::write(&scene_path, text).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let settings = BakeSettings {
        sh_order: 8,
        ..BakeSettings::default()
    };
    if let Some(t) = load_if_baked_with(&path, &scene, &settings) {
        return t;
    }
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    t.save(&path).unwrap();
    t
}

fn relight(c: &mut Criterion) {
    let t = transport();
    let ctx = LightContext::new(&t).unwrap();
    let light = ctx.prepare(&sunrise(), EnvRotation::default()).unwrap();
    let size = t.meta.width;
    let mut g = c.benchmark_group(format!("relight_{size}"));
    g.sample_size(20).measurement_time(Duration::from_secs(3));
    // Streaming read bandwidth of this machine, measured beside the kernels: a parallel sum in
    // integers, whose adds the compiler may reorder into many independent vector accumulators (a
    // float sum is one serial chain of dependent adds and measures the adder, not the memory).
    // Twice: over 256 MiB, about the size of the demo bake (which a server's last-level cache
    // may hold, as the kernel's own data then is), and over 2 GiB, more than any cache.
    for mib in [256usize, 2048] {
        let buffer: Vec<u64> = (0..(mib as u64) << 17).collect();
        g.throughput(Throughput::Bytes((buffer.len() * 8) as u64));
        g.bench_function(format!("stream_read_{mib}MiB"), |b| {
            b.iter(|| {
                use rayon::prelude::*;
                buffer
                    .par_chunks(1 << 16)
                    .map(|c| c.iter().fold(0u64, |a, &x| a.wrapping_add(x)))
                    .reduce(|| 0, u64::wrapping_add)
            })
        });
    }
    // The product's arithmetic ceiling: its panels alone, on strips that stay in the first-level
    // cache, on one thread (reported in strips a second).
    const ROUNDS: usize = 64;
    if let Some(mut panels) = CachedPanels::new() {
        g.throughput(Throughput::Elements((ROUNDS * CachedPanels::STRIPS) as u64));
        g.bench_function("panels_in_l1_1thread", |b| b.iter(|| panels.add(ROUNDS)));
    }
    // The peer: the same matrix as a plain sprs CSC matrix (f32 values, u32 row indices, 8 bytes
    // a coefficient), multiplied by the whole light on one thread.
    let csc = csc_of(&t);
    let full = light
        .wavelet
        .select(
            t.coeff_count(),
            Weighting::Unweighted,
            &ctx.support_area,
            None,
        )
        .unwrap();
    let mut dense_light = vec![[0.0f32; 3]; t.coeff_count()];
    for (&j, l) in full.indices.iter().zip(&full.values) {
        dense_light[j as usize] = *l;
    }
    g.throughput(Throughput::Bytes((csc.nnz() * 8) as u64));
    g.bench_function("sprs_csc_full_1thread", |b| {
        b.iter(|| {
            let mut y = vec![[0.0f32; 3]; csc.rows()];
            for (col, l) in csc.outer_iterator().zip(&dense_light) {
                for (r, &v) in col.iter() {
                    for k in 0..3 {
                        y[r][k] += v * l[k];
                    }
                }
            }
            y
        })
    });
    drop(csc);
    let total = t.coeff_count();
    for k in [1, 10, 100, 200, 1000, total] {
        let sparse = light
            .wavelet
            .select(k, Weighting::Area, &ctx.support_area, None)
            .unwrap();
        let (_, stats) = relight_wavelet(&t, &sparse).unwrap();
        g.throughput(Throughput::Bytes(stats.bytes_touched));
        g.bench_with_input(BenchmarkId::new("wavelet", k), &sparse, |b, s| {
            b.iter(|| relight_wavelet(&t, s).unwrap())
        });
        // The portable inner loop, the SIMD one's twin, on the same strips.
        if [200, total].contains(&k) {
            let strips = &t.strips;
            // It reads every strip's place, where the SIMD loop skips those of whole slots.
            let places = |path| relight_strips(&t, strips, &sparse, path).1.places;
            let more = places(StripPath::Portable) - places(StripPath::Best);
            g.throughput(Throughput::Bytes(stats.bytes_touched + more));
            g.bench_with_input(BenchmarkId::new("wavelet_portable", k), &sparse, |b, s| {
                b.iter(|| relight_strips(&t, strips, s, StripPath::Portable))
            });
        }
    }
    for order in [4, 8] {
        let sh = light_sh_order(&light.sh, order, t.meta.identity.sh_order as usize).unwrap();
        let (_, stats) = relight_sh(&t, &sh).unwrap();
        g.throughput(Throughput::Bytes(stats.bytes_touched));
        g.bench_with_input(BenchmarkId::new("sh", order), &sh, |b, sh| {
            b.iter(|| relight_sh(&t, sh).unwrap())
        });
    }
    g.finish();
}

/// The transport's Haar matrix (rows x 6 N², values decoded) as a sprs CSC matrix.
fn csc_of(t: &Transport) -> sprs::CsMatI<f32, u32> {
    let mut tri = sprs::TriMatI::<f32, u32>::new((t.row_pixel.len(), t.coeff_count()));
    for b in 0..t.block_count() {
        for j in 0..t.coeff_count() {
            for (row, v) in t.column(b, j) {
                tri.add_triplet(row, j, v);
            }
        }
    }
    tri.to_csc()
}

/// The GPU kernels, when an adapter exists (a software one such as lavapipe counts: its times
/// are for the record, not for comparison with a real GPU). Times include the upload of the kept
/// terms and the image readback.
fn relight_gpu(c: &mut Criterion) {
    let gpu = match wavelet_prt::relight::gpu::Gpu::new() {
        Ok(g) => g,
        Err(e) => {
            eprintln!("relight_gpu: skipped: {e}");
            return;
        }
    };
    eprintln!("relight_gpu: on {}", gpu.adapter);
    let t = transport();
    let g = wavelet_prt::relight::gpu::GpuTransport::upload(&gpu, &t, None).unwrap();
    let ctx = LightContext::new(&t).unwrap();
    let light = ctx.prepare(&sunrise(), EnvRotation::default()).unwrap();
    let mut group = c.benchmark_group(format!("relight_gpu_{}", t.meta.width));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    for k in [1, 100, 1000, t.coeff_count()] {
        let sparse = light
            .wavelet
            .select(k, Weighting::Area, &ctx.support_area, None)
            .unwrap();
        group.bench_with_input(BenchmarkId::new("wavelet", k), &sparse, |b, s| {
            b.iter(|| g.relight_wavelet(&gpu, s).unwrap())
        });
    }
    for order in [4, 8] {
        let sh = light_sh_order(&light.sh, order, t.meta.identity.sh_order as usize).unwrap();
        group.bench_with_input(BenchmarkId::new("sh", order), &sh, |b, sh| {
            b.iter(|| g.relight_sh(&gpu, sh).unwrap())
        });
    }
    group.finish();
}

/// The 64³ noise cloud of the volume benchmarks.
fn cloud64() -> wavelet_prt::medium::Medium {
    use glam::Vec3;
    use wavelet_prt::medium::{DensityGrid, DensitySource, Medium};
    let src = DensitySource::Cloud {
        center: Vec3::ZERO,
        radii: Vec3::new(0.95, 0.8, 0.95),
        seed: 3,
        frequency: 2.5,
        octaves: 4,
        coverage: 0.6,
    };
    Medium {
        grid: DensityGrid::from_fn([64; 3], Vec3::splat(-1.0), Vec3::ONE, |p| src.density(p)),
        extinction: 8.0,
        albedo: Vec3::splat(0.95),
        g: 0.3,
    }
}

fn volume(c: &mut Criterion) {
    use wavelet_prt::volume::{
        MediumLook, PhaseLight, ScatterMeta, ScatterSettings, TransferSettings, VolumeLight,
        VolumeMeta, VolumeTransfer, VolumeView, bake_transfer, render_volume,
        scatter::bake_scatter,
    };
    let medium = cloud64();
    let mut g = c.benchmark_group("volume");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for order in [3, 6] {
        let settings = TransferSettings {
            sh_order: order,
            directions: 512,
            ..TransferSettings::default()
        };
        g.bench_function(format!("transfer_bake_64^3_512dirs_order{order}"), |b| {
            b.iter(|| bake_transfer(black_box(&medium), &settings, &|_, _| {}).unwrap())
        });
    }
    let transfer = bake_transfer(&medium, &TransferSettings::default(), &|_, _| {}).unwrap();
    let vt = VolumeTransfer {
        meta: VolumeMeta {
            dims: [64; 3],
            min: [-1.0; 3],
            max: [1.0; 3],
            extinction: medium.extinction,
            albedo: medium.albedo.to_array(),
            g: medium.g,
            sh_order: 3,
            directions: 512,
            camera: wavelet_prt::store::transport::CameraMeta {
                eye: [0.0, 0.3, 3.2],
                target: [0.0; 3],
                up: [0.0, 1.0, 0.0],
                fov_y_deg: 40.0,
            },
            width: 512,
            height: 512,
            scene_hash: String::new(),
            scatter: None,
        },
        density: medium.grid.data.clone(),
        transfer,
        scatter: None,
    };
    let cube = sunrise().to_cube(32, EnvRotation::default()).unwrap();
    let light = VolumeLight::single(&cube, 3, medium.albedo, medium.g);
    let cam = vt.camera(None, None, None).unwrap();
    g.bench_function("march_cpu_512x512_order3", |b| {
        b.iter(|| render_volume(&vt, &light, &cam, VolumeView::Full))
    });
    g.bench_function("phase_light_table_n32_order3", |b| {
        b.iter(|| PhaseLight::new(&cube, 3, medium.g))
    });
    // The higher scattering orders at the default settings: their bake, the light applied to
    // their fields (what a change of light or albedo costs), and the march that adds them.
    let scatter_settings = ScatterSettings::default();
    let n = scatter_settings.orders;
    g.bench_function(format!("scatter_bake_64^3_orders{n}"), |b| {
        b.iter(|| bake_scatter(black_box(&medium), &scatter_settings, &|_, _| {}).unwrap())
    });
    let fields = bake_scatter(&medium, &scatter_settings, &|_, _| {}).unwrap();
    let vt_orders = VolumeTransfer {
        meta: VolumeMeta {
            scatter: Some(ScatterMeta {
                orders: fields.orders(),
                angular: fields.angular,
                light: fields.light,
                directions: fields.directions,
                tail_ratio: fields.tail_ratio,
            }),
            ..vt.meta.clone()
        },
        scatter: Some(fields),
        ..vt.clone()
    };
    let look = MediumLook::of(&vt_orders);
    g.bench_function(format!("scatter_light_64^3_orders{n}"), |b| {
        b.iter(|| VolumeLight::new(&vt_orders, &cube, &look).unwrap())
    });
    let every = VolumeLight::new(&vt_orders, &cube, &look).unwrap();
    g.bench_function(format!("march_cpu_512x512_order3_orders{n}"), |b| {
        b.iter(|| render_volume(&vt_orders, &every, &cam, VolumeView::Full))
    });
    if let Ok(gpu) = wavelet_prt::relight::gpu::Gpu::new() {
        eprintln!("volume: GPU march on {}", gpu.adapter);
        let mut gv = wavelet_prt::volume::gpu::GpuVolume::new(&gpu, &vt).unwrap();
        g.bench_function("march_gpu_512x512_order3", |b| {
            b.iter(|| gv.render(&gpu, &light, &cam, VolumeView::Full).unwrap())
        });
        let mut gv = wavelet_prt::volume::gpu::GpuVolume::new(&gpu, &vt_orders).unwrap();
        g.bench_function(format!("march_gpu_512x512_order3_orders{n}"), |b| {
            b.iter(|| gv.render(&gpu, &every, &cam, VolumeView::Full).unwrap())
        });
    }
    g.finish();
}

/// The local lights' columns at the many-lights scale: 256 columns of a 256² image, every light
/// added, and one light's change (its column alone), as the viewer relights them.
fn light_columns(c: &mut Criterion) {
    use wavelet_prt::store::transport::LightColumns;
    let (w, h, columns) = (256usize, 256usize, 256usize);
    let mut cols = LightColumns::zeros(columns, w, h);
    let mut state = 1u64;
    let band: Vec<f32> = (0..columns * 3 * h * w)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        })
        .collect();
    cols.set_rows(0, &band);
    let all = vec![[0.3f32, 0.2, 0.1]; columns];
    let mut one = vec![[0.0f32; 3]; columns];
    one[columns / 2] = [0.3, 0.2, 0.1];
    let mut pixels = vec![[0.0f32; 3]; w * h];
    let mut g = c.benchmark_group("light_columns_256x256");
    g.throughput(Throughput::Bytes(cols.bytes() as u64));
    g.bench_function("all_256_lights", |b| {
        b.iter(|| wavelet_prt::relight::columns::add_columns(&cols, &all, &mut pixels))
    });
    g.throughput(Throughput::Bytes((cols.bytes() / columns) as u64));
    g.bench_function("one_light", |b| {
        b.iter(|| wavelet_prt::relight::columns::add_columns(&cols, &one, &mut pixels))
    });
    g.finish();
}

criterion_group!(
    benches,
    spherical,
    relight,
    relight_gpu,
    volume,
    light_columns
);
criterion_main!(benches);
