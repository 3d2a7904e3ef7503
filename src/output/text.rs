//! Text in the images the engine writes (contact-sheet captions, plot labels, screenshot strips):
//! the Hack face egui ships, rasterised with antialiasing by `ab_glyph` through `plotters`, and
//! blended over the pixels beneath.

use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{PrtError, Result};

/// The face every image's text is set in (registered under this name).
pub const FONT: &str = "sans-serif";
/// Caption size, pixels per em.
pub const CAPTION_PX: usize = 14;
/// Height in pixels of a one-line caption strip: the text and a margin above and below.
pub const CAPTION_HEIGHT: usize = CAPTION_PX + 8;
/// Horizontal advance of one character of the monospace face, as a fraction of its size.
const ADVANCE: f64 = 0.602;

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

/// Width in pixels of `text` at `px` pixels per em.
pub fn width(text: &str, px: usize) -> usize {
    (text.chars().count() as f64 * ADVANCE * px as f64).ceil() as usize
}

/// `text` cut to fit `width` pixels at the caption size, with `..` where it was cut.
pub fn fit_text(text: &str, max_width: usize) -> String {
    if width(text, CAPTION_PX) <= max_width {
        return text.to_string();
    }
    let fits = (max_width as f64 / (ADVANCE * CAPTION_PX as f64)).floor() as usize;
    let kept: String = text.chars().take(fits.saturating_sub(2)).collect();
    format!("{kept}..")
}

/// Draws `text` at the caption size into an RGB8 buffer of width `w`, its top-left corner at
/// (x0, y0), clipped to the buffer.
pub fn draw_text(rgb: &mut [u8], w: usize, x0: usize, y0: usize, text: &str, color: [u8; 3]) {
    draw_text_sized(rgb, w, x0, y0, text, CAPTION_PX, color);
}

/// [`draw_text`] at `px` pixels per em. Text that cannot be drawn (no face) is left out: a
/// caption is never worth failing an image for.
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
    if w == 0 || h == 0 || register().is_err() {
        return;
    }
    let root = BitMapBackend::with_buffer(rgb, (w as u32, h as u32)).into_drawing_area();
    let [r, g, b] = color;
    let style = (FONT, px as f64)
        .into_font()
        .color(&RGBColor(r, g, b))
        .pos(Pos::new(HPos::Left, VPos::Top));
    // The face's top anchor sits about a quarter em above its capitals: start them at y0.
    let y = y0 as i32 + (px as i32 + 2) / 4;
    let _ = root.draw_text(text, &style, (x0 as i32, y));
    let _ = root.present();
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
        let lit: Vec<(usize, usize, u8)> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| (x, y, rgb[(y * w + x) * 3]))
            .filter(|p| p.2 > 0)
            .collect();
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
        assert!(ys.0 >= 4 && ys.1 < 5 + 20, "rows {ys:?}");
        assert!(lit.iter().any(|p| p.2 > 30 && p.2 < 220));
    }

    #[test]
    fn long_text_is_cut_to_fit() {
        let s = fit_text("a very long caption that cannot fit", 100);
        assert!(s.ends_with(".."));
        assert!(width(&s, CAPTION_PX) <= 100, "{s}");
        assert_eq!(fit_text("short", 100), "short");
    }
}
