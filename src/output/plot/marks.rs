//! The marks a plot is drawn with: lines (solid or dashed), point markers, labels wrapped to
//! a width, and the legend.

use super::*;

/// An RGB8 colour as plotters takes it.
pub(super) fn rgb([r, g, b]: [u8; 3]) -> RGBColor {
    RGBColor(r, g, b)
}

/// The dashes of a polyline: pieces `on` long with gaps `off` long (both above 0), the pattern
/// running on across its corners.
pub(super) fn dashes(points: &[(f64, f64)], on: f64, off: f64) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut dash: Vec<(f64, f64)> = Vec::new();
    // Distance into the pattern: drawing below `on`, in the gap from `on` to `on + off`.
    let mut phase = 0.0;
    for w in points.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        let len = (x1 - x0).hypot(y1 - y0);
        let at = |d: f64| (x0 + (x1 - x0) * d / len, y0 + (y1 - y0) * d / len);
        let mut d = 0.0;
        while d < len {
            let drawing = phase < on;
            let edge = if drawing { on } else { on + off };
            // To the pattern's next edge, or to the segment's end.
            let (next_d, next_phase) = if edge - phase < len - d {
                (d + edge - phase, edge)
            } else {
                (len, phase + len - d)
            };
            if drawing {
                if dash.is_empty() {
                    dash.push(at(d));
                }
                dash.push(at(next_d));
            }
            (d, phase) = (next_d, next_phase);
            if phase >= on && !dash.is_empty() {
                out.push(std::mem::take(&mut dash));
            }
            if phase >= on + off {
                phase = 0.0;
            }
        }
    }
    if dash.len() > 1 {
        out.push(dash);
    }
    out
}

/// Draws the polyline `px` (pixels of the drawing) in `look`'s width and dashes.
pub(super) fn draw_line(root: &Root, px: &[(i32, i32)], look: &Look, color: RGBColor) -> Drawn {
    if look.width == 0 || px.len() < 2 {
        return Ok(());
    }
    let s = SUPERSAMPLE as u32;
    let style = color.stroke_width(look.width * s);
    let pieces: Vec<Vec<(i32, i32)>> = match look.dash {
        None => vec![px.to_vec()],
        Some((on, off)) => {
            let line: Vec<(f64, f64)> = px.iter().map(|&(x, y)| (x as f64, y as f64)).collect();
            let (on, off) = ((on.max(1) * s) as f64, (off.max(1) * s) as f64);
            dashes(&line, on, off)
                .into_iter()
                .map(|d| {
                    d.into_iter()
                        .map(|(x, y)| (x.round() as i32, y.round() as i32))
                        .collect()
                })
                .collect()
        }
    };
    for piece in pieces {
        root.draw(&PathElement::new(piece, style))?;
    }
    Ok(())
}

/// The corners of a polygon marker of radius `r` about (x, y).
pub(super) fn outline(marker: Marker, (x, y): (i32, i32), r: i32) -> Vec<(i32, i32)> {
    match marker {
        Marker::Triangle => {
            let (half, low) = (r * 7 / 8, r / 2);
            vec![(x, y - r), (x + half, y + low), (x - half, y + low)]
        }
        Marker::Square => {
            let a = r * 4 / 5;
            vec![
                (x - a, y - a),
                (x + a, y - a),
                (x + a, y + a),
                (x - a, y + a),
            ]
        }
        _ => vec![(x, y - r), (x + r, y), (x, y + r), (x - r, y)],
    }
}

/// Draws `look`'s marker centred on `c` (pixels of the drawing).
pub(super) fn draw_marker(root: &Root, c: (i32, i32), look: &Look, color: RGBColor) -> Drawn {
    let s = SUPERSAMPLE as i32;
    let (r, stroke) = (look.size as i32 * s, MARKER_STROKE * s);
    let (x, y) = c;
    if look.marker == Marker::Cross {
        let style = color.stroke_width(stroke as u32);
        root.draw(&PathElement::new(
            vec![(x - r, y - r), (x + r, y + r)],
            style,
        ))?;
        root.draw(&PathElement::new(
            vec![(x - r, y + r), (x + r, y - r)],
            style,
        ))?;
        return Ok(());
    }
    let shape = |r: i32, fill: RGBColor| -> Drawn {
        match look.marker {
            Marker::Circle => root.draw(&Circle::new(c, r.max(1) as u32, fill.filled()))?,
            m => root.draw(&Polygon::new(outline(m, c, r), fill.filled()))?,
        }
        Ok(())
    };
    shape(r, color)?;
    if !look.filled && r > stroke {
        shape(r - stroke, WHITE)?;
    }
    Ok(())
}

/// `text` broken at spaces into lines at most `max` pixels wide at size `px` (as
/// [`crate::output::text::CAPTION_PX`]); a word wider than that has a line of its own.
pub(super) fn wrap(text: &str, px: usize, max: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split(' ') {
        match lines.last_mut() {
            Some(l) if text_width(&format!("{l} {word}"), px) <= max => {
                l.push(' ');
                l.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    lines
}

/// Draws a level's label: `lines` in a light box whose right edge is at `right` and whose
/// bottom sits just above the line at `line_y`, moved down below `below` (the bottom of the
/// label above it) where they would overlap. Returns the box's bottom.
pub(super) fn draw_label(
    root: &Root,
    lines: &[String],
    (right, line_y): (i32, i32),
    below: i32,
    font: &TextStyle,
) -> std::result::Result<i32, Box<dyn std::error::Error>> {
    if lines.is_empty() {
        return Ok(below);
    }
    let s = SUPERSAMPLE as i32;
    let px = LABEL_PT as usize;
    let widest = lines.iter().map(|l| text_width(l, px)).max().unwrap_or(0) as i32;
    let (w, h) = ((widest + 2 * PAD) * s, (lines.len() as i32 * ROW + PAD) * s);
    let top = (line_y - s - h).max(below + s);
    let left = right - w;
    let corners = [(left, top), (right, top + h)];
    root.draw(&Rectangle::new(corners, WHITE.mix(0.75).filled()))?;
    let style = font.pos(Pos::new(HPos::Left, VPos::Center));
    for (i, line) in lines.iter().enumerate() {
        let y = top + (PAD / 2 + ROW * i as i32 + ROW / 2) * s;
        root.draw_text(line, &style, (left + PAD * s, y))?;
    }
    Ok(top + h)
}

/// Draws the legend: a row per drawn series (its line and marker, then its label) in a box at
/// `corner` of `frame` (left, top, right, bottom).
pub(super) fn draw_legend(
    root: &Root,
    frame: [i32; 4],
    rows: &[(&str, Look, RGBColor)],
    corner: Corner,
    font: &TextStyle,
) -> Drawn {
    if rows.is_empty() {
        return Ok(());
    }
    let s = SUPERSAMPLE as i32;
    let px = LABEL_PT as usize;
    let widest = rows
        .iter()
        .map(|(l, ..)| text_width(l, px))
        .max()
        .unwrap_or(0) as i32;
    let w = (2 * PAD + SWATCH + GAP + widest) * s;
    let h = (2 * PAD + ROW * rows.len() as i32) * s;
    let [x0, y0, x1, y1] = frame;
    let left = match corner {
        Corner::UpperLeft | Corner::LowerLeft => x0 + INSET * s,
        Corner::UpperRight | Corner::LowerRight => x1 - INSET * s - w,
    };
    let top = match corner {
        Corner::UpperLeft | Corner::UpperRight => y0 + INSET * s,
        Corner::LowerLeft | Corner::LowerRight => y1 - INSET * s - h,
    };
    let corners = [(left, top), (left + w, top + h)];
    root.draw(&Rectangle::new(corners, WHITE.mix(0.9).filled()))?;
    root.draw(&Rectangle::new(
        corners,
        LEGEND_BORDER.stroke_width(s as u32),
    ))?;
    let style = font.pos(Pos::new(HPos::Left, VPos::Center));
    for (i, (label, look, color)) in rows.iter().enumerate() {
        let x = left + PAD * s;
        let y = top + (PAD + ROW * i as i32 + ROW / 2) * s;
        draw_line(root, &[(x, y), (x + SWATCH * s, y)], look, *color)?;
        draw_marker(root, (x + SWATCH * s / 2, y), look, *color)?;
        root.draw_text(label, &style, (x + (SWATCH + GAP) * s, y))?;
    }
    Ok(())
}
