//! Zoom and pan of the images in the window: which part of an image is shown, kept inside it.

use eframe::egui;

/// Zoom and pan of the images: `zoom` 1 fits the image, `center` is the texture coordinate
/// shown at the middle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewport {
    /// Magnification: 1 fits the image, up to [`Viewport::MAX_ZOOM`].
    pub zoom: f32,
    /// The texture coordinate at the middle of the view.
    pub center: egui::Pos2,
}

impl Default for Viewport {
    fn default() -> Self {
        Viewport {
            zoom: 1.0,
            center: egui::pos2(0.5, 0.5),
        }
    }
}

impl Viewport {
    /// The highest magnification.
    pub const MAX_ZOOM: f32 = 64.0;

    /// The part of the texture shown, in texture coordinates, with the centre kept inside.
    pub fn uv(&self) -> egui::Rect {
        let half = 0.5 / self.zoom.clamp(1.0, Self::MAX_ZOOM);
        let c = egui::pos2(
            self.center.x.clamp(half, 1.0 - half),
            self.center.y.clamp(half, 1.0 - half),
        );
        egui::Rect::from_center_size(c, egui::vec2(2.0 * half, 2.0 * half))
    }

    /// Zooms by `factor` keeping the texture point under `at` (a fraction of the shown rect)
    /// where it is.
    pub fn zoom_at(&mut self, factor: f32, at: egui::Vec2) {
        let uv = self.uv();
        let point = uv.min + at * uv.width();
        self.zoom = (self.zoom * factor).clamp(1.0, Self::MAX_ZOOM);
        let size = 1.0 / self.zoom;
        self.center = point - at * size + egui::vec2(0.5 * size, 0.5 * size);
        self.center = self.uv().center();
    }

    /// Moves the view by a drag of `delta` screen points over a rect `size` points wide.
    pub fn pan(&mut self, delta: egui::Vec2, size: egui::Vec2) {
        let uv = self.uv();
        self.center = uv.center() - delta / size * uv.width();
        self.center = self.uv().center();
    }
}
