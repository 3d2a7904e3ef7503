//! Version 3 to 6 files stored each block's coefficients as columns of entries, not strips:
//! their columns, checked against the blocks' rows and entries, turned into strips on load.

use super::strips::{BlockColumns, Layout, Stored};
use super::*;

/// The strips of a version 3 to 6 file's columns: per (block, coefficient) an entry count and
/// a scale code, then the entries' rows and values in (block, coefficient) order. Counts are
/// checked against the blocks' rows and the entries before anything is sliced.
pub(super) fn strips_of_columns(
    layout: Layout,
    columns: Columns,
    values: &Values,
) -> std::result::Result<Strips, String> {
    fn of<V: Stored>(
        layout: Layout,
        starts: &[u64],
        columns: Columns,
        values: &[V],
    ) -> std::result::Result<Strips, String> {
        let Columns {
            block_row_start,
            c,
            counts,
            codes,
            rows,
        } = columns;
        let blocks: Vec<BlockColumns<V>> = starts
            .windows(2)
            .zip(block_row_start.windows(2))
            .enumerate()
            .map(|(b, (e, r))| {
                let e = e[0] as usize..e[1] as usize;
                BlockColumns {
                    counts: &counts[b * c..(b + 1) * c],
                    codes: &codes[b * c..(b + 1) * c],
                    rows: &rows[e.clone()],
                    values: &values[e],
                    block_rows: r[1].saturating_sub(r[0]) as usize,
                }
            })
            .collect();
        Strips::of_blocks(layout, &blocks, c)
    }
    let rows = columns.rows.len();
    if values.len() != rows || columns.counts.len() != columns.codes.len() {
        return Err("the columns' tables differ in length".into());
    }
    let starts = column_pointers(columns.counts, columns.block_row_start, columns.c, rows)?;
    match values {
        Values::Q8(v) => of(layout, &starts, columns, v),
        Values::Q16(v) => of(layout, &starts, columns, v),
        Values::F32(v) => of(layout, &starts, columns, v),
    }
}

/// A version 3 to 6 file's columns of `c` coefficients a block, less their values.
#[derive(Clone, Copy)]
pub(super) struct Columns<'a> {
    /// Each block's first row, and the end.
    pub(super) block_row_start: &'a [u32],
    pub(super) c: usize,
    /// Entries of each (block, coefficient).
    pub(super) counts: &'a [u16],
    /// Scale code of each (block, coefficient).
    pub(super) codes: &'a [u8],
    /// The entries' rows inside their blocks.
    pub(super) rows: &'a [u8],
}
