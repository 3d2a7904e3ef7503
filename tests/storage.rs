//! The stored transport values: quantisation round trips within the documented bound on a real
//! bake, no stored value is subnormal, files of the previous format are refused with a message
//! that says to bake again, and the GPU kernel decodes every format as the CPU does, including
//! values the 16-bit-float format stored as subnormals.

mod common;

use common::{GPU_MATCH, SAME_SUM, StFile, random_transport, scene_from, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::light::select::SparseLight;
use wavelet_prt::math::sampling::Rng;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::{relight_dense_reference, relight_wavelet};
use wavelet_prt::store::quant::Quantization;
use wavelet_prt::store::transport::Transport;

/// A quantised value's distance from the lossless one, in steps (the column's scale times the
/// row's): rounding to the nearest integer multiple of the step errs by at most half of it,
/// `quant`'s documented bound...
const HALF_STEP: f32 = 0.5;
/// ...plus this much of the value, for the f32 rounding of the decode (the integer times two
/// scales) and of the encode's division: a few ulps.
const DECODE_ROUNDING: f32 = 1e-6;

/// A glossy sphere beside a diffuse one on the ground, with two materials seen by some pixels'
/// sub-samples: tiles with more than 256 rows (several blocks) and rows of very different size.
const GLOSSY: &str = r#"
[camera]
eye = [0.0, 1.5, 4.0]
target = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
width = 40
height = 36

[material.ground]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[material.shiny]
type = "glossy"
albedo = [0.1, 0.15, 0.3]
specular = [0.85, 0.8, 0.65]
roughness = 0.15

[[shape]]
type = "quad"
corners = [[-3.0, 0.0, -3.0], [-3.0, 0.0, 3.0], [3.0, 0.0, 3.0], [3.0, 0.0, -3.0]]
material = "ground"

[[shape]]
type = "sphere"
center = [-0.5, 0.6, 0.0]
radius = 0.6
material = "shiny"

[[shape]]
type = "sphere"
center = [0.8, 0.4, 0.5]
radius = 0.4
material = "ground"
"#;

fn settings(quantization: Quantization, lossless: bool, threshold: f32) -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        spp: 4,
        threshold,
        quantization,
        lossless,
        ..BakeSettings::default()
    }
}

/// Every value of a bake, decoded, by (row, coefficient).
fn decoded(t: &Transport) -> std::collections::HashMap<(usize, usize), f32> {
    let mut out = std::collections::HashMap::new();
    for b in 0..t.block_count() {
        for j in 0..t.coeff_count() {
            for e in t.block_column(b, j) {
                let row = t.block_row_start[b] as usize + t.entry_row[e] as usize;
                out.insert((row, j), t.value(b, j, e));
            }
        }
    }
    out
}

/// With no thresholding, every quantised value is within half a step of the lossless one: the
/// step is the column's scale times the row's scale (`quant`'s documented bound), and values
/// that round to zero are dropped only when they are below half a step.
#[test]
fn quantised_values_round_trip_within_half_a_step() {
    let scene = scene_from(GLOSSY, "storage-round-trip");
    let exact = bake(&scene, &settings(Quantization::Q8, true, 0.0), &|_| {}).unwrap();
    assert!(
        exact.block_count() > exact.tile_count(),
        "the scene should give tiles of several blocks"
    );
    let want = decoded(&exact);
    for q in [Quantization::Q8, Quantization::Q16] {
        let t = bake(&scene, &settings(q, false, 0.0), &|_| {}).unwrap();
        assert_eq!(t.row_pixel, exact.row_pixel, "rows in the same order");
        let got = decoded(&t);
        let mut checked = 0;
        for b in 0..t.block_count() {
            let r0 = t.block_row_start[b] as usize;
            for r in r0..t.block_row_start[b + 1] as usize {
                for j in 0..t.coeff_count() {
                    let step = t.scale(b, j) * t.row_scale[r];
                    let v = want.get(&(r, j)).copied().unwrap_or(0.0);
                    let g = got.get(&(r, j)).copied().unwrap_or(0.0);
                    // Half a step, and the f32 rounding of the decode.
                    let bound = HALF_STEP * step + DECODE_ROUNDING * v.abs();
                    assert!(
                        (g - v).abs() <= bound,
                        "{q} row {r} coefficient {j}: {g} for {v}, half step {}",
                        HALF_STEP * step
                    );
                    checked += (v != 0.0) as usize;
                }
            }
        }
        assert!(checked > 10_000, "only {checked} values checked");
    }
}

/// No stored value is a subnormal float: integers against normal scales, and normal row scales.
#[test]
fn no_stored_value_is_subnormal() {
    let scene = scene_from(GLOSSY, "storage-subnormal");
    for q in [Quantization::Q8, Quantization::Q16] {
        // At N = 32, as the demo bakes, most values are below f16's normal range.
        let s = BakeSettings {
            cube_n: 32,
            spp: 1,
            ..settings(q, false, 0.01)
        };
        let t = bake(&scene, &s, &|_| {}).unwrap();
        assert!(t.row_scale.iter().all(|s| s.is_normal()));
        let scales_used: std::collections::HashSet<u8> = t.col_scale.iter().copied().collect();
        assert!(
            scales_used
                .iter()
                .all(|&c| wavelet_prt::store::quant::scale_of(c).is_normal())
        );
        let mut smallest = f32::MAX;
        for (_, v) in decoded(&t) {
            assert!(v != 0.0, "a stored zero");
            assert!(v.is_normal(), "{q}: decoded value {v} is subnormal");
            smallest = smallest.min(v.abs());
        }
        // The bake holds values an f16 could only store as subnormals (below 6.1e-5).
        assert!(smallest < 6.1e-5, "{q}: smallest value {smallest}");
    }
}

/// A file written in format version 2 (16-bit floats) is refused with a message that says to
/// bake again.
#[test]
fn old_format_files_are_refused_with_a_clear_message() {
    let dir = temp_dir("storage-old");
    let t = random_transport(20, 18, 2, Quantization::Q8, 3, 1.0);
    let p = dir.join("t.prt");
    t.save(&p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let key = format!(
        "format_version\\\":{}",
        wavelet_prt::store::transport::FORMAT_VERSION
    );
    let key = key.as_bytes();
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("the header names its version");
    let mut old = bytes.clone();
    old[at + key.len() - 1] = b'2';
    let q = dir.join("old.prt");
    std::fs::write(&q, &old).unwrap();
    let e = Transport::load(&q).unwrap_err().to_string();
    assert!(
        e.contains("old.prt") && e.contains("version 2") && e.contains("bake the scene again"),
        "{e}"
    );
}

/// Version 3 and 4 files, written before the local lights and the albedo maps, still load: they
/// differ only in having neither.
#[test]
fn version_3_and_4_files_load_as_ones_without_lights_or_maps() {
    let dir = temp_dir("storage-v3");
    let t = random_transport(20, 18, 2, Quantization::Q8, 3, 1.0);
    let p = dir.join("t.prt");
    t.save(&p).unwrap();
    for version in [3, 4] {
        let mut file = StFile::read(&p);
        file.meta["format_version"] = version.into();
        let q = dir.join(format!("v{version}.prt"));
        std::fs::write(&q, file.to_bytes(true)).unwrap();
        let back = Transport::load(&q).unwrap();
        assert_eq!(back, t);
        assert!(back.meta.lights.is_empty());
    }
}

/// The tiled kernel equals its dense twin on every format, for rows spanning several blocks.
#[test]
fn kernel_equals_dense_twin_for_every_format() {
    for q in [Quantization::Q8, Quantization::Q16, Quantization::F32] {
        let t = random_transport(37, 29, 4, q, 11, 1e-5);
        assert!(t.block_count() > t.tile_count());
        let c = t.coeff_count();
        let mut rng = Rng::new(5, 0);
        let light = SparseLight {
            indices: (0..c as u32).collect(),
            values: (0..c)
                .map(|_| [rng.next_f32(), rng.next_f32(), 1.0])
                .collect(),
        };
        let (fast, _) = relight_wavelet(&t, &light).unwrap();
        let dense = relight_dense_reference(&t, &light);
        let e = relative_l2(&fast, &dense, None).unwrap();
        assert!(e < SAME_SUM, "{q}: tiled vs dense {e}");
    }
}

/// The strips hold every stored entry once, at its row and with its value, and nothing else;
/// they lie in light-major order (band, coefficient, block), and a tile row of more than 16
/// blocks is cut into bands of 16.
#[test]
fn strips_hold_every_entry_once_in_light_major_bands() {
    use wavelet_prt::store::transport::strips::{BAND_BLOCKS, STRIP_ROWS};
    for q in [Quantization::Q8, Quantization::Q16, Quantization::F32] {
        let t = random_transport(230, 20, 2, q, 17, 1.0);
        let s = t.strips().unwrap();
        let c = t.coeff_count();
        assert!(
            (0..s.group_count()).any(|g| s.group_bands(g).len() > 1),
            "{q}: no group has two bands"
        );
        // Groups are whole tile rows, at least a band's worth of blocks but the last.
        for g in 0..s.group_count() {
            let rows = s.group_rows(g);
            let blocks = t.tile_block_start[rows.end * 15] - t.tile_block_start[rows.start * 15];
            assert!(blocks as usize >= BAND_BLOCKS || g + 1 == s.group_count());
        }
        let narrow = random_transport(16, 200, 2, q, 18, 1.0);
        let n = narrow.strips().unwrap();
        assert!(
            n.group_count() > 1 && n.group_rows(0).len() > 1,
            "{q}: narrow groups"
        );
        let mut next = 0usize;
        for band in 0..s.band_count() {
            let blocks = s.band_blocks(band);
            assert!(!blocks.is_empty() && blocks.len() <= BAND_BLOCKS);
            for j in 0..c {
                for (slot, b) in s.term_slots(band, j, c).iter().zip(blocks.clone()) {
                    assert_eq!(slot.first as usize, next, "{q}: strips out of order");
                    assert_eq!(slot.code, t.col_scale[b * c + j]);
                    assert_eq!(slot.entries as usize, t.block_column(b, j).len());
                    let mut dense = [0.0f32; 256];
                    for e in t.block_column(b, j) {
                        dense[t.entry_row[e] as usize] = t.values.raw(e);
                    }
                    let mut from_strips = [0.0f32; 256];
                    let mut last = None;
                    for k in next..next + slot.count as usize {
                        let place = s.index[k] as usize;
                        assert!(last < Some(place), "{q}: strip places not increasing");
                        last = Some(place);
                        let vals: Vec<f32> = (0..STRIP_ROWS)
                            .map(|i| s.values.raw(k * STRIP_ROWS + i))
                            .collect();
                        assert!(vals.iter().any(|v| *v != 0.0), "{q}: an empty strip");
                        from_strips[place * STRIP_ROWS..(place + 1) * STRIP_ROWS]
                            .copy_from_slice(&vals);
                    }
                    assert_eq!(from_strips, dense, "{q}: block {b}, coefficient {j}");
                    next += slot.count as usize;
                }
            }
        }
        assert_eq!(next, s.strip_count());
        let all: Vec<u32> = (0..c as u32).collect();
        assert_eq!(
            s.read_by(&all, c),
            (s.strip_count() as u64, t.entry_row.len() as u64)
        );
        assert_eq!(s.values.len(), next * STRIP_ROWS);
    }
}

/// The SIMD strip loop and the portable one give the same image (to float rounding: one fuses
/// its multiply-adds) as the dense twin, on every format, bands of 16 blocks and fewer, and
/// terms in any order.
#[test]
fn simd_and_portable_strip_loops_agree_with_the_dense_twin() {
    use wavelet_prt::relight::strip_kernel::{StripPath, relight_strips};
    for (q, w, h) in [
        (Quantization::Q8, 230, 20),
        (Quantization::Q16, 230, 20),
        (Quantization::F32, 230, 20),
        // One tile wide, as a per-vertex bake is: its groups gather several tile rows.
        (Quantization::Q8, 16, 200),
    ] {
        let t = random_transport(w, h, 2, q, 19, 1e-3);
        let c = t.coeff_count();
        let mut rng = Rng::new(8, 0);
        for k in [1, 5, c] {
            let light = common::random_light(&mut rng, c, k, false, |rng| {
                [rng.next_f32(), rng.next_f32() - 0.5, 1.0]
            });
            let dense = relight_dense_reference(&t, &light);
            let s = t.strips().unwrap();
            let (best, best_read) = relight_strips(&t, s, &light, StripPath::Best);
            let (portable, read) = relight_strips(&t, s, &light, StripPath::Portable);
            assert_eq!(best_read, read);
            let (strips, entries) = s.read_by(&light.indices, c);
            assert_eq!(
                read,
                [strips, entries],
                "{q} K = {k}: what the kernel says it read"
            );
            for (name, img) in [("best", &best), ("portable", &portable)] {
                let e = relative_l2(img, &dense, None).unwrap();
                assert!(e < SAME_SUM, "{q} K = {k}: {name} vs dense {e}");
            }
        }
    }
}

/// GPU and CPU agree (1e-4) on every format, on values from 1e-7 to 1e-5: in the old format
/// these were f16 subnormals, which a GPU may flush to zero when unpacking.
#[test]
fn gpu_decodes_every_format_like_the_cpu() {
    let Some(gpu) = common::gpu_or_skip("gpu_decodes_every_format_like_the_cpu") else {
        return;
    };
    for q in [Quantization::Q8, Quantization::Q16, Quantization::F32] {
        let t = random_transport(37, 29, 4, q, 13, 1e-5);
        let c = t.coeff_count();
        let g = wavelet_prt::relight::gpu::GpuTransport::upload(&gpu, &t, None).unwrap();
        let mut rng = Rng::new(6, 0);
        for k in [3, 40, c] {
            let light = common::random_light(&mut rng, c, k, false, |rng| {
                [rng.next_f32(), 2.0 * rng.next_f32(), 1.0]
            });
            let (cpu, _) = relight_wavelet(&t, &light).unwrap();
            let (dev, _) = g.relight_wavelet(&gpu, &light).unwrap();
            let norm: f64 = cpu.pixels.iter().flatten().map(|v| (*v as f64).abs()).sum();
            assert!(norm > 0.0, "{q} K = {k}: the CPU image is black");
            let e = relative_l2(&dev, &cpu, None).unwrap();
            assert!(e < GPU_MATCH, "{q} K = {k}: GPU vs CPU {e}");
        }
    }
}

/// `prt info` prints from the header and the small tables: a file whose entries and values were
/// overwritten (same size) is still described, while loading it fails its checksum; a column
/// count that disagrees with the entries is an error, found without reading them.
#[test]
fn info_reads_the_header_and_the_small_tables_only() {
    let dir = temp_dir("storage-info");
    let t = random_transport(20, 18, 2, Quantization::Q8, 5, 1.0);
    let p = dir.join("t.prt");
    t.save(&p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let header_len = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[8..8 + header_len]).unwrap();
    let range = |name: &str| {
        let o = &header[name]["data_offsets"];
        let (a, b) = (
            o[0].as_u64().unwrap() as usize,
            o[1].as_u64().unwrap() as usize,
        );
        8 + header_len + a..8 + header_len + b
    };
    let info = |bytes: &[u8]| {
        std::fs::write(&p, bytes).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_prt"))
            .arg("info")
            .arg(&p)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned()
            + &String::from_utf8_lossy(&out.stderr);
        (out.status.code(), text)
    };
    let mut garbled = bytes.clone();
    for name in ["entry_row", "entry_value"] {
        for b in &mut garbled[range(name)] {
            *b ^= 0x5a;
        }
    }
    let (code, text) = info(&garbled);
    let e = Transport::load(&p).unwrap_err().to_string();
    assert!(e.contains("checksum mismatch"), "{e}");
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("image         20 x 18"), "{text}");
    assert!(
        text.contains(&format!("nonzeros      {}", t.meta.stats.nonzeros)),
        "{text}"
    );
    // One more entry counted in the first column than stored.
    let mut counted = bytes.clone();
    let at = range("col_count").start;
    let n = u16::from_le_bytes([counted[at], counted[at + 1]]) + 1;
    counted[at..at + 2].copy_from_slice(&n.to_le_bytes());
    let (code, text) = info(&counted);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("column counts add up"), "{text}");
}

#[test]
fn a_load_reports_progress_up_to_the_file_size_and_reads_what_was_saved() {
    // The load reads each tensor straight into its table, taking the checksum as it goes; the
    // progress it reports never goes back and ends at the file's size.
    let t = random_transport(40, 35, 8, Quantization::Q8, 41, 0.3);
    let dir = temp_dir("storage-progress");
    let path = dir.join("t.prt");
    t.save(&path).unwrap();
    let size = std::fs::metadata(&path).unwrap().len();
    let seen = std::sync::Mutex::new(Vec::new());
    let back = Transport::load_with_progress(&path, &|done, total| {
        seen.lock().unwrap().push((done, total))
    })
    .unwrap();
    assert_eq!(back, t);
    let seen = seen.into_inner().unwrap();
    assert!(seen.iter().all(|&(_, total)| total == size));
    assert!(seen.windows(2).all(|w| w[1].0 >= w[0].0));
    assert_eq!(seen.last().unwrap().0, size);
}
