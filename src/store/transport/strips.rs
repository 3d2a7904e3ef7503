//! The Haar matrix in the layout the CPU kernel reads: dense strips of [`STRIP_ROWS`] rows in
//! light-major bands of blocks.
//!
//! A block's column (coefficient j of up to 256 rows) is cut into aligned strips of 8 rows; a
//! strip that holds at least one entry is kept whole, its missing rows as zeros. On the demo bake
//! 88% of the values of kept strips are entries, so a strip (a byte for its place in the block and
//! 8 values) costs fewer bytes than the entries it holds, each a row byte and a value, and the
//! kernel widens and adds 8 values with one vector instruction each instead of scattering them
//! one by one.
//!
//! Whole tile rows are gathered into *groups* of at least [`BAND_BLOCKS`] blocks (one row of a
//! wide image; sixteen rows of a per-vertex bake, whose image is one tile wide), and a group's
//! blocks into *bands* of at most [`BAND_BLOCKS`]. A band's strips are stored coefficient by
//! coefficient (light-major, the order of Ng et al. 2003): coefficient j's strips of the band's
//! first block, then of its second, and so on. So a K-term product reads K contiguous runs per
//! band, and the band's accumulators (3 x 16 x 256 floats, 48 KiB) stay in the nearest caches
//! while it does. A group is one worker's job: its pixels are its own.

use std::ops::Range;

use rayon::prelude::*;

use super::{Transport, Values, tile_grid};
use crate::store::quant::BLOCK_ROWS;

/// Rows of one strip.
pub const STRIP_ROWS: usize = 8;
/// Strips in a block of [`BLOCK_ROWS`] rows.
pub const STRIPS_PER_BLOCK: usize = BLOCK_ROWS / STRIP_ROWS;
/// Most blocks in one band.
pub const BAND_BLOCKS: usize = 16;

/// Where a (block, coefficient)'s strips are: the first, how many, and the column's scale code.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Slot {
    /// Its first strip.
    pub first: u32,
    /// Its strips (at most [`STRIPS_PER_BLOCK`]).
    pub count: u8,
    /// The scale code of the block's column ([`crate::store::quant::scale_of`]).
    pub code: u8,
    /// The stored entries its strips hold: the column's length in the file.
    pub entries: u16,
}

/// The strips of a transport's Haar matrix (see the module's documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Strips {
    /// Band i holds blocks `band_block_start[i] .. band_block_start[i + 1]`, all of one group.
    pub band_block_start: Vec<u32>,
    /// Group g is tile rows `group_row_start[g] .. group_row_start[g + 1]`: whole tile rows, as
    /// few as hold [`BAND_BLOCKS`] blocks (one row of a wide image; 16 of a per-vertex bake's,
    /// which are one tile wide), the last group whatever is left.
    pub group_row_start: Vec<u32>,
    /// Group g holds bands `group_band_start[g] .. group_band_start[g + 1]`.
    pub group_band_start: Vec<u32>,
    /// Per band, coefficient and block of the band, in that order: where its strips are, so a
    /// term's slots of one band are side by side.
    pub slots: Vec<Slot>,
    /// Per strip: its place in its block (rows `8 s .. 8 s + 8`).
    pub index: Vec<u8>,
    /// Per strip, [`STRIP_ROWS`] stored values (integers against the column's scale, or floats),
    /// zero where the row has no entry.
    pub values: Values,
}

/// One group's layout, found in a first pass: its bands' ends and its slots, their first
/// strips counted from the group's own first.
struct GroupLayout {
    bands: Vec<u32>,
    slots: Vec<Slot>,
    strips: usize,
}

/// A stored value type: where a transport keeps its values, and how strips keep theirs.
trait Stored: Copy + Default + Send + Sync {
    fn wrap(v: Vec<Self>) -> Values;
}
impl Stored for i8 {
    fn wrap(v: Vec<i8>) -> Values {
        Values::Q8(v)
    }
}
impl Stored for i16 {
    fn wrap(v: Vec<i16>) -> Values {
        Values::Q16(v)
    }
}
impl Stored for f32 {
    fn wrap(v: Vec<f32>) -> Values {
        Values::F32(v)
    }
}

impl Strips {
    /// The strips of `t`'s matrix, in bands of [`BAND_BLOCKS`] blocks (the last of a group may
    /// have fewer). Groups are laid out in parallel. An error when the strips would not
    /// be counted in 32 bits (a matrix of more than 2^32 strips, some 30 GB).
    pub fn of(t: &Transport) -> std::result::Result<Strips, String> {
        match &t.values {
            Values::Q8(v) => Self::of_values(t, v),
            Values::Q16(v) => Self::of_values(t, v),
            Values::F32(v) => Self::of_values(t, v),
        }
    }

    fn of_values<V: Stored>(t: &Transport, values: &[V]) -> std::result::Result<Strips, String> {
        let c = t.coeff_count();
        let (w, h) = (t.meta.width as usize, t.meta.height as usize);
        let (tx, ty) = tile_grid(w, h);
        // Groups of whole tile rows, each closed once it holds a band's worth of blocks.
        let mut group_row_start = vec![0u32];
        for y in 1..=ty {
            let first = *group_row_start.last().unwrap_or(&0) as usize;
            let blocks = t.tile_block_start[y * tx] - t.tile_block_start[first * tx];
            if blocks as usize >= BAND_BLOCKS || y == ty {
                group_row_start.push(y as u32);
            }
        }
        let groups = group_row_start.len() - 1;
        let group_blocks = |g: usize| {
            let rows = group_row_start[g] as usize..group_row_start[g + 1] as usize;
            t.tile_block_start[rows.start * tx] as usize..t.tile_block_start[rows.end * tx] as usize
        };
        // First pass, in parallel over groups: every column's strips counted, and the slots
        // laid out band by band, coefficient by coefficient.
        let layouts: Vec<GroupLayout> = (0..groups)
            .into_par_iter()
            .map(|g| {
                let blocks = group_blocks(g);
                let mut counts = vec![0u8; blocks.len() * c];
                for (i, b) in blocks.clone().enumerate() {
                    for (j, count) in counts[i * c..(i + 1) * c].iter_mut().enumerate() {
                        let mut last = None;
                        for &r in &t.entry_row[t.block_column(b, j)] {
                            let place = r / STRIP_ROWS as u8;
                            if last != Some(place) {
                                last = Some(place);
                                *count += 1;
                            }
                        }
                    }
                }
                let mut group = GroupLayout {
                    bands: Vec::new(),
                    slots: Vec::with_capacity(blocks.len() * c),
                    strips: 0,
                };
                for b0 in blocks.clone().step_by(BAND_BLOCKS) {
                    let band = b0..(b0 + BAND_BLOCKS).min(blocks.end);
                    group.bands.push(band.end as u32);
                    for j in 0..c {
                        for b in band.clone() {
                            let count = counts[(b - blocks.start) * c + j];
                            group.slots.push(Slot {
                                first: group.strips as u32,
                                count,
                                code: t.col_scale[b * c + j],
                                entries: t.block_column(b, j).len() as u16,
                            });
                            group.strips += count as usize;
                        }
                    }
                }
                group
            })
            .collect();
        let total: usize = layouts.iter().map(|l| l.strips).sum();
        if u32::try_from(total).is_err() {
            return Err(format!(
                "{total} strips of 8 rows are more than the kernel counts in 32 bits"
            ));
        }
        let mut index = vec![0u8; total];
        let mut strip_values = vec![V::default(); total * STRIP_ROWS];
        // Second pass: each group fills its own part of the strips, reading its blocks in
        // the order they are stored.
        let mut parts = Vec::with_capacity(groups);
        let (mut index_rest, mut values_rest) = (&mut index[..], &mut strip_values[..]);
        for layout in &layouts {
            let (i, rest) = index_rest.split_at_mut(layout.strips);
            let (v, rest_v) = values_rest.split_at_mut(layout.strips * STRIP_ROWS);
            parts.push((i, v));
            (index_rest, values_rest) = (rest, rest_v);
        }
        parts.into_par_iter().zip(&layouts).enumerate().for_each(
            |(g, ((index, strip_values), layout))| {
                let blocks = group_blocks(g);
                for (band, b0) in blocks.clone().step_by(BAND_BLOCKS).enumerate() {
                    let nb = (b0 + BAND_BLOCKS).min(blocks.end) - b0;
                    // The band's slots start after those of the group's earlier bands (all full).
                    let start = band * BAND_BLOCKS * c;
                    for i in 0..nb {
                        for j in 0..c {
                            let slot = layout.slots[start + j * nb + i];
                            let column = t.block_column(b0 + i, j);
                            let mut k = slot.first as usize;
                            let mut last = None;
                            for (&r, &v) in t.entry_row[column.clone()].iter().zip(&values[column])
                            {
                                let place = r / STRIP_ROWS as u8;
                                if last != Some(place) {
                                    if last.is_some() {
                                        k += 1;
                                    }
                                    last = Some(place);
                                    index[k] = place;
                                }
                                strip_values[k * STRIP_ROWS + r as usize % STRIP_ROWS] = v;
                            }
                        }
                    }
                }
            },
        );
        let mut s = Strips {
            band_block_start: vec![0],
            group_row_start,
            group_band_start: vec![0],
            slots: Vec::with_capacity(t.block_count() * c),
            index,
            values: V::wrap(strip_values),
        };
        let mut base = 0u32;
        for layout in layouts {
            s.band_block_start.extend_from_slice(&layout.bands);
            s.group_band_start.push(s.band_block_start.len() as u32 - 1);
            s.slots.extend(layout.slots.iter().map(|slot| Slot {
                first: slot.first + base,
                ..*slot
            }));
            base += layout.strips as u32;
        }
        Ok(s)
    }

    /// Number of bands.
    pub fn band_count(&self) -> usize {
        self.band_block_start.len() - 1
    }

    /// The blocks of band `band`.
    #[inline]
    pub fn band_blocks(&self, band: usize) -> Range<usize> {
        self.band_block_start[band] as usize..self.band_block_start[band + 1] as usize
    }

    /// Number of groups of tile rows.
    pub fn group_count(&self) -> usize {
        self.group_row_start.len() - 1
    }

    /// The tile rows of group `g`.
    #[inline]
    pub fn group_rows(&self, g: usize) -> Range<usize> {
        self.group_row_start[g] as usize..self.group_row_start[g + 1] as usize
    }

    /// The bands of group `g`.
    #[inline]
    pub fn group_bands(&self, g: usize) -> Range<usize> {
        self.group_band_start[g] as usize..self.group_band_start[g + 1] as usize
    }

    /// The slots of coefficient `j` in band `band` (one per block of the band), for a transport
    /// of `c` coefficients.
    #[inline]
    pub fn term_slots(&self, band: usize, j: usize, c: usize) -> &[Slot] {
        let blocks = self.band_blocks(band);
        let start = blocks.start * c + j * blocks.len();
        &self.slots[start..start + blocks.len()]
    }

    /// The band that holds block `b`.
    pub fn band_of(&self, b: usize) -> usize {
        self.band_block_start.partition_point(|&s| s as usize <= b) - 1
    }

    /// Block `b`'s slots, coefficient by coefficient, for a transport of `c` coefficients.
    pub fn block_slots(&self, b: usize, c: usize) -> impl Iterator<Item = &Slot> {
        let blocks = self.band_blocks(self.band_of(b));
        let start = blocks.start * c + (b - blocks.start);
        let step = blocks.len();
        (0..c).map(move |j| &self.slots[start + j * step])
    }

    /// The strips and the stored entries a product with the light terms `indices` reads, for a
    /// transport of `c` coefficients.
    pub fn read_by(&self, indices: &[u32], c: usize) -> (u64, u64) {
        let mut read = (0u64, 0u64);
        for band in 0..self.band_count() {
            for &j in indices {
                for s in self.term_slots(band, j as usize, c) {
                    read.0 += s.count as u64;
                    read.1 += s.entries as u64;
                }
            }
        }
        read
    }

    /// Number of strips.
    pub fn strip_count(&self) -> usize {
        self.index.len()
    }

    /// Bytes of the strips and their tables as a file would store them: per strip its place and
    /// values, per (block, coefficient) a strip count and a scale code.
    pub fn bytes(&self) -> usize {
        self.index.len() * (1 + STRIP_ROWS * self.values.value_bytes()) + self.slots.len() * 2
    }
}
