//! Line plots for the benchmark reports (error and time against terms), drawn with `plotters` and
//! written as PNG. Text is set by [`crate::output::text`] (antialiased); the whole plot is drawn at twice its size and averaged down, so lines and
//! markers are antialiased too.
//!
//! Either axis may be logarithmic. A log axis spans whole decades, labels powers of ten and draws
//! light lines at 2..9 times each; a linear axis ticks at about five round values. A legend sits in
//! a corner inside the frame (the upper right unless a [`Figure`] says otherwise), a row per drawn
//! series with its line and marker. A [`Figure`] also gives each series its own [`Look`] (width,
//! dashes, marker) and draws horizontal [`Level`]s, each labelled beside its line.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{PrtError, Result};
use crate::output::film::write_png;
use crate::output::text::{FONT, GlyphBackend, width as text_width};

mod marks;
use marks::*;

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

impl Series {
    /// A series from its label, points, colour and whether its line is dashed.
    pub fn new(label: String, points: Vec<(f64, f64)>, color: [u8; 3], dashed: bool) -> Series {
        Series {
            label,
            points,
            color,
            dashed,
        }
    }
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

/// The mark drawn at each point of a series.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Marker {
    /// A disc.
    #[default]
    Circle,
    /// A triangle, point up.
    Triangle,
    /// A square.
    Square,
    /// A square standing on a corner.
    Diamond,
    /// An X.
    Cross,
}

/// How a series is drawn, besides its colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Look {
    /// Line width, pixels; 0 draws the markers alone.
    pub width: u32,
    /// Dash and gap lengths along the line, pixels; `None` for a solid line.
    pub dash: Option<(u32, u32)>,
    /// The mark at each point.
    pub marker: Marker,
    /// Marker radius, pixels.
    pub size: u32,
    /// A filled marker, or its outline around white.
    pub filled: bool,
}

impl Look {
    /// A look from its line width, dashes, marker, the marker's radius and whether it is filled.
    pub const fn new(
        width: u32,
        dash: Option<(u32, u32)>,
        marker: Marker,
        size: u32,
        filled: bool,
    ) -> Look {
        Look {
            width,
            dash,
            marker,
            size,
            filled,
        }
    }

    /// The look a series gets unless a [`Figure`] gives it one: a 2-pixel line, dashed when the
    /// series says so, and filled circles.
    pub fn of(series: &Series) -> Look {
        Look::new(2, series.dashed.then_some((6, 4)), Marker::Circle, 3, true)
    }
}

/// A corner of the plotting area.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Corner {
    /// Top left.
    UpperLeft,
    /// Top right.
    #[default]
    UpperRight,
    /// Bottom left.
    LowerLeft,
    /// Bottom right.
    LowerRight,
}

/// A horizontal line across the plot, labelled beside it.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// Where the line is, in data units (the y axis always reaches it).
    pub y: f64,
    /// The label's lines, each wrapped to fit, in a box above the line at the right.
    pub lines: Vec<String>,
    /// Ticks on the line: the x where a series crosses it, and that series' colour.
    pub marks: Vec<(f64, [u8; 3])>,
}

/// What a plot draws besides its series' points.
#[derive(Clone, Debug, Default)]
pub struct Figure {
    /// One look per series, in order; a series past the end takes [`Look::of`].
    pub looks: Vec<Look>,
    /// Horizontal lines, each with its label.
    pub levels: Vec<Level>,
    /// The corner the legend sits in.
    pub legend: Corner,
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
/// Colour of the levels' lines.
const LEVEL: RGBColor = RGBColor(120, 120, 120);
/// Size of the tick labels, the legend and the levels' labels, points at the output size.
const LABEL_PT: u32 = 12;
/// Legend and level-label layout, pixels at the output size: inner padding, height of a row,
/// length of a legend row's line sample and the gap after it, distance from the frame.
const PAD: i32 = 5;
const ROW: i32 = 16;
const SWATCH: i32 = 28;
const GAP: i32 = 6;
const INSET: i32 = 8;
/// Stroke of an X marker, a hollow marker's ring and a level's ticks, pixels.
const MARKER_STROKE: i32 = 2;
/// Half the length of a level's tick, pixels.
const TICK: i32 = 6;
/// A level's label box is at most this fraction of the plotting area wide.
const LABEL_SHARE: f64 = 0.7;

/// The drawing area of the whole image.
type Root<'a> = DrawingArea<GlyphBackend<'a>, Shift>;
/// What a drawing step returns.
type Drawn = std::result::Result<(), Box<dyn std::error::Error>>;

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

/// Renders to RGB8 bytes (width*height*3), white background, every series in the look
/// [`Look::of`] gives it and the legend in the upper-right corner: [`render_figure`] with the
/// default [`Figure`].
///
/// Points with a non-finite coordinate, or a non-positive one on a log axis, are skipped; a
/// series left with no points is neither drawn nor listed in the legend. If no series has a point
/// left, this is an error naming the plot.
pub fn render(spec: &PlotSpec, series: &[Series]) -> Result<Vec<u8>> {
    render_figure(spec, series, &Figure::default())
}

/// [`render`] with each series in its look from `figure`, its levels (the y axis reaches each)
/// and its legend's corner. Series are drawn in order, so a later one lies over an earlier one.
pub fn render_figure(spec: &PlotSpec, series: &[Series], figure: &Figure) -> Result<Vec<u8>> {
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
    let (y0, y1) = figure
        .levels
        .iter()
        .filter_map(|l| plotted(spec.log_y, l.y))
        .fold((y0, y1), |(a, b), v| (a.min(v), b.max(v)));
    let (xa, ya) = (Axis::new(spec.log_x, x0, x1), Axis::new(spec.log_y, y0, y1));
    crate::output::text::register()?;
    let s = SUPERSAMPLE;
    let mut big = vec![255u8; w * s * h * s * 3];
    let looks: Vec<Look> = series
        .iter()
        .enumerate()
        .map(|(i, ser)| {
            figure
                .looks
                .get(i)
                .copied()
                .unwrap_or_else(|| Look::of(ser))
        })
        .collect();
    let layers = Layers {
        series,
        points: &points,
        looks: &looks,
        figure,
    };
    draw(spec, &layers, &xa, &ya, &mut big).map_err(|e| named(e.to_string()))?;
    Ok(average_down(&big, w, h, s))
}

/// What [`draw`] puts inside the frame: the series, their plotted points and looks, the figure's
/// levels and legend.
/// A level's tick where a series crosses it: the pixel and the series' colour.
type Tick = ((i32, i32), RGBColor);

struct Layers<'a> {
    series: &'a [Series],
    points: &'a [Vec<(f64, f64)>],
    looks: &'a [Look],
    figure: &'a Figure,
}

/// Draws the plot at [`SUPERSAMPLE`] times its size into `buffer`.
fn draw(spec: &PlotSpec, layers: &Layers, xa: &Axis, ya: &Axis, buffer: &mut [u8]) -> Drawn {
    let s = SUPERSAMPLE as u32;
    let size = (
        (spec.width * SUPERSAMPLE) as u32,
        (spec.height * SUPERSAMPLE) as u32,
    );
    let root = GlyphBackend(BitMapBackend::with_buffer(buffer, size)).into_drawing_area();
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
        .label_style(text(LABEL_PT))
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
    let (px1, py0) = area.map_coordinate(&(xr.end, yr.end));
    let label = text(LABEL_PT);
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
    // The levels' lines and ticks under the series, their labels over them.
    let mut levels: Vec<(i32, Vec<Tick>, &Level)> = Vec::new();
    for level in &layers.figure.levels {
        let Some(y) = plotted(spec.log_y, level.y) else {
            continue;
        };
        let py = area.map_coordinate(&(xr.start, y)).1;
        let ticks: Vec<_> = level
            .marks
            .iter()
            .filter_map(|&(x, c)| {
                Some((area.map_coordinate(&(plotted(spec.log_x, x)?, y)), rgb(c)))
            })
            .filter(|((px, _), _)| (px0..=px1).contains(px))
            .collect();
        levels.push((py, ticks, level));
    }
    levels.sort_by_key(|(py, ..)| *py);
    let level_look = Look::new(1, Some((5, 4)), Marker::Circle, 0, true);
    let tick = |c: RGBColor| c.stroke_width(MARKER_STROKE as u32 * s);
    let si = s as i32;
    for (py, ticks, _) in &levels {
        draw_line(&root, &[(px0, *py), (px1, *py)], &level_look, LEVEL)?;
        for &((px, py), c) in ticks {
            let ends = vec![(px, py - TICK * si), (px, py + TICK * si)];
            root.draw(&PathElement::new(ends, tick(c)))?;
        }
    }
    let mut legend = Vec::new();
    for ((ser, pts), look) in layers.series.iter().zip(layers.points).zip(layers.looks) {
        if pts.is_empty() {
            continue;
        }
        let color = rgb(ser.color);
        let px: Vec<(i32, i32)> = pts.iter().map(|p| area.map_coordinate(p)).collect();
        draw_line(&root, &px, look, color)?;
        for &c in &px {
            draw_marker(&root, c, look, color)?;
        }
        legend.push((ser.label.as_str(), *look, color));
    }
    let widest = ((px1 - px0) as f64 * LABEL_SHARE / s as f64) as usize;
    let mut below = py0;
    for (py, _, level) in &levels {
        let lines: Vec<String> = level
            .lines
            .iter()
            .flat_map(|l| wrap(l, LABEL_PT as usize, widest))
            .collect();
        below = draw_label(&root, &lines, (px1 - INSET * si, *py), below, &label)?;
    }
    let frame = [px0, py0, px1, py1];
    draw_legend(&root, frame, &legend, layers.figure.legend, &label)?;
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
    write_figure(path, spec, series, &Figure::default())
}

/// [`render_figure`] and writes a PNG atomically.
pub fn write_figure(
    path: &Path,
    spec: &PlotSpec,
    series: &[Series],
    figure: &Figure,
) -> Result<()> {
    let rgb = render_figure(spec, series, figure)?;
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

    #[test]
    fn dashes_run_on_across_corners() {
        let d = dashes(&[(0.0, 0.0), (20.0, 0.0)], 6.0, 4.0);
        assert_eq!(
            d,
            [vec![(0.0, 0.0), (6.0, 0.0)], vec![(10.0, 0.0), (16.0, 0.0)]]
        );
        // A dash begun before a corner goes round it.
        let d = dashes(&[(0.0, 0.0), (3.0, 0.0), (3.0, 3.0)], 6.0, 4.0);
        assert_eq!(d, [vec![(0.0, 0.0), (3.0, 0.0), (3.0, 3.0)]]);
        assert!(dashes(&[(1.0, 1.0), (1.0, 1.0)], 6.0, 4.0).is_empty());
    }

    #[test]
    fn labels_wrap_at_spaces_to_fit() {
        let text = "terms for 5%: wavelet none 40, area 52; sh > 16; sh-light 310";
        let max = text_width("terms for 5%: wavelet none 40,", 12);
        let lines = wrap(text, 12, max);
        assert!(lines.len() > 1, "{lines:?}");
        assert!(lines.iter().all(|l| text_width(l, 12) <= max), "{lines:?}");
        assert_eq!(lines.join(" "), text);
        assert_eq!(wrap("short", 12, 1000), ["short"]);
    }

    /// Two series on the same points, as baked SH and SH through the light are at low orders.
    fn coincident() -> Vec<Series> {
        let pts: Vec<(f64, f64)> = [1.0, 4.0, 9.0, 16.0, 25.0]
            .iter()
            .map(|&k: &f64| (k, 0.5 / k.sqrt()))
            .collect();
        vec![
            series("sh-light", PALETTE[3], false, pts.clone()),
            series("sh", PALETTE[1], true, pts),
        ]
    }

    #[test]
    fn a_series_drawn_over_another_leaves_both_visible() {
        let s = coincident();
        let figure = Figure {
            looks: vec![
                Look::new(4, None, Marker::Circle, 6, false),
                Look::new(2, Some((6, 3)), Marker::Square, 3, true),
            ],
            ..Figure::default()
        };
        let rgb = render_figure(&spec(true), &s, &figure).unwrap();
        for si in &s {
            let n = count(&rgb, si.color);
            assert!(n > 150, "series {} barely visible: {n} pixels", si.label);
        }
        // Every marker draws, a cross with no line included.
        for marker in [Marker::Triangle, Marker::Diamond, Marker::Cross] {
            let figure = Figure {
                looks: vec![Look::new(0, None, marker, 5, true)],
                ..Figure::default()
            };
            let rgb = render_figure(&spec(true), &s[..1], &figure).unwrap();
            assert!(count(&rgb, s[0].color) > 20, "{marker:?}");
        }
    }

    #[test]
    fn levels_draw_their_ticks_and_labels() {
        let spec = spec(true);
        let s = two_curves();
        let with = |lines: Vec<String>| {
            let marks = vec![(40.0, PALETTE[5]), (100.0, PALETTE[5])];
            let figure = Figure {
                levels: vec![Level {
                    y: 0.05,
                    lines,
                    marks,
                }],
                legend: Corner::LowerLeft,
                ..Figure::default()
            };
            render_figure(&spec, &s, &figure).unwrap()
        };
        let plain = render(&spec, &s).unwrap();
        let bare = with(Vec::new());
        let labelled = with(vec!["terms for 5%: haar 40; sh 100".into()]);
        // The ticks in their colour, which no series has.
        assert_eq!(count(&plain, PALETTE[5]), 0);
        assert!(count(&bare, PALETTE[5]) > 10);
        // The label's text: dark grey pixels the same level without a label lacks.
        let ink = |rgb: &[u8]| {
            rgb.chunks_exact(3)
                .filter(|p| p[0] == p[1] && p[1] == p[2] && p[0] < 160)
                .count()
        };
        let (more, fewer) = (ink(&labelled), ink(&bare));
        assert!(more > fewer + 100, "{more} vs {fewer}");
    }
}
