//! `prt brdf`: the in-out factorisation of GGX lobes, its error against the number of terms per
//! roughness, as a table and a plot.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::error::{PrtError, Result};
use crate::output::plot::{self, PlotSpec, Series};
use crate::scene::brdf_factor::GgxFactors;

/// Arguments of `prt brdf`.
#[derive(Args, Debug)]
pub struct BrdfArgs {
    /// Output directory for brdf_factors.md and brdf_factors.png.
    #[arg(long)]
    pub out: PathBuf,
    /// GGX roughnesses (α = roughness²), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.05,0.1,0.2,0.3,0.5")]
    pub roughness: Vec<f32>,
    /// GGX terms kept per lobe (K_b is one more, for the Lambertian term).
    #[arg(long, default_value_t = 16)]
    pub terms: usize,
    /// Cells per side of the hemi-octahedral maps of view and light directions.
    #[arg(long, default_value_t = 32)]
    pub resolution: usize,
}

/// Relative errors the table gives the fewest terms for.
const TARGETS: [f64; 3] = [0.1, 0.05, 0.02];

pub(super) fn brdf_cmd(a: BrdfArgs) -> Result<()> {
    if !(4..=64).contains(&a.resolution) {
        return Err(PrtError::invalid(
            "--resolution",
            format!("{}; it goes from 4 to 64", a.resolution),
        ));
    }
    if !(1..=64).contains(&a.terms) {
        return Err(PrtError::invalid(
            "--terms",
            format!("{}; it goes from 1 to 64", a.terms),
        ));
    }
    if a.roughness.is_empty() || a.roughness.iter().any(|r| !(0.02..=1.0).contains(r)) {
        return Err(PrtError::invalid(
            "--roughness",
            format!("{:?}; each must be from 0.02 to 1", a.roughness),
        ));
    }
    crate::files::check_output_folder(&a.out)?;
    std::fs::create_dir_all(&a.out).map_err(|e| PrtError::io(&a.out, e))?;
    let mut all = Vec::new();
    for &r in &a.roughness {
        let start = Instant::now();
        let f = GgxFactors::new(r * r, a.resolution, a.terms);
        eprintln!(
            "roughness {r}: {} terms in {:.1} s, {:.2}% left by 4",
            f.terms(),
            start.elapsed().as_secs_f64(),
            100.0 * f.error(4.min(f.terms()))
        );
        all.push((r, f));
    }
    let mut md = format!(
        "In-out factorisation of the cosine-weighted GGX lobe, `{0}×{0}` hemi-octahedral maps of \
         view and light directions, each light cell averaged over 4×4 directions, the error \
         weighted by solid angle. Relative L2 of the lobe with k GGX terms (a material's K_b is \
         k + 1, its Lambertian term exact).\n\n| k |",
        a.resolution
    );
    for (r, _) in &all {
        md += &format!(" roughness {r} |");
    }
    md += "\n|---:|";
    md += &"---:|".repeat(all.len());
    md += "\n";
    for k in 1..=a.terms {
        md += &format!("| {k} |");
        for (_, f) in &all {
            md += &format!(" {:.2}% |", 100.0 * f.error(k));
        }
        md += "\n";
    }
    md += "\nFewest GGX terms to reach an error (more than kept: `>`):\n\n| error |";
    for (r, _) in &all {
        md += &format!(" roughness {r} |");
    }
    md += "\n|---:|";
    md += &"---:|".repeat(all.len());
    md += "\n";
    for t in TARGETS {
        md += &format!("| {}% |", 100.0 * t);
        for (_, f) in &all {
            match (0..=f.terms()).find(|&k| f.error(k) <= t) {
                Some(k) => md += &format!(" {k} |"),
                None => md += &format!(" > {} |", f.terms()),
            }
        }
        md += "\n";
    }
    let table = a.out.join("brdf_factors.md");
    crate::files::write_bytes_atomically(&table, md.as_bytes())?;
    let series: Vec<Series> = all
        .iter()
        .enumerate()
        .map(|(i, (r, f))| Series {
            label: format!("roughness {r}"),
            points: (1..=f.terms())
                .map(|k| (k as f64, f.error(k).max(1e-6)))
                .collect(),
            color: plot::PALETTE[i % plot::PALETTE.len()],
            dashed: false,
        })
        .collect();
    let figure = a.out.join("brdf_factors.png");
    plot::write(
        &figure,
        &PlotSpec {
            title: "GGX lobe factorised into in-out terms".into(),
            x_label: "GGX terms k".into(),
            y_label: "relative L2 of the lobe".into(),
            log_x: false,
            log_y: true,
            width: 720,
            height: 440,
        },
        &series,
    )?;
    println!("wrote {} and {}", table.display(), figure.display());
    Ok(())
}
