//! The paths of a bake's camera sub-samples as the surface cache's walk found them, kept so that
//! the tiles replay them rather than walk them again (see [`KeptWalks`]).

use std::collections::HashMap;

use glam::Vec3;

use super::Vertex;

/// The most the kept paths may take; a bake whose paths take more walks them again in its tiles.
/// The 128² demo with one bounce keeps 0.4 M vertices in about 30 MB.
pub const KEPT_BYTES: usize = 512 << 20;

/// A vertex of a walk, with what the walk gave its visitor there: the path and bounce it was
/// reached at, and the throughput that reached it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Visit {
    pub(super) step: [u32; 2],
    pub(super) vertex: Vertex,
    pub(super) throughput: Vec3,
}

/// Which of a camera sub-sample's two walks: the paths from its surface hit
/// ([`super::Bounces::walk`]) or from collisions along its ray ([`super::Bounces::walk_camera`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Start {
    Surface,
    Camera,
}

/// One walk: where its vertices lie, and the rays it traced.
#[derive(Clone, Copy, Debug)]
struct Walk {
    first: usize,
    count: usize,
    rays: u64,
}

/// The walks of a bake's camera sub-samples, each under its random stream: every vertex in the
/// order the walk visited it. A walk's vertices depend only on its stream and its start, so a
/// replay visits exactly what walking again would, and the bake's rows come out the same to the
/// bit.
#[derive(Debug, Default)]
pub struct KeptWalks {
    visits: Vec<Visit>,
    walks: HashMap<(u64, Start), Walk>,
}

impl KeptWalks {
    /// Keeps the walk from `start` of stream `stream`, which traced `rays` rays and visited
    /// `visits` (taken, leaving it empty).
    pub(super) fn keep(
        &mut self,
        (stream, start): (u64, Start),
        rays: u64,
        visits: &mut Vec<Visit>,
    ) {
        let walk = Walk {
            first: self.visits.len(),
            count: visits.len(),
            rays,
        };
        self.visits.append(visits);
        self.walks.insert((stream, start), walk);
    }

    /// Both parts' walks; each walk's vertices move with it.
    pub(super) fn merge(mut self, mut other: KeptWalks) -> KeptWalks {
        if self.visits.len() < other.visits.len() {
            std::mem::swap(&mut self, &mut other);
        }
        let shift = self.visits.len();
        self.visits.append(&mut other.visits);
        self.walks.extend(other.walks.into_iter().map(|(key, w)| {
            let first = w.first + shift;
            (key, Walk { first, ..w })
        }));
        self
    }

    /// Gives back the room the vectors grew beyond what they hold.
    pub(super) fn shrink(mut self) -> KeptWalks {
        self.visits.shrink_to_fit();
        self.walks.shrink_to_fit();
        self
    }

    /// Bytes the vertices take.
    pub fn bytes(&self) -> usize {
        self.visits.len() * std::mem::size_of::<Visit>()
    }

    /// Bytes a walk of `visits` vertices adds.
    pub(super) fn bytes_of(visits: usize) -> usize {
        visits * std::mem::size_of::<Visit>() + std::mem::size_of::<((u64, Start), Walk)>()
    }

    /// Calls `visit` at every vertex of the kept walk from `start` of stream `stream`, in the
    /// order it was walked, and returns the rays it traced; `None` if that walk is not kept.
    pub(super) fn replay(
        &self,
        key: (u64, Start),
        visit: &mut dyn FnMut(u32, u32, &Vertex, Vec3),
    ) -> Option<u64> {
        let w = self.walks.get(&key)?;
        for v in self.visits.get(w.first..w.first + w.count)? {
            let [path, bounce] = v.step;
            visit(path, bounce, &v.vertex, v.throughput);
        }
        Some(w.rays)
    }
}
