//! What the integration tests and the library's unit tests (which include this file by path)
//! share, written once: approximate equality with a named tolerance, the seeded generator of
//! random test inputs, temporary folders and the canonical scene texts.

use std::fmt::Display;
use std::path::PathBuf;

/// Asserts |got − want| ≤ tol, printing both values, the difference and what was compared.
#[track_caller]
#[allow(dead_code)]
pub fn assert_close(
    what: impl Display,
    got: impl Into<f64>,
    want: impl Into<f64>,
    tol: impl Into<f64>,
) {
    let (got, want, tol) = (got.into(), want.into(), tol.into());
    let diff = (got - want).abs();
    assert!(
        diff <= tol,
        "{what}: got {got:.9e}, want {want:.9e}, |diff| = {diff:.3e} > tol {tol:.3e}"
    );
}

/// Asserts |got − want| ≤ rel · |want|.
#[track_caller]
#[allow(dead_code)]
pub fn assert_rel_close(what: impl Display, got: f64, want: f64, rel: f64) {
    let diff = (got - want).abs();
    assert!(
        diff <= rel * want.abs().max(1e-12),
        "{what}: got {got:.9e}, want {want:.9e}, |diff| = {diff:.3e} (relative {:.3e} > {rel:.3e})",
        diff / want.abs().max(1e-30)
    );
}

/// SplitMix64: a tiny seeded generator, so random tests see the same inputs on every run.
#[allow(dead_code)]
pub struct Rng(pub u64);

#[allow(dead_code)]
impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1), from the top 53 bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform on the unit sphere (Archimedes: z uniform in [-1, 1]).
    pub fn direction(&mut self) -> glam::DVec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        glam::DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Uniform in [0, 1) in single precision, from the top 24 bits.
    pub fn unit_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi) in single precision.
    pub fn range_f32(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit_f32()
    }

    /// Uniform on the unit sphere in single precision.
    pub fn unit_vector(&mut self) -> glam::Vec3 {
        let z = self.range_f32(-1.0, 1.0);
        let phi = self.range_f32(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        glam::Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// A folder for one test's files under the system's temporary folder, unique to this process and
/// `name` (tests of one binary run in parallel: give each its own name).
#[allow(dead_code)]
pub fn temp_dir(name: &str) -> PathBuf {
    // The process id and the time this process first asked: a later run that is given the same
    // id (ids are reused) must not find this one's files, which a bake would keep as its own.
    static RUN: std::sync::OnceLock<u128> = std::sync::OnceLock::new();
    let run = RUN.get_or_init(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos())
    });
    let dir = std::env::temp_dir().join(format!("prt-test-{}-{run}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// The camera of the canonical scene, before its image size.
macro_rules! canonical_camera {
    () => {
        r#"[camera]
eye = [0.0, 1.5, 4.0]
target = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
"#
    };
}

/// The clay sphere standing on the ground quad, after the ground material.
macro_rules! sphere_on_ground {
    () => {
        r#"
[material.clay]
type = "diffuse"
albedo = [0.8, 0.3, 0.2]

[[shape]]
type = "quad"
corners = [[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]
material = "ground"

[[shape]]
type = "sphere"
center = [0.0, 0.6, 0.0]
radius = 0.6
material = "clay"
"#
    };
}

/// The canonical scene of the scene-file documentation, without the mesh.
#[allow(dead_code)]
pub const CANONICAL: &str = concat!(
    canonical_camera!(),
    r#"width = 256
height = 256

[material.ground]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]
"#,
    sphere_on_ground!()
);

/// The canonical sphere on a ground plane, at an image size 16-pixel tiles do not divide.
#[allow(dead_code)]
pub const SPHERE_ON_PLANE: &str = concat!(
    canonical_camera!(),
    r#"width = 37
height = 21

[material.ground]
type = "diffuse"
albedo = [0.8, 0.7, 0.6]
"#,
    sphere_on_ground!()
);
