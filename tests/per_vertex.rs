//! Per-vertex transport: one row per vertex of the tessellated scene, checked against a direct
//! integration of the light at each vertex, written and read back with its mesh, refused where it
//! does not apply, and driven from the command line.

mod common;

use common::{GPU_MATCH, SPHERE_ON_PLANE, StFile, assets, prt, relit, scene_from, temp_dir};
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::env::select::Weighting;
use wavelet_prt::math::cubemap::{solid_angles, texel_dirs};
use wavelet_prt::relight::{LightContext, RelightRequest, relight};
use wavelet_prt::scene::trace::Tracer;
use wavelet_prt::store::transport::BakeDomain;
use wavelet_prt::store::transport::{TILE, Transport};

/// Relative L2 between a closed mesh baked per vertex and drawn, and the same scene baked per
/// pixel, over covered pixels: the 37 x 21 image's silhouettes and the interpolation between
/// vertices, measured 12.6% (sphere) and 15.0% (torus) either way the mesh is wound. A mesh
/// baked for its inner side would be black, 100% off.
const VERTEX_VS_PIXEL_MESH: f64 = 0.25;
/// A vertex's relit colour against the light integrated here at the vertex, relative to the
/// brightest: both are the same sum over the cube's texel centres (one direction a texel), one
/// through f32 rows, the Haar transforms of row and light and the kernel, the other in f64, so
/// only f32 rounding separates them.
const VERTEX_ROUNDING_OF_BRIGHTEST: f32 = 1e-4;
/// How far a drawn pixel may rise above the largest vertex colour, relative to it: Gouraud
/// interpolation cannot leave the colours' range, and the CPU raster's f64 weights stored in f32
/// add only a few ulps.
const INTERPOLATION_OVERSHOOT: f32 = 1e-5;
/// A flat plane's vertex colour against albedo x L, relative: the texel sum of the cosine over a
/// 6 x 8² cube misses the integral by 0.52%, under this.
const COSINE_DISCRETISATION: f32 = 1e-2;
/// A drawn pixel between vertices of equal colour against that colour, relative: interpolation
/// between equal values gives the value, up to the f32 rounding of weights summing to 1.
const EQUAL_VALUES_INTERPOLATED: f32 = 1e-5;
/// Beyond this share of the brightest vertex colour, a GPU pixel counts as drawn differently from
/// the CPU's: the GPU interpolates in f32 with its own rounding, the CPU in f64.
const GPU_RASTER_OF_BRIGHTEST: f32 = 1e-4;

fn per_vertex(edge: f32) -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        domain: BakeDomain::Vertices { edge_length: edge },
        ..BakeSettings::default()
    }
}

#[test]
fn per_vertex_rows_equal_the_light_integrated_at_each_vertex() {
    let scene = scene_from(SPHERE_ON_PLANE, "per-vertex-reference");
    let t = bake(&scene, &per_vertex(0.5), &|_| {}).unwrap();
    let mesh = t.mesh().expect("a per-vertex bake keeps its mesh");
    let v = mesh.vertex_count();
    // Both sides of the ground quad and the sphere.
    assert!(v > 200, "{v} vertices");
    assert_eq!(t.meta.per_vertex.as_ref().unwrap().vertices as usize, v);
    assert_eq!(
        (t.meta.width as usize, t.meta.height as usize),
        (TILE, v.div_ceil(TILE))
    );
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let rotation = EnvRotation::yaw(60.0);
    let image = relit(&t, &env, rotation, RelightRequest::Full);
    // The light at each vertex, integrated over the cube's texels directly: radiance x
    // visibility x albedo/π x cos x solid angle, from just off the surface on its normal's side.
    let cube = env.to_cube(8, rotation).unwrap();
    let (dirs, omega) = (texel_dirs(8), solid_angles(8));
    let tracer = Tracer::new(&scene);
    let mut brightest = 0.0f32;
    let mut worst = 0.0f32;
    let mut dark = 0;
    for i in 0..v {
        let (p, n) = (mesh.positions[i], mesh.normals[i]);
        let origin = p + n * tracer.spawn_offset();
        let albedo = scene.materials[mesh.materials[i] as usize].albedo();
        let mut want = [0.0f64; 3];
        for (j, d) in dirs.iter().enumerate() {
            let d = d.normalize().as_vec3();
            let cos = n.dot(d);
            if cos <= 0.0 || tracer.occluded(origin, d, f32::INFINITY) {
                continue;
            }
            for k in 0..3 {
                want[k] +=
                    (cube.texels[j][k] * albedo[k] * cos) as f64 * omega[j] / std::f64::consts::PI;
            }
        }
        dark += (want.iter().sum::<f64>() < 1e-3) as usize;
        for (got, want) in image.pixels[i].iter().zip(want) {
            brightest = brightest.max(want as f32);
            worst = worst.max((got - want as f32).abs());
        }
    }
    assert!(brightest > 0.1, "{brightest}");
    assert!(
        worst <= VERTEX_ROUNDING_OF_BRIGHTEST * brightest,
        "off by {worst} of {brightest}"
    );
    // The ground under the sphere and the ground's underside facing the lower sky: not all
    // black, not all lit.
    assert!(dark < v / 2, "{dark} dark vertices of {v}");
    // The pixels past the last vertex hold nothing.
    assert!(image.pixels[v..].iter().all(|p| *p == [0.0; 3]));
    assert!(t.coverage[..v].iter().all(|&c| c == 1.0));
    assert!(t.coverage[v..].iter().all(|&c| c == 0.0));
}

#[test]
fn a_per_vertex_file_keeps_its_mesh_and_a_broken_mesh_is_refused() {
    let scene = scene_from(SPHERE_ON_PLANE, "per-vertex-file");
    let settings = BakeSettings {
        lossless: false,
        ..per_vertex(0.8)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let dir = temp_dir("per-vertex-file");
    let path = dir.join("v.prt");
    t.save(&path).unwrap();
    let back = Transport::load(&path).unwrap();
    assert_eq!(back, t);
    // The cached bake is found again only with the same edge length.
    assert!(wavelet_prt::bake::load_if_baked_with(&path, &scene, &settings).is_some());
    let other = BakeSettings {
        domain: BakeDomain::Vertices { edge_length: 0.7 },
        ..settings.clone()
    };
    assert!(wavelet_prt::bake::load_if_baked_with(&path, &scene, &other).is_none());
    // A triangle pointing past the vertices, with the checksum made to agree: refused by name.
    let mut file = StFile::read(&path);
    let triangles = file.tensor_mut("mesh_triangle");
    triangles[0..4].copy_from_slice(&u32::MAX.to_le_bytes());
    let bad = dir.join("bad.prt");
    file.write(&bad, true);
    let e = Transport::load(&bad).unwrap_err().to_string();
    assert!(e.contains("bad.prt") && e.contains("triangle"), "{e}");
    // A normal that is not a unit vector.
    let mut file = StFile::read(&path);
    file.tensor_mut("mesh_normal")[0..4].copy_from_slice(&7.0f32.to_le_bytes());
    file.write(&bad, true);
    let e = Transport::load(&bad).unwrap_err().to_string();
    assert!(e.contains("normal"), "{e}");
}

#[test]
fn per_vertex_bakes_refuse_what_they_cannot_hold() {
    let scene = scene_from(SPHERE_ON_PLANE, "per-vertex-refusals");
    let bounced = BakeSettings {
        bounces: 1,
        ..per_vertex(0.5)
    };
    let e = bake(&scene, &bounced, &|_| {}).unwrap_err().to_string();
    assert!(e.contains("per pixel only"), "{e}");
    let e = bake(&scene, &per_vertex(f32::NAN), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("edge length"), "{e}");
    let e = bake(&scene, &per_vertex(1e-7), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("too fine"), "{e}");
    let fog = scene_from(&common::fog_scene(0.0, 8, 8), "per-vertex-fog");
    let e = bake(&fog, &per_vertex(0.5), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("[medium]"), "{e}");
}

#[test]
fn prt_bake_per_vertex_reports_its_vertices_and_info_reads_them() {
    let dir = temp_dir("per-vertex-cli");
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, format!("edge_length = 0.6\n{SPHERE_ON_PLANE}")).unwrap();
    let out = dir.join("v.prt");
    let (code, text) = prt(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--per-vertex",
        "--cube",
        "8",
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("per vertex") && text.contains("edges up to 0.6000"),
        "{text}"
    );
    assert!(
        !text.contains("warning"),
        "every material is diffuse: {text}"
    );
    // A glossy material kept at its diffuse base (`--visibility false`), and the bake says so by
    // name.
    let glossy = dir.join("glossy.toml");
    std::fs::write(
        &glossy,
        format!("edge_length = 0.6\n{SPHERE_ON_PLANE}").replace(
            "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
            "type = \"glossy\"\nalbedo = [0.5, 0.3, 0.2]\nspecular = [0.3, 0.3, 0.3]\nroughness = 0.3",
        ),
    )
    .unwrap();
    let (code, text) = prt(&[
        "bake",
        glossy.to_str().unwrap(),
        "-o",
        dir.join("g.prt").to_str().unwrap(),
        "--per-vertex",
        "--cube",
        "4",
        "--visibility",
        "false",
    ]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains("warning") && text.contains("clay") && text.contains("diffuse base"),
        "{text}"
    );
    let t = Transport::load(&out).unwrap();
    assert_eq!(t.meta.identity.domain.edge_length(), Some(0.6));
    let (code, text) = prt(&["info", out.to_str().unwrap()]);
    assert_eq!(code, 0, "{text}");
    let v = t.mesh().unwrap().vertex_count();
    assert!(text.contains(&format!("{v} vertices")), "{text}");
    // The bench holds the bake to the brute force from the scene's camera and from another.
    let mut errors = Vec::new();
    for view in [
        &[][..],
        &["--eye=-2,1.5,3", "--width", "40", "--height", "30"][..],
    ] {
        let bench = dir.join(format!("bench{}", errors.len()));
        let mut args = vec![
            "bench",
            out.to_str().unwrap(),
            "--env",
            "sun:30,40",
            "--out",
            bench.to_str().unwrap(),
            "--terms",
            "20",
            "--sh-orders",
            "1",
            "--sh-light-orders",
            "none",
            "--reference",
        ];
        args.extend(view);
        let (code, text) = prt(&args);
        assert_eq!(code, 0, "{text}");
        let summary = std::fs::read_to_string(bench.join("summary.md")).unwrap();
        let line = summary
            .lines()
            .find(|l| l.contains("against the brute-force reference"))
            .unwrap_or_else(|| panic!("{summary}"))
            .to_string();
        errors.push(line);
    }
    assert_ne!(errors[0], errors[1], "the camera made no difference");
    // The edge length is for per-vertex bakes only.
    let (code, text) = prt(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--edge-length",
        "0.3",
    ]);
    assert_ne!(code, 0);
    assert!(text.contains("--per-vertex"), "{text}");
}

/// A per-vertex bake of the sphere on the ground, relit under sunrise with every term: the
/// transport and its vertex colours.
fn relit_sphere(name: &str, edge: f32) -> (Transport, Vec<[f32; 3]>) {
    let scene = scene_from(SPHERE_ON_PLANE, name);
    let t = bake(&scene, &per_vertex(edge), &|_| {}).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let image = relit(
        &t,
        &env,
        EnvRotation::default(),
        RelightRequest::Wavelet {
            k: 100,
            weighting: Weighting::Transport,
        },
    );
    let colours = wavelet_prt::draw::vertex::vertex_colours(&t, &image)
        .unwrap()
        .to_vec();
    (t, colours)
}

#[test]
fn the_orbit_moves_the_image_but_not_the_vertex_colours() {
    use wavelet_prt::draw::vertex::{bake_camera, draw, orbit};
    let (t, colours) = relit_sphere("per-vertex-orbit", 0.3);
    let camera = bake_camera(&t).unwrap();
    assert_eq!((camera.width, camera.height), (37, 21));
    let front = draw(&t, &colours, &camera, None, 1).unwrap();
    let side = draw(&t, &colours, &orbit(&camera, 90.0, 0.0), None, 1).unwrap();
    // The colours are the relight's, whatever the camera: drawn again from the front after the
    // turn, the image is the same.
    let again = draw(&t, &colours, &camera, None, 1).unwrap();
    assert_eq!(front, again);
    let moved = front
        .image
        .pixels
        .iter()
        .zip(&side.image.pixels)
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        moved > front.image.pixels.len() / 4,
        "{moved} pixels changed"
    );
    // Every drawn pixel lies within the range of the vertex colours (Gouraud interpolates).
    let hi = colours.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
    for (p, c) in side.image.pixels.iter().zip(&side.coverage) {
        assert!(
            p.iter()
                .all(|&v| v >= 0.0 && v <= hi * (1.0 + INTERPOLATION_OVERSHOOT)),
            "{p:?}"
        );
        assert!(*c == 0.0 || *c == 1.0);
    }
}

#[test]
fn a_flat_lit_per_vertex_bake_draws_its_one_colour_everywhere_it_covers() {
    // Unshadowed, under constant light, every up-facing vertex of a plane has albedo x L.
    let scene = scene_from(
        &common::plane_from_above(16, 16, [0.5, 0.25, 0.125], 1.0),
        "per-vertex-flat",
    );
    let settings = BakeSettings {
        unshadowed: true,
        ..per_vertex(0.4)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let env = EnvMap::constant(64, 32, [2.0, 2.0, 2.0]);
    let image = relit(&t, &env, EnvRotation::default(), RelightRequest::Full);
    let colours = wavelet_prt::draw::vertex::vertex_colours(&t, &image).unwrap();
    let camera = wavelet_prt::draw::vertex::bake_camera(&t).unwrap();
    let drawn = wavelet_prt::draw::vertex::draw(&t, colours, &camera, None, 1).unwrap();
    // albedo x L, within the cosine's discretisation over the texels of a 6x8² cube (0.52%).
    let want = [1.0f32, 0.5, 0.25];
    let mesh = t.mesh().unwrap();
    for (c, n) in colours.iter().zip(&mesh.normals) {
        if n.y > 0.0 {
            for k in 0..3 {
                assert!(
                    (c[k] - want[k]).abs() < COSINE_DISCRETISATION * want[k],
                    "{c:?}"
                );
            }
        }
    }
    // The camera looks down on the plane's top: the drawn pixels are the top's colours, exactly
    // interpolated between equal values.
    let covered = drawn.coverage.iter().filter(|&&c| c == 1.0).count();
    assert_eq!(covered, 16 * 16);
    let top = colours[mesh.normals.iter().position(|n| n.y > 0.0).unwrap()];
    for p in &drawn.image.pixels {
        for k in 0..3 {
            assert!(
                (p[k] - top[k]).abs() <= EQUAL_VALUES_INTERPOLATED * top[k],
                "{p:?} against {top:?}"
            );
        }
    }
}

#[test]
fn the_gpu_draws_a_per_vertex_bake_as_the_cpu_does() {
    use wavelet_prt::draw::gpu::{GpuMesh, GpuRaster, upload_colours};
    use wavelet_prt::draw::vertex::{bake_camera, orbit};
    let Some(gpu) = common::gpu_or_skip("the_gpu_draws_a_per_vertex_bake_as_the_cpu_does") else {
        return;
    };
    let (t, colours) = relit_sphere("per-vertex-gpu", 0.3);
    let mesh = t.mesh().unwrap();
    let g = GpuMesh::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let c = upload_colours(&gpu, &colours).unwrap();
    let mut raster = GpuRaster::new(&gpu).unwrap();
    for az in [0.0, 135.0] {
        let mut camera = orbit(&bake_camera(&t).unwrap(), az, 10.0);
        (camera.width, camera.height) = (96, 64);
        let cpu = wavelet_prt::draw::raster::rasterize(
            &camera,
            &mesh.positions,
            &mesh.triangles,
            &colours,
        )
        .unwrap();
        let gpu_drawn = raster.draw(&gpu, &camera, &g, &c).unwrap();
        let hi = colours.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
        let differ = (0..cpu.coverage.len())
            .filter(|&i| {
                cpu.coverage[i] != gpu_drawn.coverage[i]
                    || (0..3).any(|k| {
                        (cpu.image.pixels[i][k] - gpu_drawn.image.pixels[i][k]).abs()
                            > GPU_RASTER_OF_BRIGHTEST * hi
                    })
            })
            .count();
        // Silhouette pixels where the two pick different surfaces at a tie, at most.
        assert!(
            differ <= cpu.coverage.len() / 200,
            "{differ} pixels differ at {az}°"
        );
    }
}

/// A closed OBJ without normals: a UV sphere (radius 0.6 about (0, 0.6, 0)) or a torus (radii
/// 0.5 and 0.2 about (0, 0.2, 0)), its faces wound outward, or inward with `inward`.
fn closed_obj(torus: bool, inward: bool) -> String {
    let (rings, segments) = (24usize, 48usize);
    let mut text = String::new();
    for i in 0..=rings {
        for j in 0..segments {
            let (u, v) = (
                j as f32 / segments as f32 * std::f32::consts::TAU,
                i as f32 / rings as f32,
            );
            let p = if torus {
                let a = v * std::f32::consts::TAU;
                let r = 0.5 + 0.2 * a.cos();
                [r * u.cos(), 0.2 + 0.2 * a.sin(), r * u.sin()]
            } else {
                let a = v * std::f32::consts::PI;
                let ring = if i == 0 || i == rings {
                    0.0
                } else {
                    0.6 * a.sin()
                };
                let y = if i == rings { 0.0 } else { 0.6 + 0.6 * a.cos() };
                [ring * u.cos(), y, ring * u.sin()]
            };
            text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
    }
    let at = |i: usize, j: usize| {
        let i = if torus { i % rings } else { i };
        1 + i * segments + j % segments
    };
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
            // Seen from outside, (a, d, c) and (a, c, b) run counter-clockwise on the torus (its
            // rings turn upward on the outside) and clockwise on the sphere (downward).
            for (k, [x, y, z]) in [[a, d, c], [a, c, b]].into_iter().enumerate() {
                // The sphere's poles: one triangle per quad.
                if !torus && ((i == 0 && k == 1) || (i + 1 == rings && k == 0)) {
                    continue;
                }
                text += &if inward != torus {
                    format!("f {x} {y} {z}\n")
                } else {
                    format!("f {x} {z} {y}\n")
                };
            }
        }
    }
    text
}

#[test]
fn closed_meshes_wound_inward_are_turned_outward_and_bake_as_the_per_pixel_view() {
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let full = RelightRequest::Full;
    for torus in [false, true] {
        let mut images = Vec::new();
        for inward in [false, true] {
            let dir = temp_dir(&format!("per-vertex-wound-{torus}-{inward}"));
            std::fs::write(dir.join("shape.obj"), closed_obj(torus, inward)).unwrap();
            let text = SPHERE_ON_PLANE.replace(
                "type = \"sphere\"\ncenter = [0.0, 0.6, 0.0]\nradius = 0.6",
                "type = \"mesh\"\npath = \"shape.obj\"",
            );
            std::fs::write(dir.join("scene.toml"), &text).unwrap();
            let scene = wavelet_prt::scene::Scene::load(&dir.join("scene.toml")).unwrap();
            let found = wavelet_prt::scene::tessellate::inward_surfaces(&scene);
            assert_eq!(
                found,
                if inward {
                    vec!["shape[1] (shape.obj)"]
                } else {
                    vec![]
                }
            );
            let lit = |settings: &BakeSettings| {
                let t = bake(&scene, settings, &|_| {}).unwrap();
                let ctx = LightContext::new(&t).unwrap();
                let light = ctx.prepare(&env, EnvRotation::default()).unwrap();
                let (image, _) = relight(&t, &ctx, &light, &full).unwrap();
                (t, image)
            };
            let (t, vertices) = lit(&per_vertex(0.1));
            let colours = wavelet_prt::draw::vertex::vertex_colours(&t, &vertices).unwrap();
            let camera = wavelet_prt::draw::vertex::bake_camera(&t).unwrap();
            let drawn = wavelet_prt::draw::vertex::draw(&t, colours, &camera, None, 1).unwrap();
            let (pixel, per_pixel) = lit(&BakeSettings {
                cube_n: 8,
                sh_order: 2,
                lossless: true,
                ..BakeSettings::default()
            });
            let e = wavelet_prt::output::metrics::relative_l2(
                &drawn.image,
                &per_pixel,
                Some(&pixel.coverage),
            )
            .unwrap();
            // Measured 12.6% (sphere) and 15.0% (torus) either way: the 37 x 21 image's
            // silhouettes and the interpolation between vertices. Baked for its inner side, the
            // mesh would be black: 100%.
            assert!(
                e < VERTEX_VS_PIXEL_MESH,
                "torus {torus}, inward {inward}: {e:e}"
            );
            images.push(drawn.image);
        }
        // Turned outward, the inward mesh bakes as the outward one.
        let e = wavelet_prt::output::metrics::relative_l2(&images[1], &images[0], None).unwrap();
        assert!(
            e < GPU_MATCH,
            "torus {torus}: {e:e} between the two windings"
        );
    }
}

/// Vertices next to one another in the bake's order see nearly the same light, so the 8-row
/// strips their rows are stored in are mostly entries: with the two sides of the open ground
/// interleaved at the same points, as the vertices once were, half the strips' values were
/// zeros.
#[test]
fn per_vertex_rows_fill_their_strips() {
    let scene = scene_from(SPHERE_ON_PLANE, "per-vertex-strip-fill");
    let t = bake(&scene, &per_vertex(0.2), &|_| {}).unwrap();
    let values = t.strips.strip_count() * wavelet_prt::store::transport::strips::STRIP_ROWS;
    let fill = t.nonzeros() as f64 / values as f64;
    assert!(t.nonzeros() > 100_000, "{} entries", t.nonzeros());
    assert!(fill > FILL_AT_LEAST, "strips {:.1}% full", 100.0 * fill);
}

/// The least fraction of strip values that are entries in a per-vertex bake of
/// [`SPHERE_ON_PLANE`] at edges of 0.2: 93.8% with the vertices ordered by their normals' cell,
/// 50.0% with the two sides of the ground interleaved.
const FILL_AT_LEAST: f64 = 0.8;
