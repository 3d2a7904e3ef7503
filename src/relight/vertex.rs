//! A per-vertex bake seen from any camera: the relit image of such a bake holds one colour per
//! vertex (vertex `v` is pixel `v`), which [`crate::relight::raster`] draws with Gouraud shading
//! and a depth test, over the environment behind. The orbit camera turns the bake's own camera
//! about its target.

use glam::{Quat, Vec3};

use crate::error::{PrtError, Result};
use crate::light::envmap::{EnvMap, EnvRotation};
use crate::output::film::Image;
use crate::relight::background::{composite, environment_behind_camera};
use crate::relight::raster::{Raster, rasterize};
use crate::scene::Camera;
use crate::scene::tessellate::VertexMesh;
use crate::store::transport::Transport;

/// The mesh of a per-vertex bake, or an error saying that the file is a fixed view.
pub fn mesh_of(t: &Transport) -> Result<&VertexMesh> {
    t.mesh.as_ref().ok_or_else(|| {
        PrtError::invalid(
            "camera",
            "this transport is a per-pixel bake of one fixed view: its camera cannot move (bake \
             the scene with --per-vertex to draw it from any camera)",
        )
    })
}

/// The camera a per-vertex bake was made with (the scene's), at the scene's image size.
pub fn bake_camera(t: &Transport) -> Result<Camera> {
    let pv = t
        .meta
        .per_vertex
        .as_ref()
        .ok_or_else(|| PrtError::invalid("camera", "not a per-vertex bake"))?;
    let c = &t.meta.camera;
    let camera = Camera {
        eye: Vec3::from(c.eye),
        target: Vec3::from(c.target),
        up: Vec3::from(c.up),
        fov_y_deg: c.fov_y_deg,
        width: pv.image[0],
        height: pv.image[1],
    };
    camera.validate()?;
    Ok(camera)
}

/// `camera` turned about its target: the eye swings `azimuth_deg` about the up axis (+Y) and
/// rises `elevation_deg` (kept within 85° of the pole), at the same distance.
pub fn orbit(camera: &Camera, azimuth_deg: f32, elevation_deg: f32) -> Camera {
    let offset = camera.eye - camera.target;
    let distance = offset.length();
    let flat = Vec3::new(offset.x, 0.0, offset.z);
    let elevation = (offset.y / distance.max(f32::MIN_POSITIVE))
        .clamp(-1.0, 1.0)
        .asin();
    let elevation =
        (elevation + elevation_deg.to_radians()).clamp(-85f32.to_radians(), 85f32.to_radians());
    let heading = Quat::from_rotation_y(azimuth_deg.to_radians()) * flat.normalize_or(Vec3::Z);
    let dir = heading * elevation.cos() + Vec3::Y * elevation.sin();
    Camera {
        eye: camera.target + dir * distance,
        up: Vec3::Y,
        ..camera.clone()
    }
}

/// The vertex colours in a per-vertex bake's relit image.
pub fn vertex_colours<'a>(t: &Transport, relit: &'a Image) -> Result<&'a [[f32; 3]]> {
    let v = mesh_of(t)?.vertex_count();
    relit.pixels.get(..v).ok_or_else(|| {
        PrtError::invalid(
            "relit image",
            format!("{} pixels for {v} vertices", relit.pixels.len()),
        )
    })
}

/// Draws a per-vertex bake relit to `colours` (one per vertex) as `camera` sees it, on the CPU,
/// with `behind` (the environment and its turn) where no surface is drawn. Also gives the
/// coverage, for masks and tone mapping.
pub fn draw(
    t: &Transport,
    colours: &[[f32; 3]],
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
) -> Result<Raster> {
    let mesh = mesh_of(t)?;
    let raster = rasterize(camera, &mesh.positions, &mesh.triangles, colours)?;
    compose(raster, camera, behind)
}

/// A drawn raster over the environment behind it, where given.
pub fn compose(
    raster: Raster,
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
) -> Result<Raster> {
    let Some((env, rotation)) = behind else {
        return Ok(raster);
    };
    let back = environment_behind_camera(camera, &raster.coverage, env, rotation)?;
    Ok(Raster {
        image: composite(&raster.image, &back),
        coverage: raster.coverage,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_orbit_keeps_the_distance_and_the_target_and_turns_the_eye() {
        let c = Camera {
            eye: Vec3::new(0.0, 3.0, 4.0),
            target: Vec3::new(0.0, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 40.0,
            width: 8,
            height: 8,
        };
        let same = orbit(&c, 0.0, 0.0);
        assert!((same.eye - c.eye).length() < 1e-5);
        let quarter = orbit(&c, 90.0, 0.0);
        assert!(
            (quarter.eye - Vec3::new(4.0, 3.0, 0.0)).length() < 1e-4,
            "{}",
            quarter.eye
        );
        let up = orbit(&c, 0.0, 90.0);
        assert!((up.eye.length() - 5.0).abs() < 1e-4);
        assert!((up.eye.y / 5.0 - 85f32.to_radians().sin()).abs() < 1e-4);
        assert!(up.validate().is_ok());
    }
}
