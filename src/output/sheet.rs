//! Contact sheets: a grid of tone-mapped thumbnails with a caption under each, written as PNG.
//! Also what annotates the images written elsewhere: captions set to fit a width (wrapped, then
//! smaller, never cut), and error heat maps with the colour bar of their scale. Text is set by
//! [`crate::output::text`].

use std::path::Path;

use crate::error::Result;
use crate::output::film::{Image, ToneMap, percentile, write_png};
use crate::output::text::{CAPTION_PX, draw_text, draw_text_sized, width};

/// One cell of a sheet.
pub struct Cell<'a> {
    /// The linear image shown in the cell.
    pub image: &'a Image,
    /// How the image is brought to display values.
    pub tone: ToneMap,
    /// Up to two caption lines.
    pub caption: [String; 2],
}

/// Cells of captioned images, all brought to display values by `tone`.
pub fn cells_at(shots: &[(Image, [String; 2])], tone: ToneMap) -> Vec<Cell<'_>> {
    shots
        .iter()
        .map(|(image, caption)| Cell {
            image,
            tone,
            caption: caption.clone(),
        })
        .collect()
}

const LINE_H: usize = CAPTION_PX + 4;
const PAD: usize = 4;
/// Background of sheets, caption strips and colour bars.
const BACKGROUND: u8 = 24;

/// Downsamples by an integer factor (box filter, in linear radiance).
pub fn downsample(img: &Image, factor: usize) -> Image {
    let f = factor.max(1);
    let (w, h) = (img.width / f, img.height / f);
    let mut out = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f32; 3];
            for dy in 0..f {
                for dx in 0..f {
                    let p = img.pixels[(y * f + dy) * img.width + x * f + dx];
                    for c in 0..3 {
                        acc[c] += p[c];
                    }
                }
            }
            out.pixels[y * w + x] = acc.map(|v| v / (f * f) as f32);
        }
    }
    out
}

/// Lays `cells` out in rows of `columns`, each row optionally headed by a title at its left, and
/// writes a PNG. All images must share one size. Captions wrap and shrink to fit their cell
/// ([`lay_out_caption`]); the caption rows grow when one needs more than two lines.
pub fn write_sheet(path: &Path, columns: usize, cells: &[Cell], title: &str) -> Result<()> {
    let (cw, ch) = cells
        .first()
        .map(|c| (c.image.width, c.image.height))
        .unwrap_or((1, 1));
    let rows = cells.len().div_ceil(columns.max(1));
    let captions: Vec<CaptionLayout> = cells
        .iter()
        .map(|c| lay_out_caption(&[c.caption[0].as_str(), c.caption[1].as_str()], cw, 2))
        .collect();
    let caption_h = captions
        .iter()
        .map(CaptionLayout::height)
        .fold(2 * LINE_H, usize::max);
    let title_h = LINE_H + 2 * PAD;
    let cell_w = cw + PAD;
    let cell_h = ch + caption_h + PAD;
    let (w, h) = (columns * cell_w + PAD, title_h + rows * cell_h + PAD);
    let mut rgb = vec![BACKGROUND; w * h * 3];
    draw_text(&mut rgb, w, PAD, PAD, title, [235, 235, 235]);
    for (i, (cell, caption)) in cells.iter().zip(&captions).enumerate() {
        let (x0, y0) = (
            PAD + (i % columns) * cell_w,
            title_h + (i / columns) * cell_h,
        );
        let pixels = cell.image.to_srgb8(cell.tone);
        for y in 0..ch.min(cell.image.height) {
            for x in 0..cw.min(cell.image.width) {
                let s = (y * cell.image.width + x) * 3;
                let d = ((y0 + y) * w + x0 + x) * 3;
                rgb[d..d + 3].copy_from_slice(&pixels[s..s + 3]);
            }
        }
        caption.draw(&mut rgb, w, x0, y0 + ch + 2, [220, 220, 220]);
    }
    write_png(path, w, h, &rgb)
}

/// Smallest size a caption shrinks to before it takes more lines, in pixels (as
/// [`CAPTION_PX`]).
pub const MIN_CAPTION_PX: usize = 10;

/// A caption set to fit a width: its size and its lines, every character of the text kept.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptionLayout {
    /// Size in pixels (as [`CAPTION_PX`]).
    pub px: usize,
    /// The lines, top to bottom.
    pub lines: Vec<String>,
}

impl CaptionLayout {
    /// Height of one line, pixels.
    pub fn line_height(&self) -> usize {
        self.px + 4
    }

    /// Height of all the lines, pixels.
    pub fn height(&self) -> usize {
        self.lines.len() * self.line_height()
    }

    /// Draws the lines into an RGB8 buffer of width `w`, the first one's top-left at (x0, y0).
    pub fn draw(&self, rgb: &mut [u8], w: usize, x0: usize, y0: usize, color: [u8; 3]) {
        for (i, line) in self.lines.iter().enumerate() {
            let y = y0 + i * self.line_height();
            draw_text_sized(rgb, w, x0, y, line, self.px, color);
        }
    }
}

/// Sets `paragraphs` (each begins a line; empty ones are left out) to fit `max_width` pixels:
/// at the caption size, wrapped between words onto up to `max_lines` lines; else at the largest
/// smaller size, down to [`MIN_CAPTION_PX`], that fits them on `max_lines`; else at that size
/// on as many lines as they take. Nothing is cut: a word wider than a whole line goes on over
/// the next.
pub fn lay_out_caption(paragraphs: &[&str], max_width: usize, max_lines: usize) -> CaptionLayout {
    let mut px = CAPTION_PX;
    loop {
        let lines = wrap(paragraphs, max_width, px);
        if lines.len() <= max_lines.max(1) || px <= MIN_CAPTION_PX {
            return CaptionLayout { px, lines };
        }
        px -= 1;
    }
}

/// Height of a strip of captions above images: a margin above and below the tallest caption
/// (one line at the caption size at least, which is [`crate::output::text::CAPTION_HEIGHT`]).
pub fn caption_strip_height(captions: &[CaptionLayout]) -> usize {
    captions
        .iter()
        .map(CaptionLayout::height)
        .fold(LINE_H, usize::max)
        + 4
}

/// `paragraphs` wrapped between words into lines of at most `max_width` pixels at `px`.
fn wrap(paragraphs: &[&str], max_width: usize, px: usize) -> Vec<String> {
    let mut lines = Vec::new();
    for paragraph in paragraphs {
        let mut line = String::new();
        for word in paragraph.split_whitespace() {
            let joined = match line.is_empty() {
                true => word.to_string(),
                false => format!("{line} {word}"),
            };
            if line.is_empty() || width(&joined, px) <= max_width {
                line = joined;
            } else {
                lines.push(std::mem::replace(&mut line, word.to_string()));
            }
            // A word wider than the line on its own goes on over the next lines.
            while width(&line, px) > max_width && line.chars().count() > 1 {
                let (head, rest) = split_to_fit(&line, max_width, px);
                lines.push(head);
                line = rest;
            }
        }
        if !line.is_empty() {
            lines.push(line);
        }
    }
    lines
}

/// The longest head of `text` (one character at least) within `max_width` at `px`, and the rest.
fn split_to_fit(text: &str, max_width: usize, px: usize) -> (String, String) {
    let cut = text
        .char_indices()
        .skip(1)
        .find(|&(i, c)| width(&text[..i + c.len_utf8()], px) > max_width)
        .map_or(text.len(), |(i, _)| i);
    (text[..cut].to_string(), text[cut..].to_string())
}

/// Lowest full heat of an error heat map, as a fraction of the reference's mean luminance: a
/// finer scale would show float rounding as error (an image relit with every term against
/// `full` stays black).
pub const MIN_HEAT_TOP: f32 = 0.01;
/// The fraction of the lit pixels a heat map's scale keeps below full heat.
pub const HEAT_PERCENTILE: f32 = 0.99;

/// An image's error against a reference: per pixel, |Δ luminance| over the mean luminance of the
/// reference's lit pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorImage {
    /// The error of each pixel (0 where neither image has light).
    pub errors: Vec<f32>,
    /// The errors of the pixels either image lights: what a scale is chosen from.
    lit: Vec<f32>,
}

impl ErrorImage {
    /// The error of `image` against `full` (of the same size).
    pub fn of(image: &Image, full: &Image) -> ErrorImage {
        let lum = |p: &[f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
        let lit: Vec<f32> = full.pixels.iter().map(lum).filter(|l| *l > 0.0).collect();
        let mean = match lit.is_empty() {
            true => 1.0,
            false => lit.iter().sum::<f32>() / lit.len() as f32,
        };
        let mut errors = Vec::with_capacity(image.pixels.len());
        let mut measured = Vec::new();
        for (a, b) in image.pixels.iter().zip(&full.pixels) {
            let (la, lb) = (lum(a), lum(b));
            let e = (la - lb).abs() / mean;
            errors.push(e);
            if la != 0.0 || lb != 0.0 {
                measured.push(e);
            }
        }
        ErrorImage {
            errors,
            lit: measured,
        }
    }

    /// The heat map of these errors under `scale`, RGB8.
    pub fn heat_map(&self, scale: HeatScale) -> Vec<u8> {
        self.errors.iter().flat_map(|&e| scale.color(e)).collect()
    }
}

/// The scale of error heat maps: the error shown at full heat, as a fraction of the reference's
/// mean luminance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeatScale {
    /// The error at full heat: a 1-2-5 step, at least [`MIN_HEAT_TOP`].
    pub top: f32,
}

impl HeatScale {
    /// One scale for all of `maps`, so equal colours are equal errors: the 99th percentile of
    /// their lit pixels' errors, rounded up to a 1-2-5 step. At most 1% of those saturate.
    pub fn of(maps: &[&ErrorImage]) -> HeatScale {
        let mut errors: Vec<f32> = maps
            .iter()
            .flat_map(|m| m.lit.iter().copied())
            .filter(|e| e.is_finite())
            .collect();
        let high = match errors.is_empty() {
            true => 0.0,
            false => percentile(&mut errors, HEAT_PERCENTILE),
        };
        HeatScale {
            top: step_125_up(high.max(MIN_HEAT_TOP)),
        }
    }

    /// The colour of error `e` on this scale.
    pub fn color(self, e: f32) -> [u8; 3] {
        heat_color(e / self.top)
    }

    /// `count` (at least 2) evenly spaced ticks from full heat down to none: each its place, the
    /// fraction of full heat (1 first), and its label in percent of the reference's mean.
    pub fn ticks(self, count: usize) -> Vec<(f32, String)> {
        let last = count.max(2) - 1;
        (0..=last)
            .map(|i| {
                let at = (last - i) as f32 / last as f32;
                (at, percent(self.top * at))
            })
            .collect()
    }
}

/// The heat ramp at `t` of full heat (clamped to [0, 1]): black, red, yellow, white.
pub fn heat_color(t: f32) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let ramp = |lo: f32| ((3.0 * t - lo).clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [ramp(0.0), ramp(1.0), ramp(2.0)]
}

/// The least 1, 2 or 5 times a power of ten at or above `x` (> 0).
pub fn step_125_up(x: f32) -> f32 {
    let x = x as f64;
    let decade = 10f64.powf(x.log10().floor());
    let m = x / decade;
    let step = [1.0, 2.0, 5.0]
        .into_iter()
        .find(|s| m <= s * (1.0 + 1e-6))
        .unwrap_or(10.0);
    (step * decade) as f32
}

/// `fraction` in percent, with as many decimals as a 1-2-5 step or its half needs ("2.5%").
fn percent(fraction: f32) -> String {
    let p = fraction as f64 * 100.0;
    let decimals = (0..6)
        .find(|&d| {
            let s = 10f64.powi(d);
            ((p * s).round() - p * s).abs() < 1e-3
        })
        .unwrap_or(6) as usize;
    format!("{p:.decimals$}%")
}

/// A colour bar: the heat ramp, full heat at the top, with its ticks labelled (RGB8).
#[derive(Clone, Debug, PartialEq)]
pub struct ColorBar {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// RGB8, row-major.
    pub rgb: Vec<u8>,
    /// The tick labels drawn, top to bottom.
    pub labels: Vec<String>,
}

/// Width of a colour bar's ramp, pixels.
const RAMP_W: usize = 10;
/// Length of a tick, pixels.
const TICK_W: usize = 3;
/// Gap between an image and its colour bar, pixels.
pub const BAR_GAP: usize = 4;

/// The colour bar of `scale`, `height` pixels tall: three ticks (full heat, half, none) where
/// their labels fit, else full heat and none, else full heat alone; labels at the caption size,
/// smaller on a short bar.
pub fn color_bar(scale: HeatScale, height: usize) -> ColorBar {
    let height = height.max(1);
    let px = CAPTION_PX.min(height.saturating_sub(2)).max(6);
    let line = px + 2;
    let count = match height {
        h if h >= 3 * line => 3,
        h if h >= 2 * line => 2,
        _ => 1,
    };
    let ticks: Vec<(f32, String)> = match count {
        1 => vec![(1.0, percent(scale.top))],
        n => scale.ticks(n),
    };
    let text_x = RAMP_W + TICK_W + 3;
    let text_w = ticks.iter().map(|(_, l)| width(l, px)).max().unwrap_or(0);
    let w = text_x + text_w + 2;
    let mut rgb = vec![BACKGROUND; w * height * 3];
    let row_of = |at: f32| ((1.0 - at) * (height - 1) as f32).round() as usize;
    for y in 0..height {
        let t = 1.0 - y as f32 / (height - 1).max(1) as f32;
        let c = heat_color(t);
        for x in 0..RAMP_W {
            rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&c);
        }
    }
    for (at, label) in &ticks {
        let y = row_of(*at);
        for x in RAMP_W..RAMP_W + TICK_W {
            rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&[200; 3]);
        }
        let top = y.saturating_sub(px / 2).min(height.saturating_sub(px));
        draw_text_sized(&mut rgb, w, text_x, top, label, px, [220, 220, 220]);
    }
    ColorBar {
        width: w,
        height,
        rgb,
        labels: ticks.into_iter().map(|(_, l)| l).collect(),
    }
}

/// An RGB8 image of `width` x `height` with the colour bar of `scale` at its right, beyond a
/// [`BAR_GAP`]: the new width and pixels.
pub fn with_color_bar(
    rgb: &[u8],
    width: usize,
    height: usize,
    scale: HeatScale,
) -> (usize, Vec<u8>) {
    let bar = color_bar(scale, height);
    let w = width + BAR_GAP + bar.width;
    let mut out = vec![BACKGROUND; w * height * 3];
    for y in 0..height {
        let d = y * w * 3;
        out[d..d + width * 3].copy_from_slice(&rgb[y * width * 3..(y + 1) * width * 3]);
        let b = d + (width + BAR_GAP) * 3;
        out[b..b + bar.width * 3]
            .copy_from_slice(&bar.rgb[y * bar.width * 3..(y + 1) * bar.width * 3]);
    }
    (w, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_caption_wraps_between_words_and_keeps_every_word() {
        let text = "wavelet, 64 terms (transport) against the full product";
        // One line at the caption size where it fits.
        let wide = lay_out_caption(&[text], width(text, CAPTION_PX), 2);
        assert_eq!((wide.px, wide.lines.len()), (CAPTION_PX, 1));
        // Two lines at the caption size in a cell too narrow for one.
        let cell = width(text, CAPTION_PX) * 2 / 3;
        let two = lay_out_caption(&[text], cell, 2);
        assert_eq!(two.px, CAPTION_PX);
        assert_eq!(two.lines.len(), 2);
        for layout in [&wide, &two] {
            assert_eq!(
                layout.lines.join(" "),
                text,
                "every word, in order, none cut"
            );
            assert!(layout.lines.iter().all(|l| !l.contains("..")));
        }
        assert!(two.lines.iter().all(|l| width(l, CAPTION_PX) <= cell));
        // Narrower still: a smaller size on two lines before a third.
        let narrow = width(text, CAPTION_PX) / 2 - 8;
        let small = lay_out_caption(&[text], narrow, 2);
        assert!(
            small.px < CAPTION_PX && small.px >= MIN_CAPTION_PX,
            "{small:?}"
        );
        assert_eq!(small.lines.len(), 2);
        assert_eq!(small.lines.join(" "), text);
        assert!(small.lines.iter().all(|l| width(l, small.px) <= narrow));
        // Narrower than any size allows on two lines: more lines, nothing lost.
        let many = lay_out_caption(&[text], 70, 2);
        assert_eq!(many.px, MIN_CAPTION_PX);
        assert!(many.lines.len() > 2);
        assert_eq!(many.lines.join(" "), text);
        assert!(many.lines.iter().all(|l| width(l, many.px) <= 70));
        // A word wider than the line goes on over the next, every character kept.
        let word = lay_out_caption(&["transport"], 20, 1);
        assert_eq!(word.lines.concat(), "transport");
        assert!(word.lines.len() > 1);
        // Paragraphs begin lines; an empty one takes none.
        let two_parts = lay_out_caption(&["SH order 8", ""], 400, 2);
        assert_eq!(two_parts.lines, vec!["SH order 8".to_string()]);
        // The strip above images holds the tallest caption; one line is the usual strip.
        assert_eq!(
            caption_strip_height(std::slice::from_ref(&wide)),
            crate::output::text::CAPTION_HEIGHT
        );
        assert!(caption_strip_height(&[wide, many.clone()]) >= many.height() + 4);
    }

    #[test]
    fn a_sheet_caption_longer_than_its_cell_is_drawn_whole() {
        let black = Image::new(80, 20);
        let caption = "transport weighting, 64 terms".to_string();
        let dir = std::env::temp_dir().join(format!("sheet-caption-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("sheet.png");
        let cells = [Cell {
            image: &black,
            tone: ToneMap::default(),
            caption: [caption.clone(), String::new()],
        }];
        write_sheet(&path, 1, &cells, "").unwrap();
        let png = image::open(&path).unwrap();
        // The caption takes more than the two usual lines, and the cell grows to hold them.
        let layout = lay_out_caption(&[caption.as_str(), ""], 80, 2);
        assert_eq!(layout.lines.join(" "), caption);
        assert!(layout.height() > 2 * LINE_H);
        let title_h = LINE_H + 2 * PAD;
        assert_eq!(
            png.height() as usize,
            title_h + 20 + layout.height() + 2 * PAD
        );
        std::fs::remove_dir_all(dir).unwrap();
    }

    /// An image whose error against `full` (1 everywhere) rises evenly over `n` pixels to
    /// `most` of the mean, behind a black background the scale leaves out.
    fn ramp_error(n: usize, most: f32) -> (Image, Image) {
        let full = Image {
            width: n,
            height: 2,
            pixels: [vec![[1.0; 3]; n], vec![[0.0; 3]; n]].concat(),
        };
        let mut image = full.clone();
        for (i, p) in image.pixels.iter_mut().take(n).enumerate() {
            *p = [1.0 + most * (i + 1) as f32 / n as f32; 3];
        }
        (image, full)
    }

    #[test]
    fn the_heat_scale_saturates_only_the_top_percent_at_a_1_2_5_step() {
        assert_eq!(step_125_up(0.031), 0.05);
        assert_eq!(step_125_up(0.05), 0.05);
        assert_eq!(step_125_up(0.0099), 0.01);
        assert_eq!(step_125_up(0.15), 0.2);
        assert_eq!(step_125_up(7.0), 10.0);
        // Errors up to 8% of the mean: the 99th percentile is 7.9%, shown at 10%.
        let (image, full) = ramp_error(1000, 0.08);
        let error = ErrorImage::of(&image, &full);
        let scale = HeatScale::of(&[&error]);
        assert!((scale.top - 0.1).abs() < 1e-6, "{scale:?}");
        let saturated = error.errors.iter().filter(|&&e| e >= scale.top).count();
        assert!(saturated * 100 <= 1000, "{saturated} saturated");
        // Up to 300% with a few outliers past it: the scale follows the 99th percentile, not
        // the outliers.
        let (mut image, full) = ramp_error(1000, 3.0);
        for p in image.pixels.iter_mut().take(5) {
            *p = [50.0; 3];
        }
        let scale = HeatScale::of(&[&ErrorImage::of(&image, &full)]);
        assert!((scale.top - 5.0).abs() < 1e-5, "{scale:?}");
        // The map is black where there is no error, white at full heat; an image without error
        // is black throughout.
        let map = error.heat_map(HeatScale { top: 0.08 });
        assert_eq!(&map[..3], &heat_color(error.errors[0] / 0.08));
        assert_eq!(&map[999 * 3..1000 * 3], &[255, 255, 255]);
        assert!(map[1000 * 3..].iter().all(|&v| v == 0));
        let none = ErrorImage::of(&full, &full);
        let scale = HeatScale::of(&[&none]);
        assert_eq!(scale.top, MIN_HEAT_TOP);
        assert!(none.heat_map(scale).iter().all(|&v| v == 0));
        // One scale for several maps: the largest error's.
        let (small, _) = ramp_error(1000, 0.01);
        let both = HeatScale::of(&[&error, &ErrorImage::of(&small, &full)]);
        assert!(both.top >= 0.05, "{both:?}");
    }

    #[test]
    fn the_colour_bar_is_labelled_with_its_scale() {
        let scale = HeatScale { top: 0.05 };
        assert_eq!(
            scale.ticks(3),
            vec![
                (1.0, "5%".to_string()),
                (0.5, "2.5%".to_string()),
                (0.0, "0%".to_string())
            ]
        );
        assert_eq!(HeatScale { top: 0.002 }.ticks(2)[0].1, "0.2%");
        assert_eq!(HeatScale { top: 10.0 }.ticks(2)[0].1, "1000%");
        let bar = color_bar(scale, 200);
        assert_eq!(bar.labels, vec!["5%", "2.5%", "0%"]);
        assert_eq!(bar.rgb.len(), bar.width * bar.height * 3);
        // The ramp: white at the top, black at the bottom.
        assert_eq!(&bar.rgb[..3], &[255, 255, 255]);
        let last = (199 * bar.width) * 3;
        assert_eq!(&bar.rgb[last..last + 3], &[0, 0, 0]);
        // The labels are drawn right of the ramp, near each tick.
        let lit_rows: Vec<usize> = (0..bar.height)
            .filter(|&y| {
                (RAMP_W + TICK_W + 1..bar.width).any(|x| bar.rgb[(y * bar.width + x) * 3] > 120)
            })
            .collect();
        for row in [0, 100, 199] {
            assert!(
                lit_rows.iter().any(|&y| y.abs_diff(row) <= CAPTION_PX),
                "no label near row {row}"
            );
        }
        // A short bar keeps the label of full heat.
        let short = color_bar(scale, 12);
        assert_eq!(short.labels, vec!["5%"]);
        // Beside an image: the image unchanged, the bar at its right.
        let (w, rgb) = with_color_bar(&[7; 4 * 200 * 3], 4, 200, scale);
        assert_eq!(w, 4 + BAR_GAP + bar.width);
        assert_eq!(&rgb[..12], &[7; 12]);
        let at = (4 + BAR_GAP) * 3;
        assert_eq!(&rgb[at..at + 3], &[255, 255, 255]);
    }
}
