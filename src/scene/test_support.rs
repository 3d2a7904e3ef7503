//! Helpers shared by the tests of this crate's modules.

use glam::Vec3;
use std::path::PathBuf;

/// Asserts |a - b| <= tol, printing both values (and what was compared) on failure.
#[track_caller]
pub fn assert_close(what: &str, a: f32, b: f32, tol: f32) {
    assert!(
        (a - b).abs() <= tol,
        "{what}: got {a}, expected {b} (|diff| = {} > tol {tol})",
        (a - b).abs()
    );
}

/// Asserts every component of `a - b` is within `tol`, printing both on failure.
#[track_caller]
pub fn assert_vec_close(what: &str, a: Vec3, b: Vec3, tol: f32) {
    assert!(
        (a - b).abs().max_element() <= tol,
        "{what}: got {a}, expected {b} (max |diff| = {} > tol {tol})",
        (a - b).abs().max_element()
    );
}

/// A fresh, empty folder for one test's files.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("wavelet-prt-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// Small deterministic generator (SplitMix64) so random tests repeat exactly.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    /// Uniform on the unit sphere.
    pub fn unit_vector(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

#[path = "../../tests/common/scenes.rs"]
mod scenes;
pub use scenes::CANONICAL;
