//! The Haar matrix as the file stores it and the kernels read it: dense strips of
//! [`STRIP_ROWS`] rows in light-major bands of blocks, made from columns (a bake's tiles, an
//! older file's tables) or read as stored, and checked.
//!
//! A block's column (coefficient j of up to 256 rows) is cut into aligned strips of 8 rows; a
//! strip that holds at least one entry is kept whole, its missing rows as zeros. On the demo bake
//! 88% of the values of kept strips are entries, so a strip (a byte for its place in the block and
//! 8 values) costs fewer bytes than the entries it holds would as columns, each a row byte and a
//! value, and the kernel widens and adds 8 values with one vector instruction each instead of scattering them
//! one by one.
//!
//! Whole tile rows are gathered into *groups* of at least [`BAND_BLOCKS`] blocks (one row of a
//! wide image; sixteen rows of a per-vertex bake, whose image is one tile wide), and a group's
//! blocks into *bands* of at most [`BAND_BLOCKS`]. A band's strips are stored coefficient by
//! coefficient (light-major, the order of Ng et al. 2003): coefficient j's strips of the band's
//! first block, then of its second, and so on. So a K-term product reads K contiguous runs per
//! band, and the band's accumulators (3 x 16 x 256 floats, 48 KiB) stay in the nearest caches
//! while it does. A group is one worker's job: its pixels are its own.
//!
//! Strips are made from a bake's columns in `build`, and from a file's tables, then checked, in
//! `check`.

mod build;
mod check;

use std::ops::Range;

use super::Values;
use crate::store::quant::BLOCK_ROWS;

/// Rows of one strip.
pub const STRIP_ROWS: usize = 8;
/// Strips in a block of [`BLOCK_ROWS`] rows.
pub const STRIPS_PER_BLOCK: usize = BLOCK_ROWS / STRIP_ROWS;
/// Most blocks in one band.
pub const BAND_BLOCKS: usize = 16;
const _: () = assert!(
    BAND_BLOCKS <= 16,
    "a band's occupied slots are bits of a u16"
);

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
    /// term's slots of one band are side by side. The bitmask of occupied slots the kernels walk
    /// by ([`Strips::occupied`]) is made with them: they are not to be changed on their own.
    pub slots: Vec<Slot>,
    /// Per strip: its place in its block (rows `8 s .. 8 s + 8`).
    pub index: Vec<u8>,
    /// Per strip, [`STRIP_ROWS`] stored values (integers against the column's scale, or floats),
    /// zero where the row has no entry.
    pub values: Values,
    /// Per band and coefficient, a bit for each block of the band whose slot holds strips
    /// (bit i for the band's block i): on the demo bake 66% of slots are empty, and a product
    /// skips them without reading them. It follows from `slots`, and is made with them.
    occupied: Vec<u16>,
}

/// One block's columns in the stored column layout: per coefficient an entry count and a scale
/// code, then the entries of coefficient 0, of 1, and so on, each a row inside the block
/// (strictly increasing within a column) and a stored value. Strips are made from these, and a
/// tile's columns are read back from strips in this form.
#[derive(Clone, Copy, Debug)]
pub struct BlockColumns<'a, V> {
    /// Entries of each coefficient (C of them).
    pub counts: &'a [u16],
    /// Scale code of each coefficient (C of them).
    pub codes: &'a [u8],
    /// Row inside the block of each entry.
    pub rows: &'a [u8],
    /// Stored value of each entry.
    pub values: &'a [V],
    /// Rows of the block (at most [`BLOCK_ROWS`]): its strips are `block_rows.div_ceil(8)`.
    pub block_rows: usize,
}

/// The strips of a block of `rows` rows (at most [`BLOCK_ROWS`]): 32 but in a tile's last block.
pub fn block_strips(rows: usize) -> usize {
    rows.div_ceil(STRIP_ROWS).min(STRIPS_PER_BLOCK)
}

/// True when a slot whose entries fall in `count` of the `block_strips` strips of its block is
/// stored whole: every strip of the block, zeros where no entry is. Half full or more, the
/// kernel adds a whole slot a panel at a time with its accumulators in registers, several times
/// faster a strip than one strip at a time into memory; on the demo bake this stores 4% more
/// strips and takes 96% of them to the panels, against 82% before.
pub fn stored_whole(count: usize, block_strips: usize) -> bool {
    count > 0 && 2 * count >= block_strips
}

/// A stored value type: where a transport keeps its values, and how strips keep theirs.
pub trait Stored: Copy + Default + PartialEq + Send + Sync {
    /// These values as a transport keeps them.
    fn wrap(v: Vec<Self>) -> Values;
    /// The values of `v`, if they are of this type.
    fn slice(v: &Values) -> Option<&[Self]>;
    /// True when a stored value is an entry rather than padding (zero, or negative zero).
    fn is_entry(self) -> bool;
}
/// `Stored` for a value type held in a `Values` variant, padding being its `zero`.
macro_rules! stored {
    ($t:ty, $variant:ident, $zero:literal) => {
        impl Stored for $t {
            fn wrap(v: Vec<$t>) -> Values {
                Values::$variant(v)
            }
            fn slice(v: &Values) -> Option<&[$t]> {
                match v {
                    Values::$variant(v) => Some(v),
                    _ => None,
                }
            }
            fn is_entry(self) -> bool {
                self != $zero
            }
        }
    };
}

stored!(i8, Q8, 0);
stored!(i16, Q16, 0);
stored!(f32, F32, 0.0);

/// Groups, bands and blocks of an image whose tile t holds blocks `tile_block_start[t] ..
/// tile_block_start[t + 1]`, `tiles_x` tiles to a tile row: they follow from the tiles' row
/// counts alone, so a file need not store them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Layout {
    /// Band i holds blocks `band_block_start[i] .. band_block_start[i + 1]`, all of one group.
    pub band_block_start: Vec<u32>,
    /// Group g is tile rows `group_row_start[g] .. group_row_start[g + 1]`.
    pub group_row_start: Vec<u32>,
    /// Group g holds bands `group_band_start[g] .. group_band_start[g + 1]`.
    pub group_band_start: Vec<u32>,
}

impl Layout {
    /// The layout of an image of `tile_block_start.len() − 1` tiles, `tiles_x` to a row: groups
    /// of whole tile rows, each closed once it holds [`BAND_BLOCKS`] blocks (the last group
    /// whatever is left), and a group's blocks in bands of [`BAND_BLOCKS`], the last smaller.
    pub fn of(tile_block_start: &[u32], tiles_x: usize) -> Layout {
        let tiles = tile_block_start.len().saturating_sub(1);
        let ty = tiles.checked_div(tiles_x).unwrap_or(0);
        let first_block = |row: usize| tile_block_start[row * tiles_x] as usize;
        let mut l = Layout {
            band_block_start: vec![0],
            group_row_start: vec![0],
            group_band_start: vec![0],
        };
        for y in 1..=ty {
            let first = *l.group_row_start.last().unwrap_or(&0) as usize;
            if first_block(y) - first_block(first) >= BAND_BLOCKS || y == ty {
                l.group_row_start.push(y as u32);
                let mut b = first_block(first);
                while b < first_block(y) {
                    b = (b + BAND_BLOCKS).min(first_block(y));
                    l.band_block_start.push(b as u32);
                }
                l.group_band_start.push(l.band_block_start.len() as u32 - 1);
            }
        }
        l
    }

    /// The blocks of each band of group `g`.
    fn group_bands_of(&self, g: usize) -> impl Iterator<Item = Range<usize>> + '_ {
        let bands = self.group_band_start[g] as usize..self.group_band_start[g + 1] as usize;
        bands.map(|i| self.band_block_start[i] as usize..self.band_block_start[i + 1] as usize)
    }

    /// The blocks of group `g`.
    fn group_blocks(&self, g: usize) -> Range<usize> {
        let bands = self.group_band_start[g] as usize..self.group_band_start[g + 1] as usize;
        self.band_block_start[bands.start] as usize..self.band_block_start[bands.end] as usize
    }
}

impl Strips {
    /// A slot's entries: (row inside the block, stored value) for each of its strips' values
    /// that is an entry, rows increasing.
    pub fn column(&self, slot: Slot) -> impl Iterator<Item = (u8, f32)> + '_ {
        let strips = slot.first as usize..slot.first as usize + slot.count as usize;
        strips.flat_map(move |k| {
            let base = self.index[k] * STRIP_ROWS as u8;
            (0..STRIP_ROWS).filter_map(move |i| {
                let v = self.values.raw(k * STRIP_ROWS + i);
                (v != 0.0).then_some((base + i as u8, v))
            })
        })
    }

    /// The slot of coefficient `j` in block `b`, for a transport of `c` coefficients.
    pub fn slot(&self, b: usize, j: usize, c: usize) -> Slot {
        let blocks = self.band_blocks(self.band_of(b));
        self.slots[blocks.start * c + j * blocks.len() + (b - blocks.start)]
    }

    /// Stored entries in all.
    pub fn entry_count(&self) -> u64 {
        self.slots.iter().map(|s| s.entries as u64).sum()
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

    /// Which blocks of band `band` hold strips of coefficient `j` (bit i for the band's block
    /// i), for a transport of `c` coefficients: the set bits of the slots
    /// [`term_slots`](Self::term_slots) gives that have strips.
    #[inline]
    pub fn occupied(&self, band: usize, j: usize, c: usize) -> u16 {
        self.occupied[band * c + j]
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

    /// Per slot, in order, its strip count and its scale code: the two tables a file stores.
    pub fn slot_tables(&self) -> (Vec<u8>, Vec<u8>) {
        (
            self.slots.iter().map(|s| s.count).collect(),
            self.slots.iter().map(|s| s.code).collect(),
        )
    }

    /// The groups, bands and blocks these strips are laid out in.
    pub fn layout(&self) -> Layout {
        Layout {
            band_block_start: self.band_block_start.clone(),
            group_row_start: self.group_row_start.clone(),
            group_band_start: self.group_band_start.clone(),
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Blocks of 256 and 20 rows (32 and 3 strips) in 2 coefficients, slots in the order
    /// (coefficient, block): the first block's coefficient 0 has entries in 16 strips of its 32
    /// (half: stored whole), its coefficient 1 in 15 (stored as they are); the second block's
    /// coefficient 0 in 1 strip of its 3, its coefficient 1 in 2 (stored whole).
    fn strips() -> Strips {
        let first_rows: Vec<u8> = (0..16)
            .map(|k| 16 * k)
            .chain((0..15).map(|k| 8 * k))
            .collect();
        let first_values: Vec<i8> = (1..=31).collect();
        let (second_rows, second_values) = ([3u8, 3, 17], [-5i8, 6, 7]);
        let blocks = [
            BlockColumns {
                counts: &[16, 15],
                codes: &[100, 101],
                rows: &first_rows,
                values: &first_values,
                block_rows: 256,
            },
            BlockColumns {
                counts: &[1, 2],
                codes: &[102, 103],
                rows: &second_rows,
                values: &second_values,
                block_rows: 20,
            },
        ];
        Strips::of_blocks(Layout::of(&[0, 2], 1), &blocks, 2).unwrap()
    }

    /// The same strips with `edit` made to their tables, as a file's would be read.
    fn edited(edit: impl FnOnce(&mut Vec<u8>, &mut Vec<i8>)) -> Strips {
        let s = strips();
        let (counts, codes) = s.slot_tables();
        let (mut index, mut values) = (s.index.clone(), Vec::from(i8::slice(&s.values).unwrap()));
        edit(&mut index, &mut values);
        Strips::from_tables(s.layout(), &counts, &codes, index, Values::Q8(values)).unwrap()
    }

    #[test]
    fn slots_at_least_half_full_are_stored_whole_and_read_back_as_stored() {
        let s = strips();
        let counts: Vec<u8> = s.slots.iter().map(|s| s.count).collect();
        let entries: Vec<u16> = s.slots.iter().map(|s| s.entries).collect();
        assert_eq!(counts, [32, 1, 15, 3]);
        assert_eq!(entries, [16, 1, 15, 2]);
        assert_eq!(s.problem(&[256, 20], 2), None);
        // Every entry where it was, the whole slots' other strips zero.
        let column: Vec<(u8, f32)> = s.column(s.slots[0]).collect();
        let want: Vec<(u8, f32)> = (0..16).map(|k| (16 * k as u8, (k + 1) as f32)).collect();
        assert_eq!(column, want);
        assert_eq!(
            s.column(s.slots[3]).collect::<Vec<_>>(),
            [(3, 6.0), (17, 7.0)]
        );
        assert_eq!(&s.index[s.slots[3].first as usize..][..3], [0, 1, 2]);
        assert_eq!(edited(|_, _| {}), s);
    }

    #[test]
    fn only_a_whole_slot_may_hold_an_empty_strip_and_no_strip_lies_past_its_block() {
        let s = strips();
        let zero = |k: usize| move |_: &mut Vec<u8>, v: &mut Vec<i8>| v[8 * k..8 * k + 8].fill(0);
        // Strip 1 of the first block's whole slot 0 is empty already; strip 0 held an entry.
        assert_eq!(edited(zero(0)).problem(&[256, 20], 2), None);
        let first_of = |i: usize| s.slots[i].first as usize;
        let e = edited(zero(first_of(2))).problem(&[256, 20], 2).unwrap();
        assert!(
            e.contains("block 0, coefficient 1: strip 0 holds no entry"),
            "{e}"
        );
        // The second block's slot of one strip moved past its 3 strips.
        let e = edited(|i, _| i[first_of(1)] = 3)
            .problem(&[256, 20], 2)
            .unwrap();
        assert!(
            e.contains("block 1, coefficient 0: strip 3 outside the block's 20 rows"),
            "{e}"
        );
        // A column with a row past its block is refused when strips are made.
        let blocks = [BlockColumns {
            counts: &[1],
            codes: &[100],
            rows: &[20],
            values: &[1i8],
            block_rows: 20,
        }];
        let e = Strips::of_blocks(Layout::of(&[0, 1], 1), &blocks, 1).unwrap_err();
        assert!(e.contains("a row past the block's 20"), "{e}");
    }
}
