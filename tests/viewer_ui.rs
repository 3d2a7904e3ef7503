//! Drives the window headless with egui_kittest (wgpu renderer: lavapipe here).

mod common;

use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use wavelet_prt::relight::Method;
use wavelet_prt::viewer::ViewerApp;

fn harness(app: ViewerApp) -> Harness<'static, ViewerApp> {
    Harness::builder()
        .with_size(egui::vec2(1000.0, 700.0))
        .wgpu()
        .build_ui_state(|ui, app: &mut ViewerApp| app.show(ui), app)
}

#[test]
fn clicking_the_method_toggle_changes_the_state_and_the_image() {
    // The harness renders with wgpu: it needs an adapter (a software one will do).
    if common::gpu_or_skip("clicking_the_method_toggle_changes_the_state_and_the_image").is_none() {
        return;
    }
    let app = ViewerApp::new(&common::viewer_transport_path(), &["sun:30,45".to_string()]);
    let mut h = harness(app);
    h.run();
    assert_eq!(h.state().state.method, Method::Wavelet);
    h.get_by_label("SH").click();
    h.run();
    assert_eq!(h.state().state.method, Method::Sh);
    h.key_press(egui::Key::M);
    h.run();
    assert_eq!(h.state().state.method, Method::Full);
    let image = h.render().expect("headless wgpu render");
    assert!(image.width() > 0);
    if let Some(out) = std::env::var_os("VIEWER_UI_PNG") {
        image.save(out).unwrap();
    }
}

#[test]
fn a_bad_file_shows_a_message() {
    // The harness renders with wgpu: it needs an adapter (a software one will do).
    if common::gpu_or_skip("a_bad_file_shows_a_message").is_none() {
        return;
    }
    let bad = std::env::temp_dir().join(format!("viewer-ui-bad-{}.prt", std::process::id()));
    std::fs::write(&bad, b"junk").unwrap();
    let mut h = harness(ViewerApp::new(&bad, &[]));
    h.run();
    assert!(h.query_by_label_contains("Could not open").is_some());
    std::fs::remove_file(bad).unwrap();
}

#[test]
fn gpu_display_draws_what_the_cpu_path_draws() {
    // The harness renders with wgpu: it needs an adapter (a software one will do).
    if common::gpu_or_skip("gpu_display_draws_what_the_cpu_path_draws").is_none() {
        return;
    }
    use egui_kittest::wgpu::{WgpuTestRenderer, create_render_state, default_wgpu_setup};
    let rs = create_render_state(
        default_wgpu_setup(),
        eframe::egui_wgpu::RendererOptions::PREDICTABLE,
    );
    let mut app = ViewerApp::new(&common::viewer_transport_path(), &["sun:30,45".to_string()]);
    app.attach_render_state(rs.clone());
    let mut h = Harness::builder()
        .with_size(egui::vec2(1000.0, 700.0))
        .renderer(WgpuTestRenderer::from_render_state(rs))
        .build_ui_state(|ui, app: &mut ViewerApp| app.show(ui), app);
    h.run();
    // With a render state attached, the window draws from the GPU kernels by default.
    assert!(h.state().state.gpu);
    assert!(h.state().error.is_none(), "{:?}", h.state().error);
    h.query_by_label_contains("GPU pane 1")
        .expect("GPU timing shown");
    let gpu = h.render().expect("render");
    h.get_by_label("Relight on the GPU").click();
    h.run();
    assert!(!h.state().state.gpu);
    let cpu = h.render().expect("render");
    if let Some(out) = std::env::var_os("VIEWER_UI_GPU_PNG") {
        gpu.save(out).unwrap();
    }
    // Same picture; only the side panel (checkbox, timings) differs.
    let (w, hgt) = cpu.dimensions();
    let mut differ = 0usize;
    let mut total = 0usize;
    for y in 0..hgt {
        for x in 400..w {
            total += 1;
            let (a, b) = (cpu.get_pixel(x, y).0, gpu.get_pixel(x, y).0);
            if a.iter().zip(&b).any(|(p, q)| p.abs_diff(*q) > 2) {
                differ += 1;
            }
        }
    }
    assert!(
        differ * 1000 < total,
        "{differ} of {total} image-area pixels differ"
    );
}
