//! A new user's first hour on a machine without a GPU: the device chosen when nobody asks, the
//! messages a session-less machine prints, files of the wrong kind, and help texts that say what
//! the code does.

mod common;

use std::path::Path;
use std::process::Command;

use common::{SPHERE_ON_PLANE, s, temp_dir};

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
