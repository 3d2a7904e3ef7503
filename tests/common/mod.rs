//! Helpers shared by the integration tests: temporary directories and small scenes.

#![allow(dead_code)]

pub mod gltf;
mod shared;
#[allow(unused_imports)]
pub use shared::{Rng, SPHERE_ON_PLANE, assert_close, assert_rel_close, temp_dir};

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::math::cubemap::texel_count;
use wavelet_prt::math::sampling::Rng as SampleRng;
use wavelet_prt::scene::Scene;
use wavelet_prt::store::transport::{
    BakeDomain, BakeIdentity, BakeStats, CameraMeta, Quantization, RowData, TILE, Transport,
    TransportMeta, tile_grid,
};

/// Relative L2 within which two sums of the same f32 products in another order agree (a tiled
/// kernel against a dense product, a turn by 360 degrees): float rounding over a few thousand
/// terms is ~1e-6.
pub const SAME_SUM: f64 = 1e-5;

/// Relative L2 within which the same sum agrees with itself taken in other f32 steps (a prefix
/// against a whole, all terms against "full"): ~1e-7 measured.
pub const SAME_VALUE: f64 = 1e-6;

/// Relative L2 within which the GPU kernels agree with the CPU's: the same products in another
/// order and with fused multiply-adds on some devices, ~1e-6 measured; real GPUs that flush
/// subnormals stay well inside.
pub const GPU_MATCH: f64 = 1e-4;

/// Every Haar term of a cube map's light: relighting with it is the full product.
pub fn full_light(
    cube: &wavelet_prt::math::cubemap::CubeMap,
) -> wavelet_prt::env::select::SparseLight {
    let w = wavelet_prt::env::select::WaveletLight::from_cube(cube).unwrap();
    wavelet_prt::env::select::SparseLight {
        indices: (0..w.coeffs.len() as u32).collect(),
        values: w.coeffs,
    }
}

/// `k` of `c` Haar coefficients drawn at random, in a shuffled order (sorted when `ascending`, as
/// a selection returns them), each with the RGB value `value` draws: a light for holding one
/// kernel to another.
pub fn random_light(
    rng: &mut SampleRng,
    c: usize,
    k: usize,
    ascending: bool,
    mut value: impl FnMut(&mut SampleRng) -> [f32; 3],
) -> wavelet_prt::env::select::SparseLight {
    let mut indices: Vec<u32> = (0..c as u32).collect();
    for i in (1..indices.len()).rev() {
        indices.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    indices.truncate(k);
    if ascending {
        indices.sort_unstable();
    }
    wavelet_prt::env::select::SparseLight {
        values: indices.iter().map(|_| value(rng)).collect(),
        indices,
    }
}

/// A glossy sphere (GGX roughness 0.5) on a matte ground: the shared sphere on its plane with
/// its clay made glossy.
#[allow(dead_code)]
pub fn glossy_sphere() -> String {
    let clay = "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]";
    assert!(SPHERE_ON_PLANE.contains(clay));
    SPHERE_ON_PLANE.replace(
        clay,
        "type = \"glossy\"\nalbedo = [0.3, 0.1, 0.05]\nspecular = [0.5, 0.5, 0.5]\nroughness = 0.5",
    )
}

/// The shared sphere on its plane, its clay made glossy (albedo (0.5, 0.2, 0.1), specular 0.4)
/// with GGX `roughness` when one is given, loaded as scene `name`.
#[allow(dead_code)]
pub fn sphere_scene(roughness: Option<f32>, name: &str) -> Scene {
    let clay = "[material.clay]\ntype = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]";
    assert!(SPHERE_ON_PLANE.contains(clay));
    let text = match roughness {
        Some(r) => SPHERE_ON_PLANE.replace(
            clay,
            &format!(
                "[material.clay]\ntype = \"glossy\"\nalbedo = [0.5, 0.2, 0.1]\n\
                 specular = [0.4, 0.4, 0.4]\nroughness = {r}"
            ),
        ),
        None => SPHERE_ON_PLANE.to_string(),
    };
    scene_from(&text, name)
}

/// A sky with a small sun (2° radius, smaller than a texel), on a cube of face 16.
#[allow(dead_code)]
pub fn sunny_cube() -> wavelet_prt::math::cubemap::CubeMap {
    wavelet_prt::env::envmap::EnvMap::from_spec("sun:35,60")
        .unwrap()
        .to_cube(16, wavelet_prt::env::envmap::EnvRotation::default())
        .unwrap()
}

/// Writes `text` as a scene file in its own temp dir and loads it. Every call gets a directory
/// of its own: tests of one binary run in parallel and may load the same scene at once.
pub fn scene_from(text: &str, name: &str) -> Scene {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = temp_dir(&format!("{name}-{n}"));
    let p = dir.join("scene.toml");
    std::fs::write(&p, text).unwrap();
    Scene::load(&p).unwrap()
}

/// The bundled assets.
pub fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets")
}

/// A square quad of half-size `half` at y = 0 with albedo `albedo`, seen straight from above by a
/// `width` x `height` camera: every pixel sees the plane, whose normal is +Y.
pub fn plane_from_above(width: u32, height: u32, albedo: [f32; 3], half: f32) -> String {
    format!(
        r#"
[camera]
eye = [0.0, 3.0, 0.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
fov_y_deg = 30.0
width = {width}
height = {height}
[material.m]
type = "diffuse"
albedo = {albedo:?}
[[shape]]
type = "quad"
corners = [[-{half:?}, 0.0, -{half:?}], [-{half:?}, 0.0, {half:?}], [{half:?}, 0.0, {half:?}], [{half:?}, 0.0, -{half:?}]]
material = "m"
"#
    )
}

/// A red ball on a grey floor under a slanted camera, small enough to bake in a moment.
pub const VIEWER_SCENE: &str = r#"
[camera]
eye = [0.5, 2.0, 3.5]
target = [0.0, 0.4, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 45.0
width = 40
height = 30

[material.floor]
type = "diffuse"
albedo = [0.7, 0.7, 0.7]

[material.ball]
type = "diffuse"
albedo = [0.9, 0.2, 0.1]

[[shape]]
type = "quad"
corners = [[-3.0, 0.0, -3.0], [-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0]]
material = "floor"

[[shape]]
type = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
material = "ball"
"#;

/// Cube face size and SH order of the test bake.
pub const VIEWER_N: usize = 8;
pub const VIEWER_SH_ORDER: usize = 3;

/// Path of the baked test transport (baked once per test process).
pub fn viewer_transport_path() -> PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("viewer-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene_path = dir.join("scene.toml");
        std::fs::write(&scene_path, VIEWER_SCENE).unwrap();
        let scene = Scene::load(&scene_path).unwrap();
        let settings = BakeSettings {
            cube_n: VIEWER_N,
            sh_order: VIEWER_SH_ORDER,
            threshold: 0.0,
            ..BakeSettings::default()
        };
        let t = bake(&scene, &settings, &|_| {}).unwrap();
        let out = dir.join("test.prt");
        t.save(&out).unwrap();
        out
    })
    .clone()
}

/// The viewer's test scene with a quad light and a spot, the spot moving along two positions.
pub const VIEWER_LIGHTS: &str = r#"
[[light]]
name = "panel"
type = "quad"
corners = [[-0.6, 2.0, -0.6], [0.6, 2.0, -0.6], [0.6, 2.0, 0.6], [-0.6, 2.0, 0.6]]
intensity = 2.0
color = [1.0, 0.9, 0.8]

[[light]]
name = "spot"
type = "spot"
positions = [[1.5, 1.5, 1.0], [1.0, 1.5, 1.5]]
direction = [-1.0, -1.0, -0.6]
cone_deg = 35.0
falloff_deg = 8.0
intensity = 4.0
color = [0.5, 0.6, 1.0]
"#;

/// Path of the viewer's test scene with [`VIEWER_LIGHTS`], baked as [`viewer_transport_path`]
/// (once per test process).
pub fn lit_viewer_transport_path() -> PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("viewer-lights-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene_path = dir.join("scene.toml");
        std::fs::write(&scene_path, format!("{VIEWER_SCENE}\n{VIEWER_LIGHTS}")).unwrap();
        let scene = Scene::load(&scene_path).unwrap();
        let settings = BakeSettings {
            cube_n: VIEWER_N,
            sh_order: VIEWER_SH_ORDER,
            threshold: 0.0,
            light_samples: 16,
            ..BakeSettings::default()
        };
        let t = bake(&scene, &settings, &|_| {}).unwrap();
        let out = dir.join("lit.prt");
        t.save(&out).unwrap();
        out
    })
    .clone()
}

/// Path of a per-vertex bake of [`SPHERE_ON_PLANE`] (cube 8, SH order 2, every value kept),
/// baked once per test process.
pub fn per_vertex_transport_path() -> PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("per-vertex-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scene_path = dir.join("scene.toml");
        std::fs::write(&scene_path, SPHERE_ON_PLANE).unwrap();
        let scene = Scene::load(&scene_path).unwrap();
        let settings = BakeSettings {
            cube_n: 8,
            sh_order: 2,
            lossless: true,
            domain: BakeDomain::Vertices { edge_length: 0.3 },
            ..BakeSettings::default()
        };
        let t = bake(&scene, &settings, &|_| {}).unwrap();
        let out = dir.join("vertices.prt");
        t.save(&out).unwrap();
        out
    })
    .clone()
}

/// A per-vertex bake with visibility over an N-cube, triangles of about `edge` a side.
pub fn visibility_settings(n: usize, edge: f32) -> wavelet_prt::bake::BakeSettings {
    wavelet_prt::bake::BakeSettings {
        cube_n: n,
        sh_order: 2,
        domain: wavelet_prt::store::transport::BakeDomain::Vertices { edge_length: edge },
        visibility: true,
        ..wavelet_prt::bake::BakeSettings::default()
    }
}

/// The brightest channel of any pixel of `image`.
pub fn brightest(image: &wavelet_prt::output::film::Image) -> f32 {
    image.pixels.iter().flatten().fold(0.0f32, |a, b| a.max(*b))
}

/// The pixels of a GPU drawing `dev` that differ from the CPU's `cpu` in coverage or by more
/// than `of_brightest` of the CPU's brightest value in a channel, and the largest difference of
/// the rest as a share of the brightest.
pub fn pixels_apart(
    dev: &wavelet_prt::draw::raster::Raster,
    cpu: &wavelet_prt::draw::raster::Raster,
    of_brightest: f32,
) -> (usize, f32) {
    let brightest = brightest(&cpu.image);
    let (mut apart, mut worst) = (0, 0.0f32);
    for i in 0..cpu.coverage.len() {
        let (a, b) = (dev.image.pixels[i], cpu.image.pixels[i]);
        let d = (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f32::max);
        if dev.coverage[i] != cpu.coverage[i] || d > of_brightest * brightest {
            apart += 1;
        } else {
            worst = worst.max(d / brightest);
        }
    }
    (apart, worst)
}

/// A GPU for the tests: `None` (after printing why) when no adapter exists, unless
/// `PRT_REQUIRE_GPU=1`, when the test fails instead.
pub fn gpu_or_skip(test: &str) -> Option<wavelet_prt::relight::gpu::Gpu> {
    match wavelet_prt::relight::gpu::Gpu::new() {
        Ok(g) => {
            eprintln!("{test}: on {}", g.adapter);
            Some(g)
        }
        Err(e) if std::env::var("PRT_REQUIRE_GPU").as_deref() != Ok("1") => {
            eprintln!("{test}: skipped, no GPU: {e}");
            None
        }
        Err(e) => panic!("{test}: PRT_REQUIRE_GPU=1 but {e}"),
    }
}

/// A foggy blob on its own (an ellipsoid medium of asymmetry `g`, no shapes), seen at
/// `width` × `height`.
pub fn fog_scene(g: f32, width: u32, height: u32) -> String {
    format!(
        r#"
[camera]
eye = [0.0, 0.6, 3.0]
target = [0.0, 0.6, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
width = {width}
height = {height}

[medium]
type = "ellipsoid"
bounds = [[-0.8, 0.0, -0.8], [0.8, 1.2, 0.8]]
resolution = 24
extinction = 4.0
albedo = [0.9, 0.8, 0.7]
g = {g}
center = [0.0, 0.6, 0.0]
radii = [0.7, 0.5, 0.6]
falloff = 0.3
"#
    )
}

/// A random transport with several rows per pixel, empty pixels and an image size that tiles do
/// not divide; values are uniform in ±`scale`.
pub fn random_transport(
    w: usize,
    h: usize,
    n: usize,
    quantization: Quantization,
    seed: u64,
    scale: f32,
) -> Transport {
    assemble_random(w, h, random_rows(w, h, n, quantization, seed, scale))
}

/// A transport of these random rows: grey albedo, every pixel covered, zero tile statistics.
fn assemble_random(
    w: usize,
    h: usize,
    (meta, tiles): (TransportMeta, Vec<Vec<RowData>>),
) -> Transport {
    let (tx, ty) = tile_grid(w, h);
    Transport::assemble(
        meta,
        tiles,
        vec![[0.5; 3]; w * h],
        vec![1.0; w * h],
        vec![[0.0; 3]; tx * ty],
    )
    .unwrap()
}

/// [`random_transport`] with each coefficient of a row an entry with probability `density`
/// rather than 0.1: near 1, most of a full block's slots hold all of its strips.
pub fn random_transport_of_density(
    w: usize,
    h: usize,
    n: usize,
    quantization: Quantization,
    seed: u64,
    density: f32,
) -> Transport {
    let rows = random_rows_of_density(w, h, n, quantization, seed, 1e-3, density);
    assemble_random(w, h, rows)
}

/// The header and the rows, tile by tile, that [`random_transport`] assembles.
pub fn random_rows(
    w: usize,
    h: usize,
    n: usize,
    quantization: Quantization,
    seed: u64,
    scale: f32,
) -> (TransportMeta, Vec<Vec<RowData>>) {
    random_rows_of_density(w, h, n, quantization, seed, scale, 0.1)
}

fn random_rows_of_density(
    w: usize,
    h: usize,
    n: usize,
    quantization: Quantization,
    seed: u64,
    scale: f32,
    density: f32,
) -> (TransportMeta, Vec<Vec<RowData>>) {
    let mut rng = SampleRng::new(seed, 0);
    let c = texel_count(n);
    let (tx, ty) = tile_grid(w, h);
    let mut tiles = Vec::new();
    for t in 0..tx * ty {
        let mut rows = Vec::new();
        for y in (t / tx) * TILE..((t / tx + 1) * TILE).min(h) {
            for x in (t % tx) * TILE..((t % tx + 1) * TILE).min(w) {
                // 0 to 3 rows: tiles of up to 768 rows, so up to three blocks of 256.
                let count = (rng.next_u64() % 4) as usize;
                for _ in 0..count {
                    let mut entries = Vec::new();
                    for j in 0..c {
                        if rng.next_f32() < density {
                            entries.push((j as u32, (rng.next_f32() * 2.0 - 1.0) * scale));
                        }
                    }
                    rows.push(RowData {
                        pixel: (y * w + x) as u32,
                        weight: [rng.next_f32(), rng.next_f32(), rng.next_f32()],
                        entries,
                        sh: vec![rng.next_f32(); 4],
                    });
                }
            }
        }
        tiles.push(rows);
    }
    let meta = TransportMeta {
        width: w as u32,
        height: h as u32,
        tile: TILE as u32,
        scene_path: "random".into(),
        camera: CameraMeta {
            eye: [0.0; 3],
            target: [0.0, 0.0, -1.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 40.0,
        },
        identity: BakeIdentity {
            scene_hash: "0".into(),
            cube_n: n as u32,
            sh_order: 2,
            spp: 1,
            edge_spp: 0,
            texel_samples: 1,
            edge_texel_samples: 0,
            edge_texels_towards: false,
            unshadowed: false,
            seed,
            threshold: 0.0,
            budget: Default::default(),
            quantization,
            shard: None,
            bounces: 0,
            paths: 0,
            indirect: None,
            domain: BakeDomain::View,
            light_samples: 0,
            refine_shadows: false,
            visibility: false,
        },
        cache_points: 0,
        per_vertex: None,
        stats: BakeStats::default(),
        lights: Vec::new(),
    };
    (meta, tiles)
}

/// Relights `t` on the CPU under `env` turned by `rotation`: the light context, the prepared
/// light and the request, for a test that relights a transport once.
pub fn relit(
    t: &Transport,
    env: &wavelet_prt::env::envmap::EnvMap,
    rotation: wavelet_prt::env::envmap::EnvRotation,
    req: wavelet_prt::relight::RelightRequest,
) -> wavelet_prt::output::film::Image {
    let ctx = wavelet_prt::relight::LightContext::new(t).unwrap();
    let light = ctx.prepare(env, rotation).unwrap();
    wavelet_prt::relight::relight(t, &ctx, &light, &req)
        .unwrap()
        .0
}

/// A safetensors file (a transport or volume file) taken apart for editing: the `meta` JSON and
/// the tensors in name order. [`StFile::write`] can reseal it, recomputing the tensors' checksum
/// and `meta_checksum` as a careful editor would, so a test reaches the checks behind them.
#[derive(Clone, Debug)]
pub struct StFile {
    pub meta: serde_json::Value,
    /// The `meta` text as read.
    pub meta_text: String,
    /// (name, dtype as written, shape, bytes), sorted by name.
    pub tensors: Vec<(String, String, Vec<usize>, Vec<u8>)>,
}

impl StFile {
    pub fn read(path: &Path) -> StFile {
        let bytes = std::fs::read(path).unwrap();
        let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
        let (_, md) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
        let text = md.metadata().as_ref().unwrap()["meta"].clone();
        let meta = serde_json::from_str(&text).unwrap();
        let meta_text = text.clone();
        let mut tensors: Vec<_> = st
            .tensors()
            .into_iter()
            .map(|(name, t)| {
                let dtype = serde_json::to_value(t.dtype()).unwrap();
                (
                    name,
                    dtype.as_str().unwrap().to_string(),
                    t.shape().to_vec(),
                    t.data().to_vec(),
                )
            })
            .collect();
        tensors.sort_by(|a, b| a.0.cmp(&b.0));
        StFile {
            meta,
            meta_text,
            tensors,
        }
    }

    /// The bytes of a file: with `reseal`, new checksums for the tensors and the metadata;
    /// without, the stored ones (`meta` written anew, so `meta_checksum` no longer matches).
    pub fn to_bytes(&self, reseal: bool) -> Vec<u8> {
        let mut meta = self.meta.clone();
        if let Some(m) = meta.as_object_mut()
            && reseal
        {
            m.remove("meta_checksum");
        }
        if reseal {
            let sum =
                wavelet_prt::store::container::checksum(self.tensors.iter().map(|t| &t.3[..]));
            meta["checksum"] = format!("{sum:016x}").into();
        }
        let mut text = serde_json::to_string(&meta).unwrap();
        if reseal && text.ends_with('}') {
            let sum = wavelet_prt::store::container::checksum([text.as_bytes()]);
            text.pop();
            text.push_str(&format!(",\"meta_checksum\":\"{sum:016x}\"}}"));
        }
        self.assemble(&text)
    }

    /// The file with the `meta` text given as is.
    pub fn assemble(&self, meta_text: &str) -> Vec<u8> {
        let mut header = serde_json::Map::new();
        header.insert(
            "__metadata__".into(),
            serde_json::json!({ "meta": meta_text }),
        );
        let mut offset = 0;
        for (name, dtype, shape, bytes) in &self.tensors {
            header.insert(
                name.clone(),
                serde_json::json!({
                    "dtype": dtype,
                    "shape": shape,
                    "data_offsets": [offset, offset + bytes.len()],
                }),
            );
            offset += bytes.len();
        }
        let mut h = serde_json::to_string(&header).unwrap().into_bytes();
        h.resize(h.len().next_multiple_of(8), b' ');
        let mut out = (h.len() as u64).to_le_bytes().to_vec();
        out.extend_from_slice(&h);
        for t in &self.tensors {
            out.extend_from_slice(&t.3);
        }
        out
    }

    pub fn write(&self, path: &Path, reseal: bool) {
        std::fs::write(path, self.to_bytes(reseal)).unwrap();
    }

    /// The bytes of tensor `name`.
    pub fn tensor_mut(&mut self, name: &str) -> &mut Vec<u8> {
        &mut self
            .tensors
            .iter_mut()
            .find(|t| t.0 == name)
            .unwrap_or_else(|| panic!("no tensor {name}"))
            .3
    }
}

/// A path as the `&str` a command line takes.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Asserts a command failed cleanly (exit code 1, not a panic or an abort) with every needle in
/// its message.
pub fn assert_clean_error(code: i32, text: &str, needles: &[&str]) {
    assert_eq!(code, 1, "exit code {code}: {text}");
    assert!(!text.contains("panicked"), "{text}");
    for n in needles {
        assert!(text.contains(n), "`{n}` not in: {text}");
    }
}

/// Volume transfer at low resolution, `directions` directions and SH order 2, with two
/// scattering orders: enough to write and read every field of a volume file.
pub fn small_transfer(directions: usize) -> wavelet_prt::volume::TransferSettings {
    wavelet_prt::volume::TransferSettings {
        sh_order: 2,
        directions,
        scatter: wavelet_prt::volume::ScatterSettings {
            orders: 2,
            angular: 2,
            light: 2,
            directions: 16,
        },
    }
}

/// Runs the `prt` binary with `args`; returns (exit code, stdout + stderr).
pub fn prt(args: &[&str]) -> (i32, String) {
    run(std::process::Command::new(env!("CARGO_BIN_EXE_prt")).args(args))
}

/// Runs `command` to its end; returns (exit code, or -1 when a signal ended it; stdout +
/// stderr).
pub fn run(command: &mut std::process::Command) -> (i32, String) {
    let out = command.output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.code().unwrap_or(-1), text)
}

/// The names of the entries of `dir`, sorted.
pub fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}
