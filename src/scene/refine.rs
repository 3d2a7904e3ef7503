//! A per-vertex tessellation refined at shadow edges ([`VertexMesh::tessellate_refined`]): the
//! scene split uniformly at a coarser edge length, then, in rounds, the edges whose two ends see
//! the sky most differently split at their midpoints, until the mesh has as many vertices as the
//! uniform tessellation at the target length (its budget).
//!
//! What a vertex sees is its signature: which of the [`SIGNATURE_N`]-cube's texel centres above
//! its surface a shadow ray reaches, started as the bake starts them. Two ends differ by the
//! directions open from one and not the other, each weighed by its solid angle and the ends'
//! mean cosine; an edge's score is that times its length (per vertex its split adds), so long
//! edges count. An edge is split in every triangle that shares it, and a triangle with a split
//! edge also splits its longest (longest-edge bisection), so the mesh stays conforming and its
//! triangles do not thin out. Open shapes are refined before their twins are made, an edge
//! scored for the light of both sides. Scores tie by the edges' positions, and signatures are
//! traced in parallel but kept in vertex order: the same scene gives the same mesh, bit for bit.

use std::collections::{HashMap, HashSet};

use glam::Vec3;
use rayon::prelude::*;

use super::Scene;
use super::tessellate::{
    Piece, Refiner, VertexMesh, albedo_maps, assemble, bits, check_edge_length, pieces, subdivide,
};
use super::trace::Tracer;
use crate::error::Result;
use crate::math::cubemap::Directions;

/// Cube face size of a signature's directions: the centres of its 6 N² = 216 texels, about 108
/// of them above a surface.
const SIGNATURE_N: usize = 6;

/// 64-bit words of a signature: one bit a direction.
const WORDS: usize = (6 * SIGNATURE_N * SIGNATURE_N).div_ceil(64);

/// Coarse edge lengths tried first, as multiples of the target: the first whose tessellation
/// takes at most [`COARSE_SHARE`] of the budget, else the last.
const COARSE_FACTORS: [f32; 2] = [std::f32::consts::SQRT_2, 2.0];

/// Most of the budget the coarse tessellation may take.
const COARSE_SHARE: f64 = 0.6;

/// Shortest edge refinement splits, as a fraction of the target length.
const MIN_EDGE_FRACTION: f32 = 0.125;

/// Most rounds of refinement.
const ROUNDS: usize = 32;

/// A round spends at most 1/ROUND_SHARE of the vertices left in the budget, and at least
/// [`MIN_ROUND`] (or all of them where fewer are left).
const ROUND_SHARE: usize = 4;
/// The fewest vertices a round may spend, where the budget has them left.
const MIN_ROUND: usize = 64;

/// Which directions a vertex's side sees open, one bit each.
type Signature = [u64; WORDS];

/// An edge by its ends, lower index first.
type Edge = (u32, u32);

impl VertexMesh {
    /// [`VertexMesh::tessellate`]'s number of vertices at `edge_length` (or a few fewer), spent
    /// where shadows fall (see the module's notes): the edges where the light is even stay up to
    /// twice `edge_length` long, those across shadow borders are split down to an eighth of it.
    pub fn tessellate_refined(scene: &Scene, edge_length: f32) -> Result<VertexMesh> {
        check_edge_length(scene, edge_length)?;
        let maps = albedo_maps(scene);
        let textured: Vec<bool> = maps.iter().map(Option::is_some).collect();
        let uniform = pieces(scene, edge_length, &textured)?;
        let budget = count(&uniform);
        let mut coarse = Vec::new();
        for factor in COARSE_FACTORS {
            coarse = pieces(scene, edge_length * factor, &textured)?;
            if count(&coarse) as f64 <= COARSE_SHARE * budget as f64 {
                break;
            }
        }
        // Only flat pieces start coarse: their light varies only where shadows fall, which the
        // refinement finds. A curved piece's shading varies everywhere, so it keeps the uniform
        // tessellation.
        for (c, u) in coarse.iter_mut().zip(uniform) {
            if !is_flat(&u) {
                *c = u;
            }
        }
        if !coarse.is_empty() && count(&coarse) < budget {
            let tracer = Tracer::new(scene);
            refine(
                &mut coarse,
                &tracer,
                budget,
                edge_length * MIN_EDGE_FRACTION,
            );
        }
        assemble(coarse, maps)
    }
}

/// Whether every vertex of `piece` has the same shading normal.
fn is_flat(piece: &Piece) -> bool {
    let normals = &piece.mesh.normals;
    piece.sphere.is_none()
        && normals
            .first()
            .is_none_or(|n0| normals.iter().all(|n| n.dot(*n0) > 1.0 - 1e-5))
}

/// Vertices the pieces take in the whole mesh, twins included.
fn count(pieces: &[Piece]) -> usize {
    pieces.iter().map(Piece::vertices).sum()
}

/// Splits edges of `pieces` where their ends' signatures differ most, in rounds, until they take
/// `budget` vertices (or a few fewer), or no edge longer than `min_edge` differs.
fn refine(pieces: &mut [Piece], tracer: &Tracer, budget: usize, min_edge: f32) {
    let sky = Sky::diffuse(SIGNATURE_N);
    let mut seen: Vec<Seen> = pieces.iter().map(|_| Seen::default()).collect();
    for _ in 0..ROUNDS {
        let left = budget.saturating_sub(count(pieces));
        if left == 0 {
            break;
        }
        look(pieces, &mut seen, &sky, tracer);
        let candidates = candidates(pieces, &seen, &sky, min_edge);
        let allowance = (left / ROUND_SHARE).max(left.min(MIN_ROUND));
        let mut adjacent: Vec<Option<HashMap<Edge, Vec<u32>>>> = vec![None; pieces.len()];
        let mut marked: Vec<HashSet<Edge>> = vec![HashSet::new(); pieces.len()];
        let mut spent = 0;
        for c in &candidates {
            let (piece, marked) = (&pieces[c.piece], &mut marked[c.piece]);
            if marked.contains(&c.edge) {
                continue;
            }
            let adjacent = adjacent[c.piece].get_or_insert_with(|| adjacency(&piece.mesh));
            let fresh = closure(&piece.mesh, adjacent, marked, c.edge);
            let cost = fresh.len() * (1 + piece.open as usize);
            if spent + cost > allowance {
                continue;
            }
            spent += cost;
            marked.extend(fresh);
            if spent == allowance {
                break;
            }
        }
        if spent == 0 {
            break;
        }
        for (piece, marked) in pieces.iter_mut().zip(&marked) {
            if !marked.is_empty() {
                split_marked(piece, marked);
            }
        }
    }
}

/// The directions of a signature and their weights: solid angle over π, so that the cosines of
/// an open hemisphere weigh about 1.
type Sky = Directions;

impl Sky {
    /// The directions above the surface at `p` with normal `n` that a shadow ray from just off
    /// it reaches (the bake's origin: `p` moved along `n` by the tracer's offset).
    fn signature(&self, tracer: &Tracer, p: Vec3, n: Vec3) -> Signature {
        let mut rays = tracer.rays_from(p + n * tracer.spawn_offset());
        let mut open = [0u64; WORDS];
        for (j, &d) in self.dirs.iter().enumerate() {
            if n.dot(d) > 0.0 && !rays.occluded(d, f32::INFINITY) {
                open[j / 64] |= 1 << (j % 64);
            }
        }
        open
    }

    /// How differently two sides, `(signature, normal)`, see: the weights of the directions open
    /// from one only, each times the two sides' mean cosine.
    fn distance(&self, (a, na): (&Signature, Vec3), (b, nb): (&Signature, Vec3)) -> f32 {
        let mut sum = 0.0;
        for (w, (x, y)) in a.iter().zip(b).enumerate() {
            let mut differ = x ^ y;
            while differ != 0 {
                let j = w * 64 + differ.trailing_zeros() as usize;
                differ &= differ - 1;
                let d = self.dirs[j];
                let cos = 0.5 * (na.dot(d).max(0.0) + nb.dot(d).max(0.0));
                sum += cos * self.weights[j];
            }
        }
        sum
    }
}

/// The signatures of a piece's vertices: of the side their normals face, and for an open piece
/// of the other side.
#[derive(Default)]
struct Seen {
    front: Vec<Signature>,
    back: Vec<Signature>,
}

/// Traces the signatures of the vertices that have none yet, in parallel, kept in vertex order.
fn look(pieces: &[Piece], seen: &mut [Seen], sky: &Sky, tracer: &Tracer) {
    let jobs: Vec<(usize, usize)> = pieces
        .iter()
        .zip(seen.iter())
        .enumerate()
        .flat_map(|(i, (p, s))| (s.front.len()..p.mesh.vertex_count()).map(move |v| (i, v)))
        .collect();
    let found: Vec<(Signature, Option<Signature>)> = jobs
        .par_iter()
        .map(|&(i, v)| {
            let p = &pieces[i];
            let (at, n) = (p.mesh.positions[v], p.mesh.normals[v]);
            let back = p.open.then(|| sky.signature(tracer, at, -n));
            (sky.signature(tracer, at, n), back)
        })
        .collect();
    for (&(i, _), (front, back)) in jobs.iter().zip(found) {
        seen[i].front.push(front);
        seen[i].back.extend(back);
    }
}

/// An edge worth splitting: its score, where it is (which orders equal scores), its piece and
/// its ends.
struct Candidate {
    score: f32,
    place: ([u32; 3], [u32; 3]),
    piece: usize,
    edge: Edge,
}

/// Every edge longer than `min_edge` whose ends see differently, best first: its ends' distance
/// (both sides' for an open piece) times its length, per vertex its split adds.
fn candidates(pieces: &[Piece], seen: &[Seen], sky: &Sky, min_edge: f32) -> Vec<Candidate> {
    let edges: Vec<(usize, Edge)> = pieces
        .iter()
        .enumerate()
        .flat_map(|(i, p)| edges_of(&p.mesh).into_iter().map(move |e| (i, e)))
        .collect();
    let mut found: Vec<Candidate> = edges
        .par_iter()
        .filter_map(|&(i, (a, b))| {
            let (p, s) = (&pieces[i], &seen[i]);
            let m = &p.mesh;
            let (ia, ib) = (a as usize, b as usize);
            let length = m.positions[ia].distance(m.positions[ib]);
            if length <= min_edge {
                return None;
            }
            let (na, nb) = (m.normals[ia], m.normals[ib]);
            let mut differ = sky.distance((&s.front[ia], na), (&s.front[ib], nb));
            if p.open {
                differ += sky.distance((&s.back[ia], -na), (&s.back[ib], -nb));
            }
            let score = differ * length / (1 + p.open as usize) as f32;
            (score > 0.0).then(|| Candidate {
                score,
                place: place(m, (a, b)),
                piece: i,
                edge: (a, b),
            })
        })
        .collect();
    found.sort_by(|x, y| {
        y.score
            .total_cmp(&x.score)
            .then_with(|| x.place.cmp(&y.place))
            .then_with(|| (x.piece, x.edge).cmp(&(y.piece, y.edge)))
    });
    found
}

/// Edge (a, b) with its lower index first.
fn edge(a: u32, b: u32) -> Edge {
    (a.min(b), a.max(b))
}

/// The edges of `mesh`'s triangles, each once, in the order the triangles meet them.
fn edges_of(mesh: &VertexMesh) -> Vec<Edge> {
    let mut met = HashSet::new();
    mesh.triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| edge(t[k], t[(k + 1) % 3])))
        .filter(|&e| met.insert(e))
        .collect()
}

/// The triangles each edge of `mesh` belongs to.
fn adjacency(mesh: &VertexMesh) -> HashMap<Edge, Vec<u32>> {
    let mut map: HashMap<Edge, Vec<u32>> = HashMap::new();
    for (i, t) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            map.entry(edge(t[k], t[(k + 1) % 3]))
                .or_default()
                .push(i as u32);
        }
    }
    map
}

/// Where an edge is: its ends' position bits, lower first, whatever its vertices' order.
fn place(mesh: &VertexMesh, (a, b): Edge) -> ([u32; 3], [u32; 3]) {
    let (pa, pb) = (
        bits(mesh.positions[a as usize]),
        bits(mesh.positions[b as usize]),
    );
    (pa.min(pb), pa.max(pb))
}

/// The index k of the longest edge of `t` (from corner k to k + 1), ties by place.
fn longest(mesh: &VertexMesh, t: [u32; 3]) -> usize {
    let rank = |k: usize| {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let length = mesh.positions[a as usize].distance(mesh.positions[b as usize]);
        (length, place(mesh, (a, b)))
    };
    (0..3)
        .max_by(|&i, &j| {
            let ((li, pi), (lj, pj)) = (rank(i), rank(j));
            li.total_cmp(&lj).then(pi.cmp(&pj))
        })
        .unwrap_or(0)
}

/// The edges to split for `e` that are not `marked` yet: `e`, and the longest edge of every
/// triangle any of them belongs to, so that every triangle with a split edge splits its longest.
fn closure(
    mesh: &VertexMesh,
    adjacent: &HashMap<Edge, Vec<u32>>,
    marked: &HashSet<Edge>,
    e: Edge,
) -> Vec<Edge> {
    let mut fresh = vec![e];
    let mut at = 0;
    while let Some(&e) = fresh.get(at) {
        at += 1;
        for &t in adjacent.get(&e).into_iter().flatten() {
            let t = mesh.triangles[t as usize];
            let k = longest(mesh, t);
            let l = edge(t[k], t[(k + 1) % 3]);
            if !marked.contains(&l) && !fresh.contains(&l) {
                fresh.push(l);
            }
        }
    }
    fresh
}

/// Splits the `marked` edges of `piece` at their midpoints in every triangle that shares them,
/// each triangle first across its longest edge.
fn split_marked(piece: &mut Piece, marked: &HashSet<Edge>) {
    let tris = std::mem::take(&mut piece.mesh.triangles);
    let first: Vec<usize> = tris.iter().map(|&t| longest(&piece.mesh, t)).collect();
    let mut next = Vec::with_capacity(tris.len() + 3 * marked.len());
    {
        let mut refiner = Refiner::new(&mut piece.mesh, f32::INFINITY, piece.sphere, 0);
        for (t, first) in tris.into_iter().zip(first) {
            let mids = [0, 1, 2].map(|k| {
                let (a, b) = edge(t[k], t[(k + 1) % 3]);
                marked.contains(&(a, b)).then(|| refiner.midpoint(a, b))
            });
            subdivide(t, mids, Some(first), &mut next);
        }
    }
    piece.mesh.triangles = next;
}
