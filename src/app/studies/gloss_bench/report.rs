//! The report of `prt gloss`: its markdown tables, its CSV and its plot's curves.

use std::fmt::Write as _;

use super::{FrameTime, GlossBenchOptions, GlossBenchReport};
use crate::output::plot::{PALETTE, Series};

/// The plot's curves: per tessellation and camera, the error against K_b, and the visibility
/// bake's error (K_b = 0) as a level across the K_b axis.
pub(super) fn error_series(r: &GlossBenchReport, opts: &GlossBenchOptions) -> Vec<Series> {
    let mut out = Vec::new();
    let terms = || {
        opts.brdf_terms
            .iter()
            .filter(|&&k| k > 0)
            .map(|&k| k as f64)
    };
    // Without in-out bakes, the visibility's level spans every K_b the bench takes.
    let span = match terms().next() {
        Some(_) => [
            terms().fold(f64::INFINITY, f64::min),
            terms().fold(f64::NEG_INFINITY, f64::max),
        ],
        None => [1.0, 16.0],
    };
    for (f, &factor) in opts.edge_factors.iter().enumerate() {
        for (c, _) in r.cameras.iter().enumerate() {
            let color = PALETTE[(f * r.cameras.len() + c) % PALETTE.len()];
            let of = || r.bakes.iter().filter(|b| b.edge_factor == factor);
            out.push(Series {
                label: format!("camera {}, edges {factor}x", c + 1),
                points: of()
                    .filter(|b| b.brdf_terms > 0)
                    .map(|b| (b.brdf_terms as f64, b.error[c]))
                    .collect(),
                color,
                dashed: f % 2 == 1,
            });
            if let Some(v) = of().find(|b| b.brdf_terms == 0)
                && span[0] <= span[1]
            {
                out.push(Series {
                    label: format!("visibility, camera {}, edges {factor}x", c + 1),
                    points: span.iter().map(|&x| (x, v.error[c])).collect(),
                    color,
                    dashed: true,
                });
            }
        }
    }
    out
}

/// The K_b column of a bake: its count, or `visibility`.
fn method(k_b: u32) -> String {
    match k_b {
        0 => "visibility".into(),
        k => k.to_string(),
    }
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
         Relative L2 over the whole image (the background black), every stored term, `g_k` per \
         pixel ({} samples a pixel); the path tracer at {} paths a pixel, lit by the map's own \
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
         from the factorisation.\n"
    );
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
        "## Error against the path tracer\n\n| edges | vertices | K_b |{cams} `g_k` per vertex, \
         camera 1 |{ks} file | bytes a vertex | bake (s) |\n|---|---:|---:|{}{}---:|---:|---:|",
        "---:|".repeat(r.cameras.len() + 1),
        "---:|".repeat(opts.light_terms.len())
    );
    for b in &r.bakes {
        let errors: String = b
            .error
            .iter()
            .map(|e| format!(" {:.2}% |", 100.0 * e))
            .collect();
        let light: String = b
            .light_error
            .iter()
            .map(|e| format!(" {:.2}% |", 100.0 * e))
            .collect();
        let _ = writeln!(
            s,
            "| {}x ({:.3}) | {} | {} |{errors} {:.2}% |{light} {:.1} MiB | {:.0} | {:.1}{} |",
            b.edge_factor,
            b.edge_length,
            b.vertices,
            method(b.brdf_terms),
            100.0 * b.error_per_vertex.first().copied().unwrap_or(0.0),
            b.bytes as f64 / (1u64 << 20) as f64,
            b.bytes as f64 / b.vertices.max(1) as f64,
            b.bake_seconds,
            if b.reused { " (kept)" } else { "" }
        );
    }
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
        "| edges | K_b |{heads}\n|---|---:|{}",
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
        let mut line = format!("| {}x | {} |", b.edge_factor, method(b.brdf_terms));
        for (i, c) in b.cpu.iter().enumerate() {
            line.push_str(&cell(c));
            if let Some(g) = b.gpu.as_ref().and_then(|g| g.get(i)) {
                line.push_str(&cell(g));
            }
        }
        let _ = writeln!(s, "{line}");
    }
    s.push_str(&crate::app::studies::gloss_sh::markdown(
        &r.sh,
        opts.cameras.len(),
        [opts.frame_side as usize, opts.runs, opts.light_terms[0]],
    ));
    s
}

/// The report as CSV: one line per bake and camera.
pub fn csv(r: &GlossBenchReport) -> String {
    let mut s = String::from(
        "edge_factor,edge_length,vertices,brdf_terms,bytes,bake_seconds,reused,camera,rel_l2,rel_l2_per_vertex_gloss,interpolation,path_tracer_noise\n",
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
                "{},{},{},{},{},{:.3},{},{},{:.6},{:.6},{:.6},{:.6}",
                b.edge_factor,
                b.edge_length,
                b.vertices,
                b.brdf_terms,
                b.bytes,
                b.bake_seconds,
                b.reused,
                c + 1,
                b.error[c],
                b.error_per_vertex[c],
                cam.interpolation.get(t).copied().unwrap_or_default(),
                cam.noise
            );
        }
    }
    s
}
