//! A cube's texels in Morton order, so that every coarser texel of a quadtree level is one run
//! of consecutive fine ones, and the pyramid of sums over those runs: what a glossy lobe reads
//! the light and a vertex's visibility from at the level its footprint asks for.
//!
//! Texel (face, row, col) of an N-cube is at `face · N² + morton(row, col)`, where `morton`
//! interleaves the bits of `col` (even bits) and `row` (odd bits). The node of level `l` (texels
//! of side `2^l`) that holds it is the run of `4^l` texels starting at its index with the low
//! `2l` bits cleared.

use glam::DVec3;

use crate::error::Result;
use crate::math::cubemap::{
    CubeMap, dir_to_face_st, face_st_to_cell, solid_angles, texel_count, validate_n,
};

/// Bits of `x` spread to the even bit positions (up to 16 bits in).
#[inline]
fn spread(x: u32) -> u32 {
    let mut x = x & 0xffff;
    x = (x | (x << 8)) & 0x00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333;
    (x | (x << 1)) & 0x5555_5555
}

/// Index of texel (face, row, col) of an N-cube in Morton order.
#[inline]
pub fn morton_index(n: usize, face: usize, row: usize, col: usize) -> usize {
    face * n * n + (spread(col as u32) | (spread(row as u32) << 1)) as usize
}

/// Morton index of the texel holding direction `d` (any length), as
/// [`crate::math::cubemap::dir_to_texel`] picks it.
#[inline]
pub fn dir_to_morton(n: usize, d: DVec3) -> usize {
    FacePoint::of(d).morton(n)
}

/// For each texel in the cube's linear order, its Morton index.
pub fn morton_of_linear(n: usize) -> Vec<u32> {
    (0..texel_count(n))
        .map(|i| morton_index(n, i / (n * n), (i / n) % n, i % n) as u32)
        .collect()
}

/// Quadtree levels of an N-cube face: 0 (texels) to log2 N (the whole face).
#[inline]
pub fn levels(n: usize) -> usize {
    n.trailing_zeros() as usize + 1
}

/// The run of Morton indices `[start, end)` of the level-`level` node that holds Morton index
/// `m`.
#[inline]
pub fn node_run(m: usize, level: usize) -> (usize, usize) {
    let start = (m >> (2 * level)) << (2 * level);
    (start, start + (1 << (2 * level)))
}

/// The radiance of a cube as sums over every node of every level: per node, `Σ L Ω` per channel
/// and `Σ Ω`, so a node's mean radiance is their ratio whatever its texels' solid angles.
#[derive(Clone, Debug)]
pub struct CubePyramid {
    /// Face size N of level 0.
    pub n: usize,
    /// Level by level, from the texels (level 0, Morton order) to one node a face: `[Σ L Ω, Σ Ω]`
    /// of each node, RGB then the solid angle.
    pub levels: Vec<Vec<[f32; 4]>>,
    /// The same nodes' mean radiance, `Σ L Ω / Σ Ω` (0 where `Σ Ω` is), worked out once for
    /// the reads.
    means: Vec<Vec<[f32; 3]>>,
    /// The means again, each level's nodes face by face in rows (`face · side² + row · side +
    /// col`), where a node's neighbours along a row and a column are a fixed step away: the
    /// layout [`CubePyramid::bilinear`] reads.
    grid: Vec<Vec<[f32; 3]>>,
}

impl CubePyramid {
    /// The pyramid of `cube`'s radiance.
    pub fn new(cube: &CubeMap) -> Result<CubePyramid> {
        validate_n(cube.n)?;
        let n = cube.n;
        let omega = solid_angles(n);
        let order = morton_of_linear(n);
        let mut base = vec![[0.0f32; 4]; texel_count(n)];
        for (i, (l, w)) in cube.texels.iter().zip(&omega).enumerate() {
            base[order[i] as usize] = [
                (l[0] as f64 * w) as f32,
                (l[1] as f64 * w) as f32,
                (l[2] as f64 * w) as f32,
                *w as f32,
            ];
        }
        let mut all = vec![base];
        while all.len() < levels(n) {
            let below = all.last().map_or(&[][..], |v| v.as_slice());
            let up = below
                .chunks_exact(4)
                .map(|c| {
                    let mut s = [0.0f32; 4];
                    for x in c {
                        for (a, b) in s.iter_mut().zip(x) {
                            *a += b;
                        }
                    }
                    s
                })
                .collect();
            all.push(up);
        }
        let means: Vec<Vec<[f32; 3]>> = all
            .iter()
            .map(|level| {
                level
                    .iter()
                    .map(|s| {
                        if s[3] > 0.0 {
                            [s[0] / s[3], s[1] / s[3], s[2] / s[3]]
                        } else {
                            [0.0; 3]
                        }
                    })
                    .collect()
            })
            .collect();
        let grid = (0..means.len())
            .map(|level| {
                let side = n >> level;
                (0..texel_count(side))
                    .map(|i| {
                        let (face, row, col) = (i / (side * side), (i / side) % side, i % side);
                        means[level][morton_index(side, face, row, col)]
                    })
                    .collect()
            })
            .collect();
        Ok(CubePyramid {
            n,
            levels: all,
            means,
            grid,
        })
    }

    /// Mean radiance of the level-`level` node holding Morton index `m` (level clamped to the
    /// coarsest).
    #[inline]
    pub fn mean(&self, m: usize, level: usize) -> [f32; 3] {
        let level = level.min(self.levels.len() - 1);
        self.means[level][m >> (2 * level)]
    }

    /// Mean radiance about direction `d` at level `level` (clamped to the coarsest): bilinear
    /// between the centres of the four nodes of `d`'s face nearest it, held at the face's edge.
    /// A lobe's tap read so is a tent about its own direction, where [`CubePyramid::mean`] is
    /// the box that happens to hold it, whose edges show as squares about a bright light.
    #[inline]
    pub fn bilinear(&self, at: FacePoint, level: usize) -> [f32; 3] {
        let level = level.min(self.levels.len() - 1);
        let side = self.n >> level;
        let axis = |x: f64| {
            let x = ((x + 1.0) * 0.5 * side as f64 - 0.5).clamp(0.0, (side - 1) as f64);
            let lo = x as i32 as usize;
            (lo, (lo + 1).min(side - 1), (x - lo as f64) as f32)
        };
        let ((c0, c1, fc), (r0, r1, fr)) = (axis(at.s), axis(at.t));
        let face = &self.grid[level][at.face * side * side..(at.face + 1) * side * side];
        let (r0, r1) = (r0 * side, r1 * side);
        let mut out = [0.0f32; 3];
        for (row, col, w) in [
            (r0, c0, (1.0 - fr) * (1.0 - fc)),
            (r0, c1, (1.0 - fr) * fc),
            (r1, c0, fr * (1.0 - fc)),
            (r1, c1, fr * fc),
        ] {
            let mean = face[row + col];
            for (o, v) in out.iter_mut().zip(mean) {
                *o += w * v;
            }
        }
        out
    }
}

/// A direction's face and its position on it, each from -1 to 1 ([`dir_to_face_st`]): where
/// [`CubePyramid::bilinear`] reads, at every level.
#[derive(Clone, Copy, Debug)]
pub struct FacePoint {
    face: usize,
    s: f64,
    t: f64,
}

impl FacePoint {
    /// The face point of direction `d` (any length).
    #[inline]
    pub fn of(d: DVec3) -> FacePoint {
        let (face, s, t) = dir_to_face_st(d);
        FacePoint { face, s, t }
    }

    /// Morton index of the texel of an N-cube that holds the point, as [`dir_to_morton`] picks
    /// it for the point's direction: one projection serves the reads of every cube size.
    #[inline]
    pub fn morton(&self, n: usize) -> usize {
        let (face, row, col) = face_st_to_cell(n, self.face, self.s, self.t);
        morton_index(n, face, row, col)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::cubemap::{dir_to_texel, texel_dirs};

    #[test]
    fn morton_order_is_a_permutation_whose_nodes_are_square_blocks() {
        let n = 8;
        let order = morton_of_linear(n);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert!(seen.iter().enumerate().all(|(i, &m)| i == m as usize));
        // Every level-2 node is a 4 × 4 block of one face.
        for face in 0..6 {
            for row in 0..n {
                for col in 0..n {
                    let m = morton_index(n, face, row, col);
                    let (start, end) = node_run(m, 2);
                    assert_eq!(end - start, 16);
                    let block = morton_index(n, face, row & !3, col & !3);
                    assert_eq!(start, block, "({face}, {row}, {col})");
                }
            }
        }
    }

    #[test]
    fn a_direction_lands_in_the_same_texel_in_both_orders() {
        let n = 16;
        let order = morton_of_linear(n);
        for d in texel_dirs(n) {
            assert_eq!(dir_to_morton(n, d), order[dir_to_texel(n, d)] as usize);
        }
    }

    #[test]
    fn a_node_holds_the_solid_angle_weighted_mean_of_its_texels() {
        let n = 4;
        let texels: Vec<[f32; 3]> = (0..texel_count(n))
            .map(|i| [i as f32, 1.0, (i % 7) as f32])
            .collect();
        let cube = CubeMap { n, texels };
        let p = CubePyramid::new(&cube).unwrap();
        assert_eq!(p.levels.len(), 3);
        let omega = solid_angles(n);
        // Face 2's whole node: its texels' weighted mean.
        let (mut num, mut den) = (0.0f64, 0.0f64);
        let face = 2 * n * n..3 * n * n;
        for (t, w) in cube.texels[face.clone()].iter().zip(&omega[face]) {
            num += t[0] as f64 * w;
            den += w;
        }
        let got = p.mean(morton_index(n, 2, 3, 1), 2)[0] as f64;
        assert!(
            (got - num / den).abs() < 1e-4 * (num / den),
            "{got} {}",
            num / den
        );
        assert!((den - 4.0 * std::f64::consts::PI / 6.0).abs() < 1e-6);
        // Level 0 is the texel itself.
        let i = crate::math::cubemap::texel_index(n, 5, 2, 3);
        let m = morton_index(n, 5, 2, 3);
        assert!((p.mean(m, 0)[0] - cube.texels[i][0]).abs() < 1e-4);
    }

    #[test]
    fn bilinear_reads_rise_linearly_between_node_centres_and_hold_at_the_edges() {
        // Face 0's texels rise with the column, 10 · col, every other face dark.
        let n = 8;
        let mut cube = CubeMap::constant(n, [0.0; 3]).unwrap();
        for row in 0..n {
            for col in 0..n {
                cube.texels[row * n + col] = [10.0 * col as f32, 1.0, 2.0];
            }
        }
        let p = CubePyramid::new(&cube).unwrap();
        // Face 0 is +X; its s runs along -Z (dir_to_face_st).
        let at = |s: f64, t: f64| FacePoint::of(DVec3::new(1.0, -t, -s));
        let centre = |col: usize| (2 * col + 1) as f64 / n as f64 - 1.0;
        for col in 0..n {
            let v = p.bilinear(at(centre(col), 0.1), 0);
            assert!((v[0] - 10.0 * col as f32).abs() < 1e-4, "{col}: {v:?}");
            assert!((v[1] - 1.0).abs() < 1e-6 && (v[2] - 2.0).abs() < 1e-6);
        }
        // A quarter of the way from column 2's centre to column 3's.
        let v = p.bilinear(at(0.75 * centre(2) + 0.25 * centre(3), -0.3), 0);
        assert!((v[0] - 22.5).abs() < 1e-4, "{v:?}");
        // Past the first and last centres the edge node holds.
        assert!(p.bilinear(at(-0.99, 0.0), 0)[0].abs() < 1e-6);
        assert!((p.bilinear(at(0.99, 0.0), 0)[0] - 70.0).abs() < 1e-4);
        // Level 1 (side 4, centres at ±0.25 and ±0.75): (0, 0.5) is midway between the nodes
        // of rows 2 and 3 and columns 1 and 2.
        let node = |r: usize, c: usize| p.mean(morton_index(n, 0, 2 * r, 2 * c), 1)[0];
        let want = 0.25 * (node(2, 1) + node(2, 2) + node(3, 1) + node(3, 2));
        let mid = p.bilinear(at(0.0, 0.5), 1)[0];
        assert!(
            (mid - want).abs() < 1e-4 && (want - 35.0).abs() < 1.0,
            "{mid} {want}"
        );
        // The coarsest level is one node a face: the face's mean wherever it is read.
        let top = p.levels.len() - 1;
        assert_eq!(p.bilinear(at(0.9, -0.9), top), p.mean(0, top));
    }
}
