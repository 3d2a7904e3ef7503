//! A new user's first hour on a machine without a GPU: the device chosen when nobody asks, the
//! messages a session-less machine prints, files of the wrong kind, and help texts that say what
//! the code does.

mod common;

use std::path::Path;
use std::process::Command;

use common::{SPHERE_ON_PLANE, assert_clean_error, s, temp_dir};
use wavelet_prt::output::film::Image;
use wavelet_prt::output::metrics::relative_l2;

/// Runs `prt` as on a machine without a login session (no `XDG_RUNTIME_DIR`) and without the
/// variable cargo sets for the programs it runs; returns (exit code, stdout + stderr).
fn prt_sessionless(args: &[&str]) -> (i32, String) {
    common::run(
        Command::new(env!("CARGO_BIN_EXE_prt"))
            .args(args)
            .env_remove("XDG_RUNTIME_DIR")
            .env_remove("NODEVICE_SELECT"),
    )
}

/// Runs `prt` with `args` in the working folder `dir`; returns (exit code, stdout + stderr).
fn prt_in(dir: &Path, args: &[&str]) -> (i32, String) {
    common::run(
        Command::new(env!("CARGO_BIN_EXE_prt"))
            .args(args)
            .current_dir(dir),
    )
}

/// A small baked scene in `dir`.
fn baked(dir: &Path) -> std::path::PathBuf {
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let out = dir.join("t.prt");
    let (code, text) = common::prt(&["bake", s(&scene), "-o", s(&out), "--cube", "4"]);
    assert_eq!(code, 0, "{text}");
    out
}

// 1. The software adapter was the default: `prt bench` ran 27 minutes on lavapipe where the CPU
// took 11 s. `--device auto`, the default, takes a hardware GPU only.
#[test]
fn a_software_adapter_is_used_only_when_asked_for() {
    let Some(gpu) = common::gpu_or_skip("a_software_adapter_is_used_only_when_asked_for") else {
        return;
    };
    let dir = temp_dir("first-hour-device");
    let t = baked(&dir);
    let png = dir.join("out.png");
    let relight = |device: Option<&str>| {
        let mut args = vec!["relight", s(&t), "--env", "sun:30,40", "--terms", "20"];
        args.extend(["-o", s(&png)]);
        if let Some(d) = device {
            args.extend(["--device", d]);
        }
        let (code, text) = prt_sessionless(&args);
        assert_eq!(code, 0, "{text}");
        text
    };
    let default = relight(None);
    if gpu.software {
        assert!(default.contains("on the CPU"), "{default}");
        assert!(!default.contains("software adapter"), "{default}");
        // Asked for by name, it is used and said to be a software adapter, in one line.
        let asked = relight(Some("gpu"));
        assert!(asked.contains("on the GPU"), "{asked}");
        let notes: Vec<&str> = asked
            .lines()
            .filter(|l| l.contains("software adapter"))
            .collect();
        assert_eq!(notes.len(), 1, "{asked}");
    } else {
        assert!(default.contains("on the GPU"), "{default}");
    }
    let cpu = relight(Some("cpu"));
    assert!(cpu.contains("on the CPU"), "{cpu}");
    // The light is prepared beside the transport's load.
    assert!(cpu.contains("prepared beside the load in"), "{cpu}");
}

// 5. Mesa's device-select layer printed "error: XDG_RUNTIME_DIR is invalid or not set" up to
// four times on every GPU command of the installed binary.
#[test]
fn no_error_line_without_a_login_session() {
    if common::gpu_or_skip("no_error_line_without_a_login_session").is_none() {
        return;
    }
    let dir = temp_dir("first-hour-session");
    let t = baked(&dir);
    let png = dir.join("out.png");
    for args in [
        vec![
            "relight",
            s(&t),
            "--env",
            "sun:30,40",
            "--terms",
            "20",
            "--device",
            "gpu",
            "-o",
            s(&png),
        ],
        vec![
            "relight",
            s(&t),
            "--env",
            "sun:30,40",
            "--terms",
            "20",
            "-o",
            s(&png),
        ],
        vec![
            "view",
            s(&t),
            "--env",
            "sun:30,40",
            "--terms",
            "20",
            "--screenshot",
            s(&png),
        ],
    ] {
        let (code, text) = prt_sessionless(&args);
        assert_eq!(code, 0, "{args:?}: {text}");
        assert!(
            !text
                .lines()
                .any(|l| l.to_ascii_lowercase().contains("error")),
            "{args:?}: {text}"
        );
    }
}

// 5. A scene given where a bake is expected gave "header length 7958545825611718691 does not fit
// a file of 1506 bytes".
#[test]
fn a_file_of_the_wrong_kind_is_named_with_what_to_do() {
    let dir = temp_dir("first-hour-kinds");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let png = dir.join("out.png");
    let exr = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/envmaps/blender_night.exr");
    let obj = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/meshes/suzanne.obj");
    for (args, needles) in [
        (
            vec!["relight", s(&scene), "--env", "sun:30,40", "-o", s(&png)],
            vec!["a scene file, not a transport file", "prt bake"],
        ),
        (vec!["info", s(&scene)], vec!["a scene file", "prt bake"]),
        (
            vec!["view", s(&scene), "--screenshot", s(&png)],
            vec!["a scene file", "prt bake"],
        ),
        (
            vec![
                "volume",
                "render",
                s(&scene),
                "--env",
                "sun:30,40",
                "-o",
                s(&png),
            ],
            vec!["a scene file, not a volume file", "prt volume bake"],
        ),
        (
            vec!["relight", s(&exr), "--env", "sun:30,40", "-o", s(&png)],
            vec!["an OpenEXR image, not a transport file", "--env"],
        ),
        (vec!["info", s(&obj)], vec!["an OBJ mesh", "[[shape]]"]),
    ] {
        let (code, text) = common::prt(&args);
        assert_eq!(code, 1, "{args:?}: {text}");
        for n in needles {
            assert!(text.contains(n), "{args:?}: `{n}` not in {text}");
        }
        assert!(!text.contains("header length"), "{text}");
    }
}

// 5. `prt bake --help` described the estimator `--bounces` had before next-event rows; the
// device flags name what `auto` does.
#[test]
fn help_texts_name_the_current_behaviour() {
    let help = |args: &[&str]| {
        let (code, text) = common::prt(args);
        assert_eq!(code, 0, "{text}");
        text
    };
    let relight = help(&["relight", "--help"]);
    assert!(
        !relight.contains("up to 128") && relight.matches("up to 142").count() == 2,
        "{relight}"
    );
    assert!(help(&["view", "--help"]).contains("sun:ELEV,AZIM[,RADIUS]"));
    let bake = help(&["bake", "--help"]);
    assert!(
        bake.contains("next-event") && !bake.contains("binned"),
        "{bake}"
    );
    for cmd in [
        &["relight", "--help"][..],
        &["bench", "--help"],
        &["volume", "render", "--help"],
    ] {
        let text = help(cmd);
        assert!(
            text.contains("hardware GPU when one exists") && text.contains("[default: auto]"),
            "{cmd:?}: {text}"
        );
    }
    // Every command's --env goes through one loader, which takes a bundled map by name.
    for cmd in [
        &["relight", "--help"][..],
        &["bench", "--help"],
        &["bounces", "--help"],
        &["gloss", "--help"],
        &["volume", "render", "--help"],
        &["volume", "reference", "--help"],
        &["volume", "orders", "--help"],
    ] {
        let text = help(cmd);
        assert!(text.contains("bundled map"), "{cmd:?}: {text}");
    }
}

// A study given an input that is not there (or a scene without the medium it studies) made
// its output folder before it said so, and left it behind empty. The inputs are read first.
#[test]
fn a_study_whose_input_is_missing_leaves_no_folder() {
    let dir = temp_dir("first-hour-missing-input");
    let missing = dir.join("not-there.toml");
    let missing_prt = dir.join("not-there.prt");
    // And a scene with no medium, for the study of a medium.
    let no_medium = dir.join("not-there-a-medium.toml");
    std::fs::write(&no_medium, SPHERE_ON_PLANE).unwrap();
    let runs: [(&str, Vec<&str>); 5] = [
        (
            "bounces",
            vec!["bounces", s(&missing), "--env", "sun:40,60"],
        ),
        ("gloss", vec!["gloss", s(&missing), "--env", "sun:40,60"]),
        (
            "bench",
            vec!["bench", s(&missing_prt), "--env", "sun:40,60"],
        ),
        (
            "orders",
            vec!["volume", "orders", s(&missing), "--env", "sun:40,60"],
        ),
        (
            "orders-no-medium",
            vec!["volume", "orders", s(&no_medium), "--env", "sun:40,60"],
        ),
    ];
    for (name, mut args) in runs {
        let out = dir.join(format!("out-{name}"));
        args.extend(["--out", s(&out)]);
        let (code, text) = common::prt(&args);
        assert_ne!(code, 0, "{name}: {text}");
        assert!(text.contains("not-there"), "{name}: {text}");
        assert!(!out.exists(), "{name} made {}", out.display());
    }
}

// 5. Every bundled map printed its "negative samples" note on every command. Negatives that hold
// a noticeable share of a map's power are said once per map; a lossy encoder's few are not.
#[test]
fn negative_samples_are_noted_once_and_only_when_they_matter() {
    let dir = temp_dir("first-hour-notes");
    let t = baked(&dir);
    let png = dir.join("out.png");
    let sunrise = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/envmaps/blender_sunrise.exr");
    let (code, text) = common::prt(&[
        "relight",
        s(&t),
        "--env",
        s(&sunrise),
        "--terms",
        "20",
        "-o",
        s(&png),
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(!text.contains("note:"), "{text}");
    // A map with a patch of negative samples holding 2% of its power, given twice.
    let map = dir.join("patchy.exr");
    exr::prelude::write_rgb_file(&map, 32, 16, |x, y| {
        if x < 2 && y == 8 {
            (-0.8f32, -0.8, -0.8)
        } else {
            (1.0f32, 1.0, 1.0)
        }
    })
    .unwrap();
    let out = dir.join("bench");
    let (code, text) = common::prt(&[
        "bench",
        s(&t),
        "--env",
        s(&map),
        s(&map),
        "--out",
        s(&out),
        "--terms",
        "5",
        "--sh-orders",
        "1",
        "--sh-light-orders",
        "none",
    ]);
    assert_eq!(code, 0, "{text}");
    let notes: Vec<&str> = text.lines().filter(|l| l.starts_with("note:")).collect();
    assert_eq!(notes.len(), 1, "{text}");
    assert!(
        notes[0].contains("6 of its 1536 samples are negative"),
        "{}",
        notes[0]
    );
}

/// Relative L2 within which two relights of the same per-vertex rows from the same camera agree:
/// the same f32 sums in the same order, which round alike.
const SAME_IMAGE: f64 = 1e-6;

// 1. From a scene camera whose up leaned forward, `prt relight --eye` of a per-vertex bake kept
// that up, and vertical edges leaned ~20°. A moved camera keeps the world's up (or --up).
#[test]
fn a_moved_camera_keeps_the_world_up_whatever_the_scene_camera_leaned() {
    let dir = temp_dir("first-hour-upright");
    let level_up = "up = [0.0, 1.0, 0.0]";
    assert!(SPHERE_ON_PLANE.contains(level_up));
    let tilted = SPHERE_ON_PLANE.replace(level_up, "up = [0.0, 0.935, -0.355]");
    let relit = |name: &str, bake: &Path, extra: &[&str]| {
        let exr = dir.join(format!("{name}.exr"));
        let mut args = vec!["relight", s(bake), "--env", "sun:30,40", "--eye", "5,2.2,0"];
        args.extend(extra);
        args.extend(["--device", "cpu", "-o", s(&exr)]);
        let (code, text) = common::prt(&args);
        assert_eq!(code, 0, "{args:?}: {text}");
        Image::load_exr(&exr).unwrap()
    };
    let mut bakes = Vec::new();
    for (name, text) in [("level", SPHERE_ON_PLANE.to_string()), ("tilted", tilted)] {
        let scene = dir.join(format!("{name}.toml"));
        std::fs::write(&scene, text).unwrap();
        let bake = dir.join(format!("{name}.prt"));
        let (code, out) = common::prt(&[
            "bake",
            s(&scene),
            "-o",
            s(&bake),
            "--per-vertex",
            "--edge-length",
            "0.5",
            "--cube",
            "4",
            "--sh-order",
            "2",
        ]);
        assert_eq!(code, 0, "{out}");
        bakes.push(bake);
    }
    let level = relit("level", &bakes[0], &[]);
    let tilted = relit("tilted", &bakes[1], &[]);
    let e = relative_l2(&tilted, &level, None).unwrap();
    assert!(
        e < SAME_IMAGE,
        "the tilted scene camera rolled the moved one: {e}"
    );
    // --up 0,1,0 is the default; another up rolls the image.
    let asked = relit("asked", &bakes[1], &["--up", "0,1,0"]);
    assert!(relative_l2(&asked, &level, None).unwrap() < SAME_IMAGE);
    // Leaning towards +Z, across the view along −X: a roll of 45°.
    let rolled = relit("rolled", &bakes[0], &["--up", "0,1,1"]);
    assert!(relative_l2(&rolled, &level, None).unwrap() > 0.01);
    let png = dir.join("zero.png");
    let (code, text) = common::prt(&[
        "relight",
        s(&bakes[0]),
        "--env",
        "sun:30,40",
        "--eye",
        "5,2.2,0",
        "--up",
        "0,0,0",
        "-o",
        s(&png),
    ]);
    assert!(code != 0 && text.contains("zero vector"), "{text}");
}

// 2. `--eye -3.5,3.5,3.5` gave clap's "unexpected argument '-3' found": vector flags take a
// leading minus as written.
#[test]
fn vector_flags_take_negative_numbers_as_written() {
    let dir = temp_dir("first-hour-minus");
    let t = common::per_vertex_transport_path();
    let png = dir.join("minus.png");
    let (code, text) = common::prt(&[
        "relight",
        s(&t),
        "--eye",
        "-3.5,3.5,3.5",
        "--target",
        "-0.1,0.5,0",
        "--up",
        "-0.1,1,0",
        "--env",
        "sun:30,40",
        "--device",
        "cpu",
        "-o",
        s(&png),
    ]);
    assert_eq!(code, 0, "{text}");
    // The other commands' vector flags parse too: each fails later, on the missing input.
    let missing = dir.join("missing.toml");
    let missing_bake = dir.join("missing.prt");
    let (gloss, bench) = (dir.join("gloss"), dir.join("bench"));
    for args in [
        vec![
            "reference",
            s(&missing),
            "--eye",
            "-3,2,1",
            "--target",
            "-1,0,0",
            "--up",
            "-0.2,1,0",
            "--env",
            "sun:30,40",
            "-o",
            s(&png),
        ],
        vec![
            "gloss",
            s(&missing),
            "--eye",
            "-3,2,1",
            "--eye",
            "-1,2,-3",
            "--target",
            "-1,0,0",
            "--up",
            "0,1,-0.1",
            "--env",
            "sun:30,40",
            "--out",
            s(&gloss),
        ],
        vec![
            "bench",
            s(&missing_bake),
            "--eye",
            "-3,2,1",
            "--target",
            "-1,0,0",
            "--env",
            "sun:30,40",
            "--out",
            s(&bench),
        ],
    ] {
        let (code, text) = common::prt(&args);
        assert!(!text.contains("unexpected argument"), "{args:?}: {text}");
        assert_clean_error(code, &text, &["missing"]);
    }
}

// 3. `prt info` did not print the camera, and said `image 16 x 6097` and `bytes/pixel` of a
// per-vertex bake.
#[test]
fn info_prints_the_camera_and_counts_a_per_vertex_bake_in_vertices() {
    let camera = "camera        eye (0.000, 1.500, 4.000), target (0.000, 0.500, 0.000), up \
                  (0.000, 1.000, 0.000), fov_y_deg 40, 37 x 21";
    let (code, text) = common::prt(&["info", s(&common::per_vertex_transport_path())]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(camera), "{text}");
    assert!(text.contains("bytes/vertex"), "{text}");
    assert!(!text.contains("bytes/pixel"), "{text}");
    assert!(!text.lines().any(|l| l.starts_with("image")), "{text}");
    let dir = temp_dir("first-hour-info");
    let (code, text) = common::prt(&["info", s(&baked(&dir))]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(camera), "{text}");
    assert!(
        text.contains("image         37 x 21") && text.contains("bytes/pixel"),
        "{text}"
    );
}

// 4. `--env blender_sunrise.exr` away from the checkout found no file, though the map is in the
// binary. The bundled maps are taken by name, listed by `prt env --list` and named when a map
// is missing; a file of that name in the working folder comes first.
#[test]
fn bundled_maps_are_found_by_name_from_any_folder() {
    let dir = temp_dir("first-hour-bundled");
    let t = baked(&dir);
    let work = dir.join("work");
    std::fs::create_dir_all(&work).unwrap();
    let png = dir.join("sunrise.png");
    for name in ["blender_sunrise", "blender_sunrise.exr"] {
        let (code, text) = prt_in(
            &work,
            &[
                "relight",
                s(&t),
                "--env",
                name,
                "--terms",
                "20",
                "--device",
                "cpu",
                "-o",
                s(&png),
            ],
        );
        assert_eq!(code, 0, "{name}: {text}");
    }
    let (code, text) = prt_in(&work, &["env", "blender_sunrise", "--cube", "4"]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("blender_sunrise (bundled)"), "{text}");
    let (code, text) = prt_in(&work, &["env", "blender_sundown.exr"]);
    assert_clean_error(
        code,
        &text,
        &[
            "blender_sundown.exr",
            "blender_sunrise, blender_city, blender_interior, blender_night, blender_studio, \
             pmndrs_city_overcast",
            "prt env --list",
        ],
    );
    let (code, text) = prt_in(&work, &["env", "--list"]);
    assert_eq!(code, 0, "{text}");
    assert_eq!(
        text.lines().collect::<Vec<_>>(),
        [
            "blender_sunrise",
            "blender_city",
            "blender_interior",
            "blender_night",
            "blender_studio",
            "pmndrs_city_overcast"
        ]
    );
    // A file of the name is read before the bundled map.
    exr::prelude::write_rgb_file(work.join("blender_sunrise.exr"), 32, 16, |_, _| {
        (1.0f32, 1.0, 1.0)
    })
    .unwrap();
    let (code, text) = prt_in(&work, &["env", "blender_sunrise.exr", "--cube", "4"]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("32 x 16") && !text.contains("bundled"),
        "{text}"
    );
}

// 5. `prt bench /elsewhere/mine.prt --reference` from another folder gave "mine.toml: No such
// file or directory": the scene a bake recorded is also looked for beside the bake.
#[test]
fn the_scene_of_a_bake_is_found_beside_it() {
    let dir = temp_dir("first-hour-scene-beside");
    let (baked_in, elsewhere) = (dir.join("a"), dir.join("b"));
    std::fs::create_dir_all(&baked_in).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    std::fs::write(baked_in.join("mine.toml"), SPHERE_ON_PLANE).unwrap();
    let (code, text) = prt_in(
        &baked_in,
        &[
            "bake",
            "mine.toml",
            "-o",
            "mine.prt",
            "--cube",
            "4",
            "--sh-order",
            "2",
        ],
    );
    assert_eq!(code, 0, "{text}");
    let bake = baked_in.join("mine.prt");
    let out = elsewhere.join("bench");
    let bench = || {
        prt_in(
            &elsewhere,
            &[
                "bench",
                s(&bake),
                "--env",
                "sun:30,40",
                "--out",
                s(&out),
                "--terms",
                "5",
                "--sh-orders",
                "1",
                "--sh-light-orders",
                "none",
                "--reference",
            ],
        )
    };
    let (code, text) = bench();
    assert_eq!(code, 0, "{text}");
    std::fs::remove_file(baked_in.join("mine.toml")).unwrap();
    let (code, text) = bench();
    assert_clean_error(code, &text, &["mine.toml", "--scene"]);
}

/// [`SPHERE_ON_PLANE`] with a point light `lamp` baked at `positions` (a TOML array of points).
fn with_lamp(positions: &str) -> String {
    format!(
        "{SPHERE_ON_PLANE}\n[[light]]\nname = \"lamp\"\ntype = \"point\"\npositions = \
         {positions}\nintensity = 1.0\n"
    )
}

/// Bakes `text` as `name` in `dir` (cube 4, SH order 2, `extra` flags); returns the transport
/// file and what the bake printed.
fn bake_text(dir: &Path, name: &str, text: &str, extra: &[&str]) -> (std::path::PathBuf, String) {
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(&scene, text).unwrap();
    let out = dir.join(format!("{name}.prt"));
    let mut args = vec![
        "bake",
        s(&scene),
        "-o",
        s(&out),
        "--cube",
        "4",
        "--sh-order",
        "2",
    ];
    args.extend(extra);
    let (code, printed) = common::prt(&args);
    assert_eq!(code, 0, "{printed}");
    (out, printed)
}

// 6a. `--env none` printed "1 terms … 30989 nonzeros touched": with the environment off there
// are no terms, and the line says so.
#[test]
fn relighting_with_the_environment_off_counts_no_terms() {
    let dir = temp_dir("first-hour-env-off");
    let (t, _) = bake_text(&dir, "lit", &with_lamp("[[0.0, 1.8, 1.0]]"), &[]);
    let png = dir.join("lamp.png");
    let (code, text) = common::prt(&[
        "relight",
        s(&t),
        "--env",
        "none",
        "--device",
        "cpu",
        "-o",
        s(&png),
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("environment off (no light terms)") && text.contains("1 light column"),
        "{text}"
    );
    assert!(
        !text.contains(" terms,") && !text.contains("nonzeros"),
        "{text}"
    );
}

// 6b. A ground at roughness 1 was warned about as glossy by a per-vertex bake: the warning is for
// the highlights the diffuse base drops, and a rough lobe that holds much light is named apart.
#[test]
fn only_visible_gloss_is_warned_of_per_vertex() {
    let dir = temp_dir("first-hour-gloss-notes");
    let ground = "[material.ground]\ntype = \"diffuse\"\nalbedo = [0.8, 0.7, 0.6]";
    assert!(SPHERE_ON_PLANE.contains(ground));
    let glossy = |albedo: &str, specular: &str, roughness: &str| {
        SPHERE_ON_PLANE.replace(
            ground,
            &format!(
                "[material.ground]\ntype = \"glossy\"\nalbedo = {albedo}\nspecular = \
                 {specular}\nroughness = {roughness}"
            ),
        )
    };
    // With the lobe left out (`--visibility false`); by default it is drawn per pixel.
    let per_vertex = [
        "--per-vertex",
        "--edge-length",
        "0.6",
        "--visibility",
        "false",
    ];
    let cases = [
        (
            "rough",
            glossy("[0.8, 0.7, 0.6]", "[0.04, 0.04, 0.04]", "1.0"),
            None,
        ),
        (
            "shiny",
            glossy("[0.8, 0.7, 0.6]", "[0.04, 0.04, 0.04]", "0.3"),
            Some("glossy material(s) ground keep only their diffuse base"),
        ),
        (
            "metal",
            glossy("[0.05, 0.05, 0.05]", "[0.9, 0.9, 0.9]", "1.0"),
            Some("rough material(s) ground keep only their diffuse base"),
        ),
    ];
    for (name, text, warning) in &cases {
        let (_, printed) = bake_text(&dir, name, text, &per_vertex);
        match warning {
            None => assert!(!printed.contains("warning"), "{name}: {printed}"),
            Some(w) => {
                let lines: Vec<&str> = printed.lines().filter(|l| l.contains("warning")).collect();
                assert!(
                    lines.len() == 1 && lines[0].contains(w),
                    "{name}: {printed}"
                );
            }
        }
    }
    let (_, printed) = bake_text(&dir, "shiny-lobe", &cases[1].1, &per_vertex[..3]);
    assert!(!printed.contains("warning"), "{printed}");
    assert!(printed.contains("keep their visibility"), "{printed}");
}

// 6c. A moving light baked 0.8 apart at 0.6 above the ground doubles its shadows between
// positions, and nothing said so.
#[test]
fn a_moving_light_whose_steps_double_its_shadows_is_warned_of() {
    let dir = temp_dir("first-hour-light-steps");
    let (_, printed) = bake_text(
        &dir,
        "wide",
        &with_lamp("[[-0.4, 0.6, 1.5], [0.4, 0.6, 1.5]]"),
        &[],
    );
    let warning: Vec<&str> = printed.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warning.len(), 1, "{printed}");
    for needle in [
        "`lamp`",
        "0.800",
        "0.600",
        "0.5 times the height",
        "0.300 apart",
    ] {
        assert!(warning[0].contains(needle), "{needle}: {}", warning[0]);
    }
    let (_, printed) = bake_text(
        &dir,
        "close",
        &with_lamp("[[-0.1, 0.6, 1.5], [0.0, 0.6, 1.5], [0.1, 0.6, 1.5]]"),
        &[],
    );
    assert!(!printed.contains("warning"), "{printed}");
}
