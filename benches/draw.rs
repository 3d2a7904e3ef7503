//! Criterion benchmark of a glossy per-vertex frame drawn on the CPU: the glossy sphere
//! (roughness 0.2, a sharp lobe) on a broad glossy ground (roughness 0.6), 256² pixels, one
//! sample a pixel, its lobe per pixel from the vertices' visibility.
//!
//! - `own_directions`: each material with the directions its width asks for (64 for the
//!   sphere, 256 for the ground; [`wavelet_prt::draw::lobe::lobe_samples`]), as a draw takes;
//! - `broadest_directions`: every material with the broadest one's 256, as one count for the
//!   whole bake did.
//!
//! Before timing, it checks that the two draw the ground alike and the sphere apart.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::draw::lobe::{Lobe, lobe_samples};
use wavelet_prt::draw::raster::{DrawOptions, Raster, rasterize_with};
use wavelet_prt::draw::shading::{GlossMesh, ViewDependent};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::relight::{LightContext, RelightRequest, lobe_light, relight};
use wavelet_prt::scene::Scene;
use wavelet_prt::store::transport::{BakeDomain, Transport};

/// The bundled glossy sphere, its ground made a broad glossy material, its image 256².
fn scene() -> Scene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let path = root.join("assets/scenes/glossy_sphere.toml");
    let text = std::fs::read_to_string(&path).expect("bundled scene");
    let matte = "[material.ground]\ntype = \"diffuse\"\nalbedo = [0.8, 0.8, 0.8]";
    assert!(text.contains(matte));
    let glossy = "[material.ground]\ntype = \"glossy\"\nalbedo = [0.5, 0.5, 0.5]\n\
                  specular = [0.3, 0.3, 0.3]\nroughness = 0.6";
    let dir = std::env::temp_dir().join("wavelet-prt-bench-draw");
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let file = dir.join("mixed.toml");
    std::fs::write(&file, text.replace(matte, glossy)).expect("scene written");
    Scene::load(&file).expect("scene")
}

/// A frame of `t` relit to `colours` with `lobe`, from the scene's camera turned 40°.
fn frame(t: &Transport, colours: &[[f32; 3]], lobe: &Lobe) -> Raster {
    let mesh = t.mesh().expect("per vertex");
    let base = wavelet_prt::draw::vertex::bake_camera(t).expect("camera");
    let camera = wavelet_prt::draw::vertex::orbit(&base, 40.0, 10.0);
    let options = DrawOptions {
        gloss: Some(lobe as &dyn ViewDependent),
        ..DrawOptions::samples(1)
    };
    rasterize_with(&camera, &mesh.positions, &mesh.triangles, colours, options).expect("drawn")
}

fn bench(c: &mut Criterion) {
    let scene = scene();
    let settings = BakeSettings {
        cube_n: 16,
        sh_order: 2,
        domain: BakeDomain::Vertices { edge_length: 0.1 },
        visibility: true,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).expect("baked");
    let env = EnvMap::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/envmaps/blender_studio.exr"),
    )
    .expect("bundled map");
    let ctx = LightContext::new(&t).expect("context");
    let light = ctx.prepare(&env, EnvRotation::default()).expect("light");
    let (relit, _) = relight(&t, &ctx, &light, &RelightRequest::Full).expect("relit");
    let pyramid = lobe_light(&t, &ctx, Some(&light), &RelightRequest::Full)
        .expect("lobe light")
        .expect("a bake with visibility");
    let mesh = t.mesh().expect("per vertex");
    let vis = mesh.visibility.as_deref().expect("visibility");
    let colours = &relit.pixels[..mesh.vertex_count()];
    let counts = lobe_samples(vis);
    let broadest = counts.iter().copied().max().unwrap_or(0);
    println!("directions a material: {counts:?}; broadest {broadest}");
    let gloss = GlossMesh::of(mesh).expect("visibility");
    let own = Lobe::of_widths(gloss, &pyramid);
    let one = Lobe::new(gloss, &pyramid, broadest);
    let (a, b) = (frame(&t, colours, &own), frame(&t, colours, &one));
    let apart = a
        .image
        .pixels
        .iter()
        .zip(&b.image.pixels)
        .filter(|(x, y)| x != y)
        .count();
    println!("pixels drawn apart: {apart} of {}", a.image.pixels.len());
    let mut g = c.benchmark_group("glossy_frame_256");
    g.sample_size(10);
    g.bench_function("own_directions", |bch| {
        bch.iter(|| black_box(frame(&t, colours, &own)))
    });
    g.bench_function("broadest_directions", |bch| {
        bch.iter(|| black_box(frame(&t, colours, &one)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
