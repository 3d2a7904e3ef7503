//! The environment behind the scene: what a camera ray that misses the geometry sees, turned with
//! the light. It is composited under a relit image by each pixel's uncovered fraction, so the
//! silhouettes keep their antialiasing; error metrics are taken before, on covered pixels only.

use glam::Vec3;

use crate::env::envmap::{EnvMap, EnvRotation};
use crate::error::{PrtError, Result};
use crate::output::film::Image;
use crate::scene::Camera;
use crate::store::transport::TransportMeta;

/// What pixels that see no geometry show.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[derive(strum::IntoStaticStr, strum::Display, strum::VariantArray)]
#[strum(serialize_all = "lowercase")]
pub enum Background {
    /// The environment seen through the camera, rotated with the light.
    #[default]
    #[strum(serialize = "env")]
    Environment,
    /// Nothing: black.
    Black,
}

crate::named!(Background, "background", ["environment" => Background::Environment]);

/// The environment behind the baked view of `meta`: for every pixel, `(1 − coverage)` times the
/// radiance of `env` (turned by `rotation`) along the camera ray through the pixel's centre.
/// Covered pixels are black. `coverage` has one value per pixel.
pub fn environment_behind(
    meta: &TransportMeta,
    coverage: &[f32],
    env: &EnvMap,
    rotation: EnvRotation,
) -> Result<Image> {
    let c = &meta.camera;
    let camera = Camera {
        eye: Vec3::from(c.eye),
        target: Vec3::from(c.target),
        up: Vec3::from(c.up),
        fov_y_deg: c.fov_y_deg,
        width: meta.width,
        height: meta.height,
    };
    environment_behind_camera(&camera, coverage, env, rotation)
}

/// [`environment_behind`] for any camera (its image size sets the pixels).
pub fn environment_behind_camera(
    camera: &Camera,
    coverage: &[f32],
    env: &EnvMap,
    rotation: EnvRotation,
) -> Result<Image> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    if coverage.len() != w * h {
        return Err(PrtError::invalid(
            "coverage",
            format!("{} values for a {w} x {h} image", coverage.len()),
        ));
    }
    camera.validate()?;
    // World directions go to the map through the inverse of the map-to-world rotation.
    let map_from_world = rotation.world_from_map().transpose();
    let mut image = Image::new(w, h);
    for (i, (px, &cov)) in image.pixels.iter_mut().zip(coverage).enumerate() {
        let open = (1.0 - cov).clamp(0.0, 1.0);
        if open == 0.0 {
            continue;
        }
        let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
        let d = map_from_world * camera.ray(x, y).dir.as_dvec3();
        let l = env.radiance_at(d);
        *px = std::array::from_fn(|k| open * l[k]);
    }
    Ok(image)
}

/// `image + behind`, pixel by pixel (the two must have one size).
pub fn composite(image: &Image, behind: &Image) -> Image {
    let mut out = image.clone();
    for (o, b) in out.pixels.iter_mut().zip(&behind.pixels) {
        for k in 0..3 {
            o[k] += b[k];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sky behind a pixel against (1 − coverage) times the constant radiance (up to 3): the
    /// bilinear lookup of a constant map returns it exactly and both sides take the same f32
    /// product, so they differ by an ulp of 3 (2.4e-7) at most.
    const SKY_BEHIND: f32 = 1e-5;

    fn camera(width: u32, height: u32) -> Camera {
        Camera {
            eye: Vec3::ZERO,
            target: Vec3::NEG_Z,
            up: Vec3::Y,
            fov_y_deg: 60.0,
            width,
            height,
        }
    }

    #[test]
    fn a_constant_sky_shows_behind_by_the_uncovered_fraction() {
        let m = camera(4, 2);
        let coverage = [0.0, 0.25, 1.0, 0.5, 0.0, 0.0, 1.0, 0.0];
        let env = EnvMap::constant(64, 32, [1.0, 2.0, 3.0]);
        let behind =
            environment_behind_camera(&m, &coverage, &env, EnvRotation::yaw(40.0)).unwrap();
        for (p, c) in behind.pixels.iter().zip(coverage) {
            for (k, v) in p.iter().enumerate() {
                let want = (1.0 - c) * (k + 1) as f32;
                assert!((v - want).abs() < SKY_BEHIND, "{p:?} at coverage {c}");
            }
        }
        let e = environment_behind_camera(&m, &coverage[..3], &env, EnvRotation::default())
            .unwrap_err();
        assert!(e.to_string().contains("coverage"), "{e}");
    }

    #[test]
    fn the_view_direction_reads_the_map_where_the_rotation_puts_it() {
        // A map bright only in one column band: the camera looks down −z, which is lat-long
        // u = 0 (latlong_dir(0, v) points to −z at the horizon), so the centre pixel sees it
        // unturned and does not after a half turn.
        let mut env = EnvMap::constant(64, 32, [0.0; 3]);
        for y in 0..32 {
            for x in [63usize, 0, 1] {
                env.pixels[y * 64 + x] = [5.0; 3];
            }
        }
        let m = camera(1, 1);
        let seen =
            |yaw| environment_behind_camera(&m, &[0.0], &env, EnvRotation::yaw(yaw)).unwrap();
        assert!(seen(0.0).pixels[0][0] > 2.0);
        assert_eq!(seen(180.0).pixels[0][0], 0.0);
        assert!("black".parse::<Background>().unwrap() == Background::Black);
        let e = "sky".parse::<Background>().unwrap_err().to_string();
        assert!(e.contains("`sky`; expected env or black"), "{e}");
    }
}
