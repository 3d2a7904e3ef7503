//! The viewer's images: the relit panes side by side (or split), zoomed and panned, with the
//! heat maps' colour bar beside them.

use super::*;

impl ViewerApp {
    pub(super) fn images(&mut self, ui: &mut egui::Ui) {
        if let Some(e) = &self.load_error {
            ui.centered_and_justified(|ui| {
                ui.colored_label(
                    egui::Color32::RED,
                    format!("Could not open the transport file:\n{e}"),
                );
            });
            return;
        }
        let Some(loaded) = &self.loaded else {
            ui.centered_and_justified(|ui| ui.spinner());
            return;
        };
        let shown = self.shown();
        if shown.is_empty() {
            ui.spinner();
            return;
        }
        // Groups drawn as one image: pairs under the split layout, else single panes.
        let per = if self.state.split_pairs() { 2 } else { 1 };
        let groups: Vec<&[(egui::TextureId, String)]> = shown.chunks(per).collect();
        let n = groups.len() as f32;
        // The heat maps' colour bar, right of the images, while the CPU's images are shown.
        let bar = match &self.rendered {
            Some(r) if !self.showing_gpu() => r.heat.map(|scale| scale.ticks(3)),
            _ => None,
        };
        let ramp = bar
            .as_ref()
            .map(|_| heat_ramp(&mut self.heat_ramp, ui.ctx()));
        let avail = ui.available_size();
        let (w, h) = (loaded.size.0 as f32, loaded.size.1 as f32);
        let base = loaded.camera.clone();
        // The camera the images are seen through, for drawing the quad lights over them.
        let view_camera = (!loaded.transport.meta.lights.is_empty())
            .then(|| {
                loaded.camera(&self.state).or_else(|| {
                    let c = &loaded.transport.meta.camera;
                    Some(crate::scene::Camera {
                        eye: glam::Vec3::from(c.eye),
                        target: glam::Vec3::from(c.target),
                        up: glam::Vec3::from(c.up),
                        fov_y_deg: c.fov_y_deg,
                        width: loaded.transport.meta.width,
                        height: loaded.transport.meta.height,
                    })
                })
            })
            .flatten();
        let (gap, title_h) = (8.0, 20.0);
        let bar_w = if bar.is_some() { BAR_POINTS + gap } else { 0.0 };
        let scale = (((avail.x - bar_w - gap * (n - 1.0)) / n) / w)
            .min((avail.y - title_h) / h)
            .max(0.01);
        let size = egui::vec2(w * scale, h * scale);
        // A per-vertex bake is drawn at the pane's size in pixels.
        if base.is_some() {
            let ppp = ui.ctx().pixels_per_point();
            let side = |points: f32| ((points * ppp).round() as u32).clamp(1, MAX_DRAW_SIDE);
            self.state.draw_size = Some((side(size.x), side(size.y)));
        }
        let uv = self.viewport.uv();
        let split = self.state.display.split;
        let mut viewport = self.viewport;
        let mut orbit = self.state.orbit;
        ui.horizontal_top(|ui| {
            for group in &groups {
                ui.vertical(|ui| {
                    let title = match group {
                        [(_, a), (_, b)] => format!("{a}  |  {b}"),
                        _ => group[0].1.clone(),
                    };
                    ui.label(title);
                    let (rect, response) = ui.allocate_exact_size(size, egui::Sense::drag());
                    let painter = ui.painter_at(rect);
                    let white = egui::Color32::WHITE;
                    match group {
                        [(a, _), (b, _)] => {
                            let x = rect.min.x + split * rect.width();
                            let u = uv.min.x + split * uv.width();
                            let (left, right) = (
                                egui::Rect::from_min_max(rect.min, egui::pos2(x, rect.max.y)),
                                egui::Rect::from_min_max(egui::pos2(x, rect.min.y), rect.max),
                            );
                            let uv_left = egui::Rect::from_min_max(uv.min, egui::pos2(u, uv.max.y));
                            let uv_right =
                                egui::Rect::from_min_max(egui::pos2(u, uv.min.y), uv.max);
                            painter.image(*a, left, uv_left, white);
                            painter.image(*b, right, uv_right, white);
                            painter.vline(x, rect.y_range(), egui::Stroke::new(1.0, white));
                        }
                        _ => {
                            painter.image(group[0].0, rect, uv, white);
                        }
                    }
                    if let Some(camera) = &view_camera {
                        super::super::lights::outline_quads(
                            &painter,
                            rect,
                            uv,
                            camera,
                            &loaded.transport.meta.lights,
                            &self.state.lights,
                        );
                    }
                    // A per-vertex bake's camera orbits; a fixed view zooms and pans.
                    let scroll = response
                        .hover_pos()
                        .map(|pos| (pos, ui.input(|i| i.smooth_scroll_delta.y)))
                        .filter(|(_, s)| *s != 0.0);
                    match &base {
                        Some(base) => {
                            camera::interact(&mut orbit, base, &response, scroll.map(|s| s.1));
                        }
                        None => {
                            if response.dragged() {
                                viewport.pan(response.drag_delta(), rect.size());
                            }
                            if response.double_clicked() {
                                viewport = Viewport::default();
                            }
                            if let Some((pos, scroll)) = scroll {
                                let at = (pos - rect.min) / rect.size();
                                viewport.zoom_at((scroll * 0.004).exp(), at);
                            }
                        }
                    }
                });
                ui.add_space(gap);
            }
            if let (Some(ticks), Some(ramp)) = (&bar, ramp) {
                heat_bar(ui, ramp, ticks, size.y);
            }
        });
        self.viewport = viewport;
        self.state.orbit = orbit;
    }
}

/// The heat ramp as a texture one texel wide, full heat in its top row (made once into `slot`).
fn heat_ramp(slot: &mut Option<egui::TextureHandle>, ctx: &egui::Context) -> egui::TextureId {
    slot.get_or_insert_with(|| {
        let rgb: Vec<u8> = (0..256)
            .rev()
            .flat_map(|i| heat_color(i as f32 / 255.0))
            .collect();
        ctx.load_texture(
            "heat ramp",
            egui::ColorImage::from_rgb([1, 256], &rgb),
            egui::TextureOptions::LINEAR,
        )
    })
    .id()
}

/// The error heat maps' colour bar, `height` points tall under a title row as the images are:
/// the ramp, full heat at the top, and `ticks` (each its fraction of full heat and its label in
/// percent of `full`'s mean luminance).
fn heat_bar(ui: &mut egui::Ui, ramp: egui::TextureId, ticks: &[(f32, String)], height: f32) {
    ui.vertical(|ui| {
        ui.label("% of mean");
        let (rect, response) =
            ui.allocate_exact_size(egui::vec2(BAR_POINTS, height), egui::Sense::hover());
        response.on_hover_text(
            "the error against full, in percent of full's mean luminance; the scale saturates \
             at most 1% of the lit pixels",
        );
        let painter = ui.painter_at(rect);
        let white = egui::Color32::WHITE;
        let strip =
            egui::Rect::from_min_max(rect.min, egui::pos2(rect.min.x + RAMP_POINTS, rect.max.y));
        let whole = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        painter.image(ramp, strip, whole, white);
        for (at, label) in ticks {
            let y = rect.max.y - at * rect.height();
            painter.line_segment(
                [egui::pos2(strip.max.x, y), egui::pos2(strip.max.x + 4.0, y)],
                egui::Stroke::new(1.0, white),
            );
            let anchor = match *at {
                a if a >= 1.0 => egui::Align2::LEFT_TOP,
                a if a <= 0.0 => egui::Align2::LEFT_BOTTOM,
                _ => egui::Align2::LEFT_CENTER,
            };
            let at = egui::pos2(strip.max.x + 6.0, y);
            painter.text(at, anchor, label, egui::FontId::proportional(12.0), white);
        }
    });
}
