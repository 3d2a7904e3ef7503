//! The lat-long parameterisation of an environment (see [`crate::conventions`]): direction of a
//! (u, v) and back, the exact solid angle of a pixel row, and the rotation that turns a map in
//! the world.

use std::f64::consts::PI;

use glam::{DMat3, DVec3};

/// Orientation of an environment: world direction = R_x(pitch) · R_y(yaw) · map direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EnvRotation {
    /// Turn about +Y, right-hand rule, degrees.
    pub yaw_deg: f64,
    /// Turn about +X applied after the yaw, right-hand rule, degrees.
    pub pitch_deg: f64,
}

impl EnvRotation {
    /// A rotation by `yaw_deg` about +Y, then `pitch_deg` about +X.
    pub const fn new(yaw_deg: f64, pitch_deg: f64) -> Self {
        EnvRotation { yaw_deg, pitch_deg }
    }

    /// A rotation by `yaw_deg` about +Y only.
    pub fn yaw(yaw_deg: f64) -> Self {
        EnvRotation::new(yaw_deg, 0.0)
    }

    /// The matrix taking map directions to world directions.
    pub fn world_from_map(&self) -> DMat3 {
        DMat3::from_rotation_x(self.pitch_deg.to_radians())
            * DMat3::from_rotation_y(self.yaw_deg.to_radians())
    }
}

/// Unit direction of lat-long coordinates (u, v) in [0, 1]².
#[inline]
pub fn latlong_dir(u: f64, v: f64) -> DVec3 {
    let (sin_u, cos_u) = (2.0 * PI * u).sin_cos();
    let (sin_v, cos_v) = (PI * v).sin_cos();
    DVec3::new(sin_u * sin_v, cos_v, -cos_u * sin_v)
}

/// Lat-long coordinates (u, v) of a unit direction; the inverse of [`latlong_dir`].
#[inline]
pub fn latlong_uv(d: DVec3) -> (f64, f64) {
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    let u = d.x.atan2(-d.z) / (2.0 * PI);
    (if u < 0.0 { u + 1.0 } else { u }, v)
}

/// Exact solid angle of one pixel of row `y` in a `width` x `height` map.
pub fn pixel_solid_angle(width: usize, height: usize, y: usize) -> f64 {
    let h = height as f64;
    (2.0 * PI / width as f64) * ((PI * y as f64 / h).cos() - (PI * (y + 1) as f64 / h).cos())
}
