//! The front door (`wavelet_prt::api`): bake settings through JSON and TOML, a bake cancelled
//! before it starts and while it runs (leaving no file), environments from arrays against the
//! same map read from a file, and the relighter's kept lights.

mod common;

use std::sync::atomic::{AtomicUsize, Ordering};

use common::{Rng, SPHERE_ON_PLANE, names_in, scene_from, temp_dir};
use wavelet_prt::PrtError;
use wavelet_prt::api::{
    self, BakeDomain, BakeProgress, BakeSettings, Cancel, EnvRotation, Environment, Image,
    LightMix, RelightRequest, Relighter, Scene, Weighting,
};
use wavelet_prt::bake::bounce::BounceVisibility;
use wavelet_prt::output::film::ToneMap;
use wavelet_prt::store::budget::Budget;
use wavelet_prt::store::quant::Quantization;

/// A small bake: a cube of 4 x 4 faces, SH order 2.
fn small() -> BakeSettings {
    BakeSettings {
        cube_n: 4,
        sh_order: 2,
        ..BakeSettings::default()
    }
}

/// Settings that differ from the defaults in every field.
fn unusual() -> BakeSettings {
    BakeSettings {
        cube_n: 16,
        sh_order: 4,
        spp: 3,
        edge_spp: 9,
        texel_samples: 4,
        edge_texel_samples: 16,
        threshold: 0.0125,
        budget: Budget::Area,
        quantization: Quantization::Q16,
        lossless: true,
        unshadowed: true,
        seed: 12345,
        shard: Some([1, 4]),
        bounces: 2,
        paths: 64,
        bounce_visibility: BounceVisibility::Exact,
        cache_spacing: 2.5,
        domain: BakeDomain::Vertices { edge_length: 0.037 },
        light_samples: 16,
        refine_shadows: true,
        visibility: true,
    }
}

#[test]
fn bake_settings_go_through_json_and_toml_unchanged() {
    for settings in [BakeSettings::default(), small(), unusual()] {
        let json = serde_json::to_string(&settings).unwrap();
        let back: BakeSettings = serde_json::from_str(&json).unwrap();
        assert_eq!(back, settings, "through JSON: {json}");
        let text = toml::to_string(&settings).unwrap();
        let back: BakeSettings = toml::from_str(&text).unwrap();
        assert_eq!(back, settings, "through TOML:\n{text}");
    }
    // The values are written as the flags take them.
    let json = serde_json::to_string(&unusual()).unwrap();
    for part in [
        r#""budget":"area""#,
        r#""quantization":"q16""#,
        r#""bounce_visibility":"exact""#,
        r#""shard":[1,4]"#,
        r#""domain":{"vertices":{"edge_length":0.037}}"#,
    ] {
        assert!(json.contains(part), "{part} not in {json}");
    }
}

#[test]
fn partial_settings_take_the_defaults_and_unknown_keys_are_refused() {
    let want = BakeSettings {
        cube_n: 8,
        ..BakeSettings::default()
    };
    let got: BakeSettings = serde_json::from_str(r#"{"cube_n": 8}"#).unwrap();
    assert_eq!(got, want);
    // `cube` is the flag's name (`--cube`).
    let got: BakeSettings = toml::from_str("cube = 8").unwrap();
    assert_eq!(got, want);
    let got: BakeSettings = serde_json::from_str("{}").unwrap();
    assert_eq!(got, BakeSettings::default());
    let got: BakeSettings =
        toml::from_str("sh_order = 3\nbudget = \"sun\"\ndomain = \"view\"\n").unwrap();
    assert_eq!(
        got,
        BakeSettings {
            sh_order: 3,
            budget: Budget::Sun,
            ..BakeSettings::default()
        }
    );
    let e = serde_json::from_str::<BakeSettings>(r#"{"cube_size": 8}"#).unwrap_err();
    assert!(e.to_string().contains("cube_size"), "{e}");
    let e = toml::from_str::<BakeSettings>("budget = \"l3\"").unwrap_err();
    assert!(e.to_string().contains("l3"), "{e}");
}

/// The sphere on its ground at 128 x 128 pixels: 64 tiles.
fn many_tiles(name: &str) -> Scene {
    let text = SPHERE_ON_PLANE.replace("width = 37\nheight = 21", "width = 128\nheight = 128");
    scene_from(&text, name)
}

#[test]
fn a_bake_cancelled_before_it_starts_does_nothing() {
    let scene = many_tiles("api-cancel-before");
    let cancel = Cancel::new();
    assert!(!cancel.is_cancelled());
    cancel.cancel();
    assert!(cancel.clone().is_cancelled());
    let calls = AtomicUsize::new(0);
    let progress = |_: BakeProgress| {
        calls.fetch_add(1, Ordering::Relaxed);
    };
    let e = api::bake(&scene, &small(), &progress, &cancel).unwrap_err();
    assert!(matches!(e, PrtError::Cancelled), "{e:?}");
    assert_eq!(e.to_string(), "cancelled");
    let dir = temp_dir("api-cancel-before-out");
    let out = dir.join("out.prt");
    let e = api::bake_to_file(&scene, &small(), &out, &progress, &cancel).unwrap_err();
    assert!(matches!(e, PrtError::Cancelled), "{e:?}");
    assert_eq!(calls.load(Ordering::Relaxed), 0, "progress was reported");
    assert!(
        names_in(&dir).is_empty(),
        "left behind: {:?}",
        names_in(&dir)
    );
}

#[test]
fn a_bake_cancelled_after_its_first_tile_stops_and_leaves_no_file() {
    let scene = many_tiles("api-cancel-during");
    // Few threads, so that most tiles are still to take when the first one is done.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap();
    let dir = temp_dir("api-cancel-during-out");
    let out = dir.join("out.prt");
    for to_file in [false, true] {
        let cancel = Cancel::new();
        let done = AtomicUsize::new(0);
        let total = AtomicUsize::new(0);
        let progress = |p: BakeProgress| {
            done.fetch_max(p.pixels_done, Ordering::Relaxed);
            total.store(p.pixels_total, Ordering::Relaxed);
            if p.pixels_done > 0 {
                cancel.cancel();
            }
        };
        let e = pool.install(|| match to_file {
            false => api::bake(&scene, &small(), &progress, &cancel).err(),
            true => api::bake_to_file(&scene, &small(), &out, &progress, &cancel).err(),
        });
        let e = e.expect("the bake finished although it was cancelled");
        assert!(matches!(e, PrtError::Cancelled), "{e:?}");
        let (done, total) = (done.into_inner(), total.into_inner());
        assert_eq!(total, 128 * 128);
        assert!(
            done > 0 && done < total / 2,
            "{done} of {total} pixels baked before the bake stopped"
        );
    }
    assert!(
        names_in(&dir).is_empty(),
        "left behind: {:?}",
        names_in(&dir)
    );
}

#[test]
fn a_bake_to_a_file_writes_what_open_reads() {
    let scene = scene_from(SPHERE_ON_PLANE, "api-to-file");
    let dir = temp_dir("api-to-file-out");
    let out = dir.join("out.prt");
    let meta = api::bake_to_file(&scene, &small(), &out, &|_| {}, &Cancel::new()).unwrap();
    let t = api::open(&out).unwrap();
    assert_eq!(t.meta, meta);
    assert_eq!(
        t,
        api::bake(&scene, &small(), &|_| {}, &Cancel::new()).unwrap()
    );
    // The output is checked before any work, as `prt bake` checks it.
    let e = api::bake_to_file(
        &scene,
        &small(),
        dir.join("out.txt"),
        &|_| {},
        &Cancel::new(),
    )
    .unwrap_err();
    assert!(e.to_string().contains(".prt"), "{e}");
    assert_eq!(names_in(&dir), ["out.prt"]);
}

#[test]
fn an_array_is_the_same_environment_as_the_file_of_its_pixels() {
    let (w, h) = (16, 8);
    let mut rng = Rng::new(7);
    let mut pixels: Vec<[f32; 3]> = (0..w * h)
        .map(|_| std::array::from_fn(|_| rng.range_f32(0.0, 4.0)))
        .collect();
    pixels[0] = [0.0; 3];
    pixels[1] = [1e6, 1e-30, 3.0e-3];
    let dir = temp_dir("api-array");
    let path = dir.join("env.exr");
    Image {
        width: w,
        height: h,
        pixels: pixels.clone(),
    }
    .save(&path, ToneMap::default())
    .unwrap();
    let from_file = Environment::from_file(&path).unwrap();
    let from_array = Environment::from_array(w, h, pixels.clone()).unwrap();
    assert_eq!(from_array.source(), "array");
    for env in [&from_file, &from_array] {
        let map = env.map();
        assert_eq!((map.width, map.height), (w, h));
        let bits =
            |p: &[[f32; 3]]| -> Vec<u32> { p.iter().flatten().map(|v| v.to_bits()).collect() };
        assert_eq!(bits(&map.pixels), bits(&pixels), "{}", env.source());
    }
}

#[test]
fn arrays_that_are_no_environment_are_refused_with_their_reason() {
    let ok = || vec![[1.0f32; 3]; 4 * 2];
    let refused = |w: usize, h: usize, pixels: Vec<[f32; 3]>, why: &str| {
        let e = Environment::from_array(w, h, pixels).unwrap_err();
        let text = e.to_string();
        assert!(
            text.starts_with("array: ") && text.contains(why),
            "`{why}` not in: {text}"
        );
    };
    Environment::from_array(4, 2, ok()).unwrap();
    refused(
        4,
        2,
        vec![[1.0; 3]; 7],
        "7 pixels for a 4 x 2 map, which takes 8",
    );
    refused(0, 2, Vec::new(), "map size 0 x 2");
    let mut nan = ok();
    nan[5][1] = f32::NAN;
    refused(4, 2, nan, "pixel (x = 1, y = 1) channel G is NaN");
    let mut infinite = ok();
    infinite[3][2] = f32::INFINITY;
    refused(4, 2, infinite, "pixel (x = 3, y = 0) channel B is inf");
    let mut negative = ok();
    negative[2][0] = -0.5;
    refused(
        4,
        2,
        negative,
        "pixel (x = 2, y = 0) channel R is -0.5: radiance must not be negative",
    );
    refused(4, 2, vec![[0.0; 3]; 8], "it lights nothing");
    // The sun's numbers are checked as `sun:ELEV,AZIM` checks them.
    assert!(Environment::sun(95.0, 0.0).is_err());
    assert!(Environment::sun(f64::NAN, 0.0).is_err());
    assert!(Environment::sun(10.0, f64::INFINITY).is_err());
}

#[test]
fn the_relighter_prepares_an_environment_once_per_rotation() {
    let scene = scene_from(SPHERE_ON_PLANE, "api-relighter");
    let t = api::bake(&scene, &small(), &|_| {}, &Cancel::new()).unwrap();
    let mut r = Relighter::new(t).unwrap();
    assert_eq!(r.prepared(), 0);
    let sun = Environment::sun(40.0, 30.0).unwrap();
    let wavelet = RelightRequest::Wavelet {
        k: 8,
        weighting: Weighting::Area,
    };
    let still = EnvRotation::default();
    let none = LightMix::none();
    let first = r.relight(&sun, &wavelet, still, &none).unwrap();
    assert_eq!((first.width, first.height), (37, 21));
    assert!(first.pixels.iter().flatten().all(|v| v.is_finite()));
    assert!(first.pixels.iter().flatten().any(|&v| v > 0.0));
    assert_eq!(r.prepared(), 1);
    let second = r.relight(&sun, &wavelet, still, &none).unwrap();
    assert_eq!(
        r.prepared(),
        1,
        "the second relight prepared the light again"
    );
    assert_eq!(second, first);
    // Another request, or a clone of the environment, prepares nothing either.
    let full = r
        .relight(&sun.clone(), &RelightRequest::Full, still, &none)
        .unwrap();
    r.relight(&sun, &RelightRequest::Sh { order: 2 }, still, &none)
        .unwrap();
    assert_eq!(r.prepared(), 1);
    // A turn is another light; the unturned one is still kept.
    let turned = r
        .relight(&sun, &wavelet, EnvRotation::yaw(90.0), &none)
        .unwrap();
    assert_eq!(r.prepared(), 2);
    assert_ne!(turned, first);
    assert_eq!(r.relight(&sun, &wavelet, still, &none).unwrap(), first);
    assert_eq!(r.prepared(), 2);
    // The metrics over the pixels that see the scene.
    let same = api::compare(&second, &first, Some(r.coverage())).unwrap();
    assert_eq!(same.rel_l2, 0.0);
    let eight = api::compare(&first, &full, Some(r.coverage())).unwrap();
    assert!(eight.rel_l2 > 0.0 && eight.rel_l2.is_finite(), "{eight:?}");
    // A per-pixel bake's camera cannot move.
    let e = r
        .draw(&sun, &wavelet, still, &none, &scene.camera)
        .unwrap_err();
    assert!(e.to_string().contains("per-pixel bake"), "{e}");
}

#[test]
fn the_relighter_draws_a_per_vertex_bake_from_a_moved_camera() {
    let scene = scene_from(SPHERE_ON_PLANE, "api-per-vertex");
    let settings = BakeSettings {
        domain: BakeDomain::Vertices { edge_length: 0.5 },
        ..small()
    };
    let t = api::bake(&scene, &settings, &|_| {}, &Cancel::new()).unwrap();
    let mut r = Relighter::new(t).unwrap();
    let camera = r.camera_at([2.0, 2.0, 3.0], [0.0, 0.5, 0.0]).unwrap();
    let sun = Environment::sun(40.0, 30.0).unwrap();
    let request = RelightRequest::Wavelet {
        k: 8,
        weighting: Weighting::Area,
    };
    let drawn = r
        .draw(
            &sun,
            &request,
            EnvRotation::default(),
            &LightMix::none(),
            &camera,
        )
        .unwrap();
    assert_eq!((drawn.width, drawn.height), (37, 21));
    assert!(drawn.pixels.iter().flatten().all(|v| v.is_finite()));
    assert!(drawn.pixels.iter().flatten().any(|&v| v > 0.0));
    let again = r
        .draw(
            &sun,
            &request,
            EnvRotation::default(),
            &LightMix::none(),
            &camera,
        )
        .unwrap();
    assert_eq!(again, drawn);
    assert_eq!(r.prepared(), 1);
}
