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

#[path = "../tests/common/shared.rs"]
mod shared;
pub use shared::{CANONICAL, Rng, assert_close, temp_dir};
