//! Known answers and errors of scene loading.

use super::hash::Fnv1a;
use super::*;
use crate::test_support::*;

/// Direction comparisons: f32 normalisation and trigonometry are good to a few ulps.
const DIR_TOL: f32 = 1e-5;
/// Positions after a scale/rotate/translate of values around 1-5.
const POS_TOL: f32 = 1e-5;

fn canonical() -> Scene {
    Scene::from_toml_str(CANONICAL, Path::new("/nonexistent/scene.toml"))
        .expect("canonical scene parses")
}

fn load_err(text: &str) -> String {
    let err = Scene::from_toml_str(text, Path::new("/scenes/test.toml"))
        .expect_err("the scene should be rejected");
    err.to_string()
}

/// [`load_err`] for a scene read from `dir`, whose files it names.
fn load_err_in(dir: &Path, text: &str) -> String {
    Scene::from_toml_str(text, &dir.join("scene.toml"))
        .expect_err("the scene should be rejected")
        .to_string()
}

/// The 1-based line of the first line of `text` that contains `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("`{needle}` not in text"))
        + 1
}

/// Loading `text` fails with an error that mentions each of `parts` and the line of the first
/// line of `text` that contains `at`.
#[track_caller]
fn assert_rejected_at(text: &str, parts: &[&str], at: &str) {
    let line = format!(":{}:", line_of(text, at));
    assert_mentions(&load_err(text), &[parts, &[line.as_str()]].concat());
}

#[track_caller]
fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(
            message.contains(part),
            "error message lacks `{part}`: {message}"
        );
    }
}

#[test]
fn canonical_scene_parses() {
    let s = canonical();
    assert_eq!(s.camera.width, 256);
    assert_eq!(s.camera.height, 256);
    assert_eq!(s.material_names, vec!["clay", "ground"]);
    assert_eq!(s.triangle_count(), 2);
    assert_eq!(s.spheres.len(), 1);
    let clay = s.material_names.iter().position(|n| n == "clay").unwrap() as u32;
    let ground = s.material_names.iter().position(|n| n == "ground").unwrap() as u32;
    assert_eq!(s.spheres[0].material, clay);
    assert!(s.triangles.iter().all(|t| t.material == ground));
    assert_eq!(
        s.materials[clay as usize],
        Material::Diffuse {
            albedo: Vec3::new(0.8, 0.3, 0.2)
        }
    );
    // Quad split along c0-c2 into (c0,c1,c2) and (c0,c2,c3).
    assert_eq!(
        s.triangles[1].vertices,
        [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0)
        ]
    );
    let (lo, hi) = s.bounds();
    assert_vec_close("bounds min", lo, Vec3::new(-2.0, 0.0, -2.0), 0.0);
    assert_vec_close("bounds max", hi, Vec3::new(2.0, 1.2, 2.0), 1e-6);
    assert!(s.camera.validate().is_ok());
}

#[test]
fn central_ray_points_at_target() {
    let cam = canonical().camera;
    let forward = (cam.target - cam.eye).normalize();
    // Even size: no pixel is centred, so average the four around the film centre.
    let (cx, cy) = (cam.width / 2, cam.height / 2);
    let mut sum = Vec3::ZERO;
    for (x, y) in [(cx - 1, cy - 1), (cx, cy - 1), (cx - 1, cy), (cx, cy)] {
        let r = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
        assert_eq!(r.origin, cam.eye);
        assert_close("|dir|", r.dir.length(), 1.0, DIR_TOL);
        sum += r.dir;
    }
    assert_vec_close("central direction", sum.normalize(), forward, DIR_TOL);
}

#[test]
fn pixel_zero_looks_up_left_and_fov_is_vertical() {
    let mut cam = canonical().camera;
    cam.width = 320;
    cam.height = 200;
    let forward = (cam.target - cam.eye).normalize();
    let right = forward.cross(cam.up).normalize();
    let film_up = right.cross(forward);
    let d = cam.ray(0.5, 0.5).dir;
    assert!(d.dot(right) < 0.0, "pixel (0,0) should look left: {d}");
    assert!(d.dot(film_up) > 0.0, "pixel (0,0) should look up: {d}");
    // The top edge of the film, mid-width, is half the vertical fov above the view axis.
    let top = cam.ray(cam.width as f32 * 0.5, 0.0).dir;
    let half = (cam.fov_y_deg * 0.5).to_radians();
    assert_close("top-edge angle", top.dot(forward).acos(), half, 1e-4);
    assert!(top.dot(film_up) > 0.0);
    // The horizontal extent follows the aspect ratio.
    let side = cam.ray(0.0, cam.height as f32 * 0.5).dir;
    let expected = (half.tan() * 320.0 / 200.0).atan();
    assert_close("left-edge angle", side.dot(forward).acos(), expected, 1e-4);
}

#[test]
fn fnv1a_matches_reference_vectors() {
    let mut h = Fnv1a::new();
    assert_eq!(h.0, 0xcbf2_9ce4_8422_2325);
    h.write(b"a");
    assert_eq!(h.0, 0xaf63_dc4c_8601_ec8c);
    let mut h = Fnv1a::new();
    h.write(b"foobar");
    assert_eq!(h.0, 0x8594_4171_f739_67e8);
}

fn mesh_scene(obj_name: &str, extra: &str) -> String {
    let shape =
        format!("[[shape]]\ntype = \"mesh\"\npath = \"{obj_name}\"\nmaterial = \"m\"\n{extra}\n");
    grey_scene_text([0.0, 1.0, 5.0], 45.0, 8, &shape)
}

fn load_mesh(dir: &str, obj: &str, extra: &str) -> Scene {
    let dir = temp_dir(dir);
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let text = mesh_scene("m.obj", extra);
    std::fs::write(dir.join("scene.toml"), &text).unwrap();
    Scene::load(&dir.join("scene.toml")).expect("mesh scene loads")
}

#[test]
fn obj_vertex_normals_are_used() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 0 -1\nvn 0 1 1\nvn 0 1 1\nvn 1 1 0\nf 1//1 2//2 3//3\n";
    let s = load_mesh("vn", obj, "");
    assert_eq!(s.triangle_count(), 1);
    let t = s.triangles[0];
    let tilted = Vec3::new(0.0, 1.0, 1.0).normalize();
    assert_vec_close("n0", t.normals[0], tilted, DIR_TOL);
    assert_vec_close("n1", t.normals[1], tilted, DIR_TOL);
    assert_vec_close(
        "n2",
        t.normals[2],
        Vec3::new(1.0, 1.0, 0.0).normalize(),
        DIR_TOL,
    );
    assert_vec_close("geometric", t.geometric_normal(), Vec3::Y, DIR_TOL);
}

#[test]
fn obj_without_normals_is_flat() {
    // A quad face (fan-triangulated) given with negative indices and v/vt corners.
    let obj = "# square\nv 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nf -4/1 -3/1 -2/1 -1/1\n";
    let s = load_mesh("flat", obj, "");
    assert_eq!(s.triangle_count(), 2);
    for t in &s.triangles {
        let ng = t.geometric_normal();
        assert_vec_close("geometric", ng, Vec3::Y, DIR_TOL);
        assert_eq!(t.normals, [ng; 3]);
    }
    assert_eq!(s.triangles[1].vertices[2], Vec3::new(0.0, 0.0, -1.0));
}

#[test]
fn smooth_normals_weld_and_weight_by_area() {
    // Two roof slopes sharing the ridge (0,1,0)-(0,1,-1), each with its own copy of the
    // ridge vertices; the right slope is longer, so it carries more area.
    let obj = "\
v 0 1 0\nv -1 0 0\nv 0 1 -1\n\
v 0 1 0\nv 0 1 -1\nv 3 0 0\n\
vn 0 0 1\nvn 0 0 1\nvn 0 0 1\n\
f 1//1 3//3 2//2\nf 4//1 6//3 5//2\n";
    let s = load_mesh("smooth", obj, "smooth_normals = true");
    let [left, right] = [s.triangles[0], s.triangles[1]];
    let cross = |t: &Triangle| {
        let [a, b, c] = t.vertices;
        (b - a).cross(c - a)
    };
    let weighted = (cross(&left) + cross(&right)).normalize();
    let unweighted = (left.geometric_normal() + right.geometric_normal()).normalize();
    assert!(
        (weighted - unweighted).length() > 0.05,
        "test geometry must tell area weighting apart"
    );
    assert!(left.geometric_normal().y > 0.0 && right.geometric_normal().y > 0.0);
    // Ridge corners are shared (welded), the outer corners keep their face normal.
    assert_vec_close("weighted normal", weighted, Vec3::Y, DIR_TOL);
    assert_vec_close("left ridge", left.normals[0], weighted, DIR_TOL);
    assert_vec_close("left ridge 2", left.normals[1], weighted, DIR_TOL);
    assert_vec_close("right ridge", right.normals[0], weighted, DIR_TOL);
    assert_vec_close("right ridge 2", right.normals[2], weighted, DIR_TOL);
    assert_vec_close(
        "left eave",
        left.normals[2],
        left.geometric_normal(),
        DIR_TOL,
    );
    assert_vec_close(
        "right eave",
        right.normals[1],
        right.geometric_normal(),
        DIR_TOL,
    );
}

#[test]
fn mesh_transform_places_vertices() {
    let obj = "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n";
    let s = load_mesh(
        "transform",
        obj,
        "scale = 2.0\nrotate_y_deg = 90.0\ntranslate = [0.0, 0.0, 5.0]",
    );
    let [a, b, c] = s.triangles[0].vertices;
    // Right-handed +90 degrees about +Y takes +X to -Z and +Z to +X.
    assert_vec_close("x vertex", a, Vec3::new(0.0, 0.0, 3.0), POS_TOL);
    assert_vec_close("y vertex", b, Vec3::new(0.0, 2.0, 5.0), POS_TOL);
    assert_vec_close("z vertex", c, Vec3::new(2.0, 0.0, 5.0), POS_TOL);
}

#[test]
fn vertex_normals_follow_the_rotation() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 1 0 0\nf 1//1 2//1 3//1\n";
    let s = load_mesh("vn-rot", obj, "rotate_y_deg = 90.0\nscale = 3.0");
    assert_vec_close(
        "rotated normal",
        s.triangles[0].normals[0],
        -Vec3::Z,
        DIR_TOL,
    );
}

#[test]
fn content_hash_tracks_scene_and_obj_bytes() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let a = load_mesh("hash-a", obj, "");
    let b = load_mesh("hash-b", obj, "");
    assert_eq!(a.content_hash(), b.content_hash(), "same inputs, same hash");
    let c = load_mesh("hash-c", &format!("{obj}# edited\n"), "");
    assert_ne!(a.content_hash(), c.content_hash(), "OBJ bytes must count");
    let d = load_mesh("hash-d", obj, "scale = 1.0");
    assert_ne!(a.content_hash(), d.content_hash(), "scene text must count");
}

#[test]
fn malformed_obj_names_file_and_line() {
    let dir = temp_dir("bad-obj");
    let text = mesh_scene("m.obj", "");
    for (obj, line, problem) in [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
            "line 4",
            "out of range",
        ),
        ("v 0 0 0\nv 1 zero 0\n", "line 2", "`zero`"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", "line 3", "3 corners"),
    ] {
        std::fs::write(dir.join("m.obj"), obj).unwrap();
        assert_mentions(&load_err_in(&dir, &text), &["m.obj", line, problem]);
    }
}

#[test]
fn mesh_without_triangles_is_rejected() {
    let dir = temp_dir("empty-obj");
    // Only a degenerate face: no triangle with area.
    std::fs::write(dir.join("m.obj"), "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
    let text = mesh_scene("m.obj", "");
    let err = load_err_in(&dir, &text);
    assert_mentions(
        &err,
        &[
            "shape[0].path",
            "no triangles",
            &format!(":{}", line_of(&text, "path =")),
        ],
    );
}

#[test]
fn missing_obj_is_an_io_error_naming_it() {
    let dir = temp_dir("missing-obj");
    let text = mesh_scene("nowhere/bunny.obj", "");
    let err = Scene::from_toml_str(&text, &dir.join("scene.toml")).unwrap_err();
    assert!(matches!(err, PrtError::Io { .. }), "{err:?}");
    assert_mentions(&err.to_string(), &["nowhere/bunny.obj"]);
}

#[test]
fn unknown_material_names_the_shape_field() {
    let text = CANONICAL.replace("material = \"clay\"", "material = \"cley\"");
    let err = load_err(&text);
    let line = line_of(&text, "\"cley\"");
    assert_mentions(
        &err,
        &["shape[1].material", "cley", &format!("test.toml:{line}:")],
    );
}

#[test]
fn degenerate_cameras_are_rejected() {
    let eye_is_target = CANONICAL.replace("target = [0.0, 0.5, 0.0]", "target = [0.0, 1.5, 4.0]");
    assert_rejected_at(&eye_is_target, &["camera.target"], "target =");

    let up_parallel = CANONICAL.replace("up = [0.0, 1.0, 0.0]", "up = [0.0, -1.0, -4.0]");
    assert_rejected_at(&up_parallel, &["camera.up", "parallel"], "up =");

    for fov in ["0.0", "180.0", "-5.0", "nan"] {
        let text = CANONICAL.replace("fov_y_deg = 40.0", &format!("fov_y_deg = {fov}"));
        assert_mentions(&load_err(&text), &["camera.fov_y_deg", ":5:"]);
    }

    let mut cam = canonical().camera;
    cam.up = Vec3::ZERO;
    assert_mentions(&cam.validate().unwrap_err().to_string(), &["camera.up"]);
}

#[test]
fn image_size_is_bounded() {
    let err = load_err(&CANONICAL.replace("width = 256", "width = 0"));
    assert_mentions(&err, &["camera.width", ":6:"]);
    let err = load_err(&CANONICAL.replace("height = 256", "height = 16385"));
    assert_mentions(&err, &["camera.height", ":7:", "16384"]);
    let err = load_err(&CANONICAL.replace("width = 256", "width = -3"));
    assert_mentions(&err, &["camera.width", ":6:"]);
}

#[test]
fn unknown_fields_are_typos() {
    let text = CANONICAL.replace("albedo = [0.8, 0.3, 0.2]", "albdo = [0.8, 0.3, 0.2]");
    assert_rejected_at(&text, &["material.clay.albdo"], "albdo");

    let text = CANONICAL.replace("radius = 0.6", "radius = 0.6\nradus = 0.6");
    assert_rejected_at(&text, &["shape[1].radus"], "radus");

    let text = format!("{CANONICAL}\n[fog]\ndensity = 1.0\n");
    assert_rejected_at(&text, &["`fog`"], "[fog]");

    let text = format!("{CANONICAL}\n[medium]\ndensity = 1.0\n");
    assert_rejected_at(&text, &["medium.density"], "density");

    // A key that exists, but for another shape type.
    let text = CANONICAL.replace("radius = 0.6", "radius = 0.6\nscale = 2.0");
    assert_rejected_at(&text, &["shape[1].scale", "sphere"], "scale");
}

#[test]
fn schema_errors_name_field_and_line() {
    let text = CANONICAL.replace("radius = 0.6\n", "");
    assert_mentions(
        &load_err(&text),
        &[
            "shape[1].radius",
            &format!(":{}:", line_of(&text, "[[shape]]") + 5),
        ],
    );

    let text = CANONICAL.replace("type = \"sphere\"", "type = \"sphre\"");
    assert_mentions(&load_err(&text), &["shape[1].type", "sphre"]);

    let text = CANONICAL.replace(
        "type = \"diffuse\"\nalbedo = [0.8, 0.3",
        "type = \"shiny\"\nalbedo = [0.8, 0.3",
    );
    assert_mentions(&load_err(&text), &["material.clay.type", "shiny"]);

    let text = CANONICAL.replace(
        "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
        "type = \"glossy\"\nalbedo = [0.8, 0.3, 0.2]\nspecular = [0.5, 0.5, 0.5]\nroughness = 0.3",
    );
    assert_mentions(&load_err(&text), &["material.clay.specular", "at most 1"]);
    let text = CANONICAL.replace(
        "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
        "type = \"glossy\"\nalbedo = [0.4, 0.3, 0.2]\nspecular = [0.5, 0.5, 0.5]",
    );
    assert_mentions(&load_err(&text), &["material.clay.roughness"]);
    let text = CANONICAL.replace(
        "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
        "type = \"diffuse\"\nalbedo = [0.4, 0.3, 0.2]\nroughness = 0.5",
    );
    assert_mentions(&load_err(&text), &["material.clay.roughness", "glossy"]);

    let text = CANONICAL.replace("eye = [0.0, 1.5, 4.0]", "eye = [0.0, 1.5]");
    assert_mentions(&load_err(&text), &["camera.eye", ":2:"]);

    let text = CANONICAL.replace("width = 256", "width = 256 256");
    assert_mentions(&load_err(&text), &[":6:"]);
}

#[test]
fn bad_numbers_are_rejected() {
    let text = CANONICAL.replace("radius = 0.6", "radius = -0.6");
    assert_rejected_at(&text, &["shape[1].radius"], "radius");
    let text = CANONICAL.replace("radius = 0.6", "radius = 0.0");
    assert_mentions(&load_err(&text), &["shape[1].radius"]);
    let text = CANONICAL.replace("center = [0.0, 0.6, 0.0]", "center = [0.0, inf, 0.0]");
    assert_mentions(&load_err(&text), &["shape[1].center", "finite"]);
    let text = CANONICAL.replace("eye = [0.0, 1.5, 4.0]", "eye = [0.0, 1.5, 1e39]");
    assert_mentions(&load_err(&text), &["camera.eye", "finite"]);
    let text = CANONICAL.replace("albedo = [0.8, 0.3, 0.2]", "albedo = [0.8, 1.3, 0.2]");
    assert_mentions(&load_err(&text), &["material.clay.albedo", "[0, 1]"]);
    let text = CANONICAL.replace("albedo = [0.8, 0.3, 0.2]", "albedo = [0.8, -0.1, 0.2]");
    assert_mentions(&load_err(&text), &["material.clay.albedo"]);
    let text = CANONICAL.replace(
        "[2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]",
        "[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0]]",
    );
    assert_mentions(&load_err(&text), &["shape[0].corners", "zero area"]);
}

#[test]
fn scene_without_shapes_is_rejected() {
    let text = CANONICAL.split("[[shape]]").next().unwrap();
    assert_mentions(&load_err(text), &["`shape`", "no shapes"]);
}

#[test]
fn projecting_a_point_of_a_pixels_ray_gives_back_the_pixel() {
    let camera = Camera {
        eye: Vec3::new(0.3, 2.0, 4.0),
        target: Vec3::new(0.0, 0.4, 0.0),
        up: Vec3::Y,
        fov_y_deg: 40.0,
        width: 64,
        height: 48,
    };
    for (x, y) in [(0.5f32, 0.5f32), (31.5, 20.25), (63.0, 47.9)] {
        let ray = camera.ray(x, y);
        let (px, py) = camera.project(ray.origin + ray.dir * 3.7).unwrap();
        assert!(
            (px - x).abs() < 1e-3 && (py - y).abs() < 1e-3,
            "{x} {y}: {px} {py}"
        );
    }
    assert!(
        camera
            .project(camera.eye - (camera.target - camera.eye))
            .is_none()
    );
}
