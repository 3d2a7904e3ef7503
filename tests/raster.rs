//! The two rasterisers of per-vertex colours against each other: the GPU render pipeline
//! (`draw::gpu::raster`) draws what the CPU's ray-exact twin (`draw::raster`) draws, for
//! cameras inside a ground that reaches behind the eye, a sphere and a two-sided panel; the GPU
//! culls the same faces; the coverage fits the environment behind.
//!
//! Without an adapter the GPU tests print why and pass, unless `PRT_REQUIRE_GPU=1`, when they fail.

mod common;

use common::{Rng, gpu_or_skip};
use glam::Vec3;
use wavelet_prt::draw::background::{composite, environment_behind_camera};
use wavelet_prt::draw::gpu::{GpuMesh, GpuRaster, upload_colours};
use wavelet_prt::draw::raster::{DrawOptions, Raster, rasterize, rasterize_with};
use wavelet_prt::draw::shading::GlossMesh;
use wavelet_prt::env::envmap::{EnvMap, EnvRotation};
use wavelet_prt::gpu::map_and_read;
use wavelet_prt::relight::gpu::Gpu;
use wavelet_prt::scene::Camera;
use wavelet_prt::scene::visibility::Visibility;

/// Relative colour difference beyond which a GPU pixel counts as drawn differently from the
/// CPU's: both take the barycentrics of the pixel ray's hit on the triangle's plane from the
/// vertices as given, the GPU in f32 and the CPU in f64, which for affine colours stays well
/// inside; the pixels past it are what `check_against_cpu` counts.
const GPU_COLOUR_REL: f32 = 1e-4;
/// A flat colour drawn by the GPU against that colour, relative: barycentrics that sum to about 1
/// in f32 move it by a few ulps.
const FLAT_COLOUR_ROUNDING: f32 = 1e-6;

/// A mesh: positions and triangles.
#[derive(Default)]
struct Mesh {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Adds a triangle, wound so that its right-handed normal points along `outward`'s side.
    fn push(&mut self, corners: [Vec3; 3], outward: Vec3) {
        let [a, b, c] = corners;
        let n = self.positions.len() as u32;
        self.positions.extend(corners);
        if (b - a).cross(c - a).dot(outward) >= 0.0 {
            self.triangles.push([n, n + 1, n + 2]);
        } else {
            self.triangles.push([n, n + 2, n + 1]);
        }
    }

    /// A `side`-metre square at height `y`, facing up, in `cells` x `cells` quads of shared
    /// vertices.
    fn ground(&mut self, side: f32, cells: u32, y: f32) {
        let base = self.positions.len() as u32;
        for j in 0..=cells {
            for i in 0..=cells {
                let (u, v) = (i as f32 / cells as f32, j as f32 / cells as f32);
                self.positions
                    .push(Vec3::new((u - 0.5) * side, y, (v - 0.5) * side));
            }
        }
        let at = |i: u32, j: u32| base + j * (cells + 1) + i;
        for j in 0..cells {
            for i in 0..cells {
                // (b − a) × (c − a) = +z × +x = +y.
                self.triangles.push([at(i, j), at(i, j + 1), at(i + 1, j)]);
                self.triangles
                    .push([at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]);
            }
        }
    }

    /// A UV sphere of `rings` x `segments` quads with shared vertices, wound outwards.
    fn sphere(&mut self, centre: Vec3, radius: f32, rings: u32, segments: u32) {
        let base = self.positions.len() as u32;
        for r in 0..=rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..=segments {
                let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                let d = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                self.positions.push(centre + radius * d);
            }
        }
        let at = |r: u32, s: u32| base + r * (segments + 1) + s;
        for r in 0..rings {
            for s in 0..segments {
                for tri in [
                    [at(r, s), at(r + 1, s), at(r + 1, s + 1)],
                    [at(r, s), at(r + 1, s + 1), at(r, s + 1)],
                ] {
                    let [a, b, c] = tri.map(|v| self.positions[v as usize]);
                    let n = (b - a).cross(c - a);
                    if n.length_squared() < 1e-12 {
                        continue; // the poles' collapsed triangles
                    }
                    if n.dot(a + b + c - 3.0 * centre) > 0.0 {
                        self.triangles.push(tri);
                    } else {
                        self.triangles.push([tri[0], tri[2], tri[1]]);
                    }
                }
            }
        }
    }
}

/// The test scene: a 20 m ground of 24 x 24 cells, a sphere resting on it, and a two-sided
/// panel (two triangles of opposite windings on the same corners, with their own vertices).
fn scene() -> Mesh {
    let mut m = Mesh::default();
    m.ground(20.0, 24, 0.0);
    m.sphere(Vec3::new(0.0, 0.6, 0.0), 0.6, 16, 24);
    let panel = [
        Vec3::new(-1.6, 0.0, -0.8),
        Vec3::new(-0.4, 0.0, -1.4),
        Vec3::new(-1.0, 1.5, -1.1),
    ];
    let normal = (panel[1] - panel[0]).cross(panel[2] - panel[0]);
    m.push(panel, normal);
    m.push(panel, -normal);
    m
}

/// Random colours in [0.2, 1.2) per channel, one per vertex.
fn colours(n: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| std::array::from_fn(|_| rng.range_f32(0.2, 1.2)))
        .collect()
}

/// Cameras inside the ground (which reaches behind the eye and under it), looking at the sphere
/// and panel from several sides and at several aspects.
fn cameras() -> Vec<Camera> {
    let cam = |eye: [f32; 3], target: [f32; 3], width, height| Camera {
        eye: Vec3::from(eye),
        target: Vec3::from(target),
        up: Vec3::Y,
        fov_y_deg: 55.0,
        width,
        height,
    };
    vec![
        cam([3.0, 1.2, 4.0], [0.0, 0.6, 0.0], 160, 120),
        cam([-2.5, 0.8, -3.5], [-0.5, 0.5, 0.0], 96, 128),
        cam([0.4, 4.0, 1.5], [0.0, 0.0, -0.5], 128, 128),
        cam([1.0, 0.3, 1.6], [0.0, 0.5, 0.0], 150, 100),
    ]
}

/// How two rasters of one scene differ: pixels covered by one only, and pixels covered by both
/// whose colours differ by more than `rel` (relative, per channel), out of all pixels.
struct Difference {
    coverage: usize,
    colour: usize,
    both: usize,
    pixels: usize,
    worst_agreeing: f32,
    /// The first few pixels whose colours differ.
    examples: Vec<String>,
}

fn compare(a: &Raster, b: &Raster, rel: f32) -> Difference {
    let mut d = Difference {
        coverage: 0,
        colour: 0,
        both: 0,
        pixels: a.coverage.len(),
        worst_agreeing: 0.0,
        examples: Vec::new(),
    };
    for i in 0..a.coverage.len() {
        let (ca, cb) = (a.coverage[i] == 1.0, b.coverage[i] == 1.0);
        assert!(a.coverage[i] == 0.0 || ca, "coverage {}", a.coverage[i]);
        assert!(b.coverage[i] == 0.0 || cb, "coverage {}", b.coverage[i]);
        if ca != cb {
            d.coverage += 1;
            continue;
        }
        if !ca {
            assert_eq!(a.image.pixels[i], [0.0; 3], "uncovered pixel {i}");
            assert_eq!(b.image.pixels[i], [0.0; 3], "uncovered pixel {i}");
            continue;
        }
        d.both += 1;
        let (pa, pb) = (a.image.pixels[i], b.image.pixels[i]);
        let err = (0..3)
            .map(|k| (pa[k] - pb[k]).abs() / pb[k].abs())
            .fold(0.0, f32::max);
        if err > rel {
            if d.examples.len() < 8 {
                d.examples
                    .push(format!("pixel {i}: {pa:?} vs {pb:?} ({err:.1e})"));
            }
            d.colour += 1;
        } else {
            d.worst_agreeing = d.worst_agreeing.max(err);
        }
    }
    d
}

fn gpu_draw(gpu: &Gpu, cam: &Camera, mesh: &Mesh, colours: &[[f32; 3]]) -> Raster {
    let m = GpuMesh::new(gpu, &mesh.positions, &mesh.triangles).unwrap();
    let buffer = upload_colours(gpu, colours).unwrap();
    GpuRaster::new(gpu)
        .unwrap()
        .draw(gpu, cam, &m, &buffer)
        .unwrap()
}

/// Colours an affine function of position: what perspective-correct interpolation reproduces
/// exactly at every hit point, whatever the triangle.
fn affine_colours(positions: &[Vec3]) -> Vec<[f32; 3]> {
    positions
        .iter()
        .map(|p| {
            [
                0.7 + 0.05 * p.x,
                0.6 + 0.1 * p.y - 0.02 * p.z,
                0.8 + 0.03 * p.z - 0.04 * p.x,
            ]
        })
        .collect()
}

/// Draws the scene with `colours` from every camera on both rasterisers and bounds how many
/// pixels differ: in coverage, or in colour by more than 1e-4 relative. Only pixels whose centres
/// lie on an edge, to the rasterisers' precision, may differ in coverage or in which surface they
/// show; `colour_slack` more may differ in colour by interpolation precision.
fn check_against_cpu(gpu: &Gpu, mesh: &Mesh, colours: &[[f32; 3]], colour_slack: usize) {
    let m = GpuMesh::new(gpu, &mesh.positions, &mesh.triangles).unwrap();
    let buffer = upload_colours(gpu, colours).unwrap();
    let mut raster = GpuRaster::new(gpu).unwrap();
    for (k, cam) in cameras().iter().enumerate() {
        let cpu = rasterize(cam, &mesh.positions, &mesh.triangles, colours).unwrap();
        let dev = raster.draw(gpu, cam, &m, &buffer).unwrap();
        let d = compare(&dev, &cpu, GPU_COLOUR_REL);
        eprintln!(
            "camera {k}: {} of {} pixels covered by both; coverage differs on {}, colour on {}; \
             worst agreeing colour {:.2e}",
            d.both, d.pixels, d.coverage, d.colour, d.worst_agreeing
        );
        // The scene fills much of every view, the ground reaching the bottom rows.
        assert!(d.both > d.pixels / 3, "camera {k}: {} covered", d.both);
        // The edges' share: 0.1% of the pixels.
        assert!(
            (d.coverage + d.colour) * 1000 <= d.pixels + colour_slack * 1000,
            "camera {k}: {} pixels differ in coverage, {} in colour, of {}: {:#?}",
            d.coverage,
            d.colour,
            d.pixels,
            d.examples
        );
    }
}

#[test]
fn gpu_draws_what_the_cpu_draws() {
    let Some(gpu) = gpu_or_skip("gpu_draws_what_the_cpu_draws") else {
        return;
    };
    let mesh = scene();
    check_against_cpu(&gpu, &mesh, &affine_colours(&mesh.positions), 0);
}

#[test]
fn gpu_draws_what_the_cpu_draws_with_unrelated_vertex_colours() {
    let Some(gpu) = gpu_or_skip("gpu_draws_what_the_cpu_draws_with_unrelated_vertex_colours")
    else {
        return;
    };
    // Each vertex its own random colour: steep gradients across triangles a few pixels wide,
    // where the GPU's f32 barycentrics move a few pixels past 1e-4 (lavapipe: at most 7 of
    // 19,200); allow 0.2% of the pixels in all. The hardware's own interpolation, from corners
    // snapped to its sub-pixel grid, moved 3,361 of them on an NVIDIA H100.
    let mesh = scene();
    let colours = colours(mesh.positions.len(), 7);
    let pixels = cameras().iter().map(|c| c.width * c.height).min().unwrap() as usize;
    check_against_cpu(&gpu, &mesh, &colours, pixels / 1000);
}

#[test]
fn gpu_draws_several_samples_as_the_cpu_does() {
    let Some(gpu) = gpu_or_skip("gpu_draws_several_samples_as_the_cpu_does") else {
        return;
    };
    // Each sample is drawn as a pixel centre is, so a sample differs only where one pixel of the
    // plain draw would: at an exact edge, or by the f32 barycentrics of steep gradients (the
    // unrelated colours' bound, 0.2% of the pixels). The coverage is a fraction of the samples.
    let mesh = scene();
    let colours = colours(mesh.positions.len(), 11);
    let m = GpuMesh::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let buffer = upload_colours(&gpu, &colours).unwrap();
    for samples in [4, 16] {
        let mut raster = GpuRaster::multisampled(&gpu, samples).unwrap();
        let mut partly = 0;
        for (k, cam) in cameras().iter().enumerate() {
            let options = DrawOptions::samples(samples);
            let cpu =
                rasterize_with(cam, &mesh.positions, &mesh.triangles, &colours, options).unwrap();
            let dev = raster.draw(&gpu, cam, &m, &buffer).unwrap();
            let pixels = cpu.coverage.len();
            let partial = cpu.coverage.iter().filter(|&&c| c > 0.0 && c < 1.0).count();
            let differ = (0..pixels)
                .filter(|&i| {
                    let (a, b) = (dev.image.pixels[i], cpu.image.pixels[i]);
                    dev.coverage[i] != cpu.coverage[i]
                        || (0..3)
                            .any(|c| (a[c] - b[c]).abs() > GPU_COLOUR_REL * b[c].abs().max(0.2))
                })
                .count();
            eprintln!(
                "{samples} samples, camera {k}: {partial} pixels partly covered, {differ} of \
                 {pixels} differ"
            );
            partly += partial;
            assert!(
                differ * 1000 <= 2 * pixels,
                "{samples} samples, camera {k}: {differ} pixels differ"
            );
        }
        // The silhouettes are antialiased.
        assert!(
            partly > 150,
            "{samples} samples: {partly} pixels partly covered"
        );
    }
}

#[test]
fn gpu_culls_the_faces_the_cpu_culls() {
    let Some(gpu) = gpu_or_skip("gpu_culls_the_faces_the_cpu_culls") else {
        return;
    };
    let cam = &cameras()[0];
    let corners = [
        Vec3::new(-1.0, 0.2, 0.0),
        Vec3::new(1.0, 0.2, 0.5),
        Vec3::new(0.0, 1.4, 0.2),
    ];
    let towards_eye = cam.eye - corners[0];
    let mut front = Mesh::default();
    front.push(corners, towards_eye);
    let mut back = Mesh::default();
    back.push(corners, -towards_eye);
    let flat = [[0.25, 0.5, 2.0]; 3];
    let f = gpu_draw(&gpu, cam, &front, &flat);
    let b = gpu_draw(&gpu, cam, &back, &flat);
    let drawn = f.coverage.iter().filter(|&&c| c == 1.0).count();
    assert!(drawn > 300, "{drawn} pixels of the front face");
    assert!(b.coverage.iter().all(|&c| c == 0.0), "the back face drew");
    // A flat colour comes out flat (to the rounding of barycentrics that sum to about 1).
    for (p, &c) in f.image.pixels.iter().zip(&f.coverage) {
        let want = if c == 1.0 { flat[0] } else { [0.0; 3] };
        for k in 0..3 {
            assert!(
                (p[k] - want[k]).abs() <= FLAT_COLOUR_ROUNDING * want[k],
                "{p:?} for {want:?}"
            );
        }
    }
    let cpu = rasterize(cam, &front.positions, &front.triangles, &flat).unwrap();
    let d = compare(&f, &cpu, 0.0);
    assert!(d.coverage <= 20, "{} pixels differ", d.coverage);
}

#[test]
fn gpu_clips_at_the_cpu_near_plane() {
    let Some(gpu) = gpu_or_skip("gpu_clips_at_the_cpu_near_plane") else {
        return;
    };
    // A floor 0.2 mm under the eye: the bottom rows meet it nearer than NEAR (1 mm), the rows
    // between them and the horizon farther.
    let cam = Camera {
        eye: Vec3::ZERO,
        target: Vec3::NEG_Z,
        up: Vec3::Y,
        fov_y_deg: 50.0,
        width: 20,
        height: 40,
    };
    let mut floor = Mesh::default();
    let y = -2e-4;
    floor.push(
        [
            Vec3::new(-5.0, y, 5.0),
            Vec3::new(5.0, y, 5.0),
            Vec3::new(0.0, y, -50.0),
        ],
        Vec3::Y,
    );
    let flat = [[1.0; 3]; 3];
    let dev = gpu_draw(&gpu, &cam, &floor, &flat);
    let cpu = rasterize(&cam, &floor.positions, &floor.triangles, &flat).unwrap();
    let rows = |r: &Raster| -> Vec<f32> { r.coverage.chunks(20).map(|c| c.iter().sum()).collect() };
    assert_eq!(rows(&dev), rows(&cpu));
    assert_eq!(rows(&cpu)[28], 20.0);
    assert_eq!(rows(&cpu)[29], 0.0);
    // Rolled, the near plane crosses the film aslant.
    let rolled = Camera {
        up: Vec3::new(0.5, 1.0, 0.0),
        ..cam
    };
    let dev = gpu_draw(&gpu, &rolled, &floor, &flat);
    let cpu = rasterize(&rolled, &floor.positions, &floor.triangles, &flat).unwrap();
    let d = compare(&dev, &cpu, FLAT_COLOUR_ROUNDING);
    assert!(
        d.coverage + d.colour <= 2,
        "{} + {} pixels differ",
        d.coverage,
        d.colour
    );
    assert!(d.both > 100, "{} pixels drawn", d.both);
}

#[test]
fn gpu_renders_into_a_texture_what_it_reads_back() {
    let Some(gpu) = gpu_or_skip("gpu_renders_into_a_texture_what_it_reads_back") else {
        return;
    };
    let mesh = scene();
    let colours = colours(mesh.positions.len(), 3);
    let cam = &cameras()[1];
    let m = GpuMesh::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let buffer = upload_colours(&gpu, &colours).unwrap();
    // Four samples a pixel, so the resolve pass writes the caller's texture too.
    let mut raster = GpuRaster::multisampled(&gpu, 4).unwrap();
    let drawn = raster.draw(&gpu, cam, &m, &buffer).unwrap();
    assert!(drawn.coverage.iter().any(|&c| c > 0.0 && c < 1.0));
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width: cam.width,
            height: cam.height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    raster.render(&gpu, cam, &m, &buffer, &texture).unwrap();
    let row = (cam.width * 16).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let readback = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (row * cam.height) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: None,
            },
        },
        texture.size(),
    );
    gpu.queue.submit([encoder.finish()]);
    let w = cam.width as usize;
    let texels = map_and_read(&gpu.device, &readback, "test texture", |bytes| {
        (0..cam.height as usize)
            .flat_map(|y| {
                bytemuck::cast_slice::<u8, [f32; 4]>(&bytes[y * row as usize..][..w * 16]).to_vec()
            })
            .collect::<Vec<_>>()
    })
    .unwrap();
    for (i, t) in texels.iter().enumerate() {
        assert_eq!([t[0], t[1], t[2]], drawn.image.pixels[i], "pixel {i}");
        assert_eq!(t[3], drawn.coverage[i], "pixel {i}");
    }
    // A texture of the wrong size or format is refused.
    let small = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width: 8,
            height: 8,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let e = raster.render(&gpu, cam, &m, &buffer, &small).unwrap_err();
    assert!(e.to_string().contains("texture"), "{e}");
}

#[test]
fn gpu_refuses_bad_meshes_and_colour_buffers() {
    let Some(gpu) = gpu_or_skip("gpu_refuses_bad_meshes_and_colour_buffers") else {
        return;
    };
    let mesh = scene();
    let e = GpuMesh::new(&gpu, &mesh.positions[..3], &mesh.triangles)
        .err()
        .unwrap();
    assert!(e.to_string().contains("out of range"), "{e}");
    let m = GpuMesh::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let short = upload_colours(&gpu, &colours(mesh.positions.len() - 1, 1)).unwrap();
    let mut raster = GpuRaster::new(&gpu).unwrap();
    let e = raster.draw(&gpu, &cameras()[0], &m, &short).unwrap_err();
    assert!(e.to_string().contains("colours"), "{e}");
    let e = upload_colours(&gpu, &[[f32::NAN, 0.0, 0.0]])
        .unwrap_err()
        .to_string();
    assert!(e.contains("must be finite"), "{e}");
    let bad = Camera {
        fov_y_deg: 180.0,
        ..cameras()[0].clone()
    };
    let full = upload_colours(&gpu, &colours(mesh.positions.len(), 1)).unwrap();
    let e = raster.draw(&gpu, &bad, &m, &full).unwrap_err().to_string();
    assert!(
        e.contains("fov_y_deg: must be strictly between 0 and 180 degrees"),
        "{e}"
    );
    // A buffer with more colours than vertices (a relit image larger than the mesh) is drawn
    // from its start.
    let n = mesh.positions.len();
    let long = upload_colours(&gpu, &colours(n + 37, 1)).unwrap();
    let a = raster.draw(&gpu, &cameras()[0], &m, &full).unwrap();
    let b = raster.draw(&gpu, &cameras()[0], &m, &long).unwrap();
    assert_eq!(a, b);
    // A glossy mesh whose tables do not fit it is refused, as the CPU's draws refuse it.
    let n = mesh.positions.len();
    let normals = vec![Vec3::Y; n];
    let vis =
        Visibility::new(4, n, vec![0], vec![0; Visibility::words(4)], vec![[0.5; 4]]).unwrap();
    for (normals, materials, why) in [
        (&normals[..n - 1], vec![0; n], "normals"),
        (&normals[..], vec![0; n - 1], "materials"),
        (&normals[..], vec![1; n], "material 1 of 1"),
    ] {
        let gloss = GlossMesh {
            normals,
            materials: &materials,
            visibility: &vis,
        };
        let e = GpuMesh::glossy(&gpu, &mesh.positions, &mesh.triangles, None, Some(gloss))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("gloss") && e.contains(why), "{why}: {e}");
        assert_eq!(gloss.check(n).unwrap_err().to_string(), e, "{why}");
    }
    let fits = GlossMesh {
        normals: &normals,
        materials: &vec![0; n],
        visibility: &vis,
    };
    GpuMesh::glossy(&gpu, &mesh.positions, &mesh.triangles, None, Some(fits)).unwrap();
    // An empty mesh draws nothing.
    let empty = GpuMesh::new(&gpu, &[], &[]).unwrap();
    let r = raster.draw(&gpu, &cameras()[0], &empty, &full).unwrap();
    assert!(r.coverage.iter().all(|&c| c == 0.0));
}

#[test]
fn the_environment_shows_where_the_raster_leaves_the_film_open() {
    let mesh = scene();
    let cam = &cameras()[0];
    let flat = vec![[0.5, 0.25, 0.125]; mesh.positions.len()];
    let r = rasterize(cam, &mesh.positions, &mesh.triangles, &flat).unwrap();
    let env = EnvMap::constant(32, 16, [4.0, 4.0, 4.0]);
    let behind = environment_behind_camera(cam, &r.coverage, &env, EnvRotation::yaw(20.0)).unwrap();
    let frame = composite(&r.image, &behind);
    let open = r.coverage.iter().filter(|&&c| c == 0.0).count();
    assert!(open > 100, "{open} open pixels");
    for (p, &c) in frame.pixels.iter().zip(&r.coverage) {
        assert_eq!(*p, if c == 1.0 { flat[0] } else { [4.0; 3] });
    }
}
