//! Relighting a medium from its SH self-transfer by ray marching, on the CPU.
//!
//! Along a camera ray of direction `d`, single scattering brings
//! `Σ_k T_cam(x_k) sigma_t(x_k) dt · albedo · ∫ p(w·d) L(w) tau(x_k, w) dw`. With the transfer
//! `T_i(x)` the projection of `tau(x, ·)`, the inner integral is `Σ_i P_i(d) T_i(x)` exactly
//! within the SH truncation, where `P_i(d) = ∫ p(w·d) L(w) Y_i(w) dw` is the SH projection of the
//! lighting times the Henyey–Greenstein lobe around `d` (the scattering angle between the light's
//! travel, `−w`, and the way to the eye, `−d`, has cosine `w·d`). `P(d)` depends on the view
//! direction only, not on the voxel: [`PhaseLight`] tabulates it once per environment over a
//! lat-long grid of directions and each pixel interpolates it. For an isotropic medium
//! `P_i = L_i / (4π)`, the formula of [`crate::conventions`], and the table is one entry.
//!
//! Scattering of orders 2 and above adds `Σ_a g^(l_a) Y_a(d) F_a(x)` per unit optical depth,
//! with `F` the light's scattered field ([`crate::volume::scatter::ScatterLight`], albedo powers
//! included) trilinear between voxel centres.

use glam::Vec3;
use rayon::prelude::*;

use super::file::{trilinear_at, trilinear_corners};
use super::{VolumeLight, VolumeTransfer};
use crate::math::cubemap::{CubeMap, solid_angles, texel_dirs};
use crate::medium::{MarchSample, henyey_greenstein};
use crate::output::film::Image;
use crate::scene::Camera;

/// Lat-long size of the [`PhaseLight`] table of an anisotropic medium.
pub const PHASE_TABLE: [usize; 2] = [64, 32];

/// `P_i(d)`: SH projections of lighting times phase, per view direction (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseLight {
    /// SH order n of the projections (n² per table entry).
    pub order: usize,
    /// Table size in u (azimuth) and v (polar); 1 × 1 when isotropic.
    pub width: usize,
    /// Table rows, in v (polar); 1 when isotropic.
    pub height: usize,
    /// `[v][u][i]` RGB, `width · height · n²` entries.
    pub table: Vec<[f32; 3]>,
}

/// Lat-long coordinates of a direction in the table's convention ([`crate::conventions`], lat-long:
/// u = 0 towards −Z, u = 1/4 towards +X, v = 0 up).
#[inline]
pub fn table_uv(d: Vec3) -> (f32, f32) {
    let v = d.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
    let u = d.x.atan2(-d.z) / (2.0 * std::f32::consts::PI);
    (if u < 0.0 { u + 1.0 } else { u }, v)
}

impl PhaseLight {
    /// Tabulates `P(d)` for a medium of asymmetry `g` lit by `cube`, at SH order `order`.
    pub fn new(cube: &CubeMap, order: usize, g: f32) -> PhaseLight {
        let n2 = order * order;
        let dirs = texel_dirs(cube.n);
        let omega = solid_angles(cube.n);
        // L(w_t) Ω_t Y_i(w_t) per texel.
        let weighted: Vec<Vec<[f32; 3]>> = dirs
            .par_iter()
            .zip(&omega)
            .zip(&cube.texels)
            .map(|((d, o), l)| {
                crate::math::sh::eval_vec(order, *d)
                    .into_iter()
                    .map(|y| l.map(|c| (c as f64 * o * y) as f32))
                    .collect()
            })
            .collect();
        if g == 0.0 {
            let mut table = vec![[0.0f32; 3]; n2];
            for w in &weighted {
                for (t, v) in table.iter_mut().zip(w) {
                    for c in 0..3 {
                        t[c] += v[c] / (4.0 * std::f32::consts::PI);
                    }
                }
            }
            return PhaseLight {
                order,
                width: 1,
                height: 1,
                table,
            };
        }
        let [w, h] = PHASE_TABLE;
        let dirs_f: Vec<Vec3> = dirs.iter().map(|d| d.as_vec3()).collect();
        let table: Vec<[f32; 3]> = (0..w * h)
            .into_par_iter()
            .flat_map_iter(|k| {
                let (u, v) = ((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                let d = crate::env::envmap::latlong_dir(u / w as f64, v / h as f64).as_vec3();
                let mut out = vec![[0.0f32; 3]; n2];
                for (wt, td) in weighted.iter().zip(&dirs_f) {
                    let p = henyey_greenstein(g, td.dot(d));
                    for (o, x) in out.iter_mut().zip(wt) {
                        for c in 0..3 {
                            o[c] += p * x[c];
                        }
                    }
                }
                out
            })
            .collect();
        PhaseLight {
            order,
            width: w,
            height: h,
            table,
        }
    }

    /// `P(d)` into `out` (`n²` RGB), bilinear in the table (wrapping in u).
    pub fn at(&self, d: Vec3, out: &mut [[f32; 3]]) {
        let n2 = self.order * self.order;
        if self.width * self.height == 1 {
            out[..n2].copy_from_slice(&self.table[..n2]);
            return;
        }
        let (u, v) = table_uv(d);
        let x = u * self.width as f32 - 0.5;
        let y = (v * self.height as f32 - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let xi = |i: f32| (i as i64).rem_euclid(self.width as i64) as usize;
        let (xa, xb) = (xi(x0), xi(x0 + 1.0));
        let ya = y0 as usize;
        let yb = (ya + 1).min(self.height - 1);
        out[..n2].fill([0.0; 3]);
        for (xx, yy, wgt) in [
            (xa, ya, (1.0 - fx) * (1.0 - fy)),
            (xb, ya, fx * (1.0 - fy)),
            (xa, yb, (1.0 - fx) * fy),
            (xb, yb, fx * fy),
        ] {
            let base = (yy * self.width + xx) * n2;
            for (o, t) in out.iter_mut().zip(&self.table[base..base + n2]) {
                for c in 0..3 {
                    o[c] += wgt * t[c];
                }
            }
        }
    }
}

/// What [`render_volume`] shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[derive(strum::IntoStaticStr, strum::Display, strum::VariantArray)]
#[strum(serialize_all = "lowercase")]
pub enum VolumeView {
    /// Single scattering with the camera ray's transmittance.
    #[default]
    Full,
    /// The in-scattered radiance summed along the ray, without the camera ray's attenuation.
    InScatter,
    /// The camera ray's transmittance through the medium (grey).
    Transmittance,
    /// The self-shadow map: `T_0 / (2√π)`, the fraction of directions open to the sky,
    /// composited along the ray like a medium of albedo 1 (grey).
    #[strum(serialize = "dc")]
    TransferDc,
}

impl VolumeView {
    /// Every view, in the order of [`VolumeView::index`].
    pub const ALL: [VolumeView; 4] = [
        VolumeView::Full,
        VolumeView::InScatter,
        VolumeView::Transmittance,
        VolumeView::TransferDc,
    ];

    /// The view's name, as `--view` takes it.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// The index the GPU shader switches on.
    pub fn index(self) -> u32 {
        self as u32
    }
}

crate::named!(VolumeView, "view");

/// Ray-marches `vt` lit by `light` through `camera` (CPU, rayon over rows).
pub fn render_volume(
    vt: &VolumeTransfer,
    light: &VolumeLight,
    camera: &Camera,
    view: VolumeView,
) -> Image {
    let medium = vt.medium();
    let (w, h) = (camera.width as usize, camera.height as usize);
    let albedo = light.albedo;
    let scatter = light.scatter.as_ref();
    let field: &[f32] = scatter.map_or(&[], |s| bytemuck::cast_slice(&s.field));
    let stride = scatter.map_or(0, |s| s.angular.pow(2) * 3);
    let g = light.g;
    let light = &light.phase;
    let n2 = vt.sh_count().min(light.order * light.order);
    let dc_scale = 0.5 / std::f32::consts::PI.sqrt();
    let mut image = Image::new(w, h);
    image
        .pixels
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, line)| {
            let mut samples: Vec<MarchSample> = Vec::new();
            let mut t = vec![0.0f32; vt.sh_count()];
            let mut p = vec![[0.0f32; 3]; light.order * light.order];
            let mut f = vec![0.0f32; stride];
            for (x, px) in line.iter_mut().enumerate() {
                let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
                let early = view != VolumeView::InScatter;
                let left = medium.march_camera_with(
                    ray.origin,
                    ray.dir,
                    f32::INFINITY,
                    early,
                    &mut samples,
                );
                *px = match view {
                    VolumeView::Transmittance => [left; 3],
                    VolumeView::TransferDc => {
                        let mut s = 0.0;
                        for m in &samples {
                            vt.transfer_at(m.pos, &mut t);
                            s += m.weight * t[0] * dc_scale;
                        }
                        [s; 3]
                    }
                    VolumeView::Full | VolumeView::InScatter => {
                        light.at(ray.dir, &mut p);
                        let view_weights = scatter.map(|s| s.view_weights(g, ray.dir));
                        let (mut s, mut more) = ([0.0f32; 3], [0.0f32; 3]);
                        for m in &samples {
                            // One lookup of the cell serves the transfer and the field.
                            let corners = trilinear_corners(&vt.meta, m.pos);
                            trilinear_at(&corners, &vt.transfer, t.len(), &mut t);
                            let wgt = if view == VolumeView::Full {
                                m.weight
                            } else {
                                m.sigma_dt
                            };
                            for (ti, pi) in t[..n2].iter().zip(&p[..n2]) {
                                for c in 0..3 {
                                    s[c] += wgt * ti * pi[c];
                                }
                            }
                            if let Some(vw) = &view_weights {
                                trilinear_at(&corners, field, stride, &mut f);
                                for (ca, fa) in vw.iter().zip(f.chunks_exact(3)) {
                                    for c in 0..3 {
                                        more[c] += wgt * ca * fa[c];
                                    }
                                }
                            }
                        }
                        std::array::from_fn(|c| s[c] * albedo[c] + more[c])
                    }
                };
            }
        });
    image
}
