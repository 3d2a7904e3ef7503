//! Per-vertex bakes of textured glTF scenes: the vertices hold a white surface's light and the
//! raster multiplies it per pixel by each material's mip-mapped albedo map. The checker shows at
//! the texels' places from a camera the bake never saw, on a tessellation far coarser than the
//! texture; the drawn image matches the per-pixel reference from that camera; the GPU draws what
//! the CPU draws, minified as well as magnified; the maps survive the file and bad ones are
//! refused.

mod common;

use common::gltf::{checker_texel, test_scene};
use common::{StFile, assets, gpu_or_skip, temp_dir};
use glam::Vec3;
use wavelet_prt::bake::reference::render_reference_with;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::draw::raster::{DrawOptions, rasterize, rasterize_with};
use wavelet_prt::draw::shading::Texturing;
use wavelet_prt::draw::vertex::{bake_camera, draw, orbit, vertex_colours};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::math::cubemap::CubeMap;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::relight_wavelet;
use wavelet_prt::scene::texture::srgb_to_linear;
use wavelet_prt::scene::{Camera, Framing, Scene};
use wavelet_prt::store::transport::{BakeDomain, Transport};

/// A drawn pixel inside a checker texel against the vertex colour times the texel's albedo: the
/// albedo map holds the texel as a sixteen-bit fraction, within half a step (7.6e-6) of it ...
const TEXEL_QUANTUM: f32 = 0.5 / 65535.0;
/// ... and the equal vertex colours interpolate to themselves up to f32 rounding, relative.
const TEXEL_DRAWN: f32 = 1e-5;
/// The per-vertex bake drawn from a new camera against the per-pixel reference from there, on
/// pixels away from silhouettes and material edges ([`interior`]), with the texture magnified
/// (about 8 pixels a texel): the light interpolated between vertices 0.25 apart across the box's
/// shadow, and one bilinear read a pixel against the reference's 4 sub-samples. Measured 4.2%.
const VERTEX_VS_REFERENCE_MAGNIFIED: f64 = 0.05;
/// The same with the texture minified (a texel or more a pixel): the mip levels' trilinear
/// filter is wider than the reference's 4 sub-samples over the pixel, which matters most on a
/// checker, and at this low camera the footprint is long and thin while the level of detail
/// follows its long side. Measured 12.8%.
const VERTEX_VS_REFERENCE_MINIFIED: f64 = 0.15;
/// The same drawing without the albedo maps (the vertices' white light) against the reference:
/// measured 80%; anything this far off shows that the comparison sees the texture.
const UNTEXTURED_OFF: f64 = 0.3;
/// A distant checker drawn with its mip levels against the 64-sample reference, as a fraction of
/// the same drawn from level 0 alone, whose one sample a pixel aliases: measured 0.12 (2.4%
/// against 21.2%).
const MIP_VS_ALIASED: f64 = 0.3;
/// A GPU pixel against the CPU's, relative to the brightest: the two read the same texels with
/// the same weights, from texture coordinates interpolated in f32 (GPU) and f64 (CPU), whose
/// differences move the bilinear weights by about 1e-6 of a texel.
const GPU_TEXTURED_OF_BRIGHTEST: f32 = 1e-3;

fn per_vertex(edge: f32, unshadowed: bool) -> BakeSettings {
    BakeSettings {
        cube_n: 8,
        sh_order: 2,
        lossless: true,
        unshadowed,
        domain: BakeDomain::Vertices { edge_length: edge },
        ..BakeSettings::default()
    }
}

/// The test scene (a ground with a `side`-texel checker, a grey box) from its glTF file.
fn checker_scene(name: &str, side: u32, nearest: bool) -> Scene {
    let dir = temp_dir(name);
    let path = test_scene(side, nearest).write_glb(&dir, "scene");
    Scene::load_with(
        &path,
        &Framing {
            camera: None,
            width: Some(96),
            height: None,
            ..Framing::default()
        },
    )
    .unwrap()
}

/// The bake's camera turned `az` degrees and raised `el`, at `distance` times its distance,
/// drawing `width` x `height`.
fn new_camera(t: &Transport, az: f32, el: f32, distance: f32, width: u32, height: u32) -> Camera {
    let mut c = orbit(&bake_camera(t).unwrap(), az, el);
    c.eye = c.target + (c.eye - c.target) * distance;
    (c.width, c.height) = (width, height);
    c
}

/// Pixels away from every edge: the pixel and its eight neighbours see, through their centres,
/// the same material (no silhouette, no material edge), where a raster's one sample and the
/// reference's sub-samples mean the same.
fn interior(scene: &Scene, cam: &Camera) -> Vec<f32> {
    let tracer = wavelet_prt::scene::trace::Tracer::new(scene);
    let (w, h) = (cam.width as usize, cam.height as usize);
    let ids: Vec<i64> = (0..w * h)
        .map(|i| {
            let ray = cam.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            tracer
                .closest_hit(ray.origin, ray.dir, f32::INFINITY)
                .map_or(-1, |hit| hit.material as i64)
        })
        .collect();
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let same = (-1..=1).all(|dy| {
                (-1..=1).all(|dx| {
                    let (u, v) = (x + dx, y + dy);
                    u >= 0
                        && v >= 0
                        && (u as usize) < w
                        && (v as usize) < h
                        && ids[v as usize * w + u as usize] == ids[i]
                })
            });
            (same && ids[i] >= 0) as u8 as f32
        })
        .collect()
}

#[test]
fn a_coarse_per_vertex_bake_shows_the_checker_where_a_new_camera_sees_it() {
    let side = 8u32;
    let scene = checker_scene("vertex-texture-checker", side, true);
    // Edges up to 2: the 4 x 4 ground is a few triangles, each over many of the 0.5-wide
    // texels.
    let t = bake(&scene, &per_vertex(2.0, true), &|_| {}).unwrap();
    let mesh = t.mesh().unwrap();
    assert_eq!(
        mesh.albedo_maps.len(),
        1,
        "the checker's map, not the box's"
    );
    assert!(
        mesh.vertex_count() < 100,
        "{} vertices",
        mesh.vertex_count()
    );
    let cube = CubeMap::constant(8, [1.0; 3]).unwrap();
    let (img, _) = relight_wavelet(&t, &common::full_light(&cube)).unwrap();
    let colours = vertex_colours(&t, &img).unwrap();
    // Unshadowed under a white sky every upward ground vertex holds the same white light.
    let up: Vec<[f32; 3]> = (0..mesh.vertex_count())
        .filter(|&v| mesh.is_textured(v) && mesh.normals[v].y > 0.5)
        .map(|v| colours[v])
        .collect();
    assert!(up.len() >= 4);
    let white = up[0];
    assert!(up.iter().all(|c| c == &white), "{up:?}");
    assert!((white[0] - 1.0).abs() < 0.01, "{white:?}");
    let cam = new_camera(&t, 35.0, 10.0, 1.0, 160, 120);
    let drawn = draw(&t, colours, &cam, None, 1).unwrap();
    let tracer = wavelet_prt::scene::trace::Tracer::new(&scene);
    let texel = 4.0 / side as f32;
    let (mut checked, mut light, mut dark) = (0, 0, 0);
    for ty in 0..side {
        for tx in 0..side {
            let centre = Vec3::new(
                -2.0 + (tx as f32 + 0.5) * texel,
                0.0,
                -2.0 + (ty as f32 + 0.5) * texel,
            );
            let Some((px, py)) = cam.project(centre) else {
                continue;
            };
            let (x, y) = (px.floor() as usize, py.floor() as usize);
            if x >= drawn.image.width || y >= drawn.image.height {
                continue;
            }
            let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
                continue;
            };
            let p = hit.point;
            if p.y.abs() > 1e-4
                || ((p.x + 2.0) / texel).floor() as u32 != tx
                || ((p.z + 2.0) / texel).floor() as u32 != ty
            {
                continue;
            }
            let albedo =
                checker_texel(side, tx, ty).map(|c| 0.96 * srgb_to_linear(c as f32 / 255.0));
            let got = drawn.image.pixels[y * drawn.image.width + x];
            for k in 0..3 {
                let want = white[k] * albedo[k];
                assert!(
                    (got[k] - want).abs() <= white[k] * TEXEL_QUANTUM + TEXEL_DRAWN * want,
                    "texel ({tx}, {ty}) at pixel ({x}, {y}), channel {k}: {} against {want}",
                    got[k]
                );
            }
            if (tx + ty) % 2 == 1 {
                light += 1
            } else {
                dark += 1
            }
            checked += 1;
        }
    }
    assert!(
        checked >= 30 && light >= 10 && dark >= 10,
        "{checked} texels ({light} light, {dark} dark)"
    );
}

#[test]
fn a_per_vertex_bake_drawn_from_a_new_camera_matches_the_per_pixel_reference() {
    let scene = checker_scene("vertex-texture-reference", 32, false);
    let settings = per_vertex(0.25, false);
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let cube = env.to_cube(8, EnvRotation::yaw(75.0)).unwrap();
    let (img, _) = relight_wavelet(&t, &common::full_light(&cube)).unwrap();
    let colours = vertex_colours(&t, &img).unwrap();
    let mut worst = 0.0f64;
    for (az, el, d, w, bound) in [
        (40.0, 15.0, 1.0, 384, VERTEX_VS_REFERENCE_MAGNIFIED),
        (-70.0, -5.0, 1.6, 96, VERTEX_VS_REFERENCE_MINIFIED),
    ] {
        let cam = new_camera(&t, az, el, d, w, w * 2 / 3);
        let drawn = draw(&t, colours, &cam, None, 1).unwrap();
        // The per-pixel reference from the same camera, of what a per-vertex bake holds (the
        // diffuse base of every material).
        let mut seen = scene.with_diffuse_materials();
        seen.camera = cam.clone();
        let pixel_settings = BakeSettings {
            spp: 4,
            domain: BakeDomain::View,
            ..settings.clone()
        };
        let reference = render_reference_with(&seen, &cube, &pixel_settings, &|_, _| {}).unwrap();
        let both = interior(&seen, &cam);
        let err = relative_l2(&drawn.image, &reference.image, Some(&both)).unwrap();
        eprintln!("azimuth {az}, elevation {el}, distance {d}, {w} wide: {err:.4}");
        assert!(err < bound, "{err} from ({az}, {el}, {d})");
        worst = worst.max(err);
        // Without the maps the same vertices draw far off.
        let mesh = t.mesh().unwrap();
        let white = rasterize(&cam, &mesh.positions, &mesh.triangles, colours).unwrap();
        let off = relative_l2(&white.image, &reference.image, Some(&both)).unwrap();
        assert!(off > UNTEXTURED_OFF, "untextured only {off} off");
    }
    eprintln!("worst {worst:.4}");
}

#[test]
fn mip_levels_keep_a_distant_texture_from_aliasing() {
    // 64 texels over the ground seen from high above and far off at 40 x 30: several texels a
    // pixel.
    let scene = checker_scene("vertex-texture-mip", 64, false);
    let settings = per_vertex(0.5, true);
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let cube = CubeMap::constant(8, [1.0; 3]).unwrap();
    let (img, _) = relight_wavelet(&t, &common::full_light(&cube)).unwrap();
    let colours = vertex_colours(&t, &img).unwrap();
    let mesh = t.mesh().unwrap();
    let cam = new_camera(&t, 10.0, 30.0, 2.5, 40, 30);
    let mut seen = scene.with_diffuse_materials();
    seen.camera = cam.clone();
    let pixel_settings = BakeSettings {
        spp: 64,
        domain: BakeDomain::View,
        ..settings.clone()
    };
    let reference = render_reference_with(&seen, &cube, &pixel_settings, &|_, _| {}).unwrap();
    let inside = interior(&seen, &cam);
    let mipped = Texturing::of(mesh).unwrap();
    // The same maps with only their first level: every pixel reads one bilinear sample.
    let mut first_only = mesh.albedo_maps.clone();
    for m in &mut first_only {
        m.levels.truncate(1);
    }
    let flat = Texturing {
        maps: &first_only,
        ..mipped.clone()
    };
    let draw_with = |t: &Texturing| {
        let options = DrawOptions {
            texturing: Some(t),
            ..DrawOptions::samples(1)
        };
        rasterize_with(&cam, &mesh.positions, &mesh.triangles, colours, options).unwrap()
    };
    let with_mips =
        relative_l2(&draw_with(&mipped).image, &reference.image, Some(&inside)).unwrap();
    let aliased = relative_l2(&draw_with(&flat).image, &reference.image, Some(&inside)).unwrap();
    eprintln!("with mip levels {with_mips:.4}, level 0 only {aliased:.4}");
    assert!(
        with_mips < MIP_VS_ALIASED * aliased,
        "mip levels {with_mips} against level 0 only {aliased}"
    );
}

#[test]
fn the_gpu_draws_textured_vertices_as_the_cpu_does() {
    use wavelet_prt::draw::gpu::{GpuMesh, GpuRaster, upload_colours};
    let Some(gpu) = gpu_or_skip("the_gpu_draws_textured_vertices_as_the_cpu_does") else {
        return;
    };
    // 64 texels over the ground: magnified near, minified (levels 1 to 4) far and small.
    let scene = checker_scene("vertex-texture-gpu", 64, false);
    let t = bake(&scene, &per_vertex(0.5, false), &|_| {}).unwrap();
    let mesh = t.mesh().unwrap();
    let cube = CubeMap::constant(8, [1.0; 3]).unwrap();
    let (img, _) = relight_wavelet(&t, &common::full_light(&cube)).unwrap();
    let colours = vertex_colours(&t, &img).unwrap();
    let texturing = Texturing::of(mesh).unwrap();
    let g = GpuMesh::textured(&gpu, &mesh.positions, &mesh.triangles, Some(&texturing)).unwrap();
    let c = upload_colours(&gpu, colours).unwrap();
    // The last camera also with 4 samples a pixel, each sample's texture derivatives taken
    // from the same sample of its quad.
    for (az, d, w, h, samples) in [
        (20.0, 0.5, 128, 96, 1),
        (-50.0, 1.0, 96, 64, 1),
        (130.0, 3.0, 40, 30, 1),
        (-50.0, 1.0, 96, 64, 4),
    ] {
        let mut raster = GpuRaster::multisampled(&gpu, samples).unwrap();
        let cam = new_camera(&t, az, 5.0, d, w, h);
        let options = DrawOptions {
            texturing: Some(&texturing),
            ..DrawOptions::samples(samples)
        };
        let cpu = rasterize_with(&cam, &mesh.positions, &mesh.triangles, colours, options).unwrap();
        let dev = raster.draw(&gpu, &cam, &g, &c).unwrap();
        let hi = cpu
            .image
            .pixels
            .iter()
            .flatten()
            .fold(0.0f32, |a, &b| a.max(b));
        let differ = (0..cpu.coverage.len())
            .filter(|&i| {
                cpu.coverage[i] != dev.coverage[i]
                    || (0..3).any(|k| {
                        (cpu.image.pixels[i][k] - dev.image.pixels[i][k]).abs()
                            > GPU_TEXTURED_OF_BRIGHTEST * hi
                    })
            })
            .count();
        eprintln!(
            "{az}°, distance {d}, {samples} sample(s): {differ} of {} pixels differ",
            cpu.coverage.len()
        );
        assert!(
            differ <= cpu.coverage.len() / 100,
            "{differ} pixels differ at {az}°, distance {d}"
        );
        // The texture shows: the drawn ground is not the flat vertex colours.
        let flat = rasterize(&cam, &mesh.positions, &mesh.triangles, colours).unwrap();
        assert!(relative_l2(&dev.image, &flat.image, None).unwrap() > 0.1);
    }
}

#[test]
fn materials_with_the_same_map_share_it() {
    // The box takes a copy of the checker's material: two materials, one map.
    let dir = temp_dir("vertex-texture-shared");
    let mut b = test_scene(8, false);
    let checker = b.json["materials"][0].clone();
    b.json["materials"][1] = checker;
    let path = b.write_glb(&dir, "shared");
    let scene = Scene::load_with(&path, &Framing::default()).unwrap();
    assert_eq!(scene.material_maps.iter().flatten().count(), 2);
    let mesh = wavelet_prt::scene::tessellate::VertexMesh::tessellate(&scene, 1.0).unwrap();
    assert_eq!(mesh.albedo_maps.len(), 1);
    let mut owners = mesh.albedo_maps[0].materials.clone();
    owners.sort();
    assert_eq!(owners, [0, 1]);
    let slots = mesh.map_slots();
    assert!(mesh.materials.iter().all(|&m| slots[m as usize] == Some(0)));
}

#[test]
fn albedo_maps_survive_the_file_and_bad_ones_are_refused() {
    let scene = checker_scene("vertex-texture-file", 8, false);
    let t = bake(&scene, &per_vertex(1.0, true), &|_| {}).unwrap();
    let dir = temp_dir("vertex-texture-file-out");
    let path = dir.join("v.prt");
    t.save(&path).unwrap();
    let back = Transport::load(&path).unwrap();
    assert_eq!(back.attached.domain, t.attached.domain);
    assert_eq!(back.meta.per_vertex.as_ref().unwrap().albedo_maps, 1);
    let mesh = back.mesh().unwrap();
    assert_eq!(
        mesh.albedo_maps[0].levels.len(),
        4,
        "8, 4, 2 and 1 texels a side"
    );
    for (tensor, edit, want) in [
        // A wrap code past clamp.
        ("albedo_map", 2 * 4, "albedo_map[0]: wrap codes"),
        // A width past the texels stored.
        ("albedo_map", 0, "albedo_map[0]: 72 texels past"),
        // A material's map past the maps.
        (
            "albedo_map_material",
            4,
            "albedo_map_material[0]: map 9 of 1",
        ),
    ] {
        let mut st = StFile::read(&path);
        st.tensor_mut(tensor)[edit..edit + 4].copy_from_slice(&9u32.to_le_bytes());
        let bad = dir.join("bad.prt");
        st.write(&bad, true);
        let e = Transport::load(&bad).unwrap_err().to_string();
        assert!(e.contains(want), "{e}");
    }
    let mut st = StFile::read(&path);
    st.tensor_mut("mesh_uv")[..4].copy_from_slice(&f32::NAN.to_le_bytes());
    let bad = dir.join("nan.prt");
    st.write(&bad, true);
    let e = Transport::load(&bad).unwrap_err().to_string();
    assert!(e.contains("NaN") || e.contains("texture coordinate"), "{e}");
}
