//! The state -> image function behind the window and the screenshot.

mod common;

use wavelet_prt::app::viewer::{
    Engine, EnvEntry, EnvSource, LightState, ViewState, env_entries, screenshot,
};
use wavelet_prt::env::envmap::EnvRotation;
use wavelet_prt::relight::Method;

/// Relative L2 of 40 of the 384 wavelet terms against every term, over the per-vertex bake's
/// vertices, as the viewer reports it: the check is that the number is this relight's own error,
/// which is real (above 0) but far from all of the light; half is a loose ceiling for it.
const FORTY_TERMS_ERROR: f64 = 0.5;
/// 8-bit levels by which the GPU display may differ from the CPU's image: the GPU relights,
/// tone-maps and encodes in f32 on its own hardware and in its own order, so a value at a rounding
/// boundary may land one level apart.
const GPU_DISPLAY_LEVELS: u8 = 1;
/// The mean linear brightness with a sun of radius 8° against the small default one of the same
/// irradiance, relative: the larger disc softens the shadows, moving light between pixels, but
/// keeps the total within a few percent; a tenth is the ceiling.
const SUN_SIZE_MEAN_CHANGE: f64 = 0.1;
/// A per-vertex pane as the viewer shows it against the same drawing made here, from the same
/// relight over the same environment: the same f32 steps, so only rounding may separate them...
const VERTEX_PANE_ROUNDING: f32 = 1e-5;
/// ...relative to the value, or to this for values below it, so that sky and colours near black
/// are allowed an absolute `VERTEX_PANE_ROUNDING`.
const VERTEX_PANE_SCALE_FLOOR: f32 = 1.0;

/// An engine on the test bake with a sun (index 0) and the first bundled map, if any.
fn engine() -> Engine {
    let (entries, _) = env_entries(&[]);
    let mut envs = vec![EnvEntry {
        name: "sun".into(),
        source: EnvSource::Sun,
    }];
    envs.extend(
        entries
            .into_iter()
            .filter(|e| e.source != EnvSource::Sun)
            .take(1),
    );
    Engine::open(&common::viewer_transport_path(), envs).unwrap()
}

/// The first environment, with the sun placed at `elevation` and `azimuth` (degrees).
fn sun_at(elevation: f64, azimuth: f64) -> LightState {
    let mut light = LightState::default();
    (light.sun.elevation, light.sun.azimuth) = (elevation, azimuth);
    light
}

fn sun_state(engine: &mut Engine) -> ViewState {
    let mut s = engine.initial_state(sun_at(25.0, 60.0));
    s.display.exposure = 0.0;
    s
}

fn l2(engine: &mut Engine, s: &ViewState) -> f64 {
    engine.render(s).unwrap().panes[0].linear.rel_l2
}

#[test]
fn more_terms_lower_the_error_against_full() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.relight.method = Method::Wavelet;
    let all = 6 * common::VIEWER_N * common::VIEWER_N;
    let errors: Vec<f64> = [2, 16, 128, all]
        .iter()
        .map(|&k| {
            s.relight.terms = k;
            l2(&mut e, &s)
        })
        .collect();
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    assert!(errors[3] < common::SAME_SUM, "{errors:?}");
    s.relight.method = Method::Full;
    assert_eq!(l2(&mut e, &s), 0.0);
    // SH: higher order is closer for this smooth-enough sky.
    s.relight.method = Method::Sh;
    s.relight.sh_order = 1;
    let low = l2(&mut e, &s);
    s.relight.sh_order = common::VIEWER_SH_ORDER;
    let high = l2(&mut e, &s);
    assert!(
        high < low,
        "SH order 1: {low}, order {}: {high}",
        common::VIEWER_SH_ORDER
    );
}

#[test]
fn environment_yaw_and_sun_change_the_image() {
    let mut e = engine();
    let s = sun_state(&mut e);
    let base = e.render(&s).unwrap().panes[0].rgb.clone();
    let mut turned = s.clone();
    turned.light.rotation.yaw_deg = 90.0;
    assert_ne!(e.render(&turned).unwrap().panes[0].rgb, base, "yaw");
    let mut moved = s.clone();
    moved.light.sun.elevation = 60.0;
    assert_ne!(
        e.render(&moved).unwrap().panes[0].rgb,
        base,
        "sun elevation"
    );
    if e.envs.len() > 1 {
        let mut other = s.clone();
        other.light.env = 1;
        assert_ne!(e.render(&other).unwrap().panes[0].rgb, base, "environment");
    }
    // Same state, same image (the caches do not leak between states).
    assert_eq!(e.render(&s).unwrap().panes[0].rgb, base);
}

#[test]
fn exposure_changes_only_the_tone_mapping() {
    let mut e = engine();
    let s = sun_state(&mut e);
    let a = e.render(&s).unwrap();
    let mut brighter = s.clone();
    brighter.display.exposure += 1.0;
    let b = e.render(&brighter).unwrap();
    assert_eq!(a.panes[0].linear.image, b.panes[0].linear.image);
    assert_ne!(a.panes[0].rgb, b.panes[0].rgb);
    // The light was cached: neither the light nor the `full` image was prepared again.
    assert_eq!((b.light_seconds, b.full_seconds), (0.0, 0.0));
}

#[test]
fn a_new_light_reports_its_time_apart_from_the_full_image() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.light.rotation.yaw_deg = 33.5;
    let r = e.render(&s).unwrap();
    assert!(
        r.light_seconds > 0.0 && r.full_seconds > 0.0,
        "{} {}",
        r.light_seconds,
        r.full_seconds
    );
    s.light.rotation.yaw_deg = 34.5;
    let turned = e.render(&s).unwrap();
    assert!(turned.light_seconds > 0.0 && turned.full_seconds > 0.0);
}

#[test]
fn sh_order_above_baked_is_clamped_with_a_note() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.relight.method = Method::Sh;
    s.relight.sh_order = common::VIEWER_SH_ORDER + 5;
    s.relight.terms = 1_000_000;
    let r = e.render(&s).unwrap();
    assert_eq!(r.state.relight.sh_order, common::VIEWER_SH_ORDER);
    assert_eq!(
        r.state.relight.terms,
        6 * common::VIEWER_N * common::VIEWER_N
    );
    assert_eq!(r.notes.len(), 2, "{:?}", r.notes);
    assert_eq!(
        r.panes[0].linear.terms,
        common::VIEWER_SH_ORDER * common::VIEWER_SH_ORDER
    );
}

#[test]
fn sh_through_the_light_goes_past_the_baked_order_up_to_the_texel_count() {
    // VIEWER_N = 8: 384 texels, so SH through the light goes to order 19 (361 terms), past the
    // baked order; the M key passes through it.
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.relight.method = Method::ShLight;
    s.relight.sh_order = common::VIEWER_SH_ORDER + 5;
    let r = e.render(&s).unwrap();
    assert_eq!(r.state.relight.sh_order, common::VIEWER_SH_ORDER + 5);
    assert!(r.notes.is_empty(), "{:?}", r.notes);
    assert_eq!(r.panes[0].linear.request.method(), Method::ShLight);
    s.relight.sh_order = 1000;
    let r = e.render(&s).unwrap();
    assert_eq!(r.state.relight.sh_order, 19);
    assert_eq!(r.notes.len(), 1, "{:?}", r.notes);
    let mut cycled = wavelet_prt::app::viewer::RelightState {
        method: Method::Full,
        ..Default::default()
    };
    cycled.cycle_method();
    assert_eq!(cycled.method, Method::ShLight);
    cycled.cycle_method();
    assert_eq!(cycled.method, Method::Wavelet);
}

#[test]
fn compare_shows_sh_and_wavelet_at_matching_term_counts() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.relight.compare = true;
    s.relight.terms = 5;
    let r = e.render(&s).unwrap();
    assert_eq!(r.panes.len(), 2);
    assert_eq!(r.panes[0].linear.request.method(), Method::Sh);
    assert_eq!(r.panes[0].linear.terms, 4); // nearest n² to 5
    assert_eq!(r.panes[1].linear.request.method(), Method::Wavelet);
    assert_eq!(r.panes[1].linear.terms, 5);
    let (w, h, rgb) = r.side_by_side(4);
    assert_eq!((w, h), (2 * r.width + 4, r.height));
    assert_eq!(rgb.len(), w * h * 3);
}

#[test]
fn screenshot_writes_the_rendered_image() {
    let mut e = engine();
    let s = sun_state(&mut e);
    let out = std::env::temp_dir().join(format!("viewer-shot-{}.png", std::process::id()));
    let r = screenshot(&mut e, &s, &out).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    assert_eq!(r.panes.len(), 1);
    std::fs::remove_file(out).unwrap();
}

#[test]
fn comparisons_are_captioned_with_what_each_side_shows() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.relight.compare = true;
    let r = e.render(&s).unwrap();
    let captions = r.captions();
    assert_eq!(captions.len(), 2);
    assert!(captions[0].starts_with("SH"), "{captions:?}");
    assert!(captions[1].starts_with("wavelet"), "{captions:?}");
    let (w, h, plain) = r.composite(4);
    let (cw, ch, rgb) = r.captioned(4);
    assert_eq!(cw, w);
    assert!(ch > h);
    // The images sit unchanged under the strip, and the strip holds caption text over each
    // image: antialiased glyphs, brighter than the strip's dark grey (24) by more than a blend
    // of a glyph's edge would be.
    assert_eq!(&rgb[(ch - h) * w * 3..], &plain[..]);
    for i in 0..2 {
        let x0 = i * (r.width + 4);
        let lit = (0..ch - h)
            .flat_map(|y| (x0..x0 + r.width).map(move |x| (y, x)))
            .filter(|&(y, x)| rgb[(y * w + x) * 3] > 120)
            .count();
        assert!(lit > 20, "caption {i}: {lit} lit pixels");
    }
    // A split pair is one image, captioned left | right.
    s.display.layout = wavelet_prt::app::viewer::Layout::Split;
    let r = e.render(&s).unwrap();
    let captions = r.captions();
    assert_eq!(captions.len(), 1);
    assert!(captions[0].contains(" | "), "{captions:?}");
}

#[test]
fn a_bad_file_is_an_error_not_a_panic() {
    let dir = std::env::temp_dir();
    let bad = dir.join(format!("viewer-bad-{}.prt", std::process::id()));
    std::fs::write(&bad, b"not a transport").unwrap();
    let e = Engine::open(&bad, Vec::new())
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("does not fit a file of 15 bytes"), "{e}");
    // The window loads on its worker thread and shows the error once it arrives.
    let mut app = wavelet_prt::app::viewer::ViewerApp::new(&bad, &[]);
    assert!(app.wait_idle(std::time::Duration::from_secs(60)));
    app.poll(&eframe::egui::Context::default());
    assert!(!app.is_loaded());
    let msg = app.load_error.clone().expect("a load error");
    assert!(msg.contains(&bad.display().to_string()), "{msg}");
    std::fs::remove_file(bad).unwrap();
}

#[test]
fn gpu_relight_matches_the_cpu() {
    let Some(gpu) = common::gpu_or_skip("viewer GPU") else {
        return;
    };
    let mut e = engine();
    e.attach_gpu(gpu);
    let mut s = sun_state(&mut e);
    for method in [Method::Wavelet, Method::Sh, Method::Full] {
        s.relight.method = method;
        s.display.gpu = false;
        let cpu = e.render(&s).unwrap().panes[0].linear.clone();
        s.display.gpu = true;
        let gpu = e.render(&s).unwrap().panes[0].linear.clone();
        let d = wavelet_prt::output::metrics::relative_l2(&gpu.image, &cpu.image, None).unwrap();
        assert!(
            d < common::GPU_MATCH,
            "{method}: GPU differs from CPU by {d}"
        );
        assert!((gpu.rel_l2 - cpu.rel_l2).abs() < common::GPU_MATCH);
    }
}

/// What the window's GPU display path shows of `request` under `s` (the light of the last
/// render), read back as RGB8.
fn shown_on_gpu(
    e: &mut Engine,
    r: &wavelet_prt::app::viewer::Rendered,
    request: &wavelet_prt::relight::RelightRequest,
    s: &ViewState,
) -> Vec<u8> {
    let g = e.gpu().unwrap();
    let mut view =
        wavelet_prt::app::viewer::GpuView::new(&g.device, r.width as u32, r.height as u32);
    e.relight_to_view(request, &mut view, s).unwrap();
    let g = e.gpu().unwrap();
    view.read_rgb8(&g.device, &g.queue).unwrap()
}

#[test]
fn gpu_texture_path_shows_what_the_cpu_path_shows() {
    let Some(gpu) = common::gpu_or_skip("viewer GPU") else {
        return;
    };
    let mut e = engine();
    e.attach_gpu(gpu);
    let mut s = sun_state(&mut e);
    s.display.exposure = 0.5;
    for (method, compare) in [
        (Method::Wavelet, false),
        (Method::Sh, false),
        (Method::Full, true),
    ] {
        s.relight.method = method;
        s.relight.compare = compare;
        let r = e.render(&s).unwrap();
        for pane in &r.panes {
            let shown = shown_on_gpu(&mut e, &r, &pane.linear.request, &s);
            assert_eq!(shown.len(), pane.rgb.len());
            let worst = shown
                .iter()
                .zip(&pane.rgb)
                .map(|(a, b)| a.abs_diff(*b))
                .max()
                .unwrap();
            assert!(
                worst <= GPU_DISPLAY_LEVELS,
                "{method}: GPU display differs from the CPU image by {worst}"
            );
        }
    }
}

#[test]
fn error_map_is_black_at_every_term_and_lit_with_few() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.display.error_map = true;
    s.relight.method = Method::Wavelet;
    s.relight.terms = 6 * common::VIEWER_N * common::VIEWER_N;
    let r = e.render(&s).unwrap();
    assert_eq!(r.panes.len(), 2, "an image and its error map");
    assert!(
        r.panes[1].rgb.iter().all(|&v| v == 0),
        "every term: no error"
    );
    s.relight.terms = 2;
    let r = e.render(&s).unwrap();
    assert!(
        r.panes[1].rgb.iter().any(|&v| v > 0),
        "two terms: some error shows"
    );
    // Side by side with the comparison: two images, two maps.
    s.relight.compare = true;
    assert_eq!(e.render(&s).unwrap().panes.len(), 4);
}

#[test]
fn save_writes_the_png_and_the_linear_exr() {
    let mut e = engine();
    let s = sun_state(&mut e);
    let dir = std::env::temp_dir().join(format!("viewer-save-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stem = dir.join("view");
    wavelet_prt::app::viewer::save_view(&mut e, &s, &stem).unwrap();
    let png = image::open(stem.with_extension("png")).unwrap();
    let exr = wavelet_prt::output::film::Image::load_exr(&stem.with_extension("exr")).unwrap();
    // The PNG is the image under its caption strip (as tall as the caption, wrapped to fit
    // the image's width, needs).
    let shown = e.render(&s).unwrap();
    let (cw, ch, _) = shown.captioned(4);
    assert_eq!((cw, ch), (png.width() as usize, png.height() as usize));
    assert_eq!(cw, exr.width);
    assert!(ch >= exr.height + wavelet_prt::output::text::CAPTION_HEIGHT);
    assert_eq!(exr.pixels, shown.panes[0].linear.image.pixels);
}

#[test]
fn split_composite_takes_sh_left_of_the_cut_and_wavelet_right() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.relight.compare = true;
    s.relight.terms = 4;
    s.display.layout = wavelet_prt::app::viewer::Layout::Split;
    s.display.split = 0.25;
    let r = e.render(&s).unwrap();
    assert_eq!(r.panes.len(), 2);
    let (w, h, rgb) = r.composite(4);
    assert_eq!((w, h), (r.width, r.height), "one image, not two");
    let cut = (0.25 * w as f32).round() as usize;
    let (sh, wav) = (&r.panes[0].rgb, &r.panes[1].rgb);
    assert_ne!(sh, wav, "4 terms: SH and wavelet differ");
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) * 3;
            let want: &[u8] = match x.cmp(&cut) {
                std::cmp::Ordering::Less => &sh[i..i + 3],
                std::cmp::Ordering::Equal => &[255; 3],
                std::cmp::Ordering::Greater => &wav[i..i + 3],
            };
            assert_eq!(&rgb[i..i + 3], want, "pixel ({x}, {y})");
        }
    }
    // Side by side, the same panes make a double-width image.
    s.display.layout = wavelet_prt::app::viewer::Layout::SideBySide;
    assert_eq!(e.render(&s).unwrap().composite(4).0, 2 * r.width + 4);
}

#[test]
fn tone_curve_and_sun_size_change_what_they_should() {
    use wavelet_prt::output::film::ToneCurve;
    let mut e = engine();
    let mut s = sun_state(&mut e);
    s.display.exposure = 2.0;
    let clip = e.render(&s).unwrap();
    s.display.tone = ToneCurve::Reinhard;
    let reinhard = e.render(&s).unwrap();
    // Only the display changes: the same linear image and error, darker highlights.
    assert_eq!(clip.panes[0].linear.image, reinhard.panes[0].linear.image);
    let sum = |r: &wavelet_prt::app::viewer::Rendered| {
        r.panes[0].rgb.iter().map(|&v| v as u64).sum::<u64>()
    };
    assert!(sum(&reinhard) < sum(&clip));
    // A larger sun of the same irradiance softens shadows: the image changes but keeps its
    // overall brightness within a few percent.
    s.display.tone = ToneCurve::Clip;
    let mean = |r: &wavelet_prt::app::viewer::Rendered| {
        let p = &r.panes[0].linear.image.pixels;
        p.iter().map(|c| (c[0] + c[1] + c[2]) as f64).sum::<f64>() / p.len() as f64
    };
    s.relight.method = Method::Full;
    let small = e.render(&s).unwrap();
    s.light.sun.radius = 8.0;
    let big = e.render(&s).unwrap();
    assert_ne!(small.panes[0].linear.image, big.panes[0].linear.image);
    let (a, b) = (mean(&small), mean(&big));
    assert!((a - b).abs() < SUN_SIZE_MEAN_CHANGE * a, "mean {a} vs {b}");
}

#[test]
fn loading_reports_progress_up_to_the_file_size() {
    let path = common::viewer_transport_path();
    let size = std::fs::metadata(&path).unwrap().len();
    let seen = std::sync::Mutex::new(Vec::new());
    let engine = Engine::open_with_progress(&path, Vec::new(), &|read, total| {
        seen.lock().unwrap().push((read, total))
    })
    .unwrap();
    let seen = seen.into_inner().unwrap();
    assert!(!seen.is_empty());
    assert!(seen.windows(2).all(|w| w[0].0 < w[1].0), "{seen:?}");
    assert_eq!(*seen.last().unwrap(), (size, size));
    assert!(engine.transport.coeff_count() > 0);
}

#[test]
fn a_drag_gives_the_light_that_a_fresh_prepare_gives() {
    // The engine keeps a map's unturned SH light for the next turn of the same map; a turn, a
    // switch to the sun and back must each give what preparing afresh gives.
    let mut e = engine();
    assert!(e.envs.len() > 1, "the test needs a bundled map");
    let mut s = sun_state(&mut e);
    for (env, yaw, pitch) in [
        (1, 0.0, 0.0),
        (1, 33.5, 0.0),
        (1, 33.5, -20.0),
        (0, 10.0, 5.0),
        (1, 120.0, 45.0),
        (0, 0.0, 0.0),
        (0, -40.0, 30.0),
    ] {
        s.light.env = env;
        s.light.rotation = EnvRotation::new(yaw, pitch);
        e.render(&s).unwrap();
        let shown = e.current_light().unwrap();
        let fresh = e.ctx.prepare(&shown.map, s.light.rotation).unwrap();
        assert_eq!(shown.light.sh, fresh.sh, "{env}: {yaw}, {pitch}");
        assert_eq!(shown.light.wavelet.coeffs, fresh.wavelet.coeffs);
    }
}

#[test]
fn pixels_that_miss_the_geometry_show_the_environment_turned_with_it() {
    let mut e = engine();
    let mut s = sun_state(&mut e);
    let t = e.transport.clone();
    let open: Vec<usize> = (0..t.coverage.len())
        .filter(|&i| t.coverage[i] == 0.0)
        .collect();
    assert!(
        !open.is_empty(),
        "the test view must see past the geometry somewhere"
    );
    let r = e.render(&s).unwrap();
    let behind = e.current_light().unwrap().behind;
    let pane = &r.panes[0];
    for &i in &open {
        // Shown = relit (black there) + the environment behind, and never black under a sky.
        assert_eq!(pane.linear.image.pixels[i], behind.pixels[i]);
        assert!(behind.pixels[i].iter().sum::<f32>() > 0.0, "pixel {i}");
    }
    // Turning the light turns what is seen behind the scene. The view sees past the floor into
    // the ground half of the sky, which a yaw leaves alone: turn it upside down.
    s.light.rotation.pitch_deg += 180.0;
    e.render(&s).unwrap();
    let turned = e.current_light().unwrap().behind;
    assert!(open.iter().any(|&i| turned.pixels[i] != behind.pixels[i]));
}

#[test]
fn the_first_view_is_a_low_sun_with_hard_shadows() {
    let (entries, light) = env_entries(&[]);
    match entries.iter().position(|e| e.name == "blender_sunrise") {
        Some(i) => assert_eq!(light.env, i),
        None => {
            assert!(matches!(entries[light.env].source, EnvSource::Sun));
            assert!(light.sun.elevation <= 20.0, "{light:?}");
        }
    }
    // A map given on the command line still comes first, placed and sized as given.
    let (entries, light) = env_entries(&["sun:40,10,3".to_string()]);
    assert!(matches!(entries[light.env].source, EnvSource::Sun));
    assert_eq!(
        (light.sun.elevation, light.sun.azimuth, light.sun.radius),
        (40.0, 10.0, 3.0)
    );
}

#[test]
fn without_a_display_the_window_says_what_to_do_instead() {
    let t = common::viewer_transport_path();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_prt"))
        .args(["view", t.to_str().unwrap()])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(text.contains("no display to open a window on"), "{text}");
    assert!(text.contains("--screenshot OUT.png"), "{text}");
}

/// An engine on the per-vertex test bake under the bundled sunrise.
fn per_vertex_engine() -> (Engine, ViewState) {
    let envs = vec![EnvEntry {
        name: "sunrise".into(),
        source: EnvSource::File(common::assets().join("envmaps/blender_sunrise.exr")),
    }];
    let mut e = Engine::open(&common::per_vertex_transport_path(), envs).unwrap();
    let mut s = e.initial_state(sun_at(25.0, 60.0));
    s.relight.method = Method::Wavelet;
    s.relight.terms = 40;
    (e, s)
}

#[test]
fn a_per_vertex_bake_is_drawn_from_the_orbit_camera_over_the_environment() {
    use wavelet_prt::draw::background::environment_behind_camera;
    use wavelet_prt::draw::raster::{DrawOptions, rasterize_with};
    use wavelet_prt::draw::vertex::{Orbit, bake_camera, vertex_colours};
    use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
    use wavelet_prt::relight::{LightContext, RelightRequest, relight};
    let (mut e, mut s) = per_vertex_engine();
    let t = e.transport.clone();
    let base = bake_camera(&t).unwrap();
    let env = EnvMap::load(&common::assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let ctx = LightContext::new(&t).unwrap();
    let light = ctx.prepare(&env, EnvRotation::yaw(30.0)).unwrap();
    s.light.rotation.yaw_deg = 30.0;
    let request = RelightRequest::Wavelet {
        k: s.relight.terms,
        weighting: s.relight.weighting,
    };
    let (relit, _) = relight(&t, &ctx, &light, &request).unwrap();
    let colours = vertex_colours(&t, &relit).unwrap();
    let mesh = t.mesh().unwrap();
    let mut errors = Vec::new();
    let mut images = Vec::new();
    for orbit in [
        Orbit::default(),
        Orbit {
            azimuth_deg: 70.0,
            elevation_deg: 25.0,
            distance: 0.8,
        },
    ] {
        s.orbit = orbit;
        let r = e.render(&s).unwrap();
        let camera = orbit.camera(&base);
        assert_eq!(
            (r.width, r.height),
            (camera.width as usize, camera.height as usize)
        );
        // Drawn with the viewer's samples a pixel: covered pixels are the drawn vertex colours,
        // open pixels the environment along the camera's ray, turned with the light, and pixels
        // on a silhouette the drawn samples' mean plus the open ones' share of the environment.
        let options = DrawOptions::samples(s.draw_samples());
        let drawn =
            rasterize_with(&camera, &mesh.positions, &mesh.triangles, colours, options).unwrap();
        let open = vec![0.0; drawn.coverage.len()];
        let sky = environment_behind_camera(&camera, &open, &env, EnvRotation::yaw(30.0)).unwrap();
        let shown = &r.panes[0].linear.image;
        let (mut covered, mut uncovered) = (0, 0);
        for (i, p) in shown.pixels.iter().enumerate() {
            let c = drawn.coverage[i];
            covered += (c == 1.0) as usize;
            uncovered += (c == 0.0) as usize;
            let want: [f32; 3] =
                std::array::from_fn(|k| drawn.image.pixels[i][k] + (1.0 - c) * sky.pixels[i][k]);
            for k in 0..3 {
                assert!(
                    (p[k] - want[k]).abs()
                        <= VERTEX_PANE_ROUNDING * want[k].abs().max(VERTEX_PANE_SCALE_FLOOR),
                    "{orbit:?} pixel {i}: {p:?} against {want:?}"
                );
            }
        }
        assert!(
            covered > 100 && uncovered > 100,
            "{covered} covered, {uncovered} open"
        );
        errors.push(r.panes[0].linear.rel_l2);
        images.push(shown.clone());
    }
    assert_ne!(images[0], images[1], "the orbit moves the image");
    // The numbers are the relight's, over the vertices: the camera does not change them.
    assert_eq!(errors[0], errors[1]);
    assert!(
        errors[0] > 0.0 && errors[0] < FORTY_TERMS_ERROR,
        "{}",
        errors[0]
    );
}

#[test]
fn a_per_vertex_error_map_is_black_with_every_term() {
    let (mut e, mut s) = per_vertex_engine();
    s.orbit.azimuth_deg = -40.0;
    s.display.error_map = true;
    s.relight.method = Method::Full;
    let r = e.render(&s).unwrap();
    assert_eq!(r.panes.len(), 2);
    assert!(r.panes[1].rgb.iter().all(|&v| v == 0), "full against full");
    s.relight.method = Method::Wavelet;
    s.relight.terms = 4;
    let r = e.render(&s).unwrap();
    assert!(
        r.panes[1].rgb.iter().any(|&v| v > 0),
        "4 terms leave an error"
    );
}

/// Pixels of two RGB8 images more than one level apart in some channel: of a per-vertex draw,
/// those whose centre falls on a triangle edge may go to either side.
fn pixels_off(a: &[u8], b: &[u8]) -> usize {
    a.chunks(3)
        .zip(b.chunks(3))
        .filter(|(a, b)| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 1))
        .count()
}

#[test]
fn the_gpu_view_of_a_per_vertex_bake_shows_what_the_cpu_path_shows() {
    let Some(gpu) = common::gpu_or_skip("per-vertex GPU view") else {
        return;
    };
    let (mut e, mut s) = per_vertex_engine();
    e.attach_gpu(gpu);
    // As the window shows the GPU's images: the CPU path draws as many samples as they do.
    s.display.gpu = true;
    s.orbit.azimuth_deg = 50.0;
    s.orbit.elevation_deg = 15.0;
    for (method, compare) in [(Method::Wavelet, false), (Method::Sh, true)] {
        s.relight.method = method;
        s.relight.compare = compare;
        let r = e.render(&s).unwrap();
        for pane in &r.panes {
            let shown = shown_on_gpu(&mut e, &r, &pane.linear.request, &s);
            assert_eq!(shown.len(), pane.rgb.len());
            let off = pixels_off(&shown, &pane.rgb);
            assert!(
                off * 200 <= shown.len() / 3,
                "{method}: {off} of {} pixels differ",
                shown.len() / 3
            );
        }
    }
}

/// The GPU display of a glossy per-vertex bake with visibility: the lobe drawn per pixel by
/// the raster's shader shows what the CPU draws, from two cameras.
#[test]
fn the_gpu_view_of_a_glossy_bake_draws_its_lobe_as_the_cpu_path_does() {
    use wavelet_prt::bake::{BakeSettings, bake};
    use wavelet_prt::store::transport::BakeDomain;
    let Some(gpu) = common::gpu_or_skip("glossy GPU view") else {
        return;
    };
    let text = std::fs::read_to_string(common::assets().join("scenes/glossy_sphere.toml"))
        .unwrap()
        .replace("width = 256\nheight = 256", "width = 64\nheight = 64");
    let scene = common::scene_from(&text, "viewer-glossy");
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 2,
        domain: BakeDomain::Vertices { edge_length: 0.3 },
        visibility: true,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let path = common::temp_dir("viewer-glossy-bake").join("glossy.prt");
    t.save(&path).unwrap();
    let envs = vec![EnvEntry {
        name: "sunrise".into(),
        source: EnvSource::File(common::assets().join("envmaps/blender_sunrise.exr")),
    }];
    let mut e = Engine::open(&path, envs).unwrap();
    let mut s = e.initial_state(sun_at(25.0, 60.0));
    e.attach_gpu(gpu);
    s.display.gpu = true;
    s.relight.method = Method::Wavelet;
    s.relight.terms = 40;
    for azimuth in [20.0, 80.0] {
        s.orbit.azimuth_deg = azimuth;
        let r = e.render(&s).unwrap();
        let pane = &r.panes[0];
        let shown = shown_on_gpu(&mut e, &r, &pane.linear.request, &s);
        assert_eq!(shown.len(), pane.rgb.len());
        let off = pixels_off(&shown, &pane.rgb);
        assert!(
            off * 200 <= shown.len() / 3,
            "turned {azimuth}°: {off} of {} pixels differ",
            shown.len() / 3
        );
    }
}

#[test]
fn orbit_on_the_command_line_turns_a_per_vertex_bake_and_is_refused_for_a_fixed_view() {
    let dir = common::temp_dir("viewer-orbit-cli");
    let file = common::per_vertex_transport_path();
    let out = dir.join("orbit.png");
    let env = common::assets().join("envmaps/blender_sunrise.exr");
    let (code, text) = common::prt(&[
        "view",
        file.to_str().unwrap(),
        "--env",
        env.to_str().unwrap(),
        "--screenshot",
        out.to_str().unwrap(),
        "--orbit",
        "-60,20,1.2",
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(out.exists());
    let fixed = common::viewer_transport_path();
    let (code, text) = common::prt(&[
        "view",
        fixed.to_str().unwrap(),
        "--screenshot",
        dir.join("fixed.png").to_str().unwrap(),
        "--orbit",
        "30,0",
    ]);
    assert_ne!(code, 0);
    assert!(text.contains("--per-vertex"), "{text}");
    let (code, text) = common::prt(&["view", file.to_str().unwrap(), "--orbit", "30,0"]);
    assert_ne!(code, 0);
    assert!(text.contains("--screenshot"), "{text}");
}

#[test]
fn sh_transfer_on_the_command_line_needs_a_bake_with_visibility_and_a_screenshot() {
    let dir = common::temp_dir("viewer-sh-transfer-cli");
    // A matte scene's per-vertex bake keeps no visibility.
    let file = common::per_vertex_transport_path();
    let out = dir.join("transfer.png");
    let (code, text) = common::prt(&[
        "view",
        file.to_str().unwrap(),
        "--screenshot",
        out.to_str().unwrap(),
        "--sh-transfer",
        "6",
    ]);
    assert_ne!(code, 0);
    assert!(
        text.contains("--sh-transfer") && text.contains("visibility"),
        "{text}"
    );
    assert!(!out.exists());
    let (code, text) = common::prt(&["view", file.to_str().unwrap(), "--sh-transfer", "6"]);
    assert_ne!(code, 0);
    assert!(text.contains("--screenshot"), "{text}");
}

/// The pixels' difference between two renders' first panes (linear, before tone mapping).
fn difference(
    a: &wavelet_prt::app::viewer::Rendered,
    b: &wavelet_prt::app::viewer::Rendered,
) -> Vec<[f32; 3]> {
    a.panes[0]
        .linear
        .image
        .pixels
        .iter()
        .zip(&b.panes[0].linear.image.pixels)
        .map(|(p, q)| std::array::from_fn(|k| p[k] - q[k]))
        .collect()
}

#[test]
fn a_local_light_adds_exactly_its_column_and_the_errors_stay_the_environments() {
    let path = common::lit_viewer_transport_path();
    let t = wavelet_prt::store::transport::Transport::load(&path).unwrap();
    let mut e = Engine::open(&path, vec![]).unwrap();
    let mut s = sun_state(&mut e);
    assert_eq!(s.lights.lights.len(), 2);
    let on = e.render(&s).unwrap();
    s.lights.lights[0].on = false;
    let off = e.render(&s).unwrap();
    // The environment's error does not see the lights.
    assert_eq!(on.panes[0].linear.rel_l2, off.panes[0].linear.rel_l2);
    let light = &t.meta.lights[0];
    let rgb = light.color * light.intensity;
    for (p, d) in difference(&on, &off).iter().enumerate() {
        for k in 0..3 {
            let want = rgb[k] * t.attached.lights.value(0, k, p);
            assert!(
                (d[k] - want).abs() <= 1e-5 * (1.0 + want),
                "pixel {p}: {} {want}",
                d[k]
            );
        }
    }
    // One stop up doubles it; solo shows the spot alone, at its second position, over black.
    s.lights.lights[0].on = true;
    s.lights.lights[0].stops = 1.0;
    let brighter = e.render(&s).unwrap();
    for (p, d) in difference(&brighter, &on).iter().enumerate() {
        let want = rgb[0] * t.attached.lights.value(0, 0, p);
        assert!((d[0] - want).abs() <= 1e-5 * (1.0 + want), "pixel {p}");
    }
    s.lights.solo = Some(1);
    s.lights.lights[1].at = [1.0, 0.0, 0.0];
    let solo = e.render(&s).unwrap();
    let spot = &t.meta.lights[1];
    let rgb = spot.color * spot.intensity;
    for (p, px) in solo.panes[0].linear.image.pixels.iter().enumerate() {
        for k in 0..3 {
            let want = rgb[k] * t.attached.lights.value(2, k, p);
            assert!((px[k] - want).abs() <= 1e-5 * (1.0 + want), "pixel {p}");
        }
    }
    // The window's GPU display path draws the same.
    if let Some(gpu) = common::gpu_or_skip("viewer lights GPU") {
        e.attach_gpu(gpu);
        for state in [s.clone(), {
            let mut o = s.clone();
            o.lights.solo = None;
            o
        }] {
            let r = e.render(&state).unwrap();
            let shown = shown_on_gpu(&mut e, &r, &r.panes[0].linear.request, &state);
            let worst = shown
                .iter()
                .zip(&r.panes[0].rgb)
                .map(|(a, b)| a.abs_diff(*b))
                .max()
                .unwrap();
            assert!(
                worst <= GPU_DISPLAY_LEVELS,
                "GPU display differs by {worst}"
            );
        }
    }
}
