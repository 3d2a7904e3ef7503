//! Hostile input, third round: temporary files, the shape and header of environment maps,
//! outputs, memory estimates, metadata that switches its own checks off, and messages. One test
//! per defect of the report, named after it; the inputs that are files are kept in
//! `tests/data/hostile/` under the defect's name, and those tied to the transport format (which
//! changes with its version) are made here from a fresh file with the edit applied.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::{
    SPHERE_ON_PLANE, StFile, assert_clean_error, fog_scene, names_in, prt, random_transport, s,
    small_transfer, temp_dir,
};
use wavelet_prt::env::envmap::EnvMap;
use wavelet_prt::store::transport::{Quantization, Transport};
use wavelet_prt::volume::{VolumeTransfer, bake_volume};

/// A narrow or flat map's power against its cube's (relative): resampling restores the map's
/// power exactly, so only the f32 texels and f64 sums remain, rounding far below this.
const CUBE_POWER_REL: f64 = 1e-5;

/// A regression input from `tests/data/hostile`.
fn found(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/hostile")
        .join(name)
}

/// Runs `prt` under an address-space limit of 4 GiB (`ulimit -v`), as a small machine or a
/// container would: an allocation sized by a header aborts the process there.
fn prt_limited(args: &[&str]) -> (i32, String) {
    common::run(
        Command::new("sh")
            .arg("-c")
            .arg("ulimit -v 4194304 && exec \"$0\" \"$@\"")
            .arg(env!("CARGO_BIN_EXE_prt"))
            .args(args),
    )
}

/// Runs `f` on a thread that must finish within `secs`.
fn within<T: Send + 'static>(what: &str, secs: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(secs))
        .unwrap_or_else(|_| panic!("{what}: still running after {secs} s"))
}

// 1 and 2. Temporary files had predictable names and were opened following links: a link
// planted at the name made a bake overwrite another file. The names now carry 64 random bits
// and are created exclusively (the unit tests of `files` plant links at the exact names the
// writer tries, and force two writers onto one host and PID); here a bake in a folder full of
// links at every name the old scheme would use leaves the links' target untouched, and no
// temporary file behind.
#[cfg(unix)]
#[test]
fn links_planted_at_temporary_names_are_not_followed() {
    let dir = temp_dir("hostile3-links");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, b"precious").unwrap();
    let out = dir.join("out.prt");
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    let host: String = host
        .trim()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    let next = std::process::id();
    for pid in next..next + 200 {
        for part in ["", ".spill-entry_row", ".spill-sh"] {
            let link = dir.join(format!("out.prt.partial-{host}-{pid}{part}.prt"));
            std::os::unix::fs::symlink(&victim, link).unwrap();
        }
    }
    let (code, text) = prt(&["bake", s(&scene), "-o", s(&out), "--cube", "4"]);
    assert_eq!(code, 0, "{text}");
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    assert!(Transport::load(&out).is_ok());
    let left: Vec<String> = names_in(&dir)
        .into_iter()
        .filter(|n| {
            n.contains(".partial-") && !std::fs::symlink_metadata(dir.join(n)).unwrap().is_symlink()
        })
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
}

// 3. A valid map a few pixels wide hung every command: a 1 x 512 sky gradient was still
// resampling after 300 s at N = 32.
#[test]
fn maps_a_few_pixels_wide_or_one_row_tall_resample_at_once() {
    let narrow = EnvMap::load(&found("map_narrow_1x512_hang.hdr")).unwrap();
    let (w, h) = (narrow.width, narrow.height);
    assert_eq!((w, h), (1, 512));
    // The same map as 2 x 512 and, turned on its side, 1024 x 1.
    let two = EnvMap::from_pixels(
        2,
        512,
        narrow.pixels.iter().flat_map(|p| [*p, *p]).collect(),
        "2 x 512",
    )
    .unwrap();
    let flat = EnvMap::from_pixels(1024, 1, narrow.pixels.repeat(2), "1024 x 1").unwrap();
    for map in [narrow, two, flat] {
        let power = map.power();
        for n in [32, 64] {
            let m = map.clone();
            let cube = within(&format!("{} at N = {n}", m.source), 30, move || {
                m.to_cube(n, wavelet_prt::env::envmap::EnvRotation::default())
                    .unwrap()
            });
            // The cube keeps the map's power.
            let got = cube.power();
            for c in 0..3 {
                assert!(
                    (got[c] / power[c] - 1.0).abs() < CUBE_POWER_REL,
                    "{} at N = {n}: power {got:?} against {power:?}",
                    map.source
                );
            }
        }
    }
    // The command a user runs.
    let (code, text) = prt(&[
        "env",
        s(&found("map_narrow_1x512_hang.hdr")),
        "--cube",
        "64",
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("1 x 512"), "{text}");
}

// 4. A 53-byte HDR declaring 32768 x 16384, or a 313-byte EXR with a huge data window, reserved
// about 6 GiB before any pixel was read, and aborted under a 4 GiB address-space limit.
#[test]
fn headers_that_lie_about_their_size_are_refused_before_any_allocation() {
    let env = |file: &str| prt_limited(&["env", s(&found(file))]);
    let (code, text) = env("map_header_32768x16384_53_bytes.hdr");
    assert_clean_error(
        code,
        &text,
        &["32768 x 16384", "16384 x 8192 pixels in all"],
    );
    let (code, text) = env("exr_header_32768x16384_data_window.exr");
    assert_clean_error(
        code,
        &text,
        &["32768 x 16384", "16384 x 8192 pixels in all"],
    );
    // At the largest size accepted, a header on a file far too short for its rows.
    let (code, text) = env("map_header_16384x8192_52_bytes.hdr");
    assert_clean_error(code, &text, &["16384 x 8192", "cannot hold 8192 rows"]);
    // `prt compare` reads EXRs the same way.
    let lit = found("compare_lit_image.exr");
    let (code, text) = prt_limited(&[
        "compare",
        s(&found("exr_header_32768x16384_data_window.exr")),
        s(&lit),
    ]);
    assert_clean_error(code, &text, &["image size 32768 x 16384"]);
}

// 5. An output that is a folder was found only after the whole bake. Every output check (the
// extension, the folder, not an input, not a folder, writable) runs before any work.
#[test]
fn an_output_that_is_a_folder_is_refused_before_any_work() {
    let dir = temp_dir("hostile3-output-folder");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let folder_prt = dir.join("out.prt");
    std::fs::create_dir_all(&folder_prt).unwrap();
    let (code, text) = prt(&["bake", s(&scene), "-o", s(&folder_prt), "--cube", "4"]);
    assert_clean_error(code, &text, &["out.prt", "is a folder"]);
    // Refused before the bake: it printed no bake report.
    assert!(!text.contains("bake time"), "{text}");
    let t = dir.join("t.prt");
    random_transport(20, 18, 2, Quantization::Q8, 7, 1.0)
        .save(&t)
        .unwrap();
    let folder_png = dir.join("out.png");
    std::fs::create_dir_all(&folder_png).unwrap();
    let (code, text) = prt(&[
        "relight",
        s(&t),
        "--env",
        "sun:30,40",
        "--terms",
        "5",
        "-o",
        s(&folder_png),
    ]);
    assert_clean_error(code, &text, &["out.png", "is a folder"]);
    let volume_out = dir.join("v.prtv");
    std::fs::create_dir_all(&volume_out).unwrap();
    let fog = dir.join("fog.toml");
    std::fs::write(&fog, fog_scene(0.3, 12, 10)).unwrap();
    let (code, text) = prt(&["volume", "bake", s(&fog), "-o", s(&volume_out)]);
    assert_clean_error(code, &text, &["v.prtv", "is a folder"]);
    // A folder of outputs that is a file.
    let file = dir.join("plain.txt");
    std::fs::write(&file, b"x").unwrap();
    let (code, text) = prt(&["bench", s(&t), "--env", "sun:30,40", "--out", s(&file)]);
    assert_clean_error(code, &text, &["plain.txt", "is a file"]);
}

// 6. A per-vertex still at the largest accepted size (16384²) aborted with "memory allocation
// failed": it is now estimated first, against the memory the process can have.
#[test]
fn a_still_larger_than_memory_is_refused_with_an_estimate() {
    let pv = common::per_vertex_transport_path();
    let dir = temp_dir("hostile3-still");
    let out = dir.join("still.png");
    let (code, text) = prt_limited(&[
        "relight",
        s(&pv),
        "--env",
        "sun:30,40",
        "--terms",
        "20",
        "--width",
        "16384",
        "--height",
        "16384",
        "-o",
        s(&out),
    ]);
    assert_clean_error(
        code,
        &text,
        &["--width/--height", "16384 x 16384", "GiB", "smaller"],
    );
    assert!(!out.exists());
    // A still that fits is drawn.
    let (code, text) = prt_limited(&[
        "relight",
        s(&pv),
        "--env",
        "sun:30,40",
        "--terms",
        "20",
        "--width",
        "64",
        "--height",
        "48",
        "-o",
        s(&out),
    ]);
    assert_eq!(code, 0, "{text}");
}

// 7. `prt compare` against an all-black reference printed `psnr inf dB` and `rel_h1 0` for
// images that differ, and exited 0.
#[test]
fn comparing_with_a_black_reference_is_an_error() {
    let (code, text) = prt(&[
        "compare",
        s(&found("compare_lit_image.exr")),
        s(&found("compare_black_reference.exr")),
    ]);
    assert_clean_error(
        code,
        &text,
        &["compare_black_reference.exr", "black", "undefined"],
    );
    assert!(!text.contains("psnr inf"), "{text}");
    // Black against black is equal, and says so.
    let black = found("compare_black_reference.exr");
    let (code, text) = prt(&["compare", s(&black), s(&black)]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("rel_l2 0.0000%"), "{text}");
}

// 8. `prt info` printed the stored scene path raw: escape codes in it changed the terminal's
// title and colours.
#[test]
fn info_prints_control_characters_escaped() {
    let dir = temp_dir("hostile3-escapes");
    let scene = dir.join("scene\u{1b}]0;pwned\u{7}\u{1b}[2J.toml");
    std::fs::copy(found("info_escape_codes_in_scene_path.toml"), &scene).unwrap();
    let out = dir.join("t.prt");
    let (code, text) = prt(&["bake", s(&scene), "-o", s(&out), "--cube", "2"]);
    assert_eq!(code, 0, "{text}");
    let (code, text) = prt(&["info", s(&out)]);
    assert_eq!(code, 0, "{text}");
    assert!(
        !text.contains('\u{1b}') && !text.contains('\u{7}'),
        "{text:?}"
    );
    assert!(text.contains("scene\\u{1b}]0;pwned\\u{7}"), "{text}");
}

// 9. On a full disk the error named the temporary spill file, not the output asked for. A
// file-size limit (`ulimit -f`, with SIGXFSZ ignored) makes the writes fail as a full disk does.
#[test]
fn a_full_disk_is_reported_against_the_output() {
    let dir = temp_dir("hostile3-full");
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        SPHERE_ON_PLANE
            .replace("width = 37", "width = 160")
            .replace("height = 21", "height = 120"),
    )
    .unwrap();
    let out = dir.join("out.prt");
    let run = Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 64 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_prt"))
        .args(["bake", s(&scene), "-o", s(&out), "--cube", "16"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_clean_error(
        run.status.code().unwrap_or(-1),
        &text,
        &["out.prt:", "too large"],
    );
    let message = text.lines().find(|l| l.starts_with("error:")).unwrap();
    assert!(
        !message.contains("partial") && !message.contains("spill-"),
        "{message}"
    );
    assert_eq!(names_in(&dir), ["scene.toml"]);
}

// 10. A luminance-only (Y) or alpha-only EXR gave the exr crate's "no layer ... matched your
// specified requirements".
#[test]
fn an_exr_without_rgb_names_its_channels() {
    for (file, channels) in [
        ("exr_luminance_only_y.exr", "the file's channels: Y)"),
        ("exr_alpha_only_a.exr", "the file's channels: A)"),
    ] {
        let e = EnvMap::load(&found(file)).unwrap_err().to_string();
        assert!(
            e.contains(file) && e.contains("R, G and B") && e.contains(channels),
            "{e}"
        );
    }
}

// 11. A map that is -5 everywhere gave a black image, exit 0 and a note calling the samples
// "slightly negative".
#[test]
fn a_map_with_no_positive_power_is_refused_with_how_negative_it_is() {
    let file = found("map_negative_everywhere_minus5.exr");
    let e = EnvMap::load(&file).unwrap_err().to_string();
    assert!(
        e.contains("-1.8850e2")
            && e.contains("384 of its 384 samples are negative")
            && e.contains("-5.0000e0"),
        "{e}"
    );
    let t = temp_dir("hostile3-negative").join("t.prt");
    random_transport(20, 18, 2, Quantization::Q8, 7, 1.0)
        .save(&t)
        .unwrap();
    let png = t.with_extension("png");
    let (code, text) = prt(&[
        "relight",
        s(&t),
        "--env",
        s(&file),
        "--terms",
        "5",
        "-o",
        s(&png),
    ]);
    assert_clean_error(code, &text, &["lights nothing"]);
    assert!(!text.contains("slightly"), "{text}");
}

// 12. SIGTERM or Ctrl-C left the spill files, as large as the output, until the same output
// was written again.
#[cfg(unix)]
#[test]
fn an_interrupted_bake_leaves_nothing() {
    for (signal, number) in [("TERM", 15), ("INT", 2)] {
        let dir = temp_dir(&format!("hostile3-signal-{signal}"));
        let scene = dir.join("scene.toml");
        std::fs::write(
            &scene,
            SPHERE_ON_PLANE
                .replace("width = 37", "width = 320")
                .replace("height = 21", "height = 240"),
        )
        .unwrap();
        let out = dir.join("out.prt");
        let mut child = Command::new(env!("CARGO_BIN_EXE_prt"))
            .args(["bake", s(&scene), "-o", s(&out), "--cube", "32"])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Well into the bake: tiles are being spilled.
        std::thread::sleep(Duration::from_millis(1500));
        let status = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        let code = child.wait().unwrap().code();
        assert_eq!(code, Some(128 + number), "SIGTERM: exit {code:?}");
        assert_eq!(names_in(&dir), ["scene.toml"], "after SIG{signal}");
    }
}

// 13. Renaming the `meta_checksum` key loaded the file as unsealed, so a second edited value
// went unnoticed; unknown tensors (200,000 empty ones made `prt info` take 7 s and 458 MB) and
// unknown metadata keys were accepted.
/// `file` (read from a file named `stem`.EXT in `dir`) with its seal's key renamed by one byte,
/// and with an unknown tensor `zz_extra` of `dtype` added and resealed: the errors `load` gives.
fn seal_and_tensor_edits(
    dir: &Path,
    ext: &str,
    file: &StFile,
    dtype: &str,
    load: impl Fn(&Path) -> String,
) -> [String; 2] {
    let renamed = file
        .meta_text
        .replace("\"meta_checksum\"", "\"meta_checksun\"");
    assert_ne!(renamed, file.meta_text);
    let p = dir.join(format!("renamed.{ext}"));
    std::fs::write(&p, file.assemble(&renamed)).unwrap();
    let seal = load(&p);
    let mut extra = file.clone();
    extra
        .tensors
        .push(("zz_extra".into(), dtype.into(), vec![0], Vec::new()));
    let p = dir.join(format!("tensor.{ext}"));
    std::fs::write(&p, extra.to_bytes(true)).unwrap();
    [seal, load(&p)]
}

#[test]
fn metadata_cannot_switch_off_its_own_checks() {
    let dir = temp_dir("hostile3-seal");
    let path = dir.join("t.prt");
    random_transport(20, 18, 2, Quantization::Q8, 7, 1.0)
        .save(&path)
        .unwrap();
    let file = StFile::read(&path);
    let load = |p: &Path| Transport::load(p).unwrap_err().to_string();
    // The seal's key renamed by one byte: refused. An unknown tensor, resealed as a careful
    // editor would: refused, by `prt info` too, at once.
    let [seal, tensor] = seal_and_tensor_edits(&dir, "prt", &file, "U8", load);
    assert!(seal.contains("meta_checksum"), "{seal}");
    assert!(tensor.contains("unknown tensor `zz_extra`"), "{tensor}");
    let (code, text) = prt(&["info", s(&dir.join("tensor.prt"))]);
    assert_clean_error(code, &text, &["unknown tensor `zz_extra`"]);
    // An unknown metadata key, resealed: refused.
    let mut extra = file.clone();
    extra.meta["comment"] = "edited".into();
    let p = dir.join("key.prt");
    std::fs::write(&p, extra.to_bytes(true)).unwrap();
    let e = load(&p);
    assert!(e.contains("metadata key `comment`"), "{e}");
    // The volume file holds to the same rules.
    let scene = dir.join("fog.toml");
    std::fs::write(&scene, fog_scene(0.3, 12, 10)).unwrap();
    let settings = small_transfer(32);
    let scene = wavelet_prt::scene::Scene::load(&scene).unwrap();
    let vpath = dir.join("fog.prtv");
    bake_volume(&scene, Some(8), &settings, &|_, _| {})
        .unwrap()
        .save(&vpath)
        .unwrap();
    let vload = |p: &Path| VolumeTransfer::load(p).unwrap_err().to_string();
    let [seal, tensor] = seal_and_tensor_edits(&dir, "prtv", &StFile::read(&vpath), "F32", vload);
    assert!(seal.contains("meta_checksum"), "{seal}");
    assert!(tensor.contains("unknown tensor `zz_extra`"), "{tensor}");
}

// 4. A valid EXR at the largest accepted size (then 32768 x 16384) used 10.5 GB. The largest
// accepted now, 16384 x 8192, relights within a 4 GiB address space: its pixels (1.5 GiB) are
// read into the map's own table, and a map this large is splatted directly rather than through
// recorded shares.
#[test]
fn the_largest_accepted_map_relights_in_bounded_memory() {
    let dir = temp_dir("hostile3-largest");
    let map = dir.join("largest.exr");
    let (w, h) = (16384usize, 8192usize);
    let channels = exr::prelude::SpecificChannels::rgb(
        |exr::prelude::Vec2(x, y): exr::prelude::Vec2<usize>| {
            let v = 0.2 + y as f32 / h as f32 + 0.1 * ((x / 64) % 2) as f32;
            (v, 0.8 * v, 0.6 * v)
        },
    );
    let mut image = exr::prelude::Image::from_channels((w, h), channels);
    image.layer_data.encoding = exr::prelude::Encoding::SMALL_LOSSLESS;
    exr::prelude::WritableImage::write(&image)
        .to_file(&map)
        .unwrap();
    let t = dir.join("t.prt");
    random_transport(20, 18, 2, Quantization::Q8, 7, 1.0)
        .save(&t)
        .unwrap();
    let png = dir.join("out.png");
    let (code, text) = prt_limited(&[
        "relight",
        s(&t),
        "--env",
        s(&map),
        "--terms",
        "5",
        "-o",
        s(&png),
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(png.exists());
    std::fs::remove_file(&map).unwrap();
}
