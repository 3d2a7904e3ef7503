//! The vertex rows' fast cases against the general row they stand for, and the kept walks
//! against walking again.

use std::path::Path;

use super::*;
use crate::bake::{
    EdgeMap, medium_light::MediumLight, path_stream, pixel_subsamples, sample_stride,
};

/// The Lambertian fast case sums `n·(ω Ω)` where the row sums `(n·ω) Ω`: a few f32 ulps of a
/// row's largest value.
const LAMBERT_REASSOCIATED: f32 = 1e-5;

/// The glossy sphere on its matte ground (the scene in the assets) at 32 x 32 pixels, under a
/// cloud when `cloud`.
fn scene(cloud: bool) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/glossy_sphere.toml");
    let mut text = std::fs::read_to_string(&path).unwrap();
    if cloud {
        text += "[medium]\ntype = \"cloud\"\nbounds = [[-1.0, 0.8, -1.0], [1.0, 1.6, 1.0]]\n\
                 resolution = 8\nextinction = 3.0\nalbedo = [0.9, 0.9, 0.9]\ng = 0.3\n\
                 center = [0.0, 1.2, 0.0]\nradii = [0.9, 0.3, 0.9]\n";
    }
    let mut scene = Scene::from_toml_str(&text, &path).unwrap();
    (scene.camera.width, scene.camera.height) = (32, 32);
    scene
}

/// What the paths of [`scene`] need, at N = 8 with two bounces of eight paths.
struct Fixture {
    scene: Scene,
    tracer: Tracer,
    settings: BakeSettings,
    samples: TexelSamples,
    medium: Option<Medium>,
    light: Option<MediumLight>,
    edges: EdgeMap,
}

impl Fixture {
    fn new(cloud: bool) -> Fixture {
        let scene = scene(cloud);
        let tracer = Tracer::new(&scene);
        let settings = BakeSettings {
            cube_n: 8,
            bounces: 2,
            paths: 8,
            ..BakeSettings::default()
        };
        let samples = TexelSamples::new(settings.cube_n, 1, settings.seed);
        let medium = scene.medium.as_ref().map(|m| m.build(None).unwrap());
        let light = medium
            .as_ref()
            .map(|m| MediumLight::build(m, &tracer, settings.cube_n, true, &|_, _| {}).unwrap());
        let edges = EdgeMap::new(&scene, &tracer, &settings);
        Fixture {
            scene,
            tracer,
            settings,
            samples,
            medium,
            light,
            edges,
        }
    }

    /// The paths with their surface cache, keeping its walks up to `keep` bytes if given.
    fn bounces(&self, keep: Option<usize>) -> Bounces<'_> {
        let b = Bounces::new(&self.scene, &self.tracer, &self.settings, &self.samples)
            .with_medium(self.medium.as_ref().zip(self.light.as_ref()));
        match keep {
            Some(limit) => b.keeping_walks(limit),
            None => b,
        }
        .with_cache(&self.edges, &|_| true, &|_, _| {})
        .unwrap()
    }
}

/// At every surface vertex of two-bounce paths from every pixel, with visibility from the
/// cache, the rows as `vertex_rows` adds them (the glossy and the Lambertian fast cases) and as
/// the general `vertex_row` does: the glossy rows equal to the bit, with and without the
/// transmittance through a medium.
#[test]
fn fast_vertex_rows_equal_the_general_row() {
    for cloud in [false, true] {
        let f = Fixture::new(cloud);
        let (scene, tracer, samples) = (&f.scene, &f.tracer, &f.samples);
        let bounces = f.bounces(None);
        let texels = samples.dirs.len();
        let (mut glossy, mut lambertian) = (0, 0);
        let cam = &scene.camera;
        for y in 0..cam.height {
            for x in 0..cam.width {
                let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
                let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
                    continue;
                };
                let start = shading_point(tracer, &hit, ray.dir);
                let stream = (y * cam.width + x) as u64;
                bounces.walk(&start, stream, &mut |_, _, vertex, throughput| {
                    let Vertex::Surface(at) = vertex else {
                        return;
                    };
                    let visibility = bounces.visibility(at);
                    if !matches!(visibility, Visibility::Bits(_)) {
                        return;
                    }
                    let zero = || -> [Vec<f32>; 3] { std::array::from_fn(|_| vec![0.0; texels]) };
                    let mut fast = zero();
                    assert_eq!(bounces.vertex_rows(vertex, throughput, &mut fast), 0);
                    let mut general = zero();
                    let mut add = |j: usize, v: Vec3| {
                        for (row, v) in general.iter_mut().zip(v.to_array()) {
                            row[j] += v;
                        }
                    };
                    bounces.vertex_row(at, visibility, throughput, &mut add);
                    let lit = fast.iter().flatten().any(|&v| v > 0.0);
                    if at.lobes(scene).specular != Vec3::ZERO {
                        glossy += lit as usize;
                        assert!(fast == general, "cloud {cloud}: a glossy row differs");
                    } else {
                        lambertian += lit as usize;
                        for (f, g) in fast.iter().zip(&general) {
                            let top = g.iter().fold(0.0f32, |m, &v| m.max(v));
                            for (a, b) in f.iter().zip(g) {
                                assert!((a - b).abs() <= LAMBERT_REASSOCIATED * top, "{a} {b}");
                            }
                        }
                    }
                });
            }
        }
        // Enough lit vertices of both kinds that the comparison means something.
        assert!(
            glossy > 20 && lambertian > 20,
            "{glossy} glossy, {lambertian} matte"
        );
    }
}

/// At every camera sub-sample of the glossy sphere, with and without a cloud, the walks the
/// cache kept replay exactly what walking again visits, vertex for vertex and ray for ray, and
/// the rows come out the same to the bit; past their limit the walks are not kept at all.
#[test]
fn kept_walks_replay_what_walking_again_visits() {
    for cloud in [false, true] {
        let f = Fixture::new(cloud);
        let (scene, tracer, settings, edges) = (&f.scene, &f.tracer, &f.settings, &f.edges);
        let (walking, kept) = (f.bounces(None), f.bounces(Some(KEPT_BYTES)));
        let walks = |b: &Bounces| b.cache().unwrap().walks.as_ref().map(KeptWalks::bytes);
        assert_eq!(walks(&walking), None);
        assert!(walks(&kept).unwrap() > 0, "cloud {cloud}");
        assert_eq!(walks(&f.bounces(Some(1000))), None, "over the limit");

        fn seen(visits: &mut Vec<String>) -> impl FnMut(u32, u32, &Vertex, Vec3) + '_ {
            |path, bounce, at, throughput| {
                visits.push(format!("{path} {bounce} {at:?} {throughput:?}"));
            }
        }
        let cam = &scene.camera;
        let mut replayed = 0;
        for (y, x) in (0..cam.height).flat_map(|y| (0..cam.width).map(move |x| (y, x))) {
            let pixel = (y * cam.width + x) as u64;
            let subs = pixel_subsamples(edges, cam, settings, x, y);
            for (sub, (fx, fy)) in subs.into_iter().enumerate() {
                let stream = path_stream(pixel, sub, sample_stride(settings));
                let ray = cam.ray(fx, fy);
                let found = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY);
                let (mut again, mut replay) = (Vec::new(), Vec::new());
                if let Some(hit) = found {
                    let start = shading_point(tracer, &hit, ray.dir);
                    let rays = walking.walk(&start, stream, &mut seen(&mut again));
                    let key = (stream, Start::Surface);
                    assert_eq!(kept.replay(key, &mut seen(&mut replay)), Some(rays));
                    let zero = || -> [Vec<f32>; 3] { std::array::from_fn(|_| vec![0.0; 384]) };
                    let (mut a, mut b) = (zero(), zero());
                    let ra = walking.add_rows(&start, stream, 0.5, &mut a, None);
                    let rb = kept.add_rows(&start, stream, 0.5, &mut b, None);
                    assert!(ra == rb && a == b, "pixel {pixel}: the rows differ");
                }
                let t_hit = found.map_or(f32::INFINITY, |h| h.t);
                let camera = (ray.origin, ray.dir, t_hit);
                let rays = walking.walk_camera(
                    camera.0,
                    camera.1,
                    camera.2,
                    stream,
                    &mut seen(&mut again),
                );
                let key = (stream, Start::Camera);
                let kept_rays = kept.replay(key, &mut seen(&mut replay));
                assert_eq!(kept_rays, cloud.then_some(rays), "pixel {pixel}");
                assert_eq!(again, replay, "pixel {pixel}, sub-sample {sub}");
                replayed += replay.len();
            }
        }
        assert!(
            replayed > 1000,
            "cloud {cloud}: {replayed} vertices replayed"
        );
    }
}
