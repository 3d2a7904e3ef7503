//! A bake's identity: what a file records about how it was baked, made from the settings in one
//! place, read back from the file, turned back into settings, and the one test of reuse.

mod common;

use common::{SPHERE_ON_PLANE, plane_from_above, scene_from, temp_dir};
use wavelet_prt::bake::bounce::BounceVisibility;
use wavelet_prt::bake::{BakeSettings, bake, load_if_baked_with};
use wavelet_prt::store::budget::Budget;
use wavelet_prt::store::quant::Quantization;
use wavelet_prt::store::transport::{BakeDomain, Transport};

fn small() -> BakeSettings {
    BakeSettings {
        cube_n: 4,
        sh_order: 2,
        ..BakeSettings::default()
    }
}

/// Settings that differ from [`small`] in one recorded choice each.
fn variants() -> Vec<(&'static str, BakeSettings)> {
    let s = small();
    vec![
        ("default", s.clone()),
        (
            "cube",
            BakeSettings {
                cube_n: 8,
                ..s.clone()
            },
        ),
        (
            "SH order",
            BakeSettings {
                sh_order: 3,
                ..s.clone()
            },
        ),
        (
            "spp",
            BakeSettings {
                spp: 2,
                ..s.clone()
            },
        ),
        (
            "edge spp",
            BakeSettings {
                edge_spp: 9,
                ..s.clone()
            },
        ),
        (
            "texel samples",
            BakeSettings {
                texel_samples: 5,
                ..s.clone()
            },
        ),
        (
            "edge texel samples",
            BakeSettings {
                edge_texel_samples: 4,
                ..s.clone()
            },
        ),
        (
            "unshadowed",
            BakeSettings {
                unshadowed: true,
                ..s.clone()
            },
        ),
        (
            "seed",
            BakeSettings {
                seed: 9,
                ..s.clone()
            },
        ),
        (
            "threshold",
            BakeSettings {
                threshold: 0.05,
                ..s.clone()
            },
        ),
        (
            "budget",
            BakeSettings {
                budget: Budget::Area,
                ..s.clone()
            },
        ),
        (
            "quantisation",
            BakeSettings {
                quantization: Quantization::Q16,
                ..s.clone()
            },
        ),
        (
            "lossless",
            BakeSettings {
                lossless: true,
                ..s.clone()
            },
        ),
        (
            "shard",
            BakeSettings {
                shard: Some([0, 2]),
                ..s.clone()
            },
        ),
        (
            "bounces",
            BakeSettings {
                bounces: 1,
                paths: 4,
                ..s.clone()
            },
        ),
        (
            "bounce visibility",
            BakeSettings {
                bounces: 1,
                paths: 4,
                bounce_visibility: BounceVisibility::Exact,
                ..s.clone()
            },
        ),
        (
            "cache spacing",
            BakeSettings {
                bounces: 1,
                paths: 4,
                cache_spacing: 8.0,
                ..s.clone()
            },
        ),
        (
            "per vertex",
            BakeSettings {
                domain: BakeDomain::Vertices { edge_length: 0.8 },
                ..s.clone()
            },
        ),
    ]
}

#[test]
fn every_recorded_choice_changes_the_identity_and_settings_come_back_from_it() {
    let scene = scene_from(SPHERE_ON_PLANE, "identity-variants");
    let t = bake(&scene, &small(), &|_| {}).unwrap();
    let ids: Vec<_> = variants()
        .into_iter()
        .map(|(name, s)| (name, s.identity(&scene).unwrap()))
        .collect();
    for (i, (a, ia)) in ids.iter().enumerate() {
        for (b, ib) in &ids[i + 1..] {
            assert_ne!(ia, ib, "{a} and {b} have one identity");
        }
        // The settings a file's metadata gives bake the same identity again.
        let mut meta = t.meta.clone();
        meta.identity = ia.clone();
        let back = BakeSettings::from_meta(&meta).identity(&scene).unwrap();
        assert_eq!(
            &back, ia,
            "{a}: settings from the metadata bake another identity"
        );
    }
    // A real bake records exactly the identity its settings give.
    assert_eq!(t.meta.identity, small().identity(&scene).unwrap());
}

#[test]
fn what_a_file_cannot_tell_apart_is_one_identity() {
    let scene = scene_from(SPHERE_ON_PLANE, "identity-same");
    let s = small();
    let id = |s: &BakeSettings| s.identity(&scene).unwrap();
    // Edge samples no more than spp sample every pixel alike.
    assert_eq!(
        id(&BakeSettings {
            edge_spp: 1,
            ..s.clone()
        }),
        id(&BakeSettings {
            edge_spp: 0,
            ..s.clone()
        })
    );
    // Texel samples round up to a square: 3 is the 2 x 2 grid of 4.
    assert_eq!(
        id(&BakeSettings {
            texel_samples: 3,
            ..s.clone()
        }),
        id(&BakeSettings {
            texel_samples: 4,
            ..s.clone()
        })
    );
    // A lossless bake drops nothing, whatever threshold, budget or quantisation is asked.
    let lossless = BakeSettings {
        lossless: true,
        ..s.clone()
    };
    let other = BakeSettings {
        threshold: 0.2,
        budget: Budget::Sun,
        quantization: Quantization::Q16,
        ..lossless.clone()
    };
    assert_eq!(id(&lossless), id(&other));
    assert_eq!(id(&lossless).threshold, 0.0);
    assert_eq!(id(&lossless).quantization, Quantization::F32);
    // Without bounces the paths and their settings are not recorded.
    assert_eq!(
        id(&BakeSettings {
            paths: 7,
            cache_spacing: 9.0,
            ..s.clone()
        }),
        id(&s)
    );
    // A per-vertex bake has no pixels, so no edge samples.
    let pv = BakeSettings {
        domain: BakeDomain::Vertices { edge_length: 0.8 },
        ..s.clone()
    };
    assert_eq!(
        id(&BakeSettings {
            edge_spp: 16,
            ..pv.clone()
        }),
        id(&pv)
    );
    assert_eq!(id(&pv).domain, BakeDomain::Vertices { edge_length: 0.8 });
    // Another scene is another identity.
    let plane = scene_from(&plane_from_above(16, 16, [0.5; 3], 1.0), "identity-plane");
    assert_ne!(s.identity(&plane).unwrap().scene_hash, id(&s).scene_hash);
}

#[test]
fn a_file_is_reused_exactly_when_its_identity_is_the_settings() {
    let scene = scene_from(SPHERE_ON_PLANE, "identity-reuse");
    let dir = temp_dir("identity-reuse");
    let path = dir.join("t.prt");
    let s = small();
    bake(&scene, &s, &|_| {}).unwrap().save(&path).unwrap();
    let reused = load_if_baked_with(&path, &scene, &s).expect("the same settings reuse it");
    assert_eq!(reused, Transport::load(&path).unwrap());
    // Same identity in other words: reused.
    let same = BakeSettings {
        texel_samples: 1,
        paths: 3,
        ..s.clone()
    };
    assert!(load_if_baked_with(&path, &scene, &same).is_some());
    for (name, other) in variants().into_iter().skip(1) {
        assert!(
            load_if_baked_with(&path, &scene, &other).is_none(),
            "a file baked with other {name} was reused"
        );
    }
    // A medium's rules are the scene's: settings that it refuses never reuse anything.
    let fog = scene_from(&common::fog_scene(0.0, 16, 16), "identity-fog");
    let err = BakeSettings {
        domain: BakeDomain::Vertices { edge_length: 0.5 },
        ..s
    }
    .identity(&fog)
    .unwrap_err()
    .to_string();
    assert!(err.contains("per pixel only"), "{err}");
}
