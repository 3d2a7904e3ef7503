//! The orbit camera of both windows (a per-vertex bake, a volume): drag the image to turn about
//! the target, scroll to move in and out, sliders and a reset to the file's own camera. The
//! camera is an [`Orbit`] relative to the file's camera, so both windows turn, stop and zoom
//! alike.

use eframe::egui;

use crate::draw::vertex::Orbit;
use crate::scene::Camera;

/// Degrees the camera turns for each point the pointer is dragged.
pub const DRAG_DEGREES_PER_POINT: f32 = 0.4;

/// How fast scrolling moves the eye: a scroll of `p` points scales the distance by
/// `exp(-p · DOLLY_PER_POINT)`.
pub const DOLLY_PER_POINT: f32 = 0.002;

/// Turns the orbit of `base` by a drag of `delta` points: dragging right turns the scene to the
/// right, dragging down raises the eye; the elevation stops where the eye stops.
pub fn drag(orbit: &mut Orbit, base: &Camera, delta: egui::Vec2) {
    orbit.azimuth_deg -= delta.x * DRAG_DEGREES_PER_POINT;
    let range = Orbit::elevation_range(base);
    orbit.elevation_deg = (orbit.elevation_deg + delta.y * DRAG_DEGREES_PER_POINT)
        .clamp(*range.start(), *range.end());
    orbit.clamp();
}

/// Moves the eye in (scrolling up) or out by a scroll of `points`.
pub fn dolly(orbit: &mut Orbit, points: f32) {
    orbit.distance *= (-points * DOLLY_PER_POINT).exp();
    orbit.clamp();
}

/// The camera section of a panel for a file whose camera is `base`: azimuth, elevation and
/// distance from it, and a reset to it.
pub fn camera_controls(ui: &mut egui::Ui, orbit: &mut Orbit, base: &Camera) {
    ui.heading("Camera");
    ui.label("drag the image to orbit, scroll to move in and out, double-click to reset");
    ui.add(egui::Slider::new(&mut orbit.azimuth_deg, -180.0..=180.0).text("orbit azimuth°"));
    ui.add(
        egui::Slider::new(&mut orbit.elevation_deg, Orbit::elevation_range(base))
            .text("orbit elevation°"),
    );
    ui.add(
        egui::Slider::new(&mut orbit.distance, Orbit::DISTANCE)
            .logarithmic(true)
            .text("distance (x baked)"),
    );
    if ui.button("File's camera").clicked() {
        *orbit = Orbit::default();
    }
}

/// What the pointer does to the orbit over an image drawn with `response`: a drag turns it, a
/// double-click goes back to the file's camera, a scroll of `scroll` points moves the eye.
pub fn interact(orbit: &mut Orbit, base: &Camera, response: &egui::Response, scroll: Option<f32>) {
    if response.dragged() {
        drag(orbit, base, response.drag_delta());
    }
    if response.double_clicked() {
        *orbit = Orbit::default();
    }
    if let Some(points) = scroll {
        dolly(orbit, points);
    }
}
