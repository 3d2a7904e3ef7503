//! What integrating over a cube texel rather than sampling its centre needs, computed once per
//! cube size: each texel's centre, solid angle and first moment ∫ ω dω (so that a clamped cosine
//! over a texel wholly above a surface is exact, `n · moment`), how far its corners lie from its
//! centre (whether a surface's horizon can cross it), its four neighbours across face borders,
//! and a grid of sub-texels with their exact solid angles (the quadrature of a texel that needs
//! more than its centre: a shadow border, the horizon, a narrow glossy lobe).

use glam::{DVec3, Vec3};

use crate::math::cubemap::{dir_to_texel, face_st_to_dir, patch_solid_angle, texel_count};

/// Sub-cells per side of the grid the first moments are summed over (midpoint rule: each cell's
/// centre direction times its exact solid angle, which overstates the length by about δ²/12
/// for a cell δ wide; against 256 x 256 cells, the worst texel is off by 1.9e-6 relative at
/// N = 32, 2.9e-5 at N = 8 and 8.3e-5 at N = 1).
const MOMENT_SIDE: usize = 16;

/// Per-texel geometry of a cube of face size N and its sub-texel quadrature.
#[derive(Clone, Debug)]
pub struct TexelQuadrature {
    /// Face size N.
    pub n: usize,
    /// Sub-texels per side of a texel's quadrature grid.
    pub side: usize,
    /// Unit direction of each texel's centre.
    pub centres: Vec<Vec3>,
    /// Each texel's exact solid angle.
    pub solid_angles: Vec<f32>,
    /// Each texel's first moment ∫ ω dω over its solid angle.
    pub moments: Vec<Vec3>,
    /// The sine of the largest angle between a texel's centre and its corners: a plane through
    /// the origin with unit normal n crosses the texel only if |n · centre| < this.
    pub sin_radius: Vec<f32>,
    /// The largest angle between any texel's centre and its corners, in radians.
    pub max_radius: f32,
    /// The texels across each texel's four sides: −s, +s, −t, +t (across a face border, the
    /// texel of the adjacent face the step lands in).
    pub neighbours: Vec<[u32; 4]>,
    /// Sub-texel centre directions, `side²` per texel, texel-major, row-major inside.
    pub sub_dirs: Vec<Vec3>,
    /// Sub-texel exact solid angles, as `sub_dirs`; a texel's sum to its solid angle.
    pub sub_weights: Vec<f32>,
    /// The sub-texel whose centre is the texel's centre (odd `side`), whose ray is the centre's.
    pub centre_sub: Option<usize>,
}

impl TexelQuadrature {
    /// The quadrature of a cube of face size `n` with `side` x `side` sub-texels a texel.
    pub fn new(n: usize, side: usize) -> TexelQuadrature {
        let side = side.max(1);
        let count = texel_count(n);
        let step = 2.0 / n as f64;
        let mut q = TexelQuadrature {
            n,
            side,
            centres: Vec::with_capacity(count),
            solid_angles: Vec::with_capacity(count),
            moments: Vec::new(),
            sin_radius: Vec::with_capacity(count),
            max_radius: 0.0,
            neighbours: Vec::with_capacity(count),
            sub_dirs: Vec::with_capacity(count * side * side),
            sub_weights: Vec::with_capacity(count * side * side),
            centre_sub: (side % 2 == 1).then_some((side / 2) * side + side / 2),
        };
        // The corner of sub-cell i of a k x k grid over the texel at (s0, t0), row-major, and
        // the cell's side.
        let corner = |s0: f64, t0: f64, k: usize, i: usize| {
            let h = step / k as f64;
            let (a, b) = ((i / k) as f64, (i % k) as f64);
            (s0 + b * h, t0 + a * h, h)
        };
        // Unit direction and solid angle of the sub-grid cells of a texel, row-major.
        let cells = move |face: usize, s0: f64, t0: f64, k: usize| {
            (0..k * k).map(move |i| {
                let (cs, ct, h) = corner(s0, t0, k, i);
                let d = face_st_to_dir(face, cs + 0.5 * h, ct + 0.5 * h).normalize();
                (d, patch_solid_angle(cs, ct, cs + h, ct + h))
            })
        };
        // The first moments, each texel's cells' solid angles taken once for the six faces
        // (they are the same on each): the arctangents of the solid angles were most of the
        // quadrature's time.
        let mut moments = vec![Vec3::ZERO; count];
        let mut weights = vec![0.0f64; MOMENT_SIDE * MOMENT_SIDE];
        for texel in 0..n * n {
            let (s0, t0) = (
                (texel % n) as f64 * step - 1.0,
                (texel / n) as f64 * step - 1.0,
            );
            for (i, w) in weights.iter_mut().enumerate() {
                let (cs, ct, h) = corner(s0, t0, MOMENT_SIDE, i);
                *w = patch_solid_angle(cs, ct, cs + h, ct + h);
            }
            for face in 0..6 {
                let moment = weights.iter().enumerate().fold(DVec3::ZERO, |m, (i, &w)| {
                    let (cs, ct, h) = corner(s0, t0, MOMENT_SIDE, i);
                    m + face_st_to_dir(face, cs + 0.5 * h, ct + 0.5 * h).normalize() * w
                });
                moments[face * n * n + texel] = moment.as_vec3();
            }
        }
        q.moments = moments;
        for j in 0..count {
            let (face, row, col) = (j / (n * n), (j / n) % n, j % n);
            let (s0, t0) = (col as f64 * step - 1.0, row as f64 * step - 1.0);
            let centre = face_st_to_dir(face, s0 + 0.5 * step, t0 + 0.5 * step).normalize();
            q.centres.push(centre.as_vec3());
            q.solid_angles
                .push(patch_solid_angle(s0, t0, s0 + step, t0 + step) as f32);
            let radius = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .iter()
                .map(|(a, b)| {
                    let corner = face_st_to_dir(face, s0 + a * step, t0 + b * step).normalize();
                    centre.dot(corner).clamp(-1.0, 1.0).acos()
                })
                .fold(0.0f64, f64::max);
            q.sin_radius.push(radius.sin() as f32);
            q.max_radius = q.max_radius.max(radius as f32);
            let across = |ds: f64, dt: f64| {
                let d = face_st_to_dir(face, s0 + (0.5 + ds) * step, t0 + (0.5 + dt) * step);
                dir_to_texel(n, d) as u32
            };
            q.neighbours.push([
                across(-1.0, 0.0),
                across(1.0, 0.0),
                across(0.0, -1.0),
                across(0.0, 1.0),
            ]);
            for (d, w) in cells(face, s0, t0, side) {
                q.sub_dirs.push(d.as_vec3());
                q.sub_weights.push(w as f32);
            }
        }
        q
    }

    /// Whether sub-texel `s` lies in the half of its texel towards one of the sides `sides`
    /// (−s, +s, −t, +t, as `neighbours`): strictly past the middle column or row, which an odd
    /// `side` leaves in neither half.
    #[inline]
    pub fn towards(&self, s: usize, sides: [bool; 4]) -> bool {
        let (row, col) = (2 * (s / self.side), 2 * (s % self.side));
        let middle = self.side - 1;
        (sides[0] && col < middle)
            || (sides[1] && col > middle)
            || (sides[2] && row < middle)
            || (sides[3] && row > middle)
    }

    /// The sub-texel directions of texel `j`.
    #[inline]
    pub fn subs(&self, j: usize) -> (&[Vec3], &[f32]) {
        let m = self.side * self.side;
        (
            &self.sub_dirs[j * m..(j + 1) * m],
            &self.sub_weights[j * m..(j + 1) * m],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::cubemap::solid_angles;

    #[test]
    fn sub_texels_lie_towards_the_sides_of_their_half() {
        let q = TexelQuadrature::new(2, 3);
        let picked = |sides: [bool; 4]| (0..9).filter(|&s| q.towards(s, sides)).collect::<Vec<_>>();
        // Row-major: column 0 is towards −s, row 2 towards +t; the centre is towards nothing.
        assert_eq!(picked([true, false, false, false]), [0, 3, 6]);
        assert_eq!(picked([false, true, false, false]), [2, 5, 8]);
        assert_eq!(picked([false, false, true, false]), [0, 1, 2]);
        assert_eq!(picked([false, false, false, true]), [6, 7, 8]);
        assert_eq!(picked([true, false, true, false]), [0, 1, 2, 3, 6]);
        assert_eq!(picked([true; 4]), [0, 1, 2, 3, 5, 6, 7, 8]);
        assert!(picked([false; 4]).is_empty());
        // An even grid has no middle: every sub-texel is in a half both ways.
        let q = TexelQuadrature::new(2, 2);
        let picked = |sides: [bool; 4]| (0..4).filter(|&s| q.towards(s, sides)).collect::<Vec<_>>();
        assert_eq!(picked([true, false, false, false]), [0, 2]);
        assert_eq!(picked([false, false, false, true]), [2, 3]);
    }

    #[test]
    fn sub_texels_and_moments_integrate_the_sphere() {
        let q = TexelQuadrature::new(8, 3);
        let exact = solid_angles(8);
        for (j, &exact) in exact.iter().enumerate() {
            let (_, w) = q.subs(j);
            let sum: f32 = w.iter().sum();
            assert!((sum - exact as f32).abs() < 1e-5 * exact as f32);
            assert!((q.solid_angles[j] - exact as f32).abs() < 1e-7);
            // The moment points at the texel and is shorter than its solid angle.
            let m = q.moments[j];
            assert!(m.normalize().dot(q.centres[j]) > 0.999);
            assert!(m.length() < q.solid_angles[j] && m.length() > 0.99 * q.solid_angles[j]);
        }
        // ∫ max(0, n·ω) dω over the sphere is π for any n; texels wholly above give n · moment.
        let n = Vec3::new(0.3, 0.8, -0.52).normalize();
        let sum: f64 = (0..texel_count(8))
            .filter(|&j| n.dot(q.centres[j]) > q.sin_radius[j])
            .map(|j| n.dot(q.moments[j]) as f64)
            .sum::<f64>()
            + (0..texel_count(8))
                .filter(|&j| n.dot(q.centres[j]).abs() <= q.sin_radius[j])
                .map(|j| {
                    let (d, w) = q.subs(j);
                    d.iter()
                        .zip(w)
                        .map(|(d, w)| (n.dot(*d).max(0.0) * w) as f64)
                        .sum::<f64>()
                })
                .sum::<f64>();
        assert!((sum - std::f64::consts::PI).abs() < 2e-3, "{sum}");
        // The whole sphere's first moment vanishes.
        let total: Vec3 = q.moments.iter().copied().sum();
        assert!(total.length() < 1e-5, "{total}");
    }

    #[test]
    fn neighbours_are_adjacent_and_mutual() {
        let n = 8;
        let q = TexelQuadrature::new(n, 2);
        let spacing = 2.0 * q.max_radius;
        for j in 0..texel_count(n) {
            for &k in &q.neighbours[j] {
                let k = k as usize;
                assert_ne!(j, k);
                // Next to it: no farther than two texel radii, and it names j back.
                let angle = q.centres[j].dot(q.centres[k]).clamp(-1.0, 1.0).acos();
                assert!(angle < spacing * 1.01, "{j} -> {k}: {angle}");
                assert!(q.neighbours[k].contains(&(j as u32)), "{j} -> {k}");
            }
        }
        // A centre sub-texel only for an odd side, and it is the texel's centre.
        assert_eq!(q.centre_sub, None);
        let q3 = TexelQuadrature::new(n, 3);
        let c = q3.centre_sub.unwrap();
        for j in 0..texel_count(n) {
            assert!(q3.subs(j).0[c].dot(q3.centres[j]) > 1.0 - 1e-6);
        }
    }

    #[test]
    fn the_horizon_bound_holds_at_every_corner() {
        let q = TexelQuadrature::new(4, 1);
        let n = Vec3::new(0.1, -0.7, 0.7).normalize();
        let fine = TexelQuadrature::new(4, 9);
        for j in 0..texel_count(4) {
            let (d, _) = fine.subs(j);
            let signs = d.iter().map(|d| n.dot(*d) > 0.0);
            let (up, down) = signs.fold((false, false), |(u, dn), s| (u || s, dn || !s));
            if up && down {
                assert!(n.dot(q.centres[j]).abs() < q.sin_radius[j], "texel {j}");
            }
        }
    }
}
