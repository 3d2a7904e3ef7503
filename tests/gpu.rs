//! The GPU kernels against the CPU kernels: wavelet relighting at several K with every
//! weighting, SH at several orders, q8, q16 and f32 transports, an image size tiles do not divide,
//! pixels with several rows, a binding limit lowered so the transport is split into chunks,
//! accumulators in device memory as well as workgroup memory, and more terms than one dispatch
//! takes.
//!
//! Without an adapter these tests print why and pass, unless `PRT_REQUIRE_GPU=1`, when they fail.

mod common;

use common::{GPU_MATCH, SPHERE_ON_PLANE, assets, scene_from};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::env::select::Weighting;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::gpu::{Gpu, GpuTransport};
use wavelet_prt::relight::{
    LightContext, LightMix, Terms, light_sh_order, relight_sh, relight_wavelet,
};
use wavelet_prt::store::transport::Transport;

/// A GPU pixel against the CPU's, relative to the CPU's value: the same products summed in
/// another order in f32, with fused multiply-adds on some devices, so only rounding separates
/// them; per pixel the share `GPU_MATCH` allows over the whole image...
const GPU_PIXEL_REL: f32 = 1e-4;
/// ...with the value taken at least this large, so that a pixel near black is allowed an absolute
/// `GPU_PIXEL_REL` of it rather than a share of its own tiny value.
const GPU_PIXEL_SCALE_FLOOR: f32 = 1e-3;

fn bakes() -> Vec<Transport> {
    let scene = scene_from(SPHERE_ON_PLANE, "gpu");
    let base = BakeSettings {
        cube_n: 8,
        sh_order: 3,
        spp: 4,
        ..BakeSettings::default()
    };
    let lossless = BakeSettings {
        lossless: true,
        ..base.clone()
    };
    let q16 = BakeSettings {
        quantization: wavelet_prt::store::quant::Quantization::Q16,
        ..base.clone()
    };
    vec![
        bake(&scene, &lossless, &|_| {}).unwrap(),
        bake(&scene, &base, &|_| {}).unwrap(),
        bake(&scene, &q16, &|_| {}).unwrap(),
    ]
}

fn check(gpu: &Gpu, t: &Transport, limit: Option<u64>, shared_rows: Option<u32>) -> usize {
    let g = GpuTransport::upload(gpu, t, limit).unwrap();
    if let Some(rows) = shared_rows {
        g.set_shared_rows(gpu, rows);
    }
    let ctx = LightContext::new(t).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let light = ctx.prepare(&env, EnvRotation::yaw(30.0)).unwrap();
    let mask = Some(t.coverage.as_slice());
    for w in Weighting::ALL {
        for k in [1, 10, 100, t.coeff_count()] {
            let sparse = light
                .wavelet
                .select(k, w, &ctx.support_area, Some(&t.transport_magnitude))
                .unwrap();
            let (cpu, _) = relight_wavelet(t, &sparse).unwrap();
            let (dev, stats) = g.relight_wavelet(gpu, &sparse).unwrap();
            assert_eq!(stats.terms, k);
            let e = relative_l2(&dev, &cpu, mask).unwrap();
            assert!(e < GPU_MATCH, "{w} K = {k}: GPU vs CPU {e}");
            // Uncovered pixels are black on both.
            for (a, b) in dev.pixels.iter().zip(&cpu.pixels) {
                assert!(
                    (a[0] - b[0]).abs() <= GPU_PIXEL_REL * b[0].abs().max(GPU_PIXEL_SCALE_FLOOR)
                );
            }
        }
    }
    for order in 1..=3 {
        let sh = light_sh_order(&light.sh, order, 3).unwrap();
        let (cpu, _) = relight_sh(t, &sh).unwrap();
        let (dev, _) = g.relight_sh(gpu, &sh).unwrap();
        let e = relative_l2(&dev, &cpu, mask).unwrap();
        assert!(e < GPU_MATCH, "SH order {order}: GPU vs CPU {e}");
    }
    g.chunk_count()
}

#[test]
fn gpu_equals_cpu() {
    let Some(gpu) = common::gpu_or_skip("gpu_equals_cpu") else {
        return;
    };
    for t in bakes() {
        assert_eq!(check(&gpu, &t, None, None), 1);
    }
}

#[test]
fn gpu_equals_cpu_when_split_across_bindings() {
    let Some(gpu) = common::gpu_or_skip("gpu_equals_cpu_when_split_across_bindings") else {
        return;
    };
    for t in bakes() {
        // As small as the largest tile allows, so that a few tiles fill a binding: a strip is
        // its place and 8 values, a block's slots two words a coefficient.
        let value_bytes = t.meta.identity.quantization.value_bytes() as u64;
        let strips = &t.strips;
        let c = t.coeff_count();
        let tile_bytes = |tile: usize| -> u64 {
            t.blocks(tile)
                .map(|b| {
                    let n: u64 = strips.block_slots(b, c).map(|s| s.count as u64).sum();
                    (n * (1 + 8 * value_bytes)).max(8 * c as u64)
                })
                .sum::<u64>()
                + 4
        };
        let limit = (0..t.tile_count())
            .map(tile_bytes)
            .max()
            .unwrap()
            .max(t.row_pixel.len() as u64 * 16);
        // Also with every tile accumulating in device memory rather than workgroup memory.
        let chunks = check(&gpu, &t, Some(limit), Some(0));
        assert!(
            chunks >= 2,
            "only {chunks} chunk(s) at a {limit}-byte limit"
        );
    }
}

#[test]
fn bad_lights_are_errors_on_the_gpu_too() {
    let Some(gpu) = common::gpu_or_skip("bad_lights_are_errors_on_the_gpu_too") else {
        return;
    };
    let t = &bakes()[1];
    let g = GpuTransport::upload(&gpu, t, None).unwrap();
    let bad = wavelet_prt::env::select::SparseLight {
        indices: vec![t.coeff_count() as u32],
        values: vec![[1.0; 3]],
    };
    let e = g.relight_wavelet(&gpu, &bad).unwrap_err().to_string();
    assert!(
        e.contains("do not fit a transport with 384 coefficients"),
        "{e}"
    );
    let e = g
        .relight_sh(&gpu, &vec![[1.0; 3]; 10])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("10 coefficients for a transport baked with 9"),
        "{e}"
    );
}

/// Reads an RGBA32F texture back through a buffer with 256-byte aligned rows.
/// A texture the relight of `t` can be drawn into and read back from.
fn relight_texture(gpu: &Gpu, t: &Transport) -> wgpu::Texture {
    wavelet_prt::gpu::texture_2d(
        &gpu.device,
        "relight",
        [t.meta.width, t.meta.height],
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
    )
}

fn read_texture(gpu: &Gpu, texture: &wgpu::Texture) -> Vec<[f32; 4]> {
    let (w, h) = (texture.width() as usize, texture.height() as usize);
    let row = (w * 16).div_ceil(256) * 256;
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (row * h) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row as u32),
                rows_per_image: None,
            },
        },
        texture.size(),
    );
    gpu.queue.submit([encoder.finish()]);
    buffer
        .slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.unwrap());
    gpu.device
        .poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: None,
        })
        .unwrap();
    let view = buffer.slice(..).get_mapped_range().unwrap();
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        let line: &[[f32; 4]] = bytemuck::cast_slice(&view[y * row..y * row + w * 16]);
        out.extend_from_slice(line);
    }
    out
}

#[test]
fn relight_into_a_texture_equals_the_read_back_image() {
    let Some(gpu) = common::gpu_or_skip("relight_into_a_texture_equals_the_read_back_image") else {
        return;
    };
    let t = &bakes()[1];
    let g = GpuTransport::upload(&gpu, t, None).unwrap();
    let ctx = LightContext::new(t).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_city.exr")).unwrap();
    let light = ctx.prepare(&env, EnvRotation::default()).unwrap();
    let sparse = light
        .wavelet
        .select(50, Weighting::Area, &ctx.support_area, None)
        .unwrap();
    let texture = relight_texture(&gpu, t);
    let (buffered, _) = g.relight_wavelet(&gpu, &sparse).unwrap();
    let wavelet = Terms::Wavelet(sparse.clone());
    g.relight_terms_to_texture(&gpu, &wavelet, &LightMix::none(), &texture)
        .unwrap();
    let texels = read_texture(&gpu, &texture);
    assert_eq!(texels.len(), buffered.pixels.len());
    for (a, b) in texels.iter().zip(&buffered.pixels) {
        assert_eq!([a[0], a[1], a[2]], *b);
    }
    assert!(buffered.pixels.iter().any(|p| p[0] > 0.0));
    let sh = light_sh_order(&light.sh, 2, 3).unwrap();
    let (buffered, _) = g.relight_sh(&gpu, &sh).unwrap();
    let terms = Terms::Sh(sh.clone());
    g.relight_terms_to_texture(&gpu, &terms, &LightMix::none(), &texture)
        .unwrap();
    let texels = read_texture(&gpu, &texture);
    for (a, b) in texels.iter().zip(&buffered.pixels) {
        assert_eq!([a[0], a[1], a[2]], *b);
    }
}

#[test]
fn timestamp_queries_time_the_relight_passes_when_the_device_has_them() {
    let Some(gpu) = common::gpu_or_skip("timestamp queries") else {
        return;
    };
    let t = &bakes()[1];
    let g = GpuTransport::upload(&gpu, t, None).unwrap();
    let ctx = LightContext::new(t).unwrap();
    let env = EnvMap::from_spec("sun:40,30").unwrap();
    let light = ctx.prepare(&env, EnvRotation::default()).unwrap();
    let sparse = light
        .wavelet
        .select(
            t.coeff_count(),
            Weighting::Unweighted,
            &ctx.support_area,
            None,
        )
        .unwrap();
    let start = std::time::Instant::now();
    let (_, stats) = g.relight_wavelet(&gpu, &sparse).unwrap();
    let wall = start.elapsed().as_secs_f64();
    assert!(stats.kernel_seconds > 0.0);
    assert!(
        stats.kernel_seconds <= wall,
        "kernel {} s longer than the whole call {wall} s",
        stats.kernel_seconds
    );
    match gpu.last_kernel_seconds() {
        Some(k) => {
            println!("{}: timestamp queries, {k} s", gpu.adapter);
            // The stamps of the last relight stay readable until the next one.
            assert_eq!(k, stats.kernel_seconds);
        }
        None => {
            assert!(!gpu.has_timestamps());
            println!("{}: no timestamp queries; wall clock", gpu.adapter);
        }
    }
}

#[test]
fn both_backends_give_the_same_image_and_statistics_for_every_method() {
    use wavelet_prt::relight::gpu::GpuBackend;
    use wavelet_prt::relight::{Backend, Cpu, Method, RelightRequest};
    let Some(gpu) = common::gpu_or_skip("back-ends") else {
        return;
    };
    let bakes = bakes();
    let t = &bakes[1];
    let g = GpuTransport::upload(&gpu, t, None).unwrap();
    let ctx = LightContext::new(t).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let light = ctx.prepare(&env, EnvRotation::yaw(30.0)).unwrap();
    let backends: [&dyn Backend; 2] = [&Cpu(t), &GpuBackend::new(&gpu, &g, t).unwrap()];
    assert_eq!(backends[0].name(), "cpu");
    assert_eq!(backends[1].name(), gpu.adapter);
    let mask = Some(t.coverage.as_slice());
    for (method, terms, sh_order) in [
        (Method::Wavelet, 20, 1),
        (Method::Full, 0, 1),
        (Method::Sh, 0, 3),
        (Method::ShLight, 0, 5),
    ] {
        let req = RelightRequest::new(method, terms, Weighting::Area, sh_order);
        let (cpu, cs) = backends[0].relight(&ctx, &light, &req).unwrap();
        let (dev, gs) = backends[1].relight(&ctx, &light, &req).unwrap();
        assert!(
            relative_l2(&dev, &cpu, mask).unwrap() < GPU_MATCH,
            "{method}"
        );
        assert_eq!(gs.terms, cs.terms, "{method}");
        assert_eq!(gs.nonzeros_touched, cs.nonzeros_touched, "{method}");
        assert!(gs.nonzeros_touched > 0 && gs.bytes_touched > 0, "{method}");
    }
    // A resident transport answers only for a transport of its own size.
    let mut other = t.clone();
    other.meta.width += 16;
    let e = GpuBackend::new(&gpu, &g, &other)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("uploaded from another transport"), "{e}");
}

#[test]
fn many_terms_are_relit_in_batches_that_add_up_to_the_cpu_image() {
    // At 6x64² every term is 24,576 of them: six batches of TERMS_PER_DISPATCH. One batch past
    // 10,900 terms gave a nearly black image on lavapipe; the batches must also add up right in
    // the texture path and the per-vertex (in place) path, which share the encoding.
    use wavelet_prt::relight::RelightRequest;
    use wavelet_prt::relight::gpu::TERMS_PER_DISPATCH;
    let Some(gpu) = common::gpu_or_skip("many_terms") else {
        return;
    };
    let small = SPHERE_ON_PLANE.replace("width = 37\nheight = 21", "width = 20\nheight = 12");
    let scene = scene_from(&small, "gpu-many-terms");
    let settings = BakeSettings {
        cube_n: 64,
        sh_order: 2,
        threshold: 0.0,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let c = t.coeff_count();
    assert_eq!(c, 24_576);
    let g = GpuTransport::upload(&gpu, &t, None).unwrap();
    let ctx = LightContext::new(&t).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_studio.exr")).unwrap();
    let light = ctx.prepare(&env, EnvRotation::default()).unwrap();
    let mask = Some(t.coverage.as_slice());
    for k in [TERMS_PER_DISPATCH, TERMS_PER_DISPATCH + 1, 11_000, c] {
        let req = RelightRequest::Wavelet {
            k,
            weighting: Weighting::Transport,
        };
        let Terms::Wavelet(sparse) = Terms::of(&t, &ctx, &light, &req).unwrap() else {
            panic!("wavelet terms");
        };
        assert_eq!(sparse.indices.len(), k);
        let (cpu, _) = relight_wavelet(&t, &sparse).unwrap();
        let (dev, _) = g.relight_wavelet(&gpu, &sparse).unwrap();
        let e = relative_l2(&dev, &cpu, mask).unwrap();
        assert!(e < GPU_MATCH, "K = {k}: {e}");
        let texture = relight_texture(&gpu, &t);
        let wavelet = Terms::Wavelet(sparse.clone());
        g.relight_terms_to_texture(&gpu, &wavelet, &LightMix::none(), &texture)
            .unwrap();
        let texels = read_texture(&gpu, &texture);
        for (p, (a, b)) in texels.iter().zip(&dev.pixels).enumerate() {
            assert_eq!([a[0], a[1], a[2]], *b, "K = {k}, pixel {p}");
        }
    }
}
