//! The process-wide cache of lat-long -> cube weights: the last few (W, H, N, pitch) asked for,
//! most recently used first, under a lock held only to look up and insert.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use super::LatLongWeights;
use crate::error::Result;

/// Most weight matrices kept at once: the viewer needs two per cube size (pitch 0 for the
/// unturned SH light, the current pitch for the wavelet light); benchmarks and demos switch
/// between two map sizes and two cube sizes.
const CACHE_ENTRIES: usize = 8;
/// Memory the cache may hold (a 1024 x 512 map takes about 8 MiB at N = 32 and 20 MiB at
/// N = 64). The newest entry is always kept, whatever its size.
const CACHE_BYTES: usize = 512 << 20;
/// Cached weights of (`width`, `height`, `n`, `pitch_deg`), built on a miss. The lock is not held
/// while building, so two threads missing the same key at once both build it (harmless).
pub fn weights(
    width: usize,
    height: usize,
    n: usize,
    pitch_deg: f64,
) -> Result<Arc<LatLongWeights>> {
    // -0 and +0 are the same rotation.
    let pitch_deg = pitch_deg + 0.0;
    let key = |w: &LatLongWeights| {
        (w.width, w.height, w.n, w.pitch_deg.to_bits()) == (width, height, n, pitch_deg.to_bits())
    };
    {
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = cache.iter().position(|w| key(w)) {
            let hit = cache.remove(i);
            cache.insert(0, hit.clone());
            return Ok(hit);
        }
    }
    let built = Arc::new(build(width, height, n, pitch_deg)?);
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    cache.retain(|w| !key(w));
    cache.insert(0, built.clone());
    let mut bytes = 0;
    let keep = cache
        .iter()
        .take_while(|w| {
            bytes += w.bytes();
            bytes <= CACHE_BYTES
        })
        .count();
    cache.truncate(keep.clamp(1, CACHE_ENTRIES));
    Ok(built)
}

/// Unturned weights from the disk ([`super::disk`]) when a valid file is there, else recorded
/// (and then stored there, if the folder can be written); other pitches are recorded.
fn build(width: usize, height: usize, n: usize, pitch_deg: f64) -> Result<LatLongWeights> {
    let dir = (pitch_deg == 0.0 && USE_DISK.load(Ordering::Relaxed))
        .then(super::disk::folder)
        .flatten();
    if let Some(dir) = &dir
        && let Some(w) = super::disk::load(dir, width, height, n)
    {
        return Ok(w);
    }
    let w = LatLongWeights::build(width, height, n, pitch_deg)?;
    if let Some(dir) = &dir {
        // The disk only saves the next process the recording: a folder that cannot be written
        // costs nothing else.
        let _ = super::disk::store(dir, &w);
    }
    Ok(w)
}

/// Whether unturned weights are read from and written to the disk (on unless turned off).
static USE_DISK: AtomicBool = AtomicBool::new(true);

/// Turns the disk of unturned weights on or off for this process (benchmarks time the recording
/// with it off).
pub fn use_disk(on: bool) {
    USE_DISK.store(on, Ordering::Relaxed);
}

/// Most recently used first.
static CACHE: Mutex<Vec<Arc<LatLongWeights>>> = Mutex::new(Vec::new());

/// Empties the weight cache (for benchmarks that time the first call).
pub fn clear_cache() {
    CACHE.lock().unwrap_or_else(|e| e.into_inner()).clear();
}
