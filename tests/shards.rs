//! Sharded bakes: the merge of the shards is byte for byte the file one bake writes, and shards
//! that do not belong together are refused.

mod common;

use common::{SPHERE_ON_PLANE, scene_from, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::store::transport::BakeDomain;
use wavelet_prt::store::transport::Transport;

fn settings(shard: Option<[u32; 2]>) -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        spp: 4,
        threshold: 0.02,
        shard,
        ..BakeSettings::default()
    }
}

/// Merges `shards` and checks that the file it saves is, byte for byte, the one `whole` saves.
fn assert_merge_is_the_single_bake(whole: &Transport, shards: &[Transport], name: &str) {
    let merged = Transport::merge(shards).unwrap();
    let dir = temp_dir(name);
    whole.save(&dir.join("whole.prt")).unwrap();
    merged.save(&dir.join("merged.prt")).unwrap();
    assert!(
        std::fs::read(dir.join("whole.prt")).unwrap()
            == std::fs::read(dir.join("merged.prt")).unwrap(),
        "merged file differs from the single bake"
    );
}

#[test]
fn shards_with_interreflections_merge_byte_identically() {
    // Each shard picks the same surface cache points as the whole bake, so the rows agree.
    let scene = scene_from(SPHERE_ON_PLANE, "shards-bounces");
    let with = |shard| BakeSettings {
        spp: 1,
        bounces: 2,
        paths: 8,
        ..settings(shard)
    };
    let whole = bake(&scene, &with(None), &|_| {}).unwrap();
    assert!(whole.meta.cache_points > 0);
    let shards: Vec<Transport> = [1, 0]
        .iter()
        .map(|&i| bake(&scene, &with(Some([i, 2])), &|_| {}).unwrap())
        .collect();
    assert_merge_is_the_single_bake(&whole, &shards, "shards-bounces");
}

#[test]
fn merge_of_three_shards_is_byte_identical_to_one_bake() {
    // 45 rows: three bands of 16-pixel tiles, the last one partial.
    let text = SPHERE_ON_PLANE.replace("height = 21", "height = 45");
    let scene = scene_from(&text, "shards");
    let dir = temp_dir("shards-out");
    let whole = bake(&scene, &settings(None), &|_| {}).unwrap();
    whole.save(&dir.join("whole.prt")).unwrap();
    // Shards baked out of order and given to the merge out of order.
    let shards: Vec<Transport> = [2, 0, 1]
        .iter()
        .map(|&i| bake(&scene, &settings(Some([i, 3])), &|_| {}).unwrap())
        .collect();
    for s in &shards {
        assert!(s.row_pixel.len() < whole.row_pixel.len());
        assert!(!s.row_pixel.is_empty());
    }
    let merged = Transport::merge(&shards).unwrap();
    merged.save(&dir.join("merged.prt")).unwrap();
    let a = std::fs::read(dir.join("whole.prt")).unwrap();
    let b = std::fs::read(dir.join("merged.prt")).unwrap();
    assert_eq!(a.len(), b.len());
    assert!(a == b, "merged file differs from the single bake");
    // `prt merge` writes the merge tile by tile: the same bytes.
    let names: Vec<String> = ["a", "b", "c"].map(String::from).to_vec();
    let meta = Transport::merge_to_file(&shards, &names, &dir.join("streamed.prt")).unwrap();
    assert_eq!(meta, whole.meta);
    assert!(a == std::fs::read(dir.join("streamed.prt")).unwrap());
    // Shard files round-trip through disk too.
    shards[0].save(&dir.join("s.prt")).unwrap();
    // (The header's floats round-trip exactly: the statistics are compared too.)
    assert_eq!(Transport::load(&dir.join("s.prt")).unwrap(), shards[0]);
}

#[test]
fn shards_that_do_not_belong_together_are_refused() {
    let text = SPHERE_ON_PLANE.replace("height = 21", "height = 45");
    let scene = scene_from(&text, "shards-bad");
    let other = scene_from(
        &text.replace("0.8, 0.3, 0.2", "0.7, 0.3, 0.2"),
        "shards-other",
    );
    let s0 = bake(&scene, &settings(Some([0, 2])), &|_| {}).unwrap();
    let s1 = bake(&scene, &settings(Some([1, 2])), &|_| {}).unwrap();
    let foreign = bake(&other, &settings(Some([1, 2])), &|_| {}).unwrap();
    let e = Transport::merge(&[s0.clone(), foreign])
        .unwrap_err()
        .to_string();
    assert!(e.contains("another scene than file 1"), "{e}");
    let e = Transport::merge(std::slice::from_ref(&s0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing"), "{e}");
    let e = Transport::merge(&[s0.clone(), s0.clone()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("repeats"), "{e}");
    let whole = bake(&scene, &settings(None), &|_| {}).unwrap();
    let e = Transport::merge(&[s0, s1, whole]).unwrap_err().to_string();
    assert!(e.contains("not a shard"), "{e}");
    let e = settings(Some([2, 2])).validate().unwrap_err().to_string();
    assert!(e.contains("2/2"), "{e}");
    let e = bake(&scene, &settings(Some([0, 9])), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("tile rows"), "{e}");
}

#[test]
fn per_vertex_shards_merge_byte_identically() {
    // 0.25 splits the ground and the sphere into enough vertices for several bands of tiles.
    let scene = scene_from(SPHERE_ON_PLANE, "shards-vertices");
    let with = |shard| BakeSettings {
        spp: 1,
        domain: BakeDomain::Vertices { edge_length: 0.25 },
        ..settings(shard)
    };
    let whole = bake(&scene, &with(None), &|_| {}).unwrap();
    let bands = whole.meta.height as usize / 16;
    assert!(bands >= 3, "{bands} bands");
    let shards: Vec<Transport> = [2, 0, 1]
        .iter()
        .map(|&i| bake(&scene, &with(Some([i, 3])), &|_| {}).unwrap())
        .collect();
    assert_merge_is_the_single_bake(&whole, &shards, "shards-vertices");
}
