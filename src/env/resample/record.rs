//! Recording a splat: cutting each lat-long cell of one row into the pieces that go to each
//! texel (carrying edge angles down the cuts), and the symmetries of the split that spare
//! recording most rows and columns. [`super::LatLongWeights`] is made from these records.

use super::*;

/// A cell edge: its lat-long coordinate (u or v) and the cosine and sine of its angle (2πu or πv).
#[derive(Clone, Copy, Debug)]
pub(super) struct Edge {
    pub(super) t: f64,
    pub(super) cos: f64,
    pub(super) sin: f64,
}

impl Edge {
    /// The edge at coordinate `t`, angle `scale · t`, computed as the exact splat computes it.
    #[inline]
    pub(super) fn at(t: f64, scale: f64) -> Self {
        let (sin, cos) = (scale * t).sin_cos();
        Edge { t, cos, sin }
    }

    /// The edge halfway between `a` and `b`: the normalised sum of their unit vectors is the
    /// half-angle direction, which saves the trigonometry of every cut (to an ulp or two of
    /// `sin_cos`).
    #[inline]
    pub(super) fn mid(a: Edge, b: Edge, scale: f64) -> Self {
        let t = 0.5 * (a.t + b.t);
        if (b.t - a.t) * scale > MIDPOINT_DIRECT_ANGLE {
            return Edge::at(t, scale);
        }
        let (c, s) = (a.cos + b.cos, a.sin + b.sin);
        let r = 1.0 / (c * c + s * s).sqrt();
        Edge {
            t,
            cos: c * r,
            sin: s * r,
        }
    }
}

/// A last piece of a cell: its texel, its span across the cell's width (0..1) and solid angle.
#[derive(Clone, Copy, Debug)]
pub(super) struct Piece {
    pub(super) texel: u32,
    pub(super) tau: (f64, f64),
    pub(super) omega: f64,
}

/// The cutting of [`crate::math::cubemap::resample_latlong_exact`]'s splatter, with edge angles carried
/// down the recursion instead of recomputed, writing pieces instead of power.
pub(super) struct Recorder {
    pub(super) n: usize,
    pub(super) world_from_map: DMat3,
    pub(super) finest: f64,
    pub(super) texel_min: f64,
}

impl Recorder {
    #[inline]
    pub(super) fn texel_of(&self, u: Edge, v: Edge) -> u32 {
        let d = DVec3::new(u.sin * v.sin, v.cos, -u.cos * v.sin);
        dir_to_texel(self.n, self.world_from_map * d) as u32
    }

    /// Texel of the centre of [u0, u1] x [v0, v1], which takes the whole piece. A centre within
    /// rounding of a texel border (a cell centred on a face edge when W is not a multiple of 8,
    /// say) goes to whichever side rounding picks, so there the direction is recomputed from
    /// sin/cos exactly as the exact splat computes it, to pick the same side.
    pub(super) fn texel_of_centre(&self, u0: Edge, u1: Edge, v0: Edge, v1: Edge) -> u32 {
        let (u, v) = (Edge::mid(u0, u1, TAU), Edge::mid(v0, v1, PI));
        let d = self.world_from_map * DVec3::new(u.sin * v.sin, v.cos, -u.cos * v.sin);
        let a = d.abs();
        let major = a.max_element();
        let (face, s, t) = dir_to_face_st(d);
        let cell = |x: f64| (x + 1.0) * 0.5 * self.n as f64;
        let off_grid = |x: f64| (cell(x) - cell(x).round()).abs() > TIE_TOL;
        // Exactly one axis is the major one, clearly.
        let faces_apart = [a.x, a.y, a.z]
            .iter()
            .filter(|&&c| major - c <= TIE_TOL * major)
            .count()
            == 1;
        if faces_apart && off_grid(s) && off_grid(t) {
            let to_cell = |x: f64| (cell(x) as usize).min(self.n - 1);
            return texel_index(self.n, face, to_cell(t), to_cell(s)) as u32;
        }
        self.texel_of(Edge::at(u.t, TAU), Edge::at(v.t, PI))
    }

    /// Adds the last pieces of cell part [u0, u1] x [v0, v1] to `pieces`. `tau` is the part's span
    /// across its cell's width; `corners` are the texels of (u0, v0), (u1, v0), (u0, v1),
    /// (u1, v1). The same cuts as the exact splat's (`Splatter::splat` in [`crate::math::cubemap`],
    /// its slow twin by design), recording the pieces instead of adding their power.
    pub(super) fn splat(
        &self,
        (u0, u1, v0, v1): (Edge, Edge, Edge, Edge),
        (tau0, tau1): (f64, f64),
        corners: [u32; 4],
        pieces: &mut Vec<Piece>,
    ) {
        let height = PI * (v1.t - v0.t);
        let width = 2.0 * PI * (u1.t - u0.t) * widest_sin(v0.t, v1.t, v0.sin, v1.sin);
        let size = height.max(width);
        let same = corners.iter().all(|&c| c == corners[0]);
        if (same && size < self.texel_min) || size < self.finest {
            let texel = if same {
                corners[0]
            } else {
                self.texel_of_centre(u0, u1, v0, v1)
            };
            pieces.push(Piece {
                texel,
                tau: (tau0, tau1),
                omega: 2.0 * PI * (u1.t - u0.t) * (v0.cos - v1.cos),
            });
            return;
        }
        let (um, vm) = (Edge::mid(u0, u1, TAU), Edge::mid(v0, v1, PI));
        let taum = 0.5 * (tau0 + tau1);
        let [c00, c10, c01, c11] = corners;
        let (l, r) = ((tau0, taum), (taum, tau1));
        match Cut::of(width, height) {
            Cut::Across => {
                let (top, bottom) = (self.texel_of(um, v0), self.texel_of(um, v1));
                self.splat((u0, um, v0, v1), l, [c00, top, c01, bottom], pieces);
                self.splat((um, u1, v0, v1), r, [top, c10, bottom, c11], pieces);
            }
            Cut::Along => {
                let (left, right) = (self.texel_of(u0, vm), self.texel_of(u1, vm));
                let whole = (tau0, tau1);
                self.splat((u0, u1, v0, vm), whole, [c00, c10, left, right], pieces);
                self.splat((u0, u1, vm, v1), whole, [left, right, c01, c11], pieces);
            }
            Cut::Both => {
                let top = self.texel_of(um, v0);
                let left = self.texel_of(u0, vm);
                let mid = self.texel_of(um, vm);
                let right = self.texel_of(u1, vm);
                let bottom = self.texel_of(um, v1);
                self.splat((u0, um, v0, vm), l, [c00, top, left, mid], pieces);
                self.splat((um, u1, v0, vm), r, [top, c10, mid, right], pieces);
                self.splat((u0, um, vm, v1), l, [left, mid, c01, bottom], pieces);
                self.splat((um, u1, vm, v1), r, [mid, right, bottom, c11], pieces);
            }
        }
    }
}

/// What the build records for one row: share words and solid angles, the tables of the uneven
/// shares (Q − 1 fractions each, in share order), and where each cell's shares start.
#[derive(Default)]
pub(super) struct RowRecord {
    pub(super) word: Vec<u32>,
    pub(super) weight: Vec<f32>,
    pub(super) tails: Vec<u16>,
    /// Shares before each cell, and after the last.
    pub(super) cell_start: Vec<usize>,
    /// Uneven shares before each cell, and after the last.
    pub(super) cell_uneven: Vec<usize>,
}

impl RowRecord {
    /// Merges a cell's pieces into one share per texel and records them.
    pub(super) fn add_cell(&mut self, pieces: &mut [Piece], q: usize) {
        self.cell_start.push(self.word.len());
        self.cell_uneven.push(self.tails.len() / (q - 1).max(1));
        if pieces.iter().all(|p| p.texel == pieces[0].texel) {
            // The whole cell in one texel: even by construction.
            let omega: f64 = pieces.iter().map(|p| p.omega).sum();
            self.word.push(pieces[0].texel | LAST);
            self.weight.push(omega as f32);
            return;
        }
        pieces.sort_unstable_by_key(|p| p.texel);
        let groups = pieces.chunk_by(|a, b| a.texel == b.texel);
        let count = groups.clone().count();
        for (g, group) in groups.enumerate() {
            // Solid angle per sub-column, each piece spread evenly over the width it spans.
            // Spans and sub-column edges are dyadic, so the reciprocals are exact.
            let mut per_column = [0.0f64; MAX_SUBCOLUMNS];
            let (qf, inv_q) = (q as f64, 1.0 / q as f64);
            for p in group {
                let (t0, t1) = p.tau;
                let density = p.omega / (t1 - t0);
                let first = (t0 * qf).floor() as usize;
                let last = ((t1 * qf).ceil() as usize).clamp(first + 1, q);
                for (k, c) in per_column.iter_mut().enumerate().take(last).skip(first) {
                    let overlap = t1.min((k + 1) as f64 * inv_q) - t0.max(k as f64 * inv_q);
                    *c += density * overlap.max(0.0);
                }
            }
            let cols = &per_column[..q];
            let total: f64 = cols.iter().sum();
            let last = if g + 1 == count { LAST } else { 0 };
            let even = cols
                .iter()
                .all(|c| (c / total - 1.0 / qf).abs() <= EVEN_TOL);
            self.weight.push(total as f32);
            if even {
                self.word.push(group[0].texel | last);
                continue;
            }
            self.word.push(group[0].texel | last | UNEVEN);
            let mut tail = 0.0;
            for c in cols[1..].iter().rev() {
                tail += c;
                self.tails.push((tail / total * TAIL_SCALE).round() as u16);
            }
        }
    }
}

/// Symmetries of the split, so only part of the cells are cut and the rest are copies with their
/// texels renumbered. The mirror x → −x (u → 1 − u) commutes with R_x(pitch), so it holds at every
/// pitch; at pitch 0 the quarter turn about +Y (u → u + 1/4, when W is a multiple of 4) and the
/// mirror y → −y (v → 1 − v) hold too. The cube's texel grid has all three. A copy equals cutting
/// the cell itself except where a cut point lies exactly on a texel border and rounding breaks the
/// tie one way or the other; either way the pieces then tile the same region, so the shares agree
/// to rounding (the tests hold the result to the exact splat).
pub(super) struct Symmetry {
    /// Rows that are cut: 0..rows; row y beyond is row H − 1 − y mirrored.
    pub(super) rows: usize,
    /// Columns of one period that are cut: 0..cols; column r beyond is period − 1 − r mirrored.
    pub(super) cols: usize,
    /// Columns per quarter turn (W / 4), or W without quarter turns.
    pub(super) period: usize,
    /// Texel renumbering of each copy, at `a·8 + k·2 + b` for a v-mirror (a), k quarter turns and
    /// a u-mirror (b); empty where that copy does not occur.
    pub(super) renumber: Vec<Vec<u32>>,
}

impl Symmetry {
    pub(super) fn new(width: usize, height: usize, n: usize, pitch_deg: f64) -> Self {
        // With W a multiple of 8 the lines where cube faces meet at pitch 0 (u = k/8) and the
        // plane x = 0 at any pitch (u = 0, 1/2) run along cell edges, never through a point the
        // cuts take a texel at, so no tie decides a copy. Otherwise every cell is cut.
        if !width.is_multiple_of(8) {
            return Symmetry {
                rows: height,
                cols: width,
                period: width,
                renumber: vec![(0..texel_count(n) as u32).collect()],
            };
        }
        let upright = pitch_deg == 0.0;
        let quarter = upright;
        let period = if quarter { width / 4 } else { width };
        // World direction maps: d(u + 1/4) = turn · d(u); d(1 − u) and d(1 − v) are mirrors.
        let turn = DMat3::from_cols(DVec3::Z, DVec3::Y, -DVec3::X);
        let mirror_u = DMat3::from_diagonal(DVec3::new(-1.0, 1.0, 1.0));
        let mirror_v = DMat3::from_diagonal(DVec3::new(1.0, -1.0, 1.0));
        // Within a period, column r is column period − 1 − r mirrored: by u → 1 − u and, with
        // quarter turns, a turn back into the first quarter.
        let within = if quarter { turn * mirror_u } else { mirror_u };
        let dirs = texel_dirs(n);
        let renumber = (0..16)
            .map(|i| {
                let (a, k, b) = (i / 8, (i / 2) % 4, i % 2);
                if (a == 1 && !upright) || (k > 0 && !quarter) {
                    return Vec::new();
                }
                let mut m = DMat3::IDENTITY;
                if a == 1 {
                    m = mirror_v;
                }
                for _ in 0..k {
                    m *= turn;
                }
                if b == 1 {
                    m *= within;
                }
                // Texel centres map to texel centres, half a texel from any border.
                dirs.iter()
                    .map(|&d| dir_to_texel(n, m * d) as u32)
                    .collect()
            })
            .collect();
        Symmetry {
            rows: if upright { height.div_ceil(2) } else { height },
            cols: period.div_ceil(2),
            period,
            renumber,
        }
    }

    /// The cut cell that cell (x, y) copies: its column and row, the renumbering, and whether the
    /// copy is mirrored in u (so its tables run backwards).
    pub(super) fn source(&self, x: usize, y: usize, height: usize) -> (usize, usize, &[u32], bool) {
        let (ys, a) = if y < self.rows {
            (y, 0)
        } else {
            (height - 1 - y, 1)
        };
        let (k, r) = (x / self.period, x % self.period);
        let (xs, b) = if r < self.cols {
            (r, 0)
        } else {
            (self.period - 1 - r, 1)
        };
        (xs, ys, &self.renumber[a * 8 + k * 2 + b], b == 1)
    }
}
