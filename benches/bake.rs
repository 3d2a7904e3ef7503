//! Criterion benchmark of one tile of the demo bake: the demo scene at 128² pixels, N = 32,
//! no extra sub-samples at shadow edges (`--edge-spp 0`), the settings otherwise `prt bake`'s
//! defaults. What every tile reads (the tracer's BVH, the texel samples, the edge map) is built
//! once, outside the timing ([`wavelet_prt::bake::with_tile_baker`]); each iteration bakes and
//! encodes the tile at the image's centre, where the teapot is: its shadow rays, the rows'
//! accumulation, the SH projection, the Haar transform, the thresholding and the quantisation.
//!
//! Before timing, it prints the tile's shadow rays, so that the time per iteration gives the
//! bake's rays a second on one core.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use wavelet_prt::bake::{BakeSettings, with_tile_baker};
use wavelet_prt::scene::Scene;

/// The image's side and the cube's face size.
const SIDE: u32 = 128;
const N: usize = 32;

fn demo_tile(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/demo.toml");
    let mut scene = Scene::load(&path).expect("bundled demo scene");
    scene.camera.width = SIDE;
    scene.camera.height = SIDE;
    let settings = BakeSettings {
        cube_n: N,
        edge_spp: 0,
        ..BakeSettings::default()
    };
    // The tiles run one at a time here, each on one core, as a bake's do.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool of one thread");
    with_tile_baker(&scene, &settings, |tiles, bake_one| {
        let side = (tiles as f64).sqrt() as usize;
        let centre = (side / 2) * side + side / 2;
        let rays = pool
            .install(|| bake_one(centre))
            .expect("a tile of the image");
        println!("tile {centre} of {tiles}: {rays} shadow rays");
        let mut group = c.benchmark_group("bake_tile");
        group
            .sample_size(10)
            .measurement_time(Duration::from_secs(20));
        group.bench_function(format!("demo_{SIDE}_n{N}_centre"), |b| {
            b.iter(|| pool.install(|| black_box(bake_one(black_box(centre)).unwrap())))
        });
        group.finish();
    })
    .expect("the demo bake's tiles");
}

criterion_group!(benches, demo_tile);
criterion_main!(benches);
