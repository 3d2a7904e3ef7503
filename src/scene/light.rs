//! Local lights: point, spot, directional and quad lights beside the environment, each baked as
//! its own transport column (one per position it may take) at unit colour and unit intensity,
//! so that colour and intensity are chosen when relighting.
//!
//! Units (radiometric, in scene units of length):
//! - a point or spot light's intensity is its radiant intensity, W/sr: a surface at distance r
//!   facing it receives irradiance `I / r²`;
//! - a directional light's intensity is the irradiance it gives a surface facing it, W/m²; with
//!   `angle_deg` (the disc's angular diameter) that irradiance is spread over a disc of uniform
//!   radiance `E / (π sin² α)`, α the half-angle, which softens its shadows (a disc narrower
//!   than [`MIN_DISC_ANGLE`] is a delta light of the same irradiance);
//! - a quad light's intensity is its radiance, W/(m² sr), uniform over its face and emitted on
//!   the side its corners' winding faces (right-handed: `(c1 − c0) × (c2 − c0)`), as a one-sided
//!   area light. A quad light emits but is not geometry: it casts no shadow and the camera does
//!   not see it, as the lamps of most renderers.
//!
//! A spot follows pbrt-v4's falloff: full intensity within `cone_deg − falloff_deg` of its axis,
//! none beyond `cone_deg`, and a smoothstep in the cosine between.
//!
//! [`Emitter`] is one column's light, placed: what the bake, the reference and the path tracer
//! sample ([`Emitter::sample`]) and what a path tracer's rays can hit ([`Emitter::hit`]).

use glam::Vec3;
use strum::{IntoStaticStr, VariantArray};

/// Angular diameter, radians (about 0.0057°), below which a directional light is a delta light
/// of the same irradiance. A narrower disc's penumbra is under 1e-4 of the occluder's distance
/// wide, and f32 directions place its edge no better than to about a part in a thousand.
pub const MIN_DISC_ANGLE: f32 = 1e-4;

/// Most light columns a scene may have (lights times their positions): a column is a dense
/// image, so 4096 of them at 256² already take 1.5 GiB.
pub const MAX_LIGHT_COLUMNS: usize = 4096;

/// A local light of the scene file: its name, default colour and intensity, shape, and the
/// positions it is baked at.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// Unique name, as `--light NAME=…` and the viewer call it.
    pub name: String,
    /// Linear RGB colour it is relit with by default, each channel >= 0.
    pub color: Vec3,
    /// Intensity it is relit with by default, in the units of its kind (see the module).
    pub intensity: f32,
    /// What kind of light, and its shape about its position.
    pub shape: LightShape,
    /// Where it is baked, one column each: the point or spot's position, or the quad's centre.
    /// A light that does not move has one; a directional light has one, unused.
    pub positions: Vec<Vec3>,
    /// How the positions are laid out: a grid of `x · y · z` points, x varying fastest. A path
    /// is `[n, 1, 1]`, a light that does not move `[1, 1, 1]`.
    pub grid: [usize; 3],
}

/// The kinds of local light, by the one name the scene file's `type`, the transport file's
/// metadata and every message give each.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[derive(serde::Deserialize, IntoStaticStr, strum::Display, VariantArray)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum LightKind {
    /// [`LightShape::Point`].
    Point,
    /// [`LightShape::Spot`].
    Spot,
    /// [`LightShape::Directional`].
    Directional,
    /// [`LightShape::Quad`].
    Quad,
}

crate::named!(LightKind, "light type");

/// The kind of a light and its shape about its position.
#[derive(Clone, Debug, PartialEq)]
pub enum LightShape {
    /// Emits `intensity` W/sr in every direction.
    Point,
    /// A point emitting in a cone.
    Spot {
        /// Unit direction the spot points in.
        direction: Vec3,
        /// Half-angle beyond which it is dark, radians, in (0, π/2].
        cone: f32,
        /// Width of the falloff band inside the cone, radians, in [0, cone].
        falloff: f32,
    },
    /// Light from a distant source.
    Directional {
        /// Unit direction the light travels in (from the source to the scene).
        direction: Vec3,
        /// Angular diameter of the source's disc, radians; 0 (or anything below
        /// [`MIN_DISC_ANGLE`]) is a delta light.
        angle: f32,
    },
    /// A one-sided planar quad of uniform radiance.
    Quad {
        /// Corners relative to the quad's centre (the mean of the corners), in winding order.
        corners: [Vec3; 4],
    },
}

impl LightShape {
    /// Its kind.
    pub fn kind(&self) -> LightKind {
        match self {
            LightShape::Point => LightKind::Point,
            LightShape::Spot { .. } => LightKind::Spot,
            LightShape::Directional { .. } => LightKind::Directional,
            LightShape::Quad { .. } => LightKind::Quad,
        }
    }

    /// Whether it has an extent, and so takes several samples per point to integrate.
    pub fn is_sized(&self) -> bool {
        match self {
            LightShape::Point | LightShape::Spot { .. } => false,
            LightShape::Directional { angle, .. } => *angle >= MIN_DISC_ANGLE,
            LightShape::Quad { .. } => true,
        }
    }
}

/// Largest intensity or colour channel accepted, in any of the kinds' units: far beyond any
/// real lamp at any scale a scene uses, and far from overflowing f32 when squared distances
/// divide it.
pub const MAX_INTENSITY: f32 = 1e12;

/// The one rule for a light's intensity and each channel of its colour: finite, in
/// [0, [`MAX_INTENSITY`]]. The scene file, a glTF light and a stored light are held to it.
pub fn in_light_range(v: f32) -> bool {
    v.is_finite() && (0.0..=MAX_INTENSITY).contains(&v)
}

/// Whether `name` can name a light: 1 to 64 ASCII letters, digits, `_`, `-` or `.`, so that
/// `--light NAME=…` parses and messages print it plainly.
pub fn valid_name(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c))
}

/// A quad's two triangles (corners 0, 1, 2 and 0, 2, 3) as the cross products of their edges
/// from corner 0: each twice its triangle's area, along the normal of its winding.
fn quad_crosses(c: &[Vec3; 4]) -> [Vec3; 2] {
    let (e1, e2, e3) = (c[1] - c[0], c[2] - c[0], c[3] - c[0]);
    [e1.cross(e2), e2.cross(e3)]
}

/// What is wrong with a quad light's corners, if anything: it must have an area, lie in a plane
/// and go round it in order (its two triangles facing the same way).
pub fn quad_problem(c: &[Vec3; 4]) -> Option<String> {
    if !c.iter().all(|p| p.is_finite()) {
        return Some("every corner must be finite".into());
    }
    let size = (c[2] - c[0]).length().max((c[3] - c[1]).length());
    let [a, b] = quad_crosses(c);
    let area = 0.5 * (a.length() + b.length());
    if !(area > 1e-10 * size * size && area > 0.0 && area.is_finite()) {
        return Some("the quad has zero area".into());
    }
    if a.dot(b) <= 0.0 {
        return Some(
            "the corners do not go round the quad in order (list them along its edge)".into(),
        );
    }
    let normal = (a + b).normalize();
    let off = (c[3] - c[0])
        .dot(normal)
        .abs()
        .max((c[1] - c[0]).dot(normal).abs());
    if off > 1e-3 * size {
        return Some(format!(
            "the corners do not lie in one plane (a corner is {off} off it)"
        ));
    }
    None
}

impl Light {
    /// The first thing wrong with the light, for one read from a file: its name, finite colour,
    /// intensity and positions in range, unit directions, angles in range, a proper quad.
    pub fn problem(&self) -> Option<String> {
        use crate::scene::MAX_COORDINATE;
        if !valid_name(&self.name) {
            return Some("its name must be 1 to 64 letters, digits, `_`, `-` or `.`".into());
        }
        if !(self.color.to_array().into_iter().all(in_light_range)
            && in_light_range(self.intensity))
        {
            return Some(format!(
                "colour {} and intensity {} must be in [0, {MAX_INTENSITY:e}]",
                self.color, self.intensity
            ));
        }
        if self.positions.is_empty() || self.positions.len() > MAX_LIGHT_COLUMNS {
            return Some(format!(
                "{} positions; a light has 1 to {MAX_LIGHT_COLUMNS}",
                self.positions.len()
            ));
        }
        if self.grid.contains(&0) || self.grid.iter().product::<usize>() != self.positions.len() {
            return Some(format!(
                "a grid of {:?} points for {} positions",
                self.grid,
                self.positions.len()
            ));
        }
        if !self
            .positions
            .iter()
            .all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE)
        {
            return Some(format!("a position lies beyond ±{MAX_COORDINATE:e}"));
        }
        let unit = |d: Vec3| d.is_finite() && (d.length() - 1.0).abs() < 1e-3;
        let right = std::f32::consts::FRAC_PI_2 + 1e-6;
        match self.shape {
            LightShape::Point => None,
            LightShape::Spot {
                direction,
                cone,
                falloff,
            } => (!(unit(direction)
                && cone > 0.0
                && cone <= right
                && (0.0..=cone).contains(&falloff)))
            .then(|| {
                "a spot needs a unit direction, 0 < cone <= 90° and 0 <= falloff <= cone".into()
            }),
            LightShape::Directional { direction, angle } => (!(unit(direction)
                && (0.0..=right).contains(&angle)))
            .then(|| "a directional light needs a unit direction and 0 <= angle <= 90°".into()),
            LightShape::Quad { corners } => quad_problem(&corners),
        }
    }

    /// The positions' columns (indices into `positions`) and weights that place the light at
    /// `at`, a place along each axis of its grid (0 to count − 1; a path uses the first): the
    /// nearest baked positions, blended multilinearly. `at` is clamped to the grid.
    pub fn blend(&self, at: [f32; 3]) -> Vec<(usize, f32)> {
        let mut axes = [(0usize, 0usize, 0.0f32); 3];
        for a in 0..3 {
            let n = self.grid[a].max(1);
            let t = if at[a].is_finite() {
                at[a].clamp(0.0, (n - 1) as f32)
            } else {
                0.0
            };
            let i = (t.floor() as usize).min(n - 1);
            axes[a] = (i, (i + 1).min(n - 1), t - i as f32);
        }
        let index = |x: usize, y: usize, z: usize| x + self.grid[0] * (y + self.grid[1] * z);
        let mut out: Vec<(usize, f32)> = Vec::with_capacity(8);
        for corner in 0..8 {
            let mut w = 1.0;
            let mut at = [0usize; 3];
            for (a, &(i0, i1, f)) in axes.iter().enumerate() {
                let high = corner >> a & 1 == 1;
                w *= if high { f } else { 1.0 - f };
                at[a] = if high { i1 } else { i0 };
            }
            if w > 0.0 {
                let k = index(at[0], at[1], at[2]);
                match out.iter_mut().find(|(c, _)| *c == k) {
                    Some((_, v)) => *v += w,
                    None => out.push((k, w)),
                }
            }
        }
        out
    }

    /// Where it stands at `at` (see [`Light::blend`]).
    pub fn position_at(&self, at: [f32; 3]) -> Vec3 {
        self.blend(at)
            .into_iter()
            .map(|(k, w)| self.positions[k] * w)
            .sum()
    }

    /// One line about the light for `prt info`: its name, kind, shape, defaults, columns and
    /// the samples a point takes of a sized light (`samples`).
    pub fn describe(&self, samples: u32) -> String {
        // Adding zero prints −0 (a negated axis's other components) as 0.
        let v = |p: Vec3| format!("({:.3}, {:.3}, {:.3})", p.x + 0.0, p.y + 0.0, p.z + 0.0);
        let at = match self.positions.as_slice() {
            [p] => format!("at {}", v(*p)),
            path => format!(
                "along {} positions from {} to {}",
                path.len(),
                v(path[0]),
                v(path[path.len() - 1])
            ),
        };
        let shape = match &self.shape {
            LightShape::Point => format!("point {at}, {} W/sr", self.intensity),
            LightShape::Spot {
                direction,
                cone,
                falloff,
            } => format!(
                "spot {at} towards {}, cone {:.1}° ({:.1}° falloff), {} W/sr",
                v(*direction),
                cone.to_degrees(),
                falloff.to_degrees(),
                self.intensity
            ),
            LightShape::Directional { direction, angle } => format!(
                "directional towards {}{}, {} W/m²",
                v(*direction),
                if self.shape.is_sized() {
                    format!(
                        ", a disc {:.2}° wide ({samples} samples)",
                        angle.to_degrees()
                    )
                } else if *angle > 0.0 {
                    format!(
                        ", a disc {:.4}° wide, drawn as a delta at its irradiance",
                        angle.to_degrees()
                    )
                } else {
                    String::new()
                },
                self.intensity
            ),
            LightShape::Quad { corners } => {
                let [a, b] = quad_crosses(corners);
                let area = 0.5 * (a.length() + b.length());
                format!(
                    "quad {at}, {area:.3} units², {} W/(m² sr) ({samples} samples)",
                    self.intensity
                )
            }
        };
        format!(
            "{}: {shape}, colour {}; {} column(s)",
            self.name,
            v(self.color),
            self.columns()
        )
    }

    /// Columns it is baked into: one per position.
    pub fn columns(&self) -> usize {
        self.positions.len()
    }

    /// Its light at position `i`.
    pub fn emitter(&self, i: usize) -> Emitter {
        let at = self.positions.get(i).copied().unwrap_or(Vec3::ZERO);
        match self.shape {
            LightShape::Point => Emitter::Point { position: at },
            LightShape::Spot {
                direction,
                cone,
                falloff,
            } => Emitter::Spot {
                position: at,
                axis: direction,
                cos_outer: cone.cos(),
                cos_inner: (cone - falloff).cos(),
            },
            LightShape::Directional { direction, angle } => Emitter::directional(-direction, angle),
            LightShape::Quad { corners } => Emitter::quad(corners.map(|c| c + at)),
        }
    }
}

/// One column's light, placed in the scene, at unit intensity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Emitter {
    /// A point light.
    Point {
        /// Where it is.
        position: Vec3,
    },
    /// A spot light.
    Spot {
        /// Where it is.
        position: Vec3,
        /// Unit direction it points in.
        axis: Vec3,
        /// Cosine of the cone's half-angle (dark beyond).
        cos_outer: f32,
        /// Cosine of the angle within which it is at full intensity.
        cos_inner: f32,
    },
    /// A distant light, a delta or a disc.
    Directional {
        /// Unit direction towards the source.
        to_light: Vec3,
        /// Sine of the disc's half-angle α (0 for a delta light).
        sin_half: f32,
        /// Solid angle of the disc, `2π (1 − cos α)` (0 for a delta light).
        solid_angle: f32,
        /// Radiance of the disc, `1 / (π sin² α)` (the irradiance at normal incidence, 1, of a
        /// delta light).
        radiance: f32,
    },
    /// A one-sided quad of unit radiance, as two triangles (`c0 c1 c2`, `c0 c2 c3`).
    Quad {
        /// The first corner.
        origin: Vec3,
        /// The other corners relative to the first.
        edges: [Vec3; 3],
        /// Unit normal of the emitting side.
        normal: Vec3,
        /// Area of each triangle.
        areas: [f32; 2],
        /// Whether the corners make a parallelogram (a rectangle, most often): then a sample is
        /// a point of the grid `c0 + u e01 + v e03`, stratified over the whole quad.
        parallelogram: bool,
    },
}

/// A direction towards a light from a point, and what light comes along it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction towards the light.
    pub dir: Vec3,
    /// Distance to the light along `dir` (infinite for a directional light): shadow rays stop
    /// there.
    pub dist: f32,
    /// Incident radiance over the sample's density (irradiance at normal incidence for a delta
    /// light), at unit intensity: the sample's estimate of `∫ f cos L dω` is `f cos · weight`.
    pub weight: f32,
    /// Density of `dir` in solid angle; 0 for a delta light, which only light sampling reaches.
    pub pdf: f32,
}

/// The unit direction from `p` to `q`, their distance and its square; `None` where they meet or
/// their distance is not a number.
#[inline]
fn towards(p: Vec3, q: Vec3) -> Option<(Vec3, f32, f32)> {
    let d = q - p;
    let r2 = d.length_squared();
    (r2 > 0.0).then(|| {
        let dist = r2.sqrt();
        (d / dist, dist, r2)
    })
}

/// pbrt-v4's smoothstep, 0 at `a`, 1 at `b`.
fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Emitter {
    /// A quad of unit radiance from its corners in winding order (planar and convex: the scene
    /// file checks both).
    pub fn quad(c: [Vec3; 4]) -> Emitter {
        let edges = [c[1] - c[0], c[2] - c[0], c[3] - c[0]];
        let [cross_a, cross_b] = quad_crosses(&c);
        let size = edges[1].length();
        Emitter::Quad {
            origin: c[0],
            edges,
            normal: (cross_a + cross_b).normalize_or_zero(),
            areas: [0.5 * cross_a.length(), 0.5 * cross_b.length()],
            parallelogram: (c[0] + c[2] - c[1] - c[3]).length() <= 1e-5 * size,
        }
    }

    /// A distant light towards unit `to_light` giving unit irradiance at normal incidence,
    /// spread over a disc of angular diameter `angle` (radians): a delta light below
    /// [`MIN_DISC_ANGLE`]. The disc's sizes are taken in f64 and its solid angle as
    /// `4π sin²(α/2)`, never as `1 − cos α`, which f32 rounds to 0 for discs under 0.03°.
    pub fn directional(to_light: Vec3, angle: f32) -> Emitter {
        if angle.is_nan() || angle < MIN_DISC_ANGLE {
            return Emitter::Directional {
                to_light,
                sin_half: 0.0,
                solid_angle: 0.0,
                radiance: 1.0,
            };
        }
        let half = 0.5 * angle as f64;
        let sin_half = half.sin();
        Emitter::Directional {
            to_light,
            sin_half: sin_half as f32,
            solid_angle: (4.0 * std::f64::consts::PI * (0.5 * half).sin().powi(2)) as f32,
            radiance: (1.0 / (std::f64::consts::PI * sin_half * sin_half)) as f32,
        }
    }

    /// Whether the light is a delta (a point, a spot or a sun without a disc): one sample
    /// integrates it exactly.
    pub fn is_delta(&self) -> bool {
        match self {
            Emitter::Point { .. } | Emitter::Spot { .. } => true,
            Emitter::Directional { solid_angle, .. } => *solid_angle <= 0.0,
            Emitter::Quad { .. } => false,
        }
    }

    /// A direction towards the light from `p`, from two uniform numbers (stratify them for
    /// smooth penumbrae). `None` where no light reaches `p` (behind a quad, outside a spot's
    /// cone, at the light itself).
    pub fn sample(&self, p: Vec3, u: [f32; 2]) -> Option<LightSample> {
        match *self {
            Emitter::Point { position } => {
                let (dir, dist, r2) = towards(p, position)?;
                Some(LightSample {
                    dir,
                    dist,
                    weight: 1.0 / r2,
                    pdf: 0.0,
                })
            }
            Emitter::Spot {
                position,
                axis,
                cos_outer,
                cos_inner,
            } => {
                let (dir, dist, r2) = towards(p, position)?;
                let fall = smoothstep(cos_outer, cos_inner, axis.dot(-dir));
                (fall > 0.0).then_some(LightSample {
                    dir,
                    dist,
                    weight: fall / r2,
                    pdf: 0.0,
                })
            }
            Emitter::Directional {
                to_light,
                solid_angle,
                radiance,
                ..
            } => {
                if solid_angle <= 0.0 {
                    return Some(LightSample {
                        dir: to_light,
                        dist: f32::INFINITY,
                        weight: radiance,
                        pdf: 0.0,
                    });
                }
                // Uniform over the cone of the disc: `w = 1 − cos θ` uniform in
                // [0, 1 − cos α], the sine taken from `w` so that a tiny disc keeps its size.
                let w = u[0].clamp(0.0, 1.0) * (solid_angle / std::f32::consts::TAU);
                let (cos, sin) = (1.0 - w, (w * (2.0 - w)).max(0.0).sqrt());
                let phi = std::f32::consts::TAU * u[1];
                let (t, b) = to_light.any_orthonormal_pair();
                let dir =
                    (t * (sin * phi.cos()) + b * (sin * phi.sin()) + to_light * cos).normalize();
                Some(LightSample {
                    dir,
                    dist: f32::INFINITY,
                    weight: radiance * solid_angle,
                    pdf: 1.0 / solid_angle,
                })
            }
            Emitter::Quad {
                origin,
                edges,
                normal,
                areas,
                parallelogram,
            } => {
                // Uniform by area: over a parallelogram directly; otherwise a triangle in
                // proportion to its area, then a point in it.
                let total = areas[0] + areas[1];
                let q = if parallelogram {
                    origin + edges[0] * u[0] + edges[2] * u[1]
                } else {
                    let split = areas[0] / total;
                    let (a, b, x) = if u[0] < split {
                        (edges[0], edges[1], u[0] / split)
                    } else {
                        (edges[1], edges[2], (u[0] - split) / (1.0 - split))
                    };
                    let s = x.min(1.0).sqrt();
                    origin + a * (s * (1.0 - u[1])) + b * (s * u[1])
                };
                let (dir, dist, r2) = towards(p, q)?;
                let cos_light = normal.dot(-dir);
                if cos_light <= 0.0 {
                    return None;
                }
                // Area density converted to solid angle: r² / (A cos θ_l).
                let pdf = r2 / (total * cos_light);
                Some(LightSample {
                    dir,
                    dist,
                    weight: 1.0 / pdf,
                    pdf,
                })
            }
        }
    }

    /// Where a ray from `p` along unit `dir` meets the light, for a path tracer's directions
    /// that were not drawn from the light: the distance (infinite for a distant disc), the
    /// radiance it brings at unit intensity, and the density [`Emitter::sample`] would have
    /// drawn `dir` with. `None` for a delta light or a miss (or the back of a quad).
    pub fn hit(&self, p: Vec3, dir: Vec3) -> Option<(f32, f32, f32)> {
        match *self {
            Emitter::Point { .. } | Emitter::Spot { .. } => None,
            Emitter::Directional {
                to_light,
                sin_half,
                solid_angle,
                radiance,
            } => {
                // Inside the disc (α <= 45°): in front, and sin θ = |dir × to_light| <= sin α,
                // which f32 resolves for tiny discs where cos θ >= cos α does not.
                let inside = dir.dot(to_light) > 0.0
                    && dir.cross(to_light).length_squared() <= sin_half * sin_half;
                (solid_angle > 0.0 && inside).then(|| (f32::INFINITY, radiance, 1.0 / solid_angle))
            }
            Emitter::Quad {
                origin,
                edges,
                normal,
                areas,
                ..
            } => {
                let cos_light = -normal.dot(dir);
                if cos_light <= 0.0 {
                    return None;
                }
                let t = normal.dot(origin - p) / normal.dot(dir);
                if !(t > 0.0 && t.is_finite()) {
                    return None;
                }
                let q = p + dir * t - origin;
                let inside = |a: Vec3, b: Vec3| {
                    // Barycentric test in the triangle (0, a, b).
                    let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
                    let (qa, qb) = (q.dot(a), q.dot(b));
                    let det = aa * bb - ab * ab;
                    let s = (bb * qa - ab * qb) / det;
                    let r = (aa * qb - ab * qa) / det;
                    s >= 0.0 && r >= 0.0 && s + r <= 1.0
                };
                (inside(edges[0], edges[1]) || inside(edges[1], edges[2]))
                    .then(|| (t, 1.0, t * t / ((areas[0] + areas[1]) * cos_light)))
            }
        }
    }
}

/// Every light column of `lights`, in order: each light's positions in turn.
pub fn emitters(lights: &[Light]) -> Vec<Emitter> {
    lights
        .iter()
        .flat_map(|l| (0..l.columns()).map(move |i| l.emitter(i)))
        .collect()
}

/// How many strata [`stratified`] makes of `n`: `n` rounded up to a square, as the bake
/// records it ([`crate::math::sampling::TexelSamples::grid_side`]).
pub fn strata(n: usize) -> usize {
    crate::math::sampling::TexelSamples::grid_side(n).pow(2)
}

/// Stratified pairs in [0, 1)²: the cells of a ⌈√n⌉ x ⌈√n⌉ grid, row by row, each jittered by
/// two draws of `next` (x, then y), drawn as the pairs are taken.
pub fn stratified(n: usize, mut next: impl FnMut() -> f32) -> impl Iterator<Item = [f32; 2]> {
    let side = crate::math::sampling::TexelSamples::grid_side(n);
    (0..side * side).map(move |i| {
        let x = ((i % side) as f32 + next()) / side as f32;
        [x, ((i / side) as f32 + next()) / side as f32]
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_is_described_by_its_shape_in_its_units() {
        let light = |shape, positions: Vec<Vec3>| Light {
            name: "l".into(),
            color: Vec3::new(1.0, 0.5, 0.25),
            intensity: 20.0,
            shape,
            grid: [positions.len(), 1, 1],
            positions,
        };
        let at = vec![Vec3::Y];
        let point = light(LightShape::Point, at.clone()).describe(16);
        assert_eq!(
            point,
            "l: point at (0.000, 1.000, 0.000), 20 W/sr, colour (1.000, 0.500, 0.250); 1 column(s)"
        );
        let spot = LightShape::Spot {
            direction: -Vec3::Y,
            cone: 30f32.to_radians(),
            falloff: 5f32.to_radians(),
        };
        let path = vec![Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
        let spot = light(spot, path).describe(16);
        assert!(
            spot.contains("spot along 3 positions from (0.000"),
            "{spot}"
        );
        assert!(spot.contains("towards (0.000, -1.000, 0.000)"), "{spot}");
        assert!(
            spot.contains("cone 30.0° (5.0° falloff), 20 W/sr"),
            "{spot}"
        );
        assert!(spot.ends_with("; 3 column(s)"), "{spot}");
        // A 2 x 0.5 rectangle: the two triangles' areas add to 1.
        let corners = [
            [-1.0, 0.0, -0.25],
            [1.0, 0.0, -0.25],
            [1.0, 0.0, 0.25],
            [-1.0, 0.0, 0.25],
        ];
        let quad = LightShape::Quad {
            corners: corners.map(Vec3::from_array),
        };
        let quad = light(quad, at.clone()).describe(16);
        assert!(
            quad.contains("quad at (0.000, 1.000, 0.000), 1.000 units², 20 W/(m² sr) (16 samples)"),
            "{quad}"
        );
        let sun = |angle: f32| LightShape::Directional {
            direction: -Vec3::Y,
            angle: angle.to_radians(),
        };
        let wide = light(sun(0.53), at.clone()).describe(16);
        assert!(
            wide.contains("a disc 0.53° wide (16 samples), 20 W/m²"),
            "{wide}"
        );
        let narrow = light(sun(MIN_DISC_ANGLE.to_degrees() / 2.0), at.clone()).describe(16);
        assert!(
            narrow.contains("a disc 0.0029° wide, drawn as a delta at its irradiance"),
            "{narrow}"
        );
        let delta = light(sun(0.0), at).describe(16);
        assert!(
            delta.contains("directional towards (0.000, -1.000, 0.000), 20 W/m²"),
            "{delta}"
        );
    }

    #[test]
    fn a_place_in_a_grid_blends_its_nearest_positions_multilinearly() {
        let light = Light {
            name: "g".into(),
            color: Vec3::ONE,
            intensity: 1.0,
            shape: LightShape::Point,
            positions: (0..6)
                .map(|i| Vec3::new((i % 3) as f32, (i / 3) as f32, 0.0))
                .collect(),
            grid: [3, 2, 1],
        };
        assert!(light.problem().is_none());
        let mut b = light.blend([1.25, 0.5, 0.0]);
        b.sort_by_key(|(k, _)| *k);
        assert_eq!(b, vec![(1, 0.375), (2, 0.125), (4, 0.375), (5, 0.125)]);
        assert_eq!(
            light.position_at([1.25, 0.5, 0.0]),
            Vec3::new(1.25, 0.5, 0.0)
        );
        assert_eq!(light.blend([2.0, 1.0, 0.0]), vec![(5, 1.0)]);
        assert_eq!(light.blend([9.0, -1.0, 3.0]), vec![(2, 1.0)]);
        assert!(
            Light {
                grid: [2, 2, 1],
                ..light
            }
            .problem()
            .is_some()
        );
    }

    fn quad() -> Emitter {
        Emitter::quad([
            Vec3::new(-0.5, 2.0, -0.5),
            Vec3::new(0.5, 2.0, -0.5),
            Vec3::new(0.5, 2.0, 0.5),
            Vec3::new(-0.5, 2.0, 0.5),
        ])
    }

    #[test]
    fn a_quad_emits_along_its_winding_normal() {
        let Emitter::Quad { normal, areas, .. } = quad() else {
            unreachable!()
        };
        assert_eq!(normal, Vec3::NEG_Y);
        assert!((areas[0] + areas[1] - 1.0).abs() < 1e-6);
        assert!(quad().sample(Vec3::ZERO, [0.3, 0.6]).is_some());
        assert!(
            quad()
                .sample(Vec3::new(0.0, 3.0, 0.0), [0.3, 0.6])
                .is_none()
        );
    }

    #[test]
    fn a_sampled_quad_direction_hits_the_quad_with_the_same_density() {
        let q = quad();
        let p = Vec3::new(0.3, 0.1, -0.2);
        for u in stratified(16, || 0.5) {
            let s = q.sample(p, u).unwrap();
            let (t, radiance, pdf) = q.hit(p, s.dir).unwrap();
            assert!((t - s.dist).abs() < 1e-4 * s.dist, "{t} {}", s.dist);
            assert_eq!(radiance, 1.0);
            assert!((pdf - s.pdf).abs() < 1e-4 * s.pdf, "{pdf} {}", s.pdf);
        }
        assert!(q.hit(p, Vec3::Y.cross(Vec3::X)).is_none());
    }

    #[test]
    fn a_spot_is_full_inside_and_dark_outside_its_cone() {
        let light = Light {
            name: "s".into(),
            color: Vec3::ONE,
            intensity: 1.0,
            shape: LightShape::Spot {
                direction: Vec3::NEG_Y,
                cone: 30f32.to_radians(),
                falloff: 10f32.to_radians(),
            },
            positions: vec![Vec3::new(0.0, 1.0, 0.0)],
            grid: [1, 1, 1],
        };
        let e = light.emitter(0);
        let at = |deg: f32| Vec3::new(deg.to_radians().tan(), 0.0, 0.0);
        let w = |deg: f32| {
            e.sample(at(deg), [0.5; 2])
                .map_or(0.0, |s| s.weight * s.dist.powi(2))
        };
        assert!((w(19.0) - 1.0).abs() < 1e-5);
        assert_eq!(w(31.0), 0.0);
        let mid = w(25.0);
        assert!(mid > 0.0 && mid < 1.0, "{mid}");
    }

    #[test]
    fn a_sun_disc_gives_its_irradiance_at_normal_incidence() {
        let light = Light {
            name: "sun".into(),
            color: Vec3::ONE,
            intensity: 1.0,
            shape: LightShape::Directional {
                direction: Vec3::NEG_Y,
                angle: 10f32.to_radians(),
            },
            positions: vec![Vec3::ZERO],
            grid: [1, 1, 1],
        };
        let e = light.emitter(0);
        let samples: Vec<[f32; 2]> = stratified(64, || 0.5).collect();
        let e_n: f32 = samples
            .iter()
            .map(|&u| {
                let s = e.sample(Vec3::ZERO, u).unwrap();
                s.weight * s.dir.y
            })
            .sum::<f32>()
            / samples.len() as f32;
        assert!((e_n - 1.0).abs() < 1e-3, "{e_n}");
    }

    #[test]
    fn a_sun_disc_of_any_size_keeps_its_irradiance_and_is_hit_where_it_is_sampled() {
        let to_light = Vec3::new(0.3, 0.9, -0.2).normalize();
        let (t, _) = to_light.any_orthonormal_pair();
        let samples: Vec<[f32; 2]> = stratified(64, || 0.5).collect();
        for deg in [0.001f32, 0.005, 0.006, 0.01, 0.03, 0.1, 1.0, 10.0, 90.0] {
            let e = Emitter::directional(to_light, deg.to_radians());
            assert_eq!(e.is_delta(), deg.to_radians() < MIN_DISC_ANGLE, "{deg}°");
            // Irradiance on a plane facing the disc: L π sin² α = 1 (the midpoint rule is
            // exact in 1 − cos θ, which the cosine is linear in).
            let mut e_n = 0.0f64;
            for &u in &samples {
                let s = e.sample(Vec3::ZERO, u).unwrap();
                assert!(s.weight.is_finite() && s.pdf.is_finite(), "{deg}°: {s:?}");
                e_n += (s.weight * s.dir.dot(to_light)) as f64 / samples.len() as f64;
                if !e.is_delta() {
                    let (dist, radiance, pdf) = e
                        .hit(Vec3::ZERO, s.dir)
                        .unwrap_or_else(|| panic!("{deg}°: a sampled direction misses"));
                    assert_eq!(dist, f32::INFINITY);
                    assert_eq!(pdf, s.pdf, "{deg}°");
                    assert!(
                        (radiance / pdf - s.weight).abs() <= 1e-5 * s.weight,
                        "{deg}°"
                    );
                }
            }
            assert!((e_n - 1.0).abs() < 1e-4, "{deg}°: irradiance {e_n}");
            let Emitter::Directional { sin_half, .. } = e else {
                unreachable!()
            };
            let outside = (to_light + t * (2.0 * sin_half)).normalize();
            assert!(e.hit(Vec3::ZERO, outside).is_none(), "{deg}°");
        }
    }
}
