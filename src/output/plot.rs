//! Line plots rendered straight to PNG, for error-versus-terms curves in benchmark reports.
//!
//! No plotting or font crate: lines and markers are rasterised here, text uses the 5 x 7 bitmap
//! font of [`crate::output::sheet`]. Either axis may be logarithmic; log axes span whole decades and tick at
//! powers of ten, linear axes tick at about five round values. A legend sits in the upper-right
//! corner inside the frame.

use std::path::Path;

use crate::error::{PrtError, Result};
use crate::output::film::{write_atomically, write_png};
use crate::output::sheet::draw_text;

/// One curve.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub color: [u8; 3],
    pub dashed: bool,
}

/// Axes and size.
pub struct PlotSpec {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    pub width: usize,
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

const BACKGROUND: [u8; 3] = [255, 255, 255];
const PLOT_BG: [u8; 3] = [255, 255, 255];
const GRID: [u8; 3] = [225, 225, 225];
const FRAME: [u8; 3] = [70, 70, 70];
const TEXT: [u8; 3] = [25, 25, 25];
const LEGEND_BORDER: [u8; 3] = [170, 170, 170];

/// Horizontal advance and height of one character of the sheet font.
const CHAR_W: usize = 12;
const CHAR_H: usize = 14;
/// Outer margin of the image.
const MARGIN: usize = 10;
/// Distance between the frame and the nearest data point, so markers never sit on the frame.
const INSET: f64 = 8.0;
const TICK: usize = 5;
const MINOR_TICK: usize = 3;
/// Gap between tick marks and their labels.
const LABEL_GAP: usize = 4;
const DASH_ON: f64 = 6.0;
const DASH_PERIOD: f64 = 10.0;
const MARKER_HALF: i64 = 2;
const MIN_SIZE: usize = 160;
const MAX_SIZE: usize = 16384;

/// Renders to RGB8 bytes (width*height*3), white background.
///
/// Points with a non-finite coordinate, or a non-positive one on a log axis, are skipped; a
/// series left with no points is neither drawn nor listed in the legend. If no series has a point
/// left, this is an error naming the plot.
pub fn render(spec: &PlotSpec, series: &[Series]) -> Result<Vec<u8>> {
    let layout = Layout::new(spec, series)?;
    let mut canvas = Canvas::new(spec.width, spec.height, BACKGROUND);
    layout.draw_axes(&mut canvas, spec);
    for (s, pts) in series.iter().zip(&layout.points) {
        layout.draw_series(&mut canvas, s, pts);
    }
    layout.draw_legend(&mut canvas, series);
    Ok(canvas.rgb)
}

/// Renders and writes a PNG atomically.
pub fn write(path: &Path, spec: &PlotSpec, series: &[Series]) -> Result<()> {
    let rgb = render(spec, series)?;
    write_atomically(path, |tmp| write_png(tmp, spec.width, spec.height, &rgb))
}

/// Width in pixels of `text` in the sheet font, without the spacing after the last character.
fn text_width(text: &str) -> usize {
    (text.chars().count() * CHAR_W).saturating_sub(2)
}

/// A tick label for the power of ten `10^e`: plain digits near 1, `1E<e>` beyond.
fn decade_label(e: i32) -> String {
    match e {
        -2 => "0.01".into(),
        -1 => "0.1".into(),
        0..=3 => 10u32.pow(e as u32).to_string(),
        _ => format!("1E{e}"),
    }
}

/// `floor(log10(x))`, robust to values a hair below a power of ten.
fn floor_log10(x: f64) -> i32 {
    (x.log10() + 1e-9).floor() as i32
}

/// A tick label for `v` on a linear axis whose ticks are `step` apart: fixed-point with as many
/// decimals as the step needs, or `<mantissa>E<exponent>` for very large or very fine values.
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
    format!("{mantissa}E{exp}")
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

/// One axis: its range in plotted coordinates (log10 of the value on a log axis), the pixel
/// positions of the two ends of that range, and its ticks.
struct Axis {
    lo: f64,
    hi: f64,
    p_lo: f64,
    p_hi: f64,
    /// (plotted coordinate, label).
    ticks: Vec<(f64, String)>,
    /// Plotted coordinates of unlabelled minor ticks.
    minor: Vec<f64>,
}

impl Axis {
    /// Chooses the range and ticks for data spanning `[dmin, dmax]` (plotted coordinates) drawn
    /// between pixels `p_lo` and `p_hi`, such that neighbouring ticks are at least
    /// `min_spacing(labels)` pixels apart.
    fn new(
        log: bool,
        dmin: f64,
        dmax: f64,
        p_lo: f64,
        p_hi: f64,
        min_spacing: impl Fn(&[(f64, String)]) -> f64,
    ) -> Axis {
        let span_px = (p_hi - p_lo).abs();
        if log {
            let (mut lo, mut hi) = (dmin.floor(), dmax.ceil());
            if hi - lo < 1.0 {
                lo -= 1.0;
                hi += 1.0;
            }
            let decade_px = span_px / (hi - lo);
            let (lo_i, hi_i) = (lo as i32, hi as i32);
            let mut ticks = Vec::new();
            for k in [1, 2, 3, 4, 5, 10, 20, 50, 100] {
                ticks = (lo_i..=hi_i)
                    .filter(|e| e.rem_euclid(k) == 0)
                    .map(|e| (e as f64, decade_label(e)))
                    .collect();
                if k as f64 * decade_px >= min_spacing(&ticks) {
                    break;
                }
            }
            let mut minor = Vec::new();
            if decade_px >= 40.0 && (hi_i - lo_i) as usize + 1 == ticks.len() {
                for e in lo_i..hi_i {
                    minor.extend((2..10).map(|m| e as f64 + (m as f64).log10()));
                }
            }
            Axis {
                lo,
                hi,
                p_lo,
                p_hi,
                ticks,
                minor,
            }
        } else {
            let (dmin, dmax) = if dmax > dmin {
                (dmin, dmax)
            } else if dmin == 0.0 {
                (-1.0, 1.0)
            } else {
                (dmin - 0.5 * dmin.abs(), dmax + 0.5 * dmax.abs())
            };
            let mut best = None;
            for target in (2..=5).rev() {
                let step = nice_step((dmax - dmin) / target as f64);
                let (i_lo, i_hi) = ((dmin / step).floor() as i64, (dmax / step).ceil() as i64);
                let ticks: Vec<(f64, String)> = (i_lo..=i_hi)
                    .map(|i| {
                        let v = i as f64 * step;
                        (v, linear_label(v, step))
                    })
                    .collect();
                let (lo, hi) = (i_lo as f64 * step, i_hi as f64 * step);
                let spacing = span_px * step / (hi - lo);
                let fits = spacing >= min_spacing(&ticks);
                best = Some((lo, hi, ticks));
                if fits {
                    break;
                }
            }
            let (lo, hi, ticks) = best.expect("at least one tick candidate");
            Axis {
                lo,
                hi,
                p_lo,
                p_hi,
                ticks,
                minor: Vec::new(),
            }
        }
    }

    /// Pixel position of a plotted coordinate.
    fn px(&self, t: f64) -> f64 {
        self.p_lo + (t - self.lo) / (self.hi - self.lo) * (self.p_hi - self.p_lo)
    }
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

/// Where everything goes: the frame (pixel columns/rows of its lines), both axes, and each
/// series' points in pixel coordinates.
struct Layout {
    fx0: usize,
    fx1: usize,
    fy0: usize,
    fy1: usize,
    x: Axis,
    y: Axis,
    points: Vec<Vec<(f64, f64)>>,
}

impl Layout {
    fn new(spec: &PlotSpec, series: &[Series]) -> Result<Layout> {
        let (w, h) = (spec.width, spec.height);
        if !(MIN_SIZE..=MAX_SIZE).contains(&w) || !(MIN_SIZE..=MAX_SIZE).contains(&h) {
            return Err(PrtError::invalid(
                format!("plot \"{}\"", spec.title),
                format!("size {w}x{h} is outside {MIN_SIZE}..={MAX_SIZE} pixels per side"),
            ));
        }
        let plotted_pts: Vec<Vec<(f64, f64)>> = series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .filter_map(|&(x, y)| Some((plotted(spec.log_x, x)?, plotted(spec.log_y, y)?)))
                    .collect()
            })
            .collect();
        let all = || plotted_pts.iter().flatten();
        if all().next().is_none() {
            let need = match (spec.log_x, spec.log_y) {
                (false, false) => "finite",
                _ => "finite and positive on log axes",
            };
            return Err(PrtError::invalid(
                format!("plot \"{}\"", spec.title),
                format!("no point to draw: every series is empty or has no {need} point"),
            ));
        }
        let fold = |f: fn(&(f64, f64)) -> f64| {
            all()
                .map(f)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                })
        };
        let (xmin, xmax) = fold(|p| p.0);
        let (ymin, ymax) = fold(|p| p.1);

        let top = if spec.title.is_empty() {
            2 * MARGIN
        } else {
            MARGIN + CHAR_H + 2 * MARGIN
        };
        let x_label_h = if spec.x_label.is_empty() {
            0
        } else {
            CHAR_H + MARGIN
        };
        let bottom = TICK + LABEL_GAP + CHAR_H + x_label_h + MARGIN;
        let (fy0, fy1) = (top, h.saturating_sub(bottom + 1));
        let y = Axis::new(
            spec.log_y,
            ymin,
            ymax,
            fy1 as f64 - INSET,
            fy0 as f64 + INSET,
            |_| (CHAR_H + 6) as f64,
        );
        let y_tick_w = y.ticks.iter().map(|t| text_width(&t.1)).max().unwrap_or(0);
        let y_label_w = if spec.y_label.is_empty() {
            0
        } else {
            CHAR_H + MARGIN
        };
        let fx0 = MARGIN + y_label_w + y_tick_w + LABEL_GAP + TICK;
        let fx1 = w.saturating_sub(2 * MARGIN + 1);
        if fx1 < fx0 + 4 * INSET as usize || fy1 < fy0 + 4 * INSET as usize {
            return Err(PrtError::invalid(
                format!("plot \"{}\"", spec.title),
                format!("size {w}x{h} leaves no room for the plot area"),
            ));
        }
        let x = Axis::new(
            spec.log_x,
            xmin,
            xmax,
            fx0 as f64 + INSET,
            fx1 as f64 - INSET,
            |ticks| {
                let widest = ticks.iter().map(|t| text_width(&t.1)).max().unwrap_or(0);
                (widest + 2 * CHAR_W) as f64
            },
        );
        let points = plotted_pts
            .into_iter()
            .map(|pts| pts.into_iter().map(|(a, b)| (x.px(a), y.px(b))).collect())
            .collect();
        Ok(Layout {
            fx0,
            fx1,
            fy0,
            fy1,
            x,
            y,
            points,
        })
    }

    /// Plot-area fill, grid, frame, ticks with labels, title and axis labels.
    fn draw_axes(&self, c: &mut Canvas, spec: &PlotSpec) {
        let (fx0, fx1, fy0, fy1) = (self.fx0, self.fx1, self.fy0, self.fy1);
        c.fill(fx0, fy0, fx1 + 1, fy1 + 1, PLOT_BG);
        for (t, _) in &self.x.ticks {
            let px = self.x.px(*t).round() as usize;
            c.fill(px, fy0 + 1, px + 1, fy1, GRID);
        }
        for (t, _) in &self.y.ticks {
            let py = self.y.px(*t).round() as usize;
            c.fill(fx0 + 1, py, fx1, py + 1, GRID);
        }
        c.fill(fx0, fy0, fx1 + 1, fy0 + 1, FRAME);
        c.fill(fx0, fy1, fx1 + 1, fy1 + 1, FRAME);
        c.fill(fx0, fy0, fx0 + 1, fy1 + 1, FRAME);
        c.fill(fx1, fy0, fx1 + 1, fy1 + 1, FRAME);

        for (t, label) in &self.x.ticks {
            let px = self.x.px(*t).round() as usize;
            c.fill(px, fy1 + 1, px + 1, fy1 + 1 + TICK, FRAME);
            let lw = text_width(label);
            let lx = px.saturating_sub(lw / 2).min(c.w.saturating_sub(lw + 1));
            c.text(lx, fy1 + 1 + TICK + LABEL_GAP, label, TEXT);
        }
        for t in &self.x.minor {
            let px = self.x.px(*t).round() as usize;
            c.fill(px, fy1 + 1, px + 1, fy1 + 1 + MINOR_TICK, FRAME);
        }
        for (t, label) in &self.y.ticks {
            let py = self.y.px(*t).round() as usize;
            c.fill(fx0 - TICK, py, fx0, py + 1, FRAME);
            let lx = (fx0 - TICK - LABEL_GAP).saturating_sub(text_width(label));
            c.text(lx, py.saturating_sub(CHAR_H / 2 - 1), label, TEXT);
        }
        for t in &self.y.minor {
            let py = self.y.px(*t).round() as usize;
            c.fill(fx0 - MINOR_TICK, py, fx0, py + 1, FRAME);
        }

        let cx = (fx0 + fx1) / 2;
        if !spec.title.is_empty() {
            let tw = text_width(&spec.title);
            c.text(cx.saturating_sub(tw / 2), MARGIN, &spec.title, TEXT);
        }
        if !spec.x_label.is_empty() {
            let tw = text_width(&spec.x_label);
            let ty = fy1 + 1 + TICK + LABEL_GAP + CHAR_H + MARGIN;
            c.text(cx.saturating_sub(tw / 2), ty, &spec.x_label, TEXT);
        }
        if !spec.y_label.is_empty() {
            let tw = text_width(&spec.y_label);
            let cy = (fy0 + fy1) / 2;
            c.text_up(MARGIN, cy + tw / 2, &spec.y_label, TEXT);
        }
    }

    /// The polyline (2 px thick, dashed if asked) and a 5 x 5 marker at each point, clipped to
    /// the inside of the frame.
    fn draw_series(&self, c: &mut Canvas, s: &Series, pts: &[(f64, f64)]) {
        let clip = (self.fx0 + 1, self.fy0 + 1, self.fx1, self.fy1);
        let mut dist = 0.0;
        for seg in pts.windows(2) {
            let ((x0, y0), (x1, y1)) = (seg[0], seg[1]);
            let len = (x1 - x0).hypot(y1 - y0);
            let n = (len * 2.0).ceil().max(1.0) as usize;
            for i in 0..=n {
                let t = i as f64 / n as f64;
                if s.dashed && (dist + t * len) % DASH_PERIOD >= DASH_ON {
                    continue;
                }
                let (x, y) = (x0 + t * (x1 - x0), y0 + t * (y1 - y0));
                let (ix, iy) = ((x - 0.5).floor() as i64, (y - 0.5).floor() as i64);
                c.rect_clipped(ix, iy, ix + 2, iy + 2, s.color, clip);
            }
            dist += len;
        }
        for &(x, y) in pts {
            let (ix, iy) = (x.round() as i64, y.round() as i64);
            c.rect_clipped(
                ix - MARKER_HALF,
                iy - MARKER_HALF,
                ix + MARKER_HALF + 1,
                iy + MARKER_HALF + 1,
                s.color,
                clip,
            );
        }
    }

    /// A boxed legend in the upper-right corner inside the frame: a line-and-marker swatch and
    /// the label for every drawn series.
    fn draw_legend(&self, c: &mut Canvas, series: &[Series]) {
        let shown: Vec<&Series> = series
            .iter()
            .zip(&self.points)
            .filter(|(_, p)| !p.is_empty())
            .map(|(s, _)| s)
            .collect();
        if shown.is_empty() {
            return;
        }
        const PAD: usize = 8;
        const SWATCH: usize = 30;
        const ROW: usize = CHAR_H + 6;
        let label_w = shown
            .iter()
            .map(|s| text_width(&s.label))
            .max()
            .unwrap_or(0);
        let bw = PAD + SWATCH + PAD + label_w + PAD;
        let bh = PAD + shown.len() * ROW - 6 + PAD;
        let bx1 = self.fx1.saturating_sub(PAD);
        let bx0 = bx1.saturating_sub(bw).max(self.fx0 + 1);
        let by0 = self.fy0 + PAD;
        let by1 = (by0 + bh).min(self.fy1);
        c.fill(bx0, by0, bx1, by1, PLOT_BG);
        c.fill(bx0, by0, bx1, by0 + 1, LEGEND_BORDER);
        c.fill(bx0, by1 - 1, bx1, by1, LEGEND_BORDER);
        c.fill(bx0, by0, bx0 + 1, by1, LEGEND_BORDER);
        c.fill(bx1 - 1, by0, bx1, by1, LEGEND_BORDER);
        let clip = (bx0 + 1, by0 + 1, bx1 - 1, by1 - 1);
        for (i, s) in shown.iter().enumerate() {
            let ty = by0 + PAD + i * ROW;
            let sy = (ty + CHAR_H / 2) as i64;
            let sx0 = (bx0 + PAD) as i64;
            for dx in 0..SWATCH as i64 {
                if s.dashed && (dx as f64) % DASH_PERIOD >= DASH_ON {
                    continue;
                }
                c.rect_clipped(sx0 + dx, sy - 1, sx0 + dx + 1, sy + 1, s.color, clip);
            }
            let mx = sx0 + SWATCH as i64 / 2;
            c.rect_clipped(
                mx - MARKER_HALF,
                sy - 1 - MARKER_HALF,
                mx + MARKER_HALF + 1,
                sy + MARKER_HALF,
                s.color,
                clip,
            );
            if ty + CHAR_H < by1 {
                c.text(bx0 + PAD + SWATCH + PAD, ty, &s.label, TEXT);
            }
        }
    }
}

/// An RGB8 image being drawn.
struct Canvas {
    w: usize,
    h: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn new(w: usize, h: usize, color: [u8; 3]) -> Canvas {
        Canvas {
            w,
            h,
            rgb: color.repeat(w * h),
        }
    }

    /// Fills the half-open rectangle [x0, x1) x [y0, y1), clipped to the image.
    fn fill(&mut self, x0: usize, y0: usize, x1: usize, y1: usize, color: [u8; 3]) {
        for y in y0..y1.min(self.h) {
            for x in x0..x1.min(self.w) {
                self.rgb[(y * self.w + x) * 3..(y * self.w + x) * 3 + 3].copy_from_slice(&color);
            }
        }
    }

    /// Fills [x0, x1) x [y0, y1) clipped to the half-open rectangle `clip` = (x0, y0, x1, y1).
    fn rect_clipped(
        &mut self,
        x0: i64,
        y0: i64,
        x1: i64,
        y1: i64,
        color: [u8; 3],
        clip: (usize, usize, usize, usize),
    ) {
        let cx = |v: i64| v.clamp(clip.0 as i64, clip.2 as i64) as usize;
        let cy = |v: i64| v.clamp(clip.1 as i64, clip.3 as i64) as usize;
        self.fill(cx(x0), cy(y0), cx(x1), cy(y1), color);
    }

    fn text(&mut self, x: usize, y: usize, text: &str, color: [u8; 3]) {
        draw_text(&mut self.rgb, self.w, x, y, text, color);
    }

    /// Draws `text` rotated a quarter turn counter-clockwise (reading bottom to top), its first
    /// character's baseline-left corner at (x, y_bottom).
    fn text_up(&mut self, x: usize, y_bottom: usize, text: &str, color: [u8; 3]) {
        let tw = text_width(text);
        if tw == 0 {
            return;
        }
        let mut tmp = vec![0u8; tw * CHAR_H * 3];
        draw_text(&mut tmp, tw, 0, 0, text, [255, 255, 255]);
        for ty in 0..CHAR_H {
            for tx in 0..tw {
                if tmp[(ty * tw + tx) * 3] == 0 {
                    continue;
                }
                let (dx, dy) = (x + ty, y_bottom as i64 - tx as i64);
                if dy >= 0 {
                    self.fill(dx, dy as usize, dx + 1, dy as usize + 1, color);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    fn pixel(rgb: &[u8], w: usize, x: usize, y: usize) -> [u8; 3] {
        let i = (y * w + x) * 3;
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    }

    fn count(rgb: &[u8], color: [u8; 3]) -> usize {
        rgb.chunks_exact(3).filter(|p| *p == color).count()
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
        let layout = Layout::new(&spec, &s).unwrap();
        for (si, pts) in s.iter().zip(&layout.points) {
            // Far more pixels of the colour than the legend swatch alone holds.
            assert!(
                count(&rgb, si.color) > 300,
                "series {} barely drawn: {} pixels",
                si.label,
                count(&rgb, si.color)
            );
            // The marker of a middle point is there in the series' colour.
            let (x, y) = pts[2];
            let got = pixel(&rgb, spec.width, x.round() as usize, y.round() as usize);
            assert_eq!(got, si.color, "marker of {} at ({x}, {y})", si.label);
        }
        // Plot-area background between the frame and the first point.
        let (fx0, fy1) = (layout.fx0, layout.fy1);
        assert_eq!(pixel(&rgb, spec.width, fx0 + 3, fy1 - 3), PLOT_BG);
        assert_eq!(pixel(&rgb, spec.width, fx0, fy1), FRAME);
    }

    #[test]
    fn data_extremes_map_inside_the_frame() {
        for log in [true, false] {
            let spec = spec(log);
            let s = vec![series(
                "a",
                PALETTE[2],
                false,
                vec![(1.0, 1e-4), (7.0, 0.3), (5000.0, 2.5), (12.0, 0.02)],
            )];
            let l = Layout::new(&spec, &s).unwrap();
            for &(x, y) in &l.points[0] {
                assert!(
                    x > l.fx0 as f64 + 2.0 && x < l.fx1 as f64 - 2.0,
                    "log {log}: x {x} not inside {}..{}",
                    l.fx0,
                    l.fx1
                );
                assert!(
                    y > l.fy0 as f64 + 2.0 && y < l.fy1 as f64 - 2.0,
                    "log {log}: y {y} not inside {}..{}",
                    l.fy0,
                    l.fy1
                );
            }
            // The extremes are the outermost points, left/right and bottom/top.
            let xs: Vec<f64> = l.points[0].iter().map(|p| p.0).collect();
            let ys: Vec<f64> = l.points[0].iter().map(|p| p.1).collect();
            assert!(xs[0] < xs[1] && xs[2] > xs[3]);
            assert!(ys[0] > ys[1] && ys[2] < ys[1]);
        }
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
        assert!(render(&tiny, &s).is_err());
    }

    #[test]
    fn tick_labels_are_compact() {
        let labels: Vec<String> = (-4..=5).map(decade_label).collect();
        assert_eq!(
            labels,
            [
                "1E-4", "1E-3", "0.01", "0.1", "1", "10", "100", "1000", "1E4", "1E5"
            ]
        );
        assert_eq!(linear_label(0.30000000000000004, 0.1), "0.3");
        assert_eq!(linear_label(-1e-17, 0.1), "0");
        assert_eq!(linear_label(40.0, 20.0), "40");
        assert_eq!(linear_label(2.5e-4, 5e-5), "2.5E-4");
        assert_eq!(linear_label(3e6, 1e6), "3E6");
    }

    #[test]
    fn linear_axis_ticks_are_round_and_cover_the_data() {
        let a = Axis::new(false, 0.13, 0.91, 0.0, 500.0, |_| 40.0);
        assert!(a.lo <= 0.13 && a.hi >= 0.91);
        assert!((3..=7).contains(&a.ticks.len()), "{:?}", a.ticks);
        let step = a.ticks[1].0 - a.ticks[0].0;
        assert!((step - 0.2).abs() < 1e-12, "step {step}");
    }

    #[test]
    fn writes_a_png() {
        let dir = crate::scene::test_support::temp_dir("plot");
        let path = dir.join("curves.png");
        write(&path, &spec(true), &two_curves()).unwrap();
        let img = image::open(&path).unwrap();
        assert_eq!((img.width(), img.height()), (640, 420));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
