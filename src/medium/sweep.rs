//! Optical depth of a whole density grid towards one direction at a time, swept slice by slice
//! from the side the light comes from (see [`crate::volume`] for how the self-transfer bake and
//! the per-pixel medium rows use it). Each voxel takes the optical depth of the point one slice
//! upstream (bilinear in the previous slice, the same weights for the whole slice) plus the
//! trapezoid of the density over that step.
//!
//! The same sweep also gathers what a source inside the medium sends along a direction
//! ([`Sweeper::gather`], for scattering of higher orders): the short-characteristics scheme of
//! radiative transfer, where each voxel takes the gathered radiance of its upstream point,
//! attenuated over the step, plus the step's own emission with the source linear in optical
//! depth between the two ends.

use glam::Vec3;

use super::Medium;

/// The grid in the layout of one sweep axis `a`: slices along `a`, rows along `b`, `c` fastest.
struct AxisLayout {
    axes: [usize; 3],
    n: [usize; 3],
    /// sigma_t at the voxel centres, in this layout.
    sigma: Vec<f32>,
    /// Local index of every voxel, by global index.
    local_of_global: Vec<u32>,
}

/// Optical depth of a whole grid towards one direction at a time (see the module docs).
pub struct Sweeper {
    dims: [usize; 3],
    cell: Vec3,
    min: Vec3,
    layouts: [AxisLayout; 3],
}

impl Sweeper {
    /// Local index of every voxel in the layout of sweep axis `axis`, by global index: where
    /// [`Sweeper::sweep`] writes the voxel `(z·ny + y)·nx + x`.
    pub fn local_of_global(&self, axis: usize) -> &[u32] {
        &self.layouts[axis].local_of_global
    }
}

/// Optical depth at voxel centres towards one direction, in the layout of its sweep axis.
pub struct DepthGrid<'a> {
    sweeper: &'a Sweeper,
    axis: usize,
    /// Per voxel, in the layout of the sweep axis: the optical depth, or the transmittance
    /// `exp(−tau)` for [`Sweeper::transmittance`].
    pub tau: Vec<f32>,
}

impl Sweeper {
    /// Lays out `medium`'s extinction at the voxel centres along each of the three sweep axes.
    pub fn new(medium: &Medium) -> Sweeper {
        let g = &medium.grid;
        let dims = g.dims;
        let layouts = [0usize, 1, 2].map(|a| {
            let (b, c) = match a {
                0 => (1, 2),
                1 => (0, 2),
                _ => (0, 1),
            };
            let n = [dims[a], dims[b], dims[c]];
            let mut sigma = vec![0.0f32; g.voxel_count()];
            let mut local_of_global = vec![0u32; g.voxel_count()];
            for z in 0..dims[2] {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        let p = [x, y, z];
                        let global = (z * dims[1] + y) * dims[0] + x;
                        let local = (p[a] * n[1] + p[b]) * n[2] + p[c];
                        sigma[local] = medium.extinction * g.data[global];
                        local_of_global[global] = local as u32;
                    }
                }
            }
            AxisLayout {
                axes: [a, b, c],
                n,
                sigma,
                local_of_global,
            }
        });
        Sweeper {
            dims,
            cell: g.cell(),
            min: g.min,
            layouts,
        }
    }

    /// The sweep axis of `dir`: its largest component.
    pub fn axis_of(dir: Vec3) -> usize {
        let a = dir.abs();
        if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        }
    }

    /// Optical depth from every voxel centre out of the medium along `dir` (unit).
    pub fn depth(&self, dir: Vec3) -> DepthGrid<'_> {
        let axis = Self::axis_of(dir);
        let mut tau = vec![0.0f32; self.layouts[axis].sigma.len()];
        self.sweep(dir, &mut tau, |t| t);
        DepthGrid {
            sweeper: self,
            axis,
            tau,
        }
    }

    /// Transmittance `exp(−tau)` from every voxel centre out of the medium along `dir`.
    pub fn transmittance(&self, dir: Vec3) -> DepthGrid<'_> {
        let axis = Self::axis_of(dir);
        let mut tau = vec![0.0f32; self.layouts[axis].sigma.len()];
        self.sweep(dir, &mut tau, |t| (-t).exp());
        DepthGrid {
            sweeper: self,
            axis,
            tau,
        }
    }

    /// Where `p` falls in each axis layout: the base index of its trilinear cell and the
    /// fractions along (a, b, c), clamped to the edge voxels. Locating march samples once makes
    /// every later read of a grid ([`DepthGrid::at_located`]) eight loads and seven lerps.
    pub fn locate(&self, p: Vec3) -> [Located; 3] {
        let u = (p - self.min) / self.cell - 0.5;
        std::array::from_fn(|axis| {
            let layout = &self.layouts[axis];
            let [a, b, c] = layout.axes;
            let [na, nb, nc] = layout.n;
            let coord = |v: f32, n: usize| -> (usize, f32) {
                if n < 2 {
                    return (0, 0.0);
                }
                let v = v.clamp(0.0, (n - 1) as f32);
                let i = (v as usize).min(n - 2);
                (i, v - i as f32)
            };
            let (ia, fa) = coord(u[a], na);
            let (ib, fb) = coord(u[b], nb);
            let (ic, fc) = coord(u[c], nc);
            Located {
                base: ((ia * nb + ib) * nc + ic) as u32,
                frac: [fa, fb, fc],
            }
        })
    }

    /// Sweeps `dir`, writing `f(tau)` per voxel into `out` (the layout of `dir`'s axis).
    pub fn sweep(&self, dir: Vec3, out: &mut [f32], f: impl Fn(f32) -> f32) {
        let (layout, st) = self.stepping(dir);
        let [_, nb, nc] = st.n;
        let (h, wb, wc, ib, ic, pad, pc) = (st.h, st.wb, st.wc, st.ib, st.ic, st.pad, st.pc);
        let mut up = vec![0.0f32; st.padded()];
        let mut next = vec![0.0f32; st.padded()];
        let hh = 0.5 * h;
        for s in st.slices() {
            let sig = &layout.sigma[s * nb * nc..(s + 1) * nb * nc];
            let dst = &mut out[s * nb * nc..(s + 1) * nb * nc];
            for jb in 0..nb {
                let r0 = (jb as isize + pad as isize + ib) as usize;
                let (row0, row1) = (
                    &up[r0 * pc..(r0 + 1) * pc],
                    &up[(r0 + 1) * pc..(r0 + 2) * pc],
                );
                let base = (pad as isize + ic) as usize;
                let next_row = &mut next[(jb + pad) * pc + pad..(jb + pad) * pc + pad + nc];
                for jc in 0..nc {
                    let k = base + jc;
                    let u = (1.0 - wb) * ((1.0 - wc) * row0[k] + wc * row0[k + 1])
                        + wb * ((1.0 - wc) * row1[k] + wc * row1[k + 1]);
                    let sg = hh * sig[jb * nc + jc];
                    let tau = u + sg;
                    next_row[jc] = tau + sg;
                    dst[jb * nc + jc] = f(tau);
                }
            }
            std::mem::swap(&mut up, &mut next);
        }
    }
}

impl Sweeper {
    /// Voxels in the layout of `dir`'s sweep axis (every layout holds them all).
    pub fn voxel_count(&self) -> usize {
        self.dims.iter().product()
    }

    /// Gathers towards every voxel centre `x` what `channels` sources send along `−dir`:
    /// `I(x) = ∫₀^∞ e^(−tau(x, x + s·dir)) sigma_t(x + s·dir) S(x + s·dir) ds`, the radiance
    /// arriving at `x` from direction `dir` (unit) emitted by the source `S` (per unit optical
    /// depth). `source` and `out` are in the layout of `dir`'s axis
    /// ([`Sweeper::local_of_global`]), `channels` values per voxel.
    ///
    /// Each voxel takes the upstream point's `I`, `S` and `sigma_t` (bilinear in the previous
    /// slice; outside the grid `I` and `sigma_t` are zero and `S` is the voxel's own), and over the step of optical depth `Δ = h (sigma_x +
    /// sigma_up) / 2` adds `e^−Δ I_up + S_x (1 − (1 − e^−Δ)/Δ) + S_up ((1 − e^−Δ)/Δ − e^−Δ)`,
    /// the exact integral for a source linear in optical depth. It steps through the slices as
    /// [`Sweeper::sweep`] does, a twin by design: that one carries one optical depth a voxel,
    /// this one `channels` values and their sources, in a loop of its own for speed.
    pub fn gather(&self, dir: Vec3, channels: usize, source: &[f32], out: &mut [f32]) {
        let (layout, st) = self.stepping(dir);
        let [na, nb, nc] = st.n;
        let (h, wb, wc, ib, ic, pad, pc) = (st.h, st.wb, st.wc, st.ib, st.ic, st.pad, st.pc);
        let ch = channels;
        debug_assert_eq!(source.len(), na * nb * nc * ch);
        debug_assert_eq!(out.len(), na * nb * nc * ch);
        // The previous slice, padded with zeros: sigma_t, then source and gathered values.
        let mut sig_up = vec![0.0f32; st.padded()];
        // 1 inside the grid: the source is known there, and the padding takes the nearest.
        let mut inside = vec![0.0f32; st.padded()];
        let mut src_up = vec![0.0f32; st.padded() * ch];
        let mut out_up = vec![0.0f32; st.padded() * ch];
        let weights = [
            (0usize, 0usize, (1.0 - wb) * (1.0 - wc)),
            (0, 1, (1.0 - wb) * wc),
            (1, 0, wb * (1.0 - wc)),
            (1, 1, wb * wc),
        ];
        let mut s_up = vec![0.0f32; ch];
        let mut i_up = vec![0.0f32; ch];
        for s in st.slices() {
            let plane = nb * nc;
            let sig = &layout.sigma[s * plane..(s + 1) * plane];
            let src = &source[s * plane * ch..(s + 1) * plane * ch];
            let dst = &mut out[s * plane * ch..(s + 1) * plane * ch];
            for jb in 0..nb {
                let r0 = (jb as isize + pad as isize + ib) as usize;
                let base = (pad as isize + ic) as usize;
                for jc in 0..nc {
                    let k = base + jc;
                    let (mut sigma_up, mut known) = (0.0f32, 0.0f32);
                    s_up.fill(0.0);
                    i_up.fill(0.0);
                    for &(db, dc, w) in &weights {
                        if w == 0.0 {
                            continue;
                        }
                        let q = (r0 + db) * pc + k + dc;
                        sigma_up += w * sig_up[q];
                        known += w * inside[q];
                        for ((su, iu), (sv, ov)) in s_up.iter_mut().zip(i_up.iter_mut()).zip(
                            src_up[q * ch..(q + 1) * ch]
                                .iter()
                                .zip(&out_up[q * ch..(q + 1) * ch]),
                        ) {
                            *su += w * sv;
                            *iu += w * ov;
                        }
                    }
                    let v = jb * nc + jc;
                    // Outside the grid the source is the nearest known one (the density, and
                    // so the emission, falls to zero there anyway).
                    if known < 1.0 {
                        let own = &src[v * ch..(v + 1) * ch];
                        for (su, sv) in s_up.iter_mut().zip(own) {
                            *su += (1.0 - known) * sv;
                        }
                    }
                    let delta = 0.5 * h * (sig[v] + sigma_up);
                    let e = (-delta).exp();
                    let (wx, wu) = if delta < 1e-3 {
                        (delta * (0.5 - delta / 6.0), delta * (0.5 - delta / 3.0))
                    } else {
                        let q = (1.0 - e) / delta;
                        (1.0 - q, q - e)
                    };
                    for j in 0..ch {
                        dst[v * ch + j] = e * i_up[j] + wx * src[v * ch + j] + wu * s_up[j];
                    }
                }
            }
            // This slice becomes the upstream one.
            for jb in 0..nb {
                let row = (jb + pad) * pc + pad;
                sig_up[row..row + nc].copy_from_slice(&sig[jb * nc..(jb + 1) * nc]);
                inside[row..row + nc].fill(1.0);
                src_up[row * ch..(row + nc) * ch]
                    .copy_from_slice(&src[jb * nc * ch..(jb + 1) * nc * ch]);
                out_up[row * ch..(row + nc) * ch]
                    .copy_from_slice(&dst[jb * nc * ch..(jb + 1) * nc * ch]);
            }
        }
    }
}

/// How a sweep towards one direction steps through its axis layout: slice by slice from the
/// side the light comes from, each voxel reading the point one slice upstream bilinearly in the
/// previous slice, which is held padded with `pad` cells of zeros on each side.
#[derive(Clone, Copy)]
struct Stepping {
    /// Voxels along the sweep axis a and the slice axes b and c.
    n: [usize; 3],
    /// Path length from one slice to the next.
    h: f32,
    /// Bilinear fractions of the upstream point along b and c.
    wb: f32,
    wc: f32,
    /// Whole cells from a voxel to its upstream point along b and c.
    ib: isize,
    ic: isize,
    /// Padding cells on each side of a held slice.
    pad: usize,
    /// Row length of a held slice, padding included.
    pc: usize,
    /// Whether the sweep runs towards decreasing a (the light comes from +a).
    backwards: bool,
}

impl Stepping {
    /// Cells of one held slice, padding included.
    fn padded(&self) -> usize {
        (self.n[1] + 2 * self.pad) * self.pc
    }

    /// The slices along a, upstream first.
    fn slices(&self) -> Box<dyn Iterator<Item = usize>> {
        if self.backwards {
            Box::new((0..self.n[0]).rev())
        } else {
            Box::new(0..self.n[0])
        }
    }
}

impl Sweeper {
    /// The layout of `dir`'s sweep axis and how a sweep towards `dir` steps through it.
    fn stepping(&self, dir: Vec3) -> (&AxisLayout, Stepping) {
        let layout = &self.layouts[Self::axis_of(dir)];
        let [a, b, c] = layout.axes;
        let [_, nb, nc] = layout.n;
        let h = self.cell[a] / dir[a].abs();
        let (fb, wb) = upstream_offset(h * dir[b] / self.cell[b], nb);
        let (fc, wc) = upstream_offset(h * dir[c] / self.cell[c], nc);
        let (ib, ic) = (fb as isize, fc as isize);
        let pad = [ib, ib + 1, ic, ic + 1]
            .iter()
            .map(|v| v.unsigned_abs())
            .max()
            .unwrap_or(1);
        let stepping = Stepping {
            n: layout.n,
            h,
            wb,
            wc,
            ib,
            ic,
            pad,
            pc: nc + 2 * pad,
            backwards: dir[a] > 0.0,
        };
        (layout, stepping)
    }
}

/// The upstream point's offset in cells along a slice axis of `n` voxels: its whole cells and
/// the bilinear fraction. Very flat voxels (a box far longer than its grid is fine) can put it
/// many grids away: beyond one grid it only reads the empty padding, so it is cut there (and the
/// padding stays small).
fn upstream_offset(o: f32, n: usize) -> (f32, f32) {
    let limit = n as f32 + 1.0;
    if o.abs() <= limit {
        (o.floor(), o - o.floor())
    } else if o > limit {
        (limit, 0.0)
    } else {
        (-limit - 1.0, 0.0)
    }
}

/// A point located in one axis layout (see [`Sweeper::locate`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Located {
    base: u32,
    frac: [f32; 3],
}

impl DepthGrid<'_> {
    /// The grid's value at a point located by [`Sweeper::locate`] (its entry for this grid's
    /// axis), trilinear like [`DepthGrid::at`].
    #[inline]
    pub fn at_located(&self, loc: &[Located; 3]) -> f32 {
        let l = &loc[self.axis];
        let [_, nb, nc] = self.sweeper.layouts[self.axis].n;
        // Steps to the next voxel along a, b and c (0 along a side of one voxel).
        let sa = if self.sweeper.layouts[self.axis].n[0] > 1 {
            nb * nc
        } else {
            0
        };
        let sb = if nb > 1 { nc } else { 0 };
        let sc = usize::from(nc > 1);
        let t = &self.tau;
        let i = l.base as usize;
        let [fa, fb, fc] = l.frac;
        let lerp = |x: f32, y: f32, w: f32| x + (y - x) * w;
        let p00 = lerp(t[i], t[i + sc], fc);
        let p01 = lerp(t[i + sb], t[i + sb + sc], fc);
        let p10 = lerp(t[i + sa], t[i + sa + sc], fc);
        let p11 = lerp(t[i + sa + sb], t[i + sa + sb + sc], fc);
        lerp(lerp(p00, p01, fb), lerp(p10, p11, fb), fa)
    }

    /// Optical depth at `p`, trilinear between voxel centres, clamped to the edge voxels.
    #[inline]
    pub fn at(&self, p: Vec3) -> f32 {
        let s = self.sweeper;
        let layout = &s.layouts[self.axis];
        let u = (p - s.min) / s.cell - 0.5;
        let [a, b, c] = layout.axes;
        let [na, nb, nc] = layout.n;
        let coord = |v: f32, n: usize| -> (usize, usize, f32) {
            let v = v.clamp(0.0, (n - 1) as f32);
            let i = (v as usize).min(n.saturating_sub(2));
            let i1 = (i + 1).min(n - 1);
            (i, i1, v - i as f32)
        };
        let (a0, a1, fa) = coord(u[a], na);
        let (b0, b1, fb) = coord(u[b], nb);
        let (c0, c1, fc) = coord(u[c], nc);
        let t = &self.tau;
        let at = |i: usize, j: usize, k: usize| t[(i * nb + j) * nc + k];
        let lerp = |x: f32, y: f32, w: f32| x + (y - x) * w;
        let p00 = lerp(at(a0, b0, c0), at(a0, b0, c1), fc);
        let p01 = lerp(at(a0, b1, c0), at(a0, b1, c1), fc);
        let p10 = lerp(at(a1, b0, c0), at(a1, b0, c1), fc);
        let p11 = lerp(at(a1, b1, c0), at(a1, b1, c1), fc);
        lerp(lerp(p00, p01, fb), lerp(p10, p11, fb), fa)
    }

    /// Optical depth at voxel `(x, y, z)`.
    pub fn voxel(&self, x: usize, y: usize, z: usize) -> f32 {
        let d = self.sweeper.dims;
        let g = (z * d[1] + y) * d[0] + x;
        self.tau[self.sweeper.layouts[self.axis].local_of_global[g] as usize]
    }
}
