//! Per-vertex tessellations refined at shadow edges: as many vertices as the uniform
//! tessellation, more of them along the shadow a sun casts, conforming, the same mesh whatever
//! the threads, and told apart from a uniform bake by the file.

mod common;

use common::{scene_from, temp_dir};
use std::collections::HashMap;

use glam::Vec3;
use wavelet_prt::bake::{BakeSettings, bake, load_if_baked_with};
use wavelet_prt::scene::Scene;
use wavelet_prt::scene::tessellate::VertexMesh;
use wavelet_prt::store::transport::{BakeDomain, Transport};

/// A sphere on a 4 x 4 ground quad, seen from above and in front at 64 x 64.
const SCENE: &str = r#"
[camera]
eye = [0.0, 2.5, 3.5]
target = [0.0, 0.3, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 45.0
width = 64
height = 64

[material.ground]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[material.clay]
type = "diffuse"
albedo = [0.8, 0.3, 0.2]

[[shape]]
type = "quad"
corners = [[-2.0, 0.0, -2.0], [-2.0, 0.0, 2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]
material = "ground"

[[shape]]
type = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
material = "clay"
"#;

/// The sphere of [`SCENE`].
const CENTER: Vec3 = Vec3::new(0.0, 0.5, 0.0);
const RADIUS: f32 = 0.5;

/// The target edge length of the tests' tessellations: about 4,400 vertices, 2.8 pixels an edge
/// on the ground under the sphere.
const EDGE: f32 = 0.15;

/// The sun whose shadow edge the density test follows: 50° up, 60° round from −Z towards +X, so
/// that the sphere's shadow falls towards the camera, reaching about 1.1 from where it stands.
const SUN_ELEVATION_DEG: f32 = 50.0;
const SUN_AZIMUTH_DEG: f32 = 60.0;

/// The refined mesh has at most the uniform one's vertices, and at most this fraction fewer:
/// what the last rounds could not spend (a split of the open ground takes two).
const SAME_BUDGET: f64 = 0.03;

/// The ground vertices within half an edge of the sun's shadow edge, refined against uniform:
/// the coarse tessellation has half the uniform one's vertices, and the refinement spends the
/// rest around the sphere, where shadow edges of every direction pass.
const DENSER_AT_THE_EDGE: f64 = 1.2;

/// The boundary of the two sides of the ground, 4 x 4 each: a T-junction would add the length
/// of the edges it leaves unmatched.
const GROUND_BOUNDARY: f32 = 32.0;
/// Sums of a few hundred f32 edge lengths of order 0.1 against their exact total.
const BOUNDARY_SUM: f32 = 1e-3;

fn per_vertex(refine: bool) -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        domain: BakeDomain::Vertices { edge_length: EDGE },
        refine_shadows: refine,
        ..BakeSettings::default()
    }
}

/// Unit direction towards the sun of [`SUN`] (as `EnvMap::from_spec` places it).
fn towards_sun() -> Vec3 {
    let (el, az) = (SUN_ELEVATION_DEG.to_radians(), SUN_AZIMUTH_DEG.to_radians());
    Vec3::new(az.sin() * el.cos(), el.sin(), -az.cos() * el.cos())
}

/// Up-facing ground vertices whose ray towards `towards` passes within `half_width` of the
/// sphere's surface: those along the edge of its shadow.
fn near_shadow_edge(mesh: &VertexMesh, towards: Vec3, half_width: f32) -> usize {
    mesh.positions
        .iter()
        .zip(&mesh.normals)
        .filter(|(p, n)| n.y > 0.5 && p.y == 0.0)
        .filter(|(p, _)| {
            let to_center = CENTER - **p;
            let along = to_center.dot(towards);
            let miss = (to_center - along * towards).length();
            along > 0.0 && (miss - RADIUS).abs() < half_width
        })
        .count()
}

/// Total length of the edges that only one triangle has.
fn boundary_length(mesh: &VertexMesh) -> f32 {
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    assert!(
        count.values().all(|&n| n <= 2),
        "an edge of three triangles"
    );
    count
        .iter()
        .filter(|(_, n)| **n == 1)
        .map(|((a, b), _)| mesh.positions[*a as usize].distance(mesh.positions[*b as usize]))
        .sum()
}

fn scene(name: &str) -> Scene {
    scene_from(SCENE, name)
}

#[test]
fn the_refined_mesh_spends_the_uniform_budget_along_shadow_edges_and_stays_conforming() {
    let scene = scene("shadow-edges-budget");
    let uniform = VertexMesh::tessellate(&scene, EDGE).unwrap();
    let refined = VertexMesh::tessellate_refined(&scene, EDGE).unwrap();
    let (u, r) = (uniform.vertex_count(), refined.vertex_count());
    eprintln!("vertices: uniform {u}, refined {r}");
    assert!(r <= u, "{r} refined vertices past the budget of {u}");
    assert!(
        r as f64 >= (1.0 - SAME_BUDGET) * u as f64,
        "{r} refined vertices of a budget of {u}"
    );
    assert!(refined.problem(scene.materials.len()).is_none());
    // Conforming: no edge is left half split, so the only boundary is the ground's.
    let boundary = boundary_length(&refined);
    assert!(
        (boundary - GROUND_BOUNDARY).abs() < BOUNDARY_SUM,
        "boundary {boundary}"
    );
    // Every vertex of the ground has its twin facing down, at the same place.
    let ground = |up: bool| {
        let mut at: Vec<[u32; 3]> = (0..r)
            .filter(|&i| refined.positions[i].y == 0.0 && (refined.normals[i].y > 0.0) == up)
            .map(|i| refined.positions[i].to_array().map(f32::to_bits))
            .collect();
        at.sort();
        at
    };
    assert_eq!(ground(true), ground(false));
    // More of its vertices lie along the sun's shadow edge.
    let sun = towards_sun();
    let (near_u, near_r) = (
        near_shadow_edge(&uniform, sun, 0.5 * EDGE),
        near_shadow_edge(&refined, sun, 0.5 * EDGE),
    );
    eprintln!("vertices near the shadow edge: uniform {near_u}, refined {near_r}");
    assert!(near_u > 20, "{near_u}");
    assert!(
        near_r as f64 >= DENSER_AT_THE_EDGE * near_u as f64,
        "{near_r} refined against {near_u} uniform vertices near the shadow edge"
    );
}

#[test]
fn the_refined_mesh_is_the_same_whatever_the_threads_and_the_file_says_how_it_was_made() {
    let scene = scene("shadow-edges-determinism");
    let many = VertexMesh::tessellate_refined(&scene, EDGE).unwrap();
    let again = VertexMesh::tessellate_refined(&scene, EDGE).unwrap();
    assert_eq!(many, again);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| VertexMesh::tessellate_refined(&scene, EDGE).unwrap());
    assert_eq!(many, one);
    // The bake takes the refined mesh, or with the setting off the uniform one.
    let coarse = |refine: bool| BakeSettings {
        domain: BakeDomain::Vertices { edge_length: 0.3 },
        ..per_vertex(refine)
    };
    let t = bake(&scene, &coarse(true), &|_| {}).unwrap();
    let mesh = t.mesh().unwrap();
    let want = VertexMesh::tessellate_refined(&scene, 0.3).unwrap();
    assert_eq!(
        (&mesh.positions, &mesh.triangles),
        (&want.positions, &want.triangles)
    );
    let uniform = bake(&scene, &coarse(false), &|_| {}).unwrap();
    let want = VertexMesh::tessellate(&scene, 0.3).unwrap();
    let mesh = uniform.mesh().unwrap();
    assert_eq!(
        (&mesh.positions, &mesh.triangles),
        (&want.positions, &want.triangles)
    );
    // The identity records it, so a file of one is not reused for the other.
    assert!(t.meta.identity.refine_shadows);
    assert!(!uniform.meta.identity.refine_shadows);
    let path = temp_dir("shadow-edges-file").join("refined.prt");
    t.save(&path).unwrap();
    assert!(Transport::load(&path).unwrap().meta.identity.refine_shadows);
    assert!(load_if_baked_with(&path, &scene, &coarse(true)).is_some());
    assert!(load_if_baked_with(&path, &scene, &coarse(false)).is_none());
    // Without shadows there is nothing to refine: both settings are one bake.
    let unshadowed = |refine: bool| BakeSettings {
        unshadowed: true,
        ..coarse(refine)
    };
    assert_eq!(
        unshadowed(true).identity(&scene).unwrap(),
        unshadowed(false).identity(&scene).unwrap()
    );
    // A per-pixel bake's identity is the same either way.
    let view = |refine: bool| BakeSettings {
        refine_shadows: refine,
        ..BakeSettings::default()
    };
    assert_eq!(
        view(true).identity(&scene).unwrap(),
        view(false).identity(&scene).unwrap()
    );
}
