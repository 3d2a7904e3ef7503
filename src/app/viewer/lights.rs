//! The viewer's local lights: whether the environment shines, and each light's switch,
//! intensity (in stops from its scene file's), colour, place along its path and "solo"
//! ([`LightsState`]), the weights they give the baked columns, and their panel. Changing any of
//! it relights and nothing more: the prepared environment stays, and the lights are added to the
//! environment's image (exactly, whatever the method), which is what the errors shown measure.

use eframe::egui;
use glam::Vec3;

use crate::error::Result;
use crate::scene::light::Light;
use crate::scene::light_mix::{LightMix, LightSetting};

/// How one light is shown.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightControl {
    /// Whether it is on.
    pub on: bool,
    /// Its intensity, in stops from the scene file's (0: as baked with the file's intensity).
    pub stops: f32,
    /// Linear RGB colour.
    pub color: [f32; 3],
    /// Place along each axis of its baked positions, 0 to the axis's count − 1.
    pub at: [f32; 3],
}

/// The local lights of a view.
#[derive(Clone, Debug, PartialEq)]
pub struct LightsState {
    /// Whether the environment shines (off: the local lights alone).
    pub environment: bool,
    /// Each light's controls, in the file's order.
    pub lights: Vec<LightControl>,
    /// One light shown alone: the environment and the other lights off.
    pub solo: Option<usize>,
}

impl Default for LightsState {
    fn default() -> Self {
        LightsState {
            environment: true,
            lights: Vec::new(),
            solo: None,
        }
    }
}

/// Stops an intensity slider spans either way.
pub const STOPS: f32 = 10.0;

impl LightsState {
    /// Every light as its scene file says, the environment on.
    pub fn of(lights: &[Light]) -> LightsState {
        LightsState {
            environment: true,
            lights: lights
                .iter()
                .map(|l| LightControl {
                    on: true,
                    stops: 0.0,
                    color: l.color.to_array(),
                    at: [0.0; 3],
                })
                .collect(),
            solo: None,
        }
    }

    /// Whether the environment is part of the image.
    pub fn environment_shown(&self) -> bool {
        self.environment && self.solo.is_none()
    }

    /// Whether light `i` shines: the soloed one, or else those switched on.
    pub fn shows(&self, i: usize) -> bool {
        match self.solo {
            Some(s) => s == i,
            None => self.lights.get(i).is_some_and(|c| c.on),
        }
    }

    /// The relight settings of `lights` (solo applied).
    pub fn settings(&self, lights: &[Light]) -> Vec<LightSetting> {
        lights
            .iter()
            .zip(&self.lights)
            .enumerate()
            .map(|(i, (l, c))| LightSetting {
                on: self.shows(i),
                color: Vec3::from_array(c.color),
                intensity: l.intensity * c.stops.exp2(),
                at: c.at,
            })
            .collect()
    }

    /// The weights of the baked columns of `lights` this state gives.
    pub fn mix(&self, lights: &[Light]) -> Result<LightMix> {
        LightMix::new(lights, &self.settings(lights))
    }

    /// Brings the controls into range for `lights`: one per light (reset when they do not
    /// match), stops within ±`STOPS`, colours finite and >= 0, places on the path, solo on a
    /// light that exists.
    pub fn clamp(&mut self, lights: &[Light]) {
        if self.lights.len() != lights.len() {
            let environment = self.environment;
            *self = LightsState::of(lights);
            self.environment = environment;
        }
        for (c, l) in self.lights.iter_mut().zip(lights) {
            c.stops = if c.stops.is_finite() {
                c.stops.clamp(-STOPS, STOPS)
            } else {
                0.0
            };
            for v in &mut c.color {
                *v = if v.is_finite() { v.max(0.0) } else { 1.0 };
            }
            for (a, at) in c.at.iter_mut().enumerate() {
                let last = (l.grid[a] - 1) as f32;
                *at = if at.is_finite() {
                    at.clamp(0.0, last)
                } else {
                    0.0
                };
            }
        }
        if self.solo.is_some_and(|s| s >= lights.len()) {
            self.solo = None;
        }
    }
}

/// Draws the outline of every quad light over an image of `rect` showing the part `uv` of what
/// `camera` sees: each quad at its current place, in its colour, dimmed when it is off, with a
/// tick from its centre along the way it emits (it lights one side only).
pub fn outline_quads(
    painter: &egui::Painter,
    rect: egui::Rect,
    uv: egui::Rect,
    camera: &crate::scene::Camera,
    lights: &[Light],
    state: &LightsState,
) {
    let to_screen = |p: Vec3| {
        camera.project(p).map(|(x, y)| {
            let n = egui::vec2(x / camera.width as f32, y / camera.height as f32);
            rect.min + (n - uv.min.to_vec2()) / uv.size() * rect.size()
        })
    };
    for (i, (light, c)) in lights.iter().zip(&state.lights).enumerate() {
        let crate::scene::LightShape::Quad { corners } = light.shape else {
            continue;
        };
        let centre = light.position_at(c.at);
        let shown = state.shows(i);
        let top = c.color.iter().copied().fold(1e-6f32, f32::max);
        let rgb = c.color.map(|v| ((v / top) * 255.0) as u8);
        let colour = egui::Color32::from_rgb(rgb[0], rgb[1], rgb[2]).gamma_multiply(if shown {
            1.0
        } else {
            0.35
        });
        let stroke = egui::Stroke::new(1.5, colour);
        let points: Vec<Option<egui::Pos2>> =
            corners.iter().map(|&k| to_screen(centre + k)).collect();
        for e in 0..4 {
            if let (Some(a), Some(b)) = (points[e], points[(e + 1) % 4]) {
                painter.line_segment([a, b], stroke);
            }
        }
        let normal = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize_or_zero();
        let reach = 0.25 * (corners[2] - corners[0]).length();
        if let (Some(a), Some(b)) = (to_screen(centre), to_screen(centre + normal * reach)) {
            painter.line_segment([a, b], stroke);
        }
    }
}

/// Rows of the lights list shown before it scrolls.
const LIST_ROWS: f32 = 6.0;
/// Width of the lights' sliders, points: a light's switch, solo, colour and intensity share one
/// row of the panel.
const LIGHT_SLIDER_WIDTH: f32 = 64.0;

/// The Lights panel: the heading with the environment's switch, then one row per light (its
/// switch, solo, colour and intensity in stops) and, for a light that moves, a row per axis of
/// its path; past `LIST_ROWS` rows the list scrolls, so the rows below stay in the window.
pub fn lights_controls(ui: &mut egui::Ui, lights: &[Light], state: &mut LightsState) {
    ui.horizontal(|ui| {
        ui.heading("Lights").on_hover_text(
            "Every method relights the environment; the lights are added exactly in each, and \
             the errors shown are the environment's.",
        );
        ui.checkbox(&mut state.environment, "Environment");
    });
    let row = ui.spacing().interact_size.y + ui.spacing().item_spacing.y;
    egui::ScrollArea::vertical()
        .id_salt("lights")
        .max_height(LIST_ROWS * row)
        .show(ui, |ui| {
            ui.spacing_mut().slider_width = LIGHT_SLIDER_WIDTH;
            for (i, (light, c)) in lights.iter().zip(state.lights.iter_mut()).enumerate() {
                ui.horizontal_wrapped(|ui| {
                    ui.checkbox(&mut c.on, &light.name)
                        .on_hover_text(format!("a {} light", light.shape.kind()));
                    let solo = state.solo == Some(i);
                    if ui
                        .selectable_label(solo, "solo")
                        .on_hover_text("this light alone")
                        .clicked()
                    {
                        state.solo = if solo { None } else { Some(i) };
                    }
                    ui.color_edit_button_rgb(&mut c.color);
                    // Named by its hover text, which tells what it sets.
                    ui.add(egui::Slider::new(&mut c.stops, -STOPS..=STOPS))
                        .on_hover_text(format!("{} stops", light.name));
                });
                let moving = light.grid.iter().filter(|&&n| n > 1).count();
                for (a, (at, &n)) in c.at.iter_mut().zip(&light.grid).enumerate() {
                    if n > 1 {
                        let label = match moving {
                            1 => format!("{} position", light.name),
                            _ => format!("{} {}", light.name, ["x", "y", "z"][a]),
                        };
                        ui.add(egui::Slider::new(at, 0.0..=(n - 1) as f32).text(label));
                    }
                }
            }
        });
}
