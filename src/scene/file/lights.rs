//! The scene file's `[[light]]` tables: their schema, and the checks that turn them into
//! [`Light`]s, each problem naming the file, the line and the field (`light[1].cone_deg`).

use super::numbers::{numbers, some_numbers, some_point_list, some_points};
use super::{Loader, finite3, position3};
use crate::error::Result;
use crate::names::Named;
use crate::scene::light::{
    Light, LightKind, LightShape, MAX_INTENSITY, MAX_LIGHT_COLUMNS, in_light_range, quad_problem,
    valid_name,
};
use glam::Vec3;
use serde::Deserialize;

/// The keys a light of `kind` takes besides those every light takes.
fn allowed_keys(kind: LightKind) -> &'static [&'static str] {
    match kind {
        LightKind::Point => &["position", "positions", "grid"],
        LightKind::Spot => &[
            "position",
            "positions",
            "grid",
            "direction",
            "cone_deg",
            "falloff_deg",
        ],
        LightKind::Directional => &["direction", "angle_deg"],
        LightKind::Quad => &["corners", "positions", "grid"],
    }
}

/// One `[[light]]` table. Flat, with a `type` key, as the shapes are (see the schema's note).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightFile {
    name: String,
    r#type: LightKind,
    #[serde(default, deserialize_with = "some_numbers")]
    color: Option<[f32; 3]>,
    intensity: f32,
    #[serde(default, deserialize_with = "some_numbers")]
    position: Option<[f32; 3]>,
    #[serde(default, deserialize_with = "some_point_list")]
    positions: Option<Vec<[f32; 3]>>,
    #[serde(default, deserialize_with = "some_numbers")]
    direction: Option<[f32; 3]>,
    cone_deg: Option<f32>,
    falloff_deg: Option<f32>,
    angle_deg: Option<f32>,
    #[serde(default, deserialize_with = "some_points")]
    corners: Option<[[f32; 3]; 4]>,
    grid: Option<GridFile>,
}

/// A light's `grid`: `counts` points from `from` to `to` along each axis (both ends included).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GridFile {
    #[serde(deserialize_with = "numbers")]
    from: [f32; 3],
    #[serde(deserialize_with = "numbers")]
    to: [f32; 3],
    #[serde(deserialize_with = "numbers")]
    counts: [u32; 3],
}

impl LightFile {
    /// The optional keys present in this table, for checking they suit its kind.
    fn present_keys(&self) -> [(&'static str, bool); 8] {
        present!(self; position positions grid direction cone_deg falloff_deg angle_deg corners)
    }
}

impl Loader<'_> {
    /// The scene's lights, checked: unique names of letters, digits, `_`, `-` and `.`; each
    /// kind's keys and only those; finite positions; unit directions; angles in range; planar,
    /// quads with corners in order; at most [`MAX_LIGHT_COLUMNS`] columns in all.
    pub(super) fn lights(&self, files: &[LightFile]) -> Result<Vec<Light>> {
        let mut lights: Vec<Light> = Vec::with_capacity(files.len());
        let mut columns = 0usize;
        for (i, l) in files.iter().enumerate() {
            let light = self.light(i, l, &lights)?;
            columns += light.positions.len();
            if columns > MAX_LIGHT_COLUMNS {
                return Err(self.map.error(
                    &format!("light[{i}].positions"),
                    format!(
                        "the lights take more than {MAX_LIGHT_COLUMNS} columns (one per light and \
                         position), each a dense image in the bake"
                    ),
                ));
            }
            lights.push(light);
        }
        Ok(lights)
    }

    /// Light `i` of the scene file, `l`, checked (its name against those of the `earlier`
    /// lights).
    fn light(&self, i: usize, l: &LightFile, earlier: &[Light]) -> Result<Light> {
        let field = |key: &str| format!("light[{i}].{key}");
        let err = |key: &str, message: String| self.map.error(&field(key), message);
        let kind = l.r#type;
        if !valid_name(&l.name) {
            return Err(err(
                "name",
                format!(
                    "`{}`: a light's name is 1 to 64 letters, digits, `_`, `-` or `.` (the \
                     command line sets it as NAME=…)",
                    l.name.escape_debug()
                ),
            ));
        }
        if let Some(j) = earlier.iter().position(|o| o.name == l.name) {
            return Err(err(
                "name",
                format!("`{}` is already the name of light[{j}]", l.name),
            ));
        }
        for (key, present) in l.present_keys() {
            if present && !allowed_keys(kind).contains(&key) {
                return Err(err(
                    key,
                    format!("`{key}` does not apply to a {} light", kind.name()),
                ));
            }
        }
        let require = |key: &str, present: bool| {
            if present {
                Ok(())
            } else {
                Err(err(key, format!("a {} light needs `{key}`", kind.name())))
            }
        };
        let color = finite3(&self.map, &field("color"), l.color.unwrap_or([1.0; 3]))?;
        if !color.to_array().into_iter().all(in_light_range) {
            return Err(err(
                "color",
                format!("each channel must be in [0, {MAX_INTENSITY:e}], got {color}"),
            ));
        }
        if !in_light_range(l.intensity) {
            return Err(err(
                "intensity",
                format!(
                    "must be in [0, {MAX_INTENSITY:e}] ({}), got {}",
                    match kind {
                        LightKind::Point | LightKind::Spot => "W/sr",
                        LightKind::Directional => "W/m², the irradiance it gives",
                        LightKind::Quad => "W/(m² sr), its radiance",
                    },
                    l.intensity
                ),
            ));
        }
        let direction = |key: &str| -> Result<Vec3> {
            require(key, l.direction.is_some())?;
            let d = finite3(&self.map, &field(key), l.direction.unwrap_or_default())?;
            let len = d.length();
            if !(len > 1e-6 && len.is_finite()) {
                return Err(err(key, format!("must be a nonzero vector, got {d}")));
            }
            Ok(d / len)
        };
        let angle = |key: &str, value: f32, max: f32| -> Result<f32> {
            if !(value.is_finite() && (0.0..=max).contains(&value)) {
                return Err(err(
                    key,
                    format!("must be in [0, {max}] degrees, got {value}"),
                ));
            }
            Ok(value.to_radians())
        };
        let (shape, (positions, grid)) = match kind {
            LightKind::Point => (LightShape::Point, self.placed(i, l, None)?),
            LightKind::Spot => {
                let direction = direction("direction")?;
                require("cone_deg", l.cone_deg.is_some())?;
                let cone = angle("cone_deg", l.cone_deg.unwrap_or_default(), 90.0)?;
                if cone <= 0.0 {
                    return Err(err("cone_deg", "must be above 0 degrees".into()));
                }
                let falloff = angle("falloff_deg", l.falloff_deg.unwrap_or(0.0), 90.0)?;
                if falloff > cone {
                    return Err(err(
                        "falloff_deg",
                        format!(
                            "{} degrees is wider than the cone's {} degrees",
                            falloff.to_degrees(),
                            cone.to_degrees()
                        ),
                    ));
                }
                let shape = LightShape::Spot {
                    direction,
                    cone,
                    falloff,
                };
                (shape, self.placed(i, l, None)?)
            }
            LightKind::Directional => {
                let direction = direction("direction")?;
                let angle = angle("angle_deg", l.angle_deg.unwrap_or(0.0), 90.0)?;
                (
                    LightShape::Directional { direction, angle },
                    (vec![Vec3::ZERO], [1, 1, 1]),
                )
            }
            LightKind::Quad => {
                require("corners", l.corners.is_some())?;
                let mut c = [Vec3::ZERO; 4];
                for (k, corner) in l.corners.unwrap_or_default().iter().enumerate() {
                    c[k] = position3(&self.map, &field("corners"), *corner)?;
                }
                if let Some(problem) = quad_problem(&c) {
                    return Err(err("corners", problem));
                }
                let centre = (c[0] + c[1] + c[2] + c[3]) * 0.25;
                let shape = LightShape::Quad {
                    corners: c.map(|p| p - centre),
                };
                (shape, self.placed(i, l, Some(centre))?)
            }
        };
        Ok(Light {
            name: l.name.clone(),
            color,
            intensity: l.intensity,
            shape,
            positions,
            grid,
        })
    }

    /// Where light `i` (`l`) is: `position`, the path of `positions`, or a `grid` of points (x
    /// varying fastest); `fixed` where its shape sets it (a quad's centre). Returns the points
    /// and the grid's counts.
    fn placed(
        &self,
        i: usize,
        l: &LightFile,
        fixed: Option<Vec3>,
    ) -> Result<(Vec<Vec3>, [usize; 3])> {
        let field = |key: &str| format!("light[{i}].{key}");
        let err = |key: &str, message: String| self.map.error(&field(key), message);
        let kind = l.r#type;
        // Where a point or spot is: `position`, or the path of `positions`.
        let positions = || -> Result<Vec<Vec3>> {
            match (&l.positions, l.position, fixed) {
                (Some(_), Some(_), _) => Err(err(
                    "positions",
                    "give either `position` or `positions`, not both".into(),
                )),
                (Some(path), None, _) => {
                    if path.is_empty() {
                        return Err(err("positions", "must list at least one point".into()));
                    }
                    path.iter()
                        .enumerate()
                        .map(|(k, p)| position3(&self.map, &field(&format!("positions[{k}]")), *p))
                        .collect()
                }
                (None, Some(p), _) => Ok(vec![position3(&self.map, &field("position"), p)?]),
                (None, None, Some(p)) => Ok(vec![p]),
                (None, None, None) => Err(err(
                    "position",
                    format!("a {} light needs `position` (or `positions`)", kind.name()),
                )),
            }
        };
        let Some(g) = &l.grid else {
            let path = positions()?;
            let n = path.len();
            return Ok((path, [n, 1, 1]));
        };
        if l.position.is_some() || l.positions.is_some() {
            return Err(err(
                "grid",
                "give one of `position`, `positions` and `grid`".into(),
            ));
        }
        let from = position3(&self.map, &field("grid.from"), g.from)?;
        let to = position3(&self.map, &field("grid.to"), g.to)?;
        let counts = g.counts.map(|c| c as usize);
        let total = counts.iter().try_fold(1usize, |p, &c| p.checked_mul(c));
        if counts.contains(&0) || total.is_none_or(|t| t > MAX_LIGHT_COLUMNS) {
            return Err(err(
                "grid.counts",
                format!(
                    "{:?}: each count at least 1, at most {MAX_LIGHT_COLUMNS} points in all",
                    g.counts
                ),
            ));
        }
        let step = |a: usize| {
            if counts[a] > 1 {
                (to[a] - from[a]) / (counts[a] - 1) as f32
            } else {
                0.0
            }
        };
        let mut points = Vec::with_capacity(total.unwrap_or(0));
        for k in 0..counts[2] {
            for j in 0..counts[1] {
                for i in 0..counts[0] {
                    points.push(
                        from + Vec3::new(
                            i as f32 * step(0),
                            j as f32 * step(1),
                            k as f32 * step(2),
                        ),
                    );
                }
            }
        }
        Ok((points, counts))
    }
}
