//! Mutation testing of every loader: a seeded property test over thousands of structure-aware
//! mutations of valid inputs, for `.prt` transports (each quantisation, and shards through a
//! merge), `.prtv` volumes, scene TOML, OBJ meshes, glTF (`.gltf` JSON and `.glb` containers),
//! `.npy` grids and EXR and HDR maps.
//!
//! Mutations: single-value edits of every tensor with the checksums recomputed (as a careful
//! editor would, so they reach the validation behind the checksum), edits of every metadata
//! field (resealed too), tensor shape edits, truncations and raw byte changes; for text formats,
//! edits of every number and string, dropped, doubled and swapped lines, truncations and stray
//! bytes; for images, edits of header fields, offsets and pixel values.
//!
//! The property: the library call a command makes, and everything it does with what loaded
//! (relighting, baking, ray marching, merging, saving and reloading), returns an error or a
//! finite image, and never panics (`catch_unwind` turns a panic into a failure naming the seed,
//! the input's number and the mutation). An abort, such as an allocation far beyond the file's
//! size, ends the test binary, which fails too.
//!
//! Inputs tried per run: the sum of each test's count (see [`COUNTS`]); set `PRT_MUTATIONS` to a
//! multiplier for a longer search, and `PRT_MUTATIONS_TRACE` to print each input before it runs
//! (an abort leaves no other trace). A failing input is reproduced by its seed and number; once
//! fixed it goes into `tests/hostile.rs` as a test named after the defect it caught.

mod common;

use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use common::{SPHERE_ON_PLANE, StFile, fog_scene, random_transport, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation, SunSky};
use wavelet_prt::env::select::Weighting;
use wavelet_prt::math::sampling::Rng;
use wavelet_prt::relight::{LightContext, PreparedLight, RelightRequest, relight};
use wavelet_prt::scene::Scene;
use wavelet_prt::store::transport::{Quantization, Transport};
use wavelet_prt::volume::{
    MediumLook, ScatterSettings, TransferSettings, VolumeLight, VolumeTransfer, VolumeView,
    bake_volume, render_volume,
};

/// Inputs each test tries (times `PRT_MUTATIONS`): 95,500 in all, about 45 s of
/// `cargo test --release` on two cores. `PRT_MUTATIONS=10` (820,000) took 8 minutes and found
/// nothing more.
const COUNTS: [(&str, usize); 13] = [
    ("prt", 16000),
    ("shards", 4000),
    ("prtv", 12000),
    ("scene", 14000),
    ("obj", 8000),
    ("gltf", 3000),
    ("glb", 3000),
    ("gltf-uri", 1500),
    ("lights", 3000),
    ("per-vertex", 3000),
    ("npy", 8000),
    ("exr", 10000),
    ("hdr", 10000),
];

fn count(name: &str) -> usize {
    let scale: usize = std::env::var("PRT_MUTATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    COUNTS
        .iter()
        .find(|c| c.0 == name)
        .map(|c| c.1)
        .unwrap_or(0)
        * scale.max(1)
}

/// Counts what a test tried and collects the failures.
struct Harness {
    name: &'static str,
    seed: u64,
    tried: usize,
    refused: usize,
    failures: Vec<String>,
}

impl Harness {
    fn new(name: &'static str, seed: u64) -> Harness {
        Harness {
            name,
            seed,
            tried: 0,
            refused: 0,
            failures: Vec::new(),
        }
    }

    /// Runs the library on input `i` (made by `mutation`): `check` returns Ok(true) when the
    /// input was refused with an error, Ok(false) when it was accepted and everything made from
    /// it was finite, and Err when a property failed.
    fn check(
        &mut self,
        i: usize,
        mutation: &str,
        input: &Path,
        check: impl FnOnce() -> Result<bool, String>,
    ) {
        self.tried += 1;
        if std::env::var_os("PRT_MUTATIONS_TRACE").is_some() {
            // Said before the run: an abort leaves no other trace of its input.
            eprintln!("{} seed {} input {i}: {mutation}", self.name, self.seed);
        }
        let result = catch_unwind(AssertUnwindSafe(check));
        let failure = match result {
            Ok(Ok(refused)) => {
                self.refused += refused as usize;
                return;
            }
            Ok(Err(property)) => property,
            Err(panic) => {
                let msg = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                format!("panicked: {msg}")
            }
        };
        // Kept for a regression test.
        let kept = input.with_file_name(format!(
            "failed-{i}-{}",
            input.file_name().unwrap_or_default().to_string_lossy()
        ));
        let _ = std::fs::copy(input, &kept);
        self.failures.push(format!(
            "{} seed {} input {i}: {mutation}: {failure} (input kept as {})",
            self.name,
            self.seed,
            kept.display()
        ));
    }

    fn finish(self) {
        println!(
            "mutations {}: {} inputs tried, {} refused with an error, {} accepted",
            self.name,
            self.tried,
            self.refused,
            self.tried - self.refused
        );
        // A search that refuses everything (or nothing) searched nothing: its mutations never
        // reach past the first check (or never reach a check at all).
        assert!(self.tried > 0, "{}: no input tried", self.name);
        assert!(
            self.refused > 0,
            "{}: none of {} inputs was refused: the mutations change nothing a loader checks",
            self.name,
            self.tried
        );
        assert!(
            self.refused < self.tried,
            "{}: all {} inputs were refused: no mutated input reached the code behind the checks",
            self.name,
            self.tried
        );
        assert!(
            self.failures.is_empty(),
            "{} of {} inputs failed:\n{}",
            self.failures.len(),
            self.tried,
            self.failures.join("\n")
        );
    }
}

/// A uniform index below `n` (n > 0).
fn pick(rng: &mut Rng, n: usize) -> usize {
    (rng.next_u64() % n.max(1) as u64) as usize
}

fn choose<'a, T>(rng: &mut Rng, items: &'a [T]) -> &'a T {
    &items[pick(rng, items.len())]
}

// ---------------------------------------------------------------------------------------------
// Values worth trying.

fn interesting_f64(rng: &mut Rng, v: f64) -> f64 {
    *choose(
        rng,
        &[
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            -1.0,
            1.0,
            1e-45,
            1e-38,
            3.4e38,
            -3.4e38,
            1e30,
            1e300,
            v * 2.0,
            -v,
            v * 1e10,
            v + 1.0,
        ],
    )
}

fn interesting_int(rng: &mut Rng, v: i128, min: i128, max: i128) -> i128 {
    let random = (rng.next_u64() as i128) % (max - min + 1) + min;
    let x = *choose(
        rng,
        &[
            0,
            1,
            2,
            -1,
            min,
            max,
            max - 1,
            v + 1,
            v - 1,
            v * 2,
            v + 256,
            255,
            256,
            65535,
            65536,
            random,
        ],
    );
    x.clamp(min, max)
}

fn interesting_json(rng: &mut Rng, v: &serde_json::Value) -> serde_json::Value {
    use serde_json::json;
    let n = v.as_f64().unwrap_or(1.0);
    match pick(rng, 4) {
        0 if v.is_number() => json!(interesting_f64(rng, n)).clone(),
        1 if v.is_u64() || v.is_i64() => {
            json!(interesting_int(rng, v.as_i64().unwrap_or(0) as i128, 0, u32::MAX as i128) as u64)
        }
        _ => choose(
            rng,
            &[
                json!(0),
                json!(1),
                json!(-1),
                json!(3),
                json!(16),
                json!(257),
                json!(65536),
                json!(4294967295u64),
                json!(4294967296u64),
                json!(18446744073709551615u64),
                json!(-9223372036854775807i64),
                json!(1e300),
                json!(-1e300),
                json!(0.5),
                json!(3.5e38),
                json!(true),
                json!(null),
                json!(""),
                json!("x"),
                json!("wavelet-prt volume"),
                json!("wavelet-prt transport"),
                json!([]),
                json!({}),
                json!([0, 0]),
                json!([1, 2, 3]),
                json!([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]),
            ],
        )
        .clone(),
    }
}

/// Every leaf of a JSON value, as JSON pointers.
fn leaves(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                leaves(x, format!("{at}/{k}"), out);
            }
        }
        serde_json::Value::Array(a) => {
            out.push(at.clone());
            for (i, x) in a.iter().enumerate() {
                leaves(x, format!("{at}/{i}"), out);
            }
        }
        _ => out.push(at),
    }
}

// ---------------------------------------------------------------------------------------------
// Safetensors files (.prt, .prtv).

fn dtype_size(dtype: &str) -> usize {
    match dtype {
        "F64" => 8,
        "F32" | "U32" | "I32" => 4,
        "U16" | "I16" | "F16" => 2,
        _ => 1,
    }
}

/// Changes one value of `bytes` (an array of `dtype`) at `index` to an interesting one.
fn edit_value(rng: &mut Rng, dtype: &str, bytes: &mut [u8], index: usize) -> String {
    let size = dtype_size(dtype);
    let at = &mut bytes[index * size..(index + 1) * size];
    match dtype {
        "F32" => {
            let v = f32::from_le_bytes(at.try_into().unwrap());
            let x = interesting_f64(rng, v as f64) as f32;
            at.copy_from_slice(&x.to_le_bytes());
            format!("{v} -> {x}")
        }
        "F64" => {
            let v = f64::from_le_bytes(at.try_into().unwrap());
            let x = interesting_f64(rng, v);
            at.copy_from_slice(&x.to_le_bytes());
            format!("{v} -> {x}")
        }
        "U32" => {
            let v = u32::from_le_bytes(at.try_into().unwrap());
            let x = interesting_int(rng, v as i128, 0, u32::MAX as i128) as u32;
            at.copy_from_slice(&x.to_le_bytes());
            format!("{v} -> {x}")
        }
        "U16" => {
            let v = u16::from_le_bytes(at.try_into().unwrap());
            let x = interesting_int(rng, v as i128, 0, u16::MAX as i128) as u16;
            at.copy_from_slice(&x.to_le_bytes());
            format!("{v} -> {x}")
        }
        "I16" => {
            let v = i16::from_le_bytes(at.try_into().unwrap());
            let x = interesting_int(rng, v as i128, i16::MIN as i128, i16::MAX as i128) as i16;
            at.copy_from_slice(&x.to_le_bytes());
            format!("{v} -> {x}")
        }
        "I8" => {
            let v = at[0] as i8;
            let x = interesting_int(rng, v as i128, -128, 127) as i8;
            at[0] = x as u8;
            format!("{v} -> {x}")
        }
        _ => {
            let v = at[0];
            let x = interesting_int(rng, v as i128, 0, 255) as u8;
            at[0] = x;
            format!("{v} -> {x}")
        }
    }
}

/// One edit of a tensor value, a metadata field or a tensor's shape, for a file to be
/// resealed: what changed.
fn edit_resealed(rng: &mut Rng, f: &mut StFile) -> String {
    let r = pick(rng, 88);
    if r < 55 {
        // A single value of one tensor, checksums recomputed.
        let k = pick(rng, f.tensors.len());
        let (name, dtype, _, bytes) = &mut f.tensors[k];
        let n = bytes.len() / dtype_size(dtype);
        if n > 0 {
            let i = pick(rng, n);
            let what = edit_value(rng, dtype, bytes, i);
            return format!("tensor `{name}`[{i}]: {what}");
        }
    }
    if r < 82 {
        // One metadata field.
        let mut paths = Vec::new();
        leaves(&f.meta, String::new(), &mut paths);
        paths.retain(|p| !p.ends_with("checksum"));
        let path = choose(rng, &paths).clone();
        let (parent, key) = path.rsplit_once('/').unwrap_or(("", ""));
        let desc;
        if pick(rng, 10) == 0 {
            if let Some(m) = f.meta.pointer_mut(parent).and_then(|p| p.as_object_mut()) {
                m.remove(key);
            }
            desc = format!("metadata {path} removed");
        } else if let Some(slot) = f.meta.pointer_mut(&path) {
            let old = slot.clone();
            *slot = interesting_json(rng, &old);
            desc = format!("metadata {path}: {old} -> {slot}");
        } else {
            desc = format!("metadata {path} not found");
        }
        return desc;
    }
    // A tensor's shape.
    let k = pick(rng, f.tensors.len());
    let shape = f.tensors[k].2.clone();
    let product: usize = shape.iter().product();
    let new: Vec<usize> = match pick(rng, 5) {
        0 => shape.iter().rev().copied().collect(),
        1 => vec![product],
        2 => {
            let mut s = shape.clone();
            if !s.is_empty() {
                let j = pick(rng, s.len());
                s[j] += 1;
            }
            s
        }
        3 => {
            let mut s = shape.clone();
            s.insert(0, 1);
            s
        }
        _ => shape.iter().map(|_| 0).collect(),
    };
    let desc = format!("tensor `{}` shape {shape:?} -> {new:?}", f.tensors[k].0);
    f.tensors[k].2 = new;
    desc
}

/// One structure-aware mutation of a safetensors file: the new bytes and what changed. Most
/// are one or two edits resealed (see [`edit_resealed`]); the rest cut the file or change raw
/// bytes, leaving the checksums to catch them.
fn mutate_safetensors(rng: &mut Rng, file: &StFile) -> (Vec<u8>, String) {
    let r = pick(rng, 100);
    if r < 88 {
        let mut f = file.clone();
        let mut desc = edit_resealed(rng, &mut f);
        if pick(rng, 5) == 0 {
            desc = format!("{desc}; {}", edit_resealed(rng, &mut f));
        }
        return (f.to_bytes(true), format!("{desc}; resealed"));
    }
    let mut bytes = file.to_bytes(true);
    if r < 95 {
        let cut = pick(rng, bytes.len());
        bytes.truncate(cut);
        return (bytes, format!("truncated to {cut} bytes"));
    }
    let mut desc = String::from("bytes changed:");
    for _ in 0..1 + pick(rng, 4) {
        let i = pick(rng, bytes.len());
        let v = rng.next_u64() as u8;
        desc += &format!(" [{i}] {} -> {v}", bytes[i]);
        bytes[i] = v;
    }
    (bytes, desc)
}

/// A small sun and sky, the light every relight of the harness uses.
fn sky() -> EnvMap {
    SunSky::new(40.0, 60.0, 4.0, 3.0).to_latlong(64, 32, 2)
}

/// Relights a loaded transport every way a command does and checks each image; lights are
/// kept per (N, SH order).
fn exercise_transport(
    t: &Transport,
    env: &EnvMap,
    lights: &mut HashMap<(u32, u32), (LightContext, PreparedLight)>,
) -> Result<(), String> {
    let key = (t.meta.identity.cube_n, t.meta.identity.sh_order);
    let (ctx, light) = match lights.entry(key) {
        std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
        std::collections::hash_map::Entry::Vacant(e) => {
            let Ok(ctx) = LightContext::new(t) else {
                return Ok(());
            };
            let light = ctx
                .prepare(env, EnvRotation::default())
                .map_err(|e| format!("the light of a valid transport: {e}"))?;
            e.insert((ctx, light))
        }
    };
    let (ctx, light) = (&*ctx, &*light);
    let total = t.coeff_count();
    for req in [
        RelightRequest::Wavelet {
            k: 5.min(total),
            weighting: Weighting::Area,
        },
        RelightRequest::Wavelet {
            k: total,
            weighting: Weighting::Transport,
        },
        RelightRequest::Sh {
            order: t.meta.identity.sh_order as usize,
        },
        RelightRequest::Full,
    ] {
        if let Ok((image, _)) = relight(t, ctx, light, &req) {
            if let Some(p) = image.first_non_finite() {
                return Err(format!("{:?} relight wrote {p:?}", req.method()));
            }
            draw_per_vertex(t, &image)?;
        }
    }
    Ok(())
}

/// Draws a per-vertex transport relit to `relit` from its own camera and from one it never
/// saw, and checks the pictures.
fn draw_per_vertex(t: &Transport, relit: &wavelet_prt::output::film::Image) -> Result<(), String> {
    use wavelet_prt::draw::vertex::{bake_camera, draw_relit, orbit};
    if t.mesh().is_none() {
        return Ok(());
    }
    let Ok(camera) = bake_camera(t) else {
        return Ok(());
    };
    for (k, camera) in [camera.clone(), orbit(&camera, 50.0, 20.0)]
        .iter()
        .enumerate()
    {
        if let Ok(drawn) = draw_relit(t, relit, None, camera, None, 1)
            && let Some(p) = drawn.image.first_non_finite()
        {
            return Err(format!("a per-vertex draw (camera {k}) wrote {p:?}"));
        }
    }
    Ok(())
}

/// Loads a mutated transport and does with it what the commands do.
fn check_transport(
    path: &Path,
    env: &EnvMap,
    lights: &mut HashMap<(u32, u32), (LightContext, PreparedLight)>,
) -> Result<bool, String> {
    let _ = wavelet_prt::store::transport::read_header_meta(path);
    let Ok(t) = Transport::load(path) else {
        return Ok(true);
    };
    exercise_transport(&t, env, lights)?;
    // What loaded saves and loads back the same.
    let again = path.with_extension("again.prt");
    t.save(&again)
        .map_err(|e| format!("a loaded transport does not save: {e}"))?;
    let back = Transport::load(&again).map_err(|e| format!("a saved transport: {e}"))?;
    if back != t {
        return Err("save and load changed the transport".into());
    }
    Ok(false)
}

#[test]
fn mutated_transports_are_errors_or_finite_images() {
    let dir = temp_dir("mutations-prt");
    let env = sky();
    let mut sources = Vec::new();
    for (k, q) in [Quantization::Q8, Quantization::Q16, Quantization::F32]
        .into_iter()
        .enumerate()
    {
        let p = dir.join(format!("random-{q}.prt"));
        random_transport(20, 18, 2, q, 11 + k as u64, 1.0)
            .save(&p)
            .unwrap();
        sources.push(StFile::read(&p));
    }
    // A real bake: glossy rows, empty pixels, SH order 2.
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, SPHERE_ON_PLANE).unwrap();
    let settings = BakeSettings {
        cube_n: 4,
        sh_order: 2,
        ..BakeSettings::default()
    };
    let baked = dir.join("baked.prt");
    bake(&Scene::load(&scene).unwrap(), &settings, &|_| {})
        .unwrap()
        .save(&baked)
        .unwrap();
    sources.push(StFile::read(&baked));
    let mut h = Harness::new("prt", 0x5eed_0001);
    let mut lights = HashMap::new();
    let path = dir.join("mutated.prt");
    for i in 0..count("prt") {
        let mut rng = Rng::new(h.seed, i as u64);
        let source = pick(&mut rng, sources.len());
        let (bytes, what) = mutate_safetensors(&mut rng, &sources[source]);
        std::fs::write(&path, &bytes).unwrap();
        let what = format!("file {source}, {what}");
        h.check(i, &what, &path, || {
            check_transport(&path, &env, &mut lights)
        });
    }
    h.finish();
}

#[test]
fn mutated_shards_merge_or_are_refused() {
    let dir = temp_dir("mutations-shards");
    let env = sky();
    let scene_path = dir.join("scene.toml");
    std::fs::write(
        &scene_path,
        SPHERE_ON_PLANE.replace("height = 21", "height = 45"),
    )
    .unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let shards: Vec<Transport> = (0..3)
        .map(|i| {
            let settings = BakeSettings {
                cube_n: 2,
                sh_order: 1,
                shard: Some([i, 3]),
                ..BakeSettings::default()
            };
            bake(&scene, &settings, &|_| {}).unwrap()
        })
        .collect();
    let files: Vec<StFile> = shards
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let p = dir.join(format!("part-{i}.prt"));
            t.save(&p).unwrap();
            StFile::read(&p)
        })
        .collect();
    let mut h = Harness::new("shards", 0x5eed_0002);
    let mut lights = HashMap::new();
    let path = dir.join("mutated.prt");
    for i in 0..count("shards") {
        let mut rng = Rng::new(h.seed, i as u64);
        let k = pick(&mut rng, 3);
        let (bytes, what) = mutate_safetensors(&mut rng, &files[k]);
        std::fs::write(&path, &bytes).unwrap();
        let what = format!("shard {k}, {what}");
        h.check(i, &what, &path, || {
            let Ok(t) = Transport::load(&path) else {
                return Ok(true);
            };
            let mut set = shards.clone();
            set[k] = t;
            // In every order: the merge may not depend on which file comes first.
            set.rotate_left(k);
            match Transport::merge(&set) {
                Err(_) => Ok(true),
                Ok(m) => {
                    m.validate()
                        .map_err(|e| format!("merged an invalid file: {e}"))?;
                    exercise_transport(&m, &env, &mut lights)?;
                    Ok(false)
                }
            }
        });
    }
    h.finish();
}

/// Renders a loaded volume every way `volume render` and `view` do, small.
fn exercise_volume(vt: &VolumeTransfer, env: &EnvMap) -> Result<(), String> {
    let state = wavelet_prt::app::viewer::VolumeState::initial(vt);
    let _ = state.camera(vt);
    let camera = vt
        .camera(None, None, Some((8, 6)))
        .map_err(|e| format!("a loaded volume's default view: {e}"))?;
    let cube = env
        .to_cube(4, EnvRotation::default())
        .map_err(|e| e.to_string())?;
    for view in VolumeView::ALL {
        let light = VolumeLight::new(vt, &cube, &MediumLook::of(vt)).map_err(|e| e.to_string())?;
        let image = render_volume(vt, &light, &camera, view);
        // The commands refuse an image with a NaN; here it only counts as refused.
        let _ = image.check_finite("volume image");
    }
    Ok(())
}

#[test]
fn mutated_volumes_are_errors_or_render() {
    let dir = temp_dir("mutations-prtv");
    let env = sky();
    let scene_path = dir.join("fog.toml");
    std::fs::write(&scene_path, fog_scene(0.3, 12, 10)).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    // Three orders, so that the scattered fields and their metadata are damaged too.
    let settings = TransferSettings {
        sh_order: 2,
        directions: 16,
        scatter: ScatterSettings {
            orders: 3,
            angular: 2,
            light: 2,
            directions: 16,
        },
    };
    let vt = bake_volume(&scene, Some(6), &settings, &|_, _| {}).unwrap();
    assert!(vt.scatter.is_some());
    let good = dir.join("fog.prtv");
    vt.save(&good).unwrap();
    let file = StFile::read(&good);
    let mut h = Harness::new("prtv", 0x5eed_0003);
    let path = dir.join("mutated.prtv");
    for i in 0..count("prtv") {
        let mut rng = Rng::new(h.seed, i as u64);
        let (bytes, what) = mutate_safetensors(&mut rng, &file);
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what, &path, || {
            let _ = wavelet_prt::volume::is_volume_file(&path);
            let Ok(vt) = VolumeTransfer::load(&path) else {
                return Ok(true);
            };
            exercise_volume(&vt, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

// ---------------------------------------------------------------------------------------------
// Text formats (scene TOML, OBJ).

/// Byte ranges `(start, end)` in a text.
type Spans = Vec<(usize, usize)>;

/// The byte ranges of number tokens and of quoted strings in `text`.
fn tokens(text: &str) -> (Spans, Spans) {
    let b = text.as_bytes();
    let (mut numbers, mut strings) = (Vec::new(), Vec::new());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'"' {
            let start = i;
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += 1;
            }
            strings.push((start, (i + 1).min(b.len())));
        } else if b[i].is_ascii_digit()
            || (b[i] == b'-' && i + 1 < b.len() && b[i + 1].is_ascii_digit())
        {
            let start = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b"._-+".contains(&b[i])) {
                i += 1;
            }
            numbers.push((start, i));
            continue;
        }
        i += 1;
    }
    (numbers, strings)
}

/// One or (one time in five) two mutations of a text file (see [`mutate_text_once`]).
fn mutate_text(rng: &mut Rng, text: &str, strings_to_try: &[&str]) -> (Vec<u8>, String) {
    let (bytes, what) = mutate_text_once(rng, text, strings_to_try);
    if pick(rng, 5) != 0 {
        return (bytes, what);
    }
    let again = String::from_utf8_lossy(&bytes).into_owned();
    let (bytes, second) = mutate_text_once(rng, &again, strings_to_try);
    (bytes, format!("{what}; {second}"))
}

/// One mutation of a text file: a number, a string or a line edited, the text cut, or stray
/// bytes put in.
fn mutate_text_once(rng: &mut Rng, text: &str, strings_to_try: &[&str]) -> (Vec<u8>, String) {
    let (numbers, strings) = tokens(text);
    let lines: Vec<&str> = text.lines().collect();
    let replace = |(a, b): (usize, usize), with: &str| {
        let mut s = text[..a].to_string();
        s.push_str(with);
        s.push_str(&text[b..]);
        s.into_bytes()
    };
    match pick(rng, 100) {
        0..=49 if !numbers.is_empty() => {
            let t = *choose(rng, &numbers);
            let with = *choose(
                rng,
                &[
                    "0",
                    "-0.0",
                    "-1",
                    "1",
                    "2",
                    "1e39",
                    "-1e39",
                    "1e-45",
                    "nan",
                    "inf",
                    "-inf",
                    "1e308",
                    "3.4e38",
                    "99999999999",
                    "4294967296",
                    "16385",
                    "65536",
                    "0.5",
                    "-2147483649",
                    "18446744073709551616",
                    "1_000",
                    "0x10",
                    "\"x\"",
                    "true",
                    "[]",
                    "-0",
                    "1e-300",
                    "7",
                ],
            );
            let old = &text[t.0..t.1];
            (replace(t, with), format!("number `{old}` -> `{with}`"))
        }
        50..=64 if !strings.is_empty() => {
            let t = *choose(rng, &strings);
            let with = *choose(rng, strings_to_try);
            let old = &text[t.0..t.1];
            (replace(t, with), format!("string {old} -> {with}"))
        }
        65..=84 if lines.len() > 1 => {
            let i = pick(rng, lines.len());
            let j = pick(rng, lines.len());
            let mut l: Vec<&str> = lines.clone();
            let desc = match pick(rng, 3) {
                0 => {
                    l.remove(i);
                    format!("line {} dropped", i + 1)
                }
                1 => {
                    l.insert(i, lines[i]);
                    format!("line {} doubled", i + 1)
                }
                _ => {
                    l.swap(i, j);
                    format!("lines {} and {} swapped", i + 1, j + 1)
                }
            };
            (l.join("\n").into_bytes(), desc)
        }
        85..=92 => {
            let cut = pick(rng, text.len());
            (
                text.as_bytes()[..cut].to_vec(),
                format!("truncated to {cut} bytes"),
            )
        }
        _ => {
            let mut b = text.as_bytes().to_vec();
            let i = pick(rng, b.len() + 1);
            let stray = *choose(
                rng,
                &[&b"\xff"[..], b"\0", b"[", b"]]", b"=", b"\n[[shape]]\n"],
            );
            b.splice(i..i, stray.iter().copied());
            (b, format!("{stray:?} put in at byte {i}"))
        }
    }
}

/// A tiny bake of a loaded scene and a relight of it, when the scene is small enough to bake
/// in a moment (a mutation may ask for 16384² pixels or a 512³ medium, which are valid).
fn exercise_scene(scene: &Scene, env: &EnvMap) -> Result<(), String> {
    let pixels = scene.camera.width as u64 * scene.camera.height as u64;
    let medium_small = scene
        .medium
        .as_ref()
        .is_none_or(|m| m.build(Some(6)).is_ok());
    if pixels > 48 * 48 || scene.triangle_count() > 20_000 || !medium_small {
        return Ok(());
    }
    let settings = BakeSettings {
        cube_n: 2,
        sh_order: 1,
        ..BakeSettings::default()
    };
    let scene = match &scene.medium {
        // Bake the medium at a few voxels, whatever resolution the mutation asked for.
        Some(m) if m.resolution > 6 => {
            let mut s = scene.clone();
            if let Some(spec) = s.medium.as_mut() {
                spec.resolution = 6;
            }
            s
        }
        _ => scene.clone(),
    };
    let Ok(t) = bake(&scene, &settings, &|_| {}) else {
        return Ok(());
    };
    t.validate()
        .map_err(|e| format!("baked an invalid transport: {e}"))?;
    exercise_transport(&t, env, &mut HashMap::new())
}

/// The scenes the text mutations start from: the sphere on a plane, a mesh with a glossy
/// material, a cloud and a grid medium, written to `dir` with their mesh and grid.
fn scene_texts(dir: &Path) -> Vec<(PathBuf, String)> {
    let obj = "# a unit cube\nv -0.5 0 -0.5\nv 0.5 0 -0.5\nv 0.5 1 -0.5\nv -0.5 1 -0.5\n\
               v -0.5 0 0.5\nv 0.5 0 0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\nvn 0 1 0\nvt 0 0\n\
               f 1 2 3 4\nf 5/1 6/1 7/1 8/1\nf 1//1 5//1 8//1 4//1\nf 2 6 7 3\nf -1 -2 -3\n\
               f 1 2 6 5\n";
    std::fs::write(dir.join("cube.obj"), obj).unwrap();
    let grid = wavelet_prt::medium::DensityGrid::from_fn(
        [4, 3, 5],
        glam::Vec3::ZERO,
        glam::Vec3::ONE,
        |p| p.x + 0.5 * p.y,
    );
    wavelet_prt::medium::save_npy(&dir.join("grid.npy"), &grid).unwrap();
    let camera = "[camera]\neye = [0.0, 1.5, 4.0]\ntarget = [0.0, 0.5, 0.0]\nup = [0.0, 1.0, 0.0]\n\
                  fov_y_deg = 40.0\nwidth = 24\nheight = 18\n";
    let texts = [
        SPHERE_ON_PLANE.replace("width = 37", "width = 24"),
        format!(
            "{camera}\n[material.shiny]\ntype = \"glossy\"\nalbedo = [0.5, 0.5, 0.5]\n\
             specular = [0.5, 0.5, 0.5]\nroughness = 0.3\n\n[material.ground]\ntype = \"diffuse\"\n\
             albedo = [0.8, 0.8, 0.8]\n\n[[shape]]\ntype = \"mesh\"\npath = \"cube.obj\"\n\
             scale = 0.8\nrotate_y_deg = 30.0\ntranslate = [0.0, 0.0, 0.0]\nsmooth_normals = true\n\
             material = \"shiny\"\n\n[[shape]]\ntype = \"quad\"\n\
             corners = [[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]\n\
             material = \"ground\"\n"
        ),
        format!(
            "{camera}\n[medium]\ntype = \"cloud\"\nbounds = [[-1.0, 0.0, -1.0], [1.0, 1.0, 1.0]]\n\
             resolution = 6\nextinction = 4.0\nalbedo = [0.9, 0.9, 0.9]\ng = 0.2\nseed = 3\n\
             frequency = 2.5\noctaves = 2\ncoverage = 0.6\n"
        ),
        format!(
            "{camera}\n[medium]\ntype = \"grid\"\npath = \"grid.npy\"\n\
             bounds = [[-1.0, 0.0, -1.0], [1.0, 1.0, 1.0]]\nextinction = 2.0\n\
             albedo = [0.9, 0.8, 0.7]\n\n[material.m]\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n\n\
             [[shape]]\ntype = \"sphere\"\ncenter = [0.0, 0.5, 0.0]\nradius = 0.3\nmaterial = \"m\"\n"
        ),
    ];
    texts
        .into_iter()
        .enumerate()
        .map(|(i, t)| (dir.join(format!("scene-{i}.toml")), t))
        .collect()
}

const SCENE_STRINGS: &[&str] = &[
    "\"\"",
    "\"x\"",
    "\"diffuse\"",
    "\"glossy\"",
    "\"mesh\"",
    "\"quad\"",
    "\"sphere\"",
    "\"grid\"",
    "\"cloud\"",
    "\"ellipsoid\"",
    "\"ground\"",
    "\"cube.obj\"",
    "\"grid.npy\"",
    "\"missing.obj\"",
    "\"/dev/zero\"",
    "\"/\"",
    "\".\"",
    "\"scene-0.toml\"",
    "\"\\u0000\"",
];

#[test]
fn mutated_scenes_are_errors_or_bake() {
    let dir = temp_dir("mutations-scene");
    let env = sky();
    let texts = scene_texts(&dir);
    let mut h = Harness::new("scene", 0x5eed_0004);
    let path = dir.join("mutated.toml");
    for i in 0..count("scene") {
        let mut rng = Rng::new(h.seed, i as u64);
        let k = pick(&mut rng, texts.len());
        let (bytes, what) = mutate_text(&mut rng, &texts[k].1, SCENE_STRINGS);
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &format!("scene {k}, {what}"), &path, || {
            let Ok(scene) = Scene::load(&path) else {
                return Ok(true);
            };
            exercise_scene(&scene, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

#[test]
fn mutated_meshes_are_errors_or_bake() {
    let dir = temp_dir("mutations-obj");
    let env = sky();
    let texts = scene_texts(&dir);
    let obj = std::fs::read_to_string(dir.join("cube.obj")).unwrap();
    let scene = dir.join("mesh.toml");
    std::fs::write(&scene, texts[1].1.replace("cube.obj", "mutated.obj")).unwrap();
    let mut h = Harness::new("obj", 0x5eed_0005);
    let path = dir.join("mutated.obj");
    for i in 0..count("obj") {
        let mut rng = Rng::new(h.seed, i as u64);
        let (bytes, what) = mutate_text(&mut rng, &obj, &["\"\"", "f", "v", "vn", "vt"]);
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what, &path, || {
            let Ok(scene) = Scene::load(&scene) else {
                return Ok(true);
            };
            exercise_scene(&scene, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

#[test]
fn mutated_grids_are_errors_or_render() {
    let dir = temp_dir("mutations-npy");
    let env = sky();
    let texts = scene_texts(&dir);
    let npy = std::fs::read(dir.join("grid.npy")).unwrap();
    let scene_path = dir.join("grid.toml");
    std::fs::write(&scene_path, texts[3].1.replace("grid.npy", "mutated.npy")).unwrap();
    let header_end = 10 + u16::from_le_bytes([npy[8], npy[9]]) as usize;
    let header = String::from_utf8(npy[10..header_end].to_vec()).unwrap();
    let mut h = Harness::new("npy", 0x5eed_0006);
    let path = dir.join("mutated.npy");
    for i in 0..count("npy") {
        let mut rng = Rng::new(h.seed, i as u64);
        let mut bytes = npy.clone();
        let what = match pick(&mut rng, 10) {
            // The header's text: descr, fortran_order and shape, edited as text (the length
            // field follows).
            0..=3 => {
                let (b, what) = mutate_text(
                    &mut rng,
                    &header,
                    &[
                        "'<f4'", "'<f8'", "'>f4'", "'<f2'", "'|u1'", "'<i4'", "''", "'x'",
                    ],
                );
                let mut out = npy[..8].to_vec();
                out.extend_from_slice(&(b.len() as u16).to_le_bytes());
                out.extend_from_slice(&b);
                out.extend_from_slice(&npy[header_end..]);
                bytes = out;
                format!("header {what}")
            }
            // The version byte or the header length.
            4 => {
                let at = *choose(&mut rng, &[6usize, 7, 8, 9]);
                let v = *choose(&mut rng, &[0u8, 1, 2, 3, 4, 255, 0x7f]);
                bytes[at] = v;
                format!("byte {at} -> {v}")
            }
            // A density.
            5..=7 => {
                let n = (npy.len() - header_end) / 4;
                let k = pick(&mut rng, n);
                let what = edit_value(&mut rng, "F32", &mut bytes[header_end..], k);
                format!("density {k}: {what}")
            }
            8 => {
                let cut = pick(&mut rng, bytes.len());
                bytes.truncate(cut);
                format!("truncated to {cut} bytes")
            }
            _ => {
                let extra = 1 + pick(&mut rng, 16);
                bytes.extend(std::iter::repeat_n(0u8, extra));
                format!("{extra} bytes added")
            }
        };
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what, &path, || {
            let _ = wavelet_prt::medium::load_npy(&path, glam::Vec3::ZERO, glam::Vec3::ONE);
            let Ok(scene) = Scene::load(&scene_path) else {
                return Ok(true);
            };
            let settings = TransferSettings {
                sh_order: 2,
                directions: 16,
                scatter: ScatterSettings {
                    orders: 2,
                    angular: 2,
                    light: 2,
                    directions: 16,
                },
            };
            let Ok(vt) = bake_volume(&scene, None, &settings, &|_, _| {}) else {
                return Ok(true);
            };
            exercise_volume(&vt, &env)?;
            exercise_scene(&scene, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

// ---------------------------------------------------------------------------------------------
// Environment maps (EXR, HDR).

/// Loads a mutated map, prepares its light for a small transport and relights with it.
fn check_env(path: &Path, t: &Transport) -> Result<bool, String> {
    let _ = wavelet_prt::output::film::Image::load_exr(path);
    let Ok(env) = EnvMap::load(path) else {
        return Ok(true);
    };
    if let Some((i, p)) = env
        .pixels
        .iter()
        .enumerate()
        .find(|(_, p)| !p.iter().all(|v| v.is_finite() && *v >= 0.0))
    {
        return Err(format!("pixel {i} loaded as {p:?}"));
    }
    let ctx = LightContext::new(t).map_err(|e| e.to_string())?;
    let Ok(light) = ctx.prepare(&env, EnvRotation::yaw(30.0)) else {
        return Ok(true);
    };
    exercise_transport(t, &env, &mut HashMap::from([((2, 2), (ctx, light))]))?;
    Ok(false)
}

/// Where `name`'s value starts in an EXR header (after the name, type and size).
fn exr_attribute(bytes: &[u8], name: &str) -> Option<(usize, usize)> {
    let key = format!("{name}\0");
    let at = bytes.windows(key.len()).position(|w| w == key.as_bytes())?;
    let mut i = at + key.len();
    while *bytes.get(i)? != 0 {
        i += 1;
    }
    let size = u32::from_le_bytes(bytes.get(i + 1..i + 5)?.try_into().ok()?) as usize;
    Some((i + 5, size))
}

#[test]
fn mutated_exr_maps_are_errors_or_finite_light() {
    use exr::prelude::*;
    let dir = temp_dir("mutations-exr");
    let t = random_transport(20, 18, 2, Quantization::Q8, 21, 1.0);
    let pixel = |x: usize, y: usize| (x as f32 * 0.1, y as f32 * 0.2, 1.0 + (x + y) as f32);
    let mut sources = Vec::new();
    for (k, encoding) in [Encoding::UNCOMPRESSED, Encoding::FAST_LOSSLESS]
        .into_iter()
        .enumerate()
    {
        let p = dir.join(format!("map-{k}.exr"));
        Image::from_encoded_channels(
            (16, 8),
            encoding,
            SpecificChannels::rgb(|pos: Vec2<usize>| pixel(pos.x(), pos.y())),
        )
        .write()
        .to_file(&p)
        .unwrap();
        sources.push(std::fs::read(&p).unwrap());
    }
    let mut h = Harness::new("exr", 0x5eed_0007);
    let path = dir.join("mutated.exr");
    for i in 0..count("exr") {
        let mut rng = Rng::new(h.seed, i as u64);
        let k = pick(&mut rng, sources.len());
        let mut bytes = sources[k].clone();
        let header_end = bytes.windows(2).position(|w| w == [0, 0]).unwrap_or(8);
        let what = match pick(&mut rng, 10) {
            // An integer of a header attribute: the windows, channels, compression, order.
            0..=3 => {
                let name = *choose(
                    &mut rng,
                    &[
                        "dataWindow",
                        "displayWindow",
                        "channels",
                        "compression",
                        "lineOrder",
                    ],
                );
                match exr_attribute(&bytes, name) {
                    Some((at, size)) if size > 0 => {
                        let j = at + 4 * pick(&mut rng, size.div_ceil(4));
                        let v = interesting_int(&mut rng, 0, i32::MIN as i128, i32::MAX as i128);
                        let end = (j + 4).min(bytes.len());
                        let vb = (v as i32).to_le_bytes();
                        bytes[j..end].copy_from_slice(&vb[..end - j]);
                        format!("{name} word at {j} -> {v}")
                    }
                    _ => format!("{name} absent"),
                }
            }
            // A chunk offset (the table after the header) or a chunk's line number or size.
            4 | 5 => {
                let j = (header_end + 8 * pick(&mut rng, 8)).min(bytes.len() - 8);
                let v = *choose(
                    &mut rng,
                    &[0u64, 1, 7, u64::MAX, 1 << 40, bytes.len() as u64, j as u64],
                );
                bytes[j..j + 8].copy_from_slice(&v.to_le_bytes());
                format!("word at {j} -> {v}")
            }
            // A pixel value (uncompressed data is the tail of the file).
            6 | 7 => {
                let n = (bytes.len() - header_end) / 4;
                let j = bytes.len() - 4 * (1 + pick(&mut rng, n.min(16 * 8 * 3)));
                let what = edit_value(&mut rng, "F32", &mut bytes[j..j + 4], 0);
                format!("value at {j}: {what}")
            }
            8 => {
                let cut = pick(&mut rng, bytes.len());
                bytes.truncate(cut);
                format!("truncated to {cut} bytes")
            }
            _ => {
                let j = pick(&mut rng, bytes.len());
                let v = rng.next_u64() as u8;
                bytes[j] = v;
                format!("byte {j} -> {v}")
            }
        };
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &format!("map {k}, {what}"), &path, || {
            check_env(&path, &t)
        });
    }
    h.finish();
}

#[test]
fn mutated_hdr_maps_are_errors_or_finite_light() {
    let dir = temp_dir("mutations-hdr");
    let t = random_transport(20, 18, 2, Quantization::Q8, 21, 1.0);
    let mut sources = Vec::new();
    for (k, (w, h)) in [(16usize, 8usize), (4, 3)].into_iter().enumerate() {
        let p = dir.join(format!("map-{k}.hdr"));
        let pixels: Vec<image::Rgb<f32>> = (0..w * h)
            .map(|i| image::Rgb([i as f32 * 0.5, 1.0, 20.0]))
            .collect();
        image::codecs::hdr::HdrEncoder::new(std::fs::File::create(&p).unwrap())
            .encode(&pixels, w, h)
            .unwrap();
        sources.push(std::fs::read(&p).unwrap());
    }
    let mut h = Harness::new("hdr", 0x5eed_0008);
    let path = dir.join("mutated.hdr");
    for i in 0..count("hdr") {
        let mut rng = Rng::new(h.seed, i as u64);
        let k = pick(&mut rng, sources.len());
        let src = &sources[k];
        // The text header ends with the resolution line.
        let text_end = src
            .windows(2)
            .position(|w| w == b"\n-" || w == b"\n+")
            .and_then(|p| {
                src[p + 1..]
                    .iter()
                    .position(|&c| c == b'\n')
                    .map(|q| p + q + 2)
            })
            .unwrap_or(0);
        let header = String::from_utf8_lossy(&src[..text_end]).into_owned();
        let mut bytes = src.clone();
        let what = match pick(&mut rng, 10) {
            0..=3 => {
                let (b, what) = mutate_text(
                    &mut rng,
                    &header,
                    &[
                        "\"\"",
                        "-Y",
                        "+Y",
                        "-X",
                        "+X",
                        "FORMAT=32-bit_rle_xyze",
                        "EXPOSURE=nan",
                    ],
                );
                bytes = b;
                bytes.extend_from_slice(&src[text_end..]);
                format!("header {what}")
            }
            4 => {
                let mut b = header.clone().into_bytes();
                b.truncate(b.len() - 1);
                b.extend_from_slice(b"\nEXPOSURE=0\n");
                b.extend_from_slice(&src[text_end..]);
                bytes = b;
                "EXPOSURE=0 after the resolution".into()
            }
            5..=7 if text_end < src.len() => {
                let j = text_end + pick(&mut rng, src.len() - text_end);
                let v = *choose(&mut rng, &[0u8, 1, 2, 127, 128, 255]);
                bytes[j] = v;
                format!("pixel byte {j} -> {v}")
            }
            8 => {
                let cut = pick(&mut rng, bytes.len());
                bytes.truncate(cut);
                format!("truncated to {cut} bytes")
            }
            _ => {
                let extra: Vec<u8> = (0..1 + pick(&mut rng, 64))
                    .map(|_| rng.next_u64() as u8)
                    .collect();
                bytes.extend_from_slice(&extra);
                format!("{} bytes added", extra.len())
            }
        };
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &format!("map {k}, {what}"), &path, || {
            check_env(&path, &t)
        });
    }
    h.finish();
}

/// The glTF scene the glTF mutations start from, at a size `exercise_scene` bakes.
fn gltf_framing() -> wavelet_prt::scene::Framing {
    wavelet_prt::scene::Framing {
        camera: None,
        width: Some(24),
        height: Some(16),
        ..Default::default()
    }
}

const GLTF_STRINGS: &[&str] = &[
    "\"\"",
    "\"x\"",
    "\"VEC2\"",
    "\"VEC3\"",
    "\"SCALAR\"",
    "\"MAT4\"",
    "\"image/png\"",
    "\"missing.bin\"",
    "\"/dev/zero\"",
    "\"data:application/octet-stream;base64,AAAA\"",
    "\"data:,x\"",
    "\"s_image0.png\"",
    "\"perspective\"",
    "\"orthographic\"",
];

#[test]
fn mutated_gltf_json_is_an_error_or_bakes() {
    let dir = temp_dir("mutations-gltf");
    let env = sky();
    let original = common::gltf::test_scene(4, false).write_gltf(&dir, "s");
    let text = std::fs::read_to_string(&original).unwrap();
    let mut h = Harness::new("gltf", 0x5eed_0009);
    let path = dir.join("mutated.gltf");
    for i in 0..count("gltf") {
        let mut rng = Rng::new(h.seed, i as u64);
        let (bytes, what) = mutate_text(&mut rng, &text, GLTF_STRINGS);
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what, &path, || {
            let Ok(scene) = Scene::load_with(&path, &gltf_framing()) else {
                return Ok(true);
            };
            exercise_scene(&scene, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

#[test]
fn mutated_glbs_are_errors_or_bake() {
    let dir = temp_dir("mutations-glb");
    let env = sky();
    let original = std::fs::read(common::gltf::test_scene(4, false).write_glb(&dir, "s")).unwrap();
    let json_len = u32::from_le_bytes(original[12..16].try_into().unwrap()) as usize;
    let json = String::from_utf8(original[20..20 + json_len].to_vec()).unwrap();
    let bin = original[20 + json_len + 8..].to_vec();
    let mut h = Harness::new("glb", 0x5eed_000a);
    let path = dir.join("mutated.glb");
    for i in 0..count("glb") {
        let mut rng = Rng::new(h.seed, i as u64);
        let (bytes, what) = match pick(&mut rng, 4) {
            // The JSON chunk edited, the container repacked around it.
            0 | 1 => {
                let (text, what) = mutate_text(&mut rng, &json, GLTF_STRINGS);
                (common::gltf::pack_glb(&text, &bin), format!("JSON: {what}"))
            }
            // Bytes of the binary chunk (positions, indices, the PNG) changed.
            2 => {
                let mut b = bin.clone();
                let n = 1 + pick(&mut rng, 4);
                for _ in 0..n {
                    let at = pick(&mut rng, b.len());
                    b[at] = *choose(&mut rng, &[0u8, 1, 0x7f, 0x80, 0xff, b[at] ^ 0x40]);
                }
                (
                    common::gltf::pack_glb(json.as_bytes(), &b),
                    format!("{n} bytes of BIN changed"),
                )
            }
            // The container itself: a header or chunk length, or a cut.
            _ => {
                let mut b = original.clone();
                if pick(&mut rng, 2) == 0 {
                    let at = *choose(&mut rng, &[4usize, 8, 12, 16, 20 + json_len, 24 + json_len]);
                    let v = interesting_int(&mut rng, 0, 0, u32::MAX as i128) as u32;
                    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
                    (b, format!("u32 at byte {at} set to {v}"))
                } else {
                    let keep = pick(&mut rng, b.len());
                    b.truncate(keep);
                    (b, format!("cut to {keep} bytes"))
                }
            }
        };
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what, &path, || {
            let Ok(scene) = Scene::load_with(&path, &gltf_framing()) else {
                return Ok(true);
            };
            exercise_scene(&scene, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

/// The tests' glTF scene in `dir/model/`, with a copy of its buffer and image one folder up
/// (`dir/`), where a URI that leaves the model's folder would find them.
fn model_beside_copies(dir: &Path) -> (PathBuf, String) {
    let folder = dir.join("model");
    std::fs::create_dir_all(&folder).unwrap();
    let path = common::gltf::test_scene(4, false).write_gltf(&folder, "s");
    for f in ["s data.bin", "s_image0.png"] {
        std::fs::copy(folder.join(f), dir.join(f)).unwrap();
    }
    let _ = std::fs::remove_file(folder.join("up.bin"));
    std::os::unix::fs::symlink(dir.join("s data.bin"), folder.join("up.bin")).unwrap();
    std::fs::create_dir_all(folder.join("sub")).unwrap();
    std::fs::copy(folder.join("s data.bin"), folder.join("sub/b.bin")).unwrap();
    (path.clone(), std::fs::read_to_string(&path).unwrap())
}

/// URIs a buffer or an image of the glTF mutations may take: the right ones, ones inside the
/// folder by other spellings, and ones that leave it by `..`, escapes, a link or an absolute
/// path.
const GLTF_URIS: &[&str] = &[
    "s%20data.bin",
    "s data.bin",
    "./s%20data.bin",
    "sub/b.bin",
    "sub/../s%20data.bin",
    "s_image0.png",
    "../s%20data.bin",
    "..%2Fs%20data.bin",
    "%2e%2e/s_image0.png",
    "sub/../../s%20data.bin",
    "up.bin",
    "/etc/passwd",
    "../../../../../../../../proc/self/environ",
    "file:///etc/passwd",
    "missing.bin",
    "%00",
    "%zz",
    "sub",
    "",
];

#[test]
fn mutated_gltf_uris_stay_in_the_model_folder() {
    let dir = temp_dir("mutations-gltf-uri");
    let env = sky();
    let (path, text) = model_beside_copies(&dir);
    let folder = std::fs::canonicalize(dir.join("model")).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut h = Harness::new("gltf-uri", 0x5eed_000b);
    for i in 0..count("gltf-uri") {
        let mut rng = Rng::new(h.seed, i as u64);
        let mut d = doc.clone();
        let mut what = Vec::new();
        // The buffer's URI, the image's, or both; now and then mutated further as text.
        let which = pick(&mut rng, 3);
        for (k, at) in [("buffers", 0usize), ("images", 1)] {
            if which == at || which == 2 {
                let uri = *choose(&mut rng, GLTF_URIS);
                d[k][0]["uri"] = serde_json::json!(uri);
                what.push(format!("{k}[0].uri = {uri:?}"));
            }
        }
        let mut bytes = serde_json::to_vec_pretty(&d).unwrap();
        if pick(&mut rng, 4) == 0 {
            let (b, w) = mutate_text(&mut rng, &String::from_utf8(bytes).unwrap(), GLTF_STRINGS);
            bytes = b;
            what.push(w);
        }
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what.join(", "), &path, || {
            let Ok(scene) = Scene::load_with(&path, &gltf_framing()) else {
                return Ok(true);
            };
            // Whatever loaded read nothing outside the model's folder.
            for f in &scene.input_files {
                let f = std::fs::canonicalize(f).map_err(|e| format!("{}: {e}", f.display()))?;
                if !f.starts_with(&folder) {
                    return Err(format!("read {} outside the model's folder", f.display()));
                }
            }
            exercise_scene(&scene, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

/// The light tables the light mutations start from, beside the viewer's quad and spot
/// ([`common::VIEWER_LIGHTS`]): a point and a directional light with a disc.
const MORE_LIGHTS: &str = r#"
[[light]]
name = "bulb"
type = "point"
position = [-1.0, 1.0, 1.0]
intensity = 3.0

[[light]]
name = "sun"
type = "directional"
direction = [0.3, -1.0, 0.2]
angle_deg = 0.5
intensity = 1.5
"#;

const LIGHT_STRINGS: &[&str] = &[
    "\"\"",
    "\"x\"",
    "\"quad\"",
    "\"spot\"",
    "\"point\"",
    "\"directional\"",
    "\"sphere\"",
    "\"panel\"",
    "\"sun\"",
    "\"\\u0000\"",
];

#[test]
fn mutated_light_tables_are_errors_or_bake() {
    let dir = temp_dir("mutations-lights");
    let env = sky();
    let base = SPHERE_ON_PLANE
        .replace("width = 37", "width = 16")
        .replace("height = 21", "height = 10");
    let text = format!("{base}\n{}{MORE_LIGHTS}", common::VIEWER_LIGHTS);
    assert!(Scene::from_toml_str(&text, &dir.join("lit.toml")).is_ok());
    let mut h = Harness::new("lights", 0x5eed_000c);
    let path = dir.join("mutated.toml");
    for i in 0..count("lights") {
        let mut rng = Rng::new(h.seed, i as u64);
        // Mutations within the light tables, so that the camera and shapes stay valid.
        let at = text.find("[[light]]").unwrap_or(0);
        let (tail, what) = mutate_text(&mut rng, &text[at..], LIGHT_STRINGS);
        let mut bytes = text.as_bytes()[..at].to_vec();
        bytes.extend_from_slice(&tail);
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what, &path, || {
            let Ok(scene) = Scene::load(&path) else {
                return Ok(true);
            };
            exercise_lit_scene(&scene, &env)?;
            Ok(false)
        });
    }
    h.finish();
}

/// A tiny bake of a lit scene, relit with its lights at their defaults, and once with each
/// switched off.
fn exercise_lit_scene(scene: &Scene, env: &EnvMap) -> Result<(), String> {
    use wavelet_prt::relight::{Backend, Cpu, LightMix, LightSetting};
    let settings = BakeSettings {
        cube_n: 2,
        sh_order: 1,
        light_samples: 2,
        ..BakeSettings::default()
    };
    let Ok(t) = bake(scene, &settings, &|_| {}) else {
        return Ok(());
    };
    t.validate()
        .map_err(|e| format!("baked an invalid transport: {e}"))?;
    let ctx = LightContext::new(&t).map_err(|e| e.to_string())?;
    let light = ctx
        .prepare(env, EnvRotation::default())
        .map_err(|e| e.to_string())?;
    let mut settings = LightSetting::defaults(&scene.lights);
    for k in 0..=settings.len() {
        if k > 0 {
            settings[k - 1].on = false;
        }
        let mix = LightMix::new(&scene.lights, &settings).map_err(|e| e.to_string())?;
        let req = RelightRequest::Wavelet {
            k: 8.min(t.coeff_count()),
            weighting: Weighting::Area,
        };
        if let Ok((image, _)) = Backend::relight_with(&Cpu(&t), &ctx, &light, &req, &mix)
            && let Some(p) = image.first_non_finite()
        {
            return Err(format!("a lit relight wrote {p:?}"));
        }
    }
    Ok(())
}

#[test]
fn mutated_per_vertex_tensors_are_errors_or_draw() {
    let env = sky();
    let source = StFile::read(&common::per_vertex_transport_path());
    let dir = temp_dir("mutations-per-vertex");
    let mut h = Harness::new("per-vertex", 0x5eed_000d);
    let mut lights = HashMap::new();
    let path = dir.join("mutated.prt");
    for i in 0..count("per-vertex") {
        let mut rng = Rng::new(h.seed, i as u64);
        let (bytes, what) = mutate_safetensors(&mut rng, &source);
        std::fs::write(&path, &bytes).unwrap();
        h.check(i, &what, &path, || {
            check_transport(&path, &env, &mut lights)
        });
    }
    h.finish();
}
