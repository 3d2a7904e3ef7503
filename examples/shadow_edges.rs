//! Shadow-edge refinement on the demo scene: its per-vertex bake at the default edge length,
//! tessellated uniformly and refined at shadow edges within the same vertex budget, each relit
//! under sunrise with every term and drawn, against per-pixel bakes of the same scene relit
//! alike: from the bake's camera (the demo's per-pixel bake) and from the orbit camera turned
//! 40° (a per-pixel bake made from there). The error is the demo orbit's: relative L2 over the
//! pixels both images cover, leaving out those of glossy surfaces (more than one row a pixel),
//! whose lobe a per-vertex bake does not keep.
//!
//! ```sh
//! cargo run --release --example shadow_edges -- [DIR]
//! ```
//!
//! The bakes are saved in DIR (default `target/shadow_edges`) and reused by later runs; a demo
//! run's folder already holds the per-pixel one (`demo.prt`) and, when it was made with
//! refinement, the refined one (`demo_vertices.prt`).

use std::error::Error;
use std::path::{Path, PathBuf};
use std::time::Instant;

use wavelet_prt::bake::{BakeSettings, bake, load_if_baked_with};
use wavelet_prt::draw::vertex::{draw_relit, orbit};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::output::film::Image;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::{LightContext, RelightRequest, relight};
use wavelet_prt::scene::tessellate::VertexMesh;
use wavelet_prt::scene::{Camera, Scene};
use wavelet_prt::store::transport::{BakeDomain, Transport};

/// The new camera: the scene's turned about its target, degrees.
const TURN_DEG: f32 = 40.0;

/// A per-pixel bake relit with every term, and which of its pixels the comparison takes.
struct Reference {
    image: Image,
    /// Wholly covered, by one (diffuse) row.
    diffuse: Vec<bool>,
}

fn main() -> Result<(), Box<dyn Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "target/shadow_edges".into()),
    );
    std::fs::create_dir_all(&dir)?;
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let scene = Scene::load(&assets.join("scenes/demo.toml"))?;
    let env = EnvMap::load(&assets.join("envmaps/blender_sunrise.exr"))?;
    // The demo's settings (`app::studies::demo::demo_settings`).
    let settings = BakeSettings {
        sh_order: 8,
        ..BakeSettings::default()
    };
    let edge = VertexMesh::default_edge_length(&scene);
    let start = Instant::now();
    let uniform = VertexMesh::tessellate(&scene, edge)?;
    let uniform_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let refined = VertexMesh::tessellate_refined(&scene, edge)?;
    let refined_s = start.elapsed().as_secs_f64();
    println!("demo scene, edge length {edge:.4}");
    println!(
        "uniform: {} vertices, {} triangles ({uniform_s:.2} s)",
        uniform.vertex_count(),
        uniform.triangles.len()
    );
    println!(
        "refined: {} vertices, {} triangles ({refined_s:.2} s)",
        refined.vertex_count(),
        refined.triangles.len()
    );
    let turned = orbit(&scene.camera, TURN_DEG, 0.0);
    let mut turned_scene = scene.clone();
    turned_scene.camera = turned.clone();
    let from_bake = reference(&dir.join("demo.prt"), &scene, &settings, &env)?;
    let from_turned = reference(
        &dir.join(format!("demo_turned_{TURN_DEG}.prt")),
        &turned_scene,
        &settings,
        &env,
    )?;
    let mut rows = Vec::new();
    for (name, refine, file) in [
        ("uniform", false, "demo_vertices_uniform.prt"),
        ("refined", true, "demo_vertices.prt"),
    ] {
        let per_vertex = BakeSettings {
            domain: BakeDomain::Vertices { edge_length: edge },
            refine_shadows: refine,
            ..settings.clone()
        };
        let t = cached(&dir.join(file), &scene, &per_vertex)?;
        let ctx = LightContext::new(&t)?;
        let light = ctx.prepare(&env, EnvRotation::default())?;
        let (full, _) = relight(&t, &ctx, &light, &RelightRequest::Full)?;
        let vertices = t.meta.per_vertex.as_ref().map_or(0, |p| p.vertices);
        let at_bake = error(&t, &full, &scene.camera, &from_bake)?;
        let at_turned = error(&t, &full, &turned, &from_turned)?;
        rows.push((name, vertices, at_bake, at_turned));
    }
    println!("\nrelative L2 against per pixel, under sunrise, every term:");
    println!("| tessellation | vertices | bake's camera | turned {TURN_DEG}° |");
    println!("|---|---|---|---|");
    for (name, vertices, at_bake, at_turned) in &rows {
        println!(
            "| {name} | {vertices} | {:.2}% | {:.2}% |",
            100.0 * at_bake,
            100.0 * at_turned
        );
    }
    let [(_, _, u_bake, u_turned), (_, _, r_bake, r_turned)] = rows[..] else {
        return Err("two tessellations expected".into());
    };
    println!(
        "\nrefined against uniform: {:+.1}% from the bake's camera, {:+.1}% turned {TURN_DEG}°",
        100.0 * (r_bake / u_bake - 1.0),
        100.0 * (r_turned / u_turned - 1.0)
    );
    Ok(())
}

/// The bake of `scene` with `settings` at `path`: the file's when it holds this bake from the
/// same camera (the scene's hash does not see a camera turned in code), else baked and saved.
fn cached(
    path: &Path,
    scene: &Scene,
    settings: &BakeSettings,
) -> Result<Transport, Box<dyn Error>> {
    let c = &scene.camera;
    if let Some(t) = load_if_baked_with(path, scene, settings)
        && t.meta.camera.eye == c.eye.to_array()
        && t.meta.camera.target == c.target.to_array()
        && t.meta.camera.up == c.up.to_array()
    {
        println!("reusing {}", path.display());
        return Ok(t);
    }
    println!("baking {} ...", path.display());
    let start = Instant::now();
    let t = bake(scene, settings, &|_| {})?;
    t.save(path)?;
    println!("  {:.0} s", start.elapsed().as_secs_f64());
    Ok(t)
}

/// `scene` baked per pixel (or the bake at `path`), relit under `env` with every term.
fn reference(
    path: &Path,
    scene: &Scene,
    settings: &BakeSettings,
    env: &EnvMap,
) -> Result<Reference, Box<dyn Error>> {
    let t = cached(path, scene, settings)?;
    let ctx = LightContext::new(&t)?;
    let light = ctx.prepare(env, EnvRotation::default())?;
    let (image, _) = relight(&t, &ctx, &light, &RelightRequest::Full)?;
    let mut rows = vec![0u32; t.coverage.len()];
    for &p in &t.row_pixel {
        rows[p as usize] += 1;
    }
    let diffuse = t
        .coverage
        .iter()
        .zip(&rows)
        .map(|(&c, &r)| c == 1.0 && r == 1)
        .collect();
    Ok(Reference { image, diffuse })
}

/// The per-vertex bake `t` relit to `full`, drawn from `camera`, against `r` over the pixels
/// both cover with one diffuse row: relative L2.
fn error(
    t: &Transport,
    full: &Image,
    camera: &Camera,
    r: &Reference,
) -> Result<f64, Box<dyn Error>> {
    let drawn = draw_relit(t, full, None, camera, None, 1)?;
    let both: Vec<f32> = drawn
        .coverage
        .iter()
        .zip(&r.diffuse)
        .map(|(&c, &d)| (c == 1.0 && d) as u8 as f32)
        .collect();
    Ok(relative_l2(&drawn.image, &r.image, Some(&both))?)
}
