//! The stored transport values: quantisation round trips within the documented bound on a real
//! bake, no stored value is subnormal, files of the previous format are refused with a message
//! that says to bake again, and the GPU kernel decodes every format as the CPU does, including
//! values the 16-bit-float format stored as subnormals.

mod common;

use common::{GPU_MATCH, SAME_SUM, StFile, random_transport, scene_from, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::select::SparseLight;
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
            for (row, v) in t.column(b, j) {
                out.insert((row, j), v);
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
        let scales_used: std::collections::HashSet<u8> =
            t.strips.slots.iter().map(|s| s.code).collect();
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
    // The version's digits become version 2, padded with spaces before it (JSON whitespace) so
    // that the header keeps its length.
    let mut old = bytes.clone();
    let digits = wavelet_prt::store::transport::FORMAT_VERSION
        .to_string()
        .len();
    let start = at + key.len() - digits;
    old[start..at + key.len()].fill(b' ');
    old[at + key.len() - 1] = b'2';
    let q = dir.join("old.prt");
    std::fs::write(&q, &old).unwrap();
    let e = Transport::load(&q).unwrap_err().to_string();
    assert!(
        e.contains("old.prt") && e.contains("version 2") && e.contains("bake the scene again"),
        "{e}"
    );
}

/// A format 6 file's matrix, decoded here from its columns as that format lays them out (per
/// (block, coefficient) a count and a scale code, then each entry's row and value), by (row,
/// coefficient).
fn columns_of_format_6(f: &StFile) -> std::collections::HashMap<(usize, usize), f32> {
    let tensor = |name: &str| &f.tensors.iter().find(|t| t.0 == name).unwrap().3;
    let counts: Vec<u16> = bytemuck::pod_collect_to_vec(tensor("col_count"));
    let codes = tensor("col_scale");
    let rows = tensor("entry_row");
    let row_scale: Vec<f32> = bytemuck::pod_collect_to_vec(tensor("row_scale"));
    let starts: Vec<u32> = bytemuck::pod_collect_to_vec(tensor("tile_row_start"));
    let bytes = tensor("entry_value");
    let value = |e: usize| match f.meta["quantization"].as_str().unwrap() {
        "q8" => bytes[e] as i8 as f32,
        "q16" => i16::from_le_bytes([bytes[2 * e], bytes[2 * e + 1]]) as f32,
        _ => f32::from_le_bytes(bytes[4 * e..4 * e + 4].try_into().unwrap()),
    };
    // Blocks of 256 rows inside each tile.
    let mut block_start = Vec::new();
    for w in starts.windows(2) {
        block_start.extend((w[0]..w[1]).step_by(256).map(|r| r as usize));
    }
    let c = codes.len() / block_start.len();
    let mut out = std::collections::HashMap::new();
    let mut e = 0;
    for (k, &n) in counts.iter().enumerate() {
        let scale = wavelet_prt::store::quant::scale_of(codes[k]);
        for _ in 0..n {
            let row = block_start[k / c] + rows[e] as usize;
            out.insert((row, k % c), value(e) * scale * row_scale[row]);
            e += 1;
        }
    }
    out
}

/// Files of format 6, which stored columns where version 7 stores strips, load with every value
/// where those columns put it (a view in q8 and lossless, a per-vertex bake in q16, all written
/// by the build that wrote version 6); they save in this version and load back the same. Versions
/// 3 to 5 differ from 6 only in having no lights or albedo maps, so the same
/// files labelled 3 to 5 load the same.
#[test]
fn format_6_files_load_into_strips_with_every_value_in_place() {
    let dir = temp_dir("storage-format-6");
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/format6");
    for name in ["v6_q8.prt", "v6_lossless.prt", "v6_vertex.prt"] {
        let path = data.join(name);
        let file = StFile::read(&path);
        assert_eq!(file.meta["format_version"], 6);
        let t = Transport::load(&path).unwrap();
        let want = columns_of_format_6(&file);
        assert!(want.len() > 1000, "{name}: {} values", want.len());
        assert_eq!(decoded(&t), want, "{name}");
        assert_eq!(t.nonzeros(), want.len() as u64);
        // Saved in this version, loaded back: the same transport.
        let p = dir.join(name);
        t.save(&p).unwrap();
        let version = wavelet_prt::store::transport::FORMAT_VERSION;
        assert_eq!(StFile::read(&p).meta["format_version"], version);
        assert_eq!(Transport::load(&p).unwrap(), t, "{name}");
        for version in [3, 4, 5] {
            let mut old = file.clone();
            old.meta["format_version"] = version.into();
            let q = dir.join(format!("v{version}-{name}"));
            std::fs::write(&q, old.to_bytes(true)).unwrap();
            assert_eq!(
                Transport::load(&q).unwrap(),
                t,
                "{name} as version {version}"
            );
        }
        // A stored zero, which format 6 could hold, is no entry: the file loads without it.
        if name == "v6_q8.prt" {
            let mut zeroed = file.clone();
            zeroed.tensor_mut("entry_value")[0] = 0;
            let q = dir.join("zeroed.prt");
            zeroed.write(&q, true);
            let back = Transport::load(&q).unwrap();
            assert_eq!(back.nonzeros(), want.len() as u64 - 1);
            assert_eq!(decoded(&back).len(), want.len() - 1);
        }
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

/// The strips hold every entry of the tiles' columns (as [`EncodedTile::encode`] lays them
/// out) once, at its row and with its value, and nothing else; they lie in light-major order
/// (band, coefficient, block), and a tile row of more than 16 blocks is cut into bands of 16.
/// A slot holds the strips that hold entries, or, when those are at least half its block's,
/// every strip of its block (empty ones as zeros), and only then.
#[test]
fn strips_hold_every_entry_once_in_light_major_bands() {
    use wavelet_prt::store::transport::EncodedTile;
    use wavelet_prt::store::transport::strips::{BAND_BLOCKS, STRIP_ROWS};
    let (mut whole_slots, mut padded_slots) = (0, 0);
    for q in [Quantization::Q8, Quantization::Q16, Quantization::F32] {
        let (meta, tiles) = common::random_rows(230, 20, 2, q, 17, 1.0);
        let t = random_transport(230, 20, 2, q, 17, 1.0);
        let s = &t.strips;
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
        let n = &narrow.strips;
        assert!(
            n.group_count() > 1 && n.group_rows(0).len() > 1,
            "{q}: narrow groups"
        );
        // Each block's columns as the encoder lays them out: (count, code, dense raw values).
        let mut columns = Vec::new();
        for rows in &tiles {
            let e =
                EncodedTile::encode(rows, c, meta.identity.sh_order.pow(2) as usize, q).unwrap();
            let mut at = 0;
            for (&count, &code) in e.col_count.iter().zip(&e.col_scale) {
                let mut dense = [0.0f32; 256];
                for k in at..at + count as usize {
                    dense[e.entry_row[k] as usize] = e.values.raw(k);
                }
                at += count as usize;
                columns.push((count, code, dense));
            }
        }
        assert_eq!(columns.len(), t.block_count() * c);
        let mut next = 0usize;
        let mut entries = 0u64;
        for band in 0..s.band_count() {
            let blocks = s.band_blocks(band);
            assert!(!blocks.is_empty() && blocks.len() <= BAND_BLOCKS);
            for j in 0..c {
                for (slot, b) in s.term_slots(band, j, c).iter().zip(blocks.clone()) {
                    let (count, code, dense) = &columns[b * c + j];
                    assert_eq!(slot.first as usize, next, "{q}: strips out of order");
                    assert_eq!(slot.code, *code);
                    assert_eq!(slot.entries, *count);
                    let mut from_strips = [0.0f32; 256];
                    let mut last = None;
                    let mut empty = 0;
                    for k in next..next + slot.count as usize {
                        let place = s.index[k] as usize;
                        assert!(last < Some(place), "{q}: strip places not increasing");
                        last = Some(place);
                        let vals: Vec<f32> = (0..STRIP_ROWS)
                            .map(|i| s.values.raw(k * STRIP_ROWS + i))
                            .collect();
                        empty += vals.iter().all(|v| *v == 0.0) as usize;
                        from_strips[place * STRIP_ROWS..(place + 1) * STRIP_ROWS]
                            .copy_from_slice(&vals);
                    }
                    assert_eq!(&from_strips, dense, "{q}: block {b}, coefficient {j}");
                    // The strips that hold entries, or every strip of the block when those
                    // are at least half of them.
                    let rows = (t.block_row_start[b + 1] - t.block_row_start[b]) as usize;
                    let block_strips = rows.div_ceil(STRIP_ROWS);
                    let held = dense
                        .chunks(STRIP_ROWS)
                        .filter(|s| s.iter().any(|v| *v != 0.0))
                        .count();
                    let whole = held > 0 && 2 * held >= block_strips;
                    let want = if whole { block_strips } else { held };
                    assert_eq!(slot.count as usize, want, "{q}: block {b}, coefficient {j}");
                    assert_eq!(empty, want - held, "{q}: empty strips");
                    whole_slots += whole as usize;
                    padded_slots += (empty > 0) as usize;
                    next += slot.count as usize;
                    entries += *count as u64;
                }
            }
        }
        assert_eq!(next, s.strip_count());
        let all: Vec<u32> = (0..c as u32).collect();
        assert_eq!(s.read_by(&all, c), (s.strip_count() as u64, entries));
        assert_eq!(t.nonzeros(), entries);
        assert_eq!(s.values.len(), next * STRIP_ROWS);
    }
    assert!(
        whole_slots > padded_slots && padded_slots > 0,
        "slots whole as made, and made whole"
    );
}

/// The SIMD strip loop and the portable one give the same image (to float rounding: one fuses
/// its multiply-adds) as the dense twin, on every format, bands of 16 blocks and fewer, and
/// terms in any order. Every transport holds slots of all their block's strips (made whole when
/// at least half full), which the SIMD loop adds panel by panel in chunks of 64 terms, blocks
/// of fewer than 32 strips among them, beside slots of some, which it adds strip by strip.
#[test]
fn simd_and_portable_strip_loops_agree_with_the_dense_twin() {
    use wavelet_prt::relight::strip_kernel::{Read, StripPath, has_avx2_fma, relight_strips};
    use wavelet_prt::store::transport::strips::{STRIP_ROWS, STRIPS_PER_BLOCK, Slot};
    if !has_avx2_fma() {
        eprintln!("no AVX2 and FMA: the SIMD loop is not run, only the portable one");
    }
    // The strips of the last panel of each whole slot, 0 for a panel of 4.
    let mut tails = std::collections::BTreeSet::new();
    for (q, w, h, n, density) in [
        (Quantization::Q8, 230, 20, 2, 0.1),
        (Quantization::Q16, 230, 20, 2, 0.1),
        (Quantization::F32, 230, 20, 2, 0.1),
        // One tile wide, as a per-vertex bake is: its groups gather several tile rows.
        (Quantization::Q8, 16, 200, 2, 0.1),
        (Quantization::Q8, 230, 40, 4, 0.9),
        (Quantization::Q16, 100, 40, 4, 0.9),
        (Quantization::F32, 100, 40, 4, 0.9),
        (Quantization::Q8, 16, 200, 4, 0.9),
        // Small tiles, whose blocks of few rows end their whole slots in panels of 1 to 3.
        (Quantization::Q16, 19, 18, 4, 0.9),
    ] {
        let t = if density < 0.5 {
            random_transport(w, h, n, q, 19, 1e-3)
        } else {
            common::random_transport_of_density(w, h, n, q, 19, density)
        };
        let c = t.coeff_count();
        let s = &t.strips;
        // Each block's strips, and whether a slot holds all of them.
        let block_strips = |b: usize| {
            ((t.block_row_start[b + 1] - t.block_row_start[b]) as usize).div_ceil(STRIP_ROWS)
        };
        let slot_blocks = || {
            (0..s.band_count()).flat_map(|band| {
                let blocks = s.band_blocks(band);
                (0..c).flat_map(move |j| s.term_slots(band, j, c).iter().zip(blocks.clone()))
            })
        };
        let is_whole =
            |slot: &Slot, b: usize| slot.count > 0 && slot.count as usize == block_strips(b);
        let whole = slot_blocks().filter(|&(s, b)| is_whole(s, b)).count();
        let some = slot_blocks()
            .filter(|&(s, b)| s.count > 0 && !is_whole(s, b))
            .count();
        let short = slot_blocks()
            .filter(|&(s, b)| is_whole(s, b) && block_strips(b) < STRIPS_PER_BLOCK)
            .count();
        assert!(
            whole > 0 && short > 0,
            "{q}: slots of all strips, of short blocks too"
        );
        tails.extend(
            slot_blocks()
                .filter(|&(s, b)| is_whole(s, b))
                .map(|(_, b)| block_strips(b) % 4),
        );
        assert_eq!(some > 0, density < 0.5, "{q}: slots of some strips");
        let mut rng = Rng::new(8, 0);
        // 64 and 70: one chunk of terms exactly, and past it.
        for k in [1, 5, 64.min(c), 70.min(c), c] {
            let light = common::random_light(&mut rng, c, k, false, |rng| {
                [rng.next_f32(), rng.next_f32() - 0.5, 1.0]
            });
            let dense = relight_dense_reference(&t, &light);
            let (best, best_read) = relight_strips(&t, s, &light, StripPath::Best);
            let (portable, read) = relight_strips(&t, s, &light, StripPath::Portable);
            let (strips, entries) = s.read_by(&light.indices, c);
            // The kept terms' slots that hold strips (the bitmask the loops walk by must name
            // exactly these), and the strips of those that hold all their block's, whose places
            // the SIMD loop does not read.
            let (mut occupied, mut whole) = (0u64, 0u64);
            for band in 0..s.band_count() {
                for &j in &light.indices {
                    let slots = s.term_slots(band, j as usize, c);
                    for (slot, b) in slots.iter().zip(s.band_blocks(band)) {
                        occupied += (slot.count > 0) as u64;
                        if is_whole(slot, b) {
                            whole += slot.count as u64;
                        }
                    }
                }
            }
            let want = Read {
                strips,
                entries,
                places: strips,
                slots: occupied,
            };
            assert_eq!(
                read, want,
                "{q} K = {k}: what the portable loop says it read"
            );
            let places = if has_avx2_fma() {
                strips - whole
            } else {
                strips
            };
            assert_eq!(best_read, Read { places, ..want }, "{q} K = {k}");
            for (name, img) in [("best", &best), ("portable", &portable)] {
                let e = relative_l2(img, &dense, None).unwrap();
                assert!(e < SAME_SUM, "{q} K = {k}: {name} vs dense {e}");
            }
        }
    }
    assert_eq!(
        tails,
        (0..4).collect(),
        "whole slots ending in panels of 4, 1, 2 and 3 strips"
    );
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

/// `prt info` prints from the header and the small tables: a file whose strips were overwritten
/// (same size) is still described, while loading it fails its checksum; a strip count that
/// disagrees with the strips stored is an error, found without reading them.
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
    for name in ["strip_place", "strip_value"] {
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
    // One more strip counted in the first slot than stored.
    let mut counted = bytes.clone();
    let at = range("strip_count").start;
    counted[at] += 1;
    let (code, text) = info(&counted);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("strip counts add up"), "{text}");
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

/// A bake reused from a file of an older format (as the demo reuses its bakes) is written again
/// in this one, once: later runs read strips without converting columns.
#[test]
fn a_reused_bake_of_an_older_format_is_written_again_in_this_one() {
    use wavelet_prt::store::transport::{FORMAT_VERSION, read_format_version};
    let dir = temp_dir("storage-reuse-format-6");
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/format6");
    for name in ["scene.toml", "v6_q8.prt"] {
        std::fs::copy(data.join(name), dir.join(name)).unwrap();
    }
    let path = dir.join("v6_q8.prt");
    let scene = wavelet_prt::scene::Scene::load(&dir.join("scene.toml")).unwrap();
    // The settings the file was baked with (`prt bake scene.toml --cube 4 --sh-order 2`, before
    // texels were integrated, `--edge-texel-samples 0` now, and at the threshold of its day).
    let settings = BakeSettings {
        cube_n: 4,
        sh_order: 2,
        edge_texel_samples: 0,
        threshold: 0.01,
        ..BakeSettings::default()
    };
    let before = Transport::load(&path).unwrap();
    let mut baked = false;
    let (t, reused) =
        wavelet_prt::bake::load_or_bake(&path, &scene, &settings, &mut || baked = true, &|_| {})
            .unwrap();
    assert!(reused && !baked, "the format 6 bake was not reused");
    assert_eq!(t, before);
    assert_eq!(read_format_version(&path).unwrap(), FORMAT_VERSION);
    assert_eq!(Transport::load(&path).unwrap(), before);
    // Reused again: left as it is.
    let modified = std::fs::metadata(&path).unwrap().modified().unwrap();
    let (_, reused) =
        wavelet_prt::bake::load_or_bake(&path, &scene, &settings, &mut || {}, &|_| {}).unwrap();
    assert!(reused);
    assert_eq!(
        std::fs::metadata(&path).unwrap().modified().unwrap(),
        modified
    );
    // Version 7 kept only the strips that hold entries: its file, reused, is written again with
    // the slots at least half full stored whole, every value in place.
    let v7 = dir.join("v7_q8.prt");
    let mut sparse = before.clone();
    sparse.strips = strips_with_entries_only(&before.strips);
    assert!(sparse.strips.strip_count() < before.strips.strip_count());
    sparse.save(&v7).unwrap();
    let mut file = StFile::read(&v7);
    file.meta["format_version"] = 7.into();
    file.write(&v7, true);
    assert_eq!(decoded(&Transport::load(&v7).unwrap()), decoded(&before));
    let (t, reused) =
        wavelet_prt::bake::load_or_bake(&v7, &scene, &settings, &mut || {}, &|_| {}).unwrap();
    assert!(reused);
    assert_eq!(t, before);
    assert_eq!(read_format_version(&v7).unwrap(), FORMAT_VERSION);
    assert_eq!(Transport::load(&v7).unwrap(), before);
}

/// The same strips without the empty ones, as version 7 stored them.
fn strips_with_entries_only(
    s: &wavelet_prt::store::transport::Strips,
) -> wavelet_prt::store::transport::Strips {
    use wavelet_prt::store::transport::{Values, strips::STRIP_ROWS};
    let Values::Q8(values) = &s.values else {
        panic!("a q8 bake")
    };
    let (mut counts, mut index, mut kept) = (Vec::new(), Vec::new(), Vec::new());
    for slot in &s.slots {
        let strips = slot.first as usize..slot.first as usize + slot.count as usize;
        let held: Vec<usize> = strips
            .filter(|&k| {
                values[k * STRIP_ROWS..][..STRIP_ROWS]
                    .iter()
                    .any(|&v| v != 0)
            })
            .collect();
        counts.push(held.len() as u8);
        for k in held {
            index.push(s.index[k]);
            kept.extend_from_slice(&values[k * STRIP_ROWS..][..STRIP_ROWS]);
        }
    }
    let codes = s.slots.iter().map(|slot| slot.code).collect::<Vec<_>>();
    wavelet_prt::store::transport::Strips::from_tables(
        s.layout(),
        &counts,
        &codes,
        index,
        Values::Q8(kept),
    )
    .unwrap()
}
