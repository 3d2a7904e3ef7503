//! The scene file's `[medium]` table: its kinds, the keys each takes, and the checks that turn
//! it into a medium's spec.

use super::numbers::{finite3, points, position3, some_numbers};
use super::*;

#[derive(Deserialize, Clone, Copy, PartialEq, Debug)]
#[serde(rename_all = "lowercase")]
pub(super) enum MediumKind {
    Ellipsoid,
    Cloud,
    Grid,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MediumFile {
    r#type: MediumKind,
    #[serde(deserialize_with = "points")]
    bounds: [[f32; 3]; 2],
    resolution: Option<usize>,
    extinction: f32,
    #[serde(default, deserialize_with = "some_numbers")]
    albedo: Option<[f32; 3]>,
    g: Option<f32>,
    #[serde(default, deserialize_with = "some_numbers")]
    center: Option<[f32; 3]>,
    #[serde(default, deserialize_with = "some_numbers")]
    radii: Option<[f32; 3]>,
    falloff: Option<f32>,
    seed: Option<u64>,
    frequency: Option<f32>,
    octaves: Option<u32>,
    coverage: Option<f32>,
    path: Option<String>,
}

impl Loader<'_> {
    /// The scene's medium from its `[medium]` table, every key checked.
    pub(super) fn medium(&mut self, m: &MediumFile) -> Result<MediumSpec> {
        let field = |key: &str| format!("medium.{key}");
        let min = position3(&self.map, "medium.bounds", m.bounds[0])?;
        let max = position3(&self.map, "medium.bounds", m.bounds[1])?;
        if !min.cmplt(max).all() {
            return Err(self.map.error(
                "medium.bounds",
                format!("[min, max] needs min < max on every axis, got {min} and {max}"),
            ));
        }
        let resolution = m.resolution.unwrap_or(DEFAULT_MEDIUM_RESOLUTION);
        if !(1..=512).contains(&resolution) {
            return Err(self.map.error(
                &field("resolution"),
                format!("must be 1 to 512 voxels, got {resolution}"),
            ));
        }
        if !(m.extinction.is_finite() && m.extinction >= 0.0) {
            return Err(self.map.error(
                &field("extinction"),
                format!("must be finite and >= 0, got {}", m.extinction),
            ));
        }
        let albedo = finite3(&self.map, &field("albedo"), m.albedo.unwrap_or([0.95; 3]))?;
        if !(albedo.cmpge(Vec3::ZERO).all() && albedo.cmple(Vec3::ONE).all()) {
            return Err(self.map.error(
                &field("albedo"),
                format!("each channel must be in [0, 1], got {albedo}"),
            ));
        }
        let g = m.g.unwrap_or(0.0);
        if !(g.is_finite() && g.abs() < 1.0) {
            return Err(self
                .map
                .error(&field("g"), format!("must be in (-1, 1), got {g}")));
        }
        let present = [
            ("center", m.center.is_some()),
            ("radii", m.radii.is_some()),
            ("falloff", m.falloff.is_some()),
            ("seed", m.seed.is_some()),
            ("frequency", m.frequency.is_some()),
            ("octaves", m.octaves.is_some()),
            ("coverage", m.coverage.is_some()),
            ("path", m.path.is_some()),
        ];
        let (kind, allowed): (&str, &[&str]) = match m.r#type {
            MediumKind::Ellipsoid => ("ellipsoid", &["center", "radii", "falloff"]),
            MediumKind::Cloud => (
                "cloud",
                &[
                    "center",
                    "radii",
                    "seed",
                    "frequency",
                    "octaves",
                    "coverage",
                ],
            ),
            MediumKind::Grid => ("grid", &["path"]),
        };
        if m.r#type == MediumKind::Grid && m.resolution.is_some() {
            return Err(self.map.error(
                "medium.resolution",
                "a grid medium has its file's resolution (`prt volume bake --grid N` resamples it)",
            ));
        }
        for (key, set) in present {
            if set && !allowed.contains(&key) {
                return Err(self.map.error(
                    &field(key),
                    format!("`{key}` does not apply to a {kind} medium"),
                ));
            }
        }
        let center = position3(
            &self.map,
            &field("center"),
            m.center.unwrap_or(((min + max) * 0.5).to_array()),
        )?;
        let radii = position3(
            &self.map,
            &field("radii"),
            m.radii.unwrap_or(((max - min) * 0.5).to_array()),
        )?;
        if !radii.cmpgt(Vec3::ZERO).all() {
            return Err(self
                .map
                .error(&field("radii"), format!("must be > 0, got {radii}")));
        }
        let source = self.medium_source(m, [min, max], [center, radii])?;
        let (densest, edge) = match &source {
            MediumSource::Grid(g) => (g.densest(), g.cell().min_element()),
            // Procedural densities are at most 1.
            MediumSource::Procedural(_) => (1.0, crate::medium::voxel_edge(max - min, resolution)),
        };
        if let Some(problem) = crate::medium::voxel_depth_problem(m.extinction, densest, edge) {
            return Err(self.map.error(&field("extinction"), problem));
        }
        Ok(MediumSpec {
            source,
            min,
            max,
            resolution,
            extinction: m.extinction,
            albedo,
            g,
        })
    }

    /// The density of a `[medium]` table within `[min, max]`: an ellipsoid or a cloud about
    /// `center` with `radii`, or a grid read from its file.
    fn medium_source(
        &mut self,
        m: &MediumFile,
        [min, max]: [Vec3; 2],
        [center, radii]: [Vec3; 2],
    ) -> Result<MediumSource> {
        let field = |key: &str| format!("medium.{key}");
        Ok(match m.r#type {
            MediumKind::Ellipsoid => {
                let falloff = m.falloff.unwrap_or(0.3);
                if !(0.0..1.0).contains(&falloff) {
                    return Err(self.map.error(
                        &field("falloff"),
                        format!("must be in [0, 1), got {falloff}"),
                    ));
                }
                MediumSource::Procedural(DensitySource::Ellipsoid {
                    center,
                    radii,
                    falloff,
                })
            }
            MediumKind::Cloud => {
                let frequency = m.frequency.unwrap_or(3.0);
                let coverage = m.coverage.unwrap_or(0.6);
                let octaves = m.octaves.unwrap_or(4);
                if !(frequency.is_finite() && frequency > 0.0) {
                    return Err(self
                        .map
                        .error(&field("frequency"), format!("must be > 0, got {frequency}")));
                }
                if !(coverage > 0.0 && coverage <= 1.0) {
                    return Err(self.map.error(
                        &field("coverage"),
                        format!("must be in (0, 1], got {coverage}"),
                    ));
                }
                if !(1..=8).contains(&octaves) {
                    return Err(self
                        .map
                        .error(&field("octaves"), format!("must be 1 to 8, got {octaves}")));
                }
                MediumSource::Procedural(DensitySource::Cloud {
                    center,
                    radii,
                    seed: m.seed.unwrap_or(1),
                    frequency,
                    octaves,
                    coverage,
                })
            }
            MediumKind::Grid => {
                let rel = m.path.as_deref().ok_or_else(|| {
                    self.map
                        .error("medium.path", "a grid medium needs `path` (a .npy file)")
                })?;
                let path = self.base_dir.join(rel);
                let bytes = crate::files::read_regular(
                    &path,
                    crate::medium::MAX_NPY_BYTES,
                    "NumPy .npy grid",
                )
                .map_err(|e| self.map.error("medium.path", e.to_string()))?;
                let grid = crate::medium::parse_npy(&bytes, &path, min, max)
                    .map_err(|e| self.map.error("medium.path", e.to_string()))?;
                self.hasher.write_chunk(&bytes);
                self.inputs.push(path);
                MediumSource::Grid(grid)
            }
        })
    }
}
