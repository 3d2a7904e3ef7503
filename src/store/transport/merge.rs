//! Shards of one bake merged into the file a single bake would write: each shard checked to be
//! the same bake, its tiles handed on in tile order to memory or to a file.

use std::path::Path;

use super::*;
use crate::error::{PrtError, Result};

impl Transport {
    /// Joins the shards of one bake (in any order) into the file a single bake would have
    /// written. The shards must come from the same scene and settings and cover every band once.
    /// Errors name a shard as "file K" (its place in `shards`, from 1).
    pub fn merge(shards: &[Transport]) -> Result<Transport> {
        let names: Vec<String> = (1..=shards.len()).map(|k| format!("file {k}")).collect();
        Self::merge_named(shards, &names)
    }

    /// [`Transport::merge`], naming shard k as `names[k]` in errors (a path, say).
    pub fn merge_named(shards: &[Transport], names: &[String]) -> Result<Transport> {
        let mut kept = KeptTiles::default();
        let untiled = merge_tiles(shards, names, &mut |tile, stats| kept.push(tile, stats))?;
        kept.into_transport(untiled)
    }

    /// [`Transport::merge_named`] written to the transport file `path` tile by tile
    /// ([`super::TransportWriter`]): memory holds the shards, not the merged transport as well.
    /// The same bytes as the merge saved.
    pub fn merge_to_file(
        shards: &[Transport],
        names: &[String],
        path: &Path,
    ) -> Result<TransportMeta> {
        let first = shards
            .first()
            .ok_or_else(|| PrtError::invalid("merge", "no shard given"))?;
        let mut writer = super::TransportWriter::create(
            path,
            (first.meta.width as usize, first.meta.height as usize),
            first.meta.identity.cube_n as usize,
            first.meta.identity.sh_order as usize,
            first.meta.identity.quantization,
        )?;
        let untiled = merge_tiles(shards, names, &mut |tile, stats| writer.push(&tile, stats))?;
        writer.finish(untiled)
    }
}

/// Checks that `shards` (named `names` in errors) are one bake's and hands their tiles, in tile
/// order, to `deliver` with their statistics.
fn merge_tiles(
    shards: &[Transport],
    names: &[String],
    deliver: &mut dyn FnMut(EncodedTile, [f64; 3]) -> Result<()>,
) -> Result<Untiled> {
    let name = |k: usize| {
        names
            .get(k)
            .cloned()
            .unwrap_or_else(|| format!("file {}", k + 1))
    };
    let first = shards
        .first()
        .ok_or_else(|| PrtError::invalid("merge", "no shard given"))?;
    let Some([_, count]) = first.meta.identity.shard else {
        return Err(PrtError::invalid(
            "merge",
            format!("{} is not a shard", name(0)),
        ));
    };
    let same = |m: &TransportMeta| {
        let mut m = m.clone();
        m.identity.shard = None;
        m.stats = BakeStats::default();
        m
    };
    // Loading checked count <= the image's bands, so this is small.
    let mut owner = vec![usize::MAX; count as usize];
    for (k, s) in shards.iter().enumerate() {
        if same(&s.meta) != same(&first.meta) {
            return Err(PrtError::invalid(
                "merge",
                meta_difference(&same(&s.meta), &name(k), &same(&first.meta), &name(0)),
            ));
        }
        match s.meta.identity.shard {
            Some([i, n]) if n == count && i < n && owner[i as usize] == usize::MAX => {
                owner[i as usize] = k
            }
            Some([i, n]) if n == count && i < n => {
                return Err(PrtError::invalid(
                    "merge",
                    format!(
                        "shard {i}/{n} repeats: {} and {} are both shard {i}/{n}",
                        name(owner[i as usize]),
                        name(k)
                    ),
                ));
            }
            Some([i, n]) => {
                return Err(PrtError::invalid(
                    "merge",
                    format!(
                        "{} is shard {i}/{n}, which does not fit a set of {count} shards",
                        name(k)
                    ),
                ));
            }
            None => {
                return Err(PrtError::invalid(
                    "merge",
                    format!("{} is not a shard", name(k)),
                ));
            }
        }
    }
    if let Some(i) = owner.iter().position(|&o| o == usize::MAX) {
        return Err(PrtError::invalid(
            "merge",
            format!("shard {i}/{count} is missing"),
        ));
    }
    let (w, h) = (first.meta.width as usize, first.meta.height as usize);
    let (tx, ty) = tile_grid(w, h);
    // A shard holds nothing outside its own bands: a label that does not match the content
    // (two shards' labels swapped, say) would otherwise merge into a mostly black image.
    for (i, &k) in owner.iter().enumerate() {
        let s = &shards[k];
        for band in (0..ty).filter(|&b| shard_of_band(b, ty, count as usize) != i) {
            let tiles = band * tx..(band + 1) * tx;
            let pixels = band * TILE * w..((band + 1) * TILE * w).min(w * h);
            let rows = s.tile_row_start[tiles.end] - s.tile_row_start[tiles.start];
            let stats = s.tile_stats[tiles].iter().flatten().any(|v| *v != 0.0);
            let seen = s.coverage[pixels.clone()].iter().any(|v| *v != 0.0)
                || s.albedo[pixels].iter().flatten().any(|v| *v != 0.0)
                || s.attached
                    .holds_rows(band * TILE..((band + 1) * TILE).min(h));
            if rows > 0 || stats || seen {
                return Err(PrtError::invalid(
                    "merge",
                    format!(
                        "{} is labelled shard {i}/{count} but holds data in tile row {band}, \
                             which shard {}/{count} bakes: its `shard` label does not match its \
                             content",
                        name(k),
                        shard_of_band(band, ty, count as usize)
                    ),
                ));
            }
        }
    }
    if let Some(k) = shards
        .iter()
        .position(|s| s.attached.domain != first.attached.domain)
    {
        return Err(PrtError::invalid(
            "merge",
            format!("{} holds another vertex mesh than {}", name(k), name(0)),
        ));
    }
    let mut albedo = vec![[0.0f32; 3]; w * h];
    let mut coverage = vec![0.0f32; w * h];
    let mut attached = first.attached.emptied((first.meta.light_columns(), w, h));
    for band in 0..ty {
        let s = &shards[owner[shard_of_band(band, ty, count as usize)]];
        for tile in band * tx..(band + 1) * tx {
            deliver(s.encoded_tile(tile), s.tile_stats[tile])?;
        }
        let pixels = band * TILE * w..((band + 1) * TILE * w).min(w * h);
        albedo[pixels.clone()].copy_from_slice(&s.albedo[pixels.clone()]);
        coverage[pixels.clone()].copy_from_slice(&s.coverage[pixels]);
        attached.copy_rows(&s.attached, band * TILE..((band + 1) * TILE).min(h));
    }
    Ok(Untiled {
        meta: same(&first.meta),
        albedo,
        coverage,
        attached,
    })
}

/// How shard `a` (named `na`) differs from shard `b` (named `nb`): "A was baked from another
/// scene than B (scene hash X against Y)", or the first setting that differs, "A was baked with
/// seed 7, B with seed 1".
fn meta_difference(a: &TransportMeta, na: &str, b: &TransportMeta, nb: &str) -> String {
    let (ha, hb) = (&a.identity.scene_hash, &b.identity.scene_hash);
    if ha != hb {
        return format!(
            "{na} was baked from another scene than {nb} (scene hash {ha} against {hb})"
        );
    }
    if let (Ok(serde_json::Value::Object(x)), Ok(serde_json::Value::Object(y))) =
        (serde_json::to_value(a), serde_json::to_value(b))
    {
        for (key, va) in &x {
            let vb = y.get(key).unwrap_or(&serde_json::Value::Null);
            if va != vb {
                return format!("{na} was baked with {key} {va}, {nb} with {key} {vb}");
            }
        }
    }
    format!("{na} was baked with other settings than {nb}")
}

/// The shard that bakes band (tile row) `band` of `bands` when a bake is split into `count`.
pub fn shard_of_band(band: usize, bands: usize, count: usize) -> usize {
    (band * count) / bands.max(1)
}
