//! The light that reaches points in and around a medium, per texel light: what the medium's
//! single scattering and the bake's interreflections through it (`--bounces` with a `[medium]`)
//! read.
//!
//! A point `x` in the medium sees texel `t` through `T(x, ω_t) · V(x, ω_t)`: the transmittance
//! out of the medium and whether a surface blocks the way (a ground under a cloud hides the
//! lower sky from it). Both are tabulated once per bake at the texel centres ω_t:
//! - **V** on a lattice of every s-th voxel centre, s the smallest stride whose lattice takes at
//!   most [`MAX_VISIBILITY_RAYS`] shadow rays, trilinear between nodes. Surfaces around a medium
//!   change what its points see slowly, and a texel no surface blocks from any node is skipped.
//! - **T** at every voxel centre, from one sweep of the grid per texel
//!   ([`Sweeper::transmittance`]), in a byte (absolute error at most 0.002), voxel-major so that a
//!   path vertex in the medium reads eight contiguous rows. Only a bake with bounces needs it.
//!
//! A surface point reads T where each texel's ray from it enters the medium's box.

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use crate::error::{PrtError, Result};
use crate::math::cubemap::{texel_count, texel_dirs};
use crate::math::sampling::TexelSamples;
use crate::medium::sweep::Sweeper;
use crate::medium::{Medium, henyey_greenstein, ray_box};
use crate::scene::trace::Tracer;

/// Most shadow rays the surfaces' visibility lattice may take.
pub const MAX_VISIBILITY_RAYS: usize = 16 << 20;
/// Most bytes the transmittance table may take.
pub const MAX_TABLE_BYTES: u64 = 2 << 30;
/// Texels swept at once while the table is filled.
const CHUNK: usize = 256;

/// Bytes [`MediumLight::build`] takes at its peak for `voxels` voxels, `texels` texels and a
/// visibility lattice of `nodes` nodes: V per node and texel (4 bytes as f32, 1 as a byte, 1 in
/// the cells' table), and with the table, T (a byte per voxel and texel), the chunk of rows swept
/// before they are copied in (a byte per voxel and texel of the chunk), the sweeper's three
/// layouts of σ and indices (24 bytes a voxel) and one transmittance grid per thread (4 bytes a
/// voxel). Counted from the buffers, not measured.
fn peak_bytes(voxels: u64, texels: u64, nodes: u64, table: bool) -> u64 {
    let visibility = nodes.saturating_mul(texels).saturating_mul(6);
    if !table {
        return visibility;
    }
    let threads = rayon::current_num_threads() as u64;
    let per_voxel = texels + texels.min(CHUNK as u64) + 24 + 4 * threads;
    visibility.saturating_add(voxels.saturating_mul(per_voxel))
}

/// Where in a medium a texel is seen past the surfaces, at the visibility lattice's nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seen {
    /// From every node: V is 1 throughout.
    All,
    /// From no node: V is 0 throughout.
    Nowhere,
    /// From some nodes.
    Partly,
}

/// A point's trilinear cell in a lattice: the indices of its eight nodes and their weights.
#[derive(Clone, Copy, Debug)]
pub struct Corners {
    index: [u32; 8],
    weight: [f32; 8],
}

/// Every `stride`-th voxel centre of a grid of `dims` voxels along each axis, the last one
/// always included.
#[derive(Clone, Copy, Debug)]
struct Lattice {
    dims: [usize; 3],
    stride: usize,
    nodes: [usize; 3],
}

impl Lattice {
    fn new(dims: [usize; 3], stride: usize) -> Lattice {
        Lattice {
            dims,
            stride,
            nodes: dims.map(|d| (d.max(1) - 1).div_ceil(stride) + 1),
        }
    }

    fn count(&self) -> usize {
        self.nodes.iter().product()
    }

    /// The voxel index of node `k` along an axis of `dim` voxels.
    fn voxel(&self, k: usize, dim: usize) -> usize {
        (k * self.stride).min(dim.max(1) - 1)
    }

    /// The voxel centre of node `i` (x fastest) in voxel coordinates.
    fn node_voxel(&self, i: usize) -> [usize; 3] {
        let [nx, ny, _] = self.nodes;
        let k = [i % nx, (i / nx) % ny, i / (nx * ny)];
        std::array::from_fn(|a| self.voxel(k[a], self.dims[a]))
    }

    /// The cell of the point at voxel coordinates `u` (voxel centres at whole numbers), clamped
    /// to the lattice: its first node and the fractions towards the next along x, y and z.
    fn point(&self, u: Vec3) -> LatticePoint {
        let axis = |a: usize| -> (usize, f32) {
            let (dim, n) = (self.dims[a], self.nodes[a]);
            if n < 2 {
                return (0, 0.0);
            }
            let v = u[a].clamp(0.0, (dim - 1) as f32);
            let k = ((v / self.stride as f32) as usize).min(n - 2);
            let (p0, p1) = (self.voxel(k, dim) as f32, self.voxel(k + 1, dim) as f32);
            (k, ((v - p0) / (p1 - p0)).clamp(0.0, 1.0))
        };
        let ((ix, fx), (iy, fy), (iz, fz)) = (axis(0), axis(1), axis(2));
        let [nx, ny, _] = self.nodes;
        LatticePoint {
            base: ((iz * ny + iy) * nx + ix) as u32,
            frac: [fx, fy, fz],
        }
    }

    /// Steps from a node to the next along x, y and z (0 along an axis of one node).
    fn steps(&self) -> [usize; 3] {
        let [nx, ny, nz] = self.nodes;
        [
            usize::from(nx > 1),
            if ny > 1 { nx } else { 0 },
            if nz > 1 { nx * ny } else { 0 },
        ]
    }

    /// The eight nodes and weights of the cell of the point at voxel coordinates `u`.
    fn corners(&self, u: Vec3) -> Corners {
        let p = self.point(u);
        let [sx, sy, sz] = self.steps();
        let mut c = Corners {
            index: [0; 8],
            weight: [0.0; 8],
        };
        for corner in 0..8 {
            let (bx, by, bz) = (corner & 1, corner >> 1 & 1, corner >> 2 & 1);
            let w = |bit: usize, f: f32| if bit == 1 { f } else { 1.0 - f };
            c.index[corner] = (p.base as usize + bx * sx + by * sy + bz * sz) as u32;
            c.weight[corner] = w(bx, p.frac[0]) * w(by, p.frac[1]) * w(bz, p.frac[2]);
        }
        c
    }
}

/// A point located in a lattice: its cell's first node and the fractions along x, y and z.
#[derive(Clone, Copy, Debug)]
pub struct LatticePoint {
    base: u32,
    frac: [f32; 3],
}

/// What a medium's points see of every texel light (see the module docs).
pub struct MediumLight {
    texels: usize,
    centres: Vec<Vec3>,
    /// The first voxel centre and the spacing of centres.
    first: Vec3,
    cell: Vec3,
    /// The medium's box of support.
    lo: Vec3,
    hi: Vec3,
    voxels: Lattice,
    visible: Lattice,
    /// V per texel, then node: 0 or 1.
    visible_by_texel: Vec<f32>,
    /// V per node, then texel.
    visible_by_node: Vec<u8>,
    /// Per texel, then cell (by its first node): 0 or 1 where the cell's eight nodes agree, 2
    /// where they differ (the trilinear blend is needed only there).
    cells: Vec<u8>,
    /// Whether every node sees texel t, or none.
    open: Vec<Seen>,
    /// T per voxel, then texel, in 255ths; empty without the table.
    transmittance: Vec<u8>,
}

impl MediumLight {
    /// Tabulates what `medium`'s points see of the 6 N² texels of a cube of size `n` among the
    /// surfaces of `tracer`: the visibility always, the transmittance table when `table`. Calls
    /// `progress(steps done, steps)`.
    pub fn build(
        medium: &Medium,
        tracer: &Tracer,
        n: usize,
        table: bool,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<MediumLight> {
        let texels = texel_count(n);
        let grid = &medium.grid;
        let voxels = Lattice::new(grid.dims, 1);
        if table {
            let bytes = voxels.count() as u64 * texels as u64;
            if bytes > MAX_TABLE_BYTES {
                return Err(PrtError::invalid(
                    "medium",
                    format!(
                        "the transmittance table of {} voxels at N = {n} for --bounces needs {} \
                         MiB (at most {} MiB): bake with a smaller cube or a coarser medium",
                        voxels.count(),
                        bytes >> 20,
                        MAX_TABLE_BYTES >> 20
                    ),
                ));
            }
        }
        let stride = (1..)
            .find(|&s| Lattice::new(grid.dims, s).count() * texels <= MAX_VISIBILITY_RAYS)
            .unwrap_or(usize::MAX);
        let visible = Lattice::new(grid.dims, stride);
        // Every table's memory, checked before any work.
        let field = "--cube/medium.resolution";
        let with_table = match table {
            true => ", with the transmittance table for --bounces,",
            false => "",
        };
        let what = format!(
            "what the medium's {} voxels see of the {texels} texels at N = {n}{with_table}",
            voxels.count()
        );
        let peak = peak_bytes(
            voxels.count() as u64,
            texels as u64,
            visible.count() as u64,
            table,
        );
        crate::files::check_memory(field, &what, peak)?;
        let centres: Vec<Vec3> = texel_dirs(n).iter().map(|d| d.as_vec3()).collect();
        let cell = grid.cell();
        let first = grid.min + cell * 0.5;
        let at = |v: [usize; 3]| first + cell * Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
        let steps = if table { 2 * texels } else { texels };
        let done = AtomicUsize::new(0);
        let step = |count: usize| {
            let d = done.fetch_add(count, Ordering::Relaxed) + count;
            if d.is_multiple_of(64) || d == steps {
                progress(d, steps);
            }
        };
        // The surfaces' visibility, texel by texel.
        let nodes = visible.count();
        let mut visible_by_texel = crate::files::try_filled(field, &what, texels * nodes, 0.0f32)?;
        visible_by_texel
            .par_chunks_mut(nodes)
            .zip(&centres)
            .for_each(|(row, &dir)| {
                for (i, v) in row.iter_mut().enumerate() {
                    *v = f32::from(!tracer.occluded(at(visible.node_voxel(i)), dir, f32::INFINITY));
                }
                step(1);
            });
        let open = visible_by_texel
            .chunks(nodes)
            .map(
                |row| match (row.iter().all(|&v| v == 1.0), row.iter().all(|&v| v == 0.0)) {
                    (true, _) => Seen::All,
                    (_, true) => Seen::Nowhere,
                    _ => Seen::Partly,
                },
            )
            .collect();
        let [sx, sy, sz] = visible.steps();
        let cells = visible_by_texel
            .par_chunks(nodes)
            .flat_map_iter(|row| {
                (0..nodes).map(move |i| {
                    let corner = |k: usize| {
                        let j = i + (k & 1) * sx + (k >> 1 & 1) * sy + (k >> 2 & 1) * sz;
                        row.get(j).copied().unwrap_or(row[i])
                    };
                    let first = corner(0);
                    match (1..8).all(|k| corner(k) == first) {
                        true => first as u8,
                        false => 2,
                    }
                })
            })
            .collect();
        let mut visible_by_node = crate::files::try_filled(field, &what, nodes * texels, 0u8)?;
        visible_by_node
            .par_chunks_mut(texels)
            .enumerate()
            .for_each(|(i, row)| {
                for (t, v) in row.iter_mut().enumerate() {
                    *v = visible_by_texel[t * nodes + i] as u8;
                }
            });
        let transmittance = match table {
            true => transmittance_table(medium, &centres, [field, &what], &step)?,
            false => Vec::new(),
        };
        let (lo, hi) = grid.support();
        Ok(MediumLight {
            texels,
            centres,
            first,
            cell,
            lo,
            hi,
            voxels,
            visible,
            visible_by_texel,
            visible_by_node,
            cells,
            open,
            transmittance,
        })
    }

    /// `p` in voxel coordinates (voxel centres at whole numbers).
    fn voxel_coords(&self, p: Vec3) -> Vec3 {
        (p - self.first) / self.cell
    }

    /// `p` located in the visibility lattice, for [`MediumLight::visibility`].
    pub fn locate(&self, p: Vec3) -> LatticePoint {
        self.visible.point(self.voxel_coords(p))
    }

    /// Where in the medium texel `t` is seen past the surfaces.
    pub fn seen(&self, t: usize) -> Seen {
        self.open[t]
    }

    /// V towards texel `t` at a point located by [`MediumLight::locate`].
    #[inline]
    pub fn visibility(&self, t: usize, at: &LatticePoint) -> f32 {
        let count = self.visible.count();
        match self.cells[t * count + at.base as usize] {
            0 => return 0.0,
            1 => return 1.0,
            _ => {}
        }
        let row = &self.visible_by_texel[t * count..(t + 1) * count];
        let [sx, sy, sz] = self.visible.steps();
        let i = at.base as usize;
        let [fx, fy, fz] = at.frac;
        let lerp = |a: f32, b: f32, f: f32| a + (b - a) * f;
        let x = |j: usize| lerp(row[j], row[j + sx], fx);
        let y = |j: usize| lerp(x(j), x(j + sy), fy);
        lerp(y(i), y(i + sz), fz)
    }

    /// Whether the transmittance table was built.
    pub fn has_table(&self) -> bool {
        !self.transmittance.is_empty()
    }

    /// Blends the rows (`texels` bytes each) of a lattice's corners into `out`, scaled by
    /// `scale`, multiplying what `out` holds when `multiply`.
    fn blend(
        rows: &[u8],
        texels: usize,
        at: &Corners,
        scale: f32,
        out: &mut [f32],
        multiply: bool,
    ) {
        let mut acc = vec![0.0f32; texels];
        for (&i, &w) in at.index.iter().zip(&at.weight) {
            if w == 0.0 {
                continue;
            }
            let row = &rows[i as usize * texels..(i as usize + 1) * texels];
            let w = w * scale;
            for (a, &b) in acc.iter_mut().zip(row) {
                *a += w * b as f32;
            }
        }
        if multiply {
            out.iter_mut().zip(&acc).for_each(|(o, a)| *o *= a);
        } else {
            out.copy_from_slice(&acc);
        }
    }

    /// `T · V` towards every texel at the medium point `p` (needs the table).
    pub fn light_at(&self, p: Vec3, out: &mut [f32]) {
        let u = self.voxel_coords(p);
        let (t, v) = (self.voxels.corners(u), self.visible.corners(u));
        Self::blend(
            &self.transmittance,
            self.texels,
            &t,
            1.0 / 255.0,
            out,
            false,
        );
        Self::blend(&self.visible_by_node, self.texels, &v, 1.0, out, true);
    }

    /// Per texel, what a path vertex in the medium at `p`, reached travelling along `dir`,
    /// sends on per unit albedo: `Σ p(ω·dir) Ω` over the texel's samples times `T · V` (needs
    /// the table).
    pub fn vertex_weights(&self, p: Vec3, dir: Vec3, g: f32, samples: &TexelSamples) -> Vec<f32> {
        let mut light = vec![0.0f32; self.texels];
        self.light_at(p, &mut light);
        let m = samples.per_texel;
        for (j, l) in light.iter_mut().enumerate() {
            if *l == 0.0 {
                continue;
            }
            let phase: f32 = (j * m..(j + 1) * m)
                .map(|s| henyey_greenstein(g, samples.dirs[s].dot(dir)) * samples.weights[s])
                .sum();
            *l *= phase;
        }
        light
    }

    /// The transmittance from the surface point `p` through the medium towards every texel
    /// (needs the table), in 255ths like the table: T where the texel's ray from `p` enters the
    /// medium's box, 1 where it misses the box.
    pub fn surface_transmittance(&self, p: Vec3) -> Vec<u8> {
        let inside = p.cmpge(self.lo).all() && p.cmple(self.hi).all();
        let byte = |v: f32| (v * 255.0).round() as u8;
        (0..self.texels)
            .map(|t| {
                let dir = self.centres[t];
                let at = if inside {
                    p
                } else {
                    match ray_box(p, dir, self.lo, self.hi) {
                        Some((t0, _)) => p + dir * t0.max(0.0),
                        None => return byte(1.0),
                    }
                };
                let c = self.voxels.corners(self.voxel_coords(at));
                let sum: f32 = c
                    .index
                    .iter()
                    .zip(&c.weight)
                    .map(|(&i, &w)| w * self.transmittance[i as usize * self.texels + t] as f32)
                    .sum();
                byte(sum / 255.0)
            })
            .collect()
    }

    /// Bytes the tables take.
    pub fn bytes(&self) -> usize {
        self.transmittance.len() + self.visible_by_node.len() + self.visible_by_texel.len() * 4
    }
}

/// Each voxel's transmittance towards every texel's centre, `[voxel, texel]` as bytes (1 = 255),
/// calling `step(1)` per texel; memory checked as `[field, what]`.
fn transmittance_table(
    medium: &Medium,
    centres: &[Vec3],
    [field, what]: [&str; 2],
    step: &(dyn Fn(usize) + Sync),
) -> Result<Vec<u8>> {
    let grid = &medium.grid;
    let (count, texels) = (Lattice::new(grid.dims, 1).count(), centres.len());
    let mut transmittance = crate::files::try_filled(field, what, count * texels, 0u8)?;
    let sweeper = Sweeper::new(medium);
    let [nx, ny, _] = grid.dims;
    for t0 in (0..texels).step_by(CHUNK) {
        let chunk: Vec<Vec<u8>> = (t0..(t0 + CHUNK).min(texels))
            .into_par_iter()
            .map(|t| {
                let grid = sweeper.transmittance(centres[t]);
                let bytes = (0..count)
                    .map(|v| {
                        let tr = grid.voxel(v % nx, (v / nx) % ny, v / (nx * ny));
                        (tr.clamp(0.0, 1.0) * 255.0).round() as u8
                    })
                    .collect();
                step(1);
                bytes
            })
            .collect();
        transmittance
            .par_chunks_mut(texels)
            .enumerate()
            .for_each(|(v, row)| {
                for (k, bytes) in chunk.iter().enumerate() {
                    row[t0 + k] = bytes[v];
                }
            });
    }
    Ok(transmittance)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_corners_interpolate_linearly_and_clamp() {
        let l = Lattice::new([7, 1, 5], 3);
        assert_eq!(l.nodes, [3, 1, 3]);
        // Nodes at voxels 0, 3, 6 along x and 0, 3, 4 along z (the last one nearer).
        let c = l.corners(Vec3::new(4.5, 0.0, 3.5));
        let value = |f: &dyn Fn([usize; 3]) -> f32| -> f32 {
            c.index
                .iter()
                .zip(&c.weight)
                .map(|(&i, &w)| w * f(l.node_voxel(i as usize)))
                .sum()
        };
        // A linear function is reproduced exactly inside the lattice.
        let lin = |v: [usize; 3]| 2.0 * v[0] as f32 - v[2] as f32 + 1.0;
        assert!((value(&lin) - (2.0 * 4.5 - 3.5 + 1.0)).abs() < 1e-5);
        assert!((c.weight.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        // Outside, the edge value.
        let c = l.corners(Vec3::new(-3.0, 9.0, 40.0));
        let v: f32 = c
            .index
            .iter()
            .zip(&c.weight)
            .map(|(&i, &w)| w * lin(l.node_voxel(i as usize)))
            .sum();
        assert!((v - (0.0 - 4.0 + 1.0)).abs() < 1e-5, "{v}");
    }
}
