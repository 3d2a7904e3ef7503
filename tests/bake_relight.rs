//! The bake and the CPU relight against known answers: white furnaces, the analytic shadow of a
//! sphere under one texel light, the brute-force reference, analytic SH irradiance, rotations, the
//! slow twins of the sparse kernel, file round trips and corruption.

use std::f64::consts::PI;
mod common;

use common::{
    SAME_SUM, SAME_VALUE, SPHERE_ON_PLANE, assert_rel_close, assets, full_light, plane_from_above,
    random_transport, relit, scene_from, temp_dir,
};

use glam::DVec3;
use wavelet_prt::bake::reference::render_reference;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::env::envmap::{EnvMap, EnvRotation, SunSky};
use wavelet_prt::env::select::{SparseLight, Weighting};
use wavelet_prt::math::cubemap::{CubeMap, texel_count, texel_dirs, texel_index};
use wavelet_prt::math::sampling::Rng;
use wavelet_prt::math::sh;
use wavelet_prt::math::texel_quadrature::TexelQuadrature;
use wavelet_prt::output::film::Image;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::{
    LightContext, Method, RelightRequest, relight, relight_dense_reference, relight_sh,
    relight_wavelet,
};
use wavelet_prt::store::transport::{Quantization, Transport};

/// The brute-force reference and the relight of a lossless bake agree to float rounding.
const REFERENCE_MATCH: f64 = 1e-4;
/// Relative L2 between SH relighting with the rotated coefficients of the unturned N = 8 cube and
/// with the projection of the turned cube itself: rotation is exact for the sphere, so the two
/// differ only by how the 384 texels of each cube sample the map (the turned cube resamples it on
/// another grid) and by the texel-sum quadrature of each projection.
const SH_ROTATION_VS_PROJECTION: f64 = 1e-2;
/// Relative L2 between a bake thresholded at 0.05 (8-bit values) and the lossless one under
/// constant light: each row may lose at most 5 % of an unshadowed row's norm, so this is the
/// per-row budget itself; constant light sees only the scaling coefficients, which thresholding
/// keeps first, so the error stays far below it.
const THRESHOLD_BUDGET: f64 = 0.05;
/// A ground pixel under one texel of light against the analytic value (albedo · L cos θ Ω / π
/// lit, 0 in the shadow), relative to the lit value: the bake and the reference sample the texel
/// at its centre or integrate it, as the analytic value does, so only the float rounding of the
/// Haar round trip (and of the first moment's f32) remains.
const ONE_TEXEL_ROUNDING: f64 = 1e-5;
/// Relative rise of the image error from one K to the next that still counts as not rising: the
/// errors are relative L2s of f32 relights, so two equally good lights may differ by rounding.
const IMAGE_ERROR_ROUNDING: f64 = 1e-6;
/// The ground's mean direct light near the wall's foot against a_g c / 2, relative: the
/// quadrature of the texel-sampled sky (16 directions a texel at N = 16) and the wall's finite
/// size, 1%.
const WALL_FOOT_DIRECT: f64 = 1e-2;
/// The light one bounce off the wall adds against a_g a_w c / 4, relative: the Monte Carlo error
/// of 4096 paths a sub-sample over 16 pixels is about 0.5%, and the wall, seen from 0.12 away, is
/// slightly under half of the hemisphere: a few percent.
const WALL_BOUNCE: f64 = 5e-2;
/// Reference values below which an edge pixel's bound against the reference stops shrinking with
/// the value: a pixel near black (in a shadow) is allowed `REFERENCE_MATCH` of this, since the
/// signed Haar sums that make it still round at the scale of their larger terms.
const EDGE_PIXEL_SCALE_FLOOR: f32 = 1e-3;

fn lossless(n: usize, sh_order: usize) -> BakeSettings {
    BakeSettings {
        cube_n: n,
        sh_order,
        lossless: true,
        ..BakeSettings::default()
    }
}

#[test]
fn white_furnace_plane_and_convex_sphere() {
    // A plane seen from above and a lone sphere, both unoccluded by anything else, shadows on:
    // under constant radiance c every visible point has radiance albedo x c.
    let plane = plane_from_above(9, 7, [0.5, 0.25, 1.0], 50.0);
    let sphere = r#"
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 30.0
width = 19
height = 17
[material.m]
type = "diffuse"
albedo = [0.5, 0.25, 1.0]
[[shape]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 0.9
material = "m"
"#;
    // Texel-sampled cosine integrals converge as O(h²): 16 samples per texel at N = 16 leave
    // about 2e-4 of relative error for arbitrary normals.
    const QUADRATURE: f64 = 1e-3;
    let c = [2.0f32, 1.0, 0.5];
    for (name, text) in [
        ("furnace-plane", plane.as_str()),
        ("furnace-sphere", sphere),
    ] {
        let scene = scene_from(text, name);
        let settings = BakeSettings {
            texel_samples: 16,
            ..lossless(16, 2)
        };
        let t = bake(&scene, &settings, &|_| {}).unwrap();
        let cube = CubeMap::constant(16, c).unwrap();
        let (img, _) = relight_wavelet(&t, &full_light(&cube)).unwrap();
        let mut covered = 0;
        for (p, cov) in img.pixels.iter().zip(&t.coverage) {
            if *cov < 1.0 {
                continue;
            }
            covered += 1;
            let albedo = [0.5, 0.25, 1.0];
            for k in 0..3 {
                assert_rel_close(
                    format!("{name} channel {k}"),
                    p[k] as f64,
                    albedo[k] * c[k] as f64,
                    QUADRATURE,
                );
            }
        }
        assert!(covered > 20, "{name}: only {covered} covered pixels");
    }
}

/// Ray from `o` along unit `d`: does it meet the sphere (c, r), and by how much does it clear or
/// miss the surface (distance of closest approach minus r)?
fn sphere_clearance(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<f64> {
    let t = (c - o).dot(d);
    if t <= 0.0 {
        return None;
    }
    Some((o + d * t - c).length() - r)
}

#[test]
fn one_texel_light_casts_the_analytic_sphere_shadow() {
    let scene = scene_from(SPHERE_ON_PLANE, "one-texel");
    let n = 8;
    // One texel of the +Y face, off-centre, so the shadow falls sideways.
    let j = texel_index(n, 2, 2, 5);
    let d = texel_dirs(n)[j];
    let texel = TexelQuadrature::new(n, 1);
    let mut cube = CubeMap::constant(n, [0.0; 3]).unwrap();
    cube.texels[j] = [10.0, 10.0, 10.0];
    // Sampled at its centre the texel is a distant light along d: a hard shadow, and the cosine
    // at d. Integrated it is an area light: the cosine over the texel (its first moment), and a
    // penumbra as wide as the texel, which pixels near the border are left out of.
    for edge_texel_samples in [0, 9] {
        let integrated = edge_texel_samples > 0;
        // One sample at every pixel's centre, where the analytic shadow is evaluated.
        let centres = BakeSettings {
            edge_spp: 0,
            edge_texel_samples,
            ..lossless(n, 2)
        };
        let t = bake(&scene, &centres, &|_| {}).unwrap();
        let (img, _) = relight_wavelet(&t, &full_light(&cube)).unwrap();
        let brute = render_reference(&scene, &cube, &centres).unwrap();
        let cosine = match integrated {
            false => d.y * wavelet_prt::math::cubemap::solid_angles(n)[j],
            true => texel.moments[j].y as f64,
        };
        let penumbra = match integrated {
            false => 0.0,
            true => texel.sin_radius[j] as f64,
        };
        let cam = &scene.camera;
        let (center, radius) = (DVec3::new(0.0, 0.6, 0.0), 0.6);
        let (mut lit, mut shadowed) = (0, 0);
        for y in 0..cam.height {
            for x in 0..cam.width {
                let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
                let (o, dir) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
                if dir.y >= 0.0 {
                    continue;
                }
                let t_ground = -o.y / dir.y;
                let p = o + dir * t_ground;
                // Skip pixels that see the sphere or lie off the ground quad.
                if sphere_clearance(o, dir, center, radius).is_some_and(|c| c < 0.0)
                    || p.x.abs() > 2.0
                    || p.z.abs() > 2.0
                {
                    continue;
                }
                let clearance = sphere_clearance(p, d, center, radius);
                // Stay away from the numerically delicate boundary, and from the penumbra.
                let margin = 1e-3 + penumbra * (center - p).length();
                if clearance.is_some_and(|c| c.abs() < margin) {
                    continue;
                }
                let in_shadow = clearance.is_some_and(|c| c < 0.0);
                let i = (y * cam.width + x) as usize;
                let albedo = [0.8, 0.7, 0.6];
                for (k, a) in albedo.iter().enumerate() {
                    let lit_value = a * 10.0 * cosine / PI;
                    let want = if in_shadow { 0.0 } else { lit_value };
                    // Float rounding of the Haar round trip, relative to the light's
                    // contribution.
                    let tol = ONE_TEXEL_ROUNDING * lit_value;
                    let got = img.pixels[i][k] as f64;
                    assert!(
                        (got - want).abs() <= tol,
                        "integrated {integrated}: pixel ({x}, {y}) channel {k}: got {got}, \
                         want {want} (shadow {in_shadow})"
                    );
                    assert!((brute.pixels[i][k] as f64 - want).abs() <= tol);
                }
                if in_shadow {
                    shadowed += 1;
                } else {
                    lit += 1;
                }
            }
        }
        assert!(
            lit > 50 && shadowed > 5,
            "integrated {integrated}: lit {lit}, shadowed {shadowed}"
        );
    }
}

#[test]
fn lossless_relight_equals_the_brute_force_reference() {
    let scene = scene_from(SPHERE_ON_PLANE, "reference");
    let settings = BakeSettings {
        spp: 4,
        texel_samples: 4,
        ..lossless(8, 3)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/blender_sunrise.exr")).unwrap();
    let ctx = LightContext::new(&t).unwrap();
    let rotation = EnvRotation::new(75.0, 0.0);
    let light = ctx.prepare(&env, rotation).unwrap();
    let req = RelightRequest::Full;
    let (full, _) = relight(&t, &ctx, &light, &req).unwrap();
    let cube = env.to_cube(8, rotation).unwrap();
    let brute = render_reference(&scene, &cube, &settings).unwrap();
    let err = relative_l2(&full, &brute, None).unwrap();
    assert!(err < REFERENCE_MATCH, "full vs reference: {err}");
    // The reference traces the bake's camera sub-samples, so it sees the same coverage, and
    // reports every row done.
    let done = std::sync::atomic::AtomicUsize::new(0);
    let with =
        wavelet_prt::bake::reference::render_reference_with(&scene, &cube, &settings, &|d, n| {
            assert!(d <= n);
            done.fetch_max(d, std::sync::atomic::Ordering::Relaxed);
        })
        .unwrap();
    assert_eq!(with.image, brute);
    assert_eq!(with.coverage, t.coverage);
    assert_eq!(done.into_inner(), scene.camera.height as usize);
    // Wavelet relighting with every term is the same product as full.
    for w in Weighting::ALL {
        let all = RelightRequest::Wavelet {
            k: texel_count(8),
            weighting: w,
        };
        let (img, stats) = relight(&t, &ctx, &light, &all).unwrap();
        assert_eq!(stats.terms, texel_count(8));
        let e = relative_l2(&img, &full, None).unwrap();
        assert!(e < SAME_VALUE, "{w}: all terms vs full {e}");
    }
    // Fewer terms: error decreases as K grows (unweighted selection is the best K-term light).
    let mut last = f64::INFINITY;
    for k in [4, 16, 64, 256, 384] {
        let (img, _) = relight(
            &t,
            &ctx,
            &light,
            &RelightRequest::Wavelet {
                k,
                weighting: Weighting::Unweighted,
            },
        )
        .unwrap();
        let e = relative_l2(&img, &full, Some(&t.coverage)).unwrap();
        assert!(
            e <= last * (1.0 + IMAGE_ERROR_ROUNDING),
            "K = {k}: {e} after {last}"
        );
        last = e;
    }
}

#[test]
fn sh_relight_of_an_unshadowed_plane_is_the_analytic_irradiance() {
    let plane = plane_from_above(5, 5, [1.0, 1.0, 1.0], 5.0);
    let scene = scene_from(&plane, "sh-plane");
    let settings = BakeSettings {
        unshadowed: true,
        texel_samples: 16,
        ..lossless(32, 3)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    // A smooth light with a strong directional part.
    let sky = SunSky::new(40.0, 120.0, 25.0, 5.0).to_latlong(256, 128, 2);
    let light_sh = sky.project_sh(3, EnvRotation::default()).unwrap();
    let (img, _) = relight_sh(&t, &light_sh).unwrap();
    // Analytic: radiance = (albedo / π) E(n), E = clamped cosine ⊛ L, n = +Y.
    let mut irradiance = light_sh.clone();
    sh::convolve_rgb(&mut irradiance, &sh::clamped_cosine_zonal(3));
    let e = sh::reconstruct_rgb(&irradiance, DVec3::Y);
    // The SH transport is the texel-quadrature projection of max(cos, 0) at N = 32 with 16
    // samples per texel: within 1e-3 of the exact lobe coefficients.
    const SH_QUADRATURE: f64 = 2e-3;
    for p in &img.pixels {
        for k in 0..3 {
            assert_rel_close("SH irradiance", p[k] as f64, e[k] / PI, SH_QUADRATURE);
        }
    }
}

#[test]
fn rotations_full_turn_and_sh_rotation() {
    let scene = scene_from(SPHERE_ON_PLANE, "rotation");
    let t = bake(&scene, &lossless(8, 4), &|_| {}).unwrap();
    let ctx = LightContext::new(&t).unwrap();
    let env = EnvMap::load(&assets().join("envmaps/pmndrs_city_overcast.exr")).unwrap();
    let a = ctx.prepare(&env, EnvRotation::default()).unwrap();
    let b = ctx.prepare(&env, EnvRotation::yaw(360.0)).unwrap();
    for method in [Method::Wavelet, Method::Sh, Method::Full] {
        let r = RelightRequest::new(method, 100, Weighting::Area, 4);
        let (ia, _) = relight(&t, &ctx, &a, &r).unwrap();
        let (ib, _) = relight(&t, &ctx, &b, &r).unwrap();
        let e = relative_l2(&ib, &ia, None).unwrap();
        assert!(
            e < SAME_SUM,
            "{method}: 360 degrees changed the image by {e}"
        );
    }
    // The SH light of a turned environment comes from rotating the coefficient vector; it must
    // match projecting the turned map itself (same order), up to the cube-map discretisation of
    // the turned map.
    let rotation = EnvRotation::new(50.0, 30.0);
    let turned = ctx.prepare(&env, rotation).unwrap();
    let projected = ctx
        .basis
        .project_light(&env.to_cube(8, rotation).unwrap())
        .unwrap();
    let (by_rotation, _) = relight_sh(&t, &turned.sh[..16]).unwrap();
    let (by_projection, _) = relight_sh(&t, &projected[..16]).unwrap();
    let (unturned, _) = relight_sh(&t, &a.sh[..16]).unwrap();
    let e = relative_l2(&by_rotation, &by_projection, Some(&t.coverage)).unwrap();
    assert!(
        e < SH_ROTATION_VS_PROJECTION,
        "SH rotation vs rotated projection: {e}"
    );
    // And the rotation did something.
    let moved = relative_l2(&unturned, &by_projection, Some(&t.coverage)).unwrap();
    assert!(
        moved > 10.0 * e,
        "turning changed the image by only {moved}"
    );
}

#[test]
fn tiled_kernel_equals_the_dense_and_sprs_twins() {
    for (w, h, n, q) in [
        (37, 21, 4, Quantization::F32),
        (16, 16, 2, Quantization::Q8),
        (1, 45, 4, Quantization::Q16),
        (33, 17, 4, Quantization::Q8),
    ] {
        let t = random_transport(w, h, n, q, (w * h) as u64, 1.0);
        let c = texel_count(n);
        let mut rng = Rng::new(9, 1);
        for k in [1, 7, c] {
            let light = common::random_light(&mut rng, c, k, true, |rng| {
                [rng.next_f32(), rng.next_f32() - 0.5, 2.0 * rng.next_f32()]
            });
            let (fast, stats) = relight_wavelet(&t, &light).unwrap();
            let dense = relight_dense_reference(&t, &light);
            let e = relative_l2(&fast, &dense, None).unwrap();
            assert!(e < SAME_SUM, "{w}x{h} N={n} K={k}: tiled vs dense {e}");
            let via_sprs = sprs_product(&t, &light);
            let e = relative_l2(&fast, &via_sprs, None).unwrap();
            assert!(e < SAME_SUM, "{w}x{h} N={n} K={k}: tiled vs sprs {e}");
            if k == c {
                assert_eq!(stats.nonzeros_touched, t.nonzeros());
            }
        }
    }
}

/// The product through a plain sprs CSR matrix of every row, then the row weights.
fn sprs_product(t: &Transport, light: &SparseLight) -> Image {
    let c = t.coeff_count();
    let rows = t.row_pixel.len();
    let mut tri = sprs::TriMat::new((rows, c));
    for b in 0..t.block_count() {
        for j in 0..c {
            for (row, v) in t.column(b, j) {
                tri.add_triplet(row, j, v as f64);
            }
        }
    }
    let m: sprs::CsMat<f64> = tri.to_csr();
    let mut out = Image::new(t.meta.width as usize, t.meta.height as usize);
    for ch in 0..3 {
        let mut l = vec![0.0f64; c];
        for (&j, v) in light.indices.iter().zip(&light.values) {
            l[j as usize] = v[ch] as f64;
        }
        let y = &m * &sparse_vector(&l);
        for (r, v) in y.iter() {
            out.pixels[t.row_pixel[r] as usize][ch] += (t.row_weight[r][ch] as f64 * v) as f32;
        }
    }
    out
}

/// The light as a sprs sparse vector.
fn sparse_vector(l: &[f64]) -> sprs::CsVec<f64> {
    let (idx, val): (Vec<usize>, Vec<f64>) = l
        .iter()
        .enumerate()
        .filter(|(_, v)| **v != 0.0)
        .map(|(i, v)| (i, *v))
        .unzip();
    sprs::CsVec::new(l.len(), idx, val)
}

#[test]
fn file_round_trip_and_corruption() {
    let dir = temp_dir("file");
    let t = random_transport(20, 18, 4, Quantization::Q8, 5, 1.0);
    let p = dir.join("t.prt");
    t.save(&p).unwrap();
    let back = Transport::load(&p).unwrap();
    assert_eq!(back, t);
    // No temporary file is left beside it.
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(leftovers.is_empty());
    let bytes = std::fs::read(&p).unwrap();
    let bad = dir.join("bad.prt");
    // Truncated anywhere: an error that says so, never a panic.
    for cut in [0, 4, 8, 100, bytes.len() / 2, bytes.len() - 1] {
        std::fs::write(&bad, &bytes[..cut]).unwrap();
        let e = Transport::load(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.prt"), "cut {cut}: {e}");
    }
    // A flipped bit anywhere: header or data.
    let mut rng = Rng::new(3, 3);
    for _ in 0..40 {
        let mut b = bytes.clone();
        let i = (rng.next_u64() % b.len() as u64) as usize;
        b[i] ^= 1 << (rng.next_u64() % 8);
        std::fs::write(&bad, &b).unwrap();
        assert!(
            Transport::load(&bad).is_err(),
            "bit flip at byte {i} went unnoticed"
        );
    }
    // An absurd header length is refused before anything is allocated.
    let mut b = bytes.clone();
    b[..8].copy_from_slice(&(1u64 << 60).to_le_bytes());
    std::fs::write(&bad, &b).unwrap();
    let e = Transport::load(&bad).unwrap_err().to_string();
    assert!(e.contains("header length"), "{e}");
    // Not a transport file at all.
    std::fs::write(&bad, b"hello, world, this is not a transport").unwrap();
    let e = Transport::load(&bad).unwrap_err().to_string();
    assert!(e.contains("does not fit a file of 37 bytes"), "{e}");
}

#[test]
fn bad_relight_requests_are_clear_errors() {
    let scene = scene_from(SPHERE_ON_PLANE, "bad-requests");
    let t = bake(&scene, &lossless(4, 2), &|_| {}).unwrap();
    let ctx = LightContext::new(&t).unwrap();
    let env = EnvMap::constant(16, 8, [1.0; 3]);
    let light = ctx.prepare(&env, EnvRotation::default()).unwrap();
    let wavelets = |k| RelightRequest::Wavelet {
        k,
        weighting: Weighting::Area,
    };
    for (req, needle) in [
        (wavelets(0), "K = 0"),
        (wavelets(97), "K = 97"),
        (RelightRequest::Sh { order: 3 }, "baked up to order 2"),
    ] {
        let e = relight(&t, &ctx, &light, &req).unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
    }
    let e = "shiny".parse::<Method>().unwrap_err().to_string();
    assert!(e.contains("shiny") && e.contains("wavelet"), "{e}");
    let e = "heavy".parse::<Weighting>().unwrap_err().to_string();
    assert!(e.contains("heavy"), "{e}");
    // A light prepared for another cube size does not fit this transport.
    let other = random_transport(8, 8, 8, Quantization::F32, 1, 1.0);
    let other_ctx = LightContext::new(&other).unwrap();
    let other_light = other_ctx.prepare(&env, EnvRotation::default()).unwrap();
    let e = relight(&t, &ctx, &other_light, &wavelets(10))
        .unwrap_err()
        .to_string();
    assert!(e.contains("N = 8"), "{e}");
}

#[test]
fn thresholded_bake_is_sparser_and_close_to_lossless() {
    let scene = scene_from(SPHERE_ON_PLANE, "threshold");
    let exact = bake(&scene, &lossless(8, 2), &|_| {}).unwrap();
    let sparse = bake(
        &scene,
        &BakeSettings {
            threshold: 0.05,
            ..BakeSettings {
                cube_n: 8,
                sh_order: 2,
                ..BakeSettings::default()
            }
        },
        &|_| {},
    )
    .unwrap();
    assert!(
        sparse.nonzeros() < exact.nonzeros(),
        "{} entries thresholded, {} lossless",
        sparse.nonzeros(),
        exact.nonzeros()
    );
    assert_eq!(sparse.meta.identity.quantization, Quantization::Q8);
    let cube = CubeMap::constant(8, [1.0; 3]).unwrap();
    let (a, _) = relight_wavelet(&exact, &full_light(&cube)).unwrap();
    let (b, _) = relight_wavelet(&sparse, &full_light(&cube)).unwrap();
    // Under constant light only the scaling coefficients matter, and thresholding keeps the
    // largest first: the error stays far below the per-row budget.
    let e = relative_l2(&b, &a, Some(&exact.coverage)).unwrap();
    assert!(e < THRESHOLD_BUDGET, "{e}");
    assert_rel_close(
        "same rows",
        sparse.row_pixel.len() as f64,
        exact.row_pixel.len() as f64,
        SAME_SUM,
    );
}

#[test]
fn glossy_relight_with_every_term_equals_the_reference() {
    let glossy = SPHERE_ON_PLANE.replace(
        "type = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
        "type = \"glossy\"\nalbedo = [0.5, 0.2, 0.1]\nspecular = [0.4, 0.4, 0.4]\nroughness = 0.3",
    );
    let scene = scene_from(&glossy, "glossy");
    let settings = BakeSettings {
        spp: 2,
        texel_samples: 4,
        ..lossless(8, 2)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    // Every sphere pixel has a diffuse and a glossy row, weighted by albedo and specular.
    assert!(t.row_weight.contains(&[0.4, 0.4, 0.4]));
    assert!(t.row_weight.contains(&[0.5, 0.2, 0.1]));
    let env = EnvMap::load(&assets().join("envmaps/blender_studio.exr")).unwrap();
    let full = relit(&t, &env, EnvRotation::default(), RelightRequest::Full);
    let brute = render_reference(
        &scene,
        &env.to_cube(8, EnvRotation::default()).unwrap(),
        &settings,
    )
    .unwrap();
    let err = relative_l2(&full, &brute, None).unwrap();
    assert!(err < REFERENCE_MATCH, "glossy full vs reference: {err}");
    // The glossy lobe is view dependent: the same scene with the lobe removed differs.
    let matte = scene_from(
        &glossy.replace("specular = [0.4, 0.4, 0.4]", "specular = [0.0, 0.0, 0.0]"),
        "glossy-matte",
    );
    let plain = render_reference(
        &matte,
        &env.to_cube(8, EnvRotation::default()).unwrap(),
        &settings,
    )
    .unwrap();
    assert!(relative_l2(&plain, &brute, None).unwrap() > 0.01);
}

#[test]
fn one_bounce_off_a_wall_adds_the_expected_light() {
    // Ground (albedo a_g) meeting a tall, long vertical wall (albedo a_w) at x = 0, under sky
    // radiance c above the horizon and none below. A ground point at the wall's foot sees sky over
    // half its cosine-weighted hemisphere (direct: a_g c / 2) and wall over the other half. Every
    // wall point sees sky over the upper half of its hemisphere (direct radiance a_w c / 2), so
    // one bounce adds a_g (a_w c / 2) / 2 = a_g a_w c / 4.
    let scene_text = r#"
[camera]
eye = [-0.12, 0.6, 0.0]
target = [-0.12, 0.0, 0.0]
up = [1.0, 0.0, 0.0]
fov_y_deg = 6.0
width = 4
height = 4
[material.ground]
type = "diffuse"
albedo = [0.5, 0.5, 0.5]
[material.wall]
type = "diffuse"
albedo = [0.8, 0.4, 0.2]
[[shape]]
type = "quad"
corners = [[-400.0, 0.0, -400.0], [-400.0, 0.0, 400.0], [0.0, 0.0, 400.0], [0.0, 0.0, -400.0]]
material = "ground"
[[shape]]
type = "quad"
corners = [[0.0, 0.0, -400.0], [0.0, 0.0, 400.0], [0.0, 400.0, 400.0], [0.0, 400.0, -400.0]]
material = "wall"
"#;
    let scene = scene_from(scene_text, "wall");
    let n = 16;
    let c = 1.0f32;
    let sky = CubeMap::from_fn(n, |d| [c * (d.y > 0.0) as u8 as f32; 3]).unwrap();
    let settings = |bounces| BakeSettings {
        texel_samples: 16,
        bounces,
        paths: 4096,
        ..lossless(n, 1)
    };
    let direct = bake(&scene, &settings(0), &|_| {}).unwrap();
    let bounced = bake(&scene, &settings(1), &|_| {}).unwrap();
    let (d, _) = relight_wavelet(&direct, &full_light(&sky)).unwrap();
    let (b, _) = relight_wavelet(&bounced, &full_light(&sky)).unwrap();
    let mean = |img: &Image, k: usize| {
        img.pixels.iter().map(|p| p[k] as f64).sum::<f64>() / img.pixels.len() as f64
    };
    let (a_g, a_w) = (0.5, [0.8, 0.4, 0.2]);
    for (k, wall) in a_w.iter().enumerate() {
        // Quadrature of the texel-sampled sky and the wall's finite size: 1%.
        assert_rel_close(
            "direct",
            mean(&d, k),
            a_g * c as f64 / 2.0,
            WALL_FOOT_DIRECT,
        );
        // 4096 paths a sub-sample over 16 pixels: the Monte Carlo error of the added light is
        // about 0.5%; the wall is seen slightly under half from 0.12 away: a few percent.
        let added = mean(&b, k) - mean(&d, k);
        assert_rel_close(
            format!("one bounce, channel {k}"),
            added,
            a_g * wall * c as f64 / 4.0,
            WALL_BOUNCE,
        );
    }
    // Colour bleeding: the ground picks up the wall's colour, so channels differ.
    assert!(mean(&b, 0) > mean(&b, 2) * 1.2);
}

#[test]
fn relight_with_bounces_equals_the_reference_with_the_same_paths() {
    let scene = scene_from(SPHERE_ON_PLANE, "bounces");
    let settings = BakeSettings {
        spp: 2,
        bounces: 2,
        paths: 16,
        ..lossless(8, 2)
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    assert_eq!((t.meta.identity.bounces, t.meta.identity.paths), (2, 16));
    // Three colour rows per covered pixel carry the interreflections.
    assert!(t.row_weight.contains(&[1.0, 0.0, 0.0]));
    let env = EnvMap::load(&assets().join("envmaps/blender_city.exr")).unwrap();
    let cube = env.to_cube(8, EnvRotation::default()).unwrap();
    let (full, _) = relight_wavelet(&t, &full_light(&cube)).unwrap();
    let brute = render_reference(&scene, &cube, &settings).unwrap();
    let err = relative_l2(&full, &brute, None).unwrap();
    assert!(err < REFERENCE_MATCH, "bounced full vs reference: {err}");
    let direct = render_reference(
        &scene,
        &cube,
        &BakeSettings {
            bounces: 0,
            ..settings.clone()
        },
    )
    .unwrap();
    let sum = |img: &Image| img.pixels.iter().map(|p| p[1] as f64).sum::<f64>();
    let (with, without) = (sum(&full), sum(&direct));
    assert!(
        with > without * 1.001,
        "interreflections add light: {with} vs {without}"
    );
}

/// Adaptive antialiasing: pixels whose corners see different things take `edge_spp`
/// sub-samples, the rest one. At an edge pixel the relit value is the mean of the brute-force
/// values of its sub-samples (the reference rendered with that many samples at every pixel takes
/// the same ones there); elsewhere it is the one-sample reference.
#[test]
fn edge_pixels_take_the_mean_of_their_subsamples_and_others_one_sample() {
    use wavelet_prt::bake::EdgeMap;
    use wavelet_prt::scene::trace::Tracer;
    let scene = scene_from(SPHERE_ON_PLANE, "edges");
    let adaptive = BakeSettings {
        spp: 1,
        edge_spp: 16,
        texel_samples: 4,
        ..lossless(8, 2)
    };
    let t = bake(&scene, &adaptive, &|_| {}).unwrap();
    assert_eq!(t.meta.identity.edge_spp, 16);
    let env = EnvMap::from_spec("sun:35,60,4").unwrap();
    let relit = relit(&t, &env, EnvRotation::default(), RelightRequest::Full);
    let cube = env.to_cube(8, EnvRotation::default()).unwrap();
    let uniform = |spp| {
        let s = BakeSettings {
            spp,
            edge_spp: 0,
            ..adaptive.clone()
        };
        render_reference(&scene, &cube, &s).unwrap()
    };
    let (one, sixteen) = (uniform(1), uniform(16));
    let map = EdgeMap::new(&scene, &Tracer::new(&scene), &adaptive);
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut edges = 0;
    for y in 0..h {
        for x in 0..w {
            let edge = map.is_edge(x, y);
            let want = if edge { &sixteen } else { &one };
            let i = (y * w + x) as usize;
            let (got, want) = (relit.pixels[i], want.pixels[i]);
            for c in 0..3 {
                let scale = want[c].abs().max(EDGE_PIXEL_SCALE_FLOOR) as f64;
                assert!(
                    ((got[c] - want[c]) as f64).abs() <= REFERENCE_MATCH * scale,
                    "pixel ({x}, {y}), edge {edge}, channel {c}: {} against {}",
                    got[c],
                    want[c]
                );
            }
            edges += edge as usize;
        }
    }
    // The sphere's outline, the ground's border, and the shadow borders beside the contact of a
    // sphere that fills much of this small view: some pixels, not most.
    let total = (w * h) as usize;
    assert!(
        edges > 20 && edges < total / 2,
        "{edges} edge pixels of {total}"
    );
    // Sub-samples that miss the ground leave fractional coverage only where they were taken.
    assert!(t.coverage.iter().any(|c| *c > 0.0 && *c < 1.0));
}

/// Shadow borders: a ground pixel is an edge pixel where a shadow's outline sweeps across it, for
/// a light somewhere, more than 1% of its unshadowed light. Beside a sphere's contact, the
/// sphere fills much of the sky and its outline moves fast across a pixel; far away it fills too
/// little of the sky to matter. An unshadowed bake finds no shadow borders.
#[test]
fn shadow_borders_near_a_contact_are_edges_and_the_far_ground_is_not() {
    use wavelet_prt::bake::EdgeMap;
    use wavelet_prt::scene::trace::Tracer;
    let scene = scene_from(
        r#"[camera]
eye = [0.0, 3.0, 6.0]
target = [0.0, 0.0, -2.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 60.0
width = 64
height = 48

[material.ground]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]

[material.clay]
type = "diffuse"
albedo = [0.8, 0.3, 0.2]

[[shape]]
type = "quad"
corners = [[-40.0, 0.0, -40.0], [-40.0, 0.0, 40.0], [40.0, 0.0, 40.0], [40.0, 0.0, -40.0]]
material = "ground"

[[shape]]
type = "sphere"
center = [0.0, 0.6, 0.0]
radius = 0.6
material = "clay"
"#,
        "shadow-borders",
    );
    let tracer = Tracer::new(&scene);
    let settings = BakeSettings {
        edge_spp: 4,
        ..BakeSettings::default()
    };
    let shadows = EdgeMap::new(&scene, &tracer, &settings);
    let unshadowed = BakeSettings {
        unshadowed: true,
        ..settings.clone()
    };
    let geometry = EdgeMap::new(&scene, &tracer, &unshadowed);
    let cam = &scene.camera;
    let (mut near, mut near_edges, mut far) = (0, 0, 0);
    for y in 0..cam.height {
        for x in 0..cam.width {
            // Geometric edges are found with or without shadows.
            assert!(
                !geometry.is_edge(x, y) || shadows.is_edge(x, y),
                "pixel ({x}, {y})"
            );
            if geometry.is_edge(x, y) {
                continue;
            }
            let ray = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
            let Some(hit) = tracer.closest_hit(ray.origin, ray.dir, f32::INFINITY) else {
                continue;
            };
            // The ground (the sphere touches its plane at one point only).
            if hit.point.y.abs() > 1e-4 {
                continue;
            }
            let from_contact = hit.point.length();
            if (0.65..0.9).contains(&from_contact) {
                near += 1;
                near_edges += shadows.is_edge(x, y) as usize;
            } else if from_contact > 8.0 {
                far += 1;
                assert!(
                    !shadows.is_edge(x, y),
                    "pixel ({x}, {y}), {from_contact:.1} from the sphere"
                );
            }
        }
    }
    assert!(near >= 8 && far >= 100, "{near} pixels near, {far} far");
    assert_eq!(near_edges, near, "of the ground pixels beside the contact");
    // The flat ground and the sphere alone: a few geometric edges, more with shadow borders.
    assert!(shadows.count() > geometry.count() + near);
    // No extra samples, no edges.
    let one_sample = BakeSettings {
        edge_spp: 1,
        ..settings
    };
    let off = EdgeMap::new(&scene, &tracer, &one_sample);
    assert_eq!(off.count(), 0);
}

/// A tile lays its rows out kind by kind: every pixel's first lobe, then the glossy lobes, then
/// each pixel's three interreflection rows together, red, green, blue. Rows that keep the same
/// coefficients then share strips: laid out pixel by pixel, each strip mixed dense direct rows
/// with sparse bounce rows, and about a third of its values were entries.
#[test]
fn a_tile_lays_its_rows_out_kind_by_kind_so_bounce_rows_fill_their_strips() {
    let glossy = SPHERE_ON_PLANE.replace(
        "[material.clay]\ntype = \"diffuse\"\nalbedo = [0.8, 0.3, 0.2]",
        "[material.clay]\ntype = \"glossy\"\nalbedo = [0.6, 0.3, 0.2]\nspecular = [0.3, 0.3, \
         0.3]\nroughness = 0.3",
    );
    assert_ne!(glossy, SPHERE_ON_PLANE);
    let scene = scene_from(&glossy, "row-kinds");
    let settings = BakeSettings {
        cube_n: 8,
        sh_order: 2,
        edge_spp: 0,
        bounces: 1,
        paths: 16,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let channel = |r: usize| {
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .iter()
            .position(|w| *w == t.row_weight[r])
    };
    let mut glossy_pixels = 0;
    for tile in t.tile_row_start.windows(2) {
        let rows = tile[0] as usize..tile[1] as usize;
        let first_channel = rows
            .clone()
            .find(|&r| channel(r).is_some())
            .unwrap_or(rows.end);
        // Lobes first: each pixel's first lobe in pixel order, then the second lobes.
        let lobes: Vec<u32> = (rows.start..first_channel)
            .map(|r| t.row_pixel[r])
            .collect();
        // The first lobes run in increasing pixel order; the second lobes start where it falls.
        let first_count = lobes
            .windows(2)
            .position(|w| w[1] <= w[0])
            .map_or(lobes.len(), |i| i + 1);
        let (first, second) = lobes.split_at(first_count);
        assert!(
            second.windows(2).all(|w| w[0] < w[1]),
            "second lobes out of order"
        );
        assert!(second.iter().all(|p| first.contains(p)));
        glossy_pixels += second.len();
        // Then the channels, three rows a pixel, red, green and blue, pixels in order.
        let channels: Vec<usize> = (first_channel..rows.end).collect();
        assert_eq!(channels.len() % 3, 0);
        for (k, triple) in channels.chunks(3).enumerate() {
            let p = t.row_pixel[triple[0]];
            for (c, &r) in triple.iter().enumerate() {
                assert_eq!((channel(r), t.row_pixel[r]), (Some(c), p));
            }
            if k > 0 {
                assert!(p > t.row_pixel[triple[0] - 3]);
            }
            assert!(
                first.contains(&p),
                "pixel {p}: bounce rows without a lobe row"
            );
        }
    }
    assert!(glossy_pixels > 20, "{glossy_pixels} glossy pixels");
    // Most values of the strips that hold entries are entries (0.3 laid out pixel by pixel;
    // the empty strips of slots stored whole are left out).
    let held = (0..t.strips.strip_count())
        .filter(|&k| (0..8).any(|i| t.strips.values.raw(8 * k + i) != 0.0))
        .count();
    let fill = t.nonzeros() as f64 / (8 * held) as f64;
    assert!(fill > 0.5, "strips {fill:.2} full");
}

/// The tile baker of the benchmarks bakes the tiles a bake does: over every tile, as many shadow
/// rays as the bake's statistics count, tile by tile the same whatever the order; a tile past
/// the last is an error.
#[test]
fn the_tile_baker_traces_the_rays_of_the_bake() {
    use wavelet_prt::bake::with_tile_baker;
    let scene = common::scene_from(common::SPHERE_ON_PLANE, "tile-baker");
    let settings = BakeSettings {
        cube_n: 4,
        sh_order: 2,
        ..BakeSettings::default()
    };
    let t = bake(&scene, &settings, &|_| {}).unwrap();
    let (forward, backward, past) = with_tile_baker(&scene, &settings, |tiles, one| {
        let forward: Vec<u64> = (0..tiles).map(|k| one(k).unwrap()).collect();
        let mut backward: Vec<u64> = (0..tiles).rev().map(|k| one(k).unwrap()).collect();
        backward.reverse();
        (forward, backward, one(tiles).is_err())
    })
    .unwrap();
    assert!(forward.len() > 1 && past);
    assert_eq!(forward, backward);
    assert_eq!(forward.iter().sum::<u64>(), t.meta.stats.shadow_rays);
}
