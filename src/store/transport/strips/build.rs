//! Strips made from a bake's block columns, in parallel over groups, and a version-7 file's
//! strips made whole where this build stores them whole.

use std::ops::Range;

use rayon::prelude::*;

use super::{BlockColumns, Layout, STRIP_ROWS, Slot, Stored, Strips, block_strips, stored_whole};
use crate::store::quant::BLOCK_ROWS;
use crate::store::transport::Values;

/// Where each of block `b`'s columns starts among its entries.
fn column_starts<'b, V>(b: &BlockColumns<'b, V>) -> impl Iterator<Item = Range<usize>> + 'b {
    let mut at = 0usize;
    b.counts.iter().map(move |&n| {
        let s = at;
        at += n as usize;
        s..at
    })
}

/// Checks the blocks' columns of `c` coefficients against their entries: counts, codes, rows
/// strictly increasing in each column, and no entry past its block's rows.
fn check_blocks<V: Stored>(
    blocks: &[BlockColumns<V>],
    c: usize,
) -> std::result::Result<(), String> {
    for (i, b) in blocks.iter().enumerate() {
        let total: usize = b.counts.iter().map(|&n| n as usize).sum();
        if b.counts.len() != c
            || b.codes.len() != c
            || b.rows.len() != total
            || b.values.len() != total
            || b.block_rows > BLOCK_ROWS
        {
            return Err(format!("block {i}: its columns do not fit its entries"));
        }
        for (j, col) in column_starts(b).enumerate() {
            if b.rows[col.clone()].windows(2).any(|w| w[1] <= w[0]) {
                return Err(format!(
                    "block {i}, coefficient {j}: rows not strictly increasing"
                ));
            }
            // A stored zero (an older file may hold one) is no entry and may lie anywhere.
            let mut entries = b.rows[col.clone()].iter().zip(&b.values[col]);
            if entries.any(|(&r, v)| v.is_entry() && r as usize >= b.block_rows) {
                return Err(format!(
                    "block {i}, coefficient {j}: a row past the block's {}",
                    b.block_rows
                ));
            }
        }
    }
    Ok(())
}

/// The first pass of [`Strips::of_blocks`] for group `g`: every column's strips counted, and the
/// group's slots laid out band by band, coefficient by coefficient; with the group's strips.
fn group_slots<V: Stored>(
    layout: &Layout,
    blocks: &[BlockColumns<V>],
    c: usize,
    g: usize,
) -> (Vec<Slot>, usize) {
    let group = layout.group_blocks(g);
    let mut counts = vec![0u8; group.len() * c];
    for (i, b) in blocks[group.clone()].iter().enumerate() {
        let block_strips = block_strips(b.block_rows);
        for (col, count) in column_starts(b).zip(&mut counts[i * c..(i + 1) * c]) {
            let mut last = None;
            // A stored zero (an older file may hold one) is no entry and takes no strip.
            let entries = b.rows[col.clone()].iter().zip(&b.values[col]);
            for (&r, _) in entries.filter(|(_, v)| v.is_entry()) {
                let place = r / STRIP_ROWS as u8;
                if last != Some(place) {
                    last = Some(place);
                    *count += 1;
                }
            }
            if stored_whole(*count as usize, block_strips) {
                *count = block_strips as u8;
            }
        }
    }
    let mut slots = Vec::with_capacity(group.len() * c);
    let mut strips = 0usize;
    for band in layout.group_bands_of(g) {
        for j in 0..c {
            for b in band.clone() {
                let count = counts[(b - group.start) * c + j];
                slots.push(Slot {
                    first: strips as u32,
                    count,
                    code: blocks[b].codes[j],
                    entries: blocks[b].counts[j],
                });
                strips += count as usize;
            }
        }
    }
    (slots, strips)
}

impl Strips {
    /// The strips of the blocks `blocks` (block b's columns), laid out as `layout` says, in
    /// `c` coefficients. Groups are laid out in parallel, in two passes straight into the final
    /// buffers. An error when the strips would not be counted in 32 bits (a matrix of more than
    /// 2^32 strips, some 30 GB) or a column does not fit its block.
    pub fn of_blocks<V: Stored>(
        layout: Layout,
        blocks: &[BlockColumns<V>],
        c: usize,
    ) -> std::result::Result<Strips, String> {
        let groups = layout.group_row_start.len().saturating_sub(1);
        if layout.band_block_start.last().copied().unwrap_or(0) as usize != blocks.len() {
            return Err("the layout's bands do not cover the blocks".into());
        }
        check_blocks(blocks, c)?;
        // First pass, in parallel over groups: every column's strips counted, and the slots
        // laid out band by band, coefficient by coefficient.
        let layouts: Vec<(Vec<Slot>, usize)> = (0..groups)
            .into_par_iter()
            .map(|g| group_slots(&layout, blocks, c, g))
            .collect();
        let total: usize = layouts.iter().map(|l| l.1).sum();
        if u32::try_from(total).is_err() {
            return Err(format!(
                "{total} strips of 8 rows are more than the kernel counts in 32 bits"
            ));
        }
        let mut index = vec![0u8; total];
        let mut strip_values = vec![V::default(); total * STRIP_ROWS];
        // Second pass: each group fills its own part of the strips.
        let mut parts = Vec::with_capacity(groups);
        let (mut index_rest, mut values_rest) = (&mut index[..], &mut strip_values[..]);
        for (_, strips) in &layouts {
            let (i, rest) = index_rest.split_at_mut(*strips);
            let (v, rest_v) = values_rest.split_at_mut(strips * STRIP_ROWS);
            parts.push((i, v));
            (index_rest, values_rest) = (rest, rest_v);
        }
        parts.into_par_iter().zip(&layouts).enumerate().for_each(
            |(g, ((index, strip_values), (slots, _)))| {
                let group = layout.group_blocks(g);
                let mut slot_at = 0;
                for band in layout.group_bands_of(g) {
                    let nb = band.len();
                    for (i, b) in band.clone().enumerate() {
                        let cols = &blocks[b];
                        for (j, col) in column_starts(cols).enumerate() {
                            let slot = slots[slot_at + j * nb + i];
                            let first = slot.first as usize;
                            let entries = cols.rows[col.clone()].iter().zip(&cols.values[col]);
                            let mut entries = entries.filter(|(_, v)| v.is_entry()).peekable();
                            // A slot stored whole holds strip s of its block at place s.
                            if entries.peek().is_some()
                                && slot.count as usize == block_strips(cols.block_rows)
                            {
                                let whole = first..first + slot.count as usize;
                                for (place, k) in whole.enumerate() {
                                    index[k] = place as u8;
                                }
                                for (&r, &v) in entries {
                                    strip_values[first * STRIP_ROWS + r as usize] = v;
                                }
                                continue;
                            }
                            let mut k = first;
                            let mut last = None;
                            for (&r, &v) in entries {
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
                    slot_at += nb * c;
                }
                debug_assert_eq!(slot_at, group.len() * c);
            },
        );
        let mut slots = Vec::with_capacity(blocks.len() * c);
        let mut base = 0u32;
        for (group, strips) in layouts {
            slots.extend(group.iter().map(|slot| Slot {
                first: slot.first + base,
                ..*slot
            }));
            base += strips as u32;
        }
        Ok(Strips::laid_out(
            layout,
            slots,
            index,
            V::wrap(strip_values),
        ))
    }

    /// Strips laid out as `layout` says, of these slots, places and values, with every slot's
    /// entries counted and the occupied slots marked.
    pub(super) fn laid_out(
        layout: Layout,
        slots: Vec<Slot>,
        index: Vec<u8>,
        values: Values,
    ) -> Strips {
        let mut s = Strips {
            band_block_start: layout.band_block_start,
            group_row_start: layout.group_row_start,
            group_band_start: layout.group_band_start,
            slots,
            index,
            values,
            occupied: Vec::new(),
        };
        s.count_entries();
        s
    }

    /// Sets every slot's entries to the number of its strips' values that are entries (not
    /// zero), in parallel over bands, and which slots hold strips.
    fn count_entries(&mut self) {
        // Nothing here may panic on tables that do not fit ([`Strips::problem`] reports them):
        // a band whose slots are not all there reads as empty.
        let start = &self.band_block_start;
        let blocks = start.last().copied().unwrap_or(0) as usize;
        let c = self.slots.len().checked_div(blocks).unwrap_or(0);
        let slots = &self.slots;
        self.occupied = (0..start.len().saturating_sub(1))
            .into_par_iter()
            .flat_map_iter(|band| {
                let (a, b) = (start[band] as usize, start[band + 1] as usize);
                let len = b.saturating_sub(a);
                let band_slots = slots.get(a * c..b * c).unwrap_or(&[]);
                (0..c).map(move |j| {
                    band_slots.get(j * len..(j + 1) * len).map_or(0, |term| {
                        term.iter()
                            .enumerate()
                            .filter(|(_, s)| s.count > 0)
                            .fold(0u16, |m, (i, _)| {
                                m | 1u16.checked_shl(i as u32).unwrap_or(0)
                            })
                    })
                })
            })
            .collect();
        fn count<V: Stored>(slots: &mut [Slot], values: &[V]) {
            slots.par_iter_mut().with_min_len(1024).for_each(|s| {
                let v = &values[s.first as usize * STRIP_ROWS..][..s.count as usize * STRIP_ROWS];
                s.entries = v.iter().filter(|x| x.is_entry()).count() as u16;
            });
        }
        match &self.values {
            Values::Q8(v) => count(&mut self.slots, v),
            Values::Q16(v) => count(&mut self.slots, v),
            Values::F32(v) => count(&mut self.slots, v),
        }
    }

    /// These strips, already checked against blocks of `block_rows[b]` rows in `c` coefficients
    /// ([`Strips::problem`], as every loaded transport's are), with every slot that
    /// [`stored_whole`] makes whole holding all its block's strips, zeros where none was: what a
    /// file of version 7, which kept only the strips that hold entries, holds in this version.
    /// In one pass over the slots, with no more memory than the strips twice.
    pub(crate) fn with_slots_made_whole(
        &self,
        block_rows: &[u32],
        c: usize,
    ) -> std::result::Result<Strips, String> {
        fn pad<V: Stored>(
            s: &Strips,
            values: &[V],
            block_rows: &[u32],
            c: usize,
        ) -> std::result::Result<Strips, String> {
            let (mut counts, mut codes) = (Vec::with_capacity(s.slots.len()), Vec::new());
            let (mut index, mut padded) = (Vec::new(), Vec::new());
            for band in 0..s.band_count() {
                for j in 0..c {
                    let blocks = s.band_blocks(band);
                    for (slot, b) in s.term_slots(band, j, c).iter().zip(blocks) {
                        let strips = slot.first as usize..slot.first as usize + slot.count as usize;
                        let rows = block_rows.get(b).copied().unwrap_or(0) as usize;
                        let block_strips = block_strips(rows);
                        let held = &s.index[strips.clone()];
                        let own = &values[strips.start * STRIP_ROWS..strips.end * STRIP_ROWS];
                        if stored_whole(held.len(), block_strips)
                            && held.len() < block_strips
                            && held.iter().all(|&p| (p as usize) < block_strips)
                        {
                            let at = padded.len();
                            index.extend(0..block_strips as u8);
                            padded.resize(at + block_strips * STRIP_ROWS, V::default());
                            for (&p, v) in held.iter().zip(own.chunks_exact(STRIP_ROWS)) {
                                let to = at + p as usize * STRIP_ROWS;
                                padded[to..to + STRIP_ROWS].copy_from_slice(v);
                            }
                            counts.push(block_strips as u8);
                        } else {
                            index.extend_from_slice(held);
                            padded.extend_from_slice(own);
                            counts.push(slot.count);
                        }
                        codes.push(slot.code);
                    }
                }
            }
            Strips::from_tables(s.layout(), &counts, &codes, index, V::wrap(padded))
        }
        match &self.values {
            Values::Q8(v) => pad(self, v, block_rows, c),
            Values::Q16(v) => pad(self, v, block_rows, c),
            Values::F32(v) => pad(self, v, block_rows, c),
        }
    }
}
