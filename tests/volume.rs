//! Volumes: the medium through the wavelet bake against the brute-force reference, the ground
//! shadowed by a cloud, the SH self-transfer march against the reference, GPU against CPU, and bad
//! grid files.

mod common;

use common::{GPU_MATCH, scene_from, temp_dir};
use glam::Vec3;
use wavelet_prt::bake::reference::render_reference;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::math::cubemap::CubeMap;
use wavelet_prt::output::film::Image;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::RelightRequest;
use wavelet_prt::scene::Scene;
use wavelet_prt::volume::{
    MediumLook, ScatterSettings, TransferSettings, VolumeLight, VolumeView, bake_volume,
    render_volume,
};

/// Single scattering alone: what the brute-force reference of a medium computes.
fn single() -> TransferSettings {
    TransferSettings {
        scatter: ScatterSettings {
            orders: 1,
            ..ScatterSettings::default()
        },
        ..TransferSettings::default()
    }
}

/// The transmittance view (the camera march, half-voxel steps) against the medium's own
/// transmittance (one-voxel midpoint steps) along each pixel's ray: two discretisations of one
/// optical depth over the trilinear grid, plus the march's early stop below T = 1e-4.
const TRANSMITTANCE_VIEW: f32 = 0.02;
/// Relative L2 the default thresholding (a per-row budget of 1% of an unshadowed row, 8-bit
/// values) adds to the fog's lossless bake: the README's Volumes section measures 1.1% from the
/// default threshold on `fog.toml` (64², N = 16); twice that leaves room for this smaller view.
const DEFAULT_THRESHOLD_ADDS: f64 = 0.02;
/// A veiled pixel's coverage 1 − T from the bake, and the unit sky composited behind it, against
/// 1 − T and 1 − coverage computed here: the same f32 expressions on both sides, so at most a few
/// ulps of values no larger than 1.
const VEIL_ROUNDING: f32 = 1e-5;
/// How far the full view may exceed the in-scatter view: the full view weights the same samples
/// by the camera ray's transmittance (at most 1) and stops early where the in-scatter view
/// marches on, so only the rounding of their f32 sums, a few ulps of values of order 1, may lift
/// it above.
const ATTENUATION_ROUNDING: f32 = 1e-6;
/// Full red against 0.9 times the dc view under a white sky of radiance 1 (g = 0): the light's
/// band-0 term is then the dc view's scale 1/(2√π) and its higher terms vanish by symmetry, each
/// up to the rounding of f32 sums over the cube's 384 texels. This much absolute, for pixels with
/// little fog...
const DC_RELATION_ABS: f32 = 1e-4;
/// ...and this much of the dc value, for the rest.
const DC_RELATION_REL: f32 = 1e-3;
/// The SH march against the brute-force reference under low-frequency light, relative L2, for
/// isotropic fog: the sweep's blur and the SH truncation of the light-phase product, measured
/// 0.9-1.0%...
const SH_MARCH_ISOTROPIC: f64 = 0.02;
/// ...and at g = 0.4, where the forward-peaked phase gives the truncation more to cut: measured
/// 1.6%.
const SH_MARCH_FORWARD: f64 = 0.03;

/// The shared foggy blob at 24×20 pixels.
fn fog(g: f32) -> String {
    common::fog_scene(g, 24, 20)
}

/// A cloud layer over a ground plane, seen from the side and above.
fn cloud_over_ground(with_medium: bool) -> String {
    let medium = if with_medium {
        r#"
[medium]
type = "ellipsoid"
bounds = [[-0.6, 0.8, -0.6], [0.6, 1.2, 0.6]]
resolution = 24
extinction = 6.0
albedo = [0.95, 0.95, 0.95]
center = [0.0, 1.0, 0.0]
radii = [0.5, 0.15, 0.5]
falloff = 0.2
"#
    } else {
        ""
    };
    format!(
        r#"
[camera]
eye = [0.0, 2.2, 2.6]
target = [0.0, 0.4, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 45.0
width = 24
height = 20

[material.ground]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[[shape]]
type = "quad"
corners = [[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]
material = "ground"
{medium}"#
    )
}

fn lossless(n: usize) -> BakeSettings {
    BakeSettings {
        cube_n: n,
        sh_order: 3,
        lossless: true,
        ..BakeSettings::default()
    }
}

fn full(scene: &Scene, settings: &BakeSettings, env: &EnvMap) -> Image {
    let t = bake(scene, settings, &|_| {}).unwrap();
    common::relit(&t, env, EnvRotation::default(), RelightRequest::Full)
}

/// The bake reads each texel's optical depths from one sweep of the grid, the reference marches
/// every shadow ray; the sweep's bilinear steps blur the optical depth slightly (see
/// `volume::tests::sweep_matches_a_direct_march_in_a_soft_medium`). Measured on these scenes:
/// 2.0% (fog, g = 0), 2.2% (fog, g = 0.5), 0.15% (cloud over ground); everything else in the
/// two is the same sum.
const SWEEP_MATCH: f64 = 0.03;

#[test]
fn wavelet_bake_of_a_medium_with_every_term_equals_the_brute_force_reference() {
    for g in [0.0, 0.5] {
        let scene = scene_from(&fog(g), &format!("vol-fog-{g}"));
        let env = EnvMap::from_spec("sun:35,60,8").unwrap();
        let settings = lossless(8);
        let img = full(&scene, &settings, &env);
        let cube = env.to_cube(8, EnvRotation::default()).unwrap();
        let brute = render_reference(&scene, &cube, &settings).unwrap();
        let lit = brute.pixels.iter().filter(|p| p[0] > 0.0).count();
        assert!(lit > 100, "the fog covers the view ({lit} pixels)");
        let e = relative_l2(&img, &brute, None).unwrap();
        println!("fog g = {g}: bake vs reference {e}");
        assert!(e < SWEEP_MATCH, "g = {g}: bake vs reference {e}");
    }
}

#[test]
fn a_cloud_shadows_the_ground_in_the_bake_and_the_reference() {
    let env = EnvMap::from_spec("sun:80,0,3").unwrap();
    let settings = lossless(8);
    let cube = env.to_cube(8, EnvRotation::default()).unwrap();
    let with = scene_from(&cloud_over_ground(true), "vol-cloud");
    let without = scene_from(&cloud_over_ground(false), "vol-nocloud");
    let brute = render_reference(&with, &cube, &settings).unwrap();
    let clear = render_reference(&without, &cube, &settings).unwrap();
    let baked = full(&with, &settings, &env);
    let e = relative_l2(&baked, &brute, None).unwrap();
    println!("cloud over ground: bake vs reference {e}");
    assert!(e < SWEEP_MATCH, "bake vs reference {e}");
    // The ground straight below the cloud centre: the pixel that sees (0, 0, 0).
    let cam = &with.camera;
    let (mut x0, mut y0, mut best) = (0, 0, f32::INFINITY);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let r = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            let t = -r.origin.y / r.dir.y;
            let p = r.origin + r.dir * t;
            // Pixels whose camera ray misses the cloud, so only its shadow darkens them.
            let through = p.length();
            if t > 0.0
                && through < best
                && with
                    .medium
                    .as_ref()
                    .unwrap()
                    .build(None)
                    .unwrap()
                    .transmittance(r.origin, r.dir, t)
                    > 0.999
            {
                best = through;
                (x0, y0) = (x, y);
            }
        }
    }
    let i = (y0 * cam.width + x0) as usize;
    let (shadowed, open) = (brute.pixels[i][1], clear.pixels[i][1]);
    assert!(
        best < 0.35,
        "a ground pixel near the centre seen past the cloud ({best})"
    );
    assert!(
        shadowed < 0.7 * open,
        "ground under the cloud: {shadowed} with it, {open} without"
    );
}

/// A smooth sky: brighter overhead, no sun.
fn sky_cube(n: usize) -> CubeMap {
    CubeMap::from_fn(n, |d| {
        let v = 1.0 + 0.6 * d.y as f32 + 0.2 * d.x as f32;
        [v, 0.9 * v, 0.8 * v]
    })
    .unwrap()
}

#[test]
fn sh_march_matches_the_brute_force_reference_under_low_frequency_light() {
    // Measured: 0.9-1.0% isotropic, 1.6% at g = 0.4 (the sweep's blur and the SH truncation of
    // the light-phase product).
    for (g, tolerance) in [(0.0f32, SH_MARCH_ISOTROPIC), (0.4, SH_MARCH_FORWARD)] {
        let scene = scene_from(&fog(g), &format!("vol-sh-{g}"));
        let vt = bake_volume(&scene, None, &single(), &|_, _| {}).unwrap();
        for (name, cube) in [
            ("constant", CubeMap::constant(8, [1.0, 0.9, 0.8]).unwrap()),
            ("sky", sky_cube(8)),
        ] {
            let light = VolumeLight::new(&vt, &cube, &MediumLook::of(&vt)).unwrap();
            let img = render_volume(&vt, &light, &scene.camera, VolumeView::Full);
            let settings = BakeSettings {
                cube_n: 8,
                ..BakeSettings::default()
            };
            let brute = render_reference(&scene, &cube, &settings).unwrap();
            let e = relative_l2(&img, &brute, None).unwrap();
            println!("g = {g}, {name}: SH march vs reference {e}");
            assert!(e < tolerance, "g = {g}, {name}: SH march vs reference {e}");
        }
    }
}

#[test]
fn debug_views_agree_with_what_they_show() {
    let scene = scene_from(&fog(0.0), "vol-views");
    let vt = bake_volume(&scene, None, &single(), &|_, _| {}).unwrap();
    let cube = CubeMap::constant(8, [1.0; 3]).unwrap();
    let light = VolumeLight::new(&vt, &cube, &MediumLook::of(&vt)).unwrap();
    let cam = &scene.camera;
    let t = render_volume(&vt, &light, cam, VolumeView::Transmittance);
    let full = render_volume(&vt, &light, cam, VolumeView::Full);
    let inscatter = render_volume(&vt, &light, cam, VolumeView::InScatter);
    let dc = render_volume(&vt, &light, cam, VolumeView::TransferDc);
    let medium = scene.medium.as_ref().unwrap().build(None).unwrap();
    for (i, p) in t.pixels.iter().enumerate() {
        let (x, y) = (i % cam.width as usize, i / cam.width as usize);
        let r = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
        let want = medium.transmittance(r.origin, r.dir, f32::INFINITY);
        assert!(
            (p[0] - want).abs() < TRANSMITTANCE_VIEW,
            "pixel {i}: {} vs {want}",
            p[0]
        );
        // Attenuation only lowers the radiance.
        assert!(full.pixels[i][0] <= inscatter.pixels[i][0] + ATTENUATION_ROUNDING);
        // Under a white sky of radiance 1 and albedo (0.9, ...), full red = 0.9 · dc.
        assert!(
            (full.pixels[i][0] - 0.9 * dc.pixels[i][0]).abs()
                < DC_RELATION_ABS + DC_RELATION_REL * dc.pixels[i][0]
        );
    }
}

#[test]
fn gpu_march_equals_the_cpu_march() {
    let Some(gpu) = common::gpu_or_skip("volume GPU") else {
        return;
    };
    for g in [0.0, 0.6] {
        let scene = scene_from(&fog(g), &format!("vol-gpu-{g}"));
        let vt = bake_volume(&scene, None, &TransferSettings::default(), &|_, _| {}).unwrap();
        let env = EnvMap::load(&common::assets().join("envmaps/blender_sunrise.exr")).unwrap();
        let cube = env.to_cube(16, EnvRotation::default()).unwrap();
        // Every baked order, with the scattered field the march adds.
        assert!(vt.orders() > 1);
        let light = VolumeLight::new(&vt, &cube, &MediumLook::of(&vt)).unwrap();
        let mut gv = wavelet_prt::volume::gpu::GpuVolume::new(&gpu, &vt).unwrap();
        // A free camera away from the baked one, at a size 8x8 workgroups do not divide.
        let cam = vt
            .camera(Some(Vec3::new(1.5, 1.4, 2.0)), None, Some((37, 21)))
            .unwrap();
        for view in VolumeView::ALL {
            let cpu = render_volume(&vt, &light, &cam, view);
            let (dev, _) = gv.render(&gpu, &light, &cam, view).unwrap();
            let e = relative_l2(&dev, &cpu, None).unwrap();
            assert!(e < GPU_MATCH, "g = {g}, {view:?}: GPU vs CPU {e}");
        }
    }
}

#[test]
fn bad_grid_files_are_clear_errors() {
    let dir = temp_dir("vol-bad-grid");
    let scene = |npy: &str| {
        format!(
            r#"
[camera]
eye = [0.0, 0.0, 3.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
width = 8
height = 8

[medium]
type = "grid"
bounds = [[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]
extinction = 1.0
path = "{npy}"
"#
        )
    };
    let grid =
        wavelet_prt::medium::DensityGrid::from_fn([4, 3, 2], Vec3::splat(-1.0), Vec3::ONE, |p| {
            p.x.abs()
        });
    wavelet_prt::medium::save_npy(&dir.join("good.npy"), &grid).unwrap();
    let mut nan = grid.clone();
    nan.data[5] = f32::NAN;
    wavelet_prt::medium::save_npy(&dir.join("nan.npy"), &nan).unwrap();
    std::fs::write(dir.join("junk.npy"), b"not numpy").unwrap();
    let load = |npy: &str| {
        let p = dir.join(format!("{npy}.toml"));
        std::fs::write(&p, scene(&format!("{npy}.npy"))).unwrap();
        Scene::load(&p)
    };
    let good = load("good").unwrap();
    let m = good.medium.as_ref().unwrap().build(None).unwrap();
    assert_eq!(m.grid.dims, [4, 3, 2]);
    let e = load("nan").unwrap_err().to_string();
    assert!(
        e.contains("nan.npy") && e.contains("(x 1, y 1, z 0)"),
        "{e}"
    );
    let e = load("junk").unwrap_err().to_string();
    assert!(e.contains("junk.npy") && e.contains("NumPy"), "{e}");
    let e = load("missing").unwrap_err().to_string();
    assert!(
        e.contains("missing.npy") && e.contains("missing.toml") && e.contains("medium.path"),
        "{e}"
    );
    // A grid keeps its file's resolution: the key is refused rather than ignored.
    let p = dir.join("res.toml");
    std::fs::write(
        &p,
        scene("good.npy").replace("extinction", "resolution = 8\nextinction"),
    )
    .unwrap();
    let e = Scene::load(&p).unwrap_err().to_string();
    assert!(e.contains("medium.resolution"), "{e}");
}

#[test]
fn scene_mistakes_around_a_medium_are_named() {
    let dir = temp_dir("vol-scene-errors");
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    // A medium-only scene still needs its camera, and the error says so at the top level.
    let no_camera = fog(0.0).replace("[camera]", "[kamera]");
    let e = Scene::load(&write("nocam.toml", &no_camera))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("field `kamera`") || e.contains("field `camera`"),
        "{e}"
    );
    assert!(!e.contains("medium.camera"), "{e}");
    // An ellipsoid outside its box leaves nothing: an error, not a black image.
    let outside = fog(0.0).replace("center = [0.0, 0.6, 0.0]", "center = [5.0, 0.6, 0.0]");
    let scene = Scene::load(&write("outside.toml", &outside)).unwrap();
    let e = match scene.medium.as_ref().unwrap().build(None) {
        Ok(_) => panic!("an ellipsoid outside its box built a medium"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("practically empty"), "{e}");
    // Each file kind names the other when given in its place.
    let fog_scene = Scene::load(&write("fog.toml", &fog(0.0))).unwrap();
    let vt = bake_volume(
        &fog_scene,
        Some(8),
        &TransferSettings::default(),
        &|_, _| {},
    )
    .unwrap();
    let prtv = dir.join("fog.prtv");
    vt.save(&prtv).unwrap();
    let e = wavelet_prt::store::transport::Transport::load(&prtv)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a volume file") && e.contains("prt volume render"),
        "{e}"
    );
    let t = bake(&fog_scene, &lossless(4), &|_| {}).unwrap();
    let prt = dir.join("fog.prt");
    t.save(&prt).unwrap();
    let e = wavelet_prt::volume::VolumeTransfer::load(&prt)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a transport file") && e.contains("prt relight"),
        "{e}"
    );
    // An unwritable output is named as asked, not as its temporary file.
    let bad = dir.join("no-such-dir").join("fog.prtv");
    let e = vt.save(&bad).unwrap_err().to_string();
    assert!(
        e.starts_with(&bad.display().to_string()) && !e.contains("partial"),
        "{e}"
    );
}

#[test]
fn thresholding_keeps_the_faint_fringe_of_a_medium() {
    // The budget of a medium row scales with the pixel's opacity: the thin edge of the fog
    // keeps its rows instead of being dropped whole under an absolute budget.
    let scene = scene_from(&fog(0.3), "vol-threshold");
    let env = EnvMap::from_spec("sun:35,60,8").unwrap();
    let exact = full(&scene, &lossless(8), &env);
    let sparse_settings = BakeSettings {
        cube_n: 8,
        sh_order: 3,
        ..BakeSettings::default()
    };
    let sparse = full(&scene, &sparse_settings, &env);
    let e = relative_l2(&sparse, &exact, None).unwrap();
    println!("default threshold vs lossless: {e}");
    assert!(e < DEFAULT_THRESHOLD_ADDS, "thresholding added {e}");
    // Every pixel above 1% of the brightest keeps most of its light (fainter ones sit in the
    // exponential tail, down to values f16 cannot hold).
    let brightest = exact.pixels.iter().map(|p| p[1]).fold(0.0, f32::max);
    let dark = exact
        .pixels
        .iter()
        .zip(&sparse.pixels)
        .filter(|(a, b)| a[1] > 0.01 * brightest && b[1] < 0.5 * a[1])
        .count();
    assert_eq!(dark, 0, "{dark} pixels lost more than half their light");
}

// A pixel that sees the sky through a medium and no surface hid the environment entirely, so the
// medium's box showed as a dark slab against the sky. It now veils it by the medium's opacity:
// the coverage of such a pixel is 1 − T along its camera ray, and the environment behind is seen
// through T.
#[test]
fn the_environment_behind_a_medium_is_seen_through_its_transmittance() {
    let scene = scene_from(&common::fog_scene(0.3, 24, 20), "veil");
    let medium = scene.medium.as_ref().unwrap().build(None).unwrap();
    let settings = BakeSettings {
        cube_n: 2,
        sh_order: 1,
        spp: 1,
        edge_spp: 1,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let cam = &scene.camera;
    let (mut veiled, mut clear) = (0, 0);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            let seen = medium.transmittance(ray.origin, ray.dir, f32::INFINITY);
            let want = if seen < 0.999 { 1.0 - seen } else { 0.0 };
            let got = t.coverage[(y * cam.width + x) as usize];
            assert!(
                (got - want).abs() < VEIL_ROUNDING,
                "pixel ({x}, {y}): {got} against 1 − T = {want}"
            );
            if got > 0.0 && got < 0.5 {
                veiled += 1;
            } else if got == 0.0 {
                clear += 1;
            }
        }
    }
    // The thin edge of the blob veils the sky, around the box the sky is clear.
    assert!(veiled > 20 && clear > 20, "{veiled} veiled, {clear} clear");
    // Composited under a constant sky, a thinly veiled pixel shows most of the sky.
    let env = EnvMap::constant(64, 32, [1.0; 3]);
    let sky = wavelet_prt::draw::background::environment_behind(
        &t.meta,
        &t.coverage,
        &env,
        EnvRotation::default(),
    )
    .unwrap();
    for (p, c) in sky.pixels.iter().zip(&t.coverage) {
        assert!(
            (p[0] - (1.0 - c)).abs() < VEIL_ROUNDING,
            "{p:?} behind coverage {c}"
        );
    }
}
