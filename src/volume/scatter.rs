//! Multiple scattering by order: the radiance field each scattering order leaves in the medium,
//! as SH in direction and linear in the environment's SH, so that the albedo scales order k by
//! `albedo^k` at run time with no new bake.
//!
//! Write `Y_a` for the SH basis in direction (order `angular`) and `L_j` for the environment's
//! SH coefficients (order `light`). Everything here is albedo-free: a real medium's order k is
//! the field of order k times `albedo^k`.
//! - **Order 0**, the unscattered light arriving at x from w, is `tau(x, w) L(w)`, so its matrix
//!   is `R0[x][a][j] = ∫ tau(x, w) Y_a(w) Y_j(w) dw`: the self-transfer's sweeps of
//!   transmittance, projected on pairs of SH (with the control variate of the single-scattering
//!   bake: the exact `δ_aj` of `tau = 1` plus the quadrature of `tau − 1`).
//! - **The source** of the next order, the light scattered towards direction d per unit optical
//!   depth, is `∫ p(w·d) R(x, w) dw`: Henyey–Greenstein is diagonal in SH, band l scaled by `g^l`
//!   (Funk–Hecke), so the source is `Σ_a g^(l_a) R[x][a][j] Y_a(d)`.
//! - **Order k** arriving at x from w is the source of order k gathered along the ray `x + s w`
//!   by [`Sweeper::gather`], with the source seen looking along w (light that leaves there
//!   towards x). Projected on `Y_a(w)` over D quasi-uniform directions, it is `R_k[x][a][j]`.
//!
//! The camera's march then adds, for scattering order `k ≥ 2`, `albedo^k Σ_a g^(l_a) Y_a(d)
//! Σ_j R_(k−1)[x][a][j] L_j` per unit optical depth (order 1 stays the full-resolution
//! single scattering of [`crate::volume::render`]). Orders beyond the last baked one, N, are
//! extrapolated geometrically: each order of a thick medium converges to a fixed shape that
//! shrinks by a constant ratio λ (the leading eigenvalue of the albedo-free scattering
//! operator), so `Σ_(k>N) albedo^k R_(k−1) ≈ albedo^N R_(N−1) · albedo λ / (1 − albedo λ)`,
//! λ being measured as the ratio of two orders beyond the stored ones (their isotropic response
//! to a uniform sky, summed over the grid), where it has settled. The inner orders are baked with the medium's `g`, so a
//! change of `g` at run time is exact for the last scattering only.

use glam::Vec3;
use rayon::prelude::*;

use super::group_by_axis;
use crate::error::{PrtError, Result};
use crate::math::cubemap::{CubeMap, solid_angles, texel_dirs};
use crate::medium::sweep::Sweeper;
use crate::medium::{Medium, fibonacci_directions};

/// Most scattering orders a bake may hold.
pub const MAX_ORDERS: usize = 64;
/// Highest SH order of the scattered field in direction (the GPU march evaluates it to band 2).
pub const MAX_FIELD_ORDER: usize = 3;
/// Highest SH order of the light the scattered fields respond to.
pub const MAX_LIGHT_ORDER: usize = 6;

/// Settings of the multiple-scattering bake.
#[derive(Clone, Debug, PartialEq)]
pub struct ScatterSettings {
    /// Scattering orders N: 1 is single scattering alone, each order above adds one baked field.
    pub orders: usize,
    /// SH order of the scattered field in direction.
    pub angular: usize,
    /// SH order of the environment the fields respond to.
    pub light: usize,
    /// Directions D of each gather.
    pub directions: usize,
}

impl Default for ScatterSettings {
    fn default() -> Self {
        ScatterSettings {
            orders: 4,
            angular: 2,
            light: 4,
            directions: 256,
        }
    }
}

impl ScatterSettings {
    /// Checks the orders (1 to [`MAX_ORDERS`]), the SH orders (1 to [`MAX_FIELD_ORDER`]) and the
    /// directions (16 to 65536).
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_ORDERS).contains(&self.orders) {
            return Err(PrtError::invalid(
                "scattering orders",
                format!("{} is outside 1 to {MAX_ORDERS}", self.orders),
            ));
        }
        for (what, n, most) in [
            ("scattered field's SH order", self.angular, MAX_FIELD_ORDER),
            ("scattered light's SH order", self.light, MAX_LIGHT_ORDER),
        ] {
            if !(1..=most).contains(&n) {
                return Err(PrtError::invalid(
                    what,
                    format!("{n} is outside 1 to {most}"),
                ));
            }
        }
        if !(16..=65536).contains(&self.directions) {
            return Err(PrtError::invalid(
                "scattering directions",
                format!("{} is outside 16 to 65536", self.directions),
            ));
        }
        Ok(())
    }

    /// Gathers a bake of `orders` runs: one per stored order above the first, and on to order
    /// `max(2 orders, 8)` (unstored, with [`ScatterSettings::ratio_directions`] and the uniform
    /// sky's column alone) to measure the tail's ratio where it has settled.
    pub fn gathers(orders: usize) -> usize {
        if orders < 2 {
            0
        } else {
            (2 * orders).max(8) - 1
        }
    }

    /// Directions of the gathers that only measure the tail's ratio: a quarter of `directions`,
    /// at least 32.
    pub fn ratio_directions(directions: usize) -> usize {
        (directions / 4).max(32)
    }

    /// Directional sweeps of the whole bake of the higher orders (its progress's total).
    pub fn sweeps(&self) -> usize {
        let passes = self.orders.saturating_sub(1);
        passes * self.directions
            + (Self::gathers(self.orders) - passes) * Self::ratio_directions(self.directions)
    }

    /// Floats per voxel and order: `angular² · light²`.
    pub fn per_voxel(&self) -> usize {
        self.angular.pow(2) * self.light.pow(2)
    }
}

/// The baked fields of scattering orders 2 to N (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct ScatterFields {
    /// SH order of the fields in direction.
    pub angular: usize,
    /// SH order of the light they respond to.
    pub light: usize,
    /// Directions of each gather.
    pub directions: usize,
    /// Ratio λ of each order to the one before, beyond the last (0 when fewer than two fields).
    pub tail_ratio: f32,
    /// `fields[k − 2]` holds `R_(k−1)`, the albedo-free radiance that scattering order k
    /// scatters: `[voxel][a][j]`, j fastest.
    pub fields: Vec<Vec<f32>>,
}

impl ScatterFields {
    /// Scattering orders the fields stand for, single scattering included.
    pub fn orders(&self) -> usize {
        self.fields.len() + 1
    }

    /// Floats per voxel and order.
    pub fn per_voxel(&self) -> usize {
        self.angular.pow(2) * self.light.pow(2)
    }
}

/// `g^l` for each SH coefficient of order `n`.
pub fn phase_bands(g: f32, n: usize) -> Vec<f32> {
    (0..n)
        .flat_map(|l| std::iter::repeat_n(g.powi(l as i32), 2 * l + 1))
        .collect()
}

fn sh(order: usize, d: Vec3) -> Vec<f32> {
    let mut out = vec![0.0f32; order * order];
    crate::math::sh::eval_f32_into(order, d, &mut out);
    out
}

/// Bakes the fields of scattering orders 2 to `settings.orders` for `medium`, calling
/// `progress(done, total)` per batch of directions.
pub fn bake_scatter(
    medium: &Medium,
    settings: &ScatterSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<ScatterFields> {
    settings.validate()?;
    medium.validate()?;
    let (na2, nl2) = (settings.angular.pow(2), settings.light.pow(2));
    let per = na2 * nl2;
    let voxels = medium.grid.voxel_count();
    let sweeper = Sweeper::new(medium);
    let dirs = fibonacci_directions(settings.directions);
    let weight = 4.0 * std::f32::consts::PI / dirs.len() as f32;
    let passes = settings.orders.saturating_sub(1);
    let gathers = ScatterSettings::gathers(settings.orders);
    let total = settings.sweeps();
    let mut fields: Vec<Vec<f32>> = Vec::with_capacity(passes);
    if passes == 0 {
        return Ok(ScatterFields {
            angular: settings.angular,
            light: settings.light,
            directions: settings.directions,
            tail_ratio: 0.0,
            fields,
        });
    }
    let by_axis = group_by_axis(&dirs);
    // The orders beyond the stored ones only measure λ, a ratio of grid sums that a coarser
    // quadrature gives as well.
    let coarse = fibonacci_directions(ScatterSettings::ratio_directions(settings.directions));
    // Order 0: ∫ tau Y_a Y_j, the exact δ_aj plus the quadrature of tau − 1.
    let mut field = vec![0.0f32; voxels * per];
    super::project_transmittance(
        &sweeper,
        &dirs,
        per,
        |d| {
            let (ya, yj) = (sh(settings.angular, d), sh(settings.light, d));
            ya.iter()
                .flat_map(|a| yj.iter().map(move |j| a * j * weight))
                .collect()
        },
        &mut field,
        |_| {},
    );
    for v in field.chunks_exact_mut(per) {
        for a in 0..na2.min(nl2) {
            v[a * nl2 + a] += 1.0;
        }
    }
    let pass = Pass {
        sweeper: &sweeper,
        by_axis: &by_axis,
        angular: settings.angular,
        bands: phase_bands(medium.g, settings.angular),
        weight,
        voxels,
    };
    let coarse_axes = group_by_axis(&coarse);
    let ratio_pass = Pass {
        by_axis: &coarse_axes,
        weight: 4.0 * std::f32::consts::PI / coarse.len() as f32,
        bands: pass.bands.clone(),
        ..pass
    };
    let mut done = 0;
    let mut responses = Vec::with_capacity(gathers);
    let mut column: Option<Vec<f32>> = None;
    for k in 0..gathers {
        let tick = |n: usize| {
            done += n;
            progress(done, total);
        };
        if k < passes {
            let next = pass.run(&field, nl2, tick);
            responses.push(pass.isotropic(&next, nl2));
            fields.push(next);
            field = fields.last().cloned().unwrap_or_default();
        } else {
            // Beyond the stored orders only λ is wanted, which the uniform sky's column (j = 0)
            // gives alone: the scattering never mixes the light's coefficients.
            let from = column.take().unwrap_or_else(|| {
                field
                    .chunks_exact(nl2)
                    .map(|row| row[0])
                    .collect::<Vec<f32>>()
            });
            let next = ratio_pass.run(&from, 1, tick);
            responses.push(ratio_pass.isotropic(&next, 1));
            column = Some(next);
        }
    }
    // λ from the last two orders computed (beyond the stored ones: the ratio settles slowly).
    let tail_ratio = match responses.len() {
        n if n >= 2 && responses[n - 2] > 0.0 => {
            (responses[n - 1] / responses[n - 2]).clamp(0.0, 0.999) as f32
        }
        _ => 0.0,
    };
    Ok(ScatterFields {
        angular: settings.angular,
        light: settings.light,
        directions: settings.directions,
        tail_ratio,
        fields,
    })
}

/// One scattering order: the sweeps and what every gather shares.
struct Pass<'a> {
    sweeper: &'a Sweeper,
    by_axis: &'a [(usize, Vec<Vec3>)],
    angular: usize,
    bands: Vec<f32>,
    weight: f32,
    voxels: usize,
}

impl Pass<'_> {
    /// The field of the next order from `field` (`[voxel][a][j]`, `nl2` light coefficients),
    /// calling `tick(directions)` after each batch.
    fn run(&self, field: &[f32], nl2: usize, mut tick: impl FnMut(usize)) -> Vec<f32> {
        const BATCH: usize = 8;
        let per = self.angular.pow(2) * nl2;
        let voxels = self.voxels;
        let mut next = vec![0.0f32; voxels * per];
        for (axis, group) in self.by_axis {
            let local = self.sweeper.local_of_global(*axis);
            for batch in group.chunks(BATCH) {
                // The source Σ_a g^l R[x][a][j] Y_a(d), gathered along each direction.
                let gathered: Vec<Vec<f32>> = batch
                    .par_iter()
                    .map(|d| {
                        let c: Vec<f32> = sh(self.angular, *d)
                            .iter()
                            .zip(&self.bands)
                            .map(|(y, b)| y * b)
                            .collect();
                        let mut source = vec![0.0f32; voxels * nl2];
                        for (g, r) in field.chunks_exact(per).enumerate() {
                            let l = local[g] as usize;
                            let s = &mut source[l * nl2..(l + 1) * nl2];
                            for (ca, row) in c.iter().zip(r.chunks_exact(nl2)) {
                                for (sj, rj) in s.iter_mut().zip(row) {
                                    *sj += ca * rj;
                                }
                            }
                        }
                        let mut out = vec![0.0f32; voxels * nl2];
                        self.sweeper.gather(*d, nl2, &source, &mut out);
                        out
                    })
                    .collect();
                let proj: Vec<Vec<f32>> = batch
                    .iter()
                    .map(|d| {
                        sh(self.angular, *d)
                            .iter()
                            .map(|y| y * self.weight)
                            .collect()
                    })
                    .collect();
                next.par_chunks_mut(per).enumerate().for_each(|(g, out)| {
                    let l = local[g] as usize;
                    for (i, ya) in gathered.iter().zip(&proj) {
                        let i = &i[l * nl2..(l + 1) * nl2];
                        for (y, row) in ya.iter().zip(out.chunks_exact_mut(nl2)) {
                            for (o, v) in row.iter_mut().zip(i) {
                                *o += y * v;
                            }
                        }
                    }
                });
                tick(batch.len());
            }
        }
        next
    }

    /// The isotropic response to a uniform sky (a = 0, j = 0) summed over the grid.
    fn isotropic(&self, field: &[f32], nl2: usize) -> f64 {
        let per = self.angular.pow(2) * nl2;
        field.chunks_exact(per).map(|v| v[0] as f64).sum()
    }
}

/// The environment's SH projection at `order`, per channel, from the cube's texels.
pub fn light_sh(cube: &CubeMap, order: usize) -> Vec<[f32; 3]> {
    let dirs = texel_dirs(cube.n);
    let omega = solid_angles(cube.n);
    let mut out = vec![[0.0f64; 3]; order * order];
    let mut y = vec![0.0f64; order * order];
    for ((d, o), l) in dirs.iter().zip(&omega).zip(&cube.texels) {
        crate::math::sh::eval(order, *d, &mut y);
        for (acc, yi) in out.iter_mut().zip(&y) {
            for c in 0..3 {
                acc[c] += l[c] as f64 * o * yi;
            }
        }
    }
    out.into_iter().map(|v| v.map(|x| x as f32)).collect()
}

/// The scattered radiance of orders 2 and above under one light and albedo, per voxel: `[voxel]
/// [a]` RGB, `Σ_(k≥2) albedo^k Σ_j R_(k−1)[x][a][j] L_j` with the geometric tail (see the module
/// docs). The march takes `Σ_a g^(l_a) Y_a(d)` of it, trilinear.
#[derive(Clone, Debug, PartialEq)]
pub struct ScatterLight {
    /// SH order of the field in direction.
    pub angular: usize,
    /// `angular²` RGB values per voxel.
    pub field: Vec<[f32; 3]>,
}

impl ScatterLight {
    /// Applies the light `l` (SH of order `fields.light`, RGB) and the albedo to the fields of
    /// scattering orders 2 to `orders`. `tail` adds the orders beyond `orders`.
    pub fn new(
        fields: &ScatterFields,
        l: &[[f32; 3]],
        albedo: Vec3,
        orders: usize,
        tail: bool,
    ) -> ScatterLight {
        let (na2, nl2) = (fields.angular.pow(2), fields.light.pow(2));
        let per = na2 * nl2;
        let voxels = fields.fields.first().map_or(0, |f| f.len() / per);
        // Per order and channel: albedo^k, and the tail folded into the last order.
        let last = fields.fields.len().min(orders.saturating_sub(1));
        let scales: Vec<[f32; 3]> = (0..last)
            .map(|i| {
                let k = i as i32 + 2;
                std::array::from_fn(|c| {
                    let w = albedo[c];
                    let mut s = w.powi(k);
                    if tail && i + 1 == last {
                        let r = w * fields.tail_ratio;
                        s *= 1.0 + r / (1.0 - r);
                    }
                    s
                })
            })
            .collect();
        let mut field = vec![[0.0f32; 3]; voxels * na2];
        field.par_chunks_mut(na2).enumerate().for_each(|(v, out)| {
            for (f, s) in fields.fields[..last].iter().zip(&scales) {
                let r = &f[v * per..(v + 1) * per];
                for (o, row) in out.iter_mut().zip(r.chunks_exact(nl2)) {
                    let mut acc = [0.0f32; 3];
                    for (rj, lj) in row.iter().zip(&l[..nl2]) {
                        for c in 0..3 {
                            acc[c] += rj * lj[c];
                        }
                    }
                    for c in 0..3 {
                        o[c] += s[c] * acc[c];
                    }
                }
            }
        });
        ScatterLight {
            angular: fields.angular,
            field,
        }
    }

    /// `g^(l_a) Y_a(d)` for the march along `d`: the weights of the field's coefficients.
    pub fn view_weights(&self, g: f32, d: Vec3) -> Vec<f32> {
        sh(self.angular, d)
            .iter()
            .zip(phase_bands(g, self.angular))
            .map(|(y, b)| y * b)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::{DensityGrid, DensitySource};
    use crate::volume::path_trace::{VolumeTraceSettings, path_trace_volume};
    use crate::volume::{MediumLook, TransferSettings, VolumeLight, VolumeTransfer, bake_transfer};

    /// A uniform source in a homogeneous box, gathered along an axis, against `1 − e^−tau` to
    /// the box's edge: the linear-source step is exact for a constant source, so what is left is
    /// how the sweep meets the density's ramp half a voxel beyond the box.
    const GATHER_CONSTANT: f32 = 0.02;
    /// Orders 0 to N of an albedo-1 medium under a uniform sky, with the tail, against 1 (the
    /// medium's white furnace, where radiance is 1 everywhere): measured 1–3% over the sphere,
    /// from the sweeps' bilinear blur and the SH truncation in direction, both compounding over
    /// the orders.
    const FURNACE: f64 = 0.05;
    /// The march with every order against the path tracer, relative L2 over the image, beyond the
    /// tracer's own noise: measured 2.0–2.6% (the SH truncations of the single scattering and of
    /// the fields, and the sweeps).
    const ORDERS_VS_TRACER: f64 = 0.05;

    fn medium(n: usize, extinction: f32, albedo: f32, g: f32) -> Medium {
        let src = DensitySource::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::splat(0.8),
            falloff: 0.3,
        };
        Medium {
            grid: DensityGrid::from_fn([n; 3], Vec3::splat(-1.0), Vec3::splat(1.0), |p| {
                src.density(p)
            }),
            extinction,
            albedo: Vec3::splat(albedo),
            g,
        }
    }

    #[test]
    fn a_uniform_source_gathers_to_one_minus_the_transmittance() {
        let m = Medium {
            grid: DensityGrid::from_fn([12, 10, 8], Vec3::splat(-1.0), Vec3::ONE, |_| 1.0),
            extinction: 2.0,
            albedo: Vec3::ONE,
            g: 0.0,
        };
        let sweeper = Sweeper::new(&m);
        for dir in [Vec3::X, -Vec3::Y, Vec3::new(0.3, 0.2, 0.93).normalize()] {
            let n = sweeper.voxel_count();
            let (source, mut out) = (vec![1.0f32; n * 2], vec![0.0f32; n * 2]);
            sweeper.gather(dir, 2, &source, &mut out);
            let depth = sweeper.depth(dir);
            for (z, y, x) in [(3, 4, 5), (0, 0, 0), (7, 9, 11), (4, 2, 9)] {
                let g = (z * 10 + y) * 12 + x;
                let l = sweeper.local_of_global(Sweeper::axis_of(dir))[g] as usize;
                let want = 1.0 - (-depth.voxel(x, y, z)).exp();
                for c in 0..2 {
                    assert!(
                        (out[l * 2 + c] - want).abs() < GATHER_CONSTANT,
                        "{dir} voxel {x},{y},{z}: {} vs {want}",
                        out[l * 2 + c]
                    );
                }
            }
        }
    }

    #[test]
    fn an_albedo_one_medium_under_a_uniform_sky_fills_with_radiance_one() {
        let m = medium(16, 6.0, 1.0, 0.3);
        let settings = ScatterSettings {
            orders: 12,
            angular: 2,
            light: 2,
            directions: 128,
        };
        let fields = bake_scatter(&m, &settings, &|_, _| {}).unwrap();
        assert_eq!(fields.orders(), 12);
        assert!(fields.tail_ratio > 0.3 && fields.tail_ratio < 1.0);
        // Order 0 from the single-scattering transfer's own sweeps: T_0 / 2√π is the mean
        // transmittance, the DC of ∫ tau Y_0 Y_0.
        let transfer = bake_transfer(&m, &TransferSettings::default(), &|_, _| {}).unwrap();
        let per = fields.per_voxel();
        let mut worst = 0.0f64;
        for z in 3..13 {
            for y in 3..13 {
                for x in 3..13 {
                    let v = (z * 16 + y) * 16 + x;
                    let r0 = transfer[v * 9] as f64 / (2.0 * std::f64::consts::PI.sqrt());
                    let baked: f64 = fields.fields.iter().map(|f| f[v * per] as f64).sum();
                    let last = fields.fields.last().unwrap()[v * per] as f64;
                    let r = fields.tail_ratio as f64;
                    let total = r0 + baked + last * r / (1.0 - r);
                    worst = worst.max((total - 1.0).abs());
                }
            }
        }
        assert!(worst < FURNACE, "radiance off 1 by up to {worst}");
    }

    #[test]
    fn every_order_relit_agrees_with_the_volumetric_path_tracer_at_any_albedo() {
        // A thick sphere (depth about 8 across) under a sky with a bright patch: most of what it
        // sends the camera has scattered more than once.
        let m = medium(20, 5.0, 0.9, 0.3);
        let n = 8;
        let patch = glam::DVec3::new(0.6, 0.6, 0.5).normalize();
        let cube = CubeMap::from_fn(n, |d| {
            let sun = 12.0 * (d.dot(patch) > 0.85) as u8 as f32;
            let sky = 0.4 + 0.3 * d.y as f32;
            [sky + sun, sky + 0.8 * sun, sky + 0.6 * sun]
        })
        .unwrap();
        let settings = TransferSettings {
            scatter: ScatterSettings {
                directions: 128,
                ..ScatterSettings::default()
            },
            ..TransferSettings::default()
        };
        let vt = VolumeTransfer {
            meta: crate::volume::tests::meta_for(&m, 3, settings.directions),
            density: m.grid.data.clone(),
            transfer: bake_transfer(&m, &settings, &|_, _| {}).unwrap(),
            scatter: Some(bake_scatter(&m, &settings.scatter, &|_, _| {}).unwrap()),
        };
        let camera = crate::scene::Camera {
            width: 20,
            height: 20,
            ..vt.camera(None, None, None).unwrap()
        };
        for albedo in [0.9f32, 0.5, 0.99] {
            let traced = path_trace_volume(
                &Medium {
                    albedo: Vec3::splat(albedo),
                    ..m.clone()
                },
                &cube,
                &camera,
                &VolumeTraceSettings {
                    samples: 4096,
                    ..Default::default()
                },
                &|_, _| {},
            )
            .unwrap();
            let noise = traced.relative_noise(None);
            let look = MediumLook {
                albedo: Vec3::splat(albedo),
                ..MediumLook::of(&vt)
            };
            let every = VolumeLight::new(&vt, &cube, &look).unwrap();
            let once = VolumeLight::new(&vt, &cube, &MediumLook { orders: 1, ..look }).unwrap();
            let err = |light: &VolumeLight| {
                let img = crate::volume::render_volume(&vt, light, &camera, Default::default());
                crate::output::metrics::relative_l2(&img, &traced.image, None).unwrap()
            };
            let (all, single) = (err(&every), err(&once));
            assert!(
                all < ORDERS_VS_TRACER + noise,
                "albedo {albedo}: every order {all} (noise {noise})"
            );
            assert!(
                single > 3.0 * all,
                "albedo {albedo}: single scattering {single} against every order {all}"
            );
        }
    }
}
