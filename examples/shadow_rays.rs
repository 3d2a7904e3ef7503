//! The bake's shadow rays, written out for an independent tracer and timed on this one: the rays
//! a direct-light bake of SCENE traces towards its texels' centres (from the first hit of each
//! pixel of an every-STRIDE-th grid, one ray a cube texel at N = 32, on the side the normal
//! faces; a default bake adds sub-texel rays on shadow borders, which are left out here),
//! with the scene's triangles, so that `scripts/embree_shadow_rays.py` can trace the same rays
//! with Embree's one-ray query (`rtcOccluded1`) and compare the rates. They are timed twice:
//! one by one, each shading point's rays through one `Tracer::rays_from`, and as the bake traces
//! them, in packets of 8 x 8 texels (`RaysFrom::occluded_packet`); the two must answer alike.
//!
//! ```sh
//! cargo run --release --example shadow_rays -- assets/scenes/demo.toml DIR [STRIDE]
//! python3 scripts/embree_shadow_rays.py DIR
//! ```
//!
//! It then times the bake's whole pipeline per ray on the same scene: every STRIDE-th tile of a
//! bake at N = 32 without extra edge sub-samples (`prt bake --cube 32 --edge-spp 0`, its rays
//! counted as the bake counts them, sub-texel ones included), each tile's rows accumulated,
//! projected, transformed, thresholded and encoded ([`wavelet_prt::bake::with_tile_baker`]), so
//! the tracer alone and the bake as a whole are side by side in one run.
//!
//! Writes `DIR/triangles.f32` (F x 3 x 3 corner positions), `DIR/rays.f32` (R x 7: origin,
//! direction, t_max), `DIR/occluded.u8` (this tracer's answer per ray) and `DIR/rays.json` (the
//! counts, this tracer's rates, alone and in packets, and the whole bake's). The rates are taken
//! on one thread, so rays per second are rays per CPU-second; the tracer's are the medians of
//! three passes. A scene's analytic spheres are not written (the script traces triangles): the
//! example refuses a scene that has any.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use wavelet_prt::bake::{BakeSettings, CentrePackets, shading_point, with_tile_baker};
use wavelet_prt::math::texel_quadrature::TexelQuadrature;
use wavelet_prt::scene::Scene;
use wavelet_prt::scene::trace::Tracer;

/// Cube face size of the rays' directions (the demo bake's).
const CUBE_N: usize = 32;
/// Passes over the rays; the median is reported.
const PASSES: usize = 3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [scene_path, dir, rest @ ..] = &args[..] else {
        return Err("usage: shadow_rays SCENE.toml DIR [STRIDE]".into());
    };
    let stride: u32 = match rest.first() {
        Some(s) => s
            .parse()
            .map_err(|_| format!("STRIDE '{s}' is not a count"))?,
        None => 8,
    };
    if stride == 0 {
        return Err("STRIDE must be at least 1".into());
    }
    let scene = Scene::load(std::path::Path::new(scene_path))?;
    if !scene.spheres.is_empty() {
        return Err(format!(
            "{scene_path} has {} analytic spheres; the Embree script traces triangles only",
            scene.spheres.len()
        )
        .into());
    }
    let dir = PathBuf::from(dir);
    std::fs::create_dir_all(&dir)?;
    let tracer = Tracer::new(&scene);
    // The bake's texel centres and its packets of them.
    let quadrature = TexelQuadrature::new(CUBE_N, 1);
    let packets = CentrePackets::new(CUBE_N, &quadrature.centres);
    let centres = &quadrature.centres;
    let cam = &scene.camera;
    let mut points = Vec::new();
    let mut rays: Vec<[f32; 7]> = Vec::new();
    let mut hits = 0usize;
    for y in (0..cam.height).step_by(stride as usize) {
        for x in (0..cam.width).step_by(stride as usize) {
            let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let sp = shading_point(&tracer, &hit, ray.dir);
            points.push((sp.origin, sp.normal, rays.len()));
            for d in centres {
                if sp.normal.dot(*d) > 0.0 {
                    let (o, d) = (sp.origin, *d);
                    rays.push([o.x, o.y, o.z, d.x, d.y, d.z, f32::INFINITY]);
                }
            }
        }
    }
    if rays.is_empty() {
        return Err("no camera ray hit the scene".into());
    }
    let mut occluded = vec![0u8; rays.len()];
    let mut seconds = Vec::new();
    for _ in 0..PASSES {
        let start = Instant::now();
        // As the bake traces them: the rays of one shading point together.
        let mut from: Option<(glam::Vec3, _)> = None;
        for (r, o) in rays.iter().zip(&mut occluded) {
            let origin = glam::Vec3::new(r[0], r[1], r[2]);
            let d = glam::Vec3::new(r[3], r[4], r[5]);
            let rays_from = match &mut from {
                Some((at, q)) if *at == origin => q,
                _ => &mut from.insert((origin, tracer.rays_from(origin))).1,
            };
            *o = rays_from.occluded(d, r[6]) as u8;
        }
        seconds.push(start.elapsed().as_secs_f64());
    }
    seconds.sort_by(f64::total_cmp);
    let median = seconds[PASSES / 2];
    let rate = rays.len() as f64 / median;
    let packet_seconds = in_packets(&tracer, &points, (&packets, centres), &occluded)?;
    let packet_rate = rays.len() as f64 / packet_seconds;
    let blocked = occluded.iter().filter(|&&o| o == 1).count();
    let mut tri = std::io::BufWriter::new(std::fs::File::create(dir.join("triangles.f32"))?);
    for t in &scene.triangles {
        for v in &t.vertices {
            for c in v.to_array() {
                tri.write_all(&c.to_le_bytes())?;
            }
        }
    }
    tri.flush()?;
    let mut out = std::io::BufWriter::new(std::fs::File::create(dir.join("rays.f32"))?);
    for r in &rays {
        for c in r {
            out.write_all(&c.to_le_bytes())?;
        }
    }
    out.flush()?;
    std::fs::write(dir.join("occluded.u8"), &occluded)?;
    let (bake_rays, bake_seconds) = whole_bake(&scene, stride)?;
    let bake_rate = bake_rays as f64 / bake_seconds;
    let json = format!(
        "{{\"scene\": {scene_path:?}, \"triangles\": {}, \"hits\": {hits}, \"rays\": {}, \
         \"occluded\": {blocked}, \"seconds\": {median}, \"rays_per_cpu_second\": {rate}, \
         \"packet_seconds\": {packet_seconds}, \"packet_rays_per_cpu_second\": {packet_rate}, \
         \"bake_rays\": {bake_rays}, \"bake_seconds\": {bake_seconds}, \
         \"bake_rays_per_cpu_second\": {bake_rate}}}\n",
        scene.triangles.len(),
        rays.len()
    );
    std::fs::write(dir.join("rays.json"), &json)?;
    println!(
        "{}: {} triangles, {hits} hits, {} shadow rays ({:.1}% occluded); this tracer on one \
         thread: {:.2} M rays per CPU-second (median of {PASSES} passes, {:.2} s)",
        scene_path,
        scene.triangles.len(),
        rays.len(),
        100.0 * blocked as f64 / rays.len() as f64,
        rate / 1e6,
        median
    );
    println!(
        "in packets of 8 x 8 texels, as the bake traces them: {:.2} M rays per CPU-second \
         ({packet_seconds:.2} s, {:.2}x one by one), every answer the same",
        packet_rate / 1e6,
        packet_rate / rate
    );
    println!(
        "the bake's whole pipeline on every {stride}th tile, one thread: {bake_rays} shadow rays \
         in {bake_seconds:.2} s, {:.2} M rays per CPU-second ({:.2} of the tracer alone)",
        bake_rate / 1e6,
        bake_rate / rate
    );
    Ok(())
}

/// The seconds (median of [`PASSES`]) the rays of `points` (origin, normal, index of its first
/// ray) take in packets of texel centres, one thread; each answer checked against `alone`, the
/// rays' answers one by one in the same order (texel order, the centres on the normal's side).
fn in_packets(
    tracer: &Tracer,
    points: &[(glam::Vec3, glam::Vec3, usize)],
    (packets, centres): (&CentrePackets, &[glam::Vec3]),
    alone: &[u8],
) -> Result<f64, Box<dyn std::error::Error>> {
    let blocks = packets.blocks().count();
    let mut answers = vec![0u64; points.len() * blocks];
    let mut seconds = Vec::new();
    for _ in 0..PASSES {
        let start = Instant::now();
        for (&(origin, normal, _), found) in points.iter().zip(answers.chunks_mut(blocks)) {
            let mut from = tracer.rays_from(origin);
            for ((_, packet), bits) in packets.blocks().zip(found) {
                let up = packet.dirs().iter().enumerate();
                let above = up
                    .filter(|(_, d)| normal.dot(**d) > 0.0)
                    .fold(0u64, |m, (i, _)| m | 1 << i);
                *bits = from.occluded_packet(packet, above, f32::INFINITY);
            }
        }
        seconds.push(start.elapsed().as_secs_f64());
    }
    // The same answers as one by one: the rays of a point are its texels above the surface, in
    // texel order.
    for (&(_, normal, first), found) in points.iter().zip(answers.chunks(blocks)) {
        let mut blocked = vec![false; centres.len()];
        for ((texels, _), bits) in packets.blocks().zip(found) {
            for (i, &j) in texels.iter().enumerate() {
                blocked[j as usize] = bits >> i & 1 == 1;
            }
        }
        let mut at = first;
        for (j, c) in centres.iter().enumerate() {
            if normal.dot(*c) > 0.0 {
                if (alone[at] == 1) != blocked[j] {
                    return Err(format!("texel {j}: the packet answers otherwise").into());
                }
                at += 1;
            }
        }
    }
    seconds.sort_by(f64::total_cmp);
    Ok(seconds[PASSES / 2])
}

/// The shadow rays of every `stride`-th tile of a bake of `scene` at N = 32 without extra edge
/// sub-samples, and the seconds those tiles take on one thread, what every tile reads built
/// beforehand.
fn whole_bake(scene: &Scene, stride: u32) -> Result<(u64, f64), Box<dyn std::error::Error>> {
    let settings = BakeSettings {
        cube_n: CUBE_N,
        edge_spp: 0,
        ..BakeSettings::default()
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let timed = with_tile_baker(scene, &settings, |tiles, bake_one| {
        pool.install(|| {
            let start = Instant::now();
            let mut rays = 0;
            for t in (0..tiles).step_by(stride as usize) {
                rays += bake_one(t)?;
            }
            Ok::<_, wavelet_prt::PrtError>((rays, start.elapsed().as_secs_f64()))
        })
    })??;
    Ok(timed)
}
