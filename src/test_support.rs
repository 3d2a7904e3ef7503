//! Helpers shared by the unit tests of every module of the crate (the integration tests' own
//! share `tests/common/shared.rs` with them).

use glam::Vec3;

/// Asserts every component of `a - b` is within `tol`, printing both on failure.
#[track_caller]
pub fn assert_vec_close(what: &str, a: Vec3, b: Vec3, tol: f32) {
    assert!(
        (a - b).abs().max_element() <= tol,
        "{what}: got {a}, expected {b} (max |diff| = {} > tol {tol})",
        (a - b).abs().max_element()
    );
}

/// The text of a scene file: a camera at `eye` looking at the origin (field of view `fov_y_deg`,
/// `size` pixels square), one grey diffuse material `m`, then `shapes`.
pub fn grey_scene_text(eye: [f32; 3], fov_y_deg: f32, size: u32, shapes: &str) -> String {
    format!(
        "[camera]\neye = {eye:?}\ntarget = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y_deg = {fov_y_deg:?}\nwidth = {size}\nheight = {size}\n\n\
         [material.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\n{shapes}"
    )
}

#[path = "../tests/common/shared.rs"]
mod shared;
pub use shared::{CANONICAL, Rng, assert_close, temp_dir};
