//! Contact sheets: a grid of tone-mapped thumbnails with a caption under each, written as PNG.
//! Captions are set by [`crate::output::text`].

use std::path::Path;

use crate::error::Result;
use crate::output::film::{Image, ToneMap, write_png};
use crate::output::text::{CAPTION_PX, draw_text, fit_text};

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
                &fit_text(line, cw),
                [220, 220, 220],
            );
        }
    }
    write_png(path, w, h, &rgb)
}
