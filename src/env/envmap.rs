//! Lat-long environment maps: loading (OpenEXR through `exr`, Radiance `.hdr` through `image`),
//! validation, a procedural sun-and-sky, rotation, resampling to a cube map and SH projection.
//! Directions and solid angles follow [`crate::conventions`].
//!
//! Bad pixels: NaN or infinite radiance is an error naming the file and the first bad pixel;
//! negative radiance (lossy compression leaves a little) is clamped to 0 and counted in
//! [`EnvMap::negatives_clamped`] so the caller can warn.

use std::f64::consts::PI;
use std::path::Path;

use glam::DVec3;

use crate::error::{PrtError, Result};
use crate::files::{Bundled, bundled};
use crate::math::cubemap::{CubeMap, LatLong, resample_latlong_exact};
use crate::output::film::read_exr;

pub use super::latlong::{EnvRotation, latlong_dir, latlong_uv, pixel_solid_angle};

/// Largest accepted lat-long map, 16384 x 8192 (the largest published HDRIs; 1.5 GiB as f32
/// RGB), checked from the header before any pixel is allocated.
pub const MAX_ENV_PIXELS: usize = 16384 * 8192;
/// Longest accepted side of a lat-long map.
pub const MAX_ENV_SIDE: usize = 16384;

/// A lat-long map's size: at least 1 x 1, sides at most [`MAX_ENV_SIDE`] and at most
/// [`MAX_ENV_PIXELS`] in all.
pub fn check_env_size(path: &Path, w: usize, h: usize) -> Result<()> {
    if w == 0
        || h == 0
        || w > MAX_ENV_SIDE
        || h > MAX_ENV_SIDE
        || w.saturating_mul(h) > MAX_ENV_PIXELS
    {
        return Err(PrtError::file(
            path,
            format!(
                "map size {w} x {h}: an environment map has sides of 1 to {MAX_ENV_SIDE} pixels \
                 and at most 16384 x 8192 pixels in all"
            ),
        ));
    }
    Ok(())
}
/// Largest accepted image file: the largest map in uncompressed 32-bit RGBA, and its header.
pub const MAX_ENV_BYTES: u64 = crate::output::film::MAX_IMAGE_BYTES;

/// A lat-long radiance map, rows from the zenith down.
#[derive(Clone, Debug)]
pub struct EnvMap {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Linear RGB radiance, row-major.
    pub pixels: Vec<[f32; 3]>,
    /// Where the map came from (a file path or a procedural description), for messages.
    pub source: String,
    /// Number of negative samples that were clamped to zero on load.
    pub negatives_clamped: usize,
    /// The most negative of them (0 when there were none).
    pub lowest_negative: f32,
    /// What the clamped samples held: Σ |L| Ω over the negative samples, all channels (0 when
    /// there were none); [`EnvMap::negative_share`] sets it against the whole map.
    pub negative_power: f64,
}

/// An environment as a user names it: a lat-long file, or the procedural sun and sky.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvSpec {
    /// A lat-long EXR or HDR file.
    File(std::path::PathBuf),
    /// The procedural sun and sky ([`SunSky`]), rendered at 1024 x 512.
    Sun(SunSpec),
}

impl EnvSpec {
    /// `sun:ELEV,AZIM[,RADIUS]` (an error naming the spec when its numbers are wrong), else a
    /// file path.
    pub fn parse(spec: &str) -> Result<EnvSpec> {
        match SunSpec::parse(spec) {
            None => Ok(EnvSpec::File(spec.into())),
            Some(sun) => Ok(EnvSpec::Sun(sun?)),
        }
    }

    /// The map: the file loaded (a bare name that is no file, such as `blender_sunrise`, names
    /// a bundled map; see [`bundled_map`]), or the sun and sky rendered.
    pub fn load(&self) -> Result<EnvMap> {
        match self {
            EnvSpec::File(path) => match bundled_map(path) {
                Some(map) => EnvMap::bundled(map),
                None => EnvMap::load(path).map_err(|e| match std::fs::symlink_metadata(path) {
                    Err(m) if m.kind() == std::io::ErrorKind::NotFound => PrtError::file(
                        path,
                        format!(
                            "no such file, nor a map bundled in the binary, which any --env \
                             takes by name: {} (`prt env --list`)",
                            bundled_names()
                        ),
                    ),
                    _ => e,
                }),
            },
            EnvSpec::Sun(sun) => {
                Ok(SunSky::new(sun.elevation, sun.azimuth, sun.radius, 3.0)
                    .to_latlong(1024, 512, 4))
            }
        }
    }
}

/// The environment maps bundled into the binary (`assets/envmaps`), which every `--env` takes by
/// name ([`crate::files::Bundled::stem`]) from any folder, and which the demo also writes out.
pub const BUNDLED_MAPS: &[Bundled] = &[
    bundled!("envmaps/blender_sunrise.exr"),
    bundled!("envmaps/blender_city.exr"),
    bundled!("envmaps/blender_interior.exr"),
    bundled!("envmaps/blender_night.exr"),
    bundled!("envmaps/blender_studio.exr"),
    bundled!("envmaps/pmndrs_city_overcast.exr"),
];

/// The names of the bundled maps, comma-separated.
pub fn bundled_names() -> String {
    let names: Vec<&str> = BUNDLED_MAPS.iter().map(|m| m.stem()).collect();
    names.join(", ")
}

/// The bundled map a file spec names when no file of that name exists: a bare name, with or
/// without `.exr` (`blender_sunrise`, `blender_sunrise.exr`). An existing file, or a path with a
/// folder in it, is always the file.
pub fn bundled_map(path: &Path) -> Option<&'static Bundled> {
    if path.components().count() != 1 || std::fs::symlink_metadata(path).is_ok() {
        return None;
    }
    let name = path.to_str()?;
    let stem = name.strip_suffix(".exr").unwrap_or(name);
    BUNDLED_MAPS.iter().find(|m| m.stem() == stem)
}

impl EnvMap {
    /// The bundled map `map`, read from the bytes in the binary; its source names it as bundled.
    pub fn bundled(map: &Bundled) -> Result<EnvMap> {
        let source = format!("{} (bundled)", map.stem());
        let (w, h, pixels) = crate::output::film::read_exr_from(
            std::io::Cursor::new(map.bytes),
            Path::new(&source),
            check_env_size,
        )?;
        EnvMap::from_pixels(w, h, pixels, &source)
    }
}

/// A procedural sun given as `sun:ELEV,AZIM[,RADIUS]` (degrees; the radius defaults to 2): the one
/// parser of that spec, for the command line and the viewer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunSpec {
    /// Elevation of the sun above the horizon, degrees in [-90, 90].
    pub elevation: f64,
    /// Azimuth of the sun, degrees (0 towards −Z, 90 towards +X).
    pub azimuth: f64,
    /// Angular radius of the sun disc, degrees in [0.05, 45].
    pub radius: f64,
}

impl SunSpec {
    /// Radius when the spec gives none, degrees.
    pub const DEFAULT_RADIUS: f64 = 2.0;

    /// `None` when `spec` is not a sun (a file path); else the sun, or an error naming the spec
    /// when its numbers are missing, not numbers, or out of range (elevation in [-90, 90],
    /// radius in [0.05, 45], azimuth finite).
    pub fn parse(spec: &str) -> Option<Result<SunSpec>> {
        let args = spec.strip_prefix("sun:")?;
        let bad = |why: &str| PrtError::invalid("environment", format!("`{spec}`: {why}"));
        let nums: std::result::Result<Vec<f64>, _> =
            args.split(',').map(|v| v.trim().parse::<f64>()).collect();
        let sun = match nums.as_deref() {
            Ok(&[elevation, azimuth]) => SunSpec {
                elevation,
                azimuth,
                radius: Self::DEFAULT_RADIUS,
            },
            Ok(&[elevation, azimuth, radius]) => SunSpec {
                elevation,
                azimuth,
                radius,
            },
            _ => return Some(Err(bad("expected sun:ELEV,AZIM[,RADIUS]"))),
        };
        if !(-90.0..=90.0).contains(&sun.elevation)
            || !(0.05..=45.0).contains(&sun.radius)
            || !sun.azimuth.is_finite()
        {
            return Some(Err(bad(
                "elevation must be in [-90, 90] and radius in [0.05, 45] degrees",
            )));
        }
        Some(Ok(sun))
    }
}

impl EnvMap {
    /// A map of constant radiance.
    pub fn constant(width: usize, height: usize, value: [f32; 3]) -> Self {
        EnvMap {
            width,
            height,
            pixels: vec![value; width * height],
            source: format!("constant {value:?}"),
            negatives_clamped: 0,
            lowest_negative: 0.0,
            negative_power: 0.0,
        }
    }

    /// Loads an `.exr` or `.hdr` lat-long map. The file type is taken from the content's magic
    /// number, so a misnamed file gets a clear message.
    pub fn load(path: &Path) -> Result<Self> {
        let mut magic = [0u8; 4];
        {
            use std::io::Read;
            let (mut f, _) = crate::files::open_regular(path, MAX_ENV_BYTES, "environment map")?;
            let got = f.read(&mut magic).map_err(|e| PrtError::io(path, e))?;
            if got < 4 {
                return Err(PrtError::file(path, "too short to be an EXR or HDR image"));
            }
        }
        let (width, height, raw) = if magic == [0x76, 0x2f, 0x31, 0x01] {
            read_exr(path, check_env_size)?
        } else if magic.starts_with(b"#?") {
            read_hdr(path)?
        } else {
            return Err(PrtError::file(
                path,
                "not an OpenEXR or Radiance HDR image (unknown magic number)",
            ));
        };
        let map = Self::from_pixels(width, height, raw, &path.display().to_string())?;
        // The power of the pixels as read: what clamping kept, less what it took.
        let total = map.power().iter().sum::<f64>() - map.negative_power;
        if total.is_nan() || total <= 0.0 {
            return Err(PrtError::file(
                path,
                format!(
                    "the map's power (Σ L Ω over its pixels, negative samples included) is \
                     {total:.4e}: it lights nothing; {} of its {} samples are negative, the \
                     lowest {:.4e}",
                    map.negatives_clamped,
                    3 * width * height,
                    map.lowest_negative
                ),
            ));
        }
        Ok(map)
    }

    /// Opens an environment given on the command line: a file path, or `sun:ELEV,AZIM[,RADIUS]`
    /// for a procedural [`SunSky`] (degrees; radius defaults to 2) rendered at 1024 x 512.
    pub fn from_spec(spec: &str) -> Result<Self> {
        EnvSpec::parse(spec)?.load()
    }

    /// Builds a map from raw pixels, applying the bad-pixel policy of this module.
    pub fn from_pixels(
        width: usize,
        height: usize,
        mut pixels: Vec<[f32; 3]>,
        source: &str,
    ) -> Result<Self> {
        if width == 0 || height == 0 || pixels.len() != width * height {
            return Err(PrtError::file(
                source,
                format!("{width} x {height} image with {} pixels", pixels.len()),
            ));
        }
        let mut negatives = 0;
        let mut lowest = 0.0f32;
        let mut negative_power = 0.0f64;
        let omega: Vec<f64> = (0..height)
            .map(|y| pixel_solid_angle(width, height, y))
            .collect();
        for (i, p) in pixels.iter_mut().enumerate() {
            let w = omega[i / width];
            for (c, v) in p.iter_mut().enumerate() {
                if !v.is_finite() {
                    return Err(PrtError::file(
                        source,
                        format!(
                            "pixel (x = {}, y = {}) channel {} is {v}: radiance must be finite",
                            i % width,
                            i / width,
                            ["R", "G", "B"][c]
                        ),
                    ));
                }
                if *v < 0.0 {
                    negative_power += -*v as f64 * w;
                    lowest = lowest.min(*v);
                    *v = 0.0;
                    negatives += 1;
                }
            }
        }
        Ok(EnvMap {
            width,
            height,
            pixels,
            source: source.to_string(),
            negatives_clamped: negatives,
            lowest_negative: lowest,
            negative_power,
        })
    }

    /// The share of the map's power Σ |L| Ω, as read, that its negative samples held (0 when
    /// there were none). Lossy encoders leave a few thousandths of a percent.
    pub fn negative_share(&self) -> f64 {
        if self.negative_power == 0.0 {
            return 0.0;
        }
        self.negative_power / (self.power().iter().sum::<f64>() + self.negative_power)
    }

    /// Radiance seen along the unit map direction `d`: bilinear between pixel centres, wrapping
    /// around in longitude and clamped at the poles.
    pub fn radiance_at(&self, d: DVec3) -> [f32; 3] {
        let (u, v) = latlong_uv(d);
        let x = u * self.width as f64 - 0.5;
        let y = (v * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let w = self.width as i64;
        let col = |i: i64| (i.rem_euclid(w)) as usize;
        let (xa, xb) = (col(x0 as i64), col(x0 as i64 + 1));
        let ya = y0 as usize;
        let yb = (ya + 1).min(self.height - 1);
        let p = |x: usize, y: usize| self.pixels[y * self.width + x];
        let (a, b, c, e) = (p(xa, ya), p(xb, ya), p(xa, yb), p(xb, yb));
        std::array::from_fn(|k| {
            let top = a[k] + (b[k] - a[k]) * fx;
            let bottom = c[k] + (e[k] - c[k]) * fx;
            top + (bottom - top) * fy
        })
    }

    /// Radiant power per channel, Σ L · Ω over pixels (exact pixel solid angles).
    pub fn power(&self) -> [f64; 3] {
        let mut p = [0.0f64; 3];
        for y in 0..self.height {
            let w = pixel_solid_angle(self.width, self.height, y);
            for l in &self.pixels[y * self.width..(y + 1) * self.width] {
                for c in 0..3 {
                    p[c] += l[c] as f64 * w;
                }
            }
        }
        p
    }

    /// Its pixels as the resamplers take them, which check that they fit its size.
    pub fn latlong(&self) -> LatLong<'_> {
        LatLong {
            width: self.width,
            height: self.height,
            pixels: &self.pixels,
        }
    }

    /// The cube map of texel-average radiance at face size `n`, environment turned by `rotation`.
    /// Takes the fast path of [`crate::env::resample`]: the split of cells over texels is cached per
    /// (map size, N, pitch) and the yaw shifts the map, so turning and switching maps is cheap.
    pub fn to_cube(&self, n: usize, rotation: EnvRotation) -> Result<CubeMap> {
        crate::env::resample::resample_latlong(self.latlong(), n, rotation)
    }

    /// [`EnvMap::to_cube`] by the direct exact splat, cell by cell under the full rotation: the
    /// slow twin, for tests and comparisons.
    pub fn to_cube_exact(&self, n: usize, rotation: EnvRotation) -> Result<CubeMap> {
        resample_latlong_exact(self.latlong(), n, rotation.world_from_map())
    }

    /// SH coefficients of order `order` (n² RGB triples), `L_i = Σ L(pixel) Y_i(d) Ω(pixel)` with the
    /// pixel-centre direction and exact pixel solid angle.
    pub fn project_sh(&self, order: usize, rotation: EnvRotation) -> Result<Vec<[f64; 3]>> {
        crate::math::sh::check_order(order)?;
        let m = rotation.world_from_map();
        let count = order * order;
        use rayon::prelude::*;
        let coeffs = (0..self.height)
            .into_par_iter()
            .fold(
                || (vec![[0.0f64; 3]; count], vec![0.0f64; count]),
                |(mut acc, mut y_buf), y| {
                    let w = pixel_solid_angle(self.width, self.height, y);
                    let v = (y as f64 + 0.5) / self.height as f64;
                    for x in 0..self.width {
                        let l = self.pixels[y * self.width + x];
                        if l == [0.0; 3] {
                            continue;
                        }
                        let u = (x as f64 + 0.5) / self.width as f64;
                        crate::math::sh::eval(order, m * latlong_dir(u, v), &mut y_buf);
                        for (a, yi) in acc.iter_mut().zip(&y_buf) {
                            for c in 0..3 {
                                a[c] += l[c] as f64 * yi * w;
                            }
                        }
                    }
                    (acc, y_buf)
                },
            )
            .map(|(acc, _)| acc)
            .reduce(|| vec![[0.0f64; 3]; count], crate::math::sh::add_rgb);
        Ok(coeffs)
    }
}

fn read_hdr(path: &Path) -> Result<(usize, usize, Vec<[f32; 3]>)> {
    use image::ImageDecoder;
    let (file, len) = crate::files::open_regular(path, MAX_ENV_BYTES, "environment map")?;
    let decoder = image::codecs::hdr::HdrDecoder::new(std::io::BufReader::new(file))
        .map_err(|e| PrtError::file(path, format!("Radiance HDR: {e}")))?;
    let (w, h) = decoder.dimensions();
    let (w, h) = (w as usize, h as usize);
    check_env_size(path, w, h)?;
    // Every row takes its first pixel (4 bytes) and, when wider, at least a run marker or a run
    // of each component (4 bytes more): a header claiming more rows than the file can hold is
    // refused before the pixels are reserved.
    let least = h as u64 * if w > 1 { 8 } else { 4 };
    if len < least {
        return Err(PrtError::file(
            path,
            format!(
                "Radiance HDR: the header declares {w} x {h} pixels, but {len} bytes cannot hold \
                 {h} rows (at least {least} bytes): the file is truncated or its header is wrong"
            ),
        ));
    }
    if decoder.color_type() != image::ColorType::Rgb32F {
        return Err(PrtError::file(path, "Radiance HDR: not RGB"));
    }
    // The pixels go straight into the map's own table, reserved without aborting.
    let mut pixels = crate::output::film::reserve_pixels(path, w, h)?;
    decoder
        .read_image(bytemuck::cast_slice_mut(&mut pixels))
        .map_err(|e| PrtError::file(path, format!("Radiance HDR: {e}")))?;
    Ok((w, h, pixels))
}

/// A procedural clear sky with a disc sun: for tests, demos and the viewer's movable sun.
#[derive(Clone, Debug, PartialEq)]
pub struct SunSky {
    /// Unit direction towards the sun centre (world).
    pub sun_dir: DVec3,
    /// Angular radius of the sun disc, degrees.
    pub sun_radius_deg: f64,
    /// Radiance inside the disc.
    pub sun_radiance: [f32; 3],
    /// Sky radiance straight up.
    pub zenith: [f32; 3],
    /// Sky radiance at the horizon (blended with the zenith by elevation).
    pub horizon: [f32; 3],
    /// Radiance below the horizon.
    pub ground: [f32; 3],
}

impl SunSky {
    /// A sun at `elevation_deg` above the horizon and `azimuth_deg` (0 = towards −Z, 90 = towards +X,
    /// the lat-long u convention), with a blue sky and a dark ground. The sun's radiance is set so
    /// its disc delivers `sun_irradiance` (W/m² per unit) at normal incidence.
    pub fn new(
        elevation_deg: f64,
        azimuth_deg: f64,
        sun_radius_deg: f64,
        sun_irradiance: f32,
    ) -> Self {
        let (el, az) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        let sun_dir = DVec3::new(az.sin() * el.cos(), el.sin(), -az.cos() * el.cos());
        let disc = 2.0 * PI * (1.0 - sun_radius_deg.to_radians().cos());
        let l = sun_irradiance / disc as f32;
        SunSky {
            sun_dir,
            sun_radius_deg,
            sun_radiance: [l, 0.93 * l, 0.82 * l],
            zenith: [0.12, 0.22, 0.45],
            horizon: [0.45, 0.5, 0.55],
            ground: [0.04, 0.035, 0.03],
        }
    }

    /// Radiance seen along the unit direction `d`.
    pub fn radiance(&self, d: DVec3) -> [f32; 3] {
        if d.dot(self.sun_dir) >= self.sun_radius_deg.to_radians().cos() {
            return self.sun_radiance;
        }
        if d.y < 0.0 {
            return self.ground;
        }
        let t = (d.y as f32).sqrt();
        std::array::from_fn(|c| self.horizon[c] * (1.0 - t) + self.zenith[c] * t)
    }

    /// A lat-long map of this sky; each pixel averages `ss x ss` samples so the sun's edge is
    /// antialiased.
    pub fn to_latlong(&self, width: usize, height: usize, ss: usize) -> EnvMap {
        let mut pixels = vec![[0.0f32; 3]; width * height];
        use rayon::prelude::*;
        pixels
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, p) in row.iter_mut().enumerate() {
                    let mut acc = [0.0f64; 3];
                    let mut wsum = 0.0;
                    for sy in 0..ss {
                        let v = (y as f64 + (sy as f64 + 0.5) / ss as f64) / height as f64;
                        let w = (PI * v).sin();
                        for sx in 0..ss {
                            let u = (x as f64 + (sx as f64 + 0.5) / ss as f64) / width as f64;
                            let l = self.radiance(latlong_dir(u, v));
                            for c in 0..3 {
                                acc[c] += l[c] as f64 * w;
                            }
                            wsum += w;
                        }
                    }
                    *p = std::array::from_fn(|c| (acc[c] / wsum) as f32);
                }
            });
        EnvMap {
            width,
            height,
            pixels,
            source: format!(
                "sun-and-sky (sun towards {:.3?}, radius {} deg)",
                self.sun_dir.to_array(),
                self.sun_radius_deg
            ),
            negatives_clamped: 0,
            lowest_negative: 0.0,
            negative_power: 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed-form f64 results against their exact values: lat-long directions and their (u, v)
    /// round trip, a quarter-turn rotation, 32 rows of pixel solid angles summed to 4π. Trig and
    /// a short sum in f64 leave a few ulps of values up to 4π.
    const CLOSED_FORM_F64: f64 = 1e-12;
    /// A channel of 2.0 read back from an RGBE file: 8 mantissa bits under the exponent of the
    /// pixel's largest channel (up to 31, so steps of at most 1/8) hold 2.0 on their grid; 1% of
    /// it leaves room for the encoder's rounding.
    const RGBE_TWO: f32 = 0.02;
    /// A red channel of 0 to 31 read back from an RGBE file, relative: where it is the pixel's
    /// largest channel its 8 mantissa bits hold it to within 1/128 of itself, under 1%...
    const RGBE_MANTISSA: f32 = 0.01;
    /// ...with the value taken at least this large, so that 0 and 1, which sit under the blue
    /// channel's exponent (steps of 1/64 below 2.0), are held to an absolute `RGBE_MANTISSA`.
    const RGBE_SCALE_FLOOR: f32 = 1.0;

    #[test]
    fn sun_specs_parse_once_for_every_caller() {
        let sun = SunSpec::parse("sun:25,70").unwrap().unwrap();
        assert_eq!((sun.elevation, sun.azimuth, sun.radius), (25.0, 70.0, 2.0));
        let sun = SunSpec::parse("sun: -10 , 400, 0.5").unwrap().unwrap();
        assert_eq!(
            (sun.elevation, sun.azimuth, sun.radius),
            (-10.0, 400.0, 0.5)
        );
        assert!(SunSpec::parse("assets/envmaps/blender_city.exr").is_none());
        for bad in [
            "sun:",
            "sun:10",
            "sun:a,b",
            "sun:95,0",
            "sun:10,0,0",
            "sun:10,inf",
            "sun:1,2,3,4",
        ] {
            let e = SunSpec::parse(bad).unwrap().unwrap_err().to_string();
            assert!(e.contains(bad), "{bad}: {e}");
        }
        let e = EnvMap::from_spec("sun:10,0,0").unwrap_err().to_string();
        assert!(
            e.contains("`sun:10,0,0`") && e.contains("radius in [0.05, 45]"),
            "{e}"
        );
    }

    #[test]
    fn bundled_maps_load_by_name_as_their_files_do() {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/envmaps/blender_sunrise.exr");
        let from_file = EnvMap::load(&file).unwrap();
        for spec in ["blender_sunrise", "blender_sunrise.exr"] {
            let map = bundled_map(Path::new(spec)).unwrap();
            assert_eq!(map.stem(), "blender_sunrise");
            assert_eq!(map.bytes, BUNDLED_MAPS[0].bytes);
            let bundled = EnvSpec::parse(spec).unwrap().load().unwrap();
            assert_eq!(
                (bundled.width, bundled.height),
                (from_file.width, from_file.height)
            );
            assert!(bundled.pixels == from_file.pixels, "{spec}");
            assert!(bundled.source.contains("bundled"), "{}", bundled.source);
        }
        // A path with a folder, or a name no map has, is a file.
        assert!(bundled_map(Path::new("somewhere/blender_sunrise.exr")).is_none());
        assert!(bundled_map(Path::new("blender_sundown")).is_none());
        let e = EnvMap::from_spec("blender_sundown")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("blender_sundown") && e.contains(&bundled_names()),
            "{e}"
        );
        assert_eq!(BUNDLED_MAPS.len(), 6);
    }

    #[test]
    fn latlong_directions_follow_the_convention() {
        let close = |a: DVec3, b: DVec3| (a - b).length() < CLOSED_FORM_F64;
        assert!(close(latlong_dir(0.0, 0.5), DVec3::new(0.0, 0.0, -1.0)));
        assert!(close(latlong_dir(0.25, 0.5), DVec3::X));
        assert!(close(latlong_dir(0.5, 0.5), DVec3::Z));
        assert!(close(latlong_dir(0.75, 0.5), -DVec3::X));
        assert!(close(latlong_dir(0.3, 0.0), DVec3::Y));
        for (u, v) in [(0.1, 0.2), (0.6, 0.9), (0.99, 0.5)] {
            let (u2, v2) = latlong_uv(latlong_dir(u, v));
            assert!((u - u2).abs() < CLOSED_FORM_F64 && (v - v2).abs() < CLOSED_FORM_F64);
        }
    }

    #[test]
    fn pixel_solid_angles_sum_to_four_pi() {
        let (w, h) = (64, 32);
        let total: f64 = (0..h).map(|y| pixel_solid_angle(w, h, y) * w as f64).sum();
        assert!((total - 4.0 * PI).abs() < CLOSED_FORM_F64);
    }

    #[test]
    fn radiance_hdr_files_load() {
        let dir = std::env::temp_dir().join(format!("prt-hdr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("map.hdr");
        let (w, h) = (8usize, 4usize);
        let pixels: Vec<image::Rgb<f32>> = (0..w * h)
            .map(|i| image::Rgb([i as f32, 0.5, 2.0]))
            .collect();
        let f = std::fs::File::create(&p).unwrap();
        image::codecs::hdr::HdrEncoder::new(f)
            .encode(&pixels, w, h)
            .unwrap();
        let env = EnvMap::load(&p).unwrap();
        assert_eq!((env.width, env.height), (w, h));
        // RGBE keeps 8 mantissa bits per channel.
        for (i, px) in env.pixels.iter().enumerate() {
            assert!(
                (px[0] - i as f32).abs() <= RGBE_MANTISSA * (i as f32).max(RGBE_SCALE_FLOOR),
                "{i}: {px:?}"
            );
            assert!((px[2] - 2.0).abs() < RGBE_TWO);
        }
        std::fs::write(&p, b"#?RADIANCE\ngarbage").unwrap();
        let e = EnvMap::load(&p).unwrap_err().to_string();
        assert!(e.contains("map.hdr"), "{e}");
    }

    #[test]
    fn yaw_turns_about_plus_y_right_handed() {
        // A quarter turn takes the map's -Z (u = 0) to world -X.
        let m = EnvRotation::yaw(90.0).world_from_map();
        let turned = m * DVec3::new(0.0, 0.0, -1.0);
        assert!((turned - DVec3::new(-1.0, 0.0, 0.0)).length() < CLOSED_FORM_F64);
    }
}
