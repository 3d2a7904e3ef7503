//! Scenes and stored files that passed every check yet gave a wrong image: a tiny camera-less glTF
//! model framed from too far to be seen, a bake that sees nothing and says nothing, and resealed
//! per-vertex files whose normals, materials or albedo maps' materials were edited.

mod common;

use std::path::Path;

use common::gltf::{GltfBuilder, test_scene};
use common::{StFile, plane_from_above, prt, relit, s, temp_dir};
use serde_json::json;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::relight::RelightRequest;
use wavelet_prt::scene::trace::Tracer;
use wavelet_prt::scene::{Framing, Scene};
use wavelet_prt::store::transport::{BakeDomain, Transport};

/// A glTF file of one grey square of half-size `half` in the z = 0 plane, facing +Z, with no
/// camera.
fn square_without_camera(dir: &Path, half: f32) -> std::path::PathBuf {
    let mut b = GltfBuilder::default();
    let corners = [
        [-half, -half, 0.0],
        [half, -half, 0.0],
        [half, half, 0.0],
        [-half, half, 0.0],
    ];
    let square = b.primitive(&corners, [0.0, 0.0, 1.0], None, &[0, 1, 2, 0, 2, 3], 0);
    b.set(
        "materials",
        json!([{"name": "grey", "pbrMetallicRoughness": {
            "baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0,
            "roughnessFactor": 1.0}}]),
    );
    b.set(
        "meshes",
        json!([{"name": "square", "primitives": [square]}]),
    );
    b.set("nodes", json!([{"name": "square", "mesh": 0}]));
    b.set("scenes", json!([{"nodes": [0]}]));
    b.set("scene", json!(0));
    b.write_glb(dir, "square")
}

// A glTF model a micrometre across (positions ~1e-6) without a camera was framed as if it were a
// millimetre across: the bake had no rows, exited 0 and said nothing. The framing now takes the
// model's own size.
#[test]
fn a_tiny_gltf_model_without_a_camera_is_framed_by_its_own_size() {
    let dir = temp_dir("hostile-stored-tiny");
    let path = square_without_camera(&dir, 1e-6);
    let framing = Framing {
        width: Some(24),
        height: Some(18),
        ..Framing::default()
    };
    let scene = Scene::load_with(&path, &framing).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    let cam = scene.camera.clone();
    let (w, h) = (cam.width as usize, cam.height as usize);
    // The camera's rays through the pixel centres meet the square: it fills a good part of the
    // view (about 30%).
    let tracer = Tracer::new(&scene);
    let hits = (0..w * h)
        .filter(|&i| {
            let ray = cam.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            tracer
                .closest_hit(ray.origin, ray.dir, f32::INFINITY)
                .is_some()
        })
        .count();
    assert!(
        hits * 10 > w * h,
        "{hits} of {} pixel centres see the model",
        w * h
    );
    // The bake has rows, covers those pixels, and they relight to light under a white sky.
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 2,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    assert!(t.meta.stats.rows > 0);
    let covered: Vec<usize> = (0..w * h).filter(|&i| t.coverage[i] > 0.0).collect();
    assert!(
        covered.len() * 10 > w * h,
        "{} pixels covered",
        covered.len()
    );
    let white = EnvMap::from_pixels(8, 4, vec![[1.0; 3]; 32], "white").unwrap();
    let image = relit(&t, &white, EnvRotation::default(), RelightRequest::Full);
    let lit = covered
        .iter()
        .filter(|&&i| image.pixels[i].iter().all(|&c| c.is_finite() && c > 0.0))
        .count();
    assert_eq!(lit, covered.len(), "covered pixels that relight to nothing");
}

// A bake whose camera saw nothing wrote `rows 0` and exited 0 without a word. It now warns.
#[test]
fn a_bake_whose_camera_looks_away_warns() {
    let dir = temp_dir("hostile-stored-away");
    let seen = plane_from_above(8, 6, [0.5; 3], 1.0);
    let away = seen.replace("target = [0.0, 0.0, 0.0]", "target = [0.0, 6.0, 0.0]");
    assert_ne!(away, seen);
    let warning = "warning: no pixel of the camera sees the scene";
    for (name, toml, warned) in [("seen", &seen, false), ("away", &away, true)] {
        let scene = dir.join(format!("{name}.toml"));
        std::fs::write(&scene, toml).unwrap();
        let out = dir.join(format!("{name}.prt"));
        let (code, text) = prt(&[
            "bake",
            s(&scene),
            "-o",
            s(&out),
            "--cube",
            "4",
            "--sh-order",
            "2",
        ]);
        assert_eq!(code, 0, "{name}: {text}");
        assert_eq!(text.contains(warning), warned, "{name}: {text}");
    }
}

/// A per-vertex bake of the textured glTF test scene (a checker ground, a grey box: two
/// materials, the ground's with an albedo map), saved in `dir`.
fn textured_vertex_bake(dir: &Path) -> std::path::PathBuf {
    let gltf = test_scene(8, false).write_glb(dir, "scene");
    let scene = Scene::load_with(
        &gltf,
        &Framing {
            width: Some(32),
            ..Framing::default()
        },
    )
    .unwrap();
    assert_eq!(scene.materials.len(), 2);
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        unshadowed: true,
        domain: BakeDomain::Vertices { edge_length: 1.0 },
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let path = dir.join("v.prt");
    t.save(&path).unwrap();
    path
}

/// `file` with `edit` made to tensor `tensor`'s first four bytes, resealed (checksums made to
/// agree) as `bad.prt` in `dir`: the error loading it gives, which must name the file and the
/// tensor.
fn refused_with_tensor_named(dir: &Path, file: &StFile, tensor: &str, edit: [u8; 4]) -> String {
    let mut st = file.clone();
    st.tensor_mut(tensor)[..4].copy_from_slice(&edit);
    let bad = dir.join("bad.prt");
    st.write(&bad, true);
    let e = match Transport::load(&bad) {
        Ok(_) => panic!("{tensor} edited to {edit:?}: loaded"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("bad.prt") && e.contains(&format!("`{tensor}`")),
        "{tensor}: {e}"
    );
    e
}

// A resealed per-vertex file with a NaN normal, a vertex of material 7 of 2, or an albedo map of
// material 999999 loaded, and drew another image on the CPU and the GPU. Each is refused now,
// naming the file and the tensor; so are non-finite positions and texture coordinates.
#[test]
fn resealed_per_vertex_values_are_refused_by_tensor() {
    let dir = temp_dir("hostile-stored-vertex");
    let path = textured_vertex_bake(&dir);
    let t = Transport::load(&path).unwrap();
    assert_eq!(t.meta.per_vertex.as_ref().unwrap().materials, 2);
    let file = StFile::read(&path);
    // Resealed unedited, the file loads: the edits below are what is refused.
    let same = dir.join("same.prt");
    file.write(&same, true);
    assert_eq!(Transport::load(&same).unwrap(), t);
    let nan = f32::NAN.to_le_bytes();
    refused_with_tensor_named(&dir, &file, "mesh_normal", nan);
    let e = refused_with_tensor_named(&dir, &file, "mesh_material", 7u32.to_le_bytes());
    assert!(e.contains("material 7") && e.contains("2 materials"), "{e}");
    // The first map's first material.
    let e = refused_with_tensor_named(&dir, &file, "albedo_map_material", 999999u32.to_le_bytes());
    assert!(e.contains("999999"), "{e}");
    refused_with_tensor_named(&dir, &file, "mesh_position", nan);
    refused_with_tensor_named(&dir, &file, "mesh_uv", f32::INFINITY.to_le_bytes());
    // A file from before the material count was recorded still refuses a map of a material no
    // vertex has.
    let mut older = file.clone();
    older.meta["per_vertex"]
        .as_object_mut()
        .unwrap()
        .remove("materials")
        .expect("the count is recorded");
    let old = dir.join("old.prt");
    older.write(&old, true);
    let back = Transport::load(&old).unwrap();
    assert_eq!(back.meta.per_vertex.as_ref().unwrap().materials, 0);
    let e = refused_with_tensor_named(&dir, &older, "albedo_map_material", 999999u32.to_le_bytes());
    assert!(e.contains("no vertex"), "{e}");
}
