//! Line plots for the benchmark reports (error and time against terms), drawn with `plotters` and
//! written as PNG. Text is set by [`crate::output::text`] (antialiased); the whole plot is drawn at twice its size and averaged down, so lines and
//! markers are antialiased too.
//!
//! Either axis may be logarithmic. A log axis spans whole decades, labels powers of ten and draws
//! light lines at 2..9 times each; a linear axis ticks at about five round values. A legend sits in
//! the upper-right corner inside the frame.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{PrtError, Result};
use crate::output::film::write_png;
use crate::output::text::FONT;

/// One curve.
pub struct Series {
    /// Name in the legend.
    pub label: String,
    /// The `(x, y)` points, joined in order.
    pub points: Vec<(f64, f64)>,
    /// Colour of the line and markers, RGB8.
    pub color: [u8; 3],
    /// Draw a dashed line instead of a solid one.
    pub dashed: bool,
}

/// Axes and size.
pub struct PlotSpec {
    /// Caption above the plot.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Width of the image, pixels (160 to 8192).
    pub width: usize,
    /// Height of the image, pixels (160 to 8192).
    pub height: usize,
}

/// A palette of 8 distinguishable colours for series.
pub const PALETTE: [[u8; 3]; 8] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
];

const GRID: RGBColor = RGBColor(225, 225, 225);
const MINOR_GRID: RGBColor = RGBColor(240, 240, 240);
const FRAME: RGBColor = RGBColor(70, 70, 70);
const TEXT: RGBColor = RGBColor(25, 25, 25);
const LEGEND_BORDER: RGBColor = RGBColor(170, 170, 170);
const MIN_SIZE: usize = 160;
const MAX_SIZE: usize = 8192;
/// Drawn at this multiple of the output size, then averaged down.
const SUPERSAMPLE: usize = 2;
/// A tick label for the power of ten `10^e`: plain digits near 1, `1e<e>` beyond.
fn decade_label(e: i32) -> String {
    match e {
        -2 => "0.01".into(),
        -1 => "0.1".into(),
        0..=3 => 10u32.pow(e as u32).to_string(),
        _ => format!("1e{e}"),
    }
}

/// `floor(log10(x))`, robust to values a hair below a power of ten.
fn floor_log10(x: f64) -> i32 {
    (x.log10() + 1e-9).floor() as i32
}

/// A tick label for `v` on a linear axis whose ticks are `step` apart: fixed-point with as many
/// decimals as the step needs, or `<mantissa>e<exponent>` for very large or very fine values.
fn linear_label(v: f64, step: f64) -> String {
    if v.abs() < step * 1e-6 {
        return "0".into();
    }
    let step_exp = floor_log10(step);
    if v.abs() < 1e5 && step_exp >= -3 {
        let decimals = (-step_exp).max(0) as usize;
        return format!("{v:.decimals$}");
    }
    let digits = (floor_log10(v.abs()) - step_exp).max(0) as usize;
    let s = format!("{v:.digits$e}");
    let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
    let mantissa = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    format!("{mantissa}e{exp}")
}

/// A "nice" step (1, 2 or 5 times a power of ten) near `raw`.
fn nice_step(raw: f64) -> f64 {
    let mag = 10f64.powi(floor_log10(raw));
    let norm = raw / mag;
    let m = if norm < 1.5 {
        1.0
    } else if norm < 3.5 {
        2.0
    } else if norm < 7.5 {
        5.0
    } else {
        10.0
    };
    m * mag
}

/// Plotted coordinate of a data value on a linear or log axis, or None if it cannot be shown.
fn plotted(log: bool, v: f64) -> Option<f64> {
    match (v.is_finite(), log) {
        (false, _) => None,
        (true, true) if v <= 0.0 => None,
        (true, true) => Some(v.log10()),
        (true, false) => Some(v),
    }
}

/// One axis in plotted coordinates (log10 of the value on a log axis): its range, the step
/// between labelled ticks, and the unlabelled minor lines.
#[derive(Debug)]
struct Axis {
    log: bool,
    lo: f64,
    hi: f64,
    step: f64,
    minor: Vec<f64>,
}

impl Axis {
    /// The range and ticks for data spanning `[dmin, dmax]` (plotted coordinates).
    fn new(log: bool, dmin: f64, dmax: f64) -> Axis {
        if log {
            let (mut lo, mut hi) = (dmin.floor(), dmax.ceil());
            if hi - lo < 1.0 {
                lo -= 1.0;
                hi += 1.0;
            }
            // Every decade labelled while there are at most 8, else every 2nd, 5th, ...
            let step = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0]
                .into_iter()
                .find(|s| (hi - lo) / s <= 8.0)
                .unwrap_or(100.0);
            let minor = if step == 1.0 {
                (lo as i32..hi as i32)
                    .flat_map(|e| (2..10).map(move |m| e as f64 + (m as f64).log10()))
                    .collect()
            } else {
                Vec::new()
            };
            return Axis {
                log,
                lo,
                hi,
                step,
                minor,
            };
        }
        let (dmin, dmax) = if dmax > dmin {
            (dmin, dmax)
        } else if dmin == 0.0 {
            (-1.0, 1.0)
        } else {
            (dmin - 0.5 * dmin.abs(), dmax + 0.5 * dmax.abs())
        };
        let step = nice_step((dmax - dmin) / 5.0);
        Axis {
            log,
            lo: (dmin / step).floor() * step,
            hi: (dmax / step).ceil() * step,
            step,
            minor: Vec::new(),
        }
    }

    /// Labelled tick positions.
    fn ticks(&self) -> Vec<f64> {
        let n = ((self.hi - self.lo) / self.step).round() as i64;
        (0..=n).map(|i| self.lo + i as f64 * self.step).collect()
    }

    fn label(&self, v: f64) -> String {
        if self.log {
            decade_label(v.round() as i32)
        } else {
            linear_label(v, self.step)
        }
    }

    /// The range with a margin, so markers never sit on the frame.
    fn padded(&self) -> std::ops::Range<f64> {
        let pad = 0.03 * (self.hi - self.lo);
        self.lo - pad..self.hi + pad
    }
}

/// Renders to RGB8 bytes (width*height*3), white background.
///
/// Points with a non-finite coordinate, or a non-positive one on a log axis, are skipped; a
/// series left with no points is neither drawn nor listed in the legend. If no series has a point
/// left, this is an error naming the plot.
pub fn render(spec: &PlotSpec, series: &[Series]) -> Result<Vec<u8>> {
    let (w, h) = (spec.width, spec.height);
    let named = |message: String| PrtError::invalid(format!("plot \"{}\"", spec.title), message);
    if !(MIN_SIZE..=MAX_SIZE).contains(&w) || !(MIN_SIZE..=MAX_SIZE).contains(&h) {
        return Err(named(format!(
            "size {w}x{h} is outside {MIN_SIZE}..={MAX_SIZE} pixels per side"
        )));
    }
    let points: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter_map(|&(x, y)| Some((plotted(spec.log_x, x)?, plotted(spec.log_y, y)?)))
                .collect()
        })
        .collect();
    let all = || points.iter().flatten();
    if all().next().is_none() {
        let need = match (spec.log_x, spec.log_y) {
            (false, false) => "finite",
            _ => "finite and positive on log axes",
        };
        return Err(named(format!(
            "no point to draw: every series is empty or has no {need} point"
        )));
    }
    let range = |f: fn(&(f64, f64)) -> f64| {
        all()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            })
    };
    let ((x0, x1), (y0, y1)) = (range(|p| p.0), range(|p| p.1));
    let (xa, ya) = (Axis::new(spec.log_x, x0, x1), Axis::new(spec.log_y, y0, y1));
    crate::output::text::register()?;
    let s = SUPERSAMPLE;
    let mut big = vec![255u8; w * s * h * s * 3];
    draw(spec, series, &points, &xa, &ya, &mut big).map_err(|e| named(e.to_string()))?;
    Ok(average_down(&big, w, h, s))
}

/// Draws the plot at [`SUPERSAMPLE`] times its size into `buffer`.
fn draw(
    spec: &PlotSpec,
    series: &[Series],
    points: &[Vec<(f64, f64)>],
    xa: &Axis,
    ya: &Axis,
    buffer: &mut [u8],
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let s = SUPERSAMPLE as u32;
    let size = (
        (spec.width * SUPERSAMPLE) as u32,
        (spec.height * SUPERSAMPLE) as u32,
    );
    let root = BitMapBackend::with_buffer(buffer, size).into_drawing_area();
    root.fill(&WHITE)?;
    let text = |pt: u32| (FONT, (pt * s) as f64).into_font().color(&TEXT);
    let mut chart = ChartBuilder::on(&root)
        .caption(&spec.title, text(15))
        .margin(10 * s)
        .x_label_area_size(38 * s)
        .y_label_area_size(56 * s)
        .build_cartesian_2d(xa.padded(), ya.padded())?;
    let (x_ticks, y_ticks) = (xa.ticks(), ya.ticks());
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(spec.x_label.as_str())
        .y_desc(spec.y_label.as_str())
        .axis_desc_style(text(13))
        .label_style(text(12))
        .axis_style(FRAME.stroke_width(s))
        .x_labels(0)
        .y_labels(0)
        .draw()?;
    // Grid lines and tick labels at our own ticks (whole decades on log axes).
    let (xr, yr) = (xa.padded(), ya.padded());
    let thin = |c: RGBColor| c.stroke_width(s);
    for &m in &xa.minor {
        chart.draw_series(LineSeries::new(
            [(m, yr.start), (m, yr.end)],
            thin(MINOR_GRID),
        ))?;
    }
    for &m in &ya.minor {
        chart.draw_series(LineSeries::new(
            [(xr.start, m), (xr.end, m)],
            thin(MINOR_GRID),
        ))?;
    }
    for &t in &x_ticks {
        chart.draw_series(LineSeries::new([(t, yr.start), (t, yr.end)], thin(GRID)))?;
    }
    for &t in &y_ticks {
        chart.draw_series(LineSeries::new([(xr.start, t), (xr.end, t)], thin(GRID)))?;
    }
    let area = chart.plotting_area();
    let (px0, py1) = area.map_coordinate(&(xr.start, yr.start));
    let label = text(12);
    for &t in &x_ticks {
        let (px, _) = area.map_coordinate(&(t, yr.start));
        let style = label.pos(Pos::new(HPos::Center, VPos::Top));
        root.draw_text(&xa.label(t), &style, (px, py1 + 6 * s as i32))?;
    }
    for &t in &y_ticks {
        let (_, py) = area.map_coordinate(&(xr.start, t));
        let style = label.pos(Pos::new(HPos::Right, VPos::Center));
        root.draw_text(&ya.label(t), &style, (px0 - 6 * s as i32, py))?;
    }
    for (ser, pts) in series.iter().zip(points) {
        if pts.is_empty() {
            continue;
        }
        let [r, g, b] = ser.color;
        let color = RGBColor(r, g, b);
        let line = color.stroke_width(2 * s);
        let drawn = if ser.dashed {
            chart.draw_series(DashedLineSeries::new(
                pts.iter().copied(),
                6 * s,
                4 * s,
                line,
            ))?
        } else {
            chart.draw_series(LineSeries::new(pts.iter().copied(), line))?
        };
        drawn
            .label(ser.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18 * s as i32, y)], line));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3 * s, color.filled())))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(text(12))
        .legend_area_size(26 * s)
        .background_style(WHITE.mix(0.9))
        .border_style(LEGEND_BORDER)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Averages `factor` x `factor` blocks of an RGB8 image of `w·factor` x `h·factor` pixels.
fn average_down(big: &[u8], w: usize, h: usize, factor: usize) -> Vec<u8> {
    let bw = w * factor;
    let n = (factor * factor) as u32;
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let mut sum = 0u32;
                for dy in 0..factor {
                    for dx in 0..factor {
                        sum += big[((y * factor + dy) * bw + x * factor + dx) * 3 + c] as u32;
                    }
                }
                out[(y * w + x) * 3 + c] = ((sum + n / 2) / n) as u8;
            }
        }
    }
    out
}

/// Renders and writes a PNG atomically.
pub fn write(path: &Path, spec: &PlotSpec, series: &[Series]) -> Result<()> {
    let rgb = render(spec, series)?;
    write_png(path, spec.width, spec.height, &rgb)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A nice step against its round value: 2 times 10⁻¹ from `powi` in f64, a few ulps of 0.2.
    const NICE_STEP: f64 = 1e-12;

    fn spec(log: bool) -> PlotSpec {
        PlotSpec {
            title: "Error vs terms".into(),
            x_label: "terms K".into(),
            y_label: "relative L2 error".into(),
            log_x: log,
            log_y: log,
            width: 640,
            height: 420,
        }
    }

    fn series(label: &str, color: [u8; 3], dashed: bool, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.into(),
            points,
            color,
            dashed,
        }
    }

    /// Pixels within a small distance of `color` (antialiased edges blend towards white).
    fn count(rgb: &[u8], color: [u8; 3]) -> usize {
        rgb.chunks_exact(3)
            .filter(|p| (0..3).all(|c| (p[c] as i32 - color[c] as i32).abs() <= 12))
            .count()
    }

    fn two_curves() -> Vec<Series> {
        let ks = [10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0];
        vec![
            series(
                "haar",
                PALETTE[0],
                false,
                ks.iter().map(|&k| (k, 2.0 / k)).collect(),
            ),
            series(
                "sh",
                PALETTE[1],
                true,
                ks.iter().map(|&k| (k, 0.5 / k.sqrt())).collect(),
            ),
        ]
    }

    #[test]
    fn log_log_plot_has_requested_size_curves_and_background() {
        let spec = spec(true);
        let s = two_curves();
        let rgb = render(&spec, &s).unwrap();
        assert_eq!(rgb.len(), spec.width * spec.height * 3);
        for si in &s {
            // Far more pixels of the colour than the legend swatch alone holds.
            let n = count(&rgb, si.color);
            assert!(n > 300, "series {} barely drawn: {n} pixels", si.label);
        }
        // Mostly white, some of it the frame's and the text's dark grey.
        assert!(count(&rgb, [255, 255, 255]) > spec.width * spec.height / 2);
        assert!(count(&rgb, [70, 70, 70]) + count(&rgb, [25, 25, 25]) > 500);
    }

    #[test]
    fn text_is_antialiased() {
        let rgb = render(&spec(true), &two_curves()).unwrap();
        // Glyph edges blend: grey levels strictly between the text colour and white.
        let greys = rgb
            .chunks_exact(3)
            .filter(|p| p[0] == p[1] && p[1] == p[2] && p[0] > 60 && p[0] < 220)
            .count();
        assert!(greys > 200, "{greys} intermediate grey pixels");
    }

    #[test]
    fn axes_span_whole_decades_and_round_steps() {
        let a = Axis::new(true, -3.7, 0.2);
        assert_eq!((a.lo, a.hi, a.step), (-4.0, 1.0, 1.0));
        assert_eq!(a.minor.len(), 5 * 8);
        let wide = Axis::new(true, -12.0, 3.0);
        assert_eq!(wide.step, 2.0);
        assert!(wide.minor.is_empty());
        let lin = Axis::new(false, 0.13, 0.91);
        assert!(lin.lo <= 0.13 && lin.hi >= 0.91);
        assert!((lin.step - 0.2).abs() < NICE_STEP, "step {}", lin.step);
        assert!((3..=7).contains(&lin.ticks().len()), "{:?}", lin.ticks());
        // The data sit inside the padded range, never on the frame.
        let r = lin.padded();
        assert!(r.start < 0.13 && r.end > 0.91);
    }

    #[test]
    fn nonpositive_series_on_log_axis_is_skipped() {
        let spec = spec(true);
        let mut s = two_curves();
        s.push(series(
            "broken",
            PALETTE[3],
            false,
            vec![(10.0, 0.0), (100.0, -1.0), (1000.0, f64::NAN)],
        ));
        let rgb = render(&spec, &s).unwrap();
        assert_eq!(count(&rgb, PALETTE[3]), 0, "skipped series left pixels");
        assert!(count(&rgb, PALETTE[0]) > 0);
        // Non-finite and non-positive points within a good series are dropped too.
        s[0].points.push((f64::INFINITY, 1.0));
        s[0].points.push((-5.0, 1.0));
        render(&spec, &s).unwrap();
    }

    #[test]
    fn no_drawable_points_is_an_error_naming_the_plot() {
        let spec = spec(true);
        for s in [
            vec![],
            vec![series("empty", PALETTE[0], false, vec![])],
            vec![series("zero", PALETTE[0], false, vec![(1.0, 0.0)])],
        ] {
            let err = render(&spec, &s).unwrap_err().to_string();
            assert!(err.contains("Error vs terms"), "{err}");
        }
        let tiny = PlotSpec { width: 10, ..spec };
        let s = two_curves();
        let e = render(&tiny, &s).unwrap_err().to_string();
        assert!(e.contains("size 10x420 is outside 160..=8192"), "{e}");
    }

    #[test]
    fn tick_labels_are_compact() {
        let labels: Vec<String> = (-4..=5).map(decade_label).collect();
        assert_eq!(
            labels,
            [
                "1e-4", "1e-3", "0.01", "0.1", "1", "10", "100", "1000", "1e4", "1e5"
            ]
        );
        assert_eq!(linear_label(0.30000000000000004, 0.1), "0.3");
        assert_eq!(linear_label(-1e-17, 0.1), "0");
        assert_eq!(linear_label(40.0, 20.0), "40");
        assert_eq!(linear_label(2.5e-4, 5e-5), "2.5e-4");
        assert_eq!(linear_label(3e6, 1e6), "3e6");
    }

    #[test]
    fn averaging_down_keeps_flat_colours_and_blends_edges() {
        // 4 x 2 at factor 2 -> 2 x 1: a black block and a half-black block.
        let mut big = vec![255u8; 4 * 2 * 3];
        for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1), (2, 0), (2, 1)] {
            big[(y * 4 + x) * 3..(y * 4 + x) * 3 + 3].fill(0);
        }
        assert_eq!(average_down(&big, 2, 1, 2), vec![0, 0, 0, 128, 128, 128]);
    }

    #[test]
    fn writes_a_png() {
        let dir = crate::test_support::temp_dir("plot");
        let path = dir.join("curves.png");
        write(&path, &spec(true), &two_curves()).unwrap();
        let img = image::open(&path).unwrap();
        assert_eq!((img.width(), img.height()), (640, 420));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
