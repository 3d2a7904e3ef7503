//! Local lights: the bake's columns against closed forms and the path tracer, the relight's
//! linearity on the CPU and the GPU, moving lights, and the scene file's errors.

mod common;

use common::*;
use glam::Vec3;
use wavelet_prt::bake::path_tracer::path_trace_env;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::importance::CubeLight;
use wavelet_prt::math::cubemap::CubeMap;
use wavelet_prt::output::film::Image;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::{Backend, Cpu, LightMix, LightSetting, Terms};
use wavelet_prt::scene::Scene;
use wavelet_prt::store::transport::Transport;

/// Relative error of a stored light value (16-bit steps of its row's largest value, ~1e-5 of the
/// brightest pixels), with room for the shading point's offset off the surface.
const STORED_PRECISION: f64 = 1e-3;

/// The path tracer's agreement: this many of its standard errors, plus a margin for what the
/// bake's stratified light samples and the pixel's sub-samples leave.
const NOISE_SIGMAS: f64 = 3.0;
const PATH_MARGIN: f64 = 0.01;

/// The analytic irradiance of a rectangle: the form-factor formula is met within this.
const FORM_FACTOR: f64 = 0.005;

fn black(n: usize) -> CubeMap {
    CubeMap::constant(n, [0.0; 3]).unwrap()
}

/// The lights of `t` alone, relit as the scene file says (the environment off).
fn lights_alone(t: &Transport, settings: &[LightSetting]) -> Image {
    let mix = LightMix::new(&t.meta.lights, settings).unwrap();
    Cpu(t).relight_lit(&Terms::dark(), &mix).unwrap().0
}

fn with_lights(base: &str, lights: &str) -> String {
    format!("{base}\n{lights}")
}

fn lossless(light_samples: u32) -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        light_samples,
        ..BakeSettings::default()
    }
}

/// `text`'s scene baked with every value kept, `light_samples` a sized light and the pixel
/// centres alone (no edge samples, so each pixel sees one point of the plane), and its lights
/// relit as the file says.
fn plane_lit(text: &str, name: &str, light_samples: u32) -> (Scene, Transport, Image) {
    let scene = scene_from(text, name);
    let settings = BakeSettings {
        edge_spp: 0,
        ..lossless(light_samples)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let img = lights_alone(&t, &LightSetting::defaults(&t.meta.lights));
    (scene, t, img)
}

/// The point of the plane y = 0 that pixel (x, y)'s centre sees.
fn plane_point(scene: &Scene, x: usize, y: usize) -> Vec3 {
    let ray = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
    ray.origin + ray.dir * (-ray.origin.y / ray.dir.y)
}

#[test]
fn a_point_light_over_a_plane_gives_i_cos_over_r_squared() {
    let (albedo, intensity, at) = (0.6f32, 2.5f32, Vec3::new(0.3, 1.2, -0.2));
    let text = with_lights(
        &plane_from_above(24, 20, [albedo; 3], 2.0),
        &format!(
            "[[light]]\nname = \"bulb\"\ntype = \"point\"\nposition = {:?}\nintensity = {intensity}\n",
            at.to_array()
        ),
    );
    let (scene, _, img) = plane_lit(&text, "lights-point", 1);
    let mut want_img = Image::new(24, 20);
    for y in 0..20 {
        for x in 0..24 {
            let p = plane_point(&scene, x, y);
            let d = at - p;
            let want = albedo * std::f32::consts::FRAC_1_PI * intensity * d.y / d.length().powi(3);
            want_img.pixels[y * 24 + x] = [want; 3];
        }
    }
    eprintln!(
        "point light against I cos / r²: relative L2 {:.3e}",
        relative_l2(&img, &want_img, None).unwrap()
    );
    for y in 0..20 {
        for x in 0..24 {
            let want = want_img.pixels[y * 24 + x][0];
            let got = img.pixels[y * 24 + x][0];
            assert_rel_close(
                format!("pixel ({x}, {y})"),
                got as f64,
                want as f64,
                STORED_PRECISION,
            );
        }
    }
}

/// Irradiance at `p` (normal +Y) from a polygon of unit radiance: Lambert's formula,
/// `½ Σ θᵢ (n · γᵢ)` over its edges.
fn polygon_irradiance(p: Vec3, corners: &[Vec3]) -> f64 {
    let mut sum = 0.0f64;
    for i in 0..corners.len() {
        let a = (corners[i] - p).normalize().as_dvec3();
        let b = (corners[(i + 1) % corners.len()] - p)
            .normalize()
            .as_dvec3();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        sum += theta * a.cross(b).normalize().y;
    }
    0.5 * sum.abs()
}

#[test]
fn a_quad_light_over_a_plane_gives_the_rectangle_form_factor() {
    let (albedo, radiance) = (0.5f32, 3.0f32);
    let corners = [
        Vec3::new(-0.4, 1.0, -0.3),
        Vec3::new(0.4, 1.0, -0.3),
        Vec3::new(0.4, 1.0, 0.3),
        Vec3::new(-0.4, 1.0, 0.3),
    ];
    let text = with_lights(
        &plane_from_above(24, 24, [albedo; 3], 2.0),
        &format!(
            "[[light]]\nname = \"panel\"\ntype = \"quad\"\ncorners = {:?}\nintensity = {radiance}\n",
            corners.map(|c| c.to_array())
        ),
    );
    let (scene, t, img) = plane_lit(&text, "lights-quad", 256);
    assert_eq!(t.meta.identity.light_samples, 256);
    let mut want = Image::new(24, 24);
    for y in 0..24 {
        for x in 0..24 {
            let e = polygon_irradiance(plane_point(&scene, x, y), &corners);
            let v = (albedo as f64 * std::f64::consts::FRAC_1_PI * radiance as f64 * e) as f32;
            want.pixels[y * 24 + x] = [v; 3];
        }
    }
    let err = relative_l2(&img, &want, None).unwrap();
    eprintln!("quad light against the form factor: {err}");
    assert!(err < FORM_FACTOR, "{err}");
}

const SPHERE_UNDER_A_PANEL: &str = r#"
[camera]
eye = [0.0, 2.2, 3.2]
target = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
width = 40
height = 32

[material.ground]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[material.ball]
type = "glossy"
albedo = [0.5, 0.2, 0.1]
specular = [0.3, 0.3, 0.3]
roughness = 0.3

[[shape]]
type = "quad"
corners = [[-3.0, 0.0, -3.0], [-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0]]
material = "ground"

[[shape]]
type = "sphere"
center = [0.0, 0.45, 0.0]
radius = 0.45
material = "ball"

[[light]]
name = "panel"
type = "quad"
corners = [[-0.5, 1.6, -0.9], [0.9, 1.6, -0.9], [0.9, 1.6, 0.5], [-0.5, 1.6, 0.5]]
color = [1.0, 0.9, 0.8]
intensity = 2.0
"#;

/// The scene with its ball diffuse.
fn diffuse_ball() -> String {
    SPHERE_UNDER_A_PANEL.replace(
        "type = \"glossy\"\nalbedo = [0.5, 0.2, 0.1]\nspecular = [0.3, 0.3, 0.3]\nroughness = 0.3",
        "type = \"diffuse\"\nalbedo = [0.5, 0.2, 0.1]",
    )
}

/// The bake's light columns of `text`'s scene with `light_samples`, relit as the file says,
/// against the path tracer: (relative L2, the path tracer's noise, the bake).
fn against_the_path_tracer(
    text: &str,
    settings: &BakeSettings,
    paths: u32,
) -> (f64, f64, Scene, Transport) {
    let scene = scene_from(text, "lights-path");
    let t = bake(&scene, settings, &|_| {}).unwrap();
    let defaults = LightSetting::defaults(&t.meta.lights);
    let img = lights_alone(&t, &defaults);
    let mix = LightMix::new(&scene.lights, &defaults).unwrap();
    let sky = black(8);
    let traced = path_trace_env(
        &scene,
        &CubeLight::new(&sky),
        &mix,
        settings,
        paths,
        &|_, _| {},
    )
    .unwrap();
    let err = relative_l2(&img, &traced.image, None).unwrap();
    (err, traced.relative_noise(None), scene, t)
}

#[test]
fn a_glossy_balls_highlight_of_a_quad_light_converges_to_the_path_tracer() {
    let settings = lossless(256);
    let (err, noise, ..) = against_the_path_tracer(SPHERE_UNDER_A_PANEL, &settings, 2048);
    eprintln!("quad light on a glossy ball: {err} (noise {noise})");
    assert!(
        err < NOISE_SIGMAS * noise + PATH_MARGIN,
        "{err} against noise {noise}"
    );
}

#[test]
fn a_spheres_shadow_from_a_quad_light_matches_the_path_tracer() {
    let settings = lossless(BakeSettings::default().light_samples);
    let (err, noise, scene, t) = against_the_path_tracer(&diffuse_ball(), &settings, 2048);
    let defaults = LightSetting::defaults(&t.meta.lights);
    let img = lights_alone(&t, &defaults);
    eprintln!("quad light, sphere's shadow: {err} (noise {noise})");
    assert!(
        err < NOISE_SIGMAS * noise + PATH_MARGIN,
        "{err} against noise {noise}"
    );
    // The shadow is there, or the check says little: without visibility the image differs.
    let open = bake(
        &scene,
        &BakeSettings {
            unshadowed: true,
            ..settings
        },
        &|_| {},
    )
    .unwrap();
    let shadow = relative_l2(&lights_alone(&open, &defaults), &img, None).unwrap();
    assert!(
        shadow > 10.0 * err,
        "the shadow changes the image by {shadow}"
    );
}

#[test]
fn a_spots_cone_edge_sits_where_its_angles_say() {
    let (cone, falloff) = (30.0f32, 10.0f32);
    let at = Vec3::new(0.0, 1.0, 0.0);
    let text = with_lights(
        &plane_from_above(48, 48, [1.0; 3], 2.0),
        &format!(
            "[[light]]\nname = \"spot\"\ntype = \"spot\"\nposition = {:?}\ndirection = [0.0, -1.0, 0.0]\ncone_deg = {cone}\nfalloff_deg = {falloff}\nintensity = 1.0\n",
            at.to_array()
        ),
    );
    let (scene, _, img) = plane_lit(&text, "lights-spot", 1);
    let (mut inside, mut outside, mut band) = (0, 0, 0);
    for y in 0..48 {
        for x in 0..48 {
            let p = plane_point(&scene, x, y);
            let d = at - p;
            let angle = (d.y / d.length()).acos().to_degrees();
            let full = std::f32::consts::FRAC_1_PI * d.y / d.length().powi(3);
            let got = img.pixels[y * 48 + x][0];
            if angle < cone - falloff - 0.2 {
                assert_rel_close(
                    format!("({x}, {y}) inside"),
                    got as f64,
                    full as f64,
                    STORED_PRECISION,
                );
                inside += 1;
            } else if angle > cone + 0.2 {
                assert_eq!(got, 0.0, "({x}, {y}) at {angle}° is lit");
                outside += 1;
            } else if angle > cone - falloff + 0.2 && angle < cone - 0.2 {
                assert!(
                    got > 0.0 && got < full,
                    "({x}, {y}) at {angle}°: {got} of {full}"
                );
                band += 1;
            }
        }
    }
    assert!(
        inside > 50 && outside > 50 && band > 50,
        "{inside} {outside} {band}"
    );
}

/// Bakes a scene with an environment and three lights, one of them moving.
fn lit_scene_and_bake(per_vertex: bool) -> (Scene, Transport) {
    let text = with_lights(
        SPHERE_ON_PLANE,
        r#"
[[light]]
name = "panel"
type = "quad"
corners = [[-0.5, 2.0, -0.5], [0.5, 2.0, -0.5], [0.5, 2.0, 0.5], [-0.5, 2.0, 0.5]]
intensity = 3.0

[[light]]
name = "spot"
type = "spot"
position = [1.5, 1.5, 1.0]
direction = [-1.0, -1.0, -0.6]
cone_deg = 35.0
falloff_deg = 8.0
intensity = 4.0
color = [0.5, 0.6, 1.0]

[[light]]
name = "lamp"
type = "point"
positions = [[-1.0, 0.6, 0.8], [-0.6, 0.6, 0.8], [-0.2, 0.6, 0.8]]
intensity = 0.8
color = [1.0, 0.7, 0.4]
"#,
    );
    let scene = scene_from(&text, "lights-mix");
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 3,
        domain: if per_vertex {
            wavelet_prt::store::transport::BakeDomain::Vertices { edge_length: 0.5 }
        } else {
            wavelet_prt::store::transport::BakeDomain::View
        },
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    (scene, t)
}

fn env_terms(t: &Transport) -> Terms {
    let env = wavelet_prt::env::envmap::EnvMap::from_spec("sun:35,60").unwrap();
    let ctx = wavelet_prt::relight::LightContext::new(t).unwrap();
    let light = ctx
        .prepare(&env, wavelet_prt::env::envmap::EnvRotation::default())
        .unwrap();
    Terms::of(
        t,
        &ctx,
        &light,
        &wavelet_prt::relight::RelightRequest::Wavelet {
            k: 60,
            weighting: wavelet_prt::env::select::Weighting::Transport,
        },
    )
    .unwrap()
}

fn sum(a: &Image, b: &Image) -> Image {
    let mut s = a.clone();
    for (p, q) in s.pixels.iter_mut().zip(&b.pixels) {
        for k in 0..3 {
            p[k] += q[k];
        }
    }
    s
}

#[test]
fn lights_add_linearly_to_the_environment_and_each_other() {
    for per_vertex in [false, true] {
        let (_, t) = lit_scene_and_bake(per_vertex);
        assert_eq!(t.meta.light_columns(), 5);
        let cpu = Cpu(&t);
        let terms = env_terms(&t);
        let defaults = LightSetting::defaults(&t.meta.lights);
        let all = LightMix::new(&t.meta.lights, &defaults).unwrap();
        let (both, stats) = cpu.relight_lit(&terms, &all).unwrap();
        assert_eq!(stats.light_columns, 3);
        let (env, _) = cpu.relight_lit(&terms, &LightMix::none()).unwrap();
        // Each light alone, then the sum.
        let mut alone = Image::new(env.width, env.height);
        for i in 0..3 {
            let mut s = defaults.clone();
            for (j, x) in s.iter_mut().enumerate() {
                x.on = i == j;
            }
            alone = sum(&alone, &lights_alone(&t, &s));
        }
        let e = relative_l2(&both, &sum(&env, &alone), None).unwrap();
        assert!(e < SAME_SUM, "per vertex {per_vertex}: {e}");
        // Doubling the spot adds exactly its column times its colour and intensity.
        let mut doubled = defaults.clone();
        doubled[1].intensity *= 2.0;
        let (twice, _) = cpu
            .relight_lit(&terms, &LightMix::new(&t.meta.lights, &doubled).unwrap())
            .unwrap();
        let rgb = defaults[1].color * defaults[1].intensity;
        for (p, (a, b)) in twice.pixels.iter().zip(&both.pixels).enumerate() {
            for k in 0..3 {
                let col = rgb[k] * t.attached.lights.value(1, k, p);
                assert_close(
                    format!("pixel {p}"),
                    (a[k] - b[k]) as f64,
                    col as f64,
                    1e-5 * (1.0 + col.abs() as f64),
                );
            }
        }
        // A baked position relit is its own column; halfway blends the two.
        let mut moved = defaults.clone();
        for x in moved.iter_mut().take(2) {
            x.on = false;
        }
        moved[2].at = [1.0, 0.0, 0.0];
        let at_one = lights_alone(&t, &moved);
        moved[2].at = [1.5, 0.0, 0.0];
        let halfway = lights_alone(&t, &moved);
        let rgb = moved[2].color * moved[2].intensity;
        for p in 0..t.pixel_count() {
            for k in 0..3 {
                let (c1, c2) = (
                    t.attached.lights.value(3, k, p),
                    t.attached.lights.value(4, k, p),
                );
                let want = rgb[k] * c1;
                assert!(
                    (at_one.pixels[p][k] - want).abs() <= 1e-6 * (1.0 + want),
                    "{p}"
                );
                let want = rgb[k] * 0.5 * (c1 + c2);
                assert!(
                    (halfway.pixels[p][k] - want).abs() <= 1e-6 * (1.0 + want),
                    "{p}"
                );
            }
        }
        // The same on the GPU.
        if let Some(gpu) = gpu_or_skip("lights_add_linearly") {
            let g = wavelet_prt::relight::gpu::GpuTransport::upload(&gpu, &t, None).unwrap();
            let backend = wavelet_prt::relight::gpu::GpuBackend::new(&gpu, &g, &t).unwrap();
            for (terms, mix) in [
                (&terms, &all),
                (&Terms::dark(), &all),
                (&terms, &LightMix::none()),
            ] {
                let (dev, _) = backend.relight_lit(terms, mix).unwrap();
                let (host, _) = cpu.relight_lit(terms, mix).unwrap();
                let e = relative_l2(&dev, &host, None).unwrap();
                assert!(
                    e < GPU_MATCH,
                    "per vertex {per_vertex}: GPU against CPU {e}"
                );
            }
        }
    }
}

#[test]
fn a_lit_bake_survives_its_file_and_its_shards_merge_to_the_whole() {
    let (scene, t) = lit_scene_and_bake(false);
    let dir = temp_dir("lights-file");
    let whole = dir.join("whole.prt");
    t.save(&whole).unwrap();
    let back = Transport::load(&whole).unwrap();
    assert_eq!(back, t);
    assert_eq!(back.meta.lights, scene.lights);
    let settings = wavelet_prt::bake::BakeSettings::from_meta(&t.meta);
    let shards: Vec<Transport> = (0..2)
        .map(|i| {
            bake(
                &scene,
                &BakeSettings {
                    shard: Some([i, 2]),
                    ..settings.clone()
                },
                &|_| {},
            )
            .unwrap()
        })
        .collect();
    let merged = Transport::merge(&shards).unwrap();
    let m = dir.join("merged.prt");
    merged.save(&m).unwrap();
    assert!(std::fs::read(&m).unwrap() == std::fs::read(&whole).unwrap());
}

#[test]
fn light_columns_with_bad_scales_or_none_at_all_are_refused() {
    let (_, t) = lit_scene_and_bake(false);
    let dir = temp_dir("lights-hostile");
    let p = dir.join("t.prt");
    t.save(&p).unwrap();
    let file = StFile::read(&p);
    let edit = |name: &str, bytes: &[u8]| {
        let mut f = file.clone();
        let tensor = f.tensors.iter_mut().find(|x| x.0 == name).unwrap();
        tensor.3[..bytes.len()].copy_from_slice(bytes);
        let q = dir.join(format!(
            "{name}-{:x}.prt",
            bytes.iter().fold(0u64, |h, b| h * 257 + *b as u64)
        ));
        std::fs::write(&q, f.to_bytes(true)).unwrap();
        Transport::load(&q).unwrap_err().to_string()
    };
    // A scale that is not a number, a negative one, and one so small its values would be
    // subnormal floats.
    for scale in [f32::NAN, -1.0, 1e-33] {
        let e = edit("light_scale", &scale.to_le_bytes());
        assert!(e.contains("light_scale") && e.contains("finite"), "{e}");
    }
    // A header that names a light without its columns.
    let mut f = file.clone();
    f.tensors.retain(|x| !x.0.starts_with("light_"));
    let q = dir.join("no-columns.prt");
    std::fs::write(&q, f.to_bytes(true)).unwrap();
    let e = Transport::load(&q).unwrap_err().to_string();
    assert!(e.contains("light_"), "{e}");
}

#[test]
fn scene_file_lights_are_checked_field_by_field() {
    let base = plane_from_above(8, 8, [0.5; 3], 1.0);
    let dir = temp_dir("lights-errors");
    let cases: [(&str, &str); 9] = [
        (
            "[[light]]\nname = \"a\"\ntype = \"spot\"\nposition = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone_deg = 20.0\nfalloff_deg = 30.0\nintensity = 1.0\n",
            "light[0].falloff_deg",
        ),
        (
            "[[light]]\nname = \"a\"\ntype = \"point\"\nintensity = 1.0\n",
            "light[0].position",
        ),
        (
            "[[light]]\nname = \"a\"\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\ncorners = [[0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]]\nintensity = 1.0\n",
            "light[0].corners",
        ),
        (
            "[[light]]\nname = \"a\"\ntype = \"quad\"\ncorners = [[0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.5, 1.0], [0.0, 1.0, 1.0]]\nintensity = 1.0\n",
            "light[0].corners",
        ),
        (
            "[[light]]\nname = \"a b\"\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0\n",
            "light[0].name",
        ),
        (
            "[[light]]\nname = \"a\"\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0\n[[light]]\nname = \"a\"\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0\n",
            "light[1].name",
        ),
        (
            "[[light]]\nname = \"a\"\ntype = \"directional\"\ndirection = [0.0, 0.0, 0.0]\nintensity = 1.0\n",
            "light[0].direction",
        ),
        (
            "[[light]]\nname = \"a\"\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = -1.0\n",
            "light[0].intensity",
        ),
        (
            "[[light]]\nname = \"a\"\ntype = \"point\"\nintensity = 1.0\ngrid = { from = [0.0, 1.0, 0.0], to = [1.0, 1.0, 0.0], counts = [2, 0, 1] }\n",
            "light[0].grid.counts",
        ),
    ];
    for (i, (light, field)) in cases.iter().enumerate() {
        let p = dir.join(format!("s{i}.toml"));
        std::fs::write(&p, format!("{base}\n{light}")).unwrap();
        let e = Scene::load(&p).unwrap_err().to_string();
        assert!(
            e.contains(field) && e.contains(&format!("s{i}.toml")),
            "{field}: {e}"
        );
        assert!(e.contains(":"), "{e}");
    }
}

#[test]
fn the_command_line_relights_lights_alone_and_names_the_lights_it_knows() {
    let dir = temp_dir("lights-cli");
    let scene = dir.join("s.toml");
    std::fs::write(&scene, SPHERE_UNDER_A_PANEL).unwrap();
    let prt_file = dir.join("s.prt");
    let (code, out) = prt(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        prt_file.to_str().unwrap(),
        "--cube",
        "8",
        "--light-samples",
        "4",
    ]);
    assert_eq!(code, 0, "{out}");
    let (code, out) = prt(&["info", prt_file.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains("panel: quad") && out.contains("4 samples"),
        "{out}"
    );
    let png = dir.join("alone.exr");
    let (code, out) = prt(&[
        "relight",
        prt_file.to_str().unwrap(),
        "--env",
        "none",
        "--light",
        "panel=0.5",
        "--device",
        "cpu",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains("environment off") && out.contains("1 light column"),
        "{out}"
    );
    let (code, out) = prt(&[
        "relight",
        prt_file.to_str().unwrap(),
        "--env",
        "none",
        "--light",
        "lamp=1",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(
        out.contains("no light is called `lamp`; its lights are panel"),
        "{out}"
    );
    let (code, out) = prt(&[
        "relight",
        prt_file.to_str().unwrap(),
        "--env",
        "none",
        "--light",
        "panel=0",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(out.contains("no local light is on"), "{out}");
}

/// A white floor and a red wall meeting at a right angle, lit by a quad light between them.
const CORNER: &str = r#"
[camera]
eye = [1.6, 1.4, 2.6]
target = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 50.0
width = 32
height = 24

[material.floor]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[material.wall]
type = "diffuse"
albedo = [0.9, 0.1, 0.1]

[[shape]]
type = "quad"
corners = [[-1.0, 0.0, -1.0], [-1.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -1.0]]
material = "floor"

[[shape]]
type = "quad"
corners = [[-1.0, 0.0, -1.0], [-1.0, 2.0, -1.0], [-1.0, 2.0, 2.0], [-1.0, 0.0, 2.0]]
material = "wall"

[[light]]
name = "panel"
type = "quad"
corners = [[-0.4, 1.5, -0.4], [0.4, 1.5, -0.4], [0.4, 1.5, 0.4], [-0.4, 1.5, 0.4]]
intensity = 3.0
"#;

#[test]
fn a_quad_lights_bounce_bleeds_the_walls_colour_as_the_path_tracer_says() {
    let settings = BakeSettings {
        bounces: 1,
        paths: 256,
        ..lossless(BakeSettings::default().light_samples)
    };
    let (err, noise, scene, t) = against_the_path_tracer(CORNER, &settings, 2048);
    eprintln!("quad light, one bounce: {err} (noise {noise})");
    assert!(
        err < NOISE_SIGMAS * noise + PATH_MARGIN,
        "{err} against noise {noise}"
    );
    // The bounce is there: the floor near the wall turns red, above what direct light gives.
    let direct = bake(
        &scene,
        &BakeSettings {
            bounces: 0,
            ..settings
        },
        &|_| {},
    )
    .unwrap();
    let defaults = LightSetting::defaults(&t.meta.lights);
    let (with, without) = (
        lights_alone(&t, &defaults),
        lights_alone(&direct, &defaults),
    );
    let added = relative_l2(&without, &with, None).unwrap();
    assert!(added > 0.05, "the bounce adds {added}");
    let red = |img: &Image| -> f64 { img.pixels.iter().map(|p| (p[0] - p[1]) as f64).sum::<f64>() };
    assert!(
        red(&with) > red(&without) * 1.2,
        "{} {}",
        red(&with),
        red(&without)
    );
}

/// A moving light halfway between two baked positions is their blend; against the light baked
/// at that very place the error grows with the spacing, and is small when they are close.
#[test]
fn a_moving_light_between_baked_positions_is_close_to_the_light_there() {
    let errors: Vec<f64> = [0.1f32, 0.4, 1.0]
        .iter()
        .map(|&spacing| {
            let path = [-0.5 * spacing, 0.0, 0.5 * spacing]
                .map(|x| [x, 0.8, 0.0]);
            let text = with_lights(
                &plane_from_above(24, 24, [0.7; 3], 2.0),
                &format!(
                    "[[light]]\nname = \"lamp\"\ntype = \"point\"\npositions = {:?}\nintensity = 1.0\n",
                    path
                ),
            );
            let scene = scene_from(&text, "lights-moving");
            let t = bake(&scene, &lossless(1), &|_| {}).unwrap();
            let mut s = LightSetting::defaults(&t.meta.lights);
            s[0].at = [1.0, 0.0, 0.0];
            let there = lights_alone(&t, &s);
            // Blend positions 0 and 2 halfway: the column of position 1 is the truth.
            let mut blended = there.clone();
            for (p, px) in blended.pixels.iter_mut().enumerate() {
                *px = std::array::from_fn(|k| {
                    0.5 * (t.attached.lights.value(0, k, p) + t.attached.lights.value(2, k, p))
                });
            }
            relative_l2(&blended, &there, None).unwrap()
        })
        .collect();
    eprintln!("moving light, halfway error at spacings 0.1, 0.4, 1.0 (height 0.8): {errors:?}");
    assert!(
        errors[0] < 0.01 && errors[0] < errors[1] && errors[1] < errors[2],
        "{errors:?}"
    );
}

#[test]
fn the_lights_command_writes_its_tables_plot_and_images() {
    let dir = temp_dir("lights-bench");
    let out = dir.join("out");
    let (code, text) = prt(&[
        "lights",
        "--out",
        out.to_str().unwrap(),
        "--side",
        "16",
        "--samples",
        "16",
        "--grid",
        "2",
        "--many-side",
        "32",
    ]);
    assert_eq!(code, 0, "{text}");
    for kind in ["| point |", "| spot |", "| directional |", "| quad |"] {
        assert!(text.contains(kind), "{kind} missing: {text}");
    }
    assert!(text.contains("4 small quad lights"), "{text}");
    for f in [
        "lights.md",
        "lights.csv",
        "moving_light.png",
        "quad_bake.png",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let csv = std::fs::read_to_string(out.join("lights.csv")).unwrap();
    assert_eq!(
        csv.lines()
            .filter(|l| l.starts_with("moving_rel_l2"))
            .count(),
        5
    );
}

/// A light baked on a grid: the file's `grid` lays its positions out x first, a place inside a
/// cell blends the cell's corners, and the command line places it with `NAME@X,Y`.
#[test]
fn a_light_on_a_grid_blends_the_corners_of_its_cell() {
    let text = with_lights(
        &plane_from_above(16, 16, [0.6; 3], 2.0),
        "[[light]]\nname = \"lamp\"\ntype = \"point\"\nintensity = 1.0\n\
         grid = { from = [-0.4, 0.8, -0.4], to = [0.4, 0.8, 0.4], counts = [3, 1, 2] }\n",
    );
    let scene = scene_from(&text, "lights-grid");
    let light = &scene.lights[0];
    assert_eq!(light.grid, [3, 1, 2]);
    assert_eq!(light.positions.len(), 6);
    assert_eq!(light.positions[1], Vec3::new(0.0, 0.8, -0.4));
    assert_eq!(light.positions[5], Vec3::new(0.4, 0.8, 0.4));
    let t = bake(&scene, &lossless(1), &|_| {}).unwrap();
    assert_eq!(t.meta.lights[0].grid, [3, 1, 2]);
    let mut s = LightSetting::defaults(&t.meta.lights);
    s[0].at = [0.5, 0.0, 0.25];
    let img = lights_alone(&t, &s);
    for (p, px) in img.pixels.iter().enumerate() {
        let want = 0.75
            * (0.5 * t.attached.lights.value(0, 0, p) + 0.5 * t.attached.lights.value(1, 0, p))
            + 0.25
                * (0.5 * t.attached.lights.value(3, 0, p) + 0.5 * t.attached.lights.value(4, 0, p));
        assert!((px[0] - want).abs() <= 1e-6 * (1.0 + want), "pixel {p}");
    }
    let mut by_arg = LightSetting::defaults(&t.meta.lights);
    wavelet_prt::scene::light_mix::apply_light_arg(&t.meta.lights, &mut by_arg, "lamp@0.5,0,0.25")
        .unwrap();
    assert_eq!(by_arg[0].at, [0.5, 0.0, 0.25]);
    for bad in ["lamp@0,1", "lamp@3", "lamp@0,0,2"] {
        assert!(
            wavelet_prt::scene::light_mix::apply_light_arg(&t.meta.lights, &mut by_arg, bad)
                .is_err(),
            "{bad}"
        );
    }
    // The file keeps the grid.
    let dir = temp_dir("lights-grid-file");
    t.save(&dir.join("g.prt")).unwrap();
    assert_eq!(Transport::load(&dir.join("g.prt")).unwrap(), t);
}
