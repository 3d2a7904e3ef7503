use super::*;
use crate::medium::sweep::Sweeper;
use crate::medium::{DensityGrid, DensitySource, Medium};

/// Optical depth swept from the centre of a hard-edged sphere (σ = 2, radius 0.75, 48³ voxels)
/// against σ r = 1.5: sampled at voxel centres, the edge sits where the grid puts it to within
/// about half a voxel, a depth of 0.5 · 2/48 · σ ≈ 0.042, more or less of it along each direction
/// as the faceting goes.
const SPHERE_CENTRE_DEPTH: f32 = 0.04;
/// T0 at the centre of the same sphere against 2√π e^−1.5, relative: T0 averages e^−τ over the 512
/// swept directions, and each τ is off 1.5 by up to about `SPHERE_CENTRE_DEPTH` (a factor of
/// about e^±0.04) as the faceting goes, erring both ways so that the mean lands closer.
const SPHERE_CENTRE_T0: f32 = 0.03;
/// The higher SH bands there against 0, relative to the wanted T0: the symmetric sphere gives
/// them nothing, so only what the grid's faceting leaves after the opposite directions cancel.
const SPHERE_CENTRE_FACETING: f32 = 0.02;
/// Sweep against direct march in a soft cloud, |difference| / (1 + depth) over 480 voxels: the
/// bilinear steps blur the depth a little over long paths. Measured mean 0.35%...
const SWEEP_MEAN: f32 = 0.01;
/// ...the 95th percentile, so that large differences stay confined to the few longest paths...
const SWEEP_P95: f32 = 0.03;
/// ...and the worst voxel, on the far side of the grid: measured 8%.
const SWEEP_WORST: f32 = 0.12;
/// An axis-aligned sweep of a slab against the direct march: the two step through the same
/// voxels along the axis, so they differ by f32 sums and by how each samples the trilinear ramp
/// at the slab's face; this much absolute, for depths near 0...
const AXIS_SWEEP_ABS: f32 = 1e-4;
/// ...and this much of the depth, for the rest.
const AXIS_SWEEP_REL: f32 = 0.01;

fn medium(dims: [usize; 3], f: impl Fn(Vec3) -> f32, extinction: f32) -> Medium {
    Medium {
        grid: DensityGrid::from_fn(dims, Vec3::splat(-1.0), Vec3::splat(1.0), f),
        extinction,
        albedo: Vec3::ONE,
        g: 0.0,
    }
}

fn sphere(n: usize, radius: f32, extinction: f32) -> Medium {
    let src = DensitySource::Ellipsoid {
        center: Vec3::ZERO,
        radii: Vec3::splat(radius),
        falloff: 0.0,
    };
    medium([n; 3], |p| src.density(p), extinction)
}

#[test]
fn empty_space_is_exactly_2_sqrt_pi_in_band_0_and_nothing_else() {
    let m = medium([6, 5, 4], |_| 0.0, 3.0);
    let t = bake_transfer(&m, &TransferSettings::default(), &|_, _| {}).unwrap();
    let dc = 2.0 * std::f32::consts::PI.sqrt();
    for v in t.chunks_exact(9) {
        assert_eq!(v[0], dc);
        assert!(v[1..].iter().all(|x| *x == 0.0));
    }
}

#[test]
fn sphere_centre_sees_exp_minus_sigma_r_every_way() {
    // Constant sigma = 2 inside radius 0.75: from the centre tau = 1.5 along every direction.
    let m = sphere(48, 0.75, 2.0);
    let vt = baked_order_3(&m);
    let mut v = [0.0f32; 9];
    vt.transfer_at(Vec3::ZERO, &mut v);
    let want = 2.0 * std::f32::consts::PI.sqrt() * (-1.5f32).exp();
    assert!(
        (v[0] - want).abs() < SPHERE_CENTRE_T0 * want,
        "T0 {} vs {want}",
        v[0]
    );
    // Symmetric: the higher bands vanish up to the grid's faceting.
    assert!(
        v[1..]
            .iter()
            .all(|x| x.abs() < SPHERE_CENTRE_FACETING * want),
        "{v:?}"
    );
    // Every direction from the centre: sweep against exp(-sigma r).
    let s = Sweeper::new(&m);
    for d in fibonacci_directions(40) {
        let tau = s.depth(d).at(Vec3::ZERO);
        assert!((tau - 1.5).abs() < SPHERE_CENTRE_DEPTH, "{d}: tau {tau}");
    }
}

#[test]
fn sweep_matches_a_direct_march_in_a_soft_medium() {
    let src = DensitySource::Cloud {
        center: Vec3::ZERO,
        radii: Vec3::splat(0.8),
        seed: 5,
        frequency: 2.0,
        octaves: 3,
        coverage: 0.7,
    };
    let m = medium([40, 32, 36], |p| src.density(p), 3.0);
    let s = Sweeper::new(&m);
    let mut errors = Vec::new();
    for (k, d) in fibonacci_directions(24).into_iter().enumerate() {
        let grid = s.depth(d);
        for i in 0..20 {
            let (x, y, z) = ((7 * i + k) % 40, (5 * i + 3 * k) % 32, (11 * i + k) % 36);
            let p = m.grid.min + m.grid.cell() * (Vec3::new(x as f32, y as f32, z as f32) + 0.5);
            let march = m.optical_depth(p, d, f32::INFINITY);
            let sweep = grid.voxel(x, y, z);
            errors.push((sweep - march).abs() / (1.0 + march));
        }
    }
    // Bilinear steps blur the optical depth a little over long paths: small on average, a few
    // percent at the far side of the grid (measured: mean 0.35%, worst 8%, 480 voxels).
    errors.sort_by(f32::total_cmp);
    let mean = errors.iter().sum::<f32>() / errors.len() as f32;
    let p95 = errors[errors.len() * 95 / 100];
    let worst = errors[errors.len() - 1];
    assert!(mean < SWEEP_MEAN, "mean relative difference {mean}");
    assert!(p95 < SWEEP_P95, "95th percentile {p95}");
    assert!(worst < SWEEP_WORST, "worst {worst}");
}

#[test]
fn axis_aligned_sweep_of_a_slab_is_exact() {
    // Density 1 for y > 0: looking up, tau is the density's integral above the voxel.
    let m = medium([4, 16, 4], |p| (p.y > 0.0) as u8 as f32, 1.0);
    let s = Sweeper::new(&m);
    let g = s.depth(Vec3::Y);
    let cell = 2.0 / 16.0;
    for y in 0..16 {
        let march = m.optical_depth(
            Vec3::new(0.1, -1.0 + (y as f32 + 0.5) * cell, 0.1),
            Vec3::Y,
            f32::INFINITY,
        );
        assert!(
            (g.voxel(1, y, 2) - march).abs() < AXIS_SWEEP_ABS + AXIS_SWEEP_REL * march,
            "y {y}"
        );
    }
}

/// `m`'s transfer baked at order 3 with the default settings, with its metadata for 512
/// directions.
fn baked_order_3(m: &Medium) -> VolumeTransfer {
    VolumeTransfer {
        meta: meta_for(m, 3, 512),
        density: m.grid.data.clone(),
        transfer: bake_transfer(m, &TransferSettings::default(), &|_, _| {}).unwrap(),
        scatter: None,
    }
}

pub(crate) fn meta_for(m: &Medium, order: usize, directions: usize) -> VolumeMeta {
    VolumeMeta {
        dims: m.grid.dims,
        min: m.grid.min.to_array(),
        max: m.grid.max.to_array(),
        extinction: m.extinction,
        albedo: m.albedo.to_array(),
        g: m.g,
        sh_order: order,
        directions,
        camera: CameraMeta {
            eye: [0.0, 0.0, 3.0],
            target: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 40.0,
        },
        width: 32,
        height: 24,
        scene_hash: "0".into(),
        scatter: None,
    }
}

#[test]
fn file_round_trip_and_damage() {
    let m = sphere(8, 0.7, 2.0);
    let vt = baked_order_3(&m);
    let dir = std::env::temp_dir().join(format!("prt-vol-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("v.prtv");
    vt.save(&path).unwrap();
    assert_eq!(VolumeTransfer::load(&path).unwrap(), vt);
    let mut bytes = std::fs::read(&path).unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let e = VolumeTransfer::load(&path).unwrap_err().to_string();
    assert!(e.contains("checksum"), "{e}");
    std::fs::write(&path, b"junk").unwrap();
    let e = VolumeTransfer::load(&path).unwrap_err().to_string();
    assert!(e.contains("not a volume transfer file"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

/// A small sphere with three scattering orders baked coarsely: the medium, its settings and
/// its fields.
fn small_scatter() -> (Medium, TransferSettings, scatter::ScatterFields) {
    let m = sphere(6, 0.7, 4.0);
    let settings = TransferSettings {
        sh_order: 2,
        directions: 32,
        scatter: ScatterSettings {
            orders: 3,
            angular: 2,
            light: 2,
            directions: 16,
        },
    };
    let fields = scatter::bake_scatter(&m, &settings.scatter, &|_, _| {}).unwrap();
    (m, settings, fields)
}

#[test]
fn scattered_fields_round_trip_and_lying_headers_are_refused() {
    let (m, settings, fields) = small_scatter();
    let scatter_meta = ScatterMeta {
        orders: fields.orders(),
        angular: fields.angular,
        light: fields.light,
        directions: fields.directions,
        tail_ratio: fields.tail_ratio,
    };
    let vt = VolumeTransfer {
        meta: VolumeMeta {
            scatter: Some(scatter_meta.clone()),
            ..meta_for(&m, 2, 32)
        },
        density: m.grid.data.clone(),
        transfer: bake_transfer(&m, &settings, &|_, _| {}).unwrap(),
        scatter: Some(fields),
    };
    let dir = std::env::temp_dir().join(format!("prt-vol-scatter-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("v.prtv");
    vt.save(&path).unwrap();
    let back = VolumeTransfer::load(&path).unwrap();
    assert_eq!(back.orders(), 3);
    // The fields come back in half precision (11 bits of mantissa); the rest exactly.
    let (a, b) = (vt.scatter.as_ref().unwrap(), back.scatter.as_ref().unwrap());
    for (x, y) in a.fields.iter().flatten().zip(b.fields.iter().flatten()) {
        assert!((x - y).abs() <= 5e-4 * x.abs() + 6e-8, "{x} came back {y}");
    }
    assert_eq!(
        VolumeTransfer {
            scatter: None,
            ..back.clone()
        },
        VolumeTransfer {
            scatter: None,
            ..vt.clone()
        }
    );
    assert_eq!(
        (a.tail_ratio, a.angular, a.light),
        (b.tail_ratio, b.angular, b.light)
    );
    // Each lie is sealed as a real file would be, so only the loader's checks can catch it.
    let lies: [(&str, VolumeTransfer, &str); 4] = [
        (
            "more orders than the tensor holds",
            VolumeTransfer {
                meta: VolumeMeta {
                    scatter: Some(ScatterMeta {
                        orders: 5,
                        ..scatter_meta.clone()
                    }),
                    ..vt.meta.clone()
                },
                ..vt.clone()
            },
            "tensor `scatter`: expected",
        ),
        (
            "a tensor without its metadata",
            VolumeTransfer {
                meta: VolumeMeta {
                    scatter: None,
                    ..vt.meta.clone()
                },
                ..vt.clone()
            },
            "without its metadata",
        ),
        (
            "a tail ratio of 1, an infinite tail",
            VolumeTransfer {
                meta: VolumeMeta {
                    scatter: Some(ScatterMeta {
                        tail_ratio: 1.0,
                        ..scatter_meta.clone()
                    }),
                    ..vt.meta.clone()
                },
                ..vt.clone()
            },
            "tail ratio",
        ),
        (
            "a light order past the largest",
            VolumeTransfer {
                meta: VolumeMeta {
                    scatter: Some(ScatterMeta {
                        light: 40,
                        ..scatter_meta.clone()
                    }),
                    ..vt.meta.clone()
                },
                ..vt.clone()
            },
            "light's SH order",
        ),
    ];
    for (what, lie, want) in lies {
        lie.save(&path).unwrap();
        let e = VolumeTransfer::load(&path).unwrap_err().to_string();
        assert!(e.contains(want), "{what}: {e}");
        assert!(
            e.contains("v.prtv"),
            "{what}: the error names the file: {e}"
        );
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_light_in_another_look_equals_one_made_afresh() {
    let (m, settings, fields) = small_scatter();
    let vt = VolumeTransfer {
        meta: VolumeMeta {
            scatter: Some(ScatterMeta {
                orders: fields.orders(),
                angular: fields.angular,
                light: fields.light,
                directions: fields.directions,
                tail_ratio: fields.tail_ratio,
            }),
            ..meta_for(&m, 2, 32)
        },
        density: m.grid.data.clone(),
        transfer: bake_transfer(&m, &settings, &|_, _| {}).unwrap(),
        scatter: Some(fields),
    };
    let cube = crate::math::cubemap::CubeMap::constant(4, [1.0, 0.5, 0.25]).unwrap();
    let base = MediumLook::of(&vt);
    let first = VolumeLight::new(&vt, &cube, &base).unwrap();
    // The phase table kept (albedo, orders, tail) and made anew (g, SH order).
    for look in [
        MediumLook {
            albedo: Vec3::splat(0.5),
            ..base.clone()
        },
        MediumLook {
            orders: 1,
            ..base.clone()
        },
        MediumLook {
            tail: false,
            ..base.clone()
        },
        MediumLook {
            g: -0.2,
            ..base.clone()
        },
        MediumLook {
            sh_order: 1,
            ..base.clone()
        },
    ] {
        let fresh = VolumeLight::new(&vt, &cube, &look).unwrap();
        let kept = first.clone().with_look(&vt, &cube, &look).unwrap();
        assert_eq!(kept, fresh, "{look:?}");
    }
}
