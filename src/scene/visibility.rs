//! Which cube texels each glossy vertex of a per-vertex bake sees: one bit a texel, in the Morton
//! order of [`crate::math::cube_pyramid`], so that the visible fraction of any coarser texel is a
//! count of the set bits in one run. The raster interpolates these fractions across a triangle
//! and weighs a glossy lobe's light by them per pixel ([`crate::draw::lobe`]).

use crate::error::{PrtError, Result};
use crate::math::cube_pyramid::node_run;
use crate::math::cubemap::{texel_count, validate_n};

/// No row: a vertex whose visibility was not baked (its material is not glossy).
pub const NO_ROW: u32 = u32::MAX;

/// The visibility bits of a mesh's glossy vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Visibility {
    /// Face size N of the cube the bits are over.
    pub n: usize,
    /// The vertices with bits, ascending.
    pub vertices: Vec<u32>,
    /// Row `r` (of vertex `vertices[r]`) is words `r · words .. (r + 1) · words`; bit `m % 32` of
    /// word `m / 32` is texel `m` in Morton order, set where the texel's direction is open.
    pub bits: Vec<u32>,
    /// Each material's GGX lobe as `[specular r, g, b, α]`, all zero for a diffuse material:
    /// what the raster draws the bits with.
    pub lobes: Vec<[f32; 4]>,
    /// Light columns each row has a visible share of (0 for a bake without local lights, or
    /// one written before the shares were kept).
    pub columns: usize,
    /// Row `r`'s visible share of light column `c`, from 0 to 1, at `r · columns + c`: the part
    /// of the light a glossy vertex sees, which weighs the light's highlight there.
    pub light_shares: Vec<f32>,
    /// Each vertex's row, or [`NO_ROW`] (built from `vertices`).
    rows: Vec<u32>,
}

impl Visibility {
    /// Words a vertex's bits take at face size `n`.
    pub fn words(n: usize) -> usize {
        texel_count(n).div_ceil(32)
    }

    /// The lobes of `materials` as [`Visibility::lobes`] holds them.
    pub fn lobes_of(materials: &[crate::scene::Material]) -> Vec<[f32; 4]> {
        materials
            .iter()
            .map(|m| match m.glossy_lobe() {
                Some((s, alpha)) => [s.x, s.y, s.z, alpha],
                None => [0.0; 4],
            })
            .collect()
    }

    /// The glossy lobe of material `m`: specular colour and α, `None` for a diffuse one or
    /// past the table.
    #[inline]
    pub fn lobe(&self, m: u32) -> Option<(glam::Vec3, f32)> {
        let l = self.lobes.get(m as usize)?;
        (l[0] > 0.0 || l[1] > 0.0 || l[2] > 0.0).then(|| (glam::Vec3::new(l[0], l[1], l[2]), l[3]))
    }

    /// The visibility of `vertex_count` vertices from the rows of `vertices` (ascending, each
    /// below the count), their `bits` and the materials' `lobes`, checked.
    pub fn new(
        n: usize,
        vertex_count: usize,
        vertices: Vec<u32>,
        bits: Vec<u32>,
        lobes: Vec<[f32; 4]>,
    ) -> Result<Visibility> {
        validate_n(n)?;
        if let Some(i) = lobes.iter().position(|l| {
            !l.iter().all(|v| v.is_finite() && *v >= 0.0)
                || (l[..3].iter().any(|v| *v > 0.0) && !(1e-6..=1.0).contains(&l[3]))
        }) {
            return Err(PrtError::invalid(
                format!("visibility lobe {i}"),
                format!(
                    "{:?}: a specular colour of finite values ≥ 0 and, where it is not black,                      an α in [1e-6, 1]",
                    lobes[i]
                ),
            ));
        }
        let words = Self::words(n);
        if vertices.len().checked_mul(words) != Some(bits.len()) {
            return Err(PrtError::invalid(
                "visibility",
                format!(
                    "{} words of bits for {} vertices of {words} words each",
                    bits.len(),
                    vertices.len()
                ),
            ));
        }
        if let Some(i) = (0..vertices.len()).find(|&i| {
            vertices[i] as usize >= vertex_count || (i > 0 && vertices[i] <= vertices[i - 1])
        }) {
            return Err(PrtError::invalid(
                format!("visibility vertex {i}"),
                format!(
                    "{} is not below the mesh's {vertex_count} vertices or not above the one \
                     before it",
                    vertices[i]
                ),
            ));
        }
        let mut rows = vec![NO_ROW; vertex_count];
        for (r, &v) in vertices.iter().enumerate() {
            rows[v as usize] = r as u32;
        }
        Ok(Visibility {
            n,
            vertices,
            bits,
            lobes,
            columns: 0,
            light_shares: Vec::new(),
            rows,
        })
    }

    /// These bits with each row's visible share of each of `columns` light columns
    /// ([`Visibility::light_shares`]), checked: as many as rows times columns, each in [0, 1].
    pub fn with_light_shares(mut self, columns: usize, shares: Vec<f32>) -> Result<Visibility> {
        if self.vertices.len().checked_mul(columns) != Some(shares.len()) {
            return Err(PrtError::invalid(
                "visibility light shares",
                format!(
                    "{} shares for {} vertices of {columns} light columns each",
                    shares.len(),
                    self.vertices.len()
                ),
            ));
        }
        if let Some(i) = shares.iter().position(|v| !(0.0..=1.0).contains(v)) {
            return Err(PrtError::invalid(
                format!("visibility light share {i}"),
                format!("{}: a share of a light from 0 to 1", shares[i]),
            ));
        }
        self.columns = columns;
        self.light_shares = shares;
        Ok(self)
    }

    /// The visible share of light column `column` from vertex `v`: 1 for a vertex without a
    /// row, or for bits without the shares.
    #[inline]
    pub fn light_share(&self, v: usize, column: usize) -> f32 {
        match self.row_index(v) {
            Some(r) if column < self.columns => {
                self.light_shares[r as usize * self.columns + column]
            }
            _ => 1.0,
        }
    }

    /// Vertices of the mesh these were made for.
    pub fn vertex_count(&self) -> usize {
        self.rows.len()
    }

    /// Checks what a draw of these bits takes against a mesh of `vertices` vertices: as many
    /// `normals` (a count) and `materials`, visibility of as many vertices, and a lobe for every
    /// material index.
    pub fn check_draw(&self, normals: usize, materials: &[u32], vertices: usize) -> Result<()> {
        if normals != vertices || materials.len() != vertices || self.vertex_count() != vertices {
            return Err(PrtError::invalid(
                "gloss",
                format!(
                    "{normals} normals, {} materials and visibility of {} vertices for \
                     {vertices} vertices",
                    materials.len(),
                    self.vertex_count()
                ),
            ));
        }
        if let Some(m) = materials.iter().find(|&&m| m as usize >= self.lobes.len()) {
            return Err(PrtError::invalid(
                "gloss",
                format!("material {m} of {} materials' lobes", self.lobes.len()),
            ));
        }
        Ok(())
    }

    /// Vertex `v`'s row, if it has bits.
    #[inline]
    pub fn row_index(&self, v: usize) -> Option<u32> {
        self.rows.get(v).copied().filter(|&r| r != NO_ROW)
    }

    /// Vertex `v`'s bits, if it has them.
    #[inline]
    pub fn row(&self, v: usize) -> Option<&[u32]> {
        let r = *self.rows.get(v)? as usize;
        let w = Self::words(self.n);
        self.bits.get(r * w..(r + 1) * w)
    }

    /// The open share of the level-`level` node holding Morton index `m` in `row` (1 for a
    /// vertex without bits).
    #[inline]
    pub fn open_share(row: Option<&[u32]>, m: usize, level: usize) -> f32 {
        open_shares(&[row], m, level)[0]
    }
}

/// The open shares of the level-`level` node holding Morton index `m` in each of `rows` (1 for
/// a vertex without bits; [`Visibility::open_share`] for one row): the node's run and mask are
/// worked out once for the rows.
#[inline]
pub fn open_shares<const K: usize>(rows: &[Option<&[u32]>; K], m: usize, level: usize) -> [f32; K] {
    let (start, end) = node_run(m, level);
    let len = end - start;
    // A power of two, so the product is the exact quotient.
    let scale = 1.0 / len as f32;
    // A plain loop over the rows: `array::map` goes through a fallible map that the optimiser
    // does not flatten, and it cost more than the counts themselves.
    let mut shares = [1.0f32; K];
    if len <= 32 {
        // Every node of up to 32 bits lies in one word, its run starting at a multiple of its
        // length.
        let (word, shift, mask) = (start / 32, start % 32, u32::MAX >> (32 - len));
        // Without a bit-count instruction in the portable build, `count_ones` is a dozen
        // operations: a texel's bit is read as it is, and a node of four by a table of the
        // sixteen nibbles' counts packed in one word.
        let count = |bits: u32| match len {
            1 => bits,
            4 => (NIBBLE_COUNTS >> (4 * bits)) as u32 & 0xf,
            _ => bits.count_ones(),
        };
        for (share, row) in shares.iter_mut().zip(rows) {
            if let Some(r) = row {
                *share = count((r[word] >> shift) & mask) as f32 * scale;
            }
        }
    } else {
        for (share, row) in shares.iter_mut().zip(rows) {
            if let Some(r) = row {
                *share = count_ones(r, start, end) as f32 * scale;
            }
        }
    }
    shares
}

/// The set bits of each nibble 0 to 15, four bits each from the lowest.
const NIBBLE_COUNTS: u64 = 0x4332_3221_3221_2110;

/// Set bits of `words` at bit positions `[start, end)`.
#[inline]
fn count_ones(words: &[u32], start: usize, end: usize) -> u32 {
    let (first, last) = (start / 32, (end - 1) / 32);
    let mask = |w: usize| {
        let lo = if w == first { start % 32 } else { 0 };
        let hi = if w == last { (end - 1) % 32 + 1 } else { 32 };
        let ones = if hi - lo == 32 {
            u32::MAX
        } else {
            ((1u32 << (hi - lo)) - 1) << lo
        };
        words[w] & ones
    };
    (first..=last).map(|w| mask(w).count_ones()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_the_set_bits_of_any_run() {
        let words = [0xffff_0000u32, 0x0000_00ff, 0xffff_ffff];
        assert_eq!(count_ones(&words, 0, 16), 0);
        assert_eq!(count_ones(&words, 16, 32), 16);
        assert_eq!(count_ones(&words, 0, 96), 16 + 8 + 32);
        assert_eq!(count_ones(&words, 20, 36), 12 + 4);
        assert_eq!(count_ones(&words, 39, 41), 1);
        let brute = |a: usize, b: usize| {
            (a..b)
                .filter(|i| words[i / 32] >> (i % 32) & 1 == 1)
                .count()
        };
        for a in 0..96 {
            for b in a + 1..=96 {
                assert_eq!(count_ones(&words, a, b) as usize, brute(a, b), "[{a}, {b})");
            }
        }
    }

    #[test]
    fn shares_of_one_row_or_several_are_their_bits_counted_at_every_level() {
        // An 8-cube: 384 bits, 12 words a row, levels 0 (one bit) to 3 (64 bits).
        let n = 8;
        let mut rng = crate::test_support::Rng::new(7);
        let rows: Vec<Vec<u32>> = (0..2)
            .map(|_| (0..12).map(|_| rng.next_u64() as u32).collect())
            .collect();
        let set = [Some(&rows[0][..]), None, Some(&rows[1][..])];
        for level in 0..4 {
            for m in 0..texel_count(n) {
                // Each row's share counted bit by bit.
                let (start, end) = node_run(m, level);
                let each = set.map(|r| {
                    r.map_or(1.0, |r| {
                        let ones = (start..end).filter(|i| r[i / 32] >> (i % 32) & 1 == 1);
                        ones.count() as f32 / (end - start) as f32
                    })
                });
                assert_eq!(Visibility::open_share(set[0], m, level), each[0]);
                assert_eq!(
                    open_shares(&set, m, level),
                    each,
                    "level {level}, texel {m}"
                );
            }
        }
        assert_eq!(open_shares(&[None::<&[u32]>], 0, 3), [1.0]);
    }

    #[test]
    fn rows_and_shares_follow_the_vertices_and_bad_tables_are_refused() {
        let n = 2; // 24 texels, one word.
        let lobes = vec![[0.5, 0.5, 0.5, 0.04], [0.0; 4]];
        let vis = Visibility::new(
            n,
            5,
            vec![1, 3],
            vec![0x00ff_ffff, 0x0000_000f],
            lobes.clone(),
        )
        .unwrap();
        assert_eq!(vis.lobe(0), Some((glam::Vec3::splat(0.5), 0.04)));
        assert_eq!(vis.lobe(1), None);
        assert_eq!(vis.lobe(2), None);
        assert!(vis.row(0).is_none() && vis.row(9).is_none());
        assert_eq!(Visibility::open_share(vis.row(1), 5, 0), 1.0);
        assert_eq!(Visibility::open_share(vis.row(3), 0, 1), 1.0);
        assert_eq!(Visibility::open_share(vis.row(3), 4, 1), 0.0);
        assert_eq!(Visibility::open_share(vis.row(0), 4, 1), 1.0);
        let bad = |n, v, rows: Vec<u32>, bits: Vec<u32>, lobes: &[[f32; 4]]| {
            Visibility::new(n, v, rows, bits, lobes.to_vec()).is_err()
        };
        assert!(bad(n, 5, vec![3, 1], vec![0, 0], &lobes));
        assert!(bad(n, 3, vec![1, 3], vec![0, 0], &lobes));
        assert!(bad(n, 5, vec![1], vec![0, 0], &lobes));
        assert!(bad(3, 5, vec![1], vec![0], &lobes));
        assert!(bad(n, 5, vec![1], vec![0], &[[0.5, 0.5, 0.5, 0.0]]));
        assert!(bad(n, 5, vec![1], vec![0], &[[f32::NAN, 0.5, 0.5, 0.1]]));
    }
}
