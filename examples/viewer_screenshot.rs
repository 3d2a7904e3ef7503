//! Renders the whole viewer window (panel and image) headless to a PNG, for documentation:
//! `cargo run --release --example viewer_screenshot -- FILE.prt OUT.png [ENV] [--gpu] [--terms K]`. It opens FILE
//! with the SH | wavelet split comparison under ENV (default a low sun), a per-vertex bake turned
//! 35° about its target and raised 10°, and draws the window on the first wgpu adapter (a
//! software one will do).

use std::time::Duration;

use eframe::egui;
use egui_kittest::Harness;
use wavelet_prt::app::viewer::{Layout, ViewerApp};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    // `--gpu`: relight with the GPU kernels and draw from them, as the window does on a machine
    // with a GPU (the panel then shows their timings); `--terms K`: K kept terms (default 64).
    let gpu = take_flag(&mut args, "--gpu");
    let terms = take_value(&mut args, "--terms").map(|k| {
        k.parse::<usize>().unwrap_or_else(|_| {
            eprintln!("--terms {k}: not a count");
            std::process::exit(2)
        })
    });
    let [file, out, rest @ ..] = &args[..] else {
        eprintln!("usage: viewer_screenshot FILE.prt OUT.png [ENV] [--gpu] [--terms K]");
        std::process::exit(2);
    };
    let env = rest
        .first()
        .cloned()
        .unwrap_or_else(|| "sun:25,70,2".into());
    let mut app = ViewerApp::new(std::path::Path::new(file), &[env]);
    let builder = Harness::builder().with_size(egui::vec2(1280.0, 800.0));
    let builder = if gpu {
        use egui_kittest::wgpu::{WgpuTestRenderer, create_render_state, default_wgpu_setup};
        let rs = create_render_state(
            default_wgpu_setup(),
            eframe::egui_wgpu::RendererOptions::PREDICTABLE,
        );
        app.attach_render_state(rs.clone());
        builder.renderer(WgpuTestRenderer::from_render_state(rs))
    } else {
        builder.wgpu()
    };
    let mut h = builder.build_ui_state(|ui, app: &mut ViewerApp| app.show(ui), app);
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
    s.relight.compare = true;
    s.display.layout = Layout::Split;
    s.display.split = 0.5;
    s.relight.terms = terms.unwrap_or(64);
    // Ignored by a per-pixel bake, whose view is fixed.
    s.orbit = wavelet_prt::draw::vertex::Orbit {
        azimuth_deg: 35.0,
        elevation_deg: 10.0,
        distance: 1.0,
    };
    settle(&mut h);
    h.render()
        .expect("headless render")
        .save(out)
        .expect("writing the PNG");
    if let Some(e) = &h.state().error {
        eprintln!("{e}");
        std::process::exit(1);
    }
    for t in h.state().gpu_timings() {
        println!("GPU pane: {t:?}");
    }
    println!("wrote {out}");
}

/// Removes `flag` from `args`; whether it was there.
fn take_flag(args: &mut Vec<String>, flag: &str) -> bool {
    let before = args.len();
    args.retain(|a| a != flag);
    args.len() != before
}

/// Removes `flag VALUE` from `args`; the value.
fn take_value(args: &mut Vec<String>, flag: &str) -> Option<String> {
    let i = args.iter().position(|a| a == flag)?;
    args.remove(i);
    (i < args.len()).then(|| args.remove(i))
}
