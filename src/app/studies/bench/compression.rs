//! The compression curve of a bake: the scene baked again at each threshold, each bake's size
//! and its error against the every-term relight of the file benched, beside Ng et al. 2003's
//! figures for the same sweep.

use super::*;

/// One point of the compression curve: a bake at one threshold, relit with every stored term
/// under one environment, against the lossless bake.
#[derive(Clone, Debug)]
pub struct CompressionPoint {
    /// The bake's threshold ([`BakeSettings::threshold`]): the L2 error allowed per row, relative
    /// to an unshadowed row's norm.
    pub threshold: f32,
    /// Name of the environment the bakes were relit under.
    pub env: String,
    /// Stored nonzeros over the dense entry count.
    pub kept_fraction: f64,
    /// Bytes of the sparse Haar matrix (entries, scales and entry counts) per pixel.
    pub bytes_per_pixel: f64,
    /// Stored coefficients per pixel.
    pub coefficients_per_pixel: f64,
    /// Relative L2 the sparsification adds to the relit image.
    pub rel_l2: f64,
}

/// Bakes `scene` losslessly and at every threshold (other settings from `base`, SH order 1 to
/// save time), relights each with every stored term under every environment and measures the
/// error thresholding adds. `log` receives a line per bake, `progress` each bake's progress.
pub fn compression_sweep(
    scene: &Scene,
    base: &BakeSettings,
    thresholds: &[f32],
    envs: &[(String, EnvMap)],
    log: &mut dyn FnMut(&str),
    progress: &(dyn Fn(crate::bake::BakeProgress) + Sync),
) -> Result<Vec<CompressionPoint>> {
    if thresholds.is_empty() {
        return Err(PrtError::invalid("threshold list", "it is empty"));
    }
    let settings = |lossless: bool, threshold: f32| BakeSettings {
        sh_order: 1,
        lossless,
        threshold,
        ..base.clone()
    };
    for &th in thresholds {
        settings(false, th).validate()?;
    }
    log("baking the lossless reference");
    let exact = bake(scene, &settings(true, 0.0), progress)?;
    let ctx = LightContext::new(&exact)?;
    let all = |t: &Transport, light: &crate::relight::PreparedLight| -> Result<Image> {
        Ok(relight(t, &ctx, light, &RelightRequest::Full)?.0)
    };
    let lights: Vec<_> = envs
        .iter()
        .map(|(_, env)| ctx.prepare(env, EnvRotation::default()))
        .collect::<Result<_>>()?;
    let references: Vec<Image> = lights
        .iter()
        .map(|l| all(&exact, l))
        .collect::<Result<_>>()?;
    let mut points = Vec::new();
    for &th in thresholds {
        log(&format!("baking at threshold {th}"));
        let t = bake(scene, &settings(false, th), progress)?;
        let kept_fraction = t.meta.stats.nonzeros as f64 / t.meta.stats.dense_entries.max(1) as f64;
        let bytes_per_pixel = t.haar_bytes() as f64 / t.pixel_count() as f64;
        for (((name, _), light), reference) in envs.iter().zip(&lights).zip(&references) {
            points.push(CompressionPoint {
                threshold: th,
                env: name.clone(),
                kept_fraction,
                bytes_per_pixel,
                coefficients_per_pixel: t.meta.stats.nonzeros as f64 / t.pixel_count() as f64,
                rel_l2: relative_l2(&all(&t, light)?, reference, Some(&exact.coverage))?,
            });
        }
    }
    Ok(points)
}

/// Writes `compression.csv`, `compression.png` (added error against kept fraction, one curve per
/// environment, Ng et al.'s kept fraction beside them) and `compression.md` (the same as a table
/// with bytes per pixel and per coefficient). Returns the paths written.
pub fn write_compression(dir: &Path, points: &[CompressionPoint]) -> Result<Vec<PathBuf>> {
    crate::files::create_folder(dir)?;
    let mut text = String::from("threshold,environment,kept_fraction,bytes_per_pixel,rel_l2\n");
    for p in points {
        let _ = writeln!(
            text,
            "{},{},{:.6e},{:.2},{:.6e}",
            p.threshold, p.env, p.kept_fraction, p.bytes_per_pixel, p.rel_l2
        );
    }
    let csv_path = dir.join("compression.csv");
    crate::files::write_bytes_atomically(&csv_path, text.as_bytes())?;
    let mut envs: Vec<&str> = Vec::new();
    for p in points {
        if !envs.contains(&p.env.as_str()) {
            envs.push(&p.env);
        }
    }
    let series: Vec<Series> = envs
        .iter()
        .enumerate()
        .map(|(i, env)| Series {
            label: env.to_string(),
            points: points
                .iter()
                .filter(|p| p.env == *env)
                .map(|p| (100.0 * p.kept_fraction, p.rel_l2))
                .collect(),
            color: plot::PALETTE[i % plot::PALETTE.len()],
            dashed: false,
        })
        .collect();
    let mut series = series;
    if let Some(band) = ng_band(points) {
        series.push(band);
    }
    let png = dir.join("compression.png");
    plot::write(
        &png,
        &PlotSpec {
            title: "Error added by sparsification vs stored fraction".into(),
            x_label: "stored nonzeros (% of dense)".into(),
            y_label: "relative L2 error".into(),
            log_x: true,
            log_y: true,
            width: 800,
            height: 560,
        },
        &series,
    )?;
    let md = dir.join("compression.md");
    let table = compression_table(points, &envs);
    crate::files::write_bytes_atomically(&md, table.as_bytes())?;
    Ok(vec![csv_path, png, md])
}

/// The fraction of Haar coefficients Ng et al. 2003 (Table 1) kept at a 6x32x32 cube, in percent:
/// the outline of a band across the measured error range, drawn beside the curves. `None` when
/// there are no points.
fn ng_band(points: &[CompressionPoint]) -> Option<Series> {
    let errors = points.iter().map(|p| p.rel_l2).filter(|e| *e > 0.0);
    let lo = errors.clone().fold(f64::INFINITY, f64::min);
    let hi = errors.fold(0.0, f64::max);
    if !(lo.is_finite() && hi > 0.0) {
        return None;
    }
    Some(Series {
        label: "Ng et al. 2003, 6x32x32: 10-12% kept".into(),
        points: vec![(10.0, lo), (10.0, hi), (12.0, hi), (12.0, lo), (10.0, lo)],
        color: [120, 120, 120],
        dashed: true,
    })
}

/// The compression curve as a Markdown table: one row per threshold with the kept fraction, the
/// bytes per pixel and per stored coefficient (every place, count and scale table counted), and the
/// added error under each environment.
fn compression_table(points: &[CompressionPoint], envs: &[&str]) -> String {
    let mut text = String::from(
        "# Compression curve\n\nEach threshold is a bake of the scene, relit with every stored term \
         and compared with the lossless bake (relative L2 over covered pixels). Bytes count the \
         sparse Haar matrix as the file stores it: the strips' places and values, and each \
         (block, coefficient)'s strip count and scale code.\n\n\
         | threshold | kept | bytes / pixel | bytes / coefficient |",
    );
    for env in envs {
        let _ = write!(text, " {env} |");
    }
    text.push_str("\n|---:|---:|---:|---:|");
    text.push_str(&"---:|".repeat(envs.len()));
    text.push('\n');
    let mut thresholds: Vec<f32> = Vec::new();
    for p in points {
        if !thresholds.contains(&p.threshold) {
            thresholds.push(p.threshold);
        }
    }
    for th in thresholds {
        let row: Vec<&CompressionPoint> = points.iter().filter(|p| p.threshold == th).collect();
        let Some(first) = row.first() else { continue };
        let per_coefficient = first.bytes_per_pixel / first.coefficients_per_pixel.max(1e-30);
        let _ = write!(
            text,
            "| {th} | {:.1}% | {:.0} | {per_coefficient:.2} |",
            100.0 * first.kept_fraction,
            first.bytes_per_pixel
        );
        for env in envs {
            match row.iter().find(|p| p.env == *env) {
                Some(p) => {
                    let _ = write!(text, " {:.2}% |", 100.0 * p.rel_l2);
                }
                None => text.push_str(" — |"),
            }
        }
        text.push('\n');
    }
    text.push_str(
        "\nNg et al. 2003 (Table 1) kept 10-12% of the coefficients at 6x32x32 and 3.1-3.8% at \
         6x64x64, at 2 bytes a coefficient (an 8-bit value and an 8-bit row index in blocks of \
         256 rows).\n",
    );
    text
}
