//! Scene texts shared by the integration tests and the library's unit tests (which include this
//! file by path), so each is written once.

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
