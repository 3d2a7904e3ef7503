//! Local lights on a glossy per-vertex bake with visibility: each glossy vertex's share of each
//! light, checked against its own shadow rays and written and read back, and the lights'
//! highlights drawn per pixel from a camera the bake never saw, held to the path tracer lit by
//! the same lights.

mod common;

use common::{assets, scene_from, temp_dir, visibility_settings as settings};
use wavelet_prt::bake::path_tracer::path_trace_from_lit;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::draw::vertex::{draw_relit, draw_relit_lit, orbit};
use wavelet_prt::env::importance::CubeLight;
use wavelet_prt::math::cube_pyramid::CubePyramid;
use wavelet_prt::math::cubemap::CubeMap;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::{Backend, Cpu, LightMix, LightSetting, Terms};
use wavelet_prt::scene::light::emitters;
use wavelet_prt::scene::trace::Tracer;
use wavelet_prt::store::transport::Transport;

/// The glossy sphere with its highlights of a point light and a quad drawn per pixel from a new
/// camera with 16 samples a pixel, against the path tracer under the same lights, 64² pixels,
/// each pixel the mean over its area in both: measured 5.6% under both lights, 5.7% under the
/// bulb alone and 4.0% under the panel alone (without the lights' highlights, 87.6%, 89.3% and
/// 86.9%); the path tracer's noise is 2.5%, 2.5% and 3.0% of it.
const LIT_SPHERE: f64 = 0.08;

/// [`LIT_SPHERE`] with 4 samples a pixel: the bulb's highlight is smaller than a pixel, and four
/// points of a pixel miss its mean (measured 10.9%, 11.3% and 3.9%).
const LIT_SPHERE_4: f64 = 0.15;

/// The glossy sphere of the bundled scene (roughness 0.2 on a matte ground), its image small, under
/// a point light and a quad panel and no environment.
fn lit_sphere() -> wavelet_prt::scene::Scene {
    let text = std::fs::read_to_string(assets().join("scenes/glossy_sphere.toml"))
        .unwrap()
        .replace("width = 256\nheight = 256", "width = 64\nheight = 64");
    let lights = lit_sphere_text();
    scene_from(&format!("{text}\n{lights}"), "vertex-lights")
}

/// The lights of [`lit_sphere`].
fn lit_sphere_text() -> &'static str {
    r#"
[[light]]
name = "bulb"
type = "point"
position = [1.6, 2.2, 1.8]
intensity = 8.0

[[light]]
name = "panel"
type = "quad"
corners = [[-1.4, 2.0, -0.9], [-0.4, 2.0, -0.9], [-0.4, 2.0, 0.1], [-1.4, 2.0, 0.1]]
color = [1.0, 0.9, 0.8]
intensity = 3.0
"#
}

/// A dark environment's light, as a relight without one draws its lobe from.
fn dark(n: usize) -> CubePyramid {
    CubePyramid::new(&CubeMap::constant(n, [0.0; 3]).unwrap()).unwrap()
}

#[test]
fn each_glossy_vertex_sees_its_share_of_each_light_as_its_shadow_rays_say() {
    let scene = lit_sphere();
    let t = bake(&scene, &settings(8, 0.3), &|_| {}).unwrap();
    let mesh = t.mesh().unwrap();
    let vis = mesh.visibility.as_deref().unwrap();
    let lights = emitters(&scene.lights);
    assert_eq!(vis.columns, lights.len());
    let tracer = Tracer::new(&scene);
    let (mut shut, mut open, mut partial) = (0, 0, 0);
    for &v in &vis.vertices {
        let v = v as usize;
        let origin = mesh.positions[v] + mesh.normals[v] * tracer.spawn_offset();
        // The point light: one shadow ray, its share 0 or 1 as the ray says.
        let s = lights[0].sample(origin, [0.5, 0.5]).unwrap();
        let blocked = tracer.occluded(origin, s.dir, s.dist);
        let share = vis.light_share(v, 0);
        assert_eq!(share, if blocked { 0.0 } else { 1.0 }, "vertex {v}");
        (shut, open) = (shut + blocked as usize, open + !blocked as usize);
        // The panel: a share of its samples, between the rays through its corners' extremes.
        let q = vis.light_share(v, 1);
        assert!((0.0..=1.0).contains(&q));
        partial += (q > 0.0 && q < 1.0) as usize;
    }
    eprintln!("{shut} vertices shut from the bulb, {open} open, {partial} partly lit by the panel");
    assert!(shut > 0 && open > 0 && partial > 0);
    // Written and read back as they were.
    let dir = temp_dir("vertex-lights-file");
    let path = dir.join("lit.prt");
    t.save(&path).unwrap();
    let back = Transport::load(&path).unwrap();
    let again = back.mesh().unwrap().visibility.as_deref().unwrap();
    assert_eq!(again.columns, vis.columns);
    assert_eq!(again.light_shares, vis.light_shares);
    // `prt info` says what the glossy vertices keep.
    let (code, said) = common::prt(&["info", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{said}");
    assert!(
        said.contains("its share of each of the 2 light column(s) (8 bytes)"),
        "{said}"
    );
    // Without the shares (as a file of format version 9 with lights loads), the bake draws but
    // is not written: its lights' highlights would be lost.
    let mut old = back;
    if let wavelet_prt::store::transport::Domain::Mesh(m) = &mut old.attached.domain {
        let v = m.visibility.as_mut().unwrap();
        v.columns = 0;
        v.light_shares.clear();
    }
    let e = old.save(&dir.join("old.prt")).unwrap_err().to_string();
    assert!(
        e.contains("old.prt") && e.contains("format version 10"),
        "{e}"
    );
    assert!(!dir.join("old.prt").exists());
}

/// The path tracer of `scene` from `camera` under the local lights of `mix` alone, 1,024 paths a
/// pixel.
fn traced(
    scene: &wavelet_prt::scene::Scene,
    camera: &wavelet_prt::scene::Camera,
    mix: &LightMix,
) -> wavelet_prt::bake::path_tracer::PathTraced {
    let black = CubeMap::constant(8, [0.0; 3]).unwrap();
    let settings = BakeSettings {
        cube_n: 8,
        ..BakeSettings::default()
    };
    path_trace_from_lit(
        scene,
        camera,
        (&CubeLight::new(&black), mix),
        &settings,
        1024,
    )
    .unwrap()
}

#[test]
fn the_lights_highlights_from_a_new_camera_are_near_the_path_tracer() {
    let scene = lit_sphere();
    let n = 16;
    let t = bake(&scene, &settings(n, 0.05), &|_| {}).unwrap();
    let defaults = LightSetting::defaults(&t.meta.lights);
    let camera = orbit(&scene.camera, 60.0, 10.0);
    let light = dark(n);
    // Both lights, then each alone: its highlight is there, and the other's is not.
    for (what, on) in [
        ("both lights", [true, true]),
        ("the bulb", [true, false]),
        ("the panel", [false, true]),
    ] {
        let mut settings = defaults.clone();
        for (s, on) in settings.iter_mut().zip(on) {
            s.on = on;
        }
        let mix = LightMix::new(&t.meta.lights, &settings).unwrap();
        let (relit, _) = Cpu(&t).relight_lit(&Terms::dark(), &mix).unwrap();
        let lit = (Some(&light), &mix.weights[..]);
        let drawn = draw_relit_lit(&t, &relit, lit, &camera, None, 4).unwrap();
        let sixteen = draw_relit_lit(&t, &relit, lit, &camera, None, 16).unwrap();
        let without = draw_relit(&t, &relit, Some(&light), &camera, None, 16).unwrap();
        let traced = traced(&scene, &camera, &mix);
        let e4 = relative_l2(&drawn.image, &traced.image, None).unwrap();
        let e16 = relative_l2(&sixteen.image, &traced.image, None).unwrap();
        let d = relative_l2(&without.image, &traced.image, None).unwrap();
        let noise = traced.relative_noise(None);
        eprintln!(
            "{what}: {e16} with 16 samples a pixel, {e4} with 4, {d} without the highlights; \
             the path tracer's noise {noise}"
        );
        assert!(e16 < LIT_SPHERE, "{what}: {e16}");
        assert!(e4 < LIT_SPHERE_4, "{what}: {e4} with 4 samples a pixel");
        assert!(
            e16 < d / 4.0,
            "{what}: {e16} against {d} without the highlights"
        );
    }
}

/// The GPU's lights' highlights against the CPU's, of the brightest pixel (lavapipe, f32 against
/// the CPU's f64 sums).
const GPU_LIGHTS_OF_BRIGHTEST: f32 = 1e-4;
/// Pixels (per 100,000) allowed to differ more: samples so near a silhouette that the GPU's
/// sub-pixel snapping puts them on the other side.
const GPU_LIGHTS_PIXELS_APART: usize = 500;

#[test]
fn the_gpu_draws_the_lights_highlights_as_the_cpu_does() {
    use wavelet_prt::draw::gpu::{GpuMesh, GpuRaster, upload_colours};
    use wavelet_prt::draw::lobe::lit_columns;
    let Some(gpu) = common::gpu_or_skip("the_gpu_draws_the_lights_highlights_as_the_cpu_does")
    else {
        return;
    };
    // The bulb and the panel, and a sun with a disc and a spot beside them: every kind.
    let extra = r#"
[[light]]
name = "sun"
type = "directional"
direction = [0.5, -0.7, -0.4]
angle_deg = 6.0
intensity = 1.5

[[light]]
name = "spot"
type = "spot"
position = [-1.2, 2.4, 1.2]
direction = [0.45, -0.8, -0.4]
cone_deg = 25.0
falloff_deg = 8.0
intensity = 20.0
"#;
    let text = std::fs::read_to_string(assets().join("scenes/glossy_sphere.toml"))
        .unwrap()
        .replace("width = 256\nheight = 256", "width = 64\nheight = 64");
    let lit = lit_sphere_text();
    let scene = scene_from(&format!("{text}\n{lit}\n{extra}"), "vertex-lights-gpu");
    let n = 8;
    let t = bake(&scene, &settings(n, 0.3), &|_| {}).unwrap();
    let mesh = t.mesh().unwrap();
    assert_eq!(mesh.visibility.as_ref().unwrap().columns, 4);
    let mix = LightMix::new(&t.meta.lights, &LightSetting::defaults(&t.meta.lights)).unwrap();
    let (relit, _) = Cpu(&t).relight_lit(&Terms::dark(), &mix).unwrap();
    let light = dark(n);
    let m = GpuMesh::of_bake(&gpu, mesh).unwrap();
    let colours = upload_colours(&gpu, &relit.pixels[..mesh.vertex_count()]).unwrap();
    let lit = lit_columns(&t.meta.lights, &mix.weights);
    assert_eq!(lit.len(), 4);
    for samples in [1, 4] {
        let mut raster = GpuRaster::multisampled(&gpu, samples).unwrap();
        raster.set_lights(&gpu, &lit).unwrap();
        raster.set_light(&gpu, Some(&light)).unwrap();
        for az in [0.0, 130.0, 250.0] {
            let camera = orbit(&scene.camera, az, 15.0);
            let lights = (Some(&light), &mix.weights[..]);
            let cpu = draw_relit_lit(&t, &relit, lights, &camera, None, samples).unwrap();
            let dev = raster.draw(&gpu, &camera, &m, &colours).unwrap();
            // The highlights are much of what the sphere shows: a draw without them is far off.
            let without = draw_relit(&t, &relit, Some(&light), &camera, None, samples).unwrap();
            let gloss = relative_l2(&without.image, &cpu.image, None).unwrap();
            assert!(gloss > 0.05, "the highlights add {gloss}");
            let (apart, worst) = common::pixels_apart(&dev, &cpu, GPU_LIGHTS_OF_BRIGHTEST);
            eprintln!(
                "{samples} sample(s), turned {az}°: {apart} pixels apart, the rest within \
                 {worst:.2e} of the brightest; the highlights add {gloss}"
            );
            assert!(
                apart * 100_000 <= GPU_LIGHTS_PIXELS_APART * cpu.coverage.len(),
                "{apart} pixels apart"
            );
        }
    }
}

#[test]
fn sh_glossy_transfer_keeps_the_lights_highlights() {
    use wavelet_prt::draw::vertex::draw_sh_glossy;
    use wavelet_prt::relight::sh_transfer::ShTransfer;
    let scene = lit_sphere();
    let n = 8;
    let t = bake(&scene, &settings(n, 0.3), &|_| {}).unwrap();
    let mix = LightMix::new(&t.meta.lights, &LightSetting::defaults(&t.meta.lights)).unwrap();
    let (relit, _) = Cpu(&t).relight_lit(&Terms::dark(), &mix).unwrap();
    let vis = t.mesh().unwrap().visibility.as_deref().unwrap();
    let transfer = ShTransfer::new(vis, 4).unwrap();
    let camera = orbit(&scene.camera, 60.0, 10.0);
    let light = dark(n);
    let lit = (&light, &mix.weights[..]);
    let sh = draw_sh_glossy(&t, &relit, lit, &transfer, &camera, None, 1).unwrap();
    let lobe = draw_relit_lit(&t, &relit, (Some(&light), &mix.weights), &camera, None, 1).unwrap();
    let bare = draw_sh_glossy(&t, &relit, (&light, &[]), &transfer, &camera, None, 1).unwrap();
    // In the dark, SH transfer's glossy light is nothing: what is left is the lights'
    // highlights, the lobe's own to the bit.
    assert_eq!(sh.image.pixels, lobe.image.pixels);
    let added = relative_l2(&bare.image, &sh.image, None).unwrap();
    assert!(added > 0.5, "the highlights add {added}");
}
