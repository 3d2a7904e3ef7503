//! The report of `prt gloss`: its markdown tables, its CSV and its plot's curves.

use std::fmt::Write as _;

use super::{FrameTime, GlossBenchOptions, GlossBenchReport, GlossMethod};
use crate::app::studies::percent_cells;
use crate::output::plot::{PALETTE, Series};

/// The mean of `errors` (one per camera).
fn mean(errors: &[f64]) -> f64 {
    errors.iter().sum::<f64>() / errors.len().max(1) as f64
}

/// The plot's curves: per method, then per SH order, the error (mean over the cameras) against
/// the CPU frame's time at the first K (the relight and the draw), a point per tessellation.
pub(super) fn error_series(r: &GlossBenchReport) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    let mut curve = |label: String, mut points: Vec<(f64, f64)>, dashed: bool| {
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let color = PALETTE[out.len() % PALETTE.len()];
        out.push(Series {
            label,
            points,
            color,
            dashed,
        });
    };
    let mut methods: Vec<GlossMethod> = r.bakes.iter().map(|b| b.method).collect();
    methods.sort_by_key(|&m| m as u8);
    methods.dedup();
    for m in methods {
        let points = r
            .bakes
            .iter()
            .filter(|b| b.method == m)
            .filter_map(|b| {
                let f = b.cpu.first()?;
                Some((f.relight_ms + f.draw_ms, mean(&b.error)))
            })
            .collect();
        curve(m.label().to_string(), points, false);
    }
    let mut orders: Vec<usize> = r.sh.iter().map(|s| s.order).collect();
    orders.sort_unstable();
    orders.dedup();
    for o in orders {
        let points =
            r.sh.iter()
                .filter(|s| s.order == o)
                .map(|s| (s.cpu_ms[0] + s.cpu_ms[1], mean(&s.error)))
                .collect();
        curve(format!("SH transfer, order {o}"), points, true);
    }
    out
}

/// The report as markdown.
pub fn markdown(r: &GlossBenchReport, opts: &GlossBenchOptions) -> String {
    let mut s = String::new();
    let glossy: Vec<String> = r
        .glossy
        .iter()
        .map(|(n, rough)| format!("`{n}` (roughness {rough})"))
        .collect();
    let _ = writeln!(
        s,
        "# Glossy per-vertex bakes against the path tracer\n\nUnder `{}`; glossy materials {}. \
         Relative L2 over the whole image (the background black), every light term ({} samples \
         a pixel); the path tracer at {} paths a pixel, lit by the map's own \
         pixels.\n",
        r.env,
        glossy.join(", "),
        opts.samples,
        opts.paths
    );
    let _ = writeln!(
        s,
        "## Cameras\n\n| camera | eye | target | path tracer's noise | interpolation, per tessellation |\n|---:|---|---|---:|---|"
    );
    for (i, c) in r.cameras.iter().enumerate() {
        let interp: Vec<String> = c
            .interpolation
            .iter()
            .zip(&opts.edge_factors)
            .map(|(e, f)| format!("{:.2}% (edges {f}x)", 100.0 * e))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {:.2}, {:.2}, {:.2} | {:.2}, {:.2}, {:.2} | {:.1}% | {} |",
            i + 1,
            c.eye[0],
            c.eye[1],
            c.eye[2],
            c.target[0],
            c.target[1],
            c.target[2],
            100.0 * c.noise,
            interp.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "\nThe interpolation is the diffuse base drawn against the brute force of the scene made \
         diffuse, over the pixels both cover whole: what drawing between vertices costs, apart \
         from the glossy methods.\n"
    );
    error_table(&mut s, r, opts);
    frame_table(&mut s, r, opts);
    s.push_str(&crate::app::studies::gloss_sh::markdown(
        &r.sh,
        opts.cameras.len(),
        [opts.frame_side as usize, opts.runs, opts.light_terms[0]],
    ));
    s
}

/// The report's table of each bake's error against the path tracer, and what its columns mean.
fn error_table(s: &mut String, r: &GlossBenchReport, opts: &GlossBenchOptions) {
    let cams = (1..=r.cameras.len())
        .map(|i| format!(" camera {i} |"))
        .collect::<String>();
    let ks = opts
        .light_terms
        .iter()
        .map(|k| format!(" K = {k} vs every term |"))
        .collect::<String>();
    let _ = writeln!(
        s,
        "## Error against the path tracer\n\n| edges | vertices | method |{cams} within the \
         outline | on glossy pixels |{ks} file | bytes a vertex | bake (s) |\n|---|---:|---|{}{}\
         ---:|---:|---:|",
        "---:|".repeat(r.cameras.len() + 2),
        "---:|".repeat(opts.light_terms.len())
    );
    for b in &r.bakes {
        let errors = percent_cells(b.error.iter().copied());
        let inside = b
            .inside
            .iter()
            .map(|e| format!("{:.2}", 100.0 * e))
            .collect::<Vec<_>>()
            .join(" / ");
        let glossy = b
            .glossy
            .iter()
            .map(|e| e.map_or("–".to_string(), |e| format!("{:.2}", 100.0 * e)))
            .collect::<Vec<_>>()
            .join(" / ");
        let light = percent_cells(b.light_error.iter().copied());
        let _ = writeln!(
            s,
            "| {}x ({:.3}) | {} | {} |{errors} {inside}% | {glossy}% |{light} {:.1} MiB | {:.0} | \
             {:.1}{} |",
            b.edge_factor,
            b.edge_length,
            b.vertices,
            b.method.label(),
            b.bytes as f64 / (1u64 << 20) as f64,
            b.bytes as f64 / b.vertices.max(1) as f64,
            b.bake_seconds,
            if b.reused { " (kept)" } else { "" }
        );
    }
    let _ = writeln!(
        s,
        "\nWithin the outline: the same error over the pixels that the drawing and the scene both \
         cover whole, camera by camera. The outline is left out: a pixel there is partly \
         covered, and a grazing highlight in it, which the drawing's few samples a pixel catch \
         or miss, can outweigh the rest of the image (`--samples 16` draws nearer the pixel's \
         mean). On glossy pixels: the same over the pixels that the glossy materials alone \
         cover whole (a glossy object without the diffuse ground it stands on, where every \
         method draws the same), – where a camera sees none."
    );
}

/// The report's table of each bake's frame time.
fn frame_table(s: &mut String, r: &GlossBenchReport, opts: &GlossBenchOptions) {
    let _ = writeln!(
        s,
        "\n## Frame time\n\nRelight at K terms, then draw {0}x{0} at one sample a pixel from \
         camera 1, median of {1}, milliseconds (relight + draw){2}.\n",
        opts.frame_side,
        opts.runs,
        match &r.gpu {
            Some(g) => format!(
                "; on the GPU ({g}) the kernel's own time, then the colours uploaded, drawn and \
                 read back"
            ),
            None => String::new(),
        }
    );
    let heads: String = opts
        .light_terms
        .iter()
        .map(|k| {
            let mut h = format!(" CPU, K = {k} |");
            if r.gpu.is_some() {
                let _ = write!(h, " GPU, K = {k} |");
            }
            h
        })
        .collect();
    let cols = opts.light_terms.len() * (1 + r.gpu.is_some() as usize);
    let _ = writeln!(
        s,
        "| edges | method |{heads}\n|---|---|{}",
        "---:|".repeat(cols)
    );
    let cell = |f: &FrameTime| {
        format!(
            " {:.1} + {:.1} = {:.1} |",
            f.relight_ms,
            f.draw_ms,
            f.relight_ms + f.draw_ms
        )
    };
    for b in &r.bakes {
        let mut line = format!("| {}x | {} |", b.edge_factor, b.method.label());
        for (i, c) in b.cpu.iter().enumerate() {
            line.push_str(&cell(c));
            if let Some(g) = b.gpu.as_ref().and_then(|g| g.get(i)) {
                line.push_str(&cell(g));
            }
        }
        let _ = writeln!(s, "{line}");
    }
}

/// The report as CSV: one line per bake and camera.
pub fn csv(r: &GlossBenchReport) -> String {
    let mut s = String::from(
        "edge_factor,edge_length,vertices,method,bytes,bake_seconds,reused,camera,rel_l2,rel_l2_inside,rel_l2_glossy,interpolation,path_tracer_noise\n",
    );
    let factors: Vec<f32> = {
        let mut f: Vec<f32> = r.bakes.iter().map(|b| b.edge_factor).collect();
        f.dedup();
        f
    };
    for b in &r.bakes {
        let t = factors
            .iter()
            .position(|f| *f == b.edge_factor)
            .unwrap_or(0);
        for (c, cam) in r.cameras.iter().enumerate() {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{:.3},{},{},{:.6},{:.6},{},{:.6},{:.6}",
                b.edge_factor,
                b.edge_length,
                b.vertices,
                b.method,
                b.bytes,
                b.bake_seconds,
                b.reused,
                c + 1,
                b.error[c],
                b.inside.get(c).copied().unwrap_or_default(),
                b.glossy
                    .get(c)
                    .copied()
                    .flatten()
                    .map_or(String::new(), |e| format!("{e:.6}")),
                cam.interpolation.get(t).copied().unwrap_or_default(),
                cam.noise
            );
        }
    }
    s
}
