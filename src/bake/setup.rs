//! What every tile of a bake reads, built once before the tiles: the edge map, a medium's
//! stages, the interreflections' cache and paths, the local lights' sampler, the texel samples
//! and their SH basis, and the thresholding budgets, gathered into the tiles' context.

use super::tile::TileContext;
use super::{BakeProgress, BakeSettings, CentrePackets, EdgeMap, LightSampler, bounce};
use crate::bake::medium_light::MediumLight;
use crate::bake::medium_rows::MediumRows;
use crate::error::Result;
use crate::math::haar;
use crate::math::sampling::TexelSamples;
use crate::math::texel_sh::TexelShBasis;
use crate::medium::Medium;
use crate::scene::Scene;
use crate::scene::tessellate::VertexMesh;
use crate::scene::trace::Tracer;
use crate::store::budget::Thresholder;
use crate::store::transport::BakeIdentity;

/// What a bake's tiles' context is built from.
pub(super) struct TileParts<'a> {
    pub(super) scene: &'a Scene,
    pub(super) settings: &'a BakeSettings,
    pub(super) identity: &'a BakeIdentity,
    pub(super) tracer: &'a Tracer,
    pub(super) mesh: Option<&'a VertexMesh>,
    /// Size of the image the rows belong to.
    pub(super) size: [usize; 2],
    /// Pixels (or vertices) the bake makes rows for, as its progress reports them.
    pub(super) pixels_total: usize,
}

/// Builds the tiles' context from `p`, the stages before the tiles reporting to `progress` and
/// a medium's rows made for the pixels `mine_pixel`, and hands it to `f`.
pub(super) fn with_tile_context<R>(
    p: &TileParts,
    mine_pixel: &(dyn Fn(usize) -> bool + Sync),
    progress: &(dyn Fn(BakeProgress) + Sync),
    f: impl FnOnce(&TileContext) -> Result<R>,
) -> Result<R> {
    let (scene, settings, tracer) = (p.scene, p.settings, p.tracer);
    let [w, h] = p.size;
    let samples = TexelSamples::new(
        settings.cube_n,
        settings.texel_samples as usize,
        settings.seed,
    )
    .refined(settings.stored_edge_texel_samples() as usize);
    // The centres the shading points trace: the quadrature's, or the samples' at one a texel.
    let packets = match &samples.refine {
        Some(q) => Some(CentrePackets::new(q.n, &q.centres)),
        None => (samples.per_texel == 1).then(|| CentrePackets::new(samples.n, &samples.dirs)),
    };
    let basis = TexelShBasis::new(settings.cube_n, settings.sh_order)?;
    let medium = match &scene.medium {
        Some(spec) => Some(spec.build(None)?),
        None => None,
    };
    // The pixels that take more sub-samples (none per vertex); the cache's paths start at the
    // same ones as the rows.
    let edges = EdgeMap::new(scene, tracer, settings);
    let edge_pixels = edges.count();
    let stage = |medium_light: [usize; 2], medium_texels: [usize; 2], cache_points: [usize; 2]| {
        progress(BakeProgress {
            pixels_done: 0,
            pixels_total: p.pixels_total,
            shadow_rays: 0,
            edge_pixels,
            medium_light,
            medium_texels,
            cache_points,
        })
    };
    let (medium_light, medium_rows) = medium_stages(
        medium.as_ref(),
        scene,
        tracer,
        &samples,
        settings,
        mine_pixel,
        &stage,
    )?;
    let through = medium.as_ref().zip(medium_light.as_ref());
    let bounces = bounce::Bounces::new(scene, tracer, settings, &samples)
        .with_medium(through.filter(|_| settings.bounces > 0))
        .keeping_walks(bounce::KEPT_BYTES)
        .with_cache(&edges, mine_pixel, &|done, total| {
            stage([0, 0], [0, 0], [done, total])
        })?;
    let light_sampler = LightSampler::new(scene, settings);
    let (reference_energy, thresholder) = budgets(p.identity, &samples);
    f(&TileContext {
        scene,
        width: w,
        height: h,
        mesh: p.mesh,
        tracer,
        edges: &edges,
        settings,
        reference_energy,
        thresholder,
        samples: &samples,
        packets: packets.as_ref(),
        basis: &basis,
        medium: medium.as_ref(),
        medium_rows: medium_rows.as_ref(),
        bounces: &bounces,
        lights: &light_sampler,
    })
}

/// A medium's stages before the tiles: what its points see of the texels (with bounces, the
/// transmittance table too), then its rows for the pixels `mine_pixel`, each reporting to
/// `stage(medium light, medium texels, cache points)`.
fn medium_stages(
    medium: Option<&Medium>,
    scene: &Scene,
    tracer: &Tracer,
    samples: &TexelSamples,
    settings: &BakeSettings,
    mine_pixel: &(dyn Fn(usize) -> bool + Sync),
    stage: &(dyn Fn([usize; 2], [usize; 2], [usize; 2]) + Sync),
) -> Result<(Option<MediumLight>, Option<MediumRows>)> {
    let Some(m) = medium else {
        return Ok((None, None));
    };
    let light = MediumLight::build(
        m,
        tracer,
        settings.cube_n,
        settings.bounces > 0,
        &|done, total| stage([done, total], [0, 0], [0, 0]),
    )?;
    let rows = MediumRows::bake(
        (m, &light),
        scene,
        tracer,
        samples,
        [settings.spp as u64, settings.seed],
        mine_pixel,
        &|done, total| stage([0, 0], [done, total], [0, 0]),
    )?;
    Ok((Some(light), Some(rows)))
}

/// The thresholding budget: the energy of an unshadowed row (the scale of every row's budget),
/// and the thresholder.
fn budgets(
    identity: &crate::store::transport::BakeIdentity,
    samples: &TexelSamples,
) -> (f64, Thresholder) {
    let mut reference_haar = unoccluded_row(samples);
    let reference_energy: f64 = reference_haar.iter().map(|&v| (v as f64).powi(2)).sum();
    haar::forward_face_all(&mut reference_haar, samples.n, &mut Vec::new());
    let thresholder = Thresholder::new(
        identity.budget,
        identity.threshold,
        samples.n,
        &reference_haar,
    );
    (reference_energy, thresholder)
}

/// The row of an unshadowed surface facing +Y with unit albedo, in texel order: the row the
/// thresholding budget is relative to (the same energy for every normal up to texel
/// discretisation).
fn unoccluded_row(samples: &TexelSamples) -> Vec<f32> {
    let m = samples.per_texel;
    (0..samples.dirs.len() / m)
        .map(|j| {
            ((j * m..(j + 1) * m)
                .map(|k| samples.dirs[k].y.max(0.0) as f64 * samples.weights[k] as f64)
                .sum::<f64>()
                * std::f64::consts::FRAC_1_PI) as f32
        })
        .collect()
}
