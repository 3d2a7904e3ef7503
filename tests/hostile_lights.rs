//! Lights and lobes at the ends of their ranges: sun discs from 0.001° to 10° wide against the
//! irradiance they are defined to give, in the bake and in the path tracer, and materials at the
//! lowest roughness (a scene file's 0.02, a glTF `roughnessFactor` of 0) path traced and baked
//! with a bounce to finite images, with an error that names a material gone non-finite.

mod common;

use common::gltf::test_scene;
use common::{SPHERE_ON_PLANE, full_light, plane_from_above, relit, scene_from, temp_dir};
use glam::{Vec2, Vec3};
use serde_json::json;
use wavelet_prt::bake::path_tracer::{path_trace, path_trace_env};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::draw::vertex::vertex_colours;
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::env::importance::CubeLight;
use wavelet_prt::math::cubemap::CubeMap;
use wavelet_prt::output::film::Image;
use wavelet_prt::relight::{
    Backend, Cpu, LightMix, LightSetting, RelightRequest, Terms, relight_wavelet,
};
use wavelet_prt::scene::light::MIN_DISC_ANGLE;
use wavelet_prt::scene::{Framing, MIN_ROUGHNESS, Material, Scene};
use wavelet_prt::store::transport::{BakeDomain, Transport};

/// Angular diameters of the sun discs checked, degrees: below [`MIN_DISC_ANGLE`] (a delta
/// light), where f32 rounds `cos α` to 1 (under about 0.03°) or keeps few of the digits of
/// `1 − cos α`, and wide discs.
const DISC_DEGREES: [f32; 6] = [0.001, 0.01, 0.03, 0.1, 1.0, 10.0];
/// The sun's tilt from the plane's normal, degrees.
const TILT_DEG: f64 = 30.0;
/// The sun's irradiance on a surface facing it, W/m², and the plane's albedo.
const IRRADIANCE: f64 = 3.0;
const ALBEDO: f64 = 0.6;
/// Stratified samples of a sun disc per pixel in the bake.
const DISC_SAMPLES: u32 = 256;
/// A baked pixel against the closed form, relative: 16-bit storage against the brightest pixel
/// (1e-5), and the jittered strata of the 10° disc, over which the tilted plane's cosine varies
/// by ±5% (256 strata leave about 3e-4 a pixel).
const BAKE_OF_CLOSED_FORM: f64 = 2e-3;
/// A path-traced pixel against the closed form: this many of its own standard errors...
const TRACER_SIGMAS: f64 = 4.0;
/// ...plus this much of the value (f32 sums of the paths).
const TRACER_ROUNDING: f64 = 1e-3;
/// Paths a pixel of the path tracer takes.
const TRACER_PATHS: u32 = 256;

fn black(n: usize) -> CubeMap {
    CubeMap::constant(n, [0.0; 3]).unwrap()
}

/// A plane of albedo [`ALBEDO`] seen from above, lit by a sun of angular diameter `deg` degrees
/// tilted [`TILT_DEG`] from the plane's normal.
fn sunlit_plane(deg: f32) -> Scene {
    let t = TILT_DEG.to_radians();
    let text = format!(
        "{}\n[[light]]\nname = \"sun\"\ntype = \"directional\"\ndirection = [{:?}, {:?}, 0.0]\n\
         angle_deg = {deg:?}\nintensity = {IRRADIANCE:?}\n",
        plane_from_above(8, 8, [ALBEDO as f32; 3], 2.0),
        t.sin(),
        -t.cos()
    );
    scene_from(&text, &format!("hostile-sun-{deg}"))
}

/// The plane's radiance in closed form. A disc of uniform radiance L and half-angle α sends the
/// vector irradiance `L π sin² α` along its axis (the cosine-weighted integral over a spherical
/// cap), and a directional light's intensity is that irradiance, E; so while the disc stands
/// wholly above the horizon a plane tilted θ from it receives exactly `E cos θ`, at any size,
/// and reflects `albedo / π` of it.
fn closed_form() -> f64 {
    ALBEDO / std::f64::consts::PI * IRRADIANCE * TILT_DEG.to_radians().cos()
}

fn disc_settings() -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        edge_spp: 0,
        light_samples: DISC_SAMPLES,
        ..BakeSettings::default()
    }
}

/// The lights of `t` alone, relit at their file's colour and intensity.
fn lights_alone(t: &Transport) -> Image {
    let mix = LightMix::new(&t.meta.lights, &LightSetting::defaults(&t.meta.lights)).unwrap();
    Cpu(t).relight_lit(&Terms::dark(), &mix).unwrap().0
}

#[test]
fn a_baked_sun_disc_of_any_size_gives_its_irradiance() {
    let want = closed_form();
    for deg in DISC_DEGREES {
        let scene = sunlit_plane(deg);
        let t = bake(&scene, &disc_settings(), &|_| {}).unwrap();
        // Below the smallest disc the light is a delta: one sample, none recorded.
        let sized = deg.to_radians() >= MIN_DISC_ANGLE;
        assert_eq!(
            t.meta.identity.light_samples,
            if sized { DISC_SAMPLES } else { 0 },
            "{deg}°"
        );
        let img = lights_alone(&t);
        for (i, p) in img.pixels.iter().enumerate() {
            let got = p[0] as f64;
            assert!(
                (got - want).abs() <= BAKE_OF_CLOSED_FORM * want,
                "a {deg}° sun: pixel {i} is {got}, the closed form {want} ({:.3e} off)",
                (got - want) / want
            );
        }
    }
}

#[test]
fn a_path_traced_sun_disc_of_any_size_gives_its_irradiance() {
    let want = closed_form();
    for deg in DISC_DEGREES {
        let scene = sunlit_plane(deg);
        let mix = LightMix::new(&scene.lights, &LightSetting::defaults(&scene.lights)).unwrap();
        let traced = path_trace_env(
            &scene,
            &CubeLight::new(&black(8)),
            &mix,
            &disc_settings(),
            TRACER_PATHS,
            &|_, _| {},
        )
        .unwrap();
        for (i, (p, e)) in traced
            .image
            .pixels
            .iter()
            .zip(&traced.std_error)
            .enumerate()
        {
            let (got, se) = (p[0] as f64, e[0] as f64);
            assert!(
                (got - want).abs() <= TRACER_SIGMAS * se + TRACER_ROUNDING * want,
                "a {deg}° sun: pixel {i} is {got} ± {se}, the closed form {want}"
            );
        }
    }
}

/// The clay of the shared sphere on its plane made a glossy lobe at the lowest roughness, with
/// `extra` after it (lights).
fn mirror_ball(extra: &str) -> String {
    let clay = "[material.clay]\ntype = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]";
    assert!(SPHERE_ON_PLANE.contains(clay));
    let text = SPHERE_ON_PLANE.replace(
        clay,
        &format!(
            "[material.clay]\ntype = \"glossy\"\nalbedo = [0.3, 0.1, 0.05]\n\
             specular = [0.6, 0.6, 0.6]\nroughness = {MIN_ROUGHNESS:?}"
        ),
    );
    format!("{text}\n{extra}")
}

const PANEL: &str = r#"
[[light]]
name = "panel"
type = "quad"
corners = [[-0.5, 2.0, -0.5], [0.5, 2.0, -0.5], [0.5, 2.0, 0.5], [-0.5, 2.0, 0.5]]
intensity = 3.0
"#;

/// A sky with a small sun on a cube of face `n`.
fn sky(n: usize) -> CubeMap {
    EnvMap::from_spec("sun:35,60")
        .unwrap()
        .to_cube(n, EnvRotation::default())
        .unwrap()
}

fn bounce_settings() -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        edge_spp: 0,
        bounces: 1,
        paths: 8,
        light_samples: 4,
        ..BakeSettings::default()
    }
}

#[track_caller]
fn assert_finite(what: &str, img: &Image) {
    if let Some((x, y, v)) = img.first_non_finite() {
        panic!("{what}: pixel ({x}, {y}) is {v}");
    }
}

/// Path traces and bakes with a bounce `scene` (its lights on), under a sky; every image
/// finite.
fn traces_and_bakes_finite(scene: &Scene, what: &str) {
    let settings = bounce_settings();
    let cube = sky(settings.cube_n);
    let mix = LightMix::new(&scene.lights, &LightSetting::defaults(&scene.lights)).unwrap();
    let traced = path_trace_env(
        scene,
        &CubeLight::new(&cube),
        &mix,
        &settings,
        8,
        &|_, _| {},
    )
    .unwrap_or_else(|e| panic!("{what}, path traced: {e}"));
    assert_finite(&format!("{what}, path traced"), &traced.image);
    assert!(
        traced.image.pixels.iter().any(|p| p[0] > 0.0),
        "{what}: the path-traced image is black"
    );
    let t = bake(scene, &settings, &|_| {}).unwrap_or_else(|e| panic!("{what}, baked: {e}"));
    let img = relight_wavelet(&t, &full_light(&cube)).unwrap().0;
    assert_finite(&format!("{what}, baked with a bounce"), &img);
    if !scene.lights.is_empty() {
        assert_finite(&format!("{what}, its lights baked"), &lights_alone(&t));
    }
}

#[test]
fn the_lowest_roughness_path_traces_and_bakes_a_bounce_to_finite_images() {
    let scene = scene_from(&mirror_ball(PANEL), "hostile-mirror");
    let clay = scene
        .material_names
        .iter()
        .position(|n| n == "clay")
        .unwrap();
    let alpha = scene.lobes_at(clay as u32, Vec2::ZERO).alpha;
    assert!(
        (alpha - MIN_ROUGHNESS * MIN_ROUGHNESS).abs() <= 1e-9,
        "α = {alpha}"
    );
    traces_and_bakes_finite(&scene, "a ball of roughness 0.02");
    // The environment alone, as `prt reference --estimator path` and `prt bounces` trace it.
    let settings = bounce_settings();
    let traced = path_trace(&scene, &sky(8), &settings, 8, &|_, _| {}).unwrap();
    assert_finite("a ball of roughness 0.02 under the sky", &traced.image);
}

#[test]
fn the_lowest_roughness_bakes_and_draws_a_finite_lobe_per_vertex() {
    // What `prt bake --per-vertex` bakes of a glossy scene: the glossy vertices' visibility, and
    // their lobe drawn per pixel against the light, from a camera the bake never saw.
    use wavelet_prt::draw::vertex::{bake_camera, draw_relit, orbit};
    use wavelet_prt::relight::{LightContext, lobe_light};
    let scene = scene_from(&mirror_ball(""), "hostile-mirror-vertices");
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        domain: BakeDomain::Vertices { edge_length: 0.3 },
        visibility: true,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let vis = t
        .mesh()
        .and_then(|m| m.visibility.as_ref())
        .expect("the glossy material keeps its visibility");
    assert!(!vis.vertices.is_empty(), "no glossy vertex");
    let env = EnvMap::from_spec("sun:35,60").unwrap();
    let image = relit(&t, &env, EnvRotation::default(), RelightRequest::Full);
    assert_finite("the per-vertex bake, relit", &image);
    let colours = vertex_colours(&t, &image).unwrap();
    assert!(colours.iter().flatten().all(|c| c.is_finite()));
    let ctx = LightContext::new(&t).unwrap();
    let light = ctx.prepare(&env, EnvRotation::default()).unwrap();
    let lobe = lobe_light(&t, &ctx, Some(&light), &RelightRequest::Full)
        .unwrap()
        .expect("a light for the lobe");
    let camera = orbit(&bake_camera(&t).unwrap(), 40.0, 10.0);
    let drawn = draw_relit(&t, &image, Some(&lobe), &camera, None, 1).unwrap();
    assert_finite("the lobe drawn per pixel", &drawn.image);
    assert!(drawn.coverage.iter().any(|&c| c > 0.0), "nothing drawn");
}

#[test]
fn a_gltf_roughness_factor_of_zero_path_traces_and_bakes_a_bounce_to_finite_images() {
    let dir = temp_dir("hostile-lights-gltf");
    let mut b = test_scene(4, false);
    b.set(
        "materials",
        json!([
            {"name": "checker", "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 0.0}},
            {"name": "chrome", "pbrMetallicRoughness": {
                "baseColorFactor": [0.9, 0.9, 0.9, 1.0], "metallicFactor": 1.0,
                "roughnessFactor": 0.0}}
        ]),
    );
    let path = b.write_glb(&dir, "smooth");
    let framing = Framing {
        width: Some(24),
        ..Framing::default()
    };
    let scene = Scene::load_with(&path, &framing).unwrap();
    for m in 0..2 {
        let alpha = scene.lobes_at(m, Vec2::splat(0.5)).alpha;
        assert!(
            (alpha - MIN_ROUGHNESS * MIN_ROUGHNESS).abs() <= 1e-9,
            "material {m}: α = {alpha}"
        );
    }
    traces_and_bakes_finite(&scene, "a glTF scene of roughnessFactor 0");
}

#[test]
fn a_material_gone_non_finite_is_named_and_the_environment_is_not_blamed() {
    let mut scene = scene_from(&mirror_ball(""), "hostile-nan-material");
    let clay = scene
        .material_names
        .iter()
        .position(|n| n == "clay")
        .unwrap();
    scene.materials[clay] = Material::Glossy {
        albedo: Vec3::splat(0.3),
        specular: Vec3::splat(0.6),
        roughness: f32::NAN,
    };
    let e = path_trace(&scene, &sky(8), &bounce_settings(), 4, &|_, _| {})
        .err()
        .expect("a NaN lobe is an error")
        .to_string();
    assert!(e.contains("material `clay`") && e.contains("NaN"), "{e}");
    assert!(!e.contains("environment far too bright"), "{e}");
}
