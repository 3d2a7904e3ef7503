//! Identities and known answers for the SH module: scipy reference values, orthonormality, the
//! addition theorem, rotation against the rotated function, exact kernel coefficients, irradiance.

use std::f64::consts::PI;

use glam::{DMat3, DQuat, DVec3};

use super::*;

/// The scipy reference values are double precision; only rounding separates them from ours.
const REFERENCE_TOLERANCE: f64 = 1e-12;
/// Quadrature rules here are exact for the polynomials integrated, so only summation rounding
/// (thousands of terms of size ~1) remains.
const EXACT_QUADRATURE_TOLERANCE: f64 = 1e-10;
/// Two f64 evaluations of the same polynomial by different formulas (closed form vs recurrence,
/// direct vs rotated): a few ulps per operation, tens of operations.
const SAME_VALUE_TOLERANCE: f64 = 1e-12;
/// Rotated expansions summed over up to 32^2 terms after a 32-step matrix recurrence: rounding
/// grows with the band, but stays orders of magnitude below any convention error (O(1)).
const ROTATION_TOLERANCE_HIGH_BANDS: f64 = 1e-9;
/// The clamped-cosine coefficients of the conventions (`crate::conventions`), printed to 6
/// significant digits.
const PRINTED_SIX_DIGITS: f64 = 1e-5;
/// The hemisphere light is discontinuous, so its order-16 irradiance carries truncation error; the
/// cosine kernel's coefficients fall as l^-5/2, which leaves well under 1 %.
const HEMISPHERE_TRUNCATION: f64 = 0.01 * PI;
/// f32 storage of values up to ~2 in magnitude.
const F32_ROUNDING: f64 = 1e-6;

use crate::test_support::assert_close;

use crate::test_support::Rng;

/// The SH tests' random inputs, from the shared seeded generator.
trait ShSamples {
    fn symmetric(&mut self) -> f64;
    fn rotation(&mut self) -> DMat3;
    fn coefficients(&mut self, order: usize) -> Vec<f64>;
}

impl ShSamples for Rng {
    fn symmetric(&mut self) -> f64 {
        2.0 * self.unit() - 1.0
    }

    /// Uniform on SO(3) (Shoemake's unit quaternion from three uniforms).
    fn rotation(&mut self) -> DMat3 {
        let (u1, u2, u3) = (self.unit(), self.unit(), self.unit());
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let q = DQuat::from_xyzw(
            a * (2.0 * PI * u2).sin(),
            a * (2.0 * PI * u2).cos(),
            b * (2.0 * PI * u3).sin(),
            b * (2.0 * PI * u3).cos(),
        );
        DMat3::from_quat(q.normalize())
    }

    fn coefficients(&mut self, order: usize) -> Vec<f64> {
        (0..coeff_count(order)).map(|_| self.symmetric()).collect()
    }
}

/// Random directions plus the axes, where poles and sign conventions bite.
fn test_directions(rng: &mut Rng, count: usize) -> Vec<DVec3> {
    let mut dirs = vec![
        DVec3::X,
        DVec3::Y,
        DVec3::Z,
        -DVec3::X,
        -DVec3::Y,
        -DVec3::Z,
    ];
    dirs.extend((0..count).map(|_| rng.direction()));
    dirs
}

/// Legendre P_n(x) and P_(n-1)(x) by Bonnet's recurrence (independent of the module's code).
fn legendre_pair(n: usize, x: f64) -> (f64, f64) {
    let (mut older, mut old) = (0.0, 1.0);
    for k in 1..=n {
        let k = k as f64;
        (older, old) = (old, ((2.0 * k - 1.0) * x * old - (k - 1.0) * older) / k);
    }
    (old, older)
}

/// Gauss–Legendre nodes and weights on [-1, 1]: exact for polynomials of degree < 2n.
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let derivative = |x: f64| {
                let (p, p_prev) = legendre_pair(n, x);
                n as f64 * (x * p - p_prev) / (x * x - 1.0)
            };
            for _ in 0..100 {
                let step = legendre_pair(n, x).0 / derivative(x);
                x -= step;
                if step.abs() < 1e-16 {
                    break;
                }
            }
            let d = derivative(x);
            (x, 2.0 / ((1.0 - x * x) * d * d))
        })
        .collect()
}

/// Product rule on the part of the sphere with z in [z_lo, z_hi]: Gauss–Legendre in z times the
/// uniform rule in phi. Exact for polynomials in z of degree < 2 n_z times trigonometric
/// polynomials in phi of degree < n_phi, so exact for Y_i Y_j when n_z, n_phi exceed the order.
fn sphere_quadrature(n_z: usize, n_phi: usize, z_lo: f64, z_hi: f64) -> Vec<(DVec3, f64)> {
    let (mid, half) = (0.5 * (z_lo + z_hi), 0.5 * (z_hi - z_lo));
    let dphi = 2.0 * PI / n_phi as f64;
    let mut points = Vec::with_capacity(n_z * n_phi);
    for (t, w) in gauss_legendre(n_z) {
        let z = mid + half * t;
        let r = (1.0 - z * z).sqrt();
        for j in 0..n_phi {
            let phi = dphi * (j as f64 + 0.5);
            points.push((DVec3::new(r * phi.cos(), r * phi.sin(), z), w * half * dphi));
        }
    }
    points
}

fn full_sphere(order: usize) -> Vec<(DVec3, f64)> {
    sphere_quadrature(order + 1, 2 * order + 1, -1.0, 1.0)
}

/// Projects f over the given quadrature points.
fn project_fn(order: usize, points: &[(DVec3, f64)], f: impl Fn(DVec3) -> f64) -> Vec<f64> {
    project(order, points.iter().map(|&(d, w)| (d, f(d), w)))
}

fn assert_all_close(what: &str, actual: &[f64], expected: &[f64], tolerance: f64) {
    assert_eq!(actual.len(), expected.len(), "{what}: lengths differ");
    for (i, (a, e)) in actual.iter().zip(expected).enumerate() {
        assert_close(format!("{what} [{i}]"), *a, *e, tolerance);
    }
}

#[test]
fn index_enumerates_bands_in_order() {
    let mut next = 0;
    for l in 0..MAX_ORDER {
        for m in -(l as i32)..=l as i32 {
            assert_eq!(index(l, m), next, "index({l}, {m})");
            next += 1;
        }
    }
    assert_eq!(next, coeff_count(MAX_ORDER));
    assert_eq!(index(2, 0), 6);
}

#[test]
fn order_checks_reject_bad_input() {
    assert_eq!(order_from_len(9).unwrap(), 3);
    assert_eq!(order_from_len(coeff_count(MAX_ORDER)).unwrap(), MAX_ORDER);
    for bad in [0, 10, coeff_count(MAX_ORDER + 1)] {
        let err = order_from_len(bad).expect_err("should be rejected");
        assert!(err.to_string().contains(&bad.to_string()), "{err}");
    }
    for bad in [0, MAX_ORDER + 1] {
        let e = check_order(bad).unwrap_err().to_string();
        assert!(
            e.contains(&format!("{bad} is outside 1..={MAX_ORDER}")),
            "{e}"
        );
    }
}

#[test]
fn matches_scipy_reference() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/sh_basis.json");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let order = json["lmax"].as_u64().unwrap() as usize + 1;
    let numbers = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let directions = json["directions"].as_array().unwrap();
    let values = json["values"].as_array().unwrap();
    assert_eq!(directions.len(), values.len());
    assert!(directions.len() >= 6);
    for (dir, expected) in directions.iter().zip(values) {
        let d = numbers(dir);
        let dir = DVec3::new(d[0], d[1], d[2]);
        let expected = numbers(expected);
        assert_eq!(expected.len(), coeff_count(order));
        let (fast, slow) = both_forms(order, dir);
        assert_all_close(
            &format!("eval at {dir}"),
            &fast,
            &expected,
            REFERENCE_TOLERANCE,
        );
        assert_all_close(
            &format!("eval_recurrence at {dir}"),
            &slow,
            &expected,
            REFERENCE_TOLERANCE,
        );
    }
}

#[test]
fn basis_matches_conventions_table() {
    // The table of the conventions (`crate::conventions`), at a direction with all components
    // distinct and non-zero.
    let d = DVec3::new(0.3, -0.5, 0.7).normalize();
    let (x, y, z) = (d.x, d.y, d.z);
    let table = [
        0.282095,
        -0.488603 * y,
        0.488603 * z,
        -0.488603 * x,
        1.092548 * x * y,
        -1.092548 * y * z,
        0.315392 * (3.0 * z * z - 1.0),
        -1.092548 * x * z,
        0.546274 * (x * x - y * y),
    ];
    assert_all_close("order-3 basis", &eval_vec(3, d), &table, PRINTED_SIX_DIGITS);
}

/// Gram matrix sum_k w_k Y_i(d_k) Y_j(d_k) over an exact rule; returns the largest deviation
/// from the identity and where it is.
fn gram_deviation(order: usize) -> (f64, usize, usize) {
    let n = coeff_count(order);
    let mut gram = vec![0.0; n * n];
    let mut y = vec![0.0; n];
    for (d, w) in full_sphere(order) {
        eval(order, d, &mut y);
        for i in 0..n {
            let wy = w * y[i];
            for (g, yj) in gram[i * n..i * n + i + 1].iter_mut().zip(&y) {
                *g += wy * yj;
            }
        }
    }
    let mut worst = (0.0, 0, 0);
    for i in 0..n {
        for j in 0..=i {
            let target = if i == j { 1.0 } else { 0.0 };
            let dev = (gram[i * n + j] - target).abs();
            if dev > worst.0 {
                worst = (dev, i, j);
            }
        }
    }
    worst
}

/// Checks that the SH basis up to `order` is orthonormal under the exact quadrature.
fn assert_orthonormal(order: usize) {
    let (dev, i, j) = gram_deviation(order);
    assert_close(
        format!("Gram[{i}][{j}] - identity"),
        dev,
        0.0,
        EXACT_QUADRATURE_TOLERANCE,
    );
}

#[test]
fn orthonormal_up_to_band_8() {
    assert_orthonormal(9);
}

#[test]
fn orthonormal_up_to_max_order() {
    assert_orthonormal(MAX_ORDER);
}

#[test]
fn addition_theorem_up_to_max_order() {
    // sum_m Y_l^m(a) Y_l^m(b) = (2l+1)/(4 pi) P_l(a.b): checks every m of every band against an
    // independent Legendre recurrence, including the relative signs of the m terms.
    let mut rng = Rng(7);
    let order = MAX_ORDER;
    for _ in 0..50 {
        let (a, b) = (rng.direction(), rng.direction());
        let (ya, yb) = (eval_vec(order, a), eval_vec(order, b));
        for l in 0..order {
            let band = l * l..(l + 1) * (l + 1);
            let sum: f64 = ya[band.clone()]
                .iter()
                .zip(&yb[band])
                .map(|(p, q)| p * q)
                .sum();
            let expected = (2 * l + 1) as f64 / (4.0 * PI) * legendre_pair(l, a.dot(b)).0;
            assert_close(format!("band {l}"), sum, expected, SAME_VALUE_TOLERANCE);
        }
    }
}

/// The basis at `dir` by the closed forms ([`eval`]) and by the recurrence.
fn both_forms(order: usize, dir: DVec3) -> (Vec<f64>, Vec<f64>) {
    let mut fast = vec![0.0; coeff_count(order)];
    let mut slow = vec![0.0; coeff_count(order)];
    eval(order, dir, &mut fast);
    eval_recurrence(order, dir, &mut slow);
    (fast, slow)
}

#[test]
fn closed_forms_match_recurrence() {
    let mut rng = Rng(1);
    let dirs = test_directions(&mut rng, 300);
    for order in 1..=16 {
        for &d in &dirs {
            let (fast, slow) = both_forms(order, d);
            assert_all_close(
                &format!("order {order} at {d}"),
                &fast,
                &slow,
                SAME_VALUE_TOLERANCE,
            );
        }
    }
}

#[test]
fn eval_writes_only_its_coefficients() {
    let mut out = vec![f64::NAN; 20];
    eval(4, DVec3::Z, &mut out);
    assert!(out[..16].iter().all(|v| v.is_finite()));
    assert!(out[16..].iter().all(|v| v.is_nan()));
}

#[test]
fn f32_evaluation_matches_f64() {
    let mut rng = Rng(2);
    for d in test_directions(&mut rng, 50) {
        let mut out = vec![0.0_f32; coeff_count(8)];
        eval_f32_into(8, d.as_vec3(), &mut out);
        let widened: Vec<f64> = out.iter().map(|&v| v as f64).collect();
        assert_all_close("f32 eval", &widened, &eval_vec(8, d), F32_ROUNDING);
    }
}

#[test]
fn projection_round_trips_an_expansion() {
    // A band-limited function projected with an exact rule gives back its coefficients.
    let mut rng = Rng(3);
    let order = 6;
    let f = rng.coefficients(order);
    let points = full_sphere(order);
    let back = project_fn(order, &points, |d| reconstruct(&f, d));
    assert_all_close("re-projected", &back, &f, EXACT_QUADRATURE_TOLERANCE);
}

#[test]
fn rgb_versions_match_scalar_per_channel() {
    let mut rng = Rng(4);
    let order = 5;
    let channels = [
        rng.coefficients(order),
        rng.coefficients(order),
        rng.coefficients(order),
    ];
    let rgb: Vec<[f64; 3]> = (0..coeff_count(order))
        .map(|i| [channels[0][i], channels[1][i], channels[2][i]])
        .collect();
    let d = rng.direction();
    let rotation = Rotation::new(order, rng.rotation()).unwrap();
    let zonal = clamped_cosine_zonal(order);
    let rotated = rotation.apply_rgb(&rgb);
    let mut convolved = rgb.clone();
    convolve_rgb(&mut convolved, &zonal);
    let mut windowed = rgb.clone();
    apply_window_rgb(&mut windowed, Window::Lanczos);
    let points = full_sphere(order);
    let projected = project_rgb(
        order,
        points
            .iter()
            .map(|&(p, w)| (p, reconstruct_rgb(&rgb, p), w)),
    );
    for (c, f) in channels.iter().enumerate() {
        let at = |v: &[[f64; 3]]| v.iter().map(|x| x[c]).collect::<Vec<_>>();
        assert_close(
            "reconstruct_rgb",
            reconstruct_rgb(&rgb, d)[c],
            reconstruct(f, d),
            0.0,
        );
        let mut out = vec![0.0; f.len()];
        rotation.apply(f, &mut out);
        assert_all_close("apply_rgb", &at(&rotated), &out, SAME_VALUE_TOLERANCE);
        let mut g = f.clone();
        convolve(&mut g, &zonal);
        assert_all_close("convolve_rgb", &at(&convolved), &g, 0.0);
        let mut g = f.clone();
        apply_window(&mut g, Window::Lanczos);
        assert_all_close("apply_window_rgb", &at(&windowed), &g, 0.0);
        assert_all_close(
            "project_rgb",
            &at(&projected),
            f,
            EXACT_QUADRATURE_TOLERANCE,
        );
    }
}

/// reconstruct(apply(f), w) against reconstruct(f, R^T w): exact, so any wrong sign, transpose or
/// band-mixing in the recurrence shows.
fn check_rotation_is_rotated_function(order: usize, seed: u64, tolerance: f64) {
    let mut rng = Rng(seed);
    for _ in 0..5 {
        let f = rng.coefficients(order);
        let r = rng.rotation();
        let rotation = Rotation::new(order, r).unwrap();
        let mut g = vec![0.0; f.len()];
        rotation.apply(&f, &mut g);
        for w in test_directions(&mut rng, 40) {
            assert_close(
                format!("order {order}, rotated function at {w}"),
                reconstruct(&g, w),
                reconstruct(&f, r.transpose() * w),
                tolerance,
            );
        }
    }
}

#[test]
fn rotation_equals_rotated_function_up_to_band_8() {
    check_rotation_is_rotated_function(9, 5, SAME_VALUE_TOLERANCE * 100.0);
}

#[test]
fn rotation_equals_rotated_function_up_to_max_order() {
    check_rotation_is_rotated_function(MAX_ORDER, 6, ROTATION_TOLERANCE_HIGH_BANDS);
}

#[test]
fn rotation_equals_quadrature_reprojection_of_band_3() {
    let mut rng = Rng(8);
    let order = 4;
    let mut f = vec![0.0; coeff_count(order)];
    for c in &mut f[9..16] {
        *c = rng.symmetric();
    }
    let r = rng.rotation();
    let points = full_sphere(order);
    let expected = project_fn(order, &points, |w| reconstruct(&f, r.transpose() * w));
    let mut g = vec![0.0; f.len()];
    Rotation::new(order, r).unwrap().apply(&f, &mut g);
    assert_all_close("rotated band 3", &g, &expected, EXACT_QUADRATURE_TOLERANCE);
}

#[test]
fn identity_rotation_is_identity() {
    let rotation = Rotation::new(MAX_ORDER, DMat3::IDENTITY).unwrap();
    for l in 0..MAX_ORDER {
        let n = 2 * l + 1;
        for (k, &v) in rotation.band(l).iter().enumerate() {
            let expected = if k / n == k % n { 1.0 } else { 0.0 };
            assert_close(format!("band {l} entry {k}"), v, expected, 0.0);
        }
    }
}

#[test]
fn rotations_compose() {
    let mut rng = Rng(9);
    let order = 12;
    let f = rng.coefficients(order);
    let (r1, r2) = (rng.rotation(), rng.rotation());
    let mut once = vec![0.0; f.len()];
    let mut twice = vec![0.0; f.len()];
    Rotation::new(order, r1).unwrap().apply(&f, &mut once);
    Rotation::new(order, r2).unwrap().apply(&once, &mut twice);
    let mut combined = vec![0.0; f.len()];
    Rotation::new(order, r2 * r1)
        .unwrap()
        .apply(&f, &mut combined);
    assert_all_close(
        "R2 after R1 vs R2 R1",
        &twice,
        &combined,
        SAME_VALUE_TOLERANCE * 100.0,
    );
}

#[test]
fn rotation_preserves_band_energy() {
    let mut rng = Rng(10);
    let order = MAX_ORDER;
    let f = rng.coefficients(order);
    let mut g = vec![0.0; f.len()];
    Rotation::new(order, rng.rotation())
        .unwrap()
        .apply(&f, &mut g);
    for l in 0..order {
        let band = l * l..(l + 1) * (l + 1);
        let energy = |c: &[f64]| c[band.clone()].iter().map(|x| x * x).sum::<f64>();
        assert_close(
            format!("band {l} energy"),
            energy(&g),
            energy(&f),
            ROTATION_TOLERANCE_HIGH_BANDS,
        );
    }
}

#[test]
fn quarter_turn_about_z_moves_x_lobe_to_y() {
    // Y_1^1 = -k x; turned by +90 degrees about z, x goes to y, giving -k y = Y_1^-1.
    let rotation = Rotation::new(2, DMat3::from_rotation_z(0.5 * PI)).unwrap();
    let mut f = vec![0.0; 4];
    f[index(1, 1)] = 1.0;
    let mut g = vec![0.0; 4];
    rotation.apply(&f, &mut g);
    assert_all_close(
        "rotated Y_1^1",
        &g,
        &[0.0, 1.0, 0.0, 0.0],
        SAME_VALUE_TOLERANCE,
    );
}

#[test]
fn rotated_zonal_lobe_points_along_rotated_axis() {
    // A zonal function about +z turned by R is the same kernel about R z, whose coefficients are
    // sqrt(4 pi / (2l+1)) z_l Y_l^m(R z) (the Funk–Hecke form of a zonal kernel).
    let mut rng = Rng(11);
    let order = 16;
    let zonal = clamped_cosine_zonal(order);
    let mut f = vec![0.0; coeff_count(order)];
    for (l, z) in zonal.iter().enumerate() {
        f[index(l, 0)] = *z;
    }
    for _ in 0..5 {
        let r = rng.rotation();
        let axis = r * DVec3::Z;
        let mut g = vec![0.0; f.len()];
        Rotation::new(order, r).unwrap().apply(&f, &mut g);
        let mut expected = eval_vec(order, axis);
        convolve(&mut expected, &zonal);
        assert_all_close("lobe about R z", &g, &expected, SAME_VALUE_TOLERANCE * 10.0);
    }
}

#[test]
fn rotation_rejects_non_rotations() {
    let bad = [
        DMat3::from_diagonal(DVec3::new(1.0, 1.0, 1.1)),
        DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)),
        DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::new(0.0, 0.0, f64::NAN)),
    ];
    for m in bad {
        let e = Rotation::new(4, m).unwrap_err().to_string();
        assert!(e.contains("not a proper rotation"), "{m}: {e}");
    }
    for order in [0, MAX_ORDER + 1] {
        let e = Rotation::new(order, DMat3::IDENTITY)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("{order} is outside 1..={MAX_ORDER}")),
            "{e}"
        );
    }
    // A rotation built in f32 is still a rotation.
    let f32_built = glam::Mat3::from_rotation_y(0.3).as_dmat3();
    assert!(Rotation::new(4, f32_built).is_ok());
}

#[test]
fn clamped_cosine_matches_conventions() {
    let zonal = clamped_cosine_zonal(3);
    assert_all_close(
        "clamped cosine",
        &zonal,
        &[0.886227, 1.02333, 0.495416],
        PRINTED_SIX_DIGITS,
    );
    let mut coeffs = vec![0.0; 9];
    for (l, z) in zonal.iter().enumerate() {
        coeffs[index(l, 0)] = *z;
    }
    let conventions = [0.886227, 0.0, 1.02333, 0.0, 0.0, 0.0, 0.495416, 0.0, 0.0];
    assert_all_close("lobe vector", &coeffs, &conventions, PRINTED_SIX_DIGITS);
    assert_close("l = 0", zonal[0], PI.sqrt() / 2.0, SAME_VALUE_TOLERANCE);
    assert_close("l = 1", zonal[1], (PI / 3.0).sqrt(), SAME_VALUE_TOLERANCE);
}

#[test]
fn clamped_cosine_matches_quadrature() {
    // max(z, 0) is a polynomial on the upper hemisphere, so a rule on z in [0, 1] is exact. All m
    // are compared, so a kernel that is not zonal would show too.
    let order = MAX_ORDER;
    let points = sphere_quadrature(order + 1, 2 * order + 1, 0.0, 1.0);
    let numeric = project_fn(order, &points, |d| d.z);
    let mut exact = vec![0.0; coeff_count(order)];
    for (l, z) in clamped_cosine_zonal(order).iter().enumerate() {
        exact[index(l, 0)] = *z;
    }
    assert_all_close(
        "clamped cosine",
        &exact,
        &numeric,
        EXACT_QUADRATURE_TOLERANCE,
    );
}

#[test]
fn constant_radiance_gives_irradiance_pi() {
    let mut rng = Rng(12);
    let order = 8;
    let mut radiance = vec![0.0; coeff_count(order)];
    radiance[0] = 2.0 * PI.sqrt();
    convolve(&mut radiance, &clamped_cosine_zonal(order));
    for n in test_directions(&mut rng, 20) {
        assert_close(
            format!("irradiance at {n}"),
            reconstruct(&radiance, n),
            PI,
            SAME_VALUE_TOLERANCE,
        );
    }
}

#[test]
fn hemisphere_light_gives_irradiance_pi_at_zenith() {
    let order = 16;
    // Radiance 1 for z > 0 is the constant 1 on the upper hemisphere: exact rule on z in [0, 1].
    let points = sphere_quadrature(order + 1, 2 * order + 1, 0.0, 1.0);
    let mut irradiance = project_fn(order, &points, |_| 1.0);
    convolve(&mut irradiance, &clamped_cosine_zonal(order));
    let at = |n: DVec3| reconstruct(&irradiance, n);
    assert_close("zenith", at(DVec3::Z), PI, HEMISPHERE_TRUNCATION);
    assert_close("nadir", at(-DVec3::Z), 0.0, HEMISPHERE_TRUNCATION);
    // A horizontal normal sees half of the cosine lobe lit.
    assert_close("horizon", at(DVec3::X), 0.5 * PI, HEMISPHERE_TRUNCATION);
}

#[test]
fn isotropic_phase_has_only_band_0() {
    let zonal = henyey_greenstein_zonal(6, 0.0);
    let expected = [1.0 / (2.0 * PI.sqrt()), 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_all_close("HG g = 0", &zonal, &expected, SAME_VALUE_TOLERANCE);
}

#[test]
fn henyey_greenstein_matches_quadrature() {
    // The HG lobe is analytic with its nearest singularity at cos = (1 + g^2) / (2g) = 1.25 for
    // g = 0.5, so 64 Gauss nodes converge far below the tolerance.
    let g = 0.5;
    let order = 9;
    let phase = |d: DVec3| (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * d.z).powf(1.5));
    let points = sphere_quadrature(64, 2 * order + 1, -1.0, 1.0);
    let numeric = project_fn(order, &points, phase);
    let mut exact = vec![0.0; coeff_count(order)];
    for (l, z) in henyey_greenstein_zonal(order, g).iter().enumerate() {
        exact[index(l, 0)] = *z;
    }
    assert_all_close("HG g = 0.5", &exact, &numeric, EXACT_QUADRATURE_TOLERANCE);
}

#[test]
fn window_factors_are_valid() {
    for order in 1..=MAX_ORDER {
        for window in [Window::Lanczos, Window::Hanning] {
            let w = window_factors(order, window);
            assert_eq!(w.len(), order);
            assert_eq!(w[0], 1.0, "{window:?} order {order}");
            assert!(
                w.iter().all(|&x| x > 0.0 && x <= 1.0),
                "{window:?} order {order}: {w:?}"
            );
            assert!(
                w.windows(2).all(|p| p[1] < p[0]),
                "{window:?} order {order} not decreasing: {w:?}"
            );
        }
        assert!(
            window_factors(order, Window::None)
                .iter()
                .all(|&x| x == 1.0)
        );
    }
    // Lanczos sigma of band 1 at order 2 is sinc(pi / 2) = 2 / pi; Hann gives 1/2.
    assert_close(
        "Lanczos",
        window_factors(2, Window::Lanczos)[1],
        2.0 / PI,
        SAME_VALUE_TOLERANCE,
    );
    assert_close(
        "Hanning",
        window_factors(2, Window::Hanning)[1],
        0.5,
        SAME_VALUE_TOLERANCE,
    );
}

#[test]
fn windowing_reduces_ringing_of_a_sun() {
    // A delta light projects to Y(d); its truncated reconstruction rings negative away from d.
    let order = 8;
    let sun = DVec3::new(0.2, 0.3, 0.9).normalize();
    let raw = project(order, [(sun, 1.0, 1.0)]);
    let probes = full_sphere(40);
    let most_negative = |c: &[f64]| {
        probes
            .iter()
            .map(|&(d, _)| reconstruct(c, d))
            .fold(f64::INFINITY, f64::min)
    };
    let raw_min = most_negative(&raw);
    assert!(
        raw_min < 0.0,
        "the unwindowed sun should ring, min {raw_min}"
    );
    for window in [Window::Lanczos, Window::Hanning] {
        let mut windowed = raw.clone();
        apply_window(&mut windowed, window);
        let min = most_negative(&windowed);
        assert!(
            min > raw_min,
            "{window:?}: most negative value {min} not above unwindowed {raw_min}"
        );
    }
}
