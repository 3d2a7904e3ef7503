//! glTF 2.0 scenes: files the tests write (a checker-textured ground, a box under a transformed
//! parent, a camera) baked directly and held to the brute-force reference, the checker found
//! where its UVs, sampler and top-left origin put it, node transforms against a hand-built TOML
//! scene, `.glb` against `.gltf`, the material mapping, lights, and bad files.

mod common;

use common::gltf::{GltfBuilder, checker_texel, cube_faces, test_scene, with_metal};
use common::{assets, full_light, temp_dir};
use glam::{Vec2, Vec3};
use serde_json::json;
use wavelet_prt::bake::reference::render_reference;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::math::cubemap::CubeMap;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::relight_wavelet;
use wavelet_prt::scene::texture::srgb_to_linear;
use wavelet_prt::scene::{Framing, LightShape, Scene};

/// The brute-force reference and the relight of a lossless bake agree to float rounding.
const REFERENCE_MATCH: f64 = 1e-4;

fn framed(width: u32) -> Framing {
    Framing {
        camera: None,
        width: Some(width),
        height: None,
        ..Framing::default()
    }
}

fn lossless(n: usize) -> BakeSettings {
    BakeSettings {
        cube_n: n,
        sh_order: 2,
        lossless: true,
        ..BakeSettings::default()
    }
}

#[test]
fn a_written_gltf_bakes_and_matches_the_reference() {
    let dir = temp_dir("gltf-reference");
    let mut b = test_scene(16, false);
    with_metal(&mut b);
    let path = b.write_glb(&dir, "scene");
    let scene = Scene::load_with(&path, &framed(48)).unwrap();
    // The file's camera, at the width asked and its aspect ratio, looking down -Z of its node
    // with +Y of its node up.
    assert_eq!((scene.camera.width, scene.camera.height), (48, 32));
    let (forward, _, up) = scene.camera.frame();
    assert!((scene.camera.eye - Vec3::new(0.0, 4.0, 3.0)).length() < 1e-6);
    assert!(
        (forward - Vec3::new(0.0, -0.8, -0.6)).length() < 1e-5,
        "{forward}"
    );
    assert!((up - Vec3::new(0.0, 0.6, -0.8)).length() < 1e-5, "{up}");
    assert!(scene.is_textured());
    let settings = BakeSettings {
        spp: 4,
        ..lossless(8)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    // Where the box's shadow edge crosses texel edges inside a pixel, the texture's residual
    // rows (one colour channel each) are needed.
    let residual = t
        .row_weight
        .iter()
        .filter(|w| {
            let mut s = **w;
            s.sort_by(f32::total_cmp);
            s == [0.0, 0.0, 1.0]
        })
        .count();
    assert!(residual > 0, "no residual rows");
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let rotation = EnvRotation::new(75.0, 0.0);
    let cube = env.to_cube(8, rotation).unwrap();
    let (img, _) = relight_wavelet(&t, &full_light(&cube)).unwrap();
    let brute = render_reference(&scene, &cube, &settings).unwrap();
    let err = relative_l2(&img, &brute, None).unwrap();
    assert!(
        err < REFERENCE_MATCH,
        "lossless relight vs reference: {err}"
    );
    // The same bake with the texture's mean colour in place of the texture is far off: the
    // comparison sees the texture.
    let mut flat = scene.clone();
    flat.material_maps = vec![None; flat.materials.len()];
    let flat_ref = render_reference(&flat, &cube, &settings).unwrap();
    let off = relative_l2(&flat_ref, &brute, None).unwrap();
    assert!(off > 0.05, "the texture changes the image by only {off}");
}

#[test]
fn the_checker_shows_where_uvs_sampler_and_origin_put_it() {
    let side = 8u32;
    let dir = temp_dir("gltf-checker");
    let path = test_scene(side, true).write_glb(&dir, "checker");
    let scene = Scene::load_with(&path, &framed(120)).unwrap();
    let settings = BakeSettings {
        unshadowed: true,
        edge_spp: 0,
        ..lossless(4)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let cube = CubeMap::constant(4, [1.0; 3]).unwrap();
    let (img, _) = relight_wavelet(&t, &full_light(&cube)).unwrap();
    let tracer = wavelet_prt::scene::trace::Tracer::new(&scene);
    let mut checked = 0;
    for ty in 0..side {
        for tx in 0..side {
            // Texel (tx, ty) of the image covers u in [tx, tx + 1) / side, v likewise; the
            // ground's UVs put u along +x and v along +z from the corner (-2, 0, -2).
            let texel = 4.0 / side as f32;
            let centre = Vec3::new(
                -2.0 + (tx as f32 + 0.5) * texel,
                0.0,
                -2.0 + (ty as f32 + 0.5) * texel,
            );
            let Some((px, py)) = scene.camera.project(centre) else {
                continue;
            };
            let (x, y) = (px.floor() as usize, py.floor() as usize);
            if x >= img.width || y >= img.height {
                continue;
            }
            // Skip texels the box hides.
            let ray = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            let hit = tracer
                .closest_hit(ray.origin, ray.dir, f32::INFINITY)
                .unwrap();
            if hit.point.y.abs() > 1e-4 {
                continue;
            }
            // The pixel's centre lands in the same texel (the texel spans several pixels).
            let p = hit.point;
            let same = ((p.x + 2.0) / texel).floor() as u32 == tx
                && ((p.z + 2.0) / texel).floor() as u32 == ty;
            if !same {
                continue;
            }
            let want = checker_texel(side, tx, ty).map(|c| srgb_to_linear(c as f32 / 255.0));
            let got = img.pixels[y * img.width + x];
            // Under a white sky, unshadowed, the diffuse part is 0.96 · albedo; the dielectric
            // lobe adds at most its 0.04.
            for k in 0..3 {
                assert!(
                    got[k] >= 0.96 * want[k] - 1e-3 && got[k] <= 0.96 * want[k] + 0.04,
                    "texel ({tx}, {ty}) at pixel ({x}, {y}), channel {k}: {}, want about {}",
                    got[k],
                    0.96 * want[k]
                );
            }
            checked += 1;
        }
    }
    assert!(checked >= 30, "only {checked} texels checked");
}

#[test]
fn node_transforms_place_a_mesh_where_a_hand_built_toml_scene_does() {
    let dir = temp_dir("gltf-transform");
    // The test scene without its ground: the box under its rotated and scaled parent.
    let mut b = test_scene(4, false);
    b.set("scenes", json!([{"nodes": [1, 3]}]));
    let path = b.write_glb(&dir, "box");
    let from_gltf = Scene::load_with(&path, &framed(40)).unwrap();
    // The same box by hand: the parent turns local (x, y, z) into (0.5 z + 0.5, 0.5 y,
    // -0.5 x), the child lifts it by 0.5 first.
    let place = |p: [f32; 3]| [0.5 * p[2] + 0.5, 0.5 * (p[1] + 0.5), -0.5 * p[0]];
    let mut toml = String::new();
    let c = &from_gltf.camera;
    let v = |v: Vec3| format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z);
    toml += &format!(
        "[camera]\neye = {}\ntarget = {}\nup = {}\nfov_y_deg = {:?}\nwidth = {}\nheight = {}\n",
        v(c.eye),
        v(c.target),
        v(c.up),
        c.fov_y_deg,
        c.width,
        c.height
    );
    let wavelet_prt::scene::Material::Glossy {
        albedo,
        specular,
        roughness,
    } = from_gltf.materials[0]
    else {
        panic!("a dielectric glTF material is glossy");
    };
    toml += &format!(
        "[material.grey]\ntype = \"glossy\"\nalbedo = {}\nspecular = {}\nroughness = {roughness:?}\n",
        v(albedo),
        v(specular)
    );
    for face in cube_faces() {
        let corners: Vec<String> = face.iter().map(|p| v(Vec3::from(place(*p)))).collect();
        toml += &format!(
            "[[shape]]\ntype = \"quad\"\nmaterial = \"grey\"\ncorners = [{}]\n",
            corners.join(", ")
        );
    }
    let by_hand = Scene::from_toml_str(&toml, &dir.join("box.toml")).unwrap();
    assert_eq!(from_gltf.triangles.len(), 12);
    for (a, b) in from_gltf.triangles.iter().zip(&by_hand.triangles) {
        assert_eq!(a.vertices, b.vertices);
        assert_eq!(a.normals, b.normals);
    }
    let settings = BakeSettings {
        spp: 2,
        ..lossless(4)
    };
    let cube = CubeMap::constant(4, [0.7, 0.8, 0.9]).unwrap();
    let a = bake(&from_gltf, &settings, &|_| {}).unwrap();
    let b = bake(&by_hand, &settings, &|_| {}).unwrap();
    let (ia, _) = relight_wavelet(&a, &full_light(&cube)).unwrap();
    let (ib, _) = relight_wavelet(&b, &full_light(&cube)).unwrap();
    assert_eq!(
        ia, ib,
        "the glTF box and the hand-built one bake differently"
    );
    assert!(ia.pixels.iter().any(|p| p[0] > 0.0));
}

#[test]
fn glb_gltf_and_embedded_gltf_bake_bit_equal() {
    let dir = temp_dir("gltf-forms");
    let paths = [
        test_scene(8, false).write_glb(&dir, "s"),
        test_scene(8, false).write_gltf(&dir, "s"),
        test_scene(8, false).write_embedded(&dir, "embedded"),
    ];
    let settings = BakeSettings {
        spp: 2,
        ..lossless(4)
    };
    let cube = CubeMap::constant(4, [1.0; 3]).unwrap();
    let images: Vec<_> = paths
        .iter()
        .map(|p| {
            let scene = Scene::load_with(p, &framed(30)).unwrap();
            let t = bake(&scene, &settings, &|_| {}).unwrap();
            relight_wavelet(&t, &full_light(&cube)).unwrap().0
        })
        .collect();
    assert_eq!(images[0], images[1]);
    assert_eq!(images[0], images[2]);
    // The external form names its buffer and image as inputs (an output may not overwrite them).
    let external = Scene::load(&paths[1]).unwrap();
    assert_eq!(external.input_files.len(), 3, "{:?}", external.input_files);
}

#[test]
fn base_colour_is_srgb_and_metallic_roughness_is_linear() {
    let dir = temp_dir("gltf-material");
    let mut b = GltfBuilder::default();
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
    ];
    let uvs = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let prim = b.primitive(&quad, [0.0, 1.0, 0.0], Some(&uvs), &[0, 2, 1, 0, 3, 2], 0);
    let png = |rgb: [u8; 3]| {
        let mut out = Vec::new();
        image::RgbImage::from_pixel(1, 1, image::Rgb(rgb))
            .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
            .unwrap();
        out
    };
    b.images.push((png([128, 128, 128]), "image/png".into()));
    b.images.push((png([0, 128, 255]), "image/png".into()));
    b.set("textures", json!([{"source": 0}, {"source": 1}]));
    b.set(
        "materials",
        json!([{"pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 1},
            "metallicFactor": 0.5, "roughnessFactor": 1.0}}]),
    );
    b.set("meshes", json!([{"primitives": [prim]}]));
    b.set("nodes", json!([{"mesh": 0}]));
    let path = b.write_glb(&dir, "material");
    let scene = Scene::load(&path).unwrap();
    let lobes = scene.lobes_at(0, Vec2::splat(0.5));
    // Base colour: sRGB 128 decodes to 0.2159; metallic = 0.5 · (255 / 255) read linearly from
    // blue, roughness = 1 · (128 / 255) from green.
    let base = srgb_to_linear(128.0 / 255.0);
    let (m, r) = (0.5f32, 128.0f32 / 255.0);
    assert!(
        (lobes.albedo.x - 0.96 * (1.0 - m) * base).abs() < 1e-6,
        "{lobes:?}"
    );
    assert!((lobes.specular.x - (0.04 * (1.0 - m) + m * base)).abs() < 1e-6);
    assert!((lobes.alpha - r * r).abs() < 1e-6);
    // No camera: one frames the geometry, at the default size.
    assert_eq!((scene.camera.width, scene.camera.height), (256, 256));
    assert!(scene.camera.eye.z > 1.0 && scene.camera.eye.y > 0.0);
}

/// The test scene with `lights` (KHR_lights_punctual), each placed by one of `nodes` (a node's
/// transform and its `light` index) beside the scene's own nodes 0, 1 and 3.
fn lit_scene(lights: serde_json::Value, nodes: &[serde_json::Value]) -> GltfBuilder {
    let mut b = test_scene(4, false);
    b.set("extensionsUsed", json!(["KHR_lights_punctual"]));
    b.set(
        "extensions",
        json!({"KHR_lights_punctual": {"lights": lights}}),
    );
    let mut all = b.json["nodes"].as_array().unwrap().clone();
    let mut shown = vec![0, 1, 3];
    for node in nodes {
        shown.push(all.len());
        all.push(node.clone());
    }
    b.set("nodes", json!(all));
    b.set("scenes", json!([{ "nodes": shown }]));
    b
}

#[test]
fn punctual_lights_become_local_lights() {
    let dir = temp_dir("gltf-lights");
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let light = |i: usize| json!({"KHR_lights_punctual": {"light": i}});
    let b = lit_scene(
        json!([
            {"name": "lamp", "type": "point", "intensity": 683.0, "color": [1.0, 0.5, 0.25]},
            {"name": "sun light", "type": "directional", "intensity": 1366.0},
            {"type": "spot", "intensity": 68.3,
             "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}}
        ]),
        &[
            json!({"translation": [1.0, 2.0, 3.0], "extensions": light(0)}),
            json!({"extensions": light(1)}),
            json!({"translation": [0.0, 3.0, 0.0], "rotation": [-h, 0.0, 0.0, h],
                   "extensions": light(2)}),
        ],
    );
    let path = b.write_glb(&dir, "lit");
    let scene = Scene::load(&path).unwrap();
    let names: Vec<&str> = scene.lights.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["lamp", "sun_light", "light2"]);
    // 683 candela is one watt per steradian.
    assert!((scene.lights[0].intensity - 1.0).abs() < 1e-6);
    assert_eq!(scene.lights[0].positions, vec![Vec3::new(1.0, 2.0, 3.0)]);
    assert_eq!(scene.lights[0].color, Vec3::new(1.0, 0.5, 0.25));
    assert!(
        matches!(scene.lights[1].shape, LightShape::Directional { direction, .. }
        if (direction - Vec3::NEG_Z).length() < 1e-6)
    );
    // A spot turned -90° about X points down; its cone and falloff from the two angles.
    match &scene.lights[2].shape {
        LightShape::Spot {
            direction,
            cone,
            falloff,
        } => {
            assert!((*direction - Vec3::NEG_Y).length() < 1e-5, "{direction}");
            assert!((cone - 0.5).abs() < 1e-6 && (falloff - 0.3).abs() < 1e-6);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_punctual_light_past_the_intensity_range_is_refused() {
    let dir = temp_dir("gltf-bright");
    for (intensity, color) in [(1e20, 1.0), (683.0, -1.0)] {
        let b = lit_scene(
            json!([{"name": "lamp", "type": "point", "intensity": intensity,
                    "color": [color, 1.0, 1.0]}]),
            &[json!({"extensions": {"KHR_lights_punctual": {"light": 0}}})],
        );
        let path = b.write_glb(&dir, "bright");
        let e = Scene::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("lights[0]") && e.contains("must be in [0, 1e12]"),
            "{intensity} cd, red {color}: {e}"
        );
    }
}

#[test]
fn a_toml_scene_includes_a_gltf_file_beside_its_own_shapes() {
    let dir = temp_dir("gltf-include");
    test_scene(4, false).write_glb(&dir, "model");
    let toml = |extra: &str| {
        format!(
            "[camera]\neye = [0, 3, 6]\ntarget = [0, 0, 0]\nup = [0, 1, 0]\nfov_y_deg = 40\n\
             width = 16\nheight = 12\n[material.white]\ntype = \"diffuse\"\nalbedo = [0.8, 0.8, 0.8]\n\
             [[shape]]\ntype = \"sphere\"\nmaterial = \"white\"\ncenter = [0, 2, 0]\nradius = 0.3\n\
             [[shape]]\ntype = \"gltf\"\npath = \"model.glb\"\ntranslate = [0, 1, 0]\n{extra}"
        )
    };
    let p = dir.join("scene.toml");
    std::fs::write(&p, toml("")).unwrap();
    let scene = Scene::load(&p).unwrap();
    assert_eq!(scene.materials.len(), 3);
    assert_eq!(scene.material_names[1], "model.glb:checker");
    assert_eq!(scene.textures.len(), 1);
    // The ground moved up by the shape's translation.
    assert!(scene.triangles.iter().any(|t| t.vertices[0].y == 1.0));
    assert!(scene.input_files.iter().any(|f| f.ends_with("model.glb")));
    std::fs::write(&p, toml("material = \"white\"\n")).unwrap();
    let e = Scene::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("shape[1].material") && e.contains("does not apply to a gltf"),
        "{e}"
    );
    // A glTF's own camera is not a TOML scene's.
    let e = Scene::load_with(
        &dir.join("scene.toml"),
        &Framing {
            camera: Some("above".into()),
            ..Framing::default()
        },
    );
    assert!(e.is_err());
}

#[test]
fn a_gltf_whose_lights_take_a_scene_past_its_light_columns_is_refused() {
    let dir = temp_dir("gltf-columns");
    let b = lit_scene(
        json!([{"name": "lamp", "type": "point", "intensity": 683.0}]),
        &[json!({"extensions": {"KHR_lights_punctual": {"light": 0}}})],
    );
    b.write_glb(&dir, "lit");
    // A grid of 16³ places fills every column a scene may have; the glTF's lamp is one more.
    let scene = |counts: u32| {
        format!(
            "[camera]\neye = [0, 3, 6]\ntarget = [0, 0, 0]\nup = [0, 1, 0]\nfov_y_deg = 40\n\
             width = 16\nheight = 12\n\
             [[light]]\nname = \"swarm\"\ntype = \"point\"\nintensity = 1.0\n\
             grid = {{ from = [-1, 1, -1], to = [1, 2, 1], counts = [16, 16, {counts}] }}\n\
             [[shape]]\ntype = \"gltf\"\npath = \"lit.glb\"\n"
        )
    };
    let p = dir.join("scene.toml");
    std::fs::write(&p, scene(15)).unwrap();
    let lit = Scene::load(&p).unwrap();
    let columns: usize = lit.lights.iter().map(|l| l.columns()).sum();
    assert_eq!(columns, 16 * 16 * 15 + 1);
    std::fs::write(&p, scene(16)).unwrap();
    let e = Scene::load(&p).unwrap_err().to_string();
    assert!(
        e.contains("shape[0].path")
            && e.contains("its lights take the scene past 4096 light columns"),
        "{e}"
    );
}

/// A glTF of the test scene with its JSON changed by `edit`, written as `.gltf` with external
/// files; the error loading it.
fn error_of(name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let dir = temp_dir(&format!("gltf-bad-{name}"));
    let path = test_scene(4, false).write_gltf(&dir, "bad");
    let mut doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    edit(&mut doc);
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    Scene::load(&path).unwrap_err().to_string()
}

#[test]
fn bad_files_get_errors_naming_the_file_the_object_and_the_field() {
    type Edit = Box<dyn FnOnce(&mut serde_json::Value)>;
    let cases: Vec<(&str, Edit, &[&str])> = vec![
        (
            "count",
            Box::new(|d| d["accessors"][0]["count"] = json!(1_000_000)),
            &[
                "meshes[0].primitives[0].attributes.POSITION (accessor 0)",
                "run past",
            ],
        ),
        (
            "index",
            Box::new(|d| {
                let a = d["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
                // The six u16 indices read as three u32: the first is 2 << 16.
                d["accessors"][a]["componentType"] = json!(5125);
                d["accessors"][a]["count"] = json!(3);
            }),
            &["meshes[0].primitives[0].indices", "there are 4 vertices"],
        ),
        (
            "cycle",
            Box::new(|d| d["nodes"][2]["children"] = json!([1])),
            &["nodes[1]", "appears twice"],
        ),
        (
            "buffer",
            Box::new(|d| d["buffers"][0]["byteLength"] = json!(1 << 20)),
            &["buffers[0].byteLength", "declares 1048576 bytes"],
        ),
        (
            "view",
            Box::new(|d| d["bufferViews"][0]["byteOffset"] = json!(1 << 20)),
            &["bufferViews[0]", "run past the end of buffer 0"],
        ),
        (
            "missing",
            Box::new(|d| d["images"][0]["uri"] = json!("nowhere.png")),
            &["nowhere.png"],
        ),
        (
            "absolute",
            Box::new(|d| d["buffers"][0]["uri"] = json!("/etc/passwd")),
            &["buffers[0].uri", "only data URIs and paths relative"],
        ),
        (
            "extension",
            Box::new(|d| {
                d["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
                d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
            }),
            &["extensionsRequired", "KHR_draco_mesh_compression"],
        ),
        (
            "stride",
            Box::new(|d| d["bufferViews"][0]["byteStride"] = json!(4)),
            &["byteStride 4"],
        ),
        (
            "type",
            Box::new(|d| d["accessors"][0]["type"] = json!("VEC2")),
            &["POSITION (accessor 0)", "expected 3 components"],
        ),
        (
            "reference",
            Box::new(|d| d["meshes"][0]["primitives"][0]["material"] = json!(9)),
            &["bad.gltf", "not a usable glTF"],
        ),
        (
            "mime",
            Box::new(|d| {
                d["images"][0]["bufferView"] = json!(0);
            }),
            &["images[0]", "a bufferView needs a mimeType"],
        ),
        (
            "metallic",
            Box::new(|d| d["materials"][1]["pbrMetallicRoughness"]["metallicFactor"] = json!(2.0)),
            &["materials[1].pbrMetallicRoughness.metallicFactor"],
        ),
    ];
    for (name, edit, wanted) in cases {
        let e = error_of(name, edit);
        assert!(e.contains("bad"), "{name}: the file is not named: {e}");
        for w in wanted {
            assert!(e.contains(w), "{name}: `{w}` missing from: {e}");
        }
    }
    // A .glb whose header says it is shorter than its header.
    let dir = temp_dir("gltf-bad-header");
    let path = test_scene(4, false).write_glb(&dir, "short");
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[8..12].copy_from_slice(&4u32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(e.contains("short.glb") && e.contains("header"), "{e}");
    // A truncated .glb.
    let dir = temp_dir("gltf-bad-glb");
    let path = test_scene(4, false).write_glb(&dir, "cut");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(e.contains("cut.glb"), "{e}");
}

#[test]
fn normals_take_the_inverse_transpose_and_mirrors_keep_the_winding() {
    let dir = temp_dir("gltf-normals");
    let mut b = GltfBuilder::default();
    // One triangle in the plane x + y = 1 (normal (1, 1, 0) / √2), wound to face it.
    let tri = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 1.0]];
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let prim = b.primitive(&tri, [h, h, 0.0], None, &[0, 1, 2], 0);
    b.set(
        "materials",
        json!([{"pbrMetallicRoughness": {"metallicFactor": 0.0}}]),
    );
    b.set("meshes", json!([{"primitives": [prim]}]));
    // Stretched 2x along x; and mirrored in x.
    b.set(
        "nodes",
        json!([{"mesh": 0, "scale": [2.0, 1.0, 1.0]}, {"mesh": 0, "scale": [-1.0, 1.0, 1.0]}]),
    );
    let path = b.write_glb(&dir, "normals");
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.triangles.len(), 2);
    // Stretching x by 2 tilts the plane's normal towards y: (1/2, 1, 0), not (2, 1, 0).
    let want = Vec3::new(0.5, 1.0, 0.0).normalize();
    let t = &scene.triangles[0];
    for n in t.normals {
        assert!((n - want).length() < 1e-6, "{n}");
    }
    assert!((t.geometric_normal() - want).length() < 1e-6);
    // The mirror image faces (-1, 1, 0), and its winding still faces the way its normals do.
    let m = &scene.triangles[1];
    let want = Vec3::new(-1.0, 1.0, 0.0).normalize();
    for n in m.normals {
        assert!((n - want).length() < 1e-6, "{n}");
    }
    assert!(
        (m.geometric_normal() - want).length() < 1e-6,
        "{}",
        m.geometric_normal()
    );
}
