//! Glossy per-vertex bakes with visibility: each glossy vertex keeps which cube texels it sees,
//! checked ray for ray against the tracer, written and read back, and its lobe drawn per pixel
//! from a camera the bake never saw, held to the path tracer under the same cube light.

mod common;

use common::{assets, prt, scene_from, temp_dir, visibility_settings as settings};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::draw::vertex::{draw_relit, orbit};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::env::importance::CubeLight;
use wavelet_prt::math::cube_pyramid::morton_index;
use wavelet_prt::math::cubemap::texel_dir;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::{Backend, Cpu, LightContext, RelightRequest, Terms, lobe_light};
use wavelet_prt::scene::trace::Tracer;
use wavelet_prt::store::transport::Transport;

/// The sphere drawn per vertex with its lobe per pixel from a new camera against the path tracer
/// under the same N = 16 cube light, 64² pixels, each pixel the mean over its area in both:
/// measured 8.2% (the diffuse base 95.5%), of which the path tracer's noise is 5.2%, so 6.4%
/// beyond it; drawn with 16 samples a pixel, 6.7% (4.3% beyond the noise). At the scene's own
/// 256² with 4,096 paths a pixel it is 4.6% (4.1% beyond the noise). Against the light at each pixel's centre, as the path tracer once took it, the
/// sub-pixel highlights made it 30%.
const SPHERE_SAME_LIGHT: f64 = 0.10;

/// [`SPHERE_SAME_LIGHT`] with the path tracer's noise taken out (measured 6.4%).
const SPHERE_BEYOND_NOISE: f64 = 0.075;

/// The glossy sphere of the bundled scene (roughness 0.2 on a matte ground), its image small.
fn sphere() -> wavelet_prt::scene::Scene {
    rough_sphere("0.2")
}

/// [`sphere`] at GGX `roughness`.
fn rough_sphere(roughness: &str) -> wavelet_prt::scene::Scene {
    let text = std::fs::read_to_string(assets().join("scenes/glossy_sphere.toml"))
        .unwrap()
        .replace("width = 256\nheight = 256", "width = 64\nheight = 64")
        .replace("roughness = 0.2", &format!("roughness = {roughness}"));
    scene_from(&text, &format!("vertex-visibility-{roughness}"))
}

/// The glossy sphere at roughness 0.2 on a broad glossy ground (roughness 0.6).
fn sphere_on_glossy_ground() -> wavelet_prt::scene::Scene {
    let matte = "[material.ground]\ntype = \"diffuse\"\nalbedo = [0.8, 0.8, 0.8]";
    let text = std::fs::read_to_string(assets().join("scenes/glossy_sphere.toml"))
        .unwrap()
        .replace("width = 256\nheight = 256", "width = 64\nheight = 64");
    assert!(text.contains(matte));
    let glossy = "[material.ground]\ntype = \"glossy\"\nalbedo = [0.5, 0.5, 0.5]\n\
                  specular = [0.3, 0.3, 0.3]\nroughness = 0.6";
    scene_from(&text.replace(matte, glossy), "vertex-visibility-mixed")
}

#[test]
fn each_glossy_vertex_keeps_the_texels_its_rays_escape_to() {
    let scene = sphere();
    let n = 8;
    let t = bake(&scene, &settings(n, 0.3), &|_| {}).unwrap();
    let mesh = t.mesh().unwrap();
    let vis = mesh.visibility.as_ref().expect("kept");
    let glossy: Vec<u32> = (0..mesh.vertex_count() as u32)
        .filter(|&v| {
            scene.materials[mesh.materials[v as usize] as usize]
                .glossy_lobe()
                .is_some()
        })
        .collect();
    assert_eq!(vis.vertices, glossy);
    assert!(!glossy.is_empty());
    let tracer = Tracer::new(&scene);
    let (mut open, mut shut) = (0, 0);
    for &v in &glossy {
        let normal = mesh.normals[v as usize];
        let origin = mesh.positions[v as usize] + normal * tracer.spawn_offset();
        let row = vis.row(v as usize).unwrap();
        for face in 0..6 {
            for r in 0..n {
                for c in 0..n {
                    let d = texel_dir(n, face, r, c).as_vec3();
                    let want = normal.dot(d) > 0.0 && !tracer.occluded(origin, d, f32::INFINITY);
                    let m = morton_index(n, face, r, c);
                    assert_eq!(
                        row[m / 32] >> (m % 32) & 1 == 1,
                        want,
                        "vertex {v}, texel {face} {r} {c}"
                    );
                    if want { open += 1 } else { shut += 1 }
                }
            }
        }
    }
    // The ground shuts part of every lower vertex's sky.
    assert!(
        open > 0 && shut > glossy.len() * 3 * n * n,
        "{open} open, {shut} shut"
    );
    // The ground's vertices keep none.
    assert!(vis.row(0).is_none() || glossy.contains(&0));
}

#[test]
fn visibility_is_written_read_back_and_an_old_file_with_in_out_terms_is_refused() {
    let scene = sphere();
    let t = bake(&scene, &settings(4, 0.4), &|_| {}).unwrap();
    let dir = temp_dir("visibility-file");
    let path = dir.join("v.prt");
    t.save(&path).unwrap();
    let back = Transport::load(&path).unwrap();
    let (a, b) = (t.mesh().unwrap(), back.mesh().unwrap());
    assert_eq!(a.visibility, b.visibility);
    assert!(back.meta.identity.visibility);
    // A file of versions 6 to 9 baked with in-out BRDF terms says so with the pixels a vertex
    // took: it is refused, naming the file and saying how to bake it again, whatever its
    // checksums say.
    let mut file = common::StFile::read(&path);
    file.meta["per_vertex"]["brdf_stride"] = 4.into();
    let old = dir.join("in_out.prt");
    file.write(&old, true);
    let e = Transport::load(&old).unwrap_err().to_string();
    for part in [
        "in_out.prt",
        "in-out BRDF terms",
        "prt bake",
        "--per-vertex",
    ] {
        assert!(e.contains(part), "{part} is not in: {e}");
    }
}

#[test]
fn the_sphere_from_a_new_camera_is_near_the_path_tracer_under_the_same_cube() {
    let scene = sphere();
    let n = 16;
    let t = bake(&scene, &settings(n, 0.05), &|_| {}).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_studio.exr")).unwrap();
    let rotation = EnvRotation::default();
    // The lobe's light on the transport's own cube, the path tracer's (no finer cube).
    let ctx = LightContext::with_sizes(n, 2).unwrap();
    let light = ctx.prepare(&env, rotation).unwrap();
    assert!(light.lobe.is_none());
    let terms = Terms::of(&t, &ctx, &light, &RelightRequest::Full).unwrap();
    let (relit, _) = Cpu(&t).relight_terms(&terms).unwrap();
    let lobe = lobe_light(&t, &ctx, Some(&light), &RelightRequest::Full).unwrap();
    assert!(lobe.is_some());
    let camera = orbit(&scene.camera, 60.0, 0.0);
    let drawn = draw_relit(&t, &relit, lobe.as_ref(), &camera, None, 4).unwrap();
    let base = wavelet_prt::draw::vertex::draw(
        &t,
        wavelet_prt::draw::vertex::vertex_colours(&t, &relit).unwrap(),
        &camera,
        None,
        4,
    )
    .unwrap();
    let cube = env.to_cube(n, rotation).unwrap();
    let traced = wavelet_prt::bake::path_tracer::path_trace_from(
        &scene,
        &camera,
        &CubeLight::new(&cube),
        &BakeSettings {
            cube_n: n,
            ..BakeSettings::default()
        },
        1024,
    )
    .unwrap();
    let e = relative_l2(&drawn.image, &traced.image, None).unwrap();
    let d = relative_l2(&base.image, &traced.image, None).unwrap();
    // Within the outline: the pixels that the drawing and the traced sphere both cover whole.
    let whole: Vec<f32> = drawn
        .coverage
        .iter()
        .zip(&traced.coverage)
        .map(|(a, b)| (*a == 1.0 && *b == 1.0) as u8 as f32)
        .collect();
    let inside = relative_l2(&drawn.image, &traced.image, Some(&whole)).unwrap();
    let noise = traced.relative_noise(None);
    // The error the path tracer's own noise leaves, taken out: E|a − b|² = |a − truth|² + noise².
    let beyond_noise = (e * e - noise * noise).max(0.0).sqrt();
    eprintln!(
        "visibility {e} ({inside} within the outline, {beyond_noise} beyond the noise), \
         diffuse base {d}, noise {noise}"
    );
    let sum = |i: &wavelet_prt::output::film::Image| {
        i.pixels
            .iter()
            .map(|p| (p[0] + p[1] + p[2]) as f64)
            .sum::<f64>()
    };
    // The light the highlights add is all there (measured 0.1% short; the diffuse base 28%).
    let share = sum(&drawn.image) / sum(&traced.image);
    eprintln!("its light {share} of the path tracer's");
    assert!((share - 1.0).abs() < 0.05, "{share}");
    assert!(e < SPHERE_SAME_LIGHT, "{e}");
    assert!(beyond_noise < SPHERE_BEYOND_NOISE, "{beyond_noise}");
    // 16 samples a pixel reach nearer the pixels' means: the highlights are smaller than a pixel.
    let sixteen = draw_relit(&t, &relit, lobe.as_ref(), &camera, None, 16).unwrap();
    let e16 = relative_l2(&sixteen.image, &traced.image, None).unwrap();
    eprintln!("with 16 samples a pixel: {e16}");
    assert!(e16 < e, "16 samples {e16}, 4 samples {e}");
    assert!(e < d / 2.0, "{e} against the diffuse base's {d}");
    // SH glossy transfer of the same bake: the lobe's light blurred to the orders kept, so
    // further from the path tracer than the lobe, nearer than the diffuse base and nearer at
    // higher orders, its light all there (measured 87.1% and 70.5% at orders 4 and 8, with
    // 100.0% and 107.3% of the path tracer's light).
    let vis = t.mesh().unwrap().visibility.as_deref().unwrap();
    let mut last = d;
    for order in [4, 8] {
        let transfer = wavelet_prt::relight::sh_transfer::ShTransfer::new(vis, order).unwrap();
        let sh = wavelet_prt::draw::vertex::draw_sh_glossy(
            &t,
            &relit,
            (lobe.as_ref().unwrap(), &[]),
            &transfer,
            &camera,
            None,
            4,
        )
        .unwrap();
        let es = relative_l2(&sh.image, &traced.image, None).unwrap();
        let share = sum(&sh.image) / sum(&traced.image);
        eprintln!("SH transfer at order {order}: {es}, its light {share} of the path tracer's");
        assert!(es > e && es < last, "order {order}: {es}");
        assert!((share - 1.0).abs() < 0.1, "order {order}: {share}");
        last = es;
    }
    // Without the light it is drawn from, the draw says so.
    let err = draw_relit(&t, &relit, None, &camera, None, 1).unwrap_err();
    assert!(err.to_string().contains("light"), "{err}");
}

#[test]
fn the_command_line_bakes_visibility_and_draws_its_highlights() {
    let dir = temp_dir("visibility-cli");
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        std::fs::read_to_string(assets().join("scenes/glossy_sphere.toml"))
            .unwrap()
            .replace("width = 256\nheight = 256", "width = 32\nheight = 32"),
    )
    .unwrap();
    let out = dir.join("v.prt");
    let out_path = out.to_str().unwrap();
    let bake = |extra: &[&str]| {
        let common = [
            "bake",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--per-vertex",
            "--cube",
            "8",
            "--edge-length",
            "0.3",
        ];
        prt(&[&common[..], extra].concat())
    };
    // Without it asked for, the diffuse base alone, and the bake says how to keep the lobe.
    let (code, said) = bake(&["--visibility", "false"]);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains("--visibility true"), "{said}");
    assert!(!Transport::load(&out).unwrap().meta.identity.visibility);
    let studio = assets().join("envmaps/blender_studio.exr");
    let relight = |extra: &[&str], image: &std::path::Path| {
        let common = [
            "relight",
            out_path,
            "--env",
            studio.to_str().unwrap(),
            "--eye",
            "3,1.5,2",
            "-o",
            image.to_str().unwrap(),
        ];
        prt(&[&common[..], extra].concat())
    };
    // SH glossy transfer draws from visibility: refused without it.
    let (code, said) = relight(&["--sh-transfer", "4"], &dir.join("refused.exr"));
    assert_ne!(code, 0);
    assert!(
        said.contains("--sh-transfer") && said.contains("visibility"),
        "{said}"
    );
    // A glossy scene keeps its visibility by default.
    std::fs::remove_file(&out).unwrap();
    let (code, said) = bake(&[]);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains("keep their visibility"), "{said}");
    assert!(Transport::load(&out).unwrap().meta.identity.visibility);
    let image = dir.join("drawn.exr");
    let (code, said) = relight(&[], &image);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains("the glossy lobe per pixel"), "{said}");
    let drawn = wavelet_prt::output::film::Image::load_exr(&image).unwrap();
    assert!(drawn.pixels.iter().flatten().any(|v| *v > 0.0));
    // The same bake by SH glossy transfer: another glossy light, the same diffuse base.
    let sh_image = dir.join("sh.exr");
    let (code, said) = relight(&["--sh-transfer", "4"], &sh_image);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains("SH transfer at order 4"), "{said}");
    let sh = wavelet_prt::output::film::Image::load_exr(&sh_image).unwrap();
    let apart = relative_l2(&sh, &drawn, None).unwrap();
    assert!(apart > 1e-3 && apart < 1.0, "{apart}");
    let (code, said) = relight(&["--sh-transfer", "9"], &dir.join("nine.exr"));
    assert_ne!(code, 0);
    assert!(said.contains("orders 1 to 8"), "{said}");
    let (code, out) = prt(&["info", out_path]);
    assert_eq!(code, 0, "{out}");
}

#[test]
fn the_lobe_reads_the_map_on_a_finer_cube_as_the_request_keeps_it() {
    use wavelet_prt::env::select::Weighting;
    use wavelet_prt::math::cube_pyramid::CubePyramid;
    use wavelet_prt::relight::lobe_light::LOBE_N;
    let scene = sphere();
    let t = bake(&scene, &settings(4, 0.4), &|_| {}).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_studio.exr")).unwrap();
    let rotation = EnvRotation::default();
    let ctx = LightContext::new(&t).unwrap();
    assert_eq!(ctx.lobe_n, Some(LOBE_N));
    let light = ctx.prepare(&env, rotation).unwrap();
    let lobe = |req: &RelightRequest| {
        lobe_light(&t, &ctx, Some(&light), req)
            .unwrap()
            .expect("a bake with visibility")
    };
    // Every term: the map on the finer cube itself.
    let full = lobe(&RelightRequest::Full);
    let cube = env.to_cube(LOBE_N, rotation).unwrap();
    let want = CubePyramid::new(&cube).unwrap();
    assert_eq!(full.n, LOBE_N);
    for (a, b) in full.levels[0].iter().zip(&want.levels[0]) {
        for c in 0..4 {
            assert!(
                (a[c] - b[c]).abs() <= 1e-5 * b[c].abs().max(1e-3),
                "{a:?} {b:?}"
            );
        }
    }
    // Each face's power, the coarsest level, is about what every request keeps (a kept face's
    // mean is its texels' unweighted one, so the power moves by the detail dropped times the
    // texels' differing solid angles: 0.16% measured); the finer levels differ as the terms
    // kept do.
    let faces = |p: &CubePyramid| p.levels.last().unwrap().clone();
    let power = |p: &CubePyramid| faces(p).iter().map(|f| f[0] as f64).sum::<f64>();
    let few = lobe(&RelightRequest::Wavelet {
        k: 10,
        weighting: Weighting::Transport,
    });
    for (a, b) in faces(&few).iter().zip(&faces(&full)) {
        assert!(
            (a[0] - b[0]).abs() <= 0.01 * b[0].abs().max(1e-3),
            "{a:?} {b:?}"
        );
    }
    assert_ne!(few.levels[0], full.levels[0]);
    let sh = lobe(&RelightRequest::Sh { order: 2 });
    assert!(
        (power(&sh) / power(&full) - 1.0).abs() < 0.02,
        "{} {}",
        power(&sh),
        power(&full)
    );
    // The environment off: a dark lobe.
    let dark = lobe_light(&t, &ctx, None, &RelightRequest::Full)
        .unwrap()
        .unwrap();
    assert!(dark.levels.iter().flatten().all(|v| v[..3] == [0.0; 3]));
    // A bake without visibility draws no lobe and prepares no finer cube.
    let plain = bake(
        &scene,
        &BakeSettings {
            visibility: false,
            ..settings(4, 0.4)
        },
        &|_| {},
    )
    .unwrap();
    let plain_ctx = LightContext::new(&plain).unwrap();
    assert!(plain_ctx.lobe_n.is_none());
    assert!(plain_ctx.prepare(&env, rotation).unwrap().lobe.is_none());
    assert!(
        lobe_light(&plain, &plain_ctx, Some(&light), &RelightRequest::Full)
            .unwrap()
            .is_none()
    );
}

/// A GPU pixel of the lobe against the CPU's, relative to the brightest: the GPU takes the
/// frame, the taps' weights and the sums in f32 where the CPU takes them in f64.
const GPU_LOBE_OF_BRIGHTEST: f32 = 1e-4;
/// Pixels (per 100,000) allowed to differ more: samples so near a silhouette that the GPU's
/// sub-pixel snapping puts them on the other side, or a lobe direction so near a texel's edge
/// that f32 and f64 put it in different texels.
const GPU_LOBE_PIXELS_APART: usize = 500;

#[test]
fn the_gpu_draws_the_lobe_as_the_cpu_does() {
    use wavelet_prt::draw::gpu::{GpuMesh, GpuRaster, upload_colours};
    use wavelet_prt::draw::lobe::lobe_samples;
    let Some(gpu) = common::gpu_or_skip("the_gpu_draws_the_lobe_as_the_cpu_does") else {
        return;
    };
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let rotation = EnvRotation::default();
    // A sharp lobe (64 directions a pixel, the ground matte), a broad one (256), and the sharp
    // sphere on a broad glossy ground, each material with its own count.
    for (scene, directions) in [
        (rough_sphere("0.2"), vec![64, 0]),
        (rough_sphere("0.6"), vec![256, 0]),
        (sphere_on_glossy_ground(), vec![64, 256]),
    ] {
        let t = bake(&scene, &settings(8, 0.3), &|_| {}).unwrap();
        let mesh = t.mesh().unwrap();
        assert_eq!(lobe_samples(mesh.visibility.as_ref().unwrap()), directions);
        let m = GpuMesh::of_bake(&gpu, mesh).unwrap();
        assert!(m.has_lobe());
        // The lobe's light on a finer cube than the visibility's (the default) and on the same one.
        for ctx in [
            LightContext::new(&t).unwrap(),
            LightContext::with_sizes(8, 2).unwrap(),
        ] {
            let light = ctx.prepare(&env, rotation).unwrap();
            let terms = Terms::of(&t, &ctx, &light, &RelightRequest::Full).unwrap();
            let (relit, _) = Cpu(&t).relight_terms(&terms).unwrap();
            let lobe = lobe_light(&t, &ctx, Some(&light), &RelightRequest::Full)
                .unwrap()
                .unwrap();
            let colours = upload_colours(&gpu, &relit.pixels[..mesh.vertex_count()]).unwrap();
            for samples in [1, 4, 16] {
                let mut raster = GpuRaster::multisampled(&gpu, samples).unwrap();
                // Without the light the lobe is drawn from, the draw says so.
                let e = raster.draw(&gpu, &scene.camera, &m, &colours).unwrap_err();
                assert!(e.to_string().contains("light"), "{e}");
                raster.set_light(&gpu, Some(&lobe)).unwrap();
                for az in [0.0, 130.0] {
                    let camera = orbit(&scene.camera, az, 10.0);
                    let cpu = draw_relit(&t, &relit, Some(&lobe), &camera, None, samples).unwrap();
                    let dev = raster.draw(&gpu, &camera, &m, &colours).unwrap();
                    // The lobe is most of what the sphere shows: a draw without it is far off.
                    let base = wavelet_prt::draw::vertex::draw(
                        &t,
                        wavelet_prt::draw::vertex::vertex_colours(&t, &relit).unwrap(),
                        &camera,
                        None,
                        samples,
                    )
                    .unwrap();
                    let gloss = relative_l2(&base.image, &cpu.image, None).unwrap();
                    assert!(gloss > 0.2, "the lobe adds {gloss}");
                    let (apart, worst) = common::pixels_apart(&dev, &cpu, GPU_LOBE_OF_BRIGHTEST);
                    eprintln!(
                        "directions {directions:?}, light N = {}, {samples} sample(s), turned {az}°: \
                     {apart} pixels apart, the rest within {worst:.2e} of the brightest, the \
                     lobe adding {gloss:.3}",
                        lobe.n
                    );
                    assert!(
                        apart * 100_000 <= GPU_LOBE_PIXELS_APART * cpu.coverage.len(),
                        "directions {directions:?}, {samples} sample(s), turned {az}°: {apart} pixels \
                         apart"
                    );
                }
            }
        }
    }
}
