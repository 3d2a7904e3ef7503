//! One tile of the bake: for each of its pixels, every camera sub-sample's sources added to the
//! pixel's dense rows (the paths through a medium from the camera, the light columns, the direct
//! rows, the interreflections), then each row projected on SH,
//! Haar-transformed and thresholded, and the tile's rows laid out kind by kind.

use glam::Vec3;

use super::lights::LightSampler;
use super::pixels::{EdgeMap, Visit, visits};
use super::slot::Slot;
use super::{
    BakeSettings, CentrePackets, ShadingPoint, Shadows, accumulate_direct_rows, bounce,
    path_stream, sample_stride,
};
use crate::bake::medium_rows::MediumRows;
use crate::math::cubemap::texel_count;
use crate::math::haar;
use crate::math::sampling::TexelSamples;
use crate::math::texel_sh::TexelShBasis;
use crate::medium::Medium;
use crate::scene::Scene;
use crate::scene::tessellate::VertexMesh;
use crate::scene::trace::Tracer;
use crate::store::budget::Thresholder;
use crate::store::transport::RowData;

/// What one tile of the bake produces.
pub(super) struct TileOutput {
    pub(super) rows: Vec<RowData>,
    /// (pixel, mean albedo over hit sub-samples, coverage).
    pub(super) pixels: Vec<(u32, [f32; 3], f32)>,
    pub(super) dropped_energy: f64,
    pub(super) total_energy: f64,
    pub(super) rays: u64,
    /// (pixel, its response to every light column), for pixels with a visit.
    pub(super) lights: Vec<(u32, Vec<Vec3>)>,
}

/// What every tile of a bake shares.
pub(super) struct TileContext<'a> {
    pub(super) scene: &'a Scene,
    /// Size of the image the rows belong to: the view's, or one tile wide for a mesh.
    pub(super) width: usize,
    pub(super) height: usize,
    /// The mesh of a per-vertex bake: pixel v is vertex v.
    pub(super) mesh: Option<&'a VertexMesh>,
    pub(super) tracer: &'a Tracer,
    /// The pixels that take `edge_spp` sub-samples.
    pub(super) edges: &'a EdgeMap,
    pub(super) settings: &'a BakeSettings,
    pub(super) samples: &'a TexelSamples,
    /// The quadrature's texel centres in blocks traced together.
    pub(super) packets: Option<&'a CentrePackets>,
    pub(super) basis: &'a TexelShBasis,
    /// Energy of an unshadowed row, the scale of the thresholding budget.
    pub(super) reference_energy: f64,
    /// The thresholding budget.
    pub(super) thresholder: Thresholder,
    /// The scene's medium and its rows, if it has one.
    pub(super) medium: Option<&'a Medium>,
    pub(super) medium_rows: Option<&'a MediumRows>,
    /// The interreflections' paths and vertex rows.
    pub(super) bounces: &'a bounce::Bounces<'a>,
    /// The local lights' columns.
    pub(super) lights: &'a LightSampler,
}

impl TileContext<'_> {
    /// What the bake's shading points are shadowed by.
    fn shadows(&self) -> Shadows<'_> {
        Shadows {
            tracer: self.tracer,
            unshadowed: self.settings.unshadowed,
            medium: self.medium,
            packets: self.packets,
        }
    }

    /// Texels of the cube.
    fn texels(&self) -> usize {
        texel_count(self.settings.cube_n)
    }
}

/// What a row of a tile holds, in the order a tile lays its rows out. A block's column is cut into
/// strips of 8 rows, kept whole when one of them has an entry, so rows that keep the same
/// coefficients belong side by side: the first lobe of every pixel, then the second, and so on;
/// then each pixel's three interreflection rows together (their paths are the same, and so are
/// the coefficients they keep); then the medium's rows. Laid out pixel by pixel, the sparse interreflection rows shared strips with the
/// dense direct rows: on a 128² one-bounce demo bake 29% of strip values were entries, and 76%
/// this way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum RowKind {
    /// The i-th lobe row of a pixel (a material's diffuse lobe, then its GGX lobe, per material).
    Lobe(usize),
    /// A pixel's interreflection rows, one per colour channel.
    Channels,
    /// A pixel's single-scattering row through the medium.
    Medium,
}

/// What a tile reuses from one pixel to the next.
struct Scratch {
    /// The thresholder's ordering.
    order: Vec<u64>,
    /// The Haar transform's.
    haar: Vec<f32>,
    /// One sub-sample's rows of a textured material, before its colour weighs them.
    rows: [Vec<f32>; 2],
}

/// Bakes one tile: dense rows per (pixel, material), SH projection, Haar and thresholding.
pub(super) fn bake_tile(ctx: &TileContext, tile_x: usize, tile_y: usize) -> TileOutput {
    use crate::store::transport::TILE;
    let c = ctx.texels();
    let mut out = TileOutput {
        rows: Vec::new(),
        pixels: Vec::new(),
        dropped_energy: 0.0,
        total_energy: 0.0,
        rays: 0,
        lights: Vec::new(),
    };
    let mut scratch = Scratch {
        order: Vec::with_capacity(c),
        haar: Vec::new(),
        rows: [vec![0.0f32; c], vec![0.0f32; c]],
    };
    // The tile's rows, each with its kind, laid out kind by kind at the end.
    let mut rows: Vec<(RowKind, RowData)> = Vec::new();
    for y in tile_y * TILE..((tile_y + 1) * TILE).min(ctx.height) {
        for x in tile_x * TILE..((tile_x + 1) * TILE).min(ctx.width) {
            let visits = visits(ctx, x, y);
            if visits.is_empty() {
                continue;
            }
            let pixel = (y * ctx.width + x) as u32;
            let mut sums = PixelSums::new(ctx, visits.len());
            for (sub, visit) in visits.into_iter().enumerate() {
                let stream = path_stream(pixel as u64, sub, sample_stride(ctx.settings));
                out.rays += sums.add(ctx, &mut scratch, stream, visit);
            }
            sums.finish(ctx, pixel, &mut scratch, &mut out, &mut rows);
        }
    }
    // Stable: inside a kind, rows keep their pixels' order (and a pixel's channels theirs).
    rows.sort_by_key(|(kind, _)| *kind);
    out.rows = rows.into_iter().map(|(_, row)| row).collect();
    out
}

/// The interreflection rows of `c` texels, made on first use.
fn made(indirect: &mut Option<[Vec<f32>; 3]>, c: usize) -> &mut [Vec<f32>; 3] {
    indirect.get_or_insert_with(|| std::array::from_fn(|_| vec![0.0; c]))
}

/// One pixel's sums over its camera sub-samples.
struct PixelSums {
    /// 1 / the pixel's sub-samples.
    inv_spp: f32,
    /// Dense rows per material seen: the diffuse lobe's and, for glossy materials, the GGX
    /// lobe's; tinted per sub-sample for a textured material.
    dense: Vec<Slot>,
    /// Interreflected light, one row per colour channel (colour bleeding mixes them).
    indirect: Option<[Vec<f32>; 3]>,
    hits: usize,
    covered: f32,
    albedo_sum: Vec3,
    /// The response to each light column.
    light_columns: Vec<Vec3>,
    /// A textured vertex, whose rows are a white surface's.
    white: bool,
}

impl PixelSums {
    fn new(ctx: &TileContext, sub_samples: usize) -> PixelSums {
        PixelSums {
            inv_spp: 1.0 / sub_samples as f32,
            dense: Vec::new(),
            indirect: None,
            hits: 0,
            covered: 0.0,
            albedo_sum: Vec3::ZERO,
            light_columns: vec![Vec3::ZERO; ctx.lights.columns()],
            white: false,
        }
    }

    /// Adds one camera sub-sample (random stream `stream`) to the sums. Returns the rays traced.
    fn add(&mut self, ctx: &TileContext, scratch: &mut Scratch, stream: u64, visit: Visit) -> u64 {
        let settings = ctx.settings;
        let mut rays = 0;
        self.covered += visit.covered;
        if settings.bounces > 0
            && let Some(ray) = visit.ray
            && ctx.medium.is_some()
        {
            // Paths that start at collisions along the camera ray.
            let scale = self.inv_spp / settings.paths as f32;
            let rows = made(&mut self.indirect, ctx.texels());
            rays += ctx.bounces.add_camera_rows(ray, stream, scale, rows);
        }
        let Some(sp) = visit.point else {
            return rays;
        };
        let scale = self.inv_spp * visit.seen;
        rays += self.surface(ctx, scratch, stream, &sp, scale);
        if settings.bounces > 0 {
            // What the camera sees of the surface is attenuated by a medium in between.
            let scale = scale / settings.paths as f32;
            let rows = made(&mut self.indirect, ctx.texels());
            let lights = ctx.lights;
            let lit = (lights.columns() > 0).then_some((lights, &mut self.light_columns[..]));
            rays += ctx.bounces.add_rows(&sp, stream, scale, rows, lit);
        }
        rays
    }

    /// A surface hit's own light, `scale` times: its light columns and its direct rows. Returns
    /// the rays traced.
    fn surface(
        &mut self,
        ctx: &TileContext,
        scratch: &mut Scratch,
        stream: u64,
        sp: &ShadingPoint,
        scale: f32,
    ) -> u64 {
        let (scene, mesh, c) = (ctx.scene, ctx.mesh, ctx.texels());
        let mut rays = 0;
        self.hits += 1;
        // A vertex is seen from every side: only the diffuse lobe holds for all.
        let mut here = sp.lobes(scene);
        if mesh.is_some() {
            here.specular = Vec3::ZERO;
        }
        self.albedo_sum += here.albedo;
        let glossy = scene.materials[sp.material as usize]
            .glossy_lobe()
            .is_some()
            && mesh.is_none();
        // A vertex has one visit, and a textured one is baked white: no tinting.
        let textured = !sp.unit_albedo
            && scene
                .material_maps
                .get(sp.material as usize)
                .is_some_and(Option::is_some);
        self.white |= sp.unit_albedo;
        let slot = match self.dense.iter().position(|d| d.material == sp.material) {
            Some(i) => i,
            None => {
                self.dense.push(Slot::new(sp.material, c, glossy, textured));
                self.dense.len() - 1
            }
        };
        let shadows = ctx.shadows();
        if ctx.lights.columns() > 0 {
            let lobes = match mesh {
                // A vertex is seen from every side: its diffuse lobe.
                Some(_) => LightSampler::diffuse(here.albedo),
                None => here,
            };
            let draw = super::lights::Draw {
                stream,
                samples: None,
                mis: true,
            };
            rays += ctx.lights.add(
                &shadows,
                sp,
                &lobes,
                draw,
                Vec3::splat(scale),
                &mut self.light_columns,
            );
        }
        let slot = &mut self.dense[slot];
        let (diffuse, glossy_row) = slot.rows_for_sample(&mut scratch.rows);
        rays += accumulate_direct_rows(
            &shadows,
            ctx.samples,
            sp,
            scale,
            diffuse,
            glossy_row.map(|row| (here.alpha, row)),
        );
        slot.fold_sample(&here, &scratch.rows);
        rays
    }

    /// The pixel's albedo, coverage and light columns into `out`, and its rows, projected,
    /// transformed and thresholded, into `rows`.
    fn finish(
        self,
        ctx: &TileContext,
        pixel: u32,
        scratch: &mut Scratch,
        out: &mut TileOutput,
        rows: &mut Vec<(RowKind, RowData)>,
    ) {
        let scene = ctx.scene;
        let inv_spp = self.inv_spp;
        let mean_albedo = if self.hits > 0 {
            (self.albedo_sum / self.hits as f32).to_array()
        } else {
            [0.0; 3]
        };
        out.pixels
            .push((pixel, mean_albedo, self.covered * inv_spp));
        if !self.light_columns.is_empty() {
            out.lights.push((pixel, self.light_columns));
        }
        let white = self.white;
        let lobes = self
            .dense
            .into_iter()
            .flat_map(|slot| {
                let white_surface = crate::scene::Material::Diffuse { albedo: Vec3::ONE };
                let material = match white {
                    true => &white_surface,
                    false => &scene.materials[slot.material as usize],
                };
                slot.finish(material)
            })
            .enumerate()
            .map(|(i, (weight, row))| (RowKind::Lobe(i), weight, row));
        let channels = self.indirect.into_iter().flat_map(|rows| {
            rows.into_iter().enumerate().map(|(k, row)| {
                let weight = std::array::from_fn(|i| (i == k) as u8 as f32);
                (RowKind::Channels, weight, row)
            })
        });
        // Every row with its kind, its pixel and the scale of its thresholding budget.
        let reference_energy = ctx.reference_energy;
        let lobes = lobes
            .chain(channels)
            .map(|(kind, weight, row)| (kind, pixel, weight, row, reference_energy));
        let scattered = ctx.medium.zip(ctx.medium_rows).and_then(|(m, rows)| {
            let p = pixel as usize;
            Some((
                RowKind::Medium,
                pixel,
                m.albedo.to_array(),
                rows.row(p)?,
                rows.reference_energy(p),
            ))
        });
        let n = ctx.settings.cube_n;
        let pixel_rows: Vec<_> = lobes.chain(scattered).collect();
        let dense: Vec<&[f32]> = pixel_rows.iter().map(|r| &r.3[..]).collect();
        let sh = ctx.basis.project_rows(&dense);
        for ((kind, pixel, weight, mut row, budget_scale), sh) in pixel_rows.into_iter().zip(sh) {
            haar::forward_face_all(&mut row, n, &mut scratch.haar);
            let (entries, dropped, total) =
                ctx.thresholder
                    .sparsify(&row, budget_scale, &mut scratch.order);
            out.dropped_energy += dropped;
            out.total_energy += total;
            rows.push((
                kind,
                RowData {
                    pixel,
                    weight,
                    entries,
                    sh,
                },
            ));
        }
    }
}
