//! Inputs too large or too dense for the process: images and tables that need more memory than
//! it can have, and media too dense to track, each refused with a message naming what to change
//! before any work is done (an allocation that fails aborts the process); the densest medium
//! accepted renders promptly. The commands run as `prt` does for a user, under an address-space
//! limit (`ulimit -v`) where memory is the point.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{SPHERE_ON_PLANE, fog_scene, s, small_transfer, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::medium::MAX_VOXEL_DEPTH;
use wavelet_prt::scene::Scene;
use wavelet_prt::store::transport::BakeDomain;
use wavelet_prt::volume::bake_volume;

/// The address-space limit the commands run under, in KiB (about 1.9 GiB): more than any of
/// them needs to start and refuse, less than any of the images and tables they are given.
const LIMIT_KIB: u64 = 2_000_000;
/// How long a refusal may take: it comes before any work, so a fraction of a second is usual;
/// this only leaves room for a loaded machine.
const REFUSAL: Duration = Duration::from_secs(30);
/// How long the densest medium accepted may take to trace at 16², 64 paths a pixel: seconds in
/// a debug build, with room for a loaded machine (at an extinction of 1e8 it would not end).
const DENSEST_TRACE: Duration = Duration::from_secs(90);
/// The side of the largest image a camera may have.
const SIDE: &str = "16384";

/// `prt volume KIND FILE --env sun:30,40 -o OUT` and `more`.
fn volume_args<'a>(kind: &'a str, file: &'a str, out: &'a str, more: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["volume", kind, file, "--env", "sun:30,40", "-o", out];
    args.extend_from_slice(more);
    args
}

/// How a command ended.
struct Outcome {
    /// The exit code; `None` when a signal ended it or it was stopped at its time limit.
    code: Option<i32>,
    /// Standard output, then standard error.
    text: String,
    /// Whether it ended by itself within its time limit.
    finished: bool,
    /// How long it ran.
    elapsed: Duration,
}

/// Runs `prt args` (through `sh`, which sets the address-space limit of `kib` KiB when given and
/// then becomes `prt`), stopping it after `limit`; its output goes to files in `dir`.
fn prt_limited(dir: &Path, kib: Option<u64>, limit: Duration, args: &[&str]) -> Outcome {
    let ulimit = kib.map_or(String::new(), |k| format!("ulimit -v {k}; "));
    let (out, err) = (dir.join("prt.stdout"), dir.join("prt.stderr"));
    let start = Instant::now();
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!("{ulimit}exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_prt"))
        .args(args)
        .stdout(Stdio::from(std::fs::File::create(&out).unwrap()))
        .stderr(Stdio::from(std::fs::File::create(&err).unwrap()))
        .spawn()
        .unwrap();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > limit {
            // It may have ended since the last look: then there is nothing to stop.
            let _ = child.kill();
            child.wait().unwrap();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let text = format!(
        "{}{}",
        std::fs::read_to_string(&out).unwrap_or_default(),
        std::fs::read_to_string(&err).unwrap_or_default()
    );
    Outcome {
        code: status.and_then(|s| s.code()),
        text,
        finished: status.is_some(),
        elapsed: start.elapsed(),
    }
}

/// Asserts that `r` is a refusal for want of memory: an ordinary error exit (not a signal, not
/// the 134 of an aborted allocation), a message naming `field` and the GiB needed, no panic.
#[track_caller]
fn assert_memory_refusal(r: &Outcome, field: &str) {
    let text = &r.text;
    assert!(r.finished, "still running after {:?}: {text}", r.elapsed);
    assert!(
        matches!(r.code, Some(c) if c != 0 && c != 134),
        "exit {:?}: {text}",
        r.code
    );
    assert!(text.contains(field) && text.contains("GiB"), "{text}");
    assert!(
        !text.contains("panicked") && !text.contains("memory allocation"),
        "{text}"
    );
}

#[test]
fn a_volume_image_larger_than_memory_is_refused_before_any_work() {
    let dir = temp_dir("memory-volume-image");
    let scene = dir.join("fog.toml");
    std::fs::write(&scene, fog_scene(0.3, 16, 16)).unwrap();
    let out = dir.join("out.png");
    // The reference of a scene: 16384² is 3 GiB of radiance alone.
    let args = volume_args(
        "reference",
        s(&scene),
        s(&out),
        &["--width", SIDE, "--height", SIDE],
    );
    let r = prt_limited(&dir, Some(LIMIT_KIB), REFUSAL, &args);
    assert_memory_refusal(&r, "--width/--height");
    // A volume file's reference and march, and the screenshot of one baked at 16384².
    let big = dir.join("big.toml");
    std::fs::write(&big, fog_scene(0.3, 16384, 16384)).unwrap();
    let settings = small_transfer(16);
    let vt = bake_volume(&Scene::load(&big).unwrap(), Some(8), &settings, &|_, _| {}).unwrap();
    let prtv = dir.join("big.prtv");
    vt.save(&prtv).unwrap();
    let reference = volume_args("reference", s(&prtv), s(&out), &[]);
    let r = prt_limited(&dir, Some(LIMIT_KIB), REFUSAL, &reference);
    assert_memory_refusal(&r, "camera.width/height");
    let render = volume_args("render", s(&prtv), s(&out), &["--device", "cpu"]);
    let r = prt_limited(&dir, Some(LIMIT_KIB), REFUSAL, &render);
    assert_memory_refusal(&r, "camera.width/height");
    let view = ["view", s(&prtv), "--screenshot", s(&out)];
    let r = prt_limited(&dir, Some(LIMIT_KIB), REFUSAL, &view);
    assert_memory_refusal(&r, "--screenshot");
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_volume_bake_larger_than_memory_is_refused_before_any_work() {
    let dir = temp_dir("memory-volume-bake");
    let scene = dir.join("fog.toml");
    std::fs::write(&scene, fog_scene(0.3, 16, 16)).unwrap();
    let out = dir.join("fog.prtv");
    // 160 x 120 x 160 voxels, each with its transfer and the default scattered fields: about
    // 2.4 kB a voxel, 7 GB in all.
    let args = ["volume", "bake", s(&scene), "-o", s(&out), "--grid", "160"];
    let r = prt_limited(&dir, Some(LIMIT_KIB), REFUSAL, &args);
    assert_memory_refusal(&r, "--grid");
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_screenshot_of_a_per_vertex_bake_at_16384_squared_is_refused_not_aborted() {
    let dir = temp_dir("memory-per-vertex-view");
    let scene = dir.join("scene.toml");
    let text = SPHERE_ON_PLANE
        .replace("width = 37", "width = 16384")
        .replace("height = 21", "height = 16384");
    std::fs::write(&scene, text).unwrap();
    // A per-vertex bake's rows belong to its vertices: its camera's size costs it nothing.
    let settings = BakeSettings {
        cube_n: 4,
        sh_order: 2,
        domain: BakeDomain::Vertices { edge_length: 0.6 },
        ..BakeSettings::default()
    };
    let t = bake(&Scene::load(&scene).unwrap(), &settings, &|_| {}).unwrap();
    let file = dir.join("v.prt");
    t.save(&file).unwrap();
    let out = dir.join("shot.png");
    let args = ["view", s(&file), "--screenshot", s(&out)];
    let r = prt_limited(&dir, Some(LIMIT_KIB), REFUSAL, &args);
    assert_memory_refusal(&r, "--screenshot");
    assert!(r.text.contains("16384 x 16384"), "{}", r.text);
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_transmittance_table_larger_than_memory_is_refused_before_any_work() {
    let dir = temp_dir("memory-medium-table");
    // 128 x 70 x 128 voxels and 6 · 16² texels: a table of 1.76 GB, under its own 2 GiB cap,
    // with the chunk of rows swept into it over 2 GB in all.
    let scene = dir.join("slab.toml");
    std::fs::write(
        &scene,
        r#"
[camera]
eye = [0.0, 0.6, 3.0]
target = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
width = 16
height = 16

[medium]
type = "ellipsoid"
bounds = [[-0.64, 0.0, -0.64], [0.64, 0.7, 0.64]]
resolution = 128
extinction = 4.0
albedo = [0.9, 0.9, 0.9]
"#,
    )
    .unwrap();
    let out = dir.join("t.prt");
    let args = [
        "bake",
        s(&scene),
        "-o",
        s(&out),
        "--bounces",
        "1",
        "--cube",
        "16",
    ];
    let r = prt_limited(&dir, Some(LIMIT_KIB), REFUSAL, &args);
    assert_memory_refusal(&r, "--cube");
    assert!(r.text.contains("transmittance table"), "{}", r.text);
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The fog blob with `extinction`; its grid is 24 voxels of 1.6/24 units along x and z.
fn fog_with(extinction: f32) -> String {
    let text = fog_scene(0.3, 16, 16);
    assert!(text.contains("extinction = 4.0"));
    text.replace("extinction = 4.0", &format!("extinction = {extinction:?}"))
}

#[test]
fn a_medium_denser_than_its_voxels_can_hold_is_refused_at_load() {
    let dir = temp_dir("dense-medium");
    let scene = dir.join("fog.toml");
    std::fs::write(&scene, fog_with(1e8)).unwrap();
    let out = dir.join("out.png");
    let reference = volume_args("reference", s(&scene), s(&out), &[]);
    let baked = dir.join("t.prt");
    let bake_args = [
        "bake",
        s(&scene),
        "-o",
        s(&baked),
        "--bounces",
        "1",
        "--cube",
        "4",
    ];
    for args in [&reference[..], &bake_args[..]] {
        let r = prt_limited(&dir, None, REFUSAL, args);
        let text = &r.text;
        assert!(r.finished, "{args:?} still running after {:?}", r.elapsed);
        assert_eq!(r.code, Some(1), "{args:?}: {text}");
        assert!(
            text.contains("medium.extinction")
                && text.contains(&format!("above {MAX_VOXEL_DEPTH}")),
            "{text}"
        );
        assert!(
            text.contains("fog.toml") && !text.contains("panicked"),
            "{text}"
        );
    }
    assert!(!out.exists() && !baked.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_densest_medium_accepted_traces_promptly_and_a_denser_one_is_refused() {
    let dir = temp_dir("densest-medium");
    let scene = dir.join("fog.toml");
    let out = dir.join("out.png");
    // The depth limit over the fog's voxel edge, with a margin for the f32 arithmetic of both.
    let largest = MAX_VOXEL_DEPTH / (1.6 / 24.0);
    std::fs::write(&scene, fog_with(1.01 * largest)).unwrap();
    let err = Scene::load(&scene).unwrap_err().to_string();
    assert!(err.contains("medium.extinction"), "{err}");
    std::fs::write(&scene, fog_with(0.99 * largest)).unwrap();
    let args = volume_args("reference", s(&scene), s(&out), &["--samples", "64"]);
    let r = prt_limited(&dir, None, DENSEST_TRACE, &args);
    assert!(r.finished, "still tracing after {:?}", r.elapsed);
    assert_eq!(r.code, Some(0), "{}", r.text);
    assert!(out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
