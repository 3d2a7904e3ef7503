//! Texels integrated rather than sampled at their centres (`--edge-texel-samples`), against the
//! texel sum with 64 stratified directions a texel: the converged image that
//! `tests/interreflections.rs` holds the independent path tracer to. One direction a texel casts
//! a small sun's shadow as hard copies a texel apart and samples a narrow glossy lobe at a few
//! points; the integrated texels must come several times closer to the converged image, and a
//! bake of them must relight to what the texel reference sums.

mod common;

use common::{full_light, sunny_cube};

use wavelet_prt::bake::reference::render_reference;
use wavelet_prt::bake::{BakeSettings, bake};
use wavelet_prt::math::sampling::TexelSamples;
use wavelet_prt::output::film::Image;
use wavelet_prt::output::metrics::relative_l2;
use wavelet_prt::relight::relight_wavelet;
use wavelet_prt::store::transport::BakeDomain;

/// The integrated texels' relative L2 from the converged texel sum under a small sun, at most:
/// what remains is the centre visibility of texels away from a border and the sub-texels of
/// those on one (the third of a 3 x 3 grid towards each side the border crosses), and the
/// jitter of the 64 directions (measured: 0.78% matte and glossy).
const INTEGRATED_ERROR: f64 = 0.012;
/// How many times farther one direction a texel must be (measured: 4.8% and 5.0%, 6.2x and
/// 6.4x farther).
const POINT_OVER_INTEGRATED: f64 = 3.0;
/// A lossless bake with integrated texels relit with every term against the texel reference
/// with the same integration: the same sums in another order, to f32 rounding.
const BAKE_VS_REFERENCE: f64 = 1e-4;

/// The sphere on the ground, glossy (GGX roughness 0.2) when `glossy`.
fn sphere_scene(glossy: bool) -> wavelet_prt::scene::Scene {
    common::sphere_scene(
        glossy.then_some(0.2),
        if glossy { "glossy" } else { "matte" },
    )
}

fn settings(texel_samples: u32, edge_texel_samples: u32) -> BakeSettings {
    BakeSettings {
        cube_n: 16,
        edge_spp: 0,
        texel_samples,
        edge_texel_samples,
        ..BakeSettings::default()
    }
}

#[test]
fn integrated_texels_come_close_to_the_converged_texel_sum() {
    let cube = sunny_cube();
    for glossy in [false, true] {
        let scene = sphere_scene(glossy);
        let converged = render_reference(&scene, &cube, &settings(64, 0)).unwrap();
        let point = render_reference(&scene, &cube, &settings(1, 0)).unwrap();
        let integrated = render_reference(&scene, &cube, &settings(1, 9)).unwrap();
        let e_point = relative_l2(&point, &converged, None).unwrap();
        let e_int = relative_l2(&integrated, &converged, None).unwrap();
        assert!(
            e_int < INTEGRATED_ERROR,
            "glossy {glossy}: integrated {e_int} (point {e_point})"
        );
        assert!(
            e_point > POINT_OVER_INTEGRATED * e_int,
            "glossy {glossy}: point {e_point} against integrated {e_int}"
        );
    }
}

#[test]
fn the_default_integrates_texels_of_a_view_and_only_one_direction_a_texel_takes_the_quadrature() {
    let d = BakeSettings::default();
    assert_eq!((d.texel_samples, d.edge_texel_samples), (1, 9));
    assert_eq!(d.stored_edge_texel_samples(), 9);
    // The identity records the border rule with the samples, and only with them.
    let scene = sphere_scene(false);
    assert!(d.identity(&scene).unwrap().edge_texels_towards);
    let centres = BakeSettings {
        edge_texel_samples: 0,
        ..d.clone()
    };
    assert!(!centres.identity(&scene).unwrap().edge_texels_towards);
    // Rounded up to a square; off with several directions a texel or at most one sub-texel.
    assert_eq!(settings(1, 5).stored_edge_texel_samples(), 9);
    assert_eq!(settings(4, 9).stored_edge_texel_samples(), 0);
    assert_eq!(settings(1, 1).stored_edge_texel_samples(), 0);
    let per_vertex = BakeSettings {
        domain: BakeDomain::Vertices { edge_length: 0.2 },
        ..settings(1, 9)
    };
    assert_eq!(per_vertex.stored_edge_texel_samples(), 0);
    // Only one direction a texel takes the quadrature.
    assert!(TexelSamples::new(8, 1, 1).refined(9).refine.is_some());
    assert!(TexelSamples::new(8, 4, 1).refined(9).refine.is_none());
    assert!(TexelSamples::new(8, 1, 1).refined(1).refine.is_none());
    // At most 64 sub-texels.
    assert!(settings(1, 65).validate().is_err());
    assert!(settings(1, 64).validate().is_ok());
}

#[test]
fn a_bake_of_integrated_texels_relights_to_the_texel_reference() {
    let cube = sunny_cube();
    for glossy in [false, true] {
        let scene = sphere_scene(glossy);
        let s = BakeSettings {
            lossless: true,
            ..settings(1, 9)
        };
        let t = bake(&scene, &s, &|_| {}).unwrap();
        assert_eq!(t.meta.identity.edge_texel_samples, 9);
        let img: Image = relight_wavelet(&t, &full_light(&cube)).unwrap().0;
        let reference = render_reference(&scene, &cube, &s).unwrap();
        let err = relative_l2(&img, &reference, None).unwrap();
        assert!(err < BAKE_VS_REFERENCE, "glossy {glossy}: {err}");
    }
}
