//! Text in the images the engine writes (contact-sheet captions, plot labels, screenshot strips):
//! the Hack face egui ships, rasterised with antialiasing by `ab_glyph` and blended over the
//! pixels beneath, glyph by glyph at each glyph's own bearing: the captions directly, the plots'
//! text through the bitmap backend the plots are drawn on ([`GlyphBackend`]), whose layout
//! plotters takes from the same face ([`register`]).

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, GlyphId, PxScale, ScaleFont, point};
use plotters::backend::{BitMapBackend, DrawingBackend};
use plotters::style::FontStyle;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind,
};

use crate::error::{PrtError, Result};

/// The face every image's text is set in (registered under this name).
pub const FONT: &str = "sans-serif";
/// Caption size in pixels. A size here, as everywhere text is set, is the face's height from
/// its ascender to its descender (its em is 0.86 of that).
pub const CAPTION_PX: usize = 14;
/// Height in pixels of a one-line caption strip: the text and a margin above and below.
pub const CAPTION_HEIGHT: usize = CAPTION_PX + 8;

/// Registers the face once for the process; plotters looks faces up by name.
pub fn register() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, epaint_default_fonts::HACK_REGULAR)
            .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(PrtError::invalid(
            "font",
            "the bundled face could not be read",
        ))
    }
}

/// Width in pixels of `text` set at size `px`: its glyphs' advances and kerning, as
/// [`draw_text_sized`] places them (0 if the face cannot be read, when nothing is drawn).
pub fn width(text: &str, px: usize) -> usize {
    face().map_or(0, |face| {
        set(face, text, PxScale::from(px as f32)).1.ceil() as usize
    })
}

/// `text` set at `scale` from a pen at 0: each glyph with the pen's position at its origin,
/// and the pen's position after the last (its advances, with the kerning between pairs).
fn set(face: &FontRef<'static>, text: &str, scale: PxScale) -> (Vec<(GlyphId, f32)>, f32) {
    let scaled = face.as_scaled(scale);
    let mut pen = 0.0f32;
    let mut previous = None;
    let mut glyphs = Vec::with_capacity(text.len());
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            pen += scaled.kern(p, id);
        }
        previous = Some(id);
        glyphs.push((id, pen));
        pen += scaled.h_advance(id);
    }
    (glyphs, pen)
}

/// Draws `text` at the caption size into an RGB8 buffer of width `w`, its top-left corner at
/// (x0, y0), clipped to the buffer.
pub fn draw_text(rgb: &mut [u8], w: usize, x0: usize, y0: usize, text: &str, color: [u8; 3]) {
    draw_text_sized(rgb, w, x0, y0, text, CAPTION_PX, color);
}

/// [`draw_text`] at size `px`. Each glyph is placed by the face's own metrics: its
/// origin on the pen's whole pixel, its outline at its side bearing from there, every glyph on
/// one baseline. Text that cannot be drawn (no face) is left out: a caption is never worth
/// failing an image for.
pub fn draw_text_sized(
    rgb: &mut [u8],
    w: usize,
    x0: usize,
    y0: usize,
    text: &str,
    px: usize,
    color: [u8; 3],
) {
    let h = rgb.len() / (3 * w.max(1));
    if w == 0 || h == 0 {
        return;
    }
    // The baseline about three quarters of the size below y0: capitals, 0.63 of the size tall,
    // start a pixel or two below it.
    let baseline = ((px + 2) / 4 + px / 2) as f32;
    glyph_pixels(text, px as f32, baseline, |dx, dy, coverage| {
        let (x, y) = (x0 as i64 + i64::from(dx), y0 as i64 + i64::from(dy));
        if (0..w as i64).contains(&x) && (0..h as i64).contains(&y) {
            let i = (y as usize * w + x as usize) * 3;
            blend(&mut rgb[i..i + 3], color, coverage);
        }
    });
}

/// Calls `pixel(x, y, coverage)` for every pixel the glyphs of `text`, set at `size` from a pen
/// at x = 0 on the baseline y = `baseline`, cover: each glyph's origin on the pen's whole pixel,
/// its outline at its side bearing from there. Nothing without the face.
fn glyph_pixels(text: &str, size: f32, baseline: f32, mut pixel: impl FnMut(i32, i32, f32)) {
    let Some(face) = face() else {
        return;
    };
    let scale = PxScale::from(size);
    for (id, pen) in set(face, text, scale).0 {
        let origin = point(pen.round(), baseline);
        if let Some(outline) = face.outline_glyph(id.with_scale_and_position(scale, origin)) {
            // Whole pixels: the box's corner is the first pixel the outline can cover.
            let corner = outline.px_bounds().min;
            outline.draw(|dx, dy, coverage| {
                pixel(
                    corner.x as i32 + dx as i32,
                    corner.y as i32 + dy as i32,
                    coverage,
                )
            });
        }
    }
}

/// The bitmap the plots are drawn on, with their text set glyph by glyph as
/// [`draw_text_sized`] sets it: plotters' own text drops each glyph's side bearing. Everything
/// else is the bitmap's own.
pub struct GlyphBackend<'a>(pub BitMapBackend<'a>);

/// The bitmap's result.
type Drawn<'a> =
    std::result::Result<(), DrawingErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>>;

impl<'a> DrawingBackend for GlyphBackend<'a> {
    type ErrorType = <BitMapBackend<'a> as DrawingBackend>::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.0.get_size()
    }

    fn ensure_prepared(&mut self) -> Drawn<'a> {
        self.0.ensure_prepared()
    }

    fn present(&mut self) -> Drawn<'a> {
        self.0.present()
    }

    fn draw_pixel(&mut self, point: BackendCoord, color: BackendColor) -> Drawn<'a> {
        self.0.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Drawn<'a> {
        self.0.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Drawn<'a> {
        self.0.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn blit_bitmap(&mut self, pos: BackendCoord, size: (u32, u32), src: &[u8]) -> Drawn<'a> {
        self.0.blit_bitmap(pos, size, src)
    }

    /// The text anchored and turned as plotters anchors and turns it (its layout box from the
    /// same face's advances, the baseline half the size below the box's top), each glyph at
    /// its side bearing.
    fn draw_text<T: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &T,
        pos: BackendCoord,
    ) -> Drawn<'a> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        let ((min_x, min_y), (max_x, max_y)) = style
            .layout_box(text)
            .map_err(|e| DrawingErrorKind::FontError(Box::new(e)))?;
        let (width, height) = (max_x - min_x, max_y - min_y);
        let anchor = style.anchor();
        let dx = match anchor.h_pos {
            HPos::Left => 0,
            HPos::Center => -width / 2,
            HPos::Right => -width,
        };
        let dy = match anchor.v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        let turn = style.transform();
        let (w, h) = self.get_size();
        let size = style.size() as f32;
        let mut drawn = Ok(());
        glyph_pixels(text, size, size / 2.0, |x, y, coverage| {
            let (x, y) = turn.transform(x + dx - min_x, y + dy - min_y);
            let (x, y) = (pos.0 + x, pos.1 + y);
            if drawn.is_ok() && (0..w as i32).contains(&x) && (0..h as i32).contains(&y) {
                let alpha = color.alpha * f64::from(coverage.clamp(0.0, 1.0));
                drawn = self.0.draw_pixel(
                    (x, y),
                    BackendColor {
                        alpha,
                        rgb: color.rgb,
                    },
                );
            }
        });
        drawn
    }
}

/// The bundled face, read once for the process; `None` if it cannot be read.
fn face() -> Option<&'static FontRef<'static>> {
    static FACE: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FACE.get_or_init(|| FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR).ok())
        .as_ref()
}

/// `color` laid over the pixel `under` with the glyph's `coverage` of it (0 to 1).
fn blend(under: &mut [u8], color: [u8; 3], coverage: f32) {
    let a = coverage.clamp(0.0, 1.0);
    for (u, c) in under.iter_mut().zip(color) {
        *u = (f32::from(*u) + (f32::from(c) - f32::from(*u)) * a).round() as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    trait MinMax {
        fn minmax(self) -> (usize, usize);
    }
    impl<I: Iterator<Item = usize>> MinMax for I {
        fn minmax(self) -> (usize, usize) {
            self.fold((usize::MAX, 0), |(a, b), v| (a.min(v), b.max(v)))
        }
    }

    #[test]
    fn text_is_drawn_antialiased_where_asked_and_nowhere_else() {
        let (w, h) = (120, 30);
        let mut rgb = vec![0u8; w * h * 3];
        draw_text(&mut rgb, w, 10, 5, "Sunrise 5%", [255, 255, 255]);
        let lit = lit(&rgb, w);
        assert!(lit.len() > 60, "{} lit pixels", lit.len());
        // Inside the text's box, and blended at the edges (levels between black and white).
        let right = 10 + width("Sunrise 5%", CAPTION_PX) + 2;
        let (xs, ys) = (
            lit.iter().map(|p| p.0).minmax(),
            lit.iter().map(|p| p.1).minmax(),
        );
        assert!(
            xs.0 >= 9 && xs.1 <= right,
            "columns {xs:?}, text ends by {right}"
        );
        // The width is the advances': the last glyph (`%`, as wide as its cell) ends at it.
        assert!(
            xs.1 + 3 >= right,
            "columns {xs:?}, the width ends at {right}"
        );
        assert!(ys.0 >= 4 && ys.1 < 5 + 20, "rows {ys:?}");
        assert!(lit.iter().any(|p| p.2 > 30 && p.2 < 220));
    }

    /// The lit pixels (x, y, level) of an RGB8 buffer `w` pixels wide, by its red channel.
    fn lit(rgb: &[u8], w: usize) -> Vec<(usize, usize, u8)> {
        rgb.chunks_exact(3)
            .enumerate()
            .map(|(i, p)| (i % w, i / w, p[0]))
            .filter(|p| p.2 > 0)
            .collect()
    }

    /// The level-weighted mean column of `pixels`, taken at the pixels' centres.
    fn centre(pixels: &[&(usize, usize, u8)]) -> f64 {
        let mass: f64 = pixels.iter().map(|p| f64::from(p.2)).sum();
        pixels
            .iter()
            .map(|p| p.0 as f64 * f64::from(p.2))
            .sum::<f64>()
            / mass
            + 0.5
    }

    /// The advance of a glyph of the (monospaced) face at `size`.
    fn advance(size: f32) -> f64 {
        let scaled = face().unwrap().as_scaled(PxScale::from(size));
        f64::from(scaled.h_advance(scaled.glyph_id('x')))
    }

    /// The lit pixels of each character cell of `text` drawn at the caption size from x = 4:
    /// (centre column from the cell's origin on its whole pixel, lowest row) of each, `None` for
    /// a blank cell.
    fn cells(text: &str) -> Vec<Option<(f64, usize)>> {
        let w = 200;
        let mut rgb = vec![0u8; w * 30 * 3];
        draw_text(&mut rgb, w, 4, 2, text, [255, 255, 255]);
        let lit = lit(&rgb, w);
        let advance = advance(CAPTION_PX as f32);
        (0..text.chars().count())
            .map(|k| {
                let origin = (4.0 + k as f64 * advance).round();
                let cell: Vec<&(usize, usize, u8)> = lit
                    .iter()
                    .filter(|p| (origin..origin + advance).contains(&(p.0 as f64 + 0.5)))
                    .collect();
                (!cell.is_empty()).then(|| {
                    let bottom = cell
                        .iter()
                        .filter(|p| p.2 > 127)
                        .map(|p| p.1)
                        .max()
                        .unwrap();
                    (centre(&cell) - origin, bottom)
                })
            })
            .collect()
    }

    /// The lit pixels (x, y, level) of "8.3" drawn through [`GlyphBackend`] at size 28 from
    /// `at`, turned by `turn`.
    fn plotted(turn: plotters::style::FontTransform, at: (i32, i32)) -> Vec<(usize, usize, u8)> {
        use plotters::prelude::*;
        use plotters::style::text_anchor::Pos;
        register().unwrap();
        let (w, h) = (120usize, 120usize);
        let mut buffer = vec![0u8; w * h * 3];
        {
            let root = GlyphBackend(BitMapBackend::with_buffer(
                &mut buffer,
                (w as u32, h as u32),
            ))
            .into_drawing_area();
            let style = (FONT, 28.0)
                .into_font()
                .transform(turn)
                .color(&WHITE)
                .pos(Pos::new(HPos::Left, VPos::Top));
            root.draw_text("8.3", &style, at).unwrap();
            root.present().unwrap();
        }
        lit(&buffer, w)
    }

    #[test]
    fn the_plots_text_stands_at_its_bearing_upright_and_turned() {
        let advance = advance(28.0);
        // Upright: the point's pixels (the middle cell, below the digits' middle) centre on the
        // middle of its cell, where plotters' own text put them against the 8.
        let lit = plotted(plotters::style::FontTransform::None, (10, 10));
        let cell = |x: usize| ((x as f64 - 10.0) / advance).floor() as i64;
        let point: Vec<&(usize, usize, u8)> = lit.iter().filter(|p| cell(p.0) == 1).collect();
        let centre = centre(&point);
        let middle = 10.0 + advance.round() + advance / 2.0;
        assert!(
            (centre - middle).abs() < 1.0,
            "the point centres at {centre:.2}, its cell's middle is {middle:.2}"
        );
        // A quarter turn draws the same text along y, upwards from where it is anchored: its
        // box is the upright one's, turned.
        let turned = plotted(plotters::style::FontTransform::Rotate270, (10, 100));
        let extent = |v: &[(usize, usize, u8)], f: fn(&(usize, usize, u8)) -> usize| {
            v.iter().map(f).max().unwrap() - v.iter().map(f).min().unwrap()
        };
        let (tw, th) = (extent(&turned, |p| p.0), extent(&turned, |p| p.1));
        let (uw, uh) = (extent(&lit, |p| p.0), extent(&lit, |p| p.1));
        assert!(
            th > tw && (th, tw) == (uw, uh),
            "turned {tw} x {th}, upright {uw} x {uh}"
        );
    }

    #[test]
    fn each_glyph_stands_at_its_own_bearing_on_one_baseline() {
        // Hack is monospaced: a point sits in the middle of its cell, not at its left edge
        // (where a glyph drawn from its box's corner, without its side bearing, would stand).
        let got = cells("8.3x");
        let advance = advance(CAPTION_PX as f32);
        let (point_centre, _) = got[1].unwrap();
        assert!(
            (point_centre - advance / 2.0).abs() < 1.0,
            "the point's centre {point_centre:.2} px into a cell {advance:.2} wide"
        );
        // Every glyph without a descender ends on one row.
        let bottoms: Vec<usize> = got.iter().map(|c| c.unwrap().1).collect();
        assert!(bottoms.windows(2).all(|b| b[0] == b[1]), "{bottoms:?}");
        // And the same glyph is drawn alike in every cell: whole-pixel origins.
        let same = cells("....");
        assert!(
            same.windows(2)
                .all(|c| (c[0].unwrap().0 - c[1].unwrap().0).abs() < 1e-9),
            "{same:?}"
        );
    }
}
