//! The diffuse albedo of a textured material as one mip-mapped image: what a per-vertex bake of
//! a textured scene is drawn with. Such a bake stores irradiance at its vertices (the transport
//! of a white surface), and the raster multiplies it per pixel by the albedo read here, so the
//! texture's detail does not depend on the tessellation.
//!
//! A map is laid on the texel grid of the material's base-colour texture (its metallic-roughness
//! texture's when it has none) with that texture's sampler. Its texel `(x, y)` holds the material's
//! diffuse albedo at the texel's centre, `(1 − 0.04)(1 − m) b` ([`crate::scene::TexturedMaterial`]),
//! as linear sixteen-bit fractions (`q / 65535`), which keep the eight-bit textures' every level.
//! Each further level halves the sides (rounded down, at least 1) and holds the means of 2 × 2
//! texels of the level above (a missing row or column repeats the last), rounded again to
//! sixteen bits. Only the first level is stored in a transport file; the others follow from it.
//!
//! Sampling ([`AlbedoMap::sample`]) is written in f32 exactly as `shaders/raster.wgsl` writes it,
//! so the CPU and GPU rasters are twins: the level of detail is `log2 ρ` with `ρ` the longer of the
//! screen derivatives of the texture coordinate measured in level-0 texels (GPUs' isotropic
//! rule), magnification (`ρ ≤ 1`) reads level 0 with the sampler's filter, and minification
//! blends bilinear reads of the two levels around the level of detail (trilinear filtering).

use glam::{Vec2, Vec3};

use super::Scene;
use super::texture::{Filter, MAX_TEXTURE_SIDE, Wrap};

/// The value of one sixteen-bit step: a stored `q` is the albedo `q · UNORM`.
pub const UNORM: f32 = 1.0 / 65535.0;

/// Largest texel coordinate (times the level's size) a sample uses: farther out, f32 has no
/// fractional bits left, and the index must fit an `i32` in the shader.
const COORD_LIMIT: f32 = 1_073_741_824.0;

/// One level of a map.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major linear RGB albedo as sixteen-bit fractions, top row first.
    pub texels: Vec<[u16; 3]>,
}

/// A material's diffuse albedo over its texture coordinates, with its mip levels.
#[derive(Clone, Debug, PartialEq)]
pub struct AlbedoMap {
    /// Indices into [`Scene::materials`] of the materials it belongs to: several when their
    /// maps are the same (as for materials that share a texture), which is stored once.
    pub materials: Vec<u32>,
    /// Wrap along u and along v.
    pub wrap: [Wrap; 2],
    /// The magnification filter.
    pub filter: Filter,
    /// Level 0 (the texture's size) first, down to 1 × 1.
    pub levels: Vec<Level>,
}

/// A sixteen-bit fraction of a value in [0, 1] (clamped), rounded to nearest.
fn quantise(v: f32) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

impl AlbedoMap {
    /// The map of material `material` of `scene`, or `None` when the material reads no texture.
    pub fn of_material(scene: &Scene, material: u32) -> Option<AlbedoMap> {
        let maps = scene
            .material_maps
            .get(material as usize)
            .copied()
            .flatten()?;
        let grid = maps
            .base_color_texture
            .or(maps.metallic_roughness_texture)
            .and_then(|i| scene.textures.get(i as usize))?;
        let (w, h) = (grid.width, grid.height);
        let texels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
                scene.lobes_at(material, uv).albedo.to_array().map(quantise)
            })
            .collect();
        AlbedoMap::from_level0(vec![material], grid.wrap, grid.filter, w, h, texels)
    }

    /// A map from its first level, with the other levels made from it; `None` when a side is 0
    /// or above [`MAX_TEXTURE_SIDE`], or the texels do not fill it.
    pub fn from_level0(
        materials: Vec<u32>,
        wrap: [Wrap; 2],
        filter: Filter,
        width: u32,
        height: u32,
        texels: Vec<[u16; 3]>,
    ) -> Option<AlbedoMap> {
        let side = 1..=MAX_TEXTURE_SIDE;
        if !side.contains(&width)
            || !side.contains(&height)
            || texels.len() != width as usize * height as usize
        {
            return None;
        }
        let mut levels = vec![Level {
            width,
            height,
            texels,
        }];
        while let Some(last) = levels.last().filter(|l| l.width.max(l.height) > 1) {
            levels.push(last.halved());
        }
        Some(AlbedoMap {
            materials,
            wrap,
            filter,
            levels,
        })
    }

    /// Whether `other` holds the same albedo, sampled the same way (whatever its materials).
    pub fn same_image(&self, other: &AlbedoMap) -> bool {
        self.wrap == other.wrap && self.filter == other.filter && self.levels[0] == other.levels[0]
    }

    /// Texels of all levels together.
    pub fn texel_count(&self) -> usize {
        self.levels.iter().map(|l| l.texels.len()).sum()
    }

    /// The level of detail for screen derivatives `dx` and `dy` of the texture coordinate:
    /// `log2 ρ` with `ρ` the longer of the two in level-0 texels, 0 when `ρ ≤ 1` (or is not a
    /// number), at most the last level.
    pub fn lod(&self, dx: Vec2, dy: Vec2) -> f32 {
        let size = Vec2::new(self.levels[0].width as f32, self.levels[0].height as f32);
        let rho = (dx * size).length().max((dy * size).length());
        let lod = if rho > 1.0 { rho.log2() } else { 0.0 };
        lod.min((self.levels.len() - 1) as f32)
    }

    /// The albedo at texture coordinate `uv` and level of detail `lod` (from [`AlbedoMap::lod`]).
    pub fn sample(&self, uv: Vec2, lod: f32) -> Vec3 {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        if lod <= 0.0 {
            return self.read(0, uv, self.filter);
        }
        let first = lod.floor();
        let blend = lod - first;
        let k = first as usize;
        let next = (k + 1).min(self.levels.len() - 1);
        let a = self.read(k, uv, Filter::Linear);
        let b = self.read(next, uv, Filter::Linear);
        a + (b - a) * blend
    }

    /// Level `k` read at `uv` with `filter`.
    fn read(&self, k: usize, uv: Vec2, filter: Filter) -> Vec3 {
        let l = &self.levels[k];
        let (w, h) = (l.width as f32, l.height as f32);
        let x = (uv.x * w).clamp(-COORD_LIMIT, COORD_LIMIT);
        let y = (uv.y * h).clamp(-COORD_LIMIT, COORD_LIMIT);
        let fetch = |i: f32, j: f32| {
            let xi = wrap(self.wrap[0], i as i32, l.width as i32);
            let yi = wrap(self.wrap[1], j as i32, l.height as i32);
            let t = l.texels[yi as usize * l.width as usize + xi as usize];
            Vec3::new(t[0] as f32, t[1] as f32, t[2] as f32) * UNORM
        };
        match filter {
            Filter::Nearest => fetch(x.floor(), y.floor()),
            Filter::Linear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let top = fetch(x0, y0).lerp(fetch(x0 + 1.0, y0), fx);
                let bottom = fetch(x0, y0 + 1.0).lerp(fetch(x0 + 1.0, y0 + 1.0), fx);
                top.lerp(bottom, fy)
            }
        }
    }
}

impl Level {
    /// The next level: sides halved (at least 1), each texel the mean of a 2 × 2 block.
    fn halved(&self) -> Level {
        let (w, h) = ((self.width / 2).max(1), (self.height / 2).max(1));
        let at = |x: u32, y: u32| {
            let t = self.texels[y.min(self.height - 1) as usize * self.width as usize
                + x.min(self.width - 1) as usize];
            Vec3::new(t[0] as f32, t[1] as f32, t[2] as f32)
        };
        let texels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let sum = at(2 * x, 2 * y)
                    + at(2 * x + 1, 2 * y)
                    + at(2 * x, 2 * y + 1)
                    + at(2 * x + 1, 2 * y + 1);
                (sum * 0.25 * UNORM).to_array().map(quantise)
            })
            .collect();
        Level {
            width: w,
            height: h,
            texels,
        }
    }
}

/// The index that integer texel index `i` of a row of `n` reads, as the shader computes it.
fn wrap(mode: Wrap, i: i32, n: i32) -> i32 {
    match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::MirroredRepeat => {
            let k = i.rem_euclid(2 * n);
            if k < n { k } else { 2 * n - 1 - k }
        }
        Wrap::ClampToEdge => i.clamp(0, n - 1),
    }
}

/// A wrap mode as the shader and the file number it: repeat 0, mirrored repeat 1, clamp 2.
pub fn wrap_code(mode: Wrap) -> u32 {
    match mode {
        Wrap::Repeat => 0,
        Wrap::MirroredRepeat => 1,
        Wrap::ClampToEdge => 2,
    }
}

/// The wrap mode of [`wrap_code`]'s number.
pub fn wrap_of_code(code: u32) -> Option<Wrap> {
    [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge]
        .get(code as usize)
        .copied()
}

/// Albedo maps as a file's tensors: see [`to_table`].
pub type FileTables = (Vec<[u32; 5]>, Vec<[u32; 2]>, Vec<[u16; 3]>);

/// Maps as a file stores them: per map its level-0 width and height, wrap codes along u and v
/// ([`wrap_code`]) and filter (0 linear, 1 nearest); per material that has one, the material and
/// its map's index; and the level-0 texels of every map in turn.
pub fn to_table(maps: &[AlbedoMap]) -> FileTables {
    let table = maps
        .iter()
        .map(|a| {
            [
                a.levels[0].width,
                a.levels[0].height,
                wrap_code(a.wrap[0]),
                wrap_code(a.wrap[1]),
                (a.filter == Filter::Nearest) as u32,
            ]
        })
        .collect();
    let materials = maps
        .iter()
        .enumerate()
        .flat_map(|(i, a)| a.materials.iter().map(move |&m| [m, i as u32]))
        .collect();
    let texels = maps
        .iter()
        .flat_map(|a| a.levels[0].texels.iter().copied())
        .collect();
    (table, materials, texels)
}

/// The maps of [`to_table`]'s tables (as a file holds them): every size, code and index checked
/// before any slice.
pub fn from_table(
    table: &[[u32; 5]],
    materials: &[[u32; 2]],
    texels: Vec<[u16; 3]>,
) -> std::result::Result<Vec<AlbedoMap>, String> {
    let mut owners: Vec<Vec<u32>> = vec![Vec::new(); table.len()];
    for (k, &[material, map]) in materials.iter().enumerate() {
        owners
            .get_mut(map as usize)
            .ok_or_else(|| format!("albedo_map_material[{k}]: map {map} of {}", table.len()))?
            .push(material);
    }
    let mut maps = Vec::with_capacity(table.len());
    let mut start = 0usize;
    for (i, (&[width, height, wrap_u, wrap_v, nearest], owners)) in
        table.iter().zip(owners).enumerate()
    {
        let bad = |what: String| format!("albedo_map[{i}]: {what}");
        if owners.is_empty() {
            return Err(bad("no material has it".into()));
        }
        let side = 1..=MAX_TEXTURE_SIDE;
        if !side.contains(&width) || !side.contains(&height) {
            return Err(bad(format!(
                "size {width} x {height}, outside 1 to {MAX_TEXTURE_SIDE} a side"
            )));
        }
        let n = width as usize * height as usize;
        let end = start
            .checked_add(n)
            .filter(|&e| e <= texels.len())
            .ok_or_else(|| bad(format!("{n} texels past the {} stored", texels.len())))?;
        let (Some(wu), Some(wv)) = (wrap_of_code(wrap_u), wrap_of_code(wrap_v)) else {
            return Err(bad(format!("wrap codes {wrap_u}, {wrap_v} (0 to 2)")));
        };
        let filter = match nearest {
            0 => Filter::Linear,
            1 => Filter::Nearest,
            f => return Err(bad(format!("filter code {f} (0 or 1)"))),
        };
        let map = AlbedoMap::from_level0(
            owners,
            [wu, wv],
            filter,
            width,
            height,
            texels[start..end].to_vec(),
        )
        .ok_or_else(|| bad("a size that does not fit its texels".into()))?;
        maps.push(map);
        start = end;
    }
    if start != texels.len() {
        return Err(format!(
            "albedo_texel holds {} texels, the maps {start}",
            texels.len()
        ));
    }
    Ok(maps)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 x 2 map whose texel (x, y) is (x / 3, y, 0.5) in sixteen-bit steps.
    fn ramp(wrap: Wrap, filter: Filter) -> AlbedoMap {
        let texels = (0..2)
            .flat_map(|y| (0..4).map(move |x| (x, y)))
            .map(|(x, y)| [x as u16 * 21845, y as u16 * 65535, 32768])
            .collect();
        AlbedoMap::from_level0(vec![3], [wrap; 2], filter, 4, 2, texels).unwrap()
    }

    #[test]
    fn levels_halve_to_one_texel_and_keep_the_mean() {
        let m = ramp(Wrap::Repeat, Filter::Linear);
        let sizes: Vec<(u32, u32)> = m.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(4, 2), (2, 1), (1, 1)]);
        // The last level is the mean of all: x/3 averages to 0.5, y to 0.5.
        let last = m.levels[2].texels[0];
        assert_eq!(last, [32768, 32768, 32768]);
        assert_eq!(m.texel_count(), 8 + 2 + 1);
        assert!(
            AlbedoMap::from_level0(vec![0], [Wrap::Repeat; 2], Filter::Linear, 3, 2, vec![])
                .is_none()
        );
        assert!(
            AlbedoMap::from_level0(vec![0], [Wrap::Repeat; 2], Filter::Linear, 0, 0, vec![])
                .is_none()
        );
    }

    #[test]
    fn magnified_samples_read_texel_centres_and_wrap() {
        let m = ramp(Wrap::Repeat, Filter::Linear);
        // Texel centres read the texel; halfway between two texels the mean.
        let at = |u: f32, v: f32| m.sample(Vec2::new(u, v), 0.0);
        assert!((at(0.375, 0.25) - Vec3::new(1.0 / 3.0, 0.0, 32768.0 * UNORM)).length() < 1e-6);
        assert!((at(0.5, 0.25).x - 0.5).abs() < 1e-6);
        // Repeat: the left edge blends the last column with the first.
        assert!((at(0.0, 0.25).x - 0.5).abs() < 1e-6);
        let clamped = ramp(Wrap::ClampToEdge, Filter::Linear);
        assert!(clamped.sample(Vec2::new(-3.0, 0.25), 0.0).x.abs() < 1e-6);
        let mirrored = ramp(Wrap::MirroredRepeat, Filter::Nearest);
        // Texel column 4 mirrors to 3, column -1 to 0.
        assert!((mirrored.sample(Vec2::new(1.1, 0.25), 0.0).x - 1.0).abs() < 1e-6);
        assert!(mirrored.sample(Vec2::new(-0.1, 0.25), 0.0).x.abs() < 1e-6);
        assert_eq!(at(f32::NAN, 0.0), at(0.0, 0.0));
    }

    #[test]
    fn the_level_of_detail_follows_the_footprint() {
        let m = ramp(Wrap::Repeat, Filter::Linear);
        // A pixel one texel wide is magnification; four texels wide is level 2 (the last).
        assert_eq!(m.lod(Vec2::new(0.25, 0.0), Vec2::ZERO), 0.0);
        assert!((m.lod(Vec2::new(0.5, 0.0), Vec2::ZERO) - 1.0).abs() < 1e-6);
        assert_eq!(m.lod(Vec2::new(100.0, 0.0), Vec2::ZERO), 2.0);
        assert_eq!(m.lod(Vec2::splat(f32::NAN), Vec2::ZERO), 0.0);
        // Halfway between levels 1 and 2 the two blend: level 1 is (1/6 .. 5/6, 0.5), level 2
        // is 0.5 everywhere.
        let uv = Vec2::new(0.25, 0.5);
        let one = m.sample(uv, 1.0);
        let two = m.sample(uv, 2.0);
        assert!((m.sample(uv, 1.5) - (one + two) * 0.5).length() < 1e-6);
        assert!((two - Vec3::splat(0.5)).length() < 1e-4);
    }

    #[test]
    fn wrap_codes_round_trip() {
        for w in [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge] {
            assert_eq!(wrap_of_code(wrap_code(w)), Some(w));
        }
        assert_eq!(wrap_of_code(3), None);
    }
}
