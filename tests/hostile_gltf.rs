//! Hostile input, fourth round: glTF files that name files outside their folder, one model
//! named many times or instanced past memory, stacked copies of triangles, bundled assets over
//! a user's files, study commands that would write over their inputs, and `--env none` where
//! it does not apply. One test per defect, named after it.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{SPHERE_ON_PLANE, assert_clean_error, prt, run, s, temp_dir};
use serde_json::json;
use wavelet_prt::scene::{Framing, Scene};

/// `dir/model/m.gltf` (the tests' glTF scene, its buffer and image as files beside it) with its
/// buffer's URI replaced by `uri`; `dir/secret.bin` holds the buffer's bytes, outside the
/// model's folder, so that a URI reaching it would load a working scene.
fn model_with_buffer_uri(dir: &Path, uri: &str) -> PathBuf {
    let folder = dir.join("model");
    std::fs::create_dir_all(&folder).unwrap();
    let path = common::gltf::test_scene(4, false).write_gltf(&folder, "m");
    std::fs::copy(folder.join("m data.bin"), dir.join("secret.bin")).unwrap();
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    doc["buffers"][0]["uri"] = json!(uri);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

fn framed(outside: bool) -> Framing {
    Framing {
        width: Some(24),
        height: Some(16),
        read_outside_folder: outside,
        ..Framing::default()
    }
}

#[test]
fn gltf_uris_that_leave_the_model_folder_are_refused() {
    let dir = temp_dir("hostile4-uri");
    for uri in [
        "../secret.bin",
        "..%2Fsecret.bin",
        "%2e%2e/secret.bin",
        "sub/../../secret.bin",
        "../../../../../../../../proc/self/environ",
    ] {
        let path = model_with_buffer_uri(&dir, uri);
        let e = Scene::load_with(&path, &framed(false))
            .err()
            .unwrap_or_else(|| panic!("{uri} was read"))
            .to_string();
        assert!(e.contains("buffers[0].uri"), "{uri}: {e}");
        assert!(
            e.contains("outside the folder") || e.contains("No such file"),
            "{uri}: {e}"
        );
    }
    // The same file reached through a link in the folder is outside too.
    let path = model_with_buffer_uri(&dir, "link.bin");
    let link = dir.join("model/link.bin");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(dir.join("secret.bin"), &link).unwrap();
    let e = Scene::load_with(&path, &framed(false))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("outside the folder") && e.contains("link.bin"),
        "{e}"
    );
    // With the flag, both load, and the scene lists the file it read.
    let scene = Scene::load_with(&path, &framed(true)).unwrap();
    let secret = std::fs::canonicalize(dir.join("secret.bin")).unwrap();
    assert!(
        scene.input_files.contains(&secret),
        "{:?}",
        scene.input_files
    );
    let path = model_with_buffer_uri(&dir, "..%2Fsecret.bin");
    assert!(Scene::load_with(&path, &framed(true)).is_ok());
    // A file in a subfolder is inside.
    std::fs::create_dir_all(dir.join("model/sub")).unwrap();
    std::fs::copy(dir.join("secret.bin"), dir.join("model/sub/b.bin")).unwrap();
    let path = model_with_buffer_uri(&dir, "sub/b.bin");
    assert!(Scene::load_with(&path, &framed(false)).is_ok());
}

#[test]
fn a_pseudo_file_whose_size_is_not_its_content_is_refused() {
    // `/proc/self/environ` says 0 bytes and holds the environment.
    let e = wavelet_prt::files::read_regular(Path::new("/proc/self/environ"), 1 << 20, "buffer")
        .unwrap_err()
        .to_string();
    assert!(e.contains("regular file"), "{e}");
}

#[test]
fn the_bake_says_which_files_a_gltf_read_and_the_flag_reads_outside() {
    let dir = temp_dir("hostile4-bake-uri");
    let path = model_with_buffer_uri(&dir, "../secret.bin");
    let out = dir.join("m.prt");
    let base = [
        "bake",
        s(&path),
        "-o",
        s(&out),
        "--cube",
        "4",
        "--sh-order",
        "2",
        "--width",
        "12",
        "--height",
        "8",
    ];
    let (code, text) = prt(&base);
    assert_clean_error(
        code,
        &text,
        &["outside the folder", "--read-outside-folder"],
    );
    assert!(!out.exists());
    let mut args = base.to_vec();
    args.push("--read-outside-folder");
    let (code, text) = prt(&args);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("read") && text.contains("secret.bin") && text.contains("m_image0.png"),
        "{text}"
    );
}

/// A TOML scene placing `name` `copies` times, side by side.
fn placed_many_times(dir: &Path, name: &str, copies: usize) -> PathBuf {
    let mut text = String::from(
        "[camera]\neye = [0, 6, 14]\ntarget = [0, 0, 0]\nup = [0, 1, 0]\nfov_y_deg = 60\n\
         width = 16\nheight = 12\n",
    );
    for k in 0..copies {
        text += &format!(
            "\n[[shape]]\ntype = \"gltf\"\npath = \"{name}\"\ntranslate = [{}, 0, 0]\n",
            5.0 * k as f32
        );
    }
    let p = dir.join("many.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_gltf_named_many_times_is_read_and_decoded_once() {
    let dir = temp_dir("hostile4-many");
    let glb = common::gltf::test_scene(4, false).write_glb(&dir, "m");
    let once = Scene::load(&placed_many_times(&dir, "m.glb", 1)).unwrap();
    let six = Scene::load(&placed_many_times(&dir, "m.glb", 6)).unwrap();
    // One decoded texture and one set of materials, six placements of the triangles.
    assert_eq!(six.textures.len(), once.textures.len());
    assert_eq!(six.materials.len(), once.materials.len());
    assert_eq!(six.triangles.len(), 6 * once.triangles.len());
    // Each copy is the first moved along x, with the same materials.
    let n = once.triangles.len();
    for (k, copy) in six.triangles.chunks(n).enumerate() {
        for (a, b) in copy.iter().zip(&once.triangles) {
            assert_eq!(a.material, b.material);
            for (p, q) in a.vertices.iter().zip(&b.vertices) {
                assert!((*p - glam::Vec3::new(5.0 * k as f32, 0.0, 0.0) - *q).length() < 1e-5);
            }
        }
    }
    // The file is read once.
    assert_eq!(
        six.input_files
            .iter()
            .filter(|f| f.file_name() == glb.file_name())
            .count(),
        1,
        "{:?}",
        six.input_files
    );
}

/// A GLB of one mesh, a strip of `2 * quads` triangles, placed by `nodes` nodes, each moved by
/// `step` along z from the last (0: all stacked in one place).
fn instanced_glb(dir: &Path, quads: usize, nodes: usize, step: f32) -> PathBuf {
    let mut b = common::gltf::GltfBuilder::default();
    let mut positions = Vec::new();
    for i in 0..=quads {
        positions.push([i as f32 * 0.01, 0.0, 0.0]);
        positions.push([i as f32 * 0.01, 0.0, 0.01]);
    }
    let mut indices = Vec::new();
    for i in 0..quads as u16 {
        let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
        indices.extend_from_slice(&[a, b, c, c, b, d]);
    }
    let prim = b.primitive(&positions, [0.0, 1.0, 0.0], None, &indices, 0);
    b.set(
        "materials",
        json!([{"pbrMetallicRoughness": {"metallicFactor": 0.0}}]),
    );
    b.set("meshes", json!([{"primitives": [prim]}]));
    let nodes_json: Vec<_> = (0..nodes)
        .map(|k| json!({"mesh": 0, "translation": [0.0, 0.0, step * k as f32]}))
        .collect();
    b.set("nodes", json!(nodes_json));
    b.set("scenes", json!([{"nodes": (0..nodes).collect::<Vec<_>>()}]));
    b.write_glb(dir, "instanced")
}

#[test]
fn stacked_copies_of_a_mesh_are_made_once() {
    let dir = temp_dir("hostile4-stacked");
    let one = Scene::load_with(&instanced_glb(&dir, 100, 1, 0.0), &framed(false)).unwrap();
    let stacked = Scene::load_with(&instanced_glb(&dir, 100, 500, 0.0), &framed(false)).unwrap();
    assert_eq!(one.triangles.len(), 200);
    assert_eq!(stacked.triangles.len(), 200);
    assert!(
        stacked
            .ignored
            .iter()
            .any(|l| l.contains("99800 triangles")),
        "{:?}",
        stacked.ignored
    );
    // Copies side by side are all kept.
    let spread = Scene::load_with(&instanced_glb(&dir, 100, 50, 0.02), &framed(false)).unwrap();
    assert_eq!(spread.triangles.len(), 50 * 200);
}

#[test]
fn instancing_past_memory_is_an_error_not_an_abort() {
    let dir = temp_dir("hostile4-instanced");
    // 30,000 triangles placed 1,500 times: 45 M triangles, 4.5 GB, under a 3 GB address space
    // (and within the scene's limit on corners, so that memory is what refuses it).
    let glb = instanced_glb(&dir, 15_000, 1_500, 0.02);
    let out = dir.join("x.prt");
    let (code, text) = run(Command::new("sh").args([
        "-c",
        "ulimit -v 3000000; exec \"$0\" \"$@\"",
        env!("CARGO_BIN_EXE_prt"),
        "bake",
        s(&glb),
        "-o",
        s(&out),
        "--cube",
        "4",
        "--width",
        "8",
    ]));
    assert_clean_error(code, &text, &["meshes[0].primitives[0]", "GiB"]);
}

#[test]
fn bundled_assets_never_replace_a_users_files() {
    let dir = temp_dir("hostile4-assets");
    let mut log = Vec::new();
    let root =
        wavelet_prt::app::studies::demo::write_assets(&dir, &mut |l| log.push(l.to_string()))
            .unwrap();
    assert!(log.is_empty(), "{log:?}");
    let mine = root.join("scenes/spheres.toml");
    std::fs::write(&mine, "# my own edit\n").unwrap();
    std::fs::remove_file(root.join("scenes/fog.toml")).unwrap();
    let root =
        wavelet_prt::app::studies::demo::write_assets(&dir, &mut |l| log.push(l.to_string()))
            .unwrap();
    assert_eq!(std::fs::read_to_string(&mine).unwrap(), "# my own edit\n");
    assert!(
        root.join("scenes/fog.toml").exists(),
        "a missing asset is written"
    );
    assert_eq!(log.len(), 1, "{log:?}");
    assert!(
        log[0].contains("scenes/spheres.toml") && log[0].contains("kept"),
        "{log:?}"
    );
}

#[test]
fn study_commands_never_write_over_their_inputs() {
    let dir = temp_dir("hostile4-study-inputs");
    // The scene is named as the report the study writes into the same folder.
    let scene = dir.join("bounces.md");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let (code, text) = prt(&[
        "bounces",
        s(&scene),
        "--env",
        "sun:40,30",
        "--out",
        s(&dir),
        "--max-bounces",
        "0",
        "--samples",
        "1",
        "--cube",
        "4",
        "--width",
        "8",
        "--height",
        "6",
    ]);
    assert_clean_error(code, &text, &["bounces.md", "also an input"]);
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), SPHERE_ON_PLANE);
    // Refused before any work, as a single output is.
    assert!(!dir.join("bounces_sheet.png").exists());
}

#[test]
fn env_none_is_refused_clearly_where_it_does_not_apply() {
    let dir = temp_dir("hostile4-env-none");
    let scene = dir.join("s.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let glossy = dir.join("g.toml");
    std::fs::write(&glossy, common::glossy_sphere()).unwrap();
    let out = dir.join("out");
    for args in [
        vec!["bounces", s(&scene), "--env", "none", "--out", s(&out)],
        vec!["gloss", s(&glossy), "--env", "none", "--out", s(&out)],
    ] {
        let (code, text) = prt(&args);
        assert_clean_error(code, &text, &["--env", "needs an environment"]);
        assert!(!text.contains("No such file"), "{text}");
    }
    let fog = dir.join("fog.toml");
    std::fs::write(&fog, common::fog_scene(0.3, 8, 6)).unwrap();
    let (code, text) = prt(&[
        "volume",
        "reference",
        s(&fog),
        "--env",
        "none",
        "-o",
        s(&dir.join("r.exr")),
    ]);
    assert_clean_error(code, &text, &["--env", "needs an environment"]);
}
