//! Strips from the tables a file stores, and the checks every loaded transport's strips pass.

use rayon::prelude::*;

use super::{Layout, STRIP_ROWS, Slot, Stored, Strips, block_strips};
use crate::store::transport::Values;

impl Strips {
    /// Strips from their tables as a file stores them: per slot (band, coefficient, block, as
    /// `layout` orders them) a strip count and a scale code, per strip its place and
    /// [`STRIP_ROWS`] values. Every slot's first strip and entries follow from these; nothing
    /// is checked here but that the tables fit one another ([`Strips::problem`] checks the rest).
    pub fn from_tables(
        layout: Layout,
        counts: &[u8],
        codes: &[u8],
        index: Vec<u8>,
        values: Values,
    ) -> std::result::Result<Strips, String> {
        if counts.len() != codes.len() {
            return Err("strip counts and scale codes differ in number".into());
        }
        let mut first = 0u64;
        let slots: Vec<Slot> = counts
            .iter()
            .zip(codes)
            .map(|(&count, &code)| {
                let s = Slot {
                    first: first.min(u32::MAX as u64) as u32,
                    count,
                    code,
                    entries: 0,
                };
                first += count as u64;
                s
            })
            .collect();
        if first != index.len() as u64 || values.len() as u64 != first * STRIP_ROWS as u64 {
            return Err(format!(
                "strip counts add up to {first} strips but {} places and {} values are stored",
                index.len(),
                values.len()
            ));
        }
        if u32::try_from(first).is_err() {
            return Err(format!(
                "{first} strips of 8 rows are more than the kernel counts in 32 bits"
            ));
        }
        Ok(Strips::laid_out(layout, slots, index, values))
    }

    /// The first inconsistency of these strips with blocks of `block_rows[b]` rows each in `c`
    /// coefficients, if any: a slot table of the wrong size, slots that do not tile the strips in
    /// order, more strips than a block holds, places not increasing or outside the block, a
    /// value in a row the block does not have, a strip with no entry (but in a slot stored
    /// whole), an entry count that is not the strips', or a value that is not finite. Checked in
    /// parallel over bands.
    pub fn problem(&self, block_rows: &[u32], c: usize) -> Option<String> {
        let blocks = block_rows.len();
        if self.band_block_start.last().copied().unwrap_or(0) as usize != blocks
            || self.slots.len() != blocks * c
        {
            return Some(format!(
                "{} slots for {blocks} blocks of {c} coefficients",
                self.slots.len()
            ));
        }
        if self.values.len() != self.index.len() * STRIP_ROWS {
            return Some("strip values do not match the strips".into());
        }
        let mut next = 0u64;
        for (i, s) in self.slots.iter().enumerate() {
            if s.first as u64 != next {
                return Some(format!(
                    "slot {i}: its strips do not follow the slot before"
                ));
            }
            next += s.count as u64;
        }
        if next != self.index.len() as u64 {
            return Some(format!(
                "slots hold {next} strips but {} are stored",
                self.index.len()
            ));
        }
        fn check<V: Stored>(
            s: &Strips,
            values: &[V],
            finite: fn(V) -> bool,
            block_rows: &[u32],
            c: usize,
        ) -> Option<String> {
            (0..s.band_count()).into_par_iter().find_map_first(|band| {
                let blocks = s.band_blocks(band);
                for j in 0..c {
                    for (slot, b) in s.term_slots(band, j, c).iter().zip(blocks.clone()) {
                        let rows = block_rows[b] as usize;
                        let at = |m: &str| Some(format!("block {b}, coefficient {j}: {m}"));
                        let block_strips = block_strips(rows);
                        if slot.count as usize > block_strips {
                            return at(&format!("{} strips in {rows} rows", slot.count));
                        }
                        // A slot stored whole ([`stored_whole`]) may hold strips with no entry.
                        let whole = slot.count as usize == block_strips;
                        let strips = slot.first as usize..slot.first as usize + slot.count as usize;
                        let mut last: i32 = -1;
                        let mut entries = 0usize;
                        for k in strips {
                            let place = s.index[k] as i32;
                            if place <= last {
                                return at("strip places not increasing");
                            }
                            if place as usize >= block_strips {
                                return at(&format!(
                                    "strip {place} outside the block's {rows} rows"
                                ));
                            }
                            last = place;
                            let v = &values[k * STRIP_ROWS..(k + 1) * STRIP_ROWS];
                            if !v.iter().all(|&x| finite(x)) {
                                return at("a value is NaN or infinite");
                            }
                            let n = v.iter().filter(|x| x.is_entry()).count();
                            if n == 0 && !whole {
                                return at(&format!("strip {place} holds no entry"));
                            }
                            let past =
                                (place as usize * STRIP_ROWS + STRIP_ROWS).saturating_sub(rows);
                            if v[STRIP_ROWS - past.min(STRIP_ROWS)..]
                                .iter()
                                .any(|x| x.is_entry())
                            {
                                return at(&format!(
                                    "strip {place} holds a row past the block's {rows}"
                                ));
                            }
                            entries += n;
                        }
                        if entries != slot.entries as usize {
                            return at("its entry count is not its strips'");
                        }
                    }
                }
                None
            })
        }
        match &self.values {
            Values::Q8(v) => check(self, v, |_| true, block_rows, c),
            Values::Q16(v) => check(self, v, |_| true, block_rows, c),
            Values::F32(v) => check(self, v, f32::is_finite, block_rows, c),
        }
    }
}
