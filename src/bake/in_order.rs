//! Tiles baked in parallel and handed on in tile order, so that a bake can write each one out as
//! soon as the tiles before it are written, holding only those under way.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::error::{PrtError, Result};

/// A token that stops a bake between tiles. Its clones share one flag, so a progress callback
/// or another thread can cancel a bake under way, which then returns [`PrtError::Cancelled`]
/// and writes nothing.
#[derive(Clone, Debug, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A token not cancelled.
    pub fn new() -> Cancel {
        Cancel::default()
    }

    /// Cancels the bakes that hold this token or a clone of it.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`Cancel::cancel`] was called on this token or a clone of it.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// [`PrtError::Cancelled`] once cancelled.
    pub fn check(&self) -> Result<()> {
        match self.is_cancelled() {
            true => Err(PrtError::Cancelled),
            false => Ok(()),
        }
    }
}

/// Runs `work` on tiles `0..count` over the thread pool, each thread taking the next tile not
/// yet taken, and hands the results to `deliver` in tile order: a result that arrives before
/// those of earlier tiles waits for them (with threads taking tiles in order, about one per
/// thread waits). Stops taking tiles at the first error, which it returns.
pub fn in_tile_order<T: Send>(
    count: usize,
    work: impl Fn(usize) -> Result<T> + Sync,
    deliver: impl FnMut(T) -> Result<()> + Send,
) -> Result<()> {
    struct Ordered<T, D> {
        next: usize,
        early: std::collections::BTreeMap<usize, T>,
        deliver: D,
        error: Option<PrtError>,
    }
    let taken = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let state = std::sync::Mutex::new(Ordered {
        next: 0,
        early: std::collections::BTreeMap::new(),
        deliver,
        error: None,
    });
    let threads = rayon::current_num_threads().clamp(1, count.max(1));
    (0..threads).into_par_iter().for_each(|_| {
        while !failed.load(Ordering::Relaxed) {
            let t = taken.fetch_add(1, Ordering::Relaxed);
            if t >= count {
                break;
            }
            let result = work(t);
            let mut guard = state
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            let s = &mut *guard;
            let delivered = result.and_then(|v| {
                s.early.insert(t, v);
                while let Some(v) = s.early.remove(&s.next) {
                    (s.deliver)(v)?;
                    s.next += 1;
                }
                Ok(())
            });
            if let Err(e) = delivered {
                s.error.get_or_insert(e);
                failed.store(true, Ordering::Relaxed);
            }
        }
    });
    let s = state
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    match s.error {
        Some(e) => Err(e),
        None if s.next == count => Ok(()),
        None => Err(PrtError::invalid(
            "bake",
            format!("{} of {count} tiles were finished", s.next),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// Work that takes longer for some tiles, so results arrive out of order.
    fn uneven(t: usize) -> usize {
        std::thread::sleep(std::time::Duration::from_micros(
            ((t * 7919) % 13) as u64 * 200,
        ));
        t * t
    }

    #[test]
    fn results_are_delivered_in_tile_order_on_many_threads() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(5)
            .build()
            .unwrap();
        let mut got = Vec::new();
        pool.install(|| {
            in_tile_order(
                200,
                |t| Ok(uneven(t)),
                |v| {
                    got.push(v);
                    Ok(())
                },
            )
        })
        .unwrap();
        assert_eq!(got, (0..200).map(|t| t * t).collect::<Vec<_>>());
        // No tiles: nothing is delivered and nothing fails.
        in_tile_order(0, |_| Ok(()), |_: ()| panic!("delivered")).unwrap();
    }

    #[test]
    fn the_first_error_stops_the_tiles_and_is_returned() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let worked = AtomicUsize::new(0);
        let delivered = Mutex::new(Vec::new());
        let e = pool
            .install(|| {
                in_tile_order(
                    1000,
                    |t| {
                        worked.fetch_add(1, Ordering::Relaxed);
                        if t == 17 {
                            return Err(PrtError::invalid("tile", "seventeen"));
                        }
                        Ok(uneven(t))
                    },
                    |v| {
                        delivered.lock().unwrap().push(v);
                        Ok(())
                    },
                )
            })
            .unwrap_err();
        assert!(e.to_string().contains("seventeen"), "{e}");
        let delivered = delivered.into_inner().unwrap();
        // Only tiles before the failed one, in order; the rest were never taken.
        assert_eq!(
            delivered,
            (0..delivered.len()).map(|t| t * t).collect::<Vec<_>>()
        );
        assert!(delivered.len() <= 17);
        assert!(worked.load(Ordering::Relaxed) < 100);
        // An error in delivery stops the tiles as well.
        let e = in_tile_order(50, Ok, |t| match t {
            3 => Err(PrtError::invalid("disk", "full")),
            _ => Ok(()),
        })
        .unwrap_err();
        assert!(e.to_string().contains("full"), "{e}");
    }
}
