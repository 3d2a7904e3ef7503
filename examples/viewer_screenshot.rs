//! Renders the whole viewer window (panel and image) headless to a PNG, for documentation:
//! `cargo run --release --example viewer_screenshot -- FILE.prt OUT.png [ENV]`. It opens FILE
//! with the SH | wavelet split comparison under ENV (default a low sun), a per-vertex bake turned
//! 35° about its target and raised 10°, and draws the window on the first wgpu adapter (a
//! software one will do).

use std::time::Duration;

use eframe::egui;
use egui_kittest::Harness;
use wavelet_prt::app::viewer::{Layout, ViewerApp};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, out, rest @ ..] = &args[..] else {
        eprintln!("usage: viewer_screenshot FILE.prt OUT.png [ENV]");
        std::process::exit(2);
    };
    let env = rest
        .first()
        .cloned()
        .unwrap_or_else(|| "sun:25,70,2".into());
    let mut h = Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .wgpu()
        .build_ui_state(
            |ui, app: &mut ViewerApp| app.show(ui),
            ViewerApp::new(std::path::Path::new(file), &[env]),
        );
    let settle = |h: &mut Harness<'_, ViewerApp>| {
        for _ in 0..50 {
            assert!(h.state().wait_idle(Duration::from_secs(600)));
            h.step();
            if !h.state().busy() {
                break;
            }
        }
        h.run_ok();
    };
    settle(&mut h);
    if let Some(e) = &h.state().load_error {
        eprintln!("{e}");
        std::process::exit(1);
    }
    let s = &mut h.state_mut().state;
    s.compare = true;
    s.layout = Layout::Split;
    s.split = 0.5;
    s.terms = 64;
    // Ignored by a per-pixel bake, whose view is fixed.
    s.orbit = wavelet_prt::relight::vertex::Orbit {
        azimuth_deg: 35.0,
        elevation_deg: 10.0,
        distance: 1.0,
    };
    settle(&mut h);
    h.render()
        .expect("headless render")
        .save(out)
        .expect("writing the PNG");
    println!("wrote {out}");
}
