//! What a view shows, in parts that change for different reasons: the light ([`LightState`]),
//! what is relit under it ([`RelightState`]), how the result is displayed ([`DisplayState`]) and,
//! for a per-vertex bake, the camera ([`Orbit`]). The caches key on the parts: a prepared light
//! on the light's [`LightKey`], the relit values on [`RelightKey`] (light and relight), so an
//! exposure or a camera change never relights and a new field is keyed where its part is.

use std::path::PathBuf;

use super::lights::STOPS;
use super::{EnvEntry, EnvSource, LightsState};
use crate::app::cli::DEFAULT_TERMS;
use crate::draw::vertex::Orbit;
use crate::env::envmap::{EnvRotation, EnvSpec, SunSpec};
use crate::env::select::Weighting;
use crate::error::{PrtError, Result};
use crate::output::film::{ToneCurve, ToneMap};
use crate::relight::sh_transfer::MAX_TRANSFER_ORDER;
use crate::relight::{LightSetting, Method, RelightRequest};
use crate::scene::Light;

/// The light of a view: an entry of the environment list, where the procedural sun stands (used
/// when that entry is the sun, and kept while another is shown), and the environment's turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightState {
    /// Index into the environment list.
    pub env: usize,
    /// The procedural sun: elevation, azimuth and angular radius, degrees.
    pub sun: SunSpec,
    /// The environment's rotation, degrees.
    pub rotation: EnvRotation,
}

impl Default for LightState {
    fn default() -> Self {
        LightState {
            env: 0,
            sun: SunSpec {
                elevation: 30.0,
                azimuth: 45.0,
                radius: SunSpec::DEFAULT_RADIUS,
            },
            rotation: EnvRotation::default(),
        }
    }
}

impl LightState {
    /// The environment this light names in `envs` (the sun when the index is past the list).
    pub fn env_spec(&self, envs: &[EnvEntry]) -> EnvSpec {
        match envs.get(self.env).map(|e| &e.source) {
            Some(EnvSource::File(p)) => EnvSpec::File(p.clone()),
            _ => EnvSpec::Sun(self.sun),
        }
    }

    /// What a light prepared for this state is cached under.
    pub fn key(&self, envs: &[EnvEntry]) -> LightKey {
        LightKey {
            env: self.env_spec(envs),
            rotation: self.rotation,
        }
    }

    /// Brings the sun into range (elevation in [-90, 90], radius in [0.05, 45], azimuth
    /// finite) and the index into the list of `envs` entries; returns a note for an index that
    /// did not exist.
    pub fn clamp(&mut self, envs: usize) -> Option<String> {
        let sun = &mut self.sun;
        if !(-90.0..=90.0).contains(&sun.elevation) {
            sun.elevation = if sun.elevation.is_finite() {
                sun.elevation.clamp(-90.0, 90.0)
            } else {
                30.0
            };
        }
        if !sun.azimuth.is_finite() {
            sun.azimuth = 0.0;
        }
        if !(0.05..=45.0).contains(&sun.radius) {
            sun.radius = if sun.radius.is_finite() {
                sun.radius.clamp(0.05, 45.0)
            } else {
                SunSpec::DEFAULT_RADIUS
            };
        }
        (self.env >= envs).then(|| {
            let note = format!("environment {} does not exist; using the first", self.env);
            self.env = 0;
            note
        })
    }
}

/// The light a [`LightState`] makes: what a prepared light is cached under.
#[derive(Clone, Debug, PartialEq)]
pub struct LightKey {
    /// The environment: a file, or the procedural sun.
    pub env: EnvSpec,
    /// Its rotation.
    pub rotation: EnvRotation,
}

impl LightKey {
    /// The file of a file map (worth keeping: a file is read once, a procedural sun changes
    /// with every slider move).
    pub fn file(&self) -> Option<&PathBuf> {
        match &self.env {
            EnvSpec::File(p) => Some(p),
            EnvSpec::Sun(_) => None,
        }
    }
}

/// What is relit under the light: the method and its parameters, and whether SH and wavelets are
/// compared at the same term count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelightState {
    /// The method shown (when not comparing).
    pub method: Method,
    /// Kept wavelet terms K (1 to 6 N²); at first [`DEFAULT_TERMS`], as `prt relight`.
    pub terms: usize,
    /// How the K terms are chosen.
    pub weighting: Weighting,
    /// SH order n (1 to the baked order; through the light up to its own limit).
    pub sh_order: usize,
    /// SH and wavelet at the same term count, side by side or split ([`DisplayState::layout`]).
    pub compare: bool,
}

impl Default for RelightState {
    fn default() -> Self {
        RelightState {
            method: Method::Wavelet,
            terms: DEFAULT_TERMS,
            weighting: Weighting::Transport,
            sh_order: 4,
            compare: false,
        }
    }
}

/// What a transport and the environment list allow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// 6 N².
    pub coeffs: usize,
    /// Baked SH order.
    pub sh_order: usize,
    /// Highest SH order through the light: no more terms than texels, at most
    /// [`crate::math::sh::MAX_LIGHT_ORDER`].
    pub sh_light_order: usize,
    /// Entries in the environment list.
    pub envs: usize,
}

impl RelightState {
    /// Brings K and the order into range; returns a note for each that was out of it.
    pub fn clamp(&mut self, limits: Limits) -> Vec<String> {
        let mut notes = Vec::new();
        if self.terms == 0 || self.terms > limits.coeffs {
            let k = self.terms.clamp(1, limits.coeffs.max(1));
            notes.push(format!(
                "terms {} clamped to {k} (1 to 6N² = {})",
                self.terms, limits.coeffs
            ));
            self.terms = k;
        }
        let (most, why) = if self.method == Method::ShLight {
            (
                limits.sh_light_order.max(1),
                "through the light, up to order",
            )
        } else {
            (limits.sh_order.max(1), "this file was baked up to order")
        };
        if self.sh_order == 0 || self.sh_order > most {
            let n = self.sh_order.clamp(1, most);
            notes.push(format!(
                "SH order {} clamped to {n} ({why} {most})",
                self.sh_order
            ));
            self.sh_order = n;
        }
        notes
    }

    /// Next method in the cycle wavelet → SH → full → SH through the light.
    pub fn cycle_method(&mut self) {
        self.method = match self.method {
            Method::Wavelet => Method::Sh,
            Method::Sh => Method::Full,
            Method::Full => Method::ShLight,
            Method::ShLight => Method::Wavelet,
        };
    }

    /// The panes this state shows: the requests and their titles.
    pub fn requests(&self, limits: Limits) -> Vec<(String, RelightRequest)> {
        let wavelets = RelightRequest::Wavelet {
            k: self.terms,
            weighting: self.weighting,
        };
        if self.compare {
            let n = sh_order_for_terms(self.terms, limits.sh_order);
            return vec![
                (
                    format!("SH order {n} ({} terms)", n * n),
                    RelightRequest::Sh { order: n },
                ),
                (format!("wavelet, {} terms", self.terms), wavelets),
            ];
        }
        let n = self.sh_order;
        let title = match self.method {
            Method::Wavelet => format!("wavelet, {} terms ({})", self.terms, self.weighting.name()),
            Method::Sh => format!("SH order {n} ({} terms)", n * n),
            Method::Full => format!("full ({} terms)", limits.coeffs),
            Method::ShLight => format!("SH order {n} through the light ({} terms)", n * n),
        };
        let request = RelightRequest::new(self.method, self.terms, self.weighting, n);
        vec![(title, request)]
    }
}

/// The SH order whose n² terms are nearest to `terms`, within 1 and the baked order.
pub fn sh_order_for_terms(terms: usize, baked: usize) -> usize {
    let n = (terms as f64).sqrt().round() as usize;
    n.clamp(1, baked.max(1))
}

/// How [`RelightState::compare`] shows its two images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Layout {
    /// Side by side.
    #[default]
    SideBySide,
    /// One image, SH left of the split and wavelet right of it.
    Split,
}

/// How relit images are displayed: nothing here relights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayState {
    /// Exposure in stops.
    pub exposure: f32,
    /// Display curve after the exposure.
    pub tone: ToneCurve,
    /// How the two images of a comparison are shown.
    pub layout: Layout,
    /// Where the split falls in [`Layout::Split`], as a fraction of the width (SH to its left).
    pub split: f32,
    /// Show, beside each image, its error against `full` as a heat map.
    pub error_map: bool,
    /// Take the image from the GPU kernels, when a GPU is attached: in the window they write
    /// straight into a texture (the numbers still come from the CPU relight); in
    /// [`super::Engine::render`] the image is read back.
    pub gpu: bool,
    /// A per-vertex bake with visibility: its glossy light drawn by SH glossy transfer at this
    /// order (1 to [`MAX_TRANSFER_ORDER`]; Sloan, Kautz & Snyder 2002) instead of the lobe per
    /// pixel (`None`). The GPU raster draws the lobe alone, so the CPU draws this.
    pub sh_transfer: Option<usize>,
}

impl Default for DisplayState {
    fn default() -> Self {
        DisplayState {
            exposure: 0.0,
            tone: ToneCurve::Clip,
            layout: Layout::SideBySide,
            split: 0.5,
            error_map: false,
            gpu: false,
            sh_transfer: None,
        }
    }
}

impl DisplayState {
    /// The tone mapping it applies.
    pub fn tone_map(&self) -> ToneMap {
        ToneMap {
            exposure: self.exposure,
            curve: self.tone,
        }
    }

    /// Brings the split into [0, 1] and the SH transfer's order into its range.
    pub fn clamp(&mut self) {
        if let Some(order) = &mut self.sh_transfer {
            *order = (*order).clamp(1, MAX_TRANSFER_ORDER);
        }
        if !(0.0..=1.0).contains(&self.split) {
            self.split = if self.split.is_finite() {
                self.split.clamp(0.0, 1.0)
            } else {
                0.5
            };
        }
    }
}

/// Every input of the displayed image, in its parts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewState {
    /// The light.
    pub light: LightState,
    /// What is relit under it.
    pub relight: RelightState,
    /// How it is displayed.
    pub display: DisplayState,
    /// The camera of a per-vertex bake, turned from the bake's own (ignored by a per-pixel bake,
    /// whose view is fixed).
    pub orbit: Orbit,
    /// The local lights, and whether the environment shines.
    pub lights: LightsState,
    /// The size a per-vertex bake is drawn at, in pixels: the window sets its pane's, so the
    /// mesh is drawn at the resolution it is shown at; `None` draws at the bake camera's.
    pub draw_size: Option<(u32, u32)>,
}

/// Largest side a per-vertex bake is drawn at in the viewer, in pixels.
pub const MAX_DRAW_SIDE: u32 = 4096;

/// What the relit values (pixels, or a per-vertex bake's vertex colours) depend on: the light,
/// the relight and the local lights, not the display or the camera.
#[derive(Clone, Debug, PartialEq)]
pub struct RelightKey {
    /// The light's state.
    pub light: LightState,
    /// The relight's.
    pub relight: RelightState,
    /// The local lights'.
    pub lights: LightsState,
}

impl ViewState {
    /// Samples a pixel a per-vertex bake is drawn with on the CPU: [`DRAW_SAMPLES`] when the
    /// window shows the GPU's images (which draw that many; the CPU's are then for saving),
    /// else 1, so a window without a GPU stays interactive at its pane's size (on 2 cores, a
    /// 760² draw of the demo's 84k vertices takes 13 ms at 1 sample and 61 ms at 4).
    ///
    /// [`DRAW_SAMPLES`]: crate::draw::raster::DRAW_SAMPLES
    pub fn draw_samples(&self) -> u32 {
        match self.display.gpu {
            true => crate::draw::raster::DRAW_SAMPLES,
            false => 1,
        }
    }

    /// The camera a per-vertex bake made from `base` is drawn through: turned by the orbit, at
    /// the draw size.
    pub fn camera_of(&self, base: &crate::scene::Camera) -> crate::scene::Camera {
        let mut c = self.orbit.camera(base);
        if let Some((w, h)) = self.draw_size {
            (c.width, c.height) = (w.clamp(1, MAX_DRAW_SIDE), h.clamp(1, MAX_DRAW_SIDE));
        }
        c
    }

    /// Brings every part into range; returns a note for each value that was out of range.
    pub fn clamp(&mut self, limits: Limits) -> Vec<String> {
        let mut notes = self.relight.clamp(limits);
        notes.extend(self.light.clamp(limits.envs));
        // Turning past a half turn wraps around: no note.
        self.orbit.clamp();
        self.display.clamp();
        notes
    }

    /// The panes this state shows: the requests and their titles.
    pub fn requests(&self, limits: Limits) -> Vec<(String, RelightRequest)> {
        self.relight.requests(limits)
    }

    /// Sets the local lights of `lights` as `settings` say (one per light, as `--light`
    /// arguments leave them): each light's switch, colour and place, and its intensity in stops
    /// from its scene file's, within the stops the window's slider spans either way.
    pub fn set_lights(&mut self, lights: &[Light], settings: &[LightSetting]) -> Result<()> {
        if settings.len() != lights.len() {
            return Err(PrtError::invalid(
                "lights",
                format!("{} settings for {} lights", settings.len(), lights.len()),
            ));
        }
        let mut state = LightsState::of(lights);
        state.environment = self.lights.environment;
        for ((control, light), s) in state.lights.iter_mut().zip(lights).zip(settings) {
            control.on = s.on;
            control.color = s.color.to_array();
            control.at = s.at;
            if s.on && light.intensity > 0.0 {
                let scale = s.intensity / light.intensity;
                let stops = scale.log2();
                if !(-STOPS..=STOPS).contains(&stops) {
                    let most = STOPS.exp2();
                    return Err(PrtError::invalid(
                        "--light",
                        format!(
                            "`{}` at {scale} times its scene file's intensity; the viewer takes \
                             1/{most} to {most} times it",
                            light.name
                        ),
                    ));
                }
                control.stops = stops;
            }
        }
        self.lights = state;
        Ok(())
    }

    /// What its relit values are cached under.
    pub fn relight_key(&self) -> RelightKey {
        RelightKey {
            light: self.light,
            relight: self.relight,
            lights: self.lights.clone(),
        }
    }

    /// The tone mapping of this state.
    pub fn tone_map(&self) -> ToneMap {
        self.display.tone_map()
    }

    /// Whether the panes are shown in pairs split by [`DisplayState::split`].
    pub fn split_pairs(&self) -> bool {
        self.relight.compare && self.display.layout == Layout::Split
    }
}
