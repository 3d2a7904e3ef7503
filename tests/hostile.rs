//! Hostile and careless input: one regression test per defect found by trying the loaders and
//! commands as an editor of files or a careless user would. Each test is named after the
//! defect it catches; the mutation harness (`tests/mutations.rs`) searches the same ground at
//! random.

mod common;

use std::path::{Path, PathBuf};

use common::{SPHERE_ON_PLANE, StFile, fog_scene, prt, random_transport, s, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::relight::{LightContext, RelightRequest, relight};
use wavelet_prt::scene::Scene;
use wavelet_prt::store::transport::{Quantization, Transport};
use wavelet_prt::volume::{TransferSettings, VolumeTransfer, bake_volume};

/// A pixel relit under a constant map of 1e30 against the same pixel under a map of 1 scaled by
/// 1e30, relative: the light goes 1e30 times larger into the same f32 products and sums, so only
/// their rounding separates the two...
const BRIGHT_SCALED_REL: f32 = 1e-4;
/// ...plus this absolute slack, a millionth of the map's 1e30, for pixels whose signed Haar terms
/// cancel to far below their own size, where rounding at the scale of the terms is all there is.
const BRIGHT_SCALED_ABS: f32 = 1e24;

/// A small valid transport file in `dir`.
fn transport_file(dir: &Path) -> PathBuf {
    let p = dir.join("t.prt");
    random_transport(20, 18, 2, Quantization::Q8, 7, 1.0)
        .save(&p)
        .unwrap();
    p
}

/// A small volume file of the fog blob in `dir`.
/// Two scattering orders at low resolution: enough to write and read the scattered fields.
fn small_scatter() -> wavelet_prt::volume::ScatterSettings {
    wavelet_prt::volume::ScatterSettings {
        orders: 2,
        angular: 2,
        light: 2,
        directions: 16,
    }
}

fn volume_file(dir: &Path) -> PathBuf {
    let scene_path = dir.join("fog.toml");
    std::fs::write(&scene_path, fog_scene(0.3, 12, 10)).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let settings = TransferSettings {
        sh_order: 2,
        directions: 32,
        scatter: small_scatter(),
    };
    let vt = bake_volume(&scene, Some(8), &settings, &|_, _| {}).unwrap();
    let p = dir.join("fog.prtv");
    vt.save(&p).unwrap();
    p
}

/// The scene of the shard tests (three bands of tile rows) in `dir`, and its three shards.
fn shard_files(dir: &Path) -> (PathBuf, Vec<PathBuf>) {
    let scene_path = dir.join("scene.toml");
    std::fs::write(
        &scene_path,
        SPHERE_ON_PLANE.replace("height = 21", "height = 45"),
    )
    .unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let shards = (0..3)
        .map(|i| {
            let settings = BakeSettings {
                cube_n: 4,
                sh_order: 2,
                shard: Some([i, 3]),
                ..BakeSettings::default()
            };
            let p = dir.join(format!("part-{i}.prt"));
            bake(&scene, &settings, &|_| {}).unwrap().save(&p).unwrap();
            p
        })
        .collect();
    (scene_path, shards)
}

/// Asserts a command failed cleanly (exit code 1, not a panic's 101) with every needle in its
/// message.
fn assert_clean_error(args: &[&str], needles: &[&str]) -> String {
    let (code, text) = prt(args);
    assert_eq!(code, 1, "prt {args:?} exited with {code}: {text}");
    assert!(!text.contains("panicked"), "prt {args:?}: {text}");
    for n in needles {
        assert!(text.contains(n), "prt {args:?}: `{n}` not in: {text}");
    }
    text
}

// 1. A checksum-valid edit of the column table panicked (`range end index out of range`) in
// info, relight, view --screenshot and merge. The strips' counts took the column counts' place.
#[test]
fn strip_count_edits_with_the_checksum_recomputed_are_errors_not_panics() {
    let dir = temp_dir("hostile-col-count");
    let good = transport_file(&dir);
    let file = StFile::read(&good);
    let bad = dir.join("edited.prt");
    let counts: Vec<u8> = file
        .tensors
        .iter()
        .find(|t| t.0 == "strip_count")
        .unwrap()
        .3
        .clone();
    // Every count raised, lowered or set to the largest value, one at a time.
    let mut edits = 0;
    for (i, &count) in counts.iter().enumerate() {
        for v in [count.wrapping_add(1), count.wrapping_sub(1), u8::MAX] {
            if v == count {
                continue;
            }
            let mut f = file.clone();
            f.tensor_mut("strip_count")[i] = v;
            f.write(&bad, true);
            let e = Transport::load(&bad).unwrap_err().to_string();
            assert!(e.contains("edited.prt"), "count {i} = {v}: {e}");
            edits += 1;
        }
    }
    assert!(edits > 100);
    // The same file through every command that reads it.
    let mut f = file.clone();
    f.tensor_mut("strip_count")[0] = counts[0].wrapping_add(1);
    f.write(&bad, true);
    let png = dir.join("out.png");
    for args in [
        vec!["info", s(&bad)],
        vec!["relight", s(&bad), "--env", "sun:40,60", "-o", s(&png)],
        vec!["view", s(&bad), "--screenshot", s(&png)],
        vec!["merge", s(&bad), "-o", s(&dir.join("merged.prt"))],
    ] {
        assert_clean_error(&args, &["edited.prt", "strip counts"]);
    }
}

// 2. The checksum covered the tensors, not the metadata: a volume's width edited to 0 or 4e9
// made `view --screenshot` panic or allocate 48 GB.
#[test]
fn volume_view_size_edits_are_caught_by_the_metadata_checksum_and_by_validation() {
    let dir = temp_dir("hostile-volume-size");
    let good = volume_file(&dir);
    let png = dir.join("shot.png");
    for (w, h) in [(0u64, 10u64), (4_000_000_000, 4_000_000_000), (16385, 10)] {
        let mut f = StFile::read(&good);
        let bad = dir.join(format!("w{w}.prtv"));
        // Edited by accident (the text changed, the checksums not): the metadata checksum
        // catches it.
        let text = f
            .meta_text
            .replace("\"width\":12", &format!("\"width\":{w}"))
            .replace("\"height\":10", &format!("\"height\":{h}"));
        assert_ne!(text, f.meta_text);
        std::fs::write(&bad, f.assemble(&text)).unwrap();
        assert_clean_error(
            &["view", s(&bad), "--screenshot", s(&png)],
            &["metadata checksum mismatch"],
        );
        // Edited on purpose (checksums recomputed): validation catches it.
        f.meta["meta"]["width"] = w.into();
        f.meta["meta"]["height"] = h.into();
        f.write(&bad, true);
        let e = VolumeTransfer::load(&bad).unwrap_err().to_string();
        assert!(e.contains("camera.width"), "{e}");
        for args in [
            vec!["view", s(&bad), "--screenshot", s(&png)],
            vec![
                "volume",
                "render",
                s(&bad),
                "--env",
                "sun:30,0",
                "-o",
                s(&png),
            ],
            vec!["info", s(&bad)],
        ] {
            assert_clean_error(&args, &["camera.width"]);
        }
    }
}

// 2. Swapping two shards' labels merged into a third of the rows and a mostly black image; a
// shard count of 2^32 − 1 made `merge` allocate 34 GB.
#[test]
fn merge_refuses_swapped_shard_labels_and_impossible_shard_counts() {
    let dir = temp_dir("hostile-shards");
    let (_, shards) = shard_files(&dir);
    let swapped: Vec<PathBuf> = [(0, 1), (1, 0)]
        .iter()
        .map(|&(from, label)| {
            let mut f = StFile::read(&shards[from]);
            f.meta["shard"] = serde_json::json!([label, 3]);
            let p = dir.join(format!("swapped-{from}.prt"));
            f.write(&p, true);
            p
        })
        .collect();
    let out = dir.join("merged.prt");
    assert_clean_error(
        &[
            "merge",
            s(&swapped[0]),
            s(&swapped[1]),
            s(&shards[2]),
            "-o",
            s(&out),
        ],
        &["label does not match its content"],
    );
    assert!(!out.exists());
    // The merge streams to its file: a refused merge leaves no spill behind either.
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.contains(".spill-") || n.contains(".partial-"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    let mut f = StFile::read(&shards[0]);
    f.meta["shard"] = serde_json::json!([0, u32::MAX]);
    let huge = dir.join("huge-count.prt");
    f.write(&huge, true);
    assert_clean_error(
        &["merge", s(&huge), s(&shards[1]), "-o", s(&out)],
        &["huge-count.prt", "shard 0/4294967295"],
    );
    // The real shards still merge.
    let (code, text) = prt(&[
        "merge",
        s(&shards[0]),
        s(&shards[1]),
        s(&shards[2]),
        "-o",
        s(&out),
    ]);
    assert_eq!(code, 0, "{text}");
}

// 3. An environment of finite but huge pixels (3e38) overflowed in the light: 1,770 of 3,072
// output values were NaN, with exit code 0.
#[test]
fn an_environment_too_bright_for_f32_is_an_error_not_nan() {
    let dir = temp_dir("hostile-bright");
    let t = random_transport(20, 18, 2, Quantization::Q8, 7, 1.0);
    let ctx = LightContext::new(&t).unwrap();
    let env = EnvMap::constant(32, 16, [3e38; 3]);
    let e = ctx
        .prepare(&env, EnvRotation::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("beyond 32-bit floats"), "{e}");
    let e = ctx
        .prepare(&env, EnvRotation::yaw(10.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("beyond 32-bit floats"), "{e}");
    // Bright but representable: a finite image, the same as a dim map's, scaled.
    let bright = EnvMap::constant(32, 16, [1e30; 3]);
    let dim = EnvMap::constant(32, 16, [1.0; 3]);
    let req = RelightRequest::Full;
    let image = |env: &EnvMap| {
        let light = ctx.prepare(env, EnvRotation::default()).unwrap();
        relight(&t, &ctx, &light, &req).unwrap().0
    };
    let (b, d) = (image(&bright), image(&dim));
    for (x, y) in b.pixels.iter().flatten().zip(d.pixels.iter().flatten()) {
        assert!(x.is_finite());
        assert!(
            (x - y * 1e30).abs() <= BRIGHT_SCALED_REL * (y * 1e30).abs() + BRIGHT_SCALED_ABS,
            "{x} vs {y}"
        );
    }
    // Through the command line, with a map on disk.
    let exr = dir.join("bright.exr");
    exr::prelude::write_rgb_file(&exr, 32, 16, |_, _| (3e38f32, 3e38f32, 3e38f32)).unwrap();
    let prt_file = transport_file(&dir);
    let out = dir.join("out.exr");
    assert_clean_error(
        &[
            "relight",
            s(&prt_file),
            "--env",
            s(&exr),
            "--method",
            "full",
            "-o",
            s(&out),
        ],
        &["bright.exr", "beyond 32-bit floats"],
    );
    assert!(!out.exists());
}

// 3. NaN or Inf in a transport's `row_weight`, with the checksum recomputed, went straight into
// the image. Every float tensor is checked on load now.
#[test]
fn non_finite_values_in_any_stored_tensor_are_refused_on_load() {
    let dir = temp_dir("hostile-nan");
    let good = transport_file(&dir);
    let file = StFile::read(&good);
    let bad = dir.join("nan.prt");
    for (name, dtype, _, bytes) in &file.tensors {
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut b = bytes.clone();
            match dtype.as_str() {
                "F32" if b.len() >= 4 => b[..4].copy_from_slice(&(v as f32).to_le_bytes()),
                "F64" if b.len() >= 8 => b[..8].copy_from_slice(&v.to_le_bytes()),
                _ => continue,
            }
            let mut f = file.clone();
            *f.tensor_mut(name) = b;
            f.write(&bad, true);
            let e = Transport::load(&bad).unwrap_err().to_string();
            assert!(e.contains(&format!("`{name}`")), "{name} = {v}: {e}");
        }
    }
}

// 3. `--exposure nan` wrote a black PNG with exit code 0.
#[test]
fn non_finite_flags_are_refused_by_every_command() {
    let dir = temp_dir("hostile-flags");
    let t = transport_file(&dir);
    let v = volume_file(&dir);
    let png = dir.join("o.png");
    for flag in ["--exposure", "--yaw", "--pitch"] {
        for value in ["nan", "inf", "-inf"] {
            for args in [
                vec!["relight", s(&t), "--env", "sun:30,0", "-o", s(&png)],
                vec!["view", s(&t), "--screenshot", s(&png)],
                vec!["view", s(&v), "--screenshot", s(&png)],
                vec![
                    "volume",
                    "render",
                    s(&v),
                    "--env",
                    "sun:30,0",
                    "-o",
                    s(&png),
                ],
            ] {
                let mut args = args.clone();
                let flag = format!("{flag}={value}");
                args.push(&flag);
                assert_clean_error(&args, &["must be a finite number"]);
            }
        }
    }
    assert!(!png.exists());
}

// 4. A kill during the final write left a hidden `.tmpXXXXXX` (the safetensors writer's own
// temporary file) of the output's size, which nothing removed.
#[test]
fn a_killed_write_leaves_nothing_after_the_next_run() {
    let dir = temp_dir("hostile-partial");
    let out = dir.join("out.prt");
    // What a run of this host killed while writing leaves: its temporary file. A pid above
    // the kernel's largest can belong to no running process.
    let pid_max: u32 = std::fs::read_to_string("/proc/sys/kernel/pid_max")
        .map(|s| s.trim().parse().unwrap())
        .unwrap_or(4_194_304);
    let stale = wavelet_prt::files::partial_path(&out, pid_max + 1);
    std::fs::write(&stale, vec![0u8; 4096]).unwrap();
    let t = random_transport(20, 18, 2, Quantization::Q8, 7, 1.0);
    t.save(&out).unwrap();
    assert!(!stale.exists(), "{} was left", stale.display());
    assert_eq!(Transport::load(&out).unwrap(), t);
    // Nothing else beside the output: no writer's own hidden temporary file.
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["out.prt"]);
    // A bake that finds its output already done still cleans up after a killed run.
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let baked = dir.join("baked.prt");
    let args = [
        "bake",
        s(&scene),
        "-o",
        s(&baked),
        "--cube",
        "2",
        "--sh-order",
        "1",
    ];
    assert_eq!(prt(&args).0, 0);
    let stale = wavelet_prt::files::partial_path(&baked, pid_max + 1);
    std::fs::write(&stale, b"half a file").unwrap();
    let (code, text) = prt(&args);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("already holds this bake"), "{text}");
    assert!(!stale.exists());
}

// 5. `bake scene.toml -o scene.toml` replaced the scene with the transport; `bake -o x.png`
// wrote a transport named .png; `view --screenshot a.exr` wrote PNG bytes named .exr.
#[test]
fn outputs_that_are_inputs_or_of_the_wrong_kind_are_refused_before_any_work() {
    let dir = temp_dir("hostile-outputs");
    let scene = dir.join("scene.toml");
    let text = SPHERE_ON_PLANE.replace(
        "[[shape]]\ntype = \"sphere\"",
        "[[shape]]\ntype = \"mesh\"\npath = \"tri.obj\"\nmaterial = \"clay\"\n\n[[shape]]\ntype = \"sphere\"",
    );
    std::fs::write(&scene, &text).unwrap();
    let obj = dir.join("tri.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let before = std::fs::read(&scene).unwrap();
    assert_clean_error(
        &["bake", s(&scene), "-o", s(&scene)],
        &["scene.toml", "name it .prt"],
    );
    // The same file under another name: a symbolic link, a hard link, a path through `..`.
    let link = dir.join("link.prt");
    std::os::unix::fs::symlink(&scene, &link).unwrap();
    let hard = dir.join("hard.prt");
    std::fs::hard_link(&obj, &hard).unwrap();
    let dotted = dir.join("sub/../link.prt");
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    for out in [&link, &hard, &dotted] {
        assert_clean_error(
            &["bake", s(&scene), "-o", s(out)],
            &["this is also an input"],
        );
    }
    assert_eq!(std::fs::read(&scene).unwrap(), before);
    assert_eq!(std::fs::read(&obj).unwrap().len(), 32);
    assert_clean_error(
        &["bake", s(&scene), "-o", s(&dir.join("x.png"))],
        &[
            "x.png",
            "this command writes a transport file: name it .prt",
        ],
    );
    assert!(!dir.join("x.png").exists());
    let t = transport_file(&dir);
    assert_clean_error(
        &["view", s(&t), "--screenshot", s(&dir.join("a.exr"))],
        &["a.exr", "name it .png"],
    );
    assert_clean_error(
        &[
            "relight",
            s(&t),
            "--env",
            "sun:30,0",
            "-o",
            s(&dir.join("r.prt")),
        ],
        &["name it .exr or .png"],
    );
    assert_clean_error(&["merge", s(&t), "-o", s(&t)], &["this is also an input"]);
    assert_clean_error(
        &["volume", "bake", s(&scene), "-o", s(&dir.join("v.prt"))],
        &["name it .prtv"],
    );
    assert!(!dir.join("a.exr").exists() && !dir.join("r.prt").exists());
}

// 6. `.prt` and `.prtv` files were created with mode 0600 whatever the umask, so shards written
// by one user on a shared volume could not be merged by another.
#[test]
fn written_files_get_the_umask_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = temp_dir("hostile-mode");
    // What the umask gives a plain new file.
    let plain = dir.join("plain");
    std::fs::File::create(&plain).unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    let expected = mode(&plain);
    assert_eq!(mode(&transport_file(&dir)), expected);
    assert_eq!(mode(&volume_file(&dir)), expected);
}

// 7. `view` clamped `--terms 0` and `--sh-order 0/100` silently where `relight` refused them.
#[test]
fn view_refuses_what_relight_refuses_with_the_same_words() {
    let dir = temp_dir("hostile-view-flags");
    let t = transport_file(&dir);
    let png = dir.join("o.png");
    for (flags, needle) in [
        (
            vec!["--terms", "0"],
            "K = 0; it must be from 1 to 6·N² = 24 for N = 2",
        ),
        (vec!["--terms", "25"], "K = 25"),
        (
            vec!["--method", "sh", "--sh-order", "0"],
            "SH order: 0; this file was baked up to order 2",
        ),
        (
            vec!["--method", "sh", "--sh-order", "100"],
            "SH order: 100; this file was baked up to order 2",
        ),
    ] {
        let mut relight = vec!["relight", s(&t), "--env", "sun:30,0", "-o", s(&png)];
        relight.extend(&flags);
        let a = assert_clean_error(&relight, &[needle]);
        let mut view = vec!["view", s(&t), "--screenshot", s(&png)];
        view.extend(&flags);
        let b = assert_clean_error(&view, &[needle]);
        assert_eq!(a.trim(), b.trim());
    }
    let v = volume_file(&dir);
    for order in ["0", "3"] {
        let a = assert_clean_error(
            &["view", s(&v), "--screenshot", s(&png), "--sh-order", order],
            &["this file was baked up to order 2"],
        );
        let b = assert_clean_error(
            &[
                "volume",
                "render",
                s(&v),
                "--env",
                "sun:30,0",
                "-o",
                s(&png),
                "--sh-order",
                order,
            ],
            &["this file was baked up to order 2"],
        );
        assert_eq!(a.trim(), b.trim());
    }
}

// 7. `merge` of shards with a different cube size or seed said "scene hash X vs X" and never
// named the setting that differs.
#[test]
fn merge_names_the_setting_that_differs() {
    let dir = temp_dir("hostile-merge-setting");
    let (_, shards) = shard_files(&dir);
    let out = dir.join("m.prt");
    let mut f = StFile::read(&shards[1]);
    f.meta["seed"] = 7.into();
    let seed = dir.join("seed.prt");
    f.write(&seed, true);
    assert_clean_error(
        &[
            "merge",
            s(&shards[0]),
            s(&seed),
            s(&shards[2]),
            "-o",
            s(&out),
        ],
        &["seed.prt was baked with seed 7", "part-0.prt with seed 1"],
    );
    let mut f = StFile::read(&shards[1]);
    f.meta["threshold"] = 0.5.into();
    let threshold = dir.join("threshold.prt");
    f.write(&threshold, true);
    assert_clean_error(
        &[
            "merge",
            s(&shards[0]),
            s(&threshold),
            s(&shards[2]),
            "-o",
            s(&out),
        ],
        &["threshold.prt was baked with threshold 0.5"],
    );
}

// 7. An unwritable output's error named the temporary file, not the output.
#[test]
fn an_unwritable_output_is_named_in_the_error() {
    let dir = temp_dir("hostile-unwritable");
    let t = random_transport(20, 18, 2, Quantization::Q8, 7, 1.0);
    // A folder that is a file: refused whoever runs the test (a read-only folder is not, for
    // root).
    let blocker = dir.join("blocker");
    std::fs::write(&blocker, b"").unwrap();
    let out = blocker.join("out.prt");
    let e = t.save(&out).unwrap_err().to_string();
    assert!(e.starts_with(s(&out)), "{e}");
    assert!(!e.contains("partial") && !e.contains(".tmp"), "{e}");
    // The command line checks the folder before baking.
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    assert_clean_error(
        &["bake", s(&scene), "-o", s(&out)],
        &["out.prt", "blocker is not a folder"],
    );
    assert_clean_error(
        &["bake", s(&scene), "-o", s(&dir.join("missing/out.prt"))],
        &["out.prt", "the folder", "missing does not exist"],
    );
}

// 8. `/dev/zero` as a scene, mesh, .npy grid or .prtv was read until memory ran out.
#[test]
fn device_files_are_refused_at_once() {
    let dir = temp_dir("hostile-devices");
    let zero = Path::new("/dev/zero");
    let mesh_scene = dir.join("mesh.toml");
    std::fs::write(
        &mesh_scene,
        SPHERE_ON_PLANE.replace(
            "[[shape]]\ntype = \"sphere\"",
            "[[shape]]\ntype = \"mesh\"\npath = \"/dev/zero\"\nmaterial = \"clay\"\n\n[[shape]]\ntype = \"sphere\"",
        ),
    )
    .unwrap();
    let grid_scene = dir.join("grid.toml");
    std::fs::write(
        &grid_scene,
        fog_scene(0.0, 8, 8)
            .replace(
                "type = \"ellipsoid\"",
                "type = \"grid\"\npath = \"/dev/zero\"",
            )
            .replace("resolution = 24\n", "")
            .replace("center = [0.0, 0.6, 0.0]\n", "")
            .replace("radii = [0.7, 0.5, 0.6]\n", "")
            .replace("falloff = 0.3\n", ""),
    )
    .unwrap();
    // Each load runs on a thread that must answer within seconds (a read of /dev/zero would
    // never end, or end in an abort).
    let within = |what: &str, f: Box<dyn FnOnce() -> String + Send>| {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || tx.send(f()).unwrap());
        let e = rx
            .recv_timeout(std::time::Duration::from_secs(20))
            .unwrap_or_else(|_| panic!("{what}: still reading after 20 s"));
        assert!(e.contains("not a regular file"), "{what}: {e}");
    };
    within(
        "scene",
        Box::new(move || Scene::load(zero).unwrap_err().to_string()),
    );
    let m = mesh_scene.clone();
    within(
        "mesh",
        Box::new(move || Scene::load(&m).unwrap_err().to_string()),
    );
    let g = grid_scene.clone();
    within(
        "grid",
        Box::new(move || Scene::load(&g).unwrap_err().to_string()),
    );
    within(
        "npy",
        Box::new(move || {
            wavelet_prt::medium::load_npy(zero, glam::Vec3::ZERO, glam::Vec3::ONE)
                .unwrap_err()
                .to_string()
        }),
    );
    within(
        "volume",
        Box::new(move || VolumeTransfer::load(zero).unwrap_err().to_string()),
    );
    within(
        "transport",
        Box::new(move || Transport::load(zero).unwrap_err().to_string()),
    );
    within(
        "environment",
        Box::new(move || EnvMap::load(zero).unwrap_err().to_string()),
    );
    // A directory is refused too.
    let e = Scene::load(&dir).unwrap_err().to_string();
    assert!(e.contains("a directory"), "{e}");
    assert_clean_error(
        &["bake", "/dev/zero", "-o", s(&dir.join("z.prt"))],
        &["/dev/zero", "not a regular file"],
    );
}

/// A regression input the mutation harness found, from `tests/data/hostile`.
fn found(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/hostile")
        .join(name)
}

// Found by the mutation harness: a sphere centre or a quad corner of 3.4e38 (finite) made the
// BVH builder index out of bounds, its boxes' areas overflowing f32.
#[test]
fn scene_coordinates_near_the_f32_limit_are_refused_not_a_bvh_panic() {
    for (file, field) in [
        ("bvh_panic_sphere_center_3e38.toml", "shape[1].center"),
        ("bvh_panic_quad_corner_3e38.toml", "shape[1].corners"),
    ] {
        let e = Scene::load(&found(file)).unwrap_err().to_string();
        assert!(
            e.contains(file) && e.contains(field) && e.contains("beyond"),
            "{e}"
        );
    }
    // A mesh scaled past the limit, and a scene at the limit, which bakes.
    let dir = temp_dir("hostile-coordinates");
    std::fs::write(dir.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n").unwrap();
    let mesh = SPHERE_ON_PLANE.replace(
        "[[shape]]\ntype = \"sphere\"",
        "[[shape]]\ntype = \"mesh\"\npath = \"tri.obj\"\nscale = 1e30\nmaterial = \"clay\"\n\n[[shape]]\ntype = \"sphere\"",
    );
    let p = dir.join("mesh.toml");
    std::fs::write(&p, &mesh).unwrap();
    let e = Scene::load(&p).unwrap_err().to_string();
    assert!(e.contains("shape[1].scale") && e.contains("beyond"), "{e}");
    std::fs::write(&p, mesh.replace("scale = 1e30", "scale = 1e9")).unwrap();
    let scene = Scene::load(&p).unwrap();
    let settings = BakeSettings {
        cube_n: 2,
        sh_order: 1,
        ..BakeSettings::default()
    };
    bake(&scene, &settings, &|_| {}).unwrap();
}

// Found by the mutation harness: a grid medium's box far longer than its grid (2e9 units for 4
// voxels against 1 unit for 3) made the direction sweep pad its slices by a billion cells, an
// allocation of 6.6e18 bytes that aborted the process.
#[test]
fn a_medium_box_far_longer_than_its_grid_sweeps_without_a_giant_buffer() {
    let e = Scene::load(&found("sweep_overflow_grid_box_2e9_long.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("medium.bounds") && e.contains("beyond"), "{e}");
    let scene = Scene::load(&found("sweep_overflow_grid_box_1e9_long.toml")).unwrap();
    let settings = TransferSettings {
        sh_order: 2,
        directions: 64,
        scatter: small_scatter(),
    };
    let vt = bake_volume(&scene, None, &settings, &|_, _| {}).unwrap();
    assert!(vt.transfer.iter().all(|v| v.is_finite()));
    let scattered = vt.scatter.as_ref().unwrap();
    assert!(scattered.fields.iter().flatten().all(|v| v.is_finite()));
    assert!(scattered.tail_ratio.is_finite());
    let bake_settings = BakeSettings {
        cube_n: 2,
        sh_order: 1,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &bake_settings, &|_| {}).unwrap();
    t.validate().unwrap();
}
