//! Fast lat-long -> cube resampling, for interactive rotation and switching between maps.
//!
//! The exact splat of [`crate::math::cubemap::resample_latlong_exact`] cuts every lat-long cell into
//! pieces and gives each piece to a texel. Which pieces go where depends on the map's size, the
//! cube's N and the rotation, never on the pixel values, so it is recorded once as a sparse matrix
//! ([`LatLongWeights`]: per cell, the texels it gives to and the solid angle of each share) and a
//! cube is then one pass over the map: power and received solid angle per texel, radiance = power
//! / received, then one factor per channel that restores the map's exact total power, as the
//! exact splat does. Under the same rotation the result is the exact splat's, up to f32 rounding
//! of the recorded solid angles (measured: one f32 ulp on every bundled map at N = 32 and 64).
//! Recording cuts cells as the exact splat does, but carries edge angles down the cuts instead of
//! calling sin/cos at every corner, and cuts only the cells the symmetries of the split do not
//! give (see `Symmetry`).
//!
//! # Yaw is a shift
//! With world = R_y(yaw) · map (see [`crate::conventions`]), the map direction at lat-long u lands
//! at world u − yaw/360, so the turned map seen on the world's lat-long grid is
//! M'(u) = M(u + yaw/360): a cyclic shift of every row by s = W · yaw/360 pixels. The weights are
//! recorded on the world grid (under the pitch alone), so any yaw reuses them:
//!
//! - s = n whole pixels renumbers cells: world cell x holds map cell x + n and the gather is the
//!   exact splat of the turned map, to rounding.
//! - s = n + f: world cell x holds the last 1 − f of map cell x + n and the first f of cell
//!   x + n + 1. A share of world cell x spread evenly across the cell's width (a cell inside one
//!   texel, or one cut only along v) takes (1 − f) M[x+n] + f M[x+n+1], which is exact. A share
//!   that is uneven across the width (a texel border crosses the cell) takes M[x+n+1] for the
//!   part of its solid angle in the cell's last fraction f; that part is tabulated per share at
//!   Q + 1 evenly spaced f (Q = 2^depth of the cuts, at most 16) and
//!   interpolated, which is exact while the cuts are no finer than 1/Q of a cell.
//!
//! So the fast path integrates the turned map exactly over the pieces of the world grid, where the
//! slow twin integrates it over the pieces of the turned cells: both are exact up to the band,
//! `finest` wide, along texel borders where the last pieces go whole to the texel of their centre.
//! Where a texel border crosses a small bright source that band holds a few percent of it: on
//! blender_sunrise (a 2 x 2-pixel sun) the two differ by up to 4.2% relative L2 over the cube at
//! N = 32, when the exact splat itself is up to 1.9% from a splat with a 16 times narrower band;
//! on smooth maps they differ by well under 1%. Every row keeps its power and a constant map stays
//! constant under any yaw. Pitch, applied after the yaw, is splatted at the cells' centres where
//! they are small enough (the `pitch` module), and otherwise records weights of its own.
//!
//! # Cache
//! Weights (the `cache` module) are kept process-wide for the last few (W, H, N, pitch) asked for, under a lock that is
//! only held to look up and insert, so the viewer's worker thread and parallel tests share them.
//! The unturned ones (pitch 0) are also kept on disk (the `disk` module), so a fresh process
//! reads them rather than recording them again.

mod cache;
mod disk;
mod pitch;
mod record;

pub use cache::{clear_cache, use_disk, weights};
use record::*;

use std::f64::consts::{PI, TAU};

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::env::latlong::{EnvRotation, pixel_solid_angle};
use crate::error::{PrtError, Result};
use crate::math::cubemap::{
    CubeMap, Cut, LatLong, check_latlong, dir_to_face_st, dir_to_texel, resample_latlong_exact,
    solid_angles, splat_limits, splat_radiance, texel_count, texel_dirs, texel_index, validate_n,
    widest_sin,
};

/// Largest map whose split is recorded: a larger one's shares would outweigh its pixels (2.3 GB
/// beside 1.5 GiB at 16384 x 8192), so it is splatted directly, one cube per thread, every turn.
pub const MAX_RECORDED_PIXELS: usize = 8192 * 4096;

/// Row bands per thread in the gather: each band scatters into a cube of its own (590 KiB at
/// N = 64) that is then summed, so few bands; two leave some room to balance a busy machine.
const BANDS_PER_THREAD: usize = 2;
/// A yaw this close to a whole number of pixels (in pixels) is taken as whole, so whole-pixel yaws
/// given in degrees are exact renumberings despite the rounding of yaw/360.
const WHOLE_PIXEL_SNAP: f64 = 1e-9;
/// Above this angle (radians) the halfway direction of two cell edges is taken from sin/cos
/// directly rather than from the normalised sum of the two (which vanishes at π).
const MIDPOINT_DIRECT_ANGLE: f64 = 0.5;
/// Most sub-columns per cell in the tables of uneven shares. Cuts reach 1/8 of a 1024 x 512 map's
/// cell at N = 32 and 1/16 at N = 64; finer cuts (larger N, smaller maps) are interpolated
/// linearly inside a sixteenth of a cell, and memory stays at 30 bytes per uneven share.
const MAX_SUBCOLUMNS: usize = 16;
/// A share whose fraction in every sub-column is 1/Q to this is even across its cell. Shares are
/// sums of dyadic pieces, so an even one is even to rounding (1e-16); uneven ones differ by at
/// least a piece, orders of magnitude above this.
const EVEN_TOL: f64 = 1e-9;
/// Scale of the tabulated fractions (u16). The quantisation moves at most 8e-6 of an uneven
/// share's solid angle between two neighbouring cells; the total power is restored exactly by the
/// final normalisation.
const TAIL_SCALE: f64 = 65535.0;

/// A point this close to a texel border (in texels, or relative between face axes) may fall on
/// either side by rounding: far above the ~1e-16 by which the half-angle directions differ from
/// sin/cos, far below the spacing of the points the cuts make.
const TIE_TOL: f64 = 1e-9;
/// Low bits of a share's word: the texel index (6·256² < 2^30).
const TEXEL_BITS: u32 = (1 << 30) - 1;
/// Word flag: the last share of its cell.
const LAST: u32 = 1 << 30;
/// Word flag: a share uneven across its cell's width, with a table.
const UNEVEN: u32 = 1 << 31;

/// The recorded splat of a W x H lat-long map into a cube of face size N under R_x(pitch), on the
/// world grid: what [`crate::math::cubemap::resample_latlong_exact`] adds to each texel, as a sparse
/// matrix stored cell by cell, plus what a fractional yaw needs (see the module notes).
///
/// Stored by cell rather than by texel so the gather streams through the map and the shares in
/// order and scatters into the cube, which stays in cache (147 KiB at N = 32); the map (6 MiB at
/// 1024 x 512) does not.
#[derive(Debug)]
pub struct LatLongWeights {
    width: usize,
    height: usize,
    n: usize,
    pitch_deg: f64,
    /// One word per share, cells in row-major order and each cell's shares together: the texel in
    /// [`TEXEL_BITS`], [`LAST`] on the cell's last share, [`UNEVEN`] on uneven shares.
    word: Vec<u32>,
    /// Solid angle of each share.
    weight: Vec<f32>,
    /// Shares before row y (H + 1 entries).
    row_start: Vec<usize>,
    /// Uneven shares before row y (H + 1 entries).
    row_uneven: Vec<usize>,
    /// Sub-columns Q per cell of the tables.
    subcolumns: usize,
    /// Whether Q sub-columns resolve every cut ([`MAX_SUBCOLUMNS`] is enough for any map of
    /// cells no wider than texels, not for one a few pixels wide): a fractional yaw is
    /// interpolated within 1/Q of a cell only when they do.
    resolves_cuts: bool,
    /// `tail[(k − 1)·B + b]` for k = 1..Q−1 and uneven share b of B: the fraction of the share's
    /// solid angle in the last k/Q of its cell's width, times [`TAIL_SCALE`] (k = 0 and k = Q are
    /// 0 and 1). Column by column, so a yaw reads two contiguous columns.
    tail: Vec<u16>,
    /// Solid angle each texel received: the sum of its (f32) shares in f64, so a constant map
    /// divides back to exactly its value.
    received: Vec<f64>,
    /// Exact texel solid angles, for the power normalisation.
    omega: Vec<f64>,
    /// Exact solid angle of a pixel of each row, for the map's total power.
    row_omega: Vec<f64>,
}

impl LatLongWeights {
    /// Records the splat of a `width` x `height` map into a cube of face size `n` under
    /// R_x(`pitch_deg`) (the rotation [`EnvRotation`] makes with yaw 0).
    pub fn build(width: usize, height: usize, n: usize, pitch_deg: f64) -> Result<Self> {
        validate_n(n)?;
        check_latlong(width, height, width.saturating_mul(height))?;
        if u32::try_from(width * height).is_err() {
            return Err(PrtError::invalid(
                "environment map",
                format!("{width} x {height} has more pixels than a u32 index reaches"),
            ));
        }
        check_angle("pitch", pitch_deg)?;
        let (texel_min, finest) = splat_limits(n, width, height);
        // Cuts halve a cell until it is below `finest`: the largest cell (the equator's) sets
        // the depth, hence the sub-columns that resolve every cut.
        let largest = (PI / height as f64).max(TAU / width as f64);
        let mut q = 1;
        while largest / q as f64 >= finest && q < MAX_SUBCOLUMNS {
            q *= 2;
        }
        let rec = Recorder {
            n,
            world_from_map: EnvRotation::new(0.0, pitch_deg).world_from_map(),
            finest,
            texel_min,
        };
        let u_edges: Vec<Edge> = (0..=width)
            .map(|x| Edge::at(x as f64 / width as f64, TAU))
            .collect();
        let v_edges: Vec<Edge> = (0..=height)
            .map(|y| Edge::at(y as f64 / height as f64, PI))
            .collect();
        let sym = Symmetry::new(width, height, n, pitch_deg);
        let (rows, cols) = (sym.rows, sym.cols);
        // Texels of the grid points of the cut cells, each computed once and shared by the four
        // cells around it.
        let mut grid = vec![0u32; (cols + 1) * (rows + 1)];
        grid.par_chunks_mut(cols + 1)
            .zip(&v_edges)
            .for_each(|(row, &v)| {
                for (g, &u) in row.iter_mut().zip(&u_edges) {
                    *g = rec.texel_of(u, v);
                }
            });
        let cut: Vec<RowRecord> = (0..rows)
            .into_par_iter()
            .map_init(Vec::new, |pieces, y| {
                let (v0, v1) = (v_edges[y], v_edges[y + 1]);
                let top = &grid[y * (cols + 1)..(y + 1) * (cols + 1)];
                let bottom = &grid[(y + 1) * (cols + 1)..(y + 2) * (cols + 1)];
                let mut out = RowRecord::default();
                for x in 0..cols {
                    pieces.clear();
                    rec.splat(
                        (u_edges[x], u_edges[x + 1], v0, v1),
                        (0.0, 1.0),
                        [top[x], top[x + 1], bottom[x], bottom[x + 1]],
                        pieces,
                    );
                    out.add_cell(pieces, q);
                }
                out.cell_start.push(out.word.len());
                out.cell_uneven.push(out.tails.len() / (q - 1).max(1));
                out
            })
            .collect();
        // Every cell, copied from the cell it mirrors or turns to.
        let rows: Vec<RowRecord> = (0..height)
            .into_par_iter()
            .map(|y| {
                let mut out = RowRecord::default();
                for x in 0..width {
                    let (xs, ys, renumber, flip) = sym.source(x, y, height);
                    let src = &cut[ys];
                    let mut b = src.cell_uneven[xs];
                    for s in src.cell_start[xs]..src.cell_start[xs + 1] {
                        let word = src.word[s];
                        let texel = renumber[(word & TEXEL_BITS) as usize];
                        out.word.push(texel | (word & !TEXEL_BITS));
                        out.weight.push(src.weight[s]);
                        if word & UNEVEN == 0 {
                            continue;
                        }
                        let tails = &src.tails[b * (q - 1)..(b + 1) * (q - 1)];
                        b += 1;
                        if flip {
                            // The last k/Q of a mirrored share is the first k/Q of its source.
                            let scale = TAIL_SCALE as u16;
                            out.tails.extend(tails.iter().rev().map(|&t| scale - t));
                        } else {
                            out.tails.extend_from_slice(tails);
                        }
                    }
                }
                out
            })
            .collect();
        let mut row_start = vec![0usize; height + 1];
        let mut row_uneven = vec![0usize; height + 1];
        for (y, r) in rows.iter().enumerate() {
            row_start[y + 1] = row_start[y] + r.word.len();
            row_uneven[y + 1] = row_uneven[y] + r.tails.len() / (q - 1).max(1);
        }
        let (total, b_count) = (row_start[height], row_uneven[height]);
        let (mut word, mut weight) = (Vec::with_capacity(total), Vec::with_capacity(total));
        let mut tail = vec![0u16; (q - 1) * b_count];
        for (y, r) in rows.iter().enumerate() {
            word.extend_from_slice(&r.word);
            weight.extend_from_slice(&r.weight);
            // With one sub-column every share is even and there are no tables.
            for (i, fractions) in r.tails.chunks_exact((q - 1).max(1)).enumerate() {
                let b = row_uneven[y] + i;
                for (k, &t) in fractions.iter().enumerate() {
                    tail[k * b_count + b] = t;
                }
            }
        }
        Ok(LatLongWeights::from_parts(
            [width, height, n],
            pitch_deg,
            word,
            weight,
            [row_start, row_uneven],
            (q, largest / (q as f64) < finest),
            tail,
        ))
    }

    /// The weights of these recorded (or read) parts, with what the gather derives from them:
    /// the solid angle each texel received (the sum of its f32 shares in f64, in share order),
    /// the exact texel solid angles and the solid angle of a pixel of each row.
    fn from_parts(
        [width, height, n]: [usize; 3],
        pitch_deg: f64,
        word: Vec<u32>,
        weight: Vec<f32>,
        [row_start, row_uneven]: [Vec<usize>; 2],
        (subcolumns, resolves_cuts): (usize, bool),
        tail: Vec<u16>,
    ) -> LatLongWeights {
        let mut received = vec![0.0f64; texel_count(n)];
        for (&w, &s) in word.iter().zip(&weight) {
            received[(w & TEXEL_BITS) as usize] += s as f64;
        }
        LatLongWeights {
            width,
            height,
            n,
            pitch_deg,
            word,
            weight,
            row_start,
            row_uneven,
            subcolumns,
            resolves_cuts,
            tail,
            received,
            omega: solid_angles(n),
            row_omega: (0..height)
                .map(|y| pixel_solid_angle(width, height, y))
                .collect(),
        }
    }

    /// Recorded shares (non-zeros of the matrix): (all, uneven across their cell's width).
    pub fn shares(&self) -> (usize, usize) {
        (self.word.len(), self.row_uneven[self.height])
    }

    /// Sub-columns per cell of the tables of uneven shares.
    pub fn subcolumns(&self) -> usize {
        self.subcolumns
    }

    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        self.word.len() * 8
            + self.tail.len() * 2
            + (self.row_start.len() + self.row_uneven.len() + self.row_omega.len()) * 8
            + (self.received.len() + self.omega.len()) * 8
    }

    /// Adds the power that row `y` of the turned map gives each texel to `power`, and returns the
    /// row's sum of radiance. World cell x shows map cells x + `shift` and x + `shift` + 1
    /// (cyclic), the second over the fraction `f` of the cell (or `tail_at` of an uneven share);
    /// without a fraction (`FRACTIONAL` false, f = 0) only the first is read.
    #[inline(always)]
    fn scatter_row<const FRACTIONAL: bool>(
        &self,
        y: usize,
        row: &[[f32; 3]],
        shift: usize,
        f: f64,
        tail_at: &impl Fn(usize) -> f64,
        power: &mut [[f64; 3]],
    ) -> [f64; 3] {
        let w = row.len();
        let (mut s, mut b) = (self.row_start[y], self.row_uneven[y]);
        let mut sum = [0.0f64; 3];
        // Runs of shares into one texel (a texel spans several cells of a row) add up in
        // registers, not through memory.
        let (mut texel, mut acc) = (u32::MAX, [0.0f64; 3]);
        let mut x1 = shift;
        for _ in 0..w {
            let x2 = if x1 + 1 == w { 0 } else { x1 + 1 };
            let m1 = row[x1].map(|v| v as f64);
            let d: [f64; 3] = if FRACTIONAL {
                std::array::from_fn(|c| row[x2][c] as f64 - m1[c])
            } else {
                [0.0; 3]
            };
            for c in 0..3 {
                sum[c] += m1[c];
            }
            loop {
                let (word, wt) = (self.word[s], self.weight[s] as f64);
                s += 1;
                let j = word & TEXEL_BITS;
                if j != texel {
                    if let Some(p) = power.get_mut(texel as usize) {
                        for c in 0..3 {
                            p[c] += acc[c];
                        }
                    }
                    (texel, acc) = (j, [0.0; 3]);
                }
                if FRACTIONAL {
                    let g = if word & UNEVEN == 0 {
                        f
                    } else {
                        b += 1;
                        tail_at(b - 1)
                    };
                    for c in 0..3 {
                        acc[c] += wt * (m1[c] + g * d[c]);
                    }
                } else {
                    for c in 0..3 {
                        acc[c] += wt * m1[c];
                    }
                }
                if word & LAST != 0 {
                    break;
                }
            }
            x1 = x2;
        }
        if let Some(p) = power.get_mut(texel as usize) {
            for c in 0..3 {
                p[c] += acc[c];
            }
        }
        sum
    }

    /// The cube map of texel-average radiance of `pixels`, a `width` x `height` map, turned by
    /// `yaw_deg` about +Y and then by the pitch these weights were built for.
    pub fn cube(&self, pixels: &[[f32; 3]], yaw_deg: f64) -> Result<CubeMap> {
        let (w, q) = (self.width, self.subcolumns);
        check_latlong(w, self.height, pixels.len())?;
        let (shift, f) = yaw_shift(w, yaw_deg)?;
        // The tables at f: between columns k and k + 1, a fraction r of the way.
        let qf = f * q as f64;
        let k = (qf.floor() as usize).min(q - 1);
        let r = qf - k as f64;
        let b_count = self.row_uneven[self.height];
        let column = |k: usize| -> Option<&[u16]> {
            (k > 0 && k < q).then(|| &self.tail[(k - 1) * b_count..k * b_count])
        };
        let (lo, hi) = (column(k), column(k + 1));
        let scale = 1.0 / TAIL_SCALE;
        let tail_at = |b: usize| -> f64 {
            let a = lo.map_or(0.0, |c| c[b] as f64 * scale);
            let b = hi.map_or(1.0, |c| c[b] as f64 * scale);
            a + r * (b - a)
        };
        let count = texel_count(self.n);
        // Row bands, each scattering into its own cube of power.
        let bands = (BANDS_PER_THREAD * rayon::current_num_threads()).clamp(1, self.height);
        let (power, want) = (0..bands)
            .into_par_iter()
            .fold(
                || (vec![[0.0f64; 3]; count], [0.0f64; 3]),
                |(mut power, mut want), band| {
                    let rows = band * self.height / bands..(band + 1) * self.height / bands;
                    for y in rows {
                        let row = &pixels[y * w..(y + 1) * w];
                        let sum = if f == 0.0 {
                            self.scatter_row::<false>(y, row, shift, 0.0, &tail_at, &mut power)
                        } else {
                            self.scatter_row::<true>(y, row, shift, f, &tail_at, &mut power)
                        };
                        // A shift keeps every row's sum: this is the map's exact power.
                        for c in 0..3 {
                            want[c] += sum[c] * self.row_omega[y];
                        }
                    }
                    (power, want)
                },
            )
            .reduce(
                || (vec![[0.0f64; 3]; count], [0.0f64; 3]),
                |(mut pa, wa), (pb, wb)| {
                    for (a, b) in pa.iter_mut().zip(&pb) {
                        for c in 0..3 {
                            a[c] += b[c];
                        }
                    }
                    (pa, std::array::from_fn(|c| wa[c] + wb[c]))
                },
            );
        // As the exact splat: radiance is power over the solid angle received, then one factor
        // per channel restores the total power.
        Ok(splat_radiance(
            self.n,
            power.iter().copied().zip(self.received.iter().copied()),
            want,
            &self.omega,
        ))
    }
}

fn check_angle(what: &str, deg: f64) -> Result<()> {
    crate::flags::angle(what, deg)
}

/// The shift of a `width`-pixel row that turns a map by `yaw_deg`: (whole pixels n, fraction f)
/// with n + f = W · yaw/360 modulo W (see the module notes).
pub fn yaw_shift(width: usize, yaw_deg: f64) -> Result<(usize, f64)> {
    check_angle("yaw", yaw_deg)?;
    let s = (yaw_deg / 360.0).rem_euclid(1.0) * width as f64;
    let whole = s.floor();
    let f = s - whole;
    Ok(if f < WHOLE_PIXEL_SNAP {
        (whole as usize % width, 0.0)
    } else if f > 1.0 - WHOLE_PIXEL_SNAP {
        ((whole as usize + 1) % width, 0.0)
    } else {
        (whole as usize % width, f)
    })
}

/// Resamples the lat-long `map` into a cube of face size `n` turned by `rotation`:
/// the cached weights gathered with the yaw's shift; a pitch splatted at the cells' centres
/// where they are no larger than the smallest texels (`pitch`), else by weights recorded for
/// it.
pub fn resample_latlong(map: LatLong, n: usize, rotation: EnvRotation) -> Result<CubeMap> {
    validate_n(n)?;
    map.check()?;
    check_angle("yaw", rotation.yaw_deg)?;
    if map.width * map.height > MAX_RECORDED_PIXELS {
        // Recorded shares would take several bytes a pixel on top of the map; splat directly.
        return resample_latlong_exact(map, n, rotation.world_from_map());
    }
    check_angle("pitch", rotation.pitch_deg)?;
    if rotation.pitch_deg + 0.0 != 0.0
        && pitch::splats_at_centres(map.width, map.height, n)
        && let Some(cube) = pitch::splat(map, n, rotation)?
    {
        // A pitch records no weights where the cells are small enough (see `pitch`).
        return Ok(cube);
    }
    resample_latlong_recorded(map, n, rotation)
}

/// [`resample_latlong`] by weights recorded for the rotation's pitch, whatever it is: the path of
/// an unpitched map, and of a pitched one whose cells are larger than the smallest texels.
pub fn resample_latlong_recorded(map: LatLong, n: usize, rotation: EnvRotation) -> Result<CubeMap> {
    validate_n(n)?;
    map.check()?;
    check_angle("yaw", rotation.yaw_deg)?;
    if map.width * map.height > MAX_RECORDED_PIXELS {
        return resample_latlong_exact(map, n, rotation.world_from_map());
    }
    let recorded = weights(map.width, map.height, n, rotation.pitch_deg)?;
    let (_, fraction) = yaw_shift(map.width, rotation.yaw_deg)?;
    if fraction != 0.0 && !recorded.resolves_cuts {
        // Cells much wider than texels (a map a few pixels wide): the tables would interpolate
        // across many cuts, and the exact splat costs little on so few cells.
        return resample_latlong_exact(map, n, rotation.world_from_map());
    }
    recorded.cube(map.pixels, rotation.yaw_deg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// Fast vs exact splat under the same rotation (or a whole-pixel yaw): the shares are the
    /// exact splat's pieces rounded to f32 (2^-24 relative), texels are f32 too, and sums run in
    /// another order, so a texel may differ by a few f32 ulps (measured: one, 1.2e-7).
    const ROUNDING_REL: f64 = 5e-7;
    /// A constant map: radiance is Σ w·c / Σ w over the same f32 shares, exact but for f64
    /// rounding, then stored as f32.
    const CONSTANT_REL: f64 = 1e-6;
    /// Total power: the normalisation restores the map's exact power; only the f32 texels and f64
    /// sums remain.
    const POWER_REL: f64 = 1e-6;
    /// Fractional yaw on a map with a 2 x 2-pixel sun, relative L2 over the cube against the
    /// exact splat at the same yaw. Both split cells exactly except for pieces below `finest`
    /// along texel borders, which go whole to the texel of their centre; the two cut different
    /// grids (the world's and the turned map's), so where a border crosses the sun they differ by
    /// the band's share of it. The band is widest (texel_min / 4) where cells are larger than the
    /// smallest texels, here at N = 64. Measured at most 4.7% (N = 64), 1.5% at N = 16 and 32;
    /// the shift without the tables of uneven shares (a plain box filter) is 14.5% off at
    /// N = 64, yaw 12.345.
    const FRACTIONAL_SUN_L2: f64 = 0.08;
    /// The same on a smooth map (no feature smaller than a few texels): the band only moves the
    /// small differences between neighbouring cells. Measured at most 1.6e-4.
    const FRACTIONAL_SMOOTH_L2: f64 = 5e-4;
    /// A pitch splatted at sub-cell centres ([`pitch`]) against the exact splat, relative L2 over
    /// the cube (a 1024 x 512 map): sub-cells go whole to the texel of their centre, a band up to
    /// half the smallest texel wide along texel borders, which holds a share of the sun where a
    /// border crosses it. Measured at most 3.6% at N = 8 to 32 and 5.3% at N = 64 (the recorded
    /// weights of a fractional yaw: 1.5% and 4.7%).
    const PITCH_SUN_L2: f64 = 0.05;
    /// The same at N = 64, where the band is widest against the texels: measured 5.3%.
    const PITCH_SUN_L2_64: f64 = 0.07;
    /// The same on a smooth map. Measured at most 4.3e-4.
    const PITCH_SMOOTH_L2: f64 = 6e-4;
    /// A whole turn of pitch on the smooth map against the recorded gather of its yaw alone at
    /// N = 32 and 64: the band only. Measured at most 4.6e-4; reading the next map cell from the
    /// wrong side makes it 1.05e-3 and 6.0e-4 at the two smaller yaws.
    const WHOLE_TURN_SMOOTH_L2: f64 = 5.5e-4;
    /// A map only a few pixels wide (or one row tall) against its 1024 x 512 twin by the same
    /// recorded weights, relative L2 over the cube: both splats integrate one piecewise-constant function, so they differ only
    /// in the border bands. Measured at most 3.6e-4 (2 x 512 under a fractional yaw).
    const WIDE_TWIN_L2: f64 = 1e-3;
    /// The same narrow maps, fast path against exact splat: measured within 4.1e-9 (a fractional
    /// yaw of cells wider than the tables resolve takes the exact splat itself).
    const NARROW_FAST_L2: f64 = 1e-6;
    /// The fraction of a pixel a yaw leaves (0.18 degrees of a 1000-pixel row, exactly 0.5):
    /// yaw / 360 and the scaling by the width round in f64, a few ulps.
    const YAW_FRACTION: f64 = 1e-9;

    /// A `width` x `height` map: noisy sky, and with `sun` a 2 x 2-pixel source 5000 times
    /// brighter.
    fn test_map(width: usize, height: usize, sun: bool) -> Vec<[f32; 3]> {
        let mut rng = crate::test_support::Rng(0x5eed_0123);
        let mut pixels: Vec<[f32; 3]> = (0..width * height)
            .map(|_| {
                let b = 0.5 + rng.unit();
                [b as f32, (0.8 * b) as f32, (0.3 + 0.5 * rng.unit()) as f32]
            })
            .collect();
        if sun {
            let (x0, y0) = (width * 3 / 10, height * 3 / 10);
            for y in y0..y0 + 2 {
                for x in x0..x0 + 2 {
                    pixels[y * width + x] = [5000.0, 4000.0, 3000.0];
                }
            }
        }
        pixels
    }

    /// A smooth map: low-frequency waves in u and v.
    fn smooth_map(width: usize, height: usize) -> Vec<[f32; 3]> {
        (0..width * height)
            .map(|i| {
                let (u, v) = (
                    (i % width) as f64 / width as f64,
                    (i / width) as f64 / height as f64,
                );
                let a = 1.0 + 0.5 * (TAU * u).sin() * (PI * v).sin() + 0.3 * (3.0 * PI * v).cos();
                [a as f32, (0.5 * a) as f32, (2.0 - a) as f32]
            })
            .collect()
    }

    fn exact(w: usize, h: usize, px: &[[f32; 3]], n: usize, r: EnvRotation) -> CubeMap {
        resample_latlong_exact(map(w, h, px), n, r.world_from_map()).unwrap()
    }

    fn fast(w: usize, h: usize, px: &[[f32; 3]], n: usize, r: EnvRotation) -> CubeMap {
        resample_latlong(map(w, h, px), n, r).unwrap()
    }

    /// The `w` x `h` map of `px`.
    fn map(w: usize, h: usize, px: &[[f32; 3]]) -> LatLong<'_> {
        LatLong::new(w, h, px).unwrap()
    }

    /// The weights recorded for the rotation's pitch, whatever it is.
    fn recorded(w: usize, h: usize, px: &[[f32; 3]], n: usize, r: EnvRotation) -> CubeMap {
        resample_latlong_recorded(map(w, h, px), n, r).unwrap()
    }

    /// Largest per-channel relative difference of two cubes.
    fn worst_rel(a: &CubeMap, b: &CubeMap) -> f64 {
        a.texels
            .iter()
            .zip(&b.texels)
            .flat_map(|(x, y)| (0..3).map(move |c| (x[c] as f64, y[c] as f64)))
            .map(|(x, y)| (x - y).abs() / y.abs().max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max)
    }

    #[test]
    fn unturned_and_pitched_equal_the_exact_splat() {
        // Cells smaller than texels (256 x 128 at N = 8, 16) and larger (at N = 64); widths with
        // quarter turns of even and odd length (256, 300), without (90), and an odd height, so
        // every copy of a cut cell in the build is checked.
        for (w, h) in [(256, 128), (300, 150), (90, 45)] {
            let px = test_map(w, h, true);
            for n in [1, 8, 16, 64] {
                for pitch in [0.0, 20.0, -73.0] {
                    let r = EnvRotation::new(0.0, pitch);
                    let e = worst_rel(&recorded(w, h, &px, n, r), &exact(w, h, &px, n, r));
                    assert!(
                        e <= ROUNDING_REL,
                        "{w} x {h}, N = {n}, pitch {pitch}: {e:e}"
                    );
                }
            }
        }
    }

    #[test]
    fn whole_pixel_yaws_equal_the_exact_splat() {
        // A yaw of k·360/W degrees shifts rows by k pixels: the fast path only renumbers cells,
        // the exact splat turns every corner by R_y; both must agree, which also checks the
        // direction of the shift.
        let (w, h) = (200, 100);
        let px = test_map(w, h, true);
        for k in [1i32, 37, -5, 50, 199] {
            for pitch in [0.0, 20.0] {
                let r = EnvRotation::new(k as f64 * 360.0 / w as f64, pitch);
                let e = worst_rel(&recorded(w, h, &px, 16, r), &exact(w, h, &px, 16, r));
                assert!(e <= ROUNDING_REL, "{k} pixels, pitch {pitch}: {e:e}");
            }
        }
        // And the shift moved something: one pixel off is far from rounding.
        let r = EnvRotation::yaw(37.0 * 360.0 / w as f64);
        let off = EnvRotation::yaw(38.0 * 360.0 / w as f64);
        let e = worst_rel(&recorded(w, h, &px, 16, off), &exact(w, h, &px, 16, r));
        assert!(
            e > 1e3 * ROUNDING_REL,
            "a one-pixel error went unseen: {e:e}"
        );
    }

    #[test]
    fn fractional_yaws_stay_within_the_border_band_of_the_exact_splat() {
        let (w, h) = (512, 256);
        let sun = test_map(w, h, true);
        let smooth = smooth_map(w, h);
        for n in [16, 32, 64] {
            for (yaw, pitch) in [(37.3, 0.0), (100.71, 0.0), (12.345, 0.0), (-61.17, 25.0)] {
                let r = EnvRotation::new(yaw, pitch);
                let e = recorded(w, h, &sun, n, r).relative_l2(&exact(w, h, &sun, n, r));
                assert!(e <= FRACTIONAL_SUN_L2, "sun, N = {n}, {r:?}: {e:e}");
                let e = recorded(w, h, &smooth, n, r).relative_l2(&exact(w, h, &smooth, n, r));
                assert!(e <= FRACTIONAL_SMOOTH_L2, "smooth, N = {n}, {r:?}: {e:e}");
            }
        }
    }

    #[test]
    fn a_pitch_splatted_at_cell_centres_stays_near_the_exact_splat() {
        let (w, h) = (1024, 512);
        let sun = test_map(w, h, true);
        let smooth = smooth_map(w, h);
        for n in [8, 16, 32, 64] {
            assert!(pitch::splats_at_centres(w, h, n));
            let sun_limit = if n <= 32 {
                PITCH_SUN_L2
            } else {
                PITCH_SUN_L2_64
            };
            for (yaw, pitch) in [(0.0, 20.0), (12.345, -73.0), (200.0, 45.5)] {
                let r = EnvRotation::new(yaw, pitch);
                let unpitched = EnvRotation {
                    pitch_deg: 0.0,
                    ..r
                };
                for (px, limit) in [(&sun, sun_limit), (&smooth, PITCH_SMOOTH_L2)] {
                    let got = pitch::splat(map(w, h, px), n, r)
                        .unwrap()
                        .expect("every texel receives a sub-cell");
                    assert_eq!(got.texels, fast(w, h, px, n, r).texels, "the light's path");
                    let want = exact(w, h, px, n, r);
                    let e = got.relative_l2(&want);
                    assert!(e <= limit, "N = {n}, {r:?}: {e:e}");
                    // The pitch turned the map: far more than the band moves.
                    let turned = exact(w, h, px, n, unpitched).relative_l2(&want);
                    assert!(
                        turned > 10.0 * e,
                        "N = {n}, {r:?}: {turned:e} against {e:e}"
                    );
                }
            }
        }
    }

    #[test]
    fn southern_rows_looked_up_through_their_twins_splat_as_looked_up_themselves() {
        let (w, h) = (1024, 512);
        for (px, name) in [(test_map(w, h, true), "sun"), (smooth_map(w, h), "smooth")] {
            for n in [8, 32, 64] {
                for (yaw, pitch) in [(0.0, 20.0), (12.345, -73.0), (200.0, 45.5)] {
                    let r = EnvRotation::new(yaw, pitch);
                    let paired = pitch::splat_rows(map(w, h, &px), n, r, true)
                        .unwrap()
                        .unwrap();
                    let each = pitch::splat_rows(map(w, h, &px), n, r, false)
                        .unwrap()
                        .unwrap();
                    // Only a sub-cell centre within f32 rounding of a texel border may land on
                    // the other side of it in one than in the other (none did below N = 64);
                    // the power kept then moves every texel by rounding.
                    let moved = (paired.texels.iter().zip(&each.texels))
                        .filter(|(a, b)| (0..3).any(|c| (a[c] - b[c]).abs() > 1e-5 * b[c].abs()))
                        .count();
                    let e = paired.relative_l2(&each);
                    assert!(
                        moved <= 64 && e <= 1e-4,
                        "{name}, N = {n}, {r:?}: {moved} texels, {e:e}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_pitch_of_a_whole_turn_splats_the_yawed_map_as_the_recorded_weights_gather_it() {
        // R_x(360°) turns nothing, so what remains is the yaw's shift, its fractions of a cell
        // included, and the band.
        let (w, h) = (1024, 512);
        let smooth = smooth_map(w, h);
        for n in [32, 64] {
            for yaw in [0.1, 12.345, -61.17] {
                let r = EnvRotation::new(yaw, 360.0);
                let got = pitch::splat(map(w, h, &smooth), n, r).unwrap().unwrap();
                let want = recorded(w, h, &smooth, n, EnvRotation::yaw(yaw));
                let e = got.relative_l2(&want);
                assert!(e <= WHOLE_TURN_SMOOTH_L2, "N = {n}, yaw {yaw}: {e:e}");
            }
        }
    }

    #[test]
    fn constant_map_stays_constant_under_any_turn() {
        let value = [1.5f32, 0.25, 3.0];
        for (w, h) in [(64, 32), (300, 150)] {
            let px = vec![value; w * h];
            for n in [1, 4, 32, 256] {
                for (yaw, pitch) in [(0.0, 0.0), (37.3, 0.0), (-112.9, -20.0)] {
                    let r = EnvRotation::new(yaw, pitch);
                    let cube = fast(w, h, &px, n, r);
                    for (j, t) in cube.texels.iter().enumerate() {
                        for c in 0..3 {
                            let e = (t[c] as f64 / value[c] as f64 - 1.0).abs();
                            assert!(
                                e <= CONSTANT_REL,
                                "{w} x {h}, N = {n}, {r:?}: texel {j} {t:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn total_power_is_kept() {
        let (w, h) = (128, 64);
        let px = test_map(w, h, true);
        let env = crate::env::envmap::EnvMap::from_pixels(w, h, px.clone(), "test").unwrap();
        let want = env.power();
        for n in [2, 16, 64] {
            for (yaw, pitch) in [(0.0, 0.0), (37.3, 0.0), (37.3, -20.0)] {
                let r = EnvRotation::new(yaw, pitch);
                let got = fast(w, h, &px, n, r).power();
                for c in 0..3 {
                    let e = (got[c] / want[c] - 1.0).abs();
                    assert!(e <= POWER_REL, "N = {n}, {r:?}, channel {c}: {e:e}");
                }
            }
        }
    }

    /// A map only a few pixels wide (or one row tall) against its wide twin: the same radiance
    /// function drawn on a 1024 x 512 grid. Both splats integrate one piecewise-constant function
    /// over each texel, so they differ only in the border bands. Measured: at most 3.6e-4 relative
    /// L2 (2 x 512 under a fractional yaw), and the fast path within 4.1e-9 of the exact splat
    /// (a fractional yaw of cells wider than the tables resolve takes the exact splat itself).
    #[test]
    fn narrow_and_flat_maps_resample_as_their_wide_twins() {
        let value = |u: f64, v: f64| {
            let a = 1.0 + 0.6 * (PI * v).cos() + 0.3 * (TAU * u).sin();
            [a as f32, (0.5 * a) as f32, (2.0 - a) as f32]
        };
        let grid = |w: usize, h: usize| -> Vec<[f32; 3]> {
            (0..w * h)
                .map(|i| {
                    value(
                        ((i % w) as f64 + 0.5) / w as f64,
                        ((i / w) as f64 + 0.5) / h as f64,
                    )
                })
                .collect()
        };
        // The twin samples each of its pixels at the centre of the narrow map's cell it lies in.
        let twin = |w: usize, h: usize| -> Vec<[f32; 3]> {
            let (tw, th) = (1024, 512);
            (0..tw * th)
                .map(|i| {
                    let (x, y) = ((i % tw) * w / tw, (i / tw) * h / th);
                    value((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64)
                })
                .collect()
        };
        for (w, h) in [(1, 512), (2, 512), (1024, 1), (1, 1)] {
            let (px, wide) = (grid(w, h), twin(w, h));
            for n in [32, 64] {
                for r in [EnvRotation::default(), EnvRotation::new(37.3, -20.0)] {
                    let got = fast(w, h, &px, n, r);
                    let e = got.relative_l2(&recorded(1024, 512, &wide, n, r));
                    assert!(
                        e < WIDE_TWIN_L2,
                        "{w} x {h}, N = {n}, {r:?}: {e:e} from the wide twin"
                    );
                    let x = recorded(w, h, &px, n, r).relative_l2(&exact(w, h, &px, n, r));
                    assert!(
                        x < NARROW_FAST_L2,
                        "{w} x {h}, N = {n}, {r:?}: {x:e} from the exact splat"
                    );
                }
            }
        }
    }

    #[test]
    fn yaw_shift_follows_the_convention() {
        // world = R_y(yaw)·map: the map's u lands at u − yaw/360, so world cell x shows map
        // cell x + W·yaw/360.
        let w = 1024;
        assert_eq!(yaw_shift(w, 0.0).unwrap(), (0, 0.0));
        assert_eq!(yaw_shift(w, 360.0).unwrap(), (0, 0.0));
        assert_eq!(yaw_shift(w, 37.0 * 360.0 / 1024.0).unwrap(), (37, 0.0));
        assert_eq!(yaw_shift(w, -90.0).unwrap(), (768, 0.0));
        assert_eq!(yaw_shift(w, 90.0 + 720.0).unwrap(), (256, 0.0));
        let (n, f) = yaw_shift(1000, 0.18).unwrap();
        assert_eq!(n, 0);
        assert!((f - 0.5).abs() < YAW_FRACTION, "{f}");
        // Whole pixels given in degrees that do not divide evenly still snap.
        assert_eq!(yaw_shift(1000, 37.0 * 0.36).unwrap(), (37, 0.0));
        for bad in [f64::NAN, f64::INFINITY] {
            let e = yaw_shift(w, bad).unwrap_err().to_string();
            assert!(e.contains("yaw") && e.contains(&bad.to_string()), "{e}");
        }
    }

    #[test]
    fn weights_are_cached_by_size_and_pitch() {
        // A size no other test uses, so parallel tests do not evict it between the calls.
        let (w, h) = (24, 12);
        let a = weights(w, h, 4, 0.0).unwrap();
        let b = weights(w, h, 4, -0.0).unwrap();
        assert!(Arc::ptr_eq(&a, &b), "pitch -0 is pitch 0");
        let c = weights(w, h, 4, 10.0).unwrap();
        assert!(!Arc::ptr_eq(&a, &c));
        assert!(!Arc::ptr_eq(&a, &weights(w, h, 8, 0.0).unwrap()));
        assert!(Arc::ptr_eq(&c, &weights(w, h, 4, 10.0).unwrap()));
        let e = weights(w, h, 4, f64::NAN).unwrap_err().to_string();
        assert!(e.contains("pitch"), "{e}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let px = vec![[1.0f32; 3]; 8 * 4];
        let e = resample_latlong(map(8, 4, &px), 3, EnvRotation::default()).unwrap_err();
        assert!(e.to_string().contains("power of two"), "{e}");
        let e = LatLong::new(8, 5, &px).unwrap_err();
        assert!(e.to_string().contains("pixels"), "{e}");
        // A map built without `new` is checked by each resampler.
        for (w, h) in [(8, 5), (0, 4)] {
            let bad = LatLong {
                width: w,
                height: h,
                pixels: &px,
            };
            let r = EnvRotation::new(10.0, 20.0);
            for e in [
                resample_latlong(bad, 4, r).unwrap_err(),
                resample_latlong_recorded(bad, 4, r).unwrap_err(),
                resample_latlong_exact(bad, 4, r.world_from_map()).unwrap_err(),
            ] {
                assert!(e.to_string().contains("pixels"), "{w} x {h}: {e}");
            }
        }
        let e = resample_latlong(map(8, 4, &px), 4, EnvRotation::yaw(f64::NAN)).unwrap_err();
        assert!(e.to_string().contains("yaw"), "{e}");
        let w = weights(8, 4, 4, 0.0).unwrap();
        let e = w.cube(&px[1..], 0.0).unwrap_err().to_string();
        assert!(e.contains("8 x 4 needs 32 pixels, got 31"), "{e}");
    }
}
