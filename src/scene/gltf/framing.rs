//! A glTF file as a whole scene: the camera the command line picks (or one that frames the
//! geometry), the image size, and the content hash that keys its bakes.

use std::path::Path;

use glam::{Mat4, Vec3};

use super::{GltfCamera, read};
use crate::error::{PrtError, Result};
use crate::scene::{Camera, Scene};

/// How a scene is framed where its file does not fix it: which of a glTF file's cameras, and
/// the image size. A TOML scene's camera takes `width` and `height` from here when they are
/// given.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Framing {
    /// The glTF camera to use, by name; the file's first when `None`.
    pub camera: Option<String>,
    /// Image width in pixels (default 256).
    pub width: Option<u32>,
    /// Image height in pixels (default: the width over the camera's aspect ratio, or 256).
    pub height: Option<u32>,
    /// Whether a glTF file may read buffers and images outside its own folder. Off by default:
    /// a model from elsewhere must not read the files of whoever bakes it into the bake.
    pub read_outside_folder: bool,
}

/// Default image width of a glTF scene, pixels.
pub const DEFAULT_WIDTH: u32 = 256;

impl Framing {
    /// The image size for a camera of aspect ratio `aspect` (width over height), if known.
    fn size(&self, aspect: Option<f32>) -> (u32, u32) {
        match (self.width, self.height) {
            (Some(w), Some(h)) => (w, h),
            (Some(w), None) => (
                w,
                aspect.map_or(w, |a| ((w as f32 / a).round() as u32).max(1)),
            ),
            (None, Some(h)) => (
                aspect.map_or(h, |a| ((h as f32 * a).round() as u32).max(1)),
                h,
            ),
            (None, None) => {
                let w = DEFAULT_WIDTH;
                (
                    w,
                    aspect.map_or(w, |a| ((w as f32 / a).round() as u32).max(1)),
                )
            }
        }
    }
}

/// A whole scene from a glTF file: its meshes, materials, lights and the camera `framing` picks
/// (or, when the file has none, one that frames the geometry from the front, +Z, and a little
/// above).
pub(in crate::scene) fn scene(path: &Path, framing: &Framing) -> Result<Scene> {
    let data = read(path, Mat4::IDENTITY, framing.read_outside_folder)?;
    let mut hasher = crate::scene::hash::Fnv1a::new();
    hasher.write(&data.hash.to_le_bytes());
    let mut scene = Scene {
        camera: Camera {
            eye: Vec3::Z,
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 1,
            height: 1,
        },
        materials: Vec::new(),
        material_maps: Vec::new(),
        material_names: Vec::new(),
        textures: data.textures,
        triangles: data.triangles,
        surfaces: data.surfaces.iter().map(|(r, _)| r.clone()).collect(),
        surface_names: data.surfaces.into_iter().map(|(_, n)| n).collect(),
        edge_length: None,
        spheres: Vec::new(),
        medium: None,
        lights: data.lights,
        source_path: path.to_path_buf(),
        input_files: data.files,
        ignored: data.ignored.into_iter().collect(),
        content_hash: 0,
    };
    for m in data.materials {
        scene.materials.push(m.material);
        scene.material_maps.push(m.maps);
        scene.material_names.push(m.name);
    }
    scene.camera = pick_camera(path, &data.cameras, framing, &scene)?;
    hash_camera(&mut hasher, &scene.camera);
    scene.content_hash = hasher.0;
    Ok(scene)
}

/// Mixes a camera into a content hash.
pub(in crate::scene) fn hash_camera(hasher: &mut crate::scene::hash::Fnv1a, c: &Camera) {
    for v in [c.eye, c.target, c.up] {
        for x in v.to_array() {
            hasher.write(&x.to_le_bytes());
        }
    }
    hasher.write(&c.fov_y_deg.to_le_bytes());
    hasher.write(&c.width.to_le_bytes());
    hasher.write(&c.height.to_le_bytes());
}

fn pick_camera(
    path: &Path,
    cameras: &[GltfCamera],
    framing: &Framing,
    scene: &Scene,
) -> Result<Camera> {
    let chosen = match &framing.camera {
        Some(name) => Some(cameras.iter().find(|c| c.name == *name).ok_or_else(|| {
            let known = crate::names::known(
                cameras.iter().map(|c| c.name.as_str()),
                "it has no perspective cameras",
                "it has",
            );
            PrtError::file(path, format!("no camera named `{name}`: {known}"))
        })?),
        None => cameras.first(),
    };
    let camera = match chosen {
        Some(c) => {
            let (width, height) = framing.size(c.aspect);
            Camera {
                eye: c.eye,
                // A step the size of the eye's distance from the origin, so that the direction
                // survives rounding far from it.
                target: c.eye + c.forward * c.eye.length().max(1.0),
                up: c.up,
                fov_y_deg: c.fov_y_deg,
                width,
                height,
            }
        }
        None => {
            let (lo, hi) = scene.bounds();
            let centre = (lo + hi) * 0.5;
            let radius = frame_radius(lo, hi);
            let fov_y_deg = 40.0f32;
            let (width, height) = framing.size(None);
            // Far enough that the bounding sphere fits the narrower of the two fields of view.
            let aspect = width as f32 / height as f32;
            let half = (fov_y_deg.to_radians() * 0.5).tan() * aspect.min(1.0);
            let distance = radius * (1.0 + half * half).sqrt() / half * 1.05;
            Camera {
                eye: centre + Vec3::new(0.0, 0.35, 1.0).normalize() * distance,
                target: centre,
                up: Vec3::Y,
                fov_y_deg,
                width,
                height,
            }
        }
    };
    match camera.problem() {
        None => Ok(camera),
        Some((field, message)) => Err(PrtError::file(
            path,
            format!(
                "camera {}: {field} {message}",
                chosen.map_or("framing the scene", |c| c.name.as_str())
            ),
        )),
    }
}

/// The radius of the sphere that frames the bounds `lo`..`hi`: the scene's own size, however
/// small, but at least a few f32 steps (1e-6 relative) of where it lies, below which the camera
/// would have no view direction ([`Camera::validate`]); 1 for a scene of no size at the origin
/// (a point, or nothing) or one whose size squares below f32's normal range.
fn frame_radius(lo: Vec3, hi: Vec3) -> f32 {
    /// Below this the view's squared lengths are no longer normal f32 numbers.
    const SMALLEST: f32 = 1e-15;
    let centre = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(centre.abs().max_element() * 1e-6);
    if radius.is_finite() && radius >= SMALLEST {
        radius
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_is_the_size_of_the_scene_however_small() {
        for scale in [1.0f32, 1e-3, 1e-6, 1e-9] {
            let r = frame_radius(Vec3::splat(-scale), Vec3::splat(scale));
            let want = 3f32.sqrt() * scale;
            assert!((r - want).abs() <= 1e-6 * want, "scale {scale}: radius {r}");
        }
        // No size at the origin: unit radius, never zero.
        assert_eq!(frame_radius(Vec3::ZERO, Vec3::ZERO), 1.0);
        // Elsewhere, at least a few f32 steps of its place.
        assert_eq!(frame_radius(Vec3::ONE, Vec3::ONE), 1.0e-6);
        let at = Vec3::new(1000.0, 0.0, 0.0);
        assert_eq!(frame_radius(at, at), 1000.0 * 1e-6);
    }
}
