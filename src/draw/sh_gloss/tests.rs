use super::*;
use crate::draw::lobe::tests::glossy;
use crate::math::cube_pyramid::dir_to_morton;
use crate::math::cubemap::{CubeMap, solid_angles, texel_dirs};
use crate::scene::visibility::Visibility;

/// Visibility of one glossy vertex (vertex 0, material 0 of roughness `r`, white) open where
/// `open` says, at face size `n`.
fn one_vertex(n: usize, r: f32, open: impl Fn(DVec3) -> bool) -> Visibility {
    let mut bits = vec![0u32; Visibility::words(n)];
    for d in texel_dirs(n) {
        if open(d) {
            let m = dir_to_morton(n, d);
            bits[m / 32] |= 1 << (m % 32);
        }
    }
    Visibility::new(n, 1, vec![0], bits, vec![[1.0, 1.0, 1.0, r * r]]).unwrap()
}

/// A smooth light on an N-cube: brighter towards +y and +x, coloured.
fn smooth_light(n: usize) -> CubeMap {
    CubeMap::from_fn(n, |d| {
        let v = (1.0 + 0.8 * d.y + 0.4 * d.x + 0.3 * d.x * d.z) as f32;
        [v, 0.8 * v, 0.6 * v + 0.1]
    })
    .unwrap()
}

#[test]
fn a_fully_open_matrix_is_the_identity_and_a_shut_one_zero() {
    let open = one_vertex(16, 0.5, |_| true);
    let t = ShTransfer::new(&open, 4).unwrap();
    let nn = 16;
    let mut out = vec![[0.0f32; 3]; nn];
    for k in 0..nn {
        let mut e = vec![[0.0f32; 3]; nn];
        e[k] = [1.0, 2.0, 3.0];
        t.transfer_into(0, &e, &mut out);
        for (i, o) in out.iter().enumerate() {
            let want = if i == k { 1.0 } else { 0.0 };
            for c in 0..3 {
                // Orthonormal up to the texel centres' quadrature of band-3 products (0.23%
                // at N = 16).
                assert!(
                    (o[c] - want * e[k][c]).abs() < 4e-3 * e[k][c],
                    "{k} {i} {o:?}"
                );
            }
        }
    }
    let shut = one_vertex(16, 0.5, |_| false);
    let t = ShTransfer::new(&shut, 4).unwrap();
    assert!(
        t.transferred(&[[1.0; 3]; 16])
            .iter()
            .flatten()
            .all(|&v| v == 0.0)
    );
    assert!(ShTransfer::new(&shut, 0).is_err() && ShTransfer::new(&shut, 9).is_err());
}

/// `M · l` against the projection onto SH, by a sum over the open texels, of the light's own
/// order-n reconstruction times the visibility: the glossy transfer of Sloan et al. by brute
/// force, the matrix never formed.
#[test]
fn the_transfer_is_the_projection_of_the_shadowed_light() {
    let n = 16;
    let order = 5;
    // Open above a tilted horizon and outside a cone (an occluder).
    let up = DVec3::new(0.3, 1.0, 0.2).normalize();
    let cone = DVec3::new(0.8, 0.5, 0.0).normalize();
    let open = |d: DVec3| d.dot(up) > 0.0 && d.dot(cone) < 0.9;
    let vis = one_vertex(n, 0.5, open);
    let pyramid = CubePyramid::new(&smooth_light(n)).unwrap();
    let light = pyramid_sh(&pyramid, order);
    let got = ShTransfer::new(&vis, order).unwrap().transferred(&light);
    let nn = order * order;
    let mut want = vec![[0.0f64; 3]; nn];
    let omega = solid_angles(n);
    let mut y = vec![0.0; nn];
    for (d, w) in texel_dirs(n).iter().zip(&omega) {
        if !open(*d) {
            continue;
        }
        sh::eval(order, *d, &mut y);
        for c in 0..3 {
            let l: f64 = (0..nn).map(|k| light[k][c] as f64 * y[k]).sum();
            for k in 0..nn {
                want[k][c] += l * y[k] * w;
            }
        }
    }
    let scale = want.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    for k in 0..nn {
        for c in 0..3 {
            assert!(
                (got[k][c] as f64 - want[k][c]).abs() < 1e-5 * scale,
                "{k} {c}: {} {}",
                got[k][c],
                want[k][c]
            );
        }
    }
}

/// The exit radiance a pixel gets is the transferred radiance, reconstructed, integrated
/// against the lobe about the reflection direction by brute force over a fine cube: the band
/// factors, the basis at the reflection and the interpolation together.
#[test]
fn a_pixel_is_the_transferred_light_integrated_against_the_lobe() {
    let order = 6;
    let roughness = 0.5f32;
    let vis = one_vertex(16, roughness, |d| d.y > -0.2);
    let pyramid = CubePyramid::new(&smooth_light(16)).unwrap();
    let transfer = ShTransfer::new(&vis, order).unwrap();
    let normals = [Vec3::new(0.2, 1.0, 0.1).normalize()];
    let materials = [0u32];
    let gloss = ShGloss::new(glossy(&normals, &materials, &vis), &transfer, &pyramid);
    gloss.check(1).unwrap();
    assert!(gloss.check(2).is_err());
    let coeffs = gloss.coefficients(0).to_vec();
    let fine = 128;
    let dirs = texel_dirs(fine);
    let omega = solid_angles(fine);
    let nn = order * order;
    let mut y = vec![0.0; nn];
    for to_eye in [
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(0.5, 0.7, 0.3).normalize(),
        DVec3::new(-0.6, 0.4, 0.2).normalize(),
    ] {
        let got = gloss.shade([0; 3], [1.0, 0.0, 0.0], to_eye);
        let n = normals[0].as_dvec3();
        let r = n * (2.0 * n.dot(to_eye)) - to_eye;
        let mut want = DVec3::ZERO;
        for (d, w) in dirs.iter().zip(&omega) {
            let t = d.dot(r);
            let l = Vec3::new((1.0 - t * t).max(0.0).sqrt() as f32, 0.0, t as f32);
            let k = ggx_cosine(Vec3::Z, Vec3::Z, l, roughness * roughness) as f64;
            if k == 0.0 {
                continue;
            }
            sh::eval(order, *d, &mut y);
            let c: DVec3 = (0..nn)
                .map(|i| Vec3::from(coeffs[i]).as_dvec3() * y[i])
                .sum();
            want += c * k * w;
        }
        assert!(
            (got - want).length() < 5e-3 * want.length(),
            "{to_eye}: {got} against {want}"
        );
    }
}

#[test]
fn the_band_factors_hold_the_lobes_albedo_and_narrow_lobes_keep_more_bands() {
    // Band 0 is the directional albedo at normal incidence (√(4π) · Y_0^0 = 1).
    for alpha in [0.04f32, 0.25] {
        let bands = ggx_bands(alpha, 8);
        let albedo: f64 = texel_dirs(128)
            .iter()
            .zip(solid_angles(128))
            .map(|(d, w)| ggx_cosine(Vec3::Z, Vec3::Z, d.as_vec3(), alpha) as f64 * w)
            .sum();
        assert!(
            (bands[0] - albedo).abs() < 3e-3 * albedo,
            "{bands:?} {albedo}"
        );
        assert!(bands.iter().all(|b| *b > 0.0 && *b <= bands[0] * 1.0001));
    }
    let (sharp, broad) = (ggx_bands(0.04, 8), ggx_bands(0.25, 8));
    assert!(sharp[7] / sharp[0] > broad[7] / broad[0]);
}
