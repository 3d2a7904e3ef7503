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
use crate::math::cubemap::{CubeMap, dir_to_cell, solid_angles, texel_count, validate_n};

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
    let (face, row, col) = dir_to_cell(n, d);
    morton_index(n, face, row, col)
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
        Ok(CubePyramid { n, levels: all })
    }

    /// Mean radiance of the level-`level` node holding Morton index `m` (level clamped to the
    /// coarsest).
    #[inline]
    pub fn mean(&self, m: usize, level: usize) -> [f32; 3] {
        let level = level.min(self.levels.len() - 1);
        let s = self.levels[level][m >> (2 * level)];
        if s[3] > 0.0 {
            [s[0] / s[3], s[1] / s[3], s[2] / s[3]]
        } else {
            [0.0; 3]
        }
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
}
