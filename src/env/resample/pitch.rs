//! Pitch without weights of its own. Recording the splat under a pitch takes 80 ms at N = 32 for a
//! 1024 x 512 map and 264 ms at N = 64, and every pitch of a drag is new, so a pitch drag cost 30
//! and 56 times a yaw drag. Where the map's cells are no larger than the
//! smallest texels, a pitched light is instead splatted at the centres of sub-cells:
//! - each cell of the world grid (world = R_x(pitch) · R_y(yaw) · map, see
//!   [`crate::conventions`]) is cut into q x q sub-cells no wider than half the smallest texel;
//! - each takes the turned map's mean over it, as the yaw's shift gives it (exact: the map is
//!   constant over a cell, see the module notes of [`super`]);
//! - and gives its power whole to the texel its centre lands in under the pitch.
//!
//! As in the exact splat, a texel's radiance is the power it received over the solid angle it
//! received, and one factor per channel restores the map's power, so a constant map stays
//! constant and no power is lost.
//!
//! Where the exact splat cuts cells along texel borders down to a band of texel_min / 16, this
//! moves whole sub-cells, a band of up to texel_min / 2: the two differ where a border crosses a
//! feature no larger than a few cells, such as a small sun, by the share of it in the band.
//! Measured against the exact splat over the cube, on a 1024 x 512 map (the `light::resample`
//! test `a_pitch_splatted_at_cell_centres_stays_near_the_exact_splat`): at most 3.6% at N = 8 to
//! 32 and 5.3% at N = 64 with a 2 x 2-pixel sun, where the recorded weights of a fractional yaw
//! differ by 1.5% and 4.7%; 4.3e-4 on a smooth map. On blender_sunrise, whose sun is a few cells
//! across, it is worse where the sun straddles a border (`cargo bench --bench light` prints it:
//! at pitch −20°, over 24 yaws, a median of 1.0% and a worst of 26% at N = 32, where the recorded
//! weights of the same yaws unpitched give 0.47% and 2.1%). A map whose cells are larger than
//! the smallest texels (a small map, or N above 64 for a 1024 x 512 one) records weights for the
//! pitch as before, as does any splat that leaves a texel without a cell.
//!
//! The work is one texel lookup per sub-cell, made cheap four ways:
//! - the lookup runs in f32 without branches, four sub-cells an SSE2 instruction
//!   ([`texels_of`]);
//! - R_x(pitch) keeps x, so the second half of every row is the mirror of the first: its texels
//!   are looked up in a table and its runs are the first half's, mirrored ([`mirrors`],
//!   [`row_runs`]);
//! - R_x(pitch) commutes with R_x(π), which takes (u, v) to (π − u, π − v), so a southern row's
//!   texels are its northern twin's, reversed and looked up in another table ([`half_turns`],
//!   [`turn_half`]): a quarter of the sub-cells are looked up;
//! - a row's sub-cells run through a texel several in turn, and each run scatters its power
//!   once, its sum the difference of the row's running sums at its two ends, whatever its
//!   length ([`runs`], [`RowSums`]).
//!
//! On the 2-core machine (`cargo bench --bench light`, blender_sunrise, one run, the README's
//! table), with the map's unturned SH light kept from one step of a drag to the next as the
//! viewer keeps it: a pitch drag prepares a light in 1.48 ms at N = 32 and 4.70 ms at N = 64,
//! against 1.70 and 2.93 ms for a yaw drag, and 74.6 and 275 ms through weights recorded for
//! each pitch.
//!
//! Pitch 0 keeps the recorded weights, exact to the band of the recorded splat: a light that
//! leaves pitch 0 steps by the difference above (on a small sun crossing a texel border, a few
//! percent of that texel).

use std::f64::consts::{PI, TAU};
use std::sync::{Arc, Mutex};

use glam::DVec3;
use rayon::prelude::*;

use super::{EnvRotation, yaw_shift};
use crate::error::Result;
use crate::math::cubemap::{
    CubeMap, LatLong, dir_to_texel, solid_angles, splat_limits, splat_radiance, texel_count,
    texel_dirs, texel_index,
};

/// Whether a `width` x `height` map's cells are small enough, against a cube of face `n`, to be
/// splatted at their centres: none larger than the smallest texel.
pub(super) fn splats_at_centres(width: usize, height: usize, n: usize) -> bool {
    let (texel_min, _) = splat_limits(n, width, height);
    cell(width, height) <= texel_min
}

/// A cell's largest side (radians): its height, or its width at the equator.
fn cell(width: usize, height: usize) -> f64 {
    (PI / height as f64).max(TAU / width as f64)
}

/// Row bands per thread.
const BANDS_PER_THREAD: usize = 2;
/// Most sub-cells along each side of a cell.
const MAX_SPLIT: usize = 4;

/// Sub-cells along each side of a cell, so that none is wider than half the smallest texel: the
/// band along texel borders where power may go to the wrong side. (A quarter halves the band but
/// not the error against the exact splat, which has a band of its own, at four times the work:
/// measured 3.0% against 3.6% at N = 32 on a map with a small sun.)
fn split(width: usize, height: usize, n: usize) -> usize {
    let (texel_min, _) = splat_limits(n, width, height);
    ((cell(width, height) / (texel_min / 2.0)).ceil() as usize).clamp(1, MAX_SPLIT)
}

/// The share of each of a cell's `q` sub-columns that lies in the cell's last fraction `f`, where
/// a yaw of a fraction f of a cell puts the next map cell (see the module notes of [`super`]).
fn tail_shares(q: usize, f: f64) -> Vec<f64> {
    (0..q)
        .map(|i| {
            let (a, b) = (i as f64 / q as f64, (i + 1) as f64 / q as f64);
            (b - (1.0 - f)).clamp(0.0, b - a) * q as f64
        })
        .collect()
}

/// The texels of the directions (sin u·sin v, y0 + y1·cos u, z0 − z1·cos u), u given by
/// `sin_u`, `cos_u`, into `texels`: [`crate::math::cubemap::dir_to_texel`] in f32 and without
/// branches, so that it runs several directions an instruction. (A direction within f32 rounding
/// of a texel border may fall on the other side of it than in f64.)
fn texels_of(
    n: usize,
    sin_u: &[f32],
    cos_u: &[f32],
    sin_v: f32,
    (y0, y1): (f32, f32),
    (z0, z1): (f32, f32),
    texels: &mut [u32],
) {
    let half_n = 0.5 * n as f32;
    let last = (n - 1) as f32;
    let size = n as f32;
    // 1.5 · 2^23: sums with anything within 2^22 of 0 lie in [2^23, 2^24), spaced by 1.
    const ROUND: f32 = (3u32 << 22) as f32;
    for ((t, &su), &cu) in texels.iter_mut().zip(sin_u).zip(cos_u) {
        let (x, y, z) = (su * sin_v, y0 + y1 * cu, z0 - z1 * cu);
        let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
        // Ties go to the first face in order, as in `dir_to_face_st`; every choice is a select.
        let on_x = (ax >= ay) & (ax >= az);
        let on_y = !on_x & (ay >= az);
        let sign = |v: f32| if v < 0.0 { -1.0f32 } else { 1.0 };
        let pick = |a: f32, b: f32, c: f32| {
            if on_x {
                a
            } else if on_y {
                b
            } else {
                c
            }
        };
        let major = pick(ax, ay, az);
        // Faces ±x: s = ∓z, t = −y; ±y: s = x, t = ±z; ±z: s = ±x, t = −y.
        let s = pick(-z * sign(x), x, x * sign(z));
        let t_ = pick(-y, z * sign(y), -y);
        let negative = pick(x, y, z) < 0.0;
        let face = pick(0.0, 2.0, 4.0) + if negative { 1.0 } else { 0.0 };
        let inverse = half_n / major;
        // Whole numbers in f32 (exact below 2^22) without a conversion (Rust's saturating `as`
        // stops the loop running four directions an instruction): adding 1.5 · 2^23 rounds to
        // a whole number, which then fills the mantissa's low bits. Half a cell down makes the
        // rounding a floor, but for a point exactly on a border.
        let whole = |v: f32| (v + ROUND) - ROUND;
        // A select, not `f32::min`, whose NaN rule costs a compare and a blend (no value here
        // is NaN).
        let cell = |v: f32| {
            let c = whole((v * inverse + half_n).clamp(0.0, size) - 0.5);
            if c > last { last } else { c }
        };
        let index = (face * size + cell(t_)) * size + cell(s);
        *t = (index + ROUND).to_bits() - ROUND.to_bits();
    }
}

/// Calls `give(texel, start, end, mirrored)` for the runs of a whole sub-row of `columns`
/// sub-columns, from `texels`, those of its first half: each run of the first half in turn, and
/// after it its mirror in the second half (`mirrored`), so that each run of either half starts
/// where the last of that half ended, and the mirrors end where the last one started.
/// R_x(pitch) keeps x, so sub-column columns − 1 − k, at u' = 2π − u, lands where sub-column k
/// does with x negated: in the mirror of its texel (an odd row's middle sub-column, at u = π, is
/// its own).
fn row_runs(
    texels: &[u32],
    columns: usize,
    mirror: &[u32],
    mut give: impl FnMut(usize, usize, usize, bool),
) {
    let mirrored = columns - texels.len();
    runs(texels, |start, end, texel| {
        give(texel as usize, start, end, false);
        let end = end.min(mirrored);
        if start < end {
            give(
                mirror[texel as usize] as usize,
                columns - end,
                columns - start,
                true,
            );
        }
    });
}

/// The texel of (−x, y, z) for each texel of (x, y, z): faces ±x trade places, and s turns
/// into −s on every face (see `dir_to_face_st`), so the column counts from the other side.
fn mirrors(n: usize) -> Vec<u32> {
    (0..texel_count(n))
        .map(|texel| {
            let (face, row, col) = (texel / (n * n), texel / n % n, texel % n);
            let face = [1, 0, 2, 3, 4, 5][face];
            texel_index(n, face, row, n - 1 - col) as u32
        })
        .collect()
}

/// Calls `give(start, end, texel)` for each run of equal `texels`: the sub-cells of a sub-row run
/// through a texel several in turn (about eight at N = 32 for a 1024-pixel row), and each run
/// scatters its power once. Eight equal texels are skipped at a time.
fn runs(texels: &[u32], mut give: impl FnMut(usize, usize, u32)) {
    let mut start = 0;
    while let Some(&at) = texels.get(start) {
        let mut end = start + 1;
        while let Some(next) = texels.get(end..end + 8)
            && next.iter().all(|&t| t == at)
        {
            end += 8;
        }
        while texels.get(end) == Some(&at) {
            end += 1;
        }
        give(start, end, at);
        start = end;
    }
}

/// The yawed map's values along one row of the world grid, summed from the row's start to any
/// sub-cell, so that a run of sub-cells takes its sum in two lookups whatever its length.
///
/// World cell x shows v_x, the map cell the yaw's shift puts there, and its last fraction f the
/// next, v_{x+1} (see the module notes of `super`). Its sub-cell i holds v_x + tail_i ·
/// (v_{x+1} − v_x) (see [`tail_shares`]), so its first i sub-cells sum to i · v_x + (tail_0 + … +
/// tail_{i−1}) · (v_{x+1} − v_x) and a whole cell to q · v_x + q · f · (v_{x+1} − v_x). Summed
/// over the cells before x, with R_x = v_0 + … + v_{x−1}, that is q · (R_x + f · (v_x − v_0)).
struct RowSums {
    q: usize,
    f: f64,
    /// (i − t_i, t_i) for i = 0..q, with t_i = tail_0 + … + tail_{i−1}: sub-cell i of cell x
    /// starts at q · (R_x + f · (v_x − v_0)) + (i − t_i) · v_x + t_i · v_{x+1}.
    shares: Vec<(f64, f64)>,
    /// Per world cell x, R_x and v_x, and one more for the row's end (v_W = v_0).
    cells: Vec<([f64; 3], [f64; 3])>,
}

impl RowSums {
    fn new(width: usize, q: usize, f: f64) -> Self {
        let mut shares = vec![(0.0, 0.0)];
        for (i, t) in tail_shares(q, f).into_iter().enumerate().take(q - 1) {
            let before = shares[i].1 + t;
            shares.push(((i + 1) as f64 - before, before));
        }
        RowSums {
            q,
            f,
            shares,
            cells: vec![([0.0; 3], [0.0; 3]); width + 1],
        }
    }

    /// Takes `row` (a map row) under the yaw's shift: world cell x shows map cell x + `whole`.
    fn fill(&mut self, row: &[[f32; 3]], whole: usize) {
        let width = self.cells.len() - 1;
        let (after, before) = row.split_at(whole);
        let (head, tail) = self.cells[..width].split_at_mut(before.len());
        for (cells, values) in [(head, before), (tail, after)] {
            for (cell, v) in cells.iter_mut().zip(values) {
                cell.1 = v.map(f64::from);
            }
        }
        // Two cells a step, so that the running sum waits on one addition per two cells.
        let mut sum = [0.0f64; 3];
        let mut pairs = self.cells[..width].chunks_exact_mut(2);
        for pair in &mut pairs {
            let (a, b) = (pair[0].1, pair[1].1);
            pair[0].0 = sum;
            pair[1].0 = std::array::from_fn(|c| sum[c] + a[c]);
            sum = std::array::from_fn(|c| sum[c] + (a[c] + b[c]));
        }
        if let [last] = pairs.into_remainder() {
            last.0 = sum;
            sum = std::array::from_fn(|c| sum[c] + last.1[c]);
        }
        self.cells[width] = (sum, self.cells[0].1);
    }

    /// The sum of the row's first `k` sub-cells.
    #[inline(always)]
    fn upto(&self, k: usize) -> [f64; 3] {
        // q is one of a few small numbers, the same all along a splat.
        let (x, i) = match self.q {
            1 => (k, 0),
            2 => (k >> 1, k & 1),
            4 => (k >> 2, k & 3),
            q => (k / q, k % q),
        };
        let ((r, v), v0) = (self.cells[x], self.cells[0].1);
        let q = self.q as f64;
        let before: [f64; 3] = std::array::from_fn(|c| q * (r[c] + self.f * (v[c] - v0[c])));
        if i == 0 {
            return before;
        }
        let ((a, t), next) = (self.shares[i], self.cells[x + 1].1);
        std::array::from_fn(|c| before[c] + a * v[c] + t * next[c])
    }

    /// [`RowSums::upto`] `k`, or `known`'s sum when it is at `k`.
    #[inline(always)]
    fn upto_or(&self, known: (usize, [f64; 3]), k: usize) -> [f64; 3] {
        if known.0 == k { known.1 } else { self.upto(k) }
    }
}

/// The texel of R_x(π)·(x, y, z) = (x, −y, −z) for each texel of (x, y, z), from the texels'
/// centres (far from any border, so exact).
fn half_turns(n: usize) -> Vec<u32> {
    texel_dirs(n)
        .iter()
        .map(|d| dir_to_texel(n, DVec3::new(d.x, -d.y, -d.z)) as u32)
        .collect()
}

/// The tables of a cube size that every splat at that size reads: each texel's mirror
/// ([`mirrors`]), half turn ([`half_turns`]) and solid angle.
struct Tables {
    n: usize,
    mirror: Vec<u32>,
    half_turn: Vec<u32>,
    omega: Vec<f64>,
}

/// The tables of face size `n`, made on the first splat at that size (a drag asks for one size
/// at every step): the last few sizes asked for are kept.
fn tables(n: usize) -> Arc<Tables> {
    static KEPT: Mutex<Vec<Arc<Tables>>> = Mutex::new(Vec::new());
    const SIZES: usize = 4;
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(t) = kept.iter().find(|t| t.n == n) {
        return t.clone();
    }
    let made = Arc::new(Tables {
        n,
        mirror: mirrors(n),
        half_turn: half_turns(n),
        omega: solid_angles(n),
    });
    kept.insert(0, made.clone());
    kept.truncate(SIZES);
    made
}

/// Turns the texels of the first half of a sub-row at v, `north`, into those of the sub-row at
/// π − v, `south`, when the row has an even number of sub-columns. The direction of
/// (π − u, π − v) is R_x(π) times that of (u, v), and R_x(π) commutes with R_x(pitch), so
/// sub-column k of the south row lands in the half turn of the texel of sub-column
/// columns / 2 − 1 − k of the north row (its u is π − u_k).
fn turn_half(north: &[u32], half_turn: &[u32], south: &mut [u32]) {
    for (s, &t) in south.iter_mut().zip(north.iter().rev()) {
        *s = half_turn[t as usize];
    }
}

/// Splats a sub-row whose sub-cells each cover `omega` and whose first half lands in `texels`:
/// each run of sub-cells through one texel adds its power, from the row's running `sums`, and
/// its solid angle to that texel of `cube` (power in RGB, then the solid angle received, so that
/// a run touches one cache line).
fn splat_sub_row(
    texels: &[u32],
    columns: usize,
    mirror: &[u32],
    sums: &RowSums,
    omega: f64,
    cube: &mut [[f64; 4]],
) {
    // The sums at the last boundary of each half, taken once for the two runs that meet there.
    let mut forward = (0, [0.0; 3]);
    let mut backward = (columns, sums.upto(columns));
    row_runs(texels, columns, mirror, |texel, start, end, mirrored| {
        let (from, to) = if mirrored {
            let to = sums.upto_or(backward, end);
            let from = sums.upto(start);
            backward = (start, from);
            (from, to)
        } else {
            let from = sums.upto_or(forward, start);
            let to = sums.upto(end);
            forward = (end, to);
            (from, to)
        };
        let texel = &mut cube[texel];
        for c in 0..3 {
            texel[c] += (to[c] - from[c]) * omega;
        }
        texel[3] += (end - start) as f64 * omega;
    });
}

/// `map` turned by `rotation` and splatted at the centres
/// of the world cells' sub-cells into a cube of face `n`; `None` when a texel received nothing
/// (the caller then records weights for the pitch).
pub(super) fn splat(map: LatLong, n: usize, rotation: EnvRotation) -> Result<Option<CubeMap>> {
    splat_rows(map, n, rotation, true)
}

/// [`splat`], the texels of each southern sub-row looked up from its northern twin's (see
/// [`turn_half`]) when `paired` and the row's sub-columns are even in number, else each looked
/// up itself (the slow twin the tests compare with).
pub(super) fn splat_rows(
    map: LatLong,
    n: usize,
    rotation: EnvRotation,
    paired: bool,
) -> Result<Option<CubeMap>> {
    let LatLong {
        width,
        height,
        pixels,
    } = map;
    let (whole, f) = yaw_shift(width, rotation.yaw_deg)?;
    let q = split(width, height, n);
    // The sub-columns of the first half of a row: the second half mirrors them (see
    // [`row_runs`]).
    let columns = width * q;
    let paired = paired && columns.is_multiple_of(2);
    let (sin_u, cos_u): (Vec<f32>, Vec<f32>) = (0..columns.div_ceil(2))
        .map(|x| {
            let (s, c) = (TAU * (x as f64 + 0.5) / columns as f64).sin_cos();
            (s as f32, c as f32)
        })
        .unzip();
    let count = texel_count(n);
    let tables = tables(n);
    let (sin_p, cos_p) = rotation.pitch_deg.to_radians().sin_cos();
    // Paired, a unit of work is a northern map row and its southern twin.
    let units = if paired { height.div_ceil(2) } else { height };
    // A few bands a thread, each scattering into a cube of its own.
    let bands = (rayon::current_num_threads() * BANDS_PER_THREAD).clamp(1, units);
    let cube = (0..bands)
        .into_par_iter()
        .map(|band| {
            let mut cube = vec![[0.0f64; 4]; count];
            let mut texels = vec![0u32; sin_u.len()];
            let mut turned = vec![0u32; sin_u.len()];
            let mut sums = RowSums::new(width, q, f);
            let mut south_sums = RowSums::new(width, q, f);
            // The solid angle of a sub-cell of sub-row `j` of map row `y`.
            let omega = |y: usize, j: usize| {
                let v0 = PI * (y * q + j) as f64 / (height * q) as f64;
                let v1 = PI * (y * q + j + 1) as f64 / (height * q) as f64;
                TAU / columns as f64 * (v0.cos() - v1.cos())
            };
            for y in band * units / bands..(band + 1) * units / bands {
                let south = height - 1 - y;
                let twin = paired && south != y;
                sums.fill(&pixels[y * width..(y + 1) * width], whole);
                if twin {
                    south_sums.fill(&pixels[south * width..(south + 1) * width], whole);
                }
                for j in 0..q {
                    // The sub-row's centre's direction turned by R_x(pitch): (sin u sin v,
                    // cos v, −cos u sin v) goes to (sin u sin v, c cos v + s cos u sin v,
                    // s cos v − c cos u sin v).
                    let v = PI * ((y * q + j) as f64 + 0.5) / (height * q) as f64;
                    let (sin_v, cos_v) = v.sin_cos();
                    texels_of(
                        n,
                        &sin_u,
                        &cos_u,
                        sin_v as f32,
                        ((cos_p * cos_v) as f32, (sin_p * sin_v) as f32),
                        ((sin_p * cos_v) as f32, (cos_p * sin_v) as f32),
                        &mut texels,
                    );
                    let mut sub_row = |texels: &[u32], sums: &RowSums, omega: f64| {
                        splat_sub_row(texels, columns, &tables.mirror, sums, omega, &mut cube);
                    };
                    sub_row(&texels, &sums, omega(y, j));
                    if twin {
                        turn_half(&texels, &tables.half_turn, &mut turned);
                        sub_row(&turned, &south_sums, omega(south, q - 1 - j));
                    }
                }
            }
            cube
        })
        .reduce_with(|mut a, b| {
            for (a, b) in a.iter_mut().zip(&b) {
                for c in 0..4 {
                    a[c] += b[c];
                }
            }
            a
        })
        .unwrap_or_default();
    if cube.len() != count || cube.iter().any(|t| t[3] == 0.0) {
        return Ok(None);
    }
    // The map's exact power: each row's turned means keep its sum.
    let want: [f64; 3] = std::array::from_fn(|c| cube.iter().map(|p| p[c]).sum());
    Ok(Some(splat_radiance(
        n,
        cube.iter().map(|t| ([t[0], t[1], t[2]], t[3])),
        want,
        &tables.omega,
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Directions whose face coordinates lie this close to a texel border (in texels) are left
    /// out: f32 may put them on either side.
    const BORDER: f64 = 1e-4;

    /// Random rows of directions, as the splat makes them: (sin u sin v, y0 + y1 cos u,
    /// z0 − z1 cos u) for a pitch and a v.
    fn rows(count: usize) -> Vec<(f64, f64, Vec<f64>)> {
        let mut rng = crate::test_support::Rng(0x7e11);
        (0..count)
            .map(|_| {
                let pitch = (rng.unit() - 0.5) * TAU;
                let v = rng.unit() * PI;
                let us = (0..64).map(|_| rng.unit() * TAU).collect();
                (pitch, v, us)
            })
            .collect()
    }

    fn off_borders(n: usize, d: DVec3) -> bool {
        let (_, s, t) = crate::math::cubemap::dir_to_face_st(d);
        [s, t].iter().all(|&x| {
            let c = (x + 1.0) * 0.5 * n as f64;
            (c - c.round()).abs() > BORDER
        })
    }

    #[test]
    fn texels_are_looked_up_as_in_f64() {
        for n in [1, 2, 7, 32, 64, 256] {
            let mut checked = 0;
            for (pitch, v, us) in rows(200) {
                let (sin_p, cos_p) = pitch.sin_cos();
                let (sin_v, cos_v) = v.sin_cos();
                let (su, cu): (Vec<f32>, Vec<f32>) = us
                    .iter()
                    .map(|u: &f64| (u.sin() as f32, u.cos() as f32))
                    .unzip();
                let mut got = vec![0u32; us.len()];
                let (y, z) = (
                    (cos_p * cos_v, sin_p * sin_v),
                    (sin_p * cos_v, cos_p * sin_v),
                );
                texels_of(
                    n,
                    &su,
                    &cu,
                    sin_v as f32,
                    (y.0 as f32, y.1 as f32),
                    (z.0 as f32, z.1 as f32),
                    &mut got,
                );
                for (k, &u) in us.iter().enumerate() {
                    let d = DVec3::new(u.sin() * sin_v, y.0 + y.1 * u.cos(), z.0 - z.1 * u.cos());
                    if off_borders(n, d) {
                        assert_eq!(got[k] as usize, dir_to_texel(n, d), "N = {n}, {d}");
                        checked += 1;
                    }
                }
            }
            assert!(checked > 10_000, "N = {n}: {checked}");
        }
    }

    #[test]
    fn a_row_is_mirrored_about_its_middle_at_odd_and_even_lengths() {
        for (n, columns) in [(8, 20usize), (8, 21), (32, 1023), (32, 1024), (4, 1)] {
            let mirror = mirrors(n);
            let u = |k: usize| TAU * (k as f64 + 0.5) / columns as f64;
            let (su, cu): (Vec<f32>, Vec<f32>) = (0..columns.div_ceil(2))
                .map(|k| (u(k).sin() as f32, u(k).cos() as f32))
                .unzip();
            for (pitch, v, _) in rows(20) {
                let (sin_p, cos_p) = pitch.sin_cos();
                let (sin_v, cos_v) = v.sin_cos();
                let (y, z) = (
                    (cos_p * cos_v, sin_p * sin_v),
                    (sin_p * cos_v, cos_p * sin_v),
                );
                let mut half = vec![0u32; su.len()];
                let narrow = |p: (f64, f64)| (p.0 as f32, p.1 as f32);
                texels_of(n, &su, &cu, sin_v as f32, narrow(y), narrow(z), &mut half);
                // Every sub-column in one run, and only one.
                let mut got = vec![None; columns];
                // Each half's runs follow one another: the first half's from 0 up, the
                // mirrors from the row's end down.
                let (mut forward, mut backward) = (0, columns);
                row_runs(&half, columns, &mirror, |texel, start, end, mirrored| {
                    assert!(start < end && end <= columns, "{start}..{end} of {columns}");
                    if mirrored {
                        assert_eq!(end, backward, "N = {n}, {columns}: a mirror at {start}");
                        backward = start;
                    } else {
                        assert_eq!(start, forward, "N = {n}, {columns}: a run at {start}");
                        forward = end;
                    }
                    for g in &mut got[start..end] {
                        assert_eq!(*g, None, "N = {n}, {columns}: {start}..{end} twice");
                        *g = Some(texel);
                    }
                });
                for (k, &texel) in got.iter().enumerate() {
                    let texel = texel.expect("every sub-column in a run");
                    let d = DVec3::new(
                        u(k).sin() * sin_v,
                        y.0 + y.1 * u(k).cos(),
                        z.0 - z.1 * u(k).cos(),
                    );
                    if off_borders(n, d) {
                        assert_eq!(texel, dir_to_texel(n, d), "N = {n}, {columns}: {k}");
                    }
                }
            }
        }
    }

    #[test]
    fn mirrored_and_half_turned_directions_land_in_mirrored_and_half_turned_texels() {
        for n in [1, 4, 32, 64] {
            let (mirror, half_turn) = (mirrors(n), half_turns(n));
            for (pitch, v, us) in rows(50) {
                for u in us {
                    let d = DVec3::new(
                        u.sin() * v.sin(),
                        pitch.cos(),
                        u.cos() * v.cos() - pitch.sin(),
                    );
                    if off_borders(n, d) {
                        let texel = dir_to_texel(n, d);
                        let flipped = DVec3::new(-d.x, d.y, d.z);
                        let turned = DVec3::new(d.x, -d.y, -d.z);
                        assert_eq!(
                            mirror[texel] as usize,
                            dir_to_texel(n, flipped),
                            "N = {n}, {d}"
                        );
                        assert_eq!(
                            half_turn[texel] as usize,
                            dir_to_texel(n, turned),
                            "N = {n}, {d}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn a_southern_sub_row_is_its_northern_twin_half_turned() {
        for (n, columns) in [(8, 20usize), (32, 1024), (64, 2048)] {
            let half_turn = half_turns(n);
            let u = |k: usize| TAU * (k as f64 + 0.5) / columns as f64;
            let (su, cu): (Vec<f32>, Vec<f32>) = (0..columns / 2)
                .map(|k| (u(k).sin() as f32, u(k).cos() as f32))
                .unzip();
            let mut checked = 0;
            for (pitch, v, _) in rows(20) {
                let (sin_p, cos_p) = pitch.sin_cos();
                let look_up = |v: f64| {
                    let (sin_v, cos_v) = v.sin_cos();
                    let mut texels = vec![0u32; su.len()];
                    let y = ((cos_p * cos_v) as f32, (sin_p * sin_v) as f32);
                    let z = ((sin_p * cos_v) as f32, (cos_p * sin_v) as f32);
                    texels_of(n, &su, &cu, sin_v as f32, y, z, &mut texels);
                    texels
                };
                let mut turned = vec![0u32; su.len()];
                turn_half(&look_up(v), &half_turn, &mut turned);
                let south = PI - v;
                for (k, (&got, &direct)) in turned.iter().zip(&look_up(south)).enumerate() {
                    let (sin_v, cos_v) = south.sin_cos();
                    let d = DVec3::new(
                        u(k).sin() * sin_v,
                        cos_p * cos_v + sin_p * sin_v * u(k).cos(),
                        sin_p * cos_v - cos_p * sin_v * u(k).cos(),
                    );
                    if off_borders(n, d) {
                        assert_eq!(got, direct, "N = {n}, {columns}: {k}");
                        assert_eq!(got as usize, dir_to_texel(n, d), "N = {n}: {k}");
                        checked += 1;
                    }
                }
            }
            assert!(checked > 100, "N = {n}: {checked}");
        }
    }

    #[test]
    fn a_run_of_sub_cells_sums_as_its_sub_cells_one_by_one() {
        let mut rng = crate::test_support::Rng(0x5e3);
        let width = 37;
        let row: Vec<[f32; 3]> = (0..width)
            .map(|_| std::array::from_fn(|_| (rng.unit() * 10.0) as f32))
            .collect();
        for q in 1..=MAX_SPLIT {
            for (whole, f) in [(0, 0.0), (5, 0.3), (36, 0.75), (17, 0.999)] {
                let mut sums = RowSums::new(width, q, f);
                sums.fill(&row, whole);
                // The slow twin: every sub-cell's value, as the yaw's shift gives it.
                let tail = tail_shares(q, f);
                let values: Vec<[f64; 3]> = (0..width * q)
                    .map(|k| {
                        let (x, i) = (k / q, k % q);
                        let a = row[(x + whole) % width].map(f64::from);
                        let b = row[(x + whole + 1) % width].map(f64::from);
                        std::array::from_fn(|c| a[c] + tail[i] * (b[c] - a[c]))
                    })
                    .collect();
                for _ in 0..200 {
                    let start = (rng.unit() * (width * q) as f64) as usize;
                    let end = start + (rng.unit() * (width * q + 1 - start) as f64) as usize;
                    let (from, to) = (sums.upto(start), sums.upto(end));
                    let got: [f64; 3] = std::array::from_fn(|c| to[c] - from[c]);
                    for c in 0..3 {
                        let want: f64 = values[start..end].iter().map(|v| v[c]).sum();
                        assert!(
                            (got[c] - want).abs() <= 1e-12 * (1.0 + want.abs()),
                            "q = {q}, shift {whole} + {f}, {start}..{end}: {} against {want}",
                            got[c]
                        );
                    }
                }
                // The whole row is the map row's sum, q sub-cells a cell.
                let total = sums.upto(width * q);
                assert_eq!(sums.upto(0), [0.0; 3]);
                for c in 0..3 {
                    let want = q as f64 * row.iter().map(|v| v[c] as f64).sum::<f64>();
                    assert!((total[c] - want).abs() <= 1e-12 * want, "{total:?}");
                }
            }
        }
    }

    #[test]
    fn the_next_cell_fills_the_last_sub_columns_first() {
        let near = |got: Vec<f64>, want: &[f64]| {
            assert!(
                got.len() == want.len() && got.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
                "{got:?} against {want:?}"
            )
        };
        near(tail_shares(1, 0.3), &[0.3]);
        near(tail_shares(4, 0.0), &[0.0; 4]);
        near(tail_shares(4, 0.25), &[0.0, 0.0, 0.0, 1.0]);
        near(tail_shares(4, 0.375), &[0.0, 0.0, 0.5, 1.0]);
        // Every share together is the fraction.
        for q in 1..=MAX_SPLIT {
            for f in [0.1, 0.5, 0.9] {
                let sum: f64 = tail_shares(q, f).iter().sum::<f64>() / q as f64;
                assert!((sum - f).abs() < 1e-12, "q = {q}, f = {f}: {sum}");
            }
        }
    }
}
