//! The bake streamed to its file tile by tile (`bake_to_file`, what `prt bake` runs) writes the
//! file that the bake kept in memory and saved writes, byte for byte, leaves nothing else behind,
//! and fails cleanly.

mod common;

use common::{SPHERE_ON_PLANE, prt, random_transport, scene_from, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake, bake_to_file};
use wavelet_prt::scene::Scene;
use wavelet_prt::store::quant::Quantization;
use wavelet_prt::store::transport::BakeDomain;
use wavelet_prt::store::transport::{BakeStats, EncodedTile, Transport, TransportWriter, Untiled};

fn settings() -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 3,
        spp: 2,
        texel_samples: 4,
        threshold: 0.02,
        ..BakeSettings::default()
    }
}

/// Bakes `scene` both ways into a folder of its own and checks that the two files are the same
/// bytes, that the streamed bake returns the kept bake's header, and that no spill is left.
fn streamed_equals_kept(scene: &Scene, settings: &BakeSettings, name: &str) -> Transport {
    let dir = temp_dir(name);
    let kept = bake(scene, settings, &|_| {}).unwrap();
    kept.save(&dir.join("kept.prt")).unwrap();
    let meta = bake_to_file(scene, settings, &dir.join("streamed.prt"), &|_| {}).unwrap();
    assert_eq!(meta, kept.meta, "{name}: header");
    let a = std::fs::read(dir.join("kept.prt")).unwrap();
    let b = std::fs::read(dir.join("streamed.prt")).unwrap();
    assert_eq!(a.len(), b.len(), "{name}: file sizes");
    assert!(
        a == b,
        "{name}: the streamed file differs from the kept one"
    );
    assert_eq!(
        common::names_in(&dir),
        ["kept.prt", "streamed.prt"],
        "{name}"
    );
    assert_eq!(Transport::load(&dir.join("streamed.prt")).unwrap(), kept);
    kept
}

#[test]
fn a_glossy_bake_with_tiles_of_several_blocks_streams_to_the_same_bytes() {
    // A glossy sphere gives two rows per pixel, so the tiles it covers pass 256 rows.
    let glossy = SPHERE_ON_PLANE
        .replace(
            "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
            "type = \"glossy\"\nalbedo = [0.5, 0.2, 0.1]\nspecular = [0.4, 0.4, 0.4]\nroughness = 0.3",
        )
        .replace("width = 37\nheight = 21", "width = 64\nheight = 64");
    let scene = scene_from(&glossy, "streamed-glossy");
    let t = streamed_equals_kept(&scene, &settings(), "streamed-glossy");
    assert!(
        (0..t.tile_count()).any(|tile| t.blocks(tile).len() > 1),
        "no tile of several blocks"
    );
    for (q, name) in [
        (Quantization::Q16, "streamed-q16"),
        (Quantization::F32, "streamed-f32"),
    ] {
        let s = BakeSettings {
            quantization: q,
            lossless: q == Quantization::F32,
            ..settings()
        };
        let t = streamed_equals_kept(&scene, &s, name);
        assert_eq!(t.quantization(), q);
    }
}

#[test]
fn shards_vertices_and_interreflections_stream_to_the_same_bytes() {
    let scene = scene_from(SPHERE_ON_PLANE, "streamed-kinds");
    let shard = BakeSettings {
        shard: Some([1, 2]),
        ..settings()
    };
    let t = streamed_equals_kept(&scene, &shard, "streamed-shard");
    assert!(t.tile_row_start[t.tile_count()] > 0);
    let vertices = BakeSettings {
        domain: BakeDomain::Vertices { edge_length: 0.25 },
        ..settings()
    };
    let t = streamed_equals_kept(&scene, &vertices, "streamed-vertices");
    assert!(t.mesh().is_some());
    let bounces = BakeSettings {
        spp: 1,
        bounces: 1,
        paths: 4,
        ..settings()
    };
    streamed_equals_kept(&scene, &bounces, "streamed-bounces");
}

#[test]
fn the_streamed_bake_is_the_same_on_any_number_of_threads() {
    // Tiles finish out of order on many threads and are written in order all the same.
    let scene = scene_from(SPHERE_ON_PLANE, "streamed-threads");
    let dir = temp_dir("streamed-threads");
    let mut files = Vec::new();
    for threads in [1, 2, 7] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let path = dir.join(format!("t{threads}.prt"));
        pool.install(|| bake_to_file(&scene, &settings(), &path, &|_| {}))
            .unwrap();
        files.push(std::fs::read(&path).unwrap());
    }
    assert!(files[0] == files[1] && files[1] == files[2]);
}

#[test]
fn a_streamed_bake_that_cannot_write_fails_with_the_path_and_leaves_nothing() {
    let scene = scene_from(SPHERE_ON_PLANE, "streamed-fail");
    let dir = temp_dir("streamed-fail");
    let missing = dir.join("no such folder").join("out.prt");
    let e = bake_to_file(&scene, &settings(), &missing, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("no such folder"), "{e}");
    assert!(common::names_in(&dir).is_empty());
    // A file there already is replaced whole, atomically.
    let out = dir.join("out.prt");
    std::fs::write(&out, b"old").unwrap();
    bake_to_file(&scene, &settings(), &out, &|_| {}).unwrap();
    assert!(Transport::load(&out).is_ok());
    assert_eq!(common::names_in(&dir), ["out.prt"]);
}

#[test]
fn prt_bake_writes_the_file_the_library_bakes() {
    let dir = temp_dir("streamed-cli");
    let scene_path = dir.join("scene.toml");
    std::fs::write(&scene_path, SPHERE_ON_PLANE).unwrap();
    let out = dir.join("cli.prt");
    let (code, text) = prt(&[
        "bake",
        scene_path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--cube",
        "8",
        "--sh-order",
        "3",
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("written"), "{text}");
    let scene = Scene::load(&scene_path).unwrap();
    let s = BakeSettings {
        cube_n: 8,
        sh_order: 3,
        ..BakeSettings::default()
    };
    let kept = bake(&scene, &s, &|_| {}).unwrap();
    kept.save(&dir.join("kept.prt")).unwrap();
    assert!(std::fs::read(&out).unwrap() == std::fs::read(dir.join("kept.prt")).unwrap());
}

/// The parts of `t` a writer is finished with, statistics not yet filled in.
fn untiled(t: &Transport) -> Untiled {
    Untiled {
        meta: wavelet_prt::store::transport::TransportMeta {
            stats: BakeStats::default(),
            ..t.meta.clone()
        },
        albedo: t.albedo.clone(),
        coverage: t.coverage.clone(),
        attached: t.attached.clone(),
    }
}

#[test]
fn the_writer_refuses_tiles_that_do_not_fit_and_a_file_with_tiles_missing() {
    let dir = temp_dir("streamed-writer");
    let path = dir.join("w.prt");
    // One tile over 6 x 2² coefficients.
    let t = random_transport(16, 16, 2, Quantization::Q8, 5, 1.0);
    let (c, shc, sh_order) = (
        t.coeff_count(),
        t.sh_count(),
        t.meta.identity.sh_order as usize,
    );
    let rows = t.tile_rows(0);
    assert!(!rows.is_empty());
    let tile = EncodedTile::encode(&rows, c, shc, Quantization::Q8).unwrap();
    let mut w = TransportWriter::create(&path, (16, 16), 2, sh_order, Quantization::Q8).unwrap();
    // A tile whose counts miss a coefficient, one of another quantisation, one of another cube.
    let mut bad = tile.clone();
    bad.col_count.pop();
    let q16 = EncodedTile::encode(&rows, c, shc, Quantization::Q16).unwrap();
    let wider = EncodedTile::encode(&rows, 6 * 4 * 4, shc, Quantization::Q8).unwrap();
    for refused in [&bad, &q16, &wider] {
        let e = w.push(refused, [0.0; 3]).unwrap_err().to_string();
        assert!(e.contains("w.prt") && e.contains("tile 0"), "{e}");
    }
    w.push(&tile, t.tile_stats[0]).unwrap();
    // An image of two tiles, one written: refused, and nothing is left.
    let two = random_transport(32, 16, 2, Quantization::Q8, 6, 1.0);
    let e = w.finish(untiled(&two)).unwrap_err().to_string();
    assert!(e.contains("1 of the 2 tiles of a 32 x 16 image"), "{e}");
    assert!(
        common::names_in(&dir).is_empty(),
        "{:?}",
        common::names_in(&dir)
    );
    // The whole image: a file that loads back with the tile's rows and the header's counts.
    let mut w = TransportWriter::create(&path, (16, 16), 2, sh_order, Quantization::Q8).unwrap();
    w.push(&tile, t.tile_stats[0]).unwrap();
    let meta = w.finish(untiled(&t)).unwrap();
    assert_eq!(meta.stats.rows, t.meta.stats.rows);
    assert_eq!(meta.stats.nonzeros, tile.entry_row.len() as u64);
    let back = Transport::load(&path).unwrap();
    assert_eq!(back.meta, meta);
    let pixels = |r: &[wavelet_prt::store::transport::RowData]| {
        r.iter()
            .map(|r| (r.pixel, r.entries.len()))
            .collect::<Vec<_>>()
    };
    assert_eq!(pixels(&back.tile_rows(0)), pixels(&rows));
    assert_eq!(common::names_in(&dir), ["w.prt"]);
}
