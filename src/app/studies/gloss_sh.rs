//! `prt gloss --sh-transfer ORDERS`: beside each bake with visibility, its glossy light by SH
//! glossy transfer at each order (Sloan, Kautz & Snyder 2002; [`crate::draw::sh_gloss`]), held
//! to the same path tracer from the same cameras as the lobe per pixel, with what its matrices
//! take to build and would take to store, and a CPU frame.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use super::{median, percent_cells};
use crate::draw::vertex::draw_sh_glossy;
use crate::error::Result;
use crate::math::cube_pyramid::CubePyramid;
use crate::output::film::{Image, ToneMap};
use crate::output::metrics::relative_l2;
use crate::relight::sh_transfer::ShTransfer;
use crate::relight::{
    Backend, Cpu, LightContext, PreparedLight, RelightRequest, Terms, lobe_light,
};
use crate::store::transport::Transport;

/// One bake with visibility drawn by SH glossy transfer at one order.
#[derive(Clone, Debug)]
pub struct ShTransferRow {
    /// Edge length of the bake, as a multiple of the default.
    pub edge_factor: f32,
    /// SH order n (n² coefficients).
    pub order: usize,
    /// Glossy vertices (those with a matrix).
    pub glossy_vertices: usize,
    /// Seconds to build the matrices from the visibility bits.
    pub build_seconds: f64,
    /// Per camera: against the path tracer (relative L2 over the image).
    pub error: Vec<f64>,
    /// A CPU frame's median milliseconds at the first K of `prt gloss --terms`: the relight and
    /// the light's pyramid, then the transfer and the draw.
    pub cpu_ms: [f64; 2],
}

impl ShTransferRow {
    /// Bytes a glossy vertex's matrix would take stored.
    pub fn bytes_per_vertex(&self) -> usize {
        ShTransfer::bytes_per_vertex(self.order)
    }
}

/// What [`measure`] draws and compares: a bake with visibility, its light, its image relit with
/// every term and that light's pyramid, and each camera's path-traced reference and tone.
pub struct ShInputs<'a> {
    /// The bake with visibility.
    pub t: &'a Transport,
    /// Its light context.
    pub ctx: &'a LightContext,
    /// The light, prepared.
    pub light: &'a PreparedLight,
    /// Its image relit with every term.
    pub full: &'a Image,
    /// The pyramid of the light with every term.
    pub full_light: &'a CubePyramid,
    /// Per camera, the path tracer's image and its tone.
    pub references: &'a [(Image, ToneMap)],
    /// The bake's edge length as a multiple of the default.
    pub edge_factor: f32,
    /// The cameras the references were made from.
    pub cameras: &'a [crate::scene::Camera],
    /// Samples a pixel of the drawings compared with them.
    pub samples: u32,
    /// The timed frames: their side in pixels, how many, and the light's K terms.
    pub frame: [usize; 3],
}

/// Measures the SH glossy transfer of `i.t` at `order`, writing each camera's image into
/// `images`.
pub fn measure(i: &ShInputs, order: usize, images: &Path) -> Result<ShTransferRow> {
    let vis = crate::draw::vertex::mesh_of(i.t)?
        .visibility
        .as_deref()
        .expect("a bake with visibility");
    let start = Instant::now();
    let transfer = ShTransfer::new(vis, order)?;
    let build_seconds = start.elapsed().as_secs_f64();
    let mut error = Vec::new();
    for (c, (cam, (traced, tone))) in i.cameras.iter().zip(i.references).enumerate() {
        let drawn = draw_sh_glossy(
            i.t,
            i.full,
            (i.full_light, &[]),
            &transfer,
            cam,
            None,
            i.samples,
        )?;
        error.push(relative_l2(&drawn.image, traced, None)?);
        drawn.image.save(
            &images.join(format!(
                "camera{}_edges{}_sh{order}.exr",
                c + 1,
                i.edge_factor
            )),
            *tone,
        )?;
    }
    let [side, runs, k] = i.frame;
    let frame_cam = crate::scene::Camera {
        width: side as u32,
        height: side as u32,
        ..i.cameras[0].clone()
    };
    let req = RelightRequest::Wavelet {
        k,
        weighting: crate::env::select::Weighting::Transport,
    };
    let (mut relight_ms, mut draw_ms) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let t0 = Instant::now();
        let terms = Terms::of(i.t, i.ctx, i.light, &req)?;
        let (img, _) = Cpu(i.t).relight_terms(&terms)?;
        let pyramid = lobe_light(i.t, i.ctx, Some(i.light), &req)?.expect("visibility");
        let t1 = Instant::now();
        draw_sh_glossy(i.t, &img, (&pyramid, &[]), &transfer, &frame_cam, None, 1)?;
        relight_ms.push((t1 - t0).as_secs_f64() * 1e3);
        draw_ms.push(t1.elapsed().as_secs_f64() * 1e3);
    }
    Ok(ShTransferRow {
        edge_factor: i.edge_factor,
        order,
        glossy_vertices: transfer.rows(),
        build_seconds,
        error,
        cpu_ms: [median(relight_ms), median(draw_ms)],
    })
}

/// [`measure`] at each of `orders`, saying each row's errors to `log`.
pub fn measure_orders(
    i: &ShInputs,
    orders: &[usize],
    images: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<Vec<ShTransferRow>> {
    orders
        .iter()
        .map(|&order| {
            let row = measure(i, order, images)?;
            log(&format!(
                "edges {}x, SH glossy transfer at order {order}: against the path tracer {}",
                i.edge_factor,
                super::percents(&row.error)
            ));
            Ok(row)
        })
        .collect()
}

/// The SH transfer's section of the report, beside the lobe's figures of the same bakes, from
/// `cameras` cameras, the frames as [`ShInputs::frame`] says.
pub fn markdown(rows: &[ShTransferRow], cameras: usize, [side, runs, k]: [usize; 3]) -> String {
    let mut s = String::new();
    if rows.is_empty() {
        return s;
    }
    let cams = (1..=cameras)
        .map(|i| format!(" camera {i} |"))
        .collect::<String>();
    let _ = writeln!(
        s,
        "\n## SH glossy transfer\n\nThe bakes with visibility drawn by SH glossy transfer \
         (Sloan, Kautz & Snyder 2002): per glossy vertex the matrix of the shadowed light, built \
         from its visibility bits at load, and per pixel the lobe, symmetric about the \
         reflection, convolved with it. Against the path tracer as above; a frame at K = {k} and \
         {side}x{side} pixels, median of {runs}, milliseconds (relight and light + transfer and \
         draw).\n\n| edges | SH order |{cams} glossy vertices | bytes a vertex if stored | build \
         (s) | CPU frame |\n|---|---:|{rule}---:|---:|---:|---:|",
        rule = "---:|".repeat(cameras)
    );
    for r in rows {
        let errors = percent_cells(r.error.iter().copied());
        let _ = writeln!(
            s,
            "| {}x | {} |{errors} {} | {} | {:.2} | {:.1} + {:.1} = {:.1} |",
            r.edge_factor,
            r.order,
            r.glossy_vertices,
            r.bytes_per_vertex(),
            r.build_seconds,
            r.cpu_ms[0],
            r.cpu_ms[1],
            r.cpu_ms[0] + r.cpu_ms[1]
        );
    }
    s
}
