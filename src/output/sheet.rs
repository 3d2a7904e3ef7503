//! Contact sheets: a grid of tone-mapped thumbnails with a caption under each, written as PNG.
//! Captions use a small built-in 5 x 7 bitmap font, so no font file or font crate is needed.

use std::path::Path;

use crate::error::Result;
use crate::output::film::{Image, ToneMap, write_atomically, write_png};

/// One cell of a sheet.
pub struct Cell<'a> {
    pub image: &'a Image,
    pub tone: ToneMap,
    /// Up to two caption lines.
    pub caption: [String; 2],
}

const GLYPH_W: usize = 5;
const GLYPH_H: usize = 7;
/// Pixels per font pixel.
const SCALE: usize = 2;
const LINE_H: usize = (GLYPH_H + 2) * SCALE;
const PAD: usize = 4;

/// Rows of a 5 x 7 glyph, high bit left; unknown characters draw as a box.
fn glyph(ch: char) -> [u8; 7] {
    match ch.to_ascii_uppercase() {
        '0' => [0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e],
        '1' => [0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e],
        '2' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f],
        '3' => [0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e],
        '4' => [0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02],
        '5' => [0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e],
        '6' => [0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e],
        '7' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e],
        '9' => [0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c],
        'A' => [0x0e, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11],
        'B' => [0x1e, 0x11, 0x11, 0x1e, 0x11, 0x11, 0x1e],
        'C' => [0x0e, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0e],
        'D' => [0x1c, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1c],
        'E' => [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x1f],
        'F' => [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x10],
        'G' => [0x0e, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0f],
        'H' => [0x11, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11],
        'I' => [0x0e, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0c],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1f],
        'M' => [0x11, 0x1b, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'P' => [0x1e, 0x11, 0x11, 0x1e, 0x10, 0x10, 0x10],
        'Q' => [0x0e, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0d],
        'R' => [0x1e, 0x11, 0x11, 0x1e, 0x14, 0x12, 0x11],
        'S' => [0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e],
        'T' => [0x1f, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0a, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0a],
        'X' => [0x11, 0x11, 0x0a, 0x04, 0x0a, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0a, 0x04, 0x04, 0x04],
        'Z' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1f],
        ' ' => [0; 7],
        '.' => [0, 0, 0, 0, 0, 0x0c, 0x0c],
        ',' => [0, 0, 0, 0, 0x0c, 0x04, 0x08],
        ':' => [0, 0x0c, 0x0c, 0, 0x0c, 0x0c, 0],
        '=' => [0, 0, 0x1f, 0, 0x1f, 0, 0],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        '-' => [0, 0, 0, 0x1f, 0, 0, 0],
        '_' => [0, 0, 0, 0, 0, 0, 0x1f],
        '/' => [0, 0x01, 0x02, 0x04, 0x08, 0x10, 0],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '+' => [0, 0x04, 0x04, 0x1f, 0x04, 0x04, 0],
        '*' => [0, 0x04, 0x15, 0x0e, 0x15, 0x04, 0],
        '<' => [0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02],
        '>' => [0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08],
        '[' => [0x0e, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0e],
        ']' => [0x0e, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0e],
        '|' => [0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        '^' => [0x04, 0x0a, 0x11, 0, 0, 0, 0],
        '\'' => [0x04, 0x04, 0x08, 0, 0, 0, 0],
        '"' => [0x0a, 0x0a, 0x0a, 0, 0, 0, 0],
        '!' => [0x04, 0x04, 0x04, 0x04, 0x04, 0, 0x04],
        '?' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0, 0x04],
        ';' => [0, 0x0c, 0x0c, 0, 0x0c, 0x04, 0x08],
        '#' => [0x0a, 0x0a, 0x1f, 0x0a, 0x1f, 0x0a, 0x0a],
        '&' => [0x0c, 0x12, 0x14, 0x08, 0x15, 0x12, 0x0d],
        '~' => [0, 0, 0x08, 0x15, 0x02, 0, 0],
        _ => [0x1f, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1f],
    }
}

/// Height in pixels of a one-line caption strip: the glyphs and a margin above and below.
pub const CAPTION_HEIGHT: usize = GLYPH_H * SCALE + 8;

/// `text` cut to fit `width` pixels in this font, with `..` where it was cut.
pub fn fit_text(text: &str, width: usize) -> String {
    let per = (GLYPH_W + 1) * SCALE;
    let fits = width / per;
    if text.chars().count() <= fits {
        return text.to_string();
    }
    let kept: String = text.chars().take(fits.saturating_sub(2)).collect();
    format!("{kept}..")
}

/// Draws `text` into an RGB8 buffer of width `w` at (x0, y0), clipped to the buffer.
pub fn draw_text(rgb: &mut [u8], w: usize, x0: usize, y0: usize, text: &str, color: [u8; 3]) {
    let h = rgb.len() / (3 * w);
    for (i, ch) in text.chars().enumerate() {
        let rows = glyph(ch);
        let gx = x0 + i * (GLYPH_W + 1) * SCALE;
        for (ry, bits) in rows.iter().enumerate() {
            for rx in 0..GLYPH_W {
                if bits & (0x10 >> rx) == 0 {
                    continue;
                }
                for sy in 0..SCALE {
                    for sx in 0..SCALE {
                        let (x, y) = (gx + rx * SCALE + sx, y0 + ry * SCALE + sy);
                        if x < w && y < h {
                            rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&color);
                        }
                    }
                }
            }
        }
    }
}

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
/// writes a PNG. All images must share one size.
pub fn write_sheet(path: &Path, columns: usize, cells: &[Cell], title: &str) -> Result<()> {
    let (cw, ch) = cells
        .first()
        .map(|c| (c.image.width, c.image.height))
        .unwrap_or((1, 1));
    let rows = cells.len().div_ceil(columns.max(1));
    let title_h = LINE_H + 2 * PAD;
    let cell_w = cw + PAD;
    let cell_h = ch + 2 * LINE_H + PAD;
    let (w, h) = (columns * cell_w + PAD, title_h + rows * cell_h + PAD);
    let mut rgb = vec![24u8; w * h * 3];
    draw_text(&mut rgb, w, PAD, PAD, title, [235, 235, 235]);
    for (i, cell) in cells.iter().enumerate() {
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
        for (l, line) in cell.caption.iter().enumerate() {
            draw_text(
                &mut rgb,
                w,
                x0,
                y0 + ch + 2 + l * LINE_H,
                line,
                [220, 220, 220],
            );
        }
    }
    write_atomically(path, |tmp| write_png(tmp, w, h, &rgb))
}
