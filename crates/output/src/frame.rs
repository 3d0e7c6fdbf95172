//! The picture of one frame of a run (`frames/decision-NNNNNN.png`): the decision map at one
//! pixel per cell, north up, the ego marked where the scanner stood, and under it a strip that
//! names every colour, so that a single frame opened on its own can be read.
//!
//! The colours are the figures' ([`crate::COLOURS`] by the callers), so a class looks the same
//! in a frame, a figure, the GeoTIFF and Foxglove.

use crate::raster::{Rgb, RgbImage};
use evigrid::{Label, Window};

use crate::error::{OutputError, check_len};
use crate::figure::PATH;
use crate::text::{draw_text, text_width};
use crate::views::{ClassColours, colour_table, paint_into};

/// Height of the legend strip under the map, pixels.
pub const STRIP_PX: u32 = 18;
/// Font size of the strip's labels, pixels.
const STRIP_FONT_PX: f32 = 11.0;
/// Side of a swatch, pixels.
const SWATCH_PX: u32 = 10;
/// Half the span of the ego's cross, pixels (cells).
const EGO_ARM_PX: i64 = 3;
const PAPER: Rgb = Rgb([255, 255, 255]);
const INK: Rgb = Rgb([0, 0, 0]);

/// The labels a frame's strip names, in order: every code a decision map can hold.
pub const STRIP_LABELS: [Label; 7] = [
    Label::F,
    Label::I,
    Label::U,
    Label::S,
    Label::M,
    Label::O,
    Label::Unknown,
];

/// The short name of a label in the strip.
pub fn strip_name(label: Label) -> &'static str {
    match label {
        Label::Unknown => "unknown",
        Label::F => "F",
        Label::I => "I",
        Label::U => "U",
        Label::S => "S",
        Label::M => "M",
        Label::O => "O",
        Label::Edge => "edge",
    }
}

/// The entries of the strip: a colour and its short name, then the ego's mark.
pub fn strip_entries(colours: &ClassColours) -> Vec<([u8; 3], &'static str)> {
    let mut entries: Vec<([u8; 3], &'static str)> = STRIP_LABELS
        .iter()
        .map(|&l| (colours.of(l), strip_name(l)))
        .collect();
    entries.push((PATH.0, "ego"));
    entries
}

/// The frame's picture: `decisions` (storage order) one pixel per cell, north up, a cross in
/// the ego path's colour (black casing) at `ego_xy` (world metres, x east, y north; left out
/// when it is outside the window), and a [`STRIP_PX`]-high legend strip below.
///
/// # Errors
///
/// [`OutputError::Size`] if `decisions` does not have one entry per window cell.
pub fn frame_picture(
    window: &Window,
    decisions: &[Label],
    ego_xy: [f64; 2],
    colours: &ClassColours,
) -> Result<RgbImage, OutputError> {
    check_len("decisions", decisions.len(), window)?;
    let (w, h) = (window.width() as u32, window.height() as u32);
    // The map painted straight into the canvas (no picture of its own copied over), the strip
    // below it on paper.
    let mut canvas = RgbImage::new(w, h + STRIP_PX);
    let table = colour_table(colours);
    paint_into(window, &mut canvas, |idx| table[decisions[idx] as usize]);
    let strip_start = 3 * w as usize * h as usize;
    let bytes = canvas.as_raw_mut();
    for pixel in bytes[strip_start..].chunks_exact_mut(3) {
        pixel.copy_from_slice(&PAPER.0);
    }
    // The ego's cell, in image pixels (row 0 north).
    let s = window.cell_size_m();
    let col = (ego_xy[0] / s).floor() - window.first_col() as f64;
    let row_from_south = (ego_xy[1] / s).floor() - window.first_row() as f64;
    if (0.0..f64::from(w)).contains(&col) && (0.0..f64::from(h)).contains(&row_from_south) {
        let (x, y) = (col as i64, i64::from(h) - 1 - row_from_south as i64);
        draw_cross(&mut canvas, (x, y), h, EGO_ARM_PX + 1, INK);
        draw_cross(&mut canvas, (x, y), h, EGO_ARM_PX, PATH);
    }
    let mut x = 2u32;
    let swatch_top = h + (STRIP_PX - SWATCH_PX) / 2;
    for (colour, name) in strip_entries(colours) {
        if name == "ego" {
            let centre = (
                i64::from(x + SWATCH_PX / 2),
                i64::from(swatch_top + SWATCH_PX / 2),
            );
            draw_cross(&mut canvas, centre, h + STRIP_PX, 5, INK);
            draw_cross(&mut canvas, centre, h + STRIP_PX, 4, PATH);
        } else {
            fill(&mut canvas, x, swatch_top, SWATCH_PX, SWATCH_PX, INK);
            fill(
                &mut canvas,
                x + 1,
                swatch_top + 1,
                SWATCH_PX - 2,
                SWATCH_PX - 2,
                Rgb(colour),
            );
        }
        x += SWATCH_PX + 2;
        draw_text(
            &mut canvas,
            i64::from(x),
            i64::from(h + 2),
            name,
            STRIP_FONT_PX,
            INK,
        );
        x += text_width(name, STRIP_FONT_PX) + 6;
    }
    Ok(canvas)
}

/// A plus sign of arms `arm` pixels, one pixel thick (three for the casing colour when drawn
/// first), clipped to rows `..rows`.
fn draw_cross(canvas: &mut RgbImage, (x, y): (i64, i64), rows: u32, arm: i64, colour: Rgb) {
    let thick = i64::from(colour == INK);
    for d in -arm..=arm {
        for t in -thick..=thick {
            put(canvas, x + d, y + t, rows, colour);
            put(canvas, x + t, y + d, rows, colour);
        }
    }
}

fn put(canvas: &mut RgbImage, x: i64, y: i64, rows: u32, colour: Rgb) {
    if x >= 0 && y >= 0 && x < i64::from(canvas.width()) && y < i64::from(rows) {
        canvas.put_pixel(x as u32, y as u32, colour);
    }
}

fn fill(canvas: &mut RgbImage, x: u32, y: u32, w: u32, h: u32, colour: Rgb) {
    for py in y..(y + h).min(canvas.height()) {
        for px in x..(x + w).min(canvas.width()) {
            canvas.put_pixel(px, py, colour);
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::views::COLOURS;

    #[test]
    fn the_ego_is_crossed_and_every_code_has_a_swatch() {
        // 40 × 30 cells of 0.5 m from cell (0, 0): the ego at (10.2 m, 5.1 m) is cell (20, 10),
        // image pixel (20, 30 − 1 − 10) = (20, 19).
        let window = Window::new(40, 30, 0.5).unwrap();
        let decisions = vec![Label::F; window.len()];
        let picture = frame_picture(&window, &decisions, [10.2, 5.1], &COLOURS).unwrap();
        assert_eq!(picture.dimensions(), (40, 30 + STRIP_PX));
        assert_eq!(picture.get_pixel(20, 19).0, PATH.0);
        assert_eq!(picture.get_pixel(23, 19).0, PATH.0);
        // The casing one pixel past the arm, and free cells beyond it.
        assert_eq!(picture.get_pixel(24, 19).0, [0, 0, 0]);
        assert_eq!(picture.get_pixel(26, 19).0, COLOURS.of(Label::F));
        assert_eq!(picture.get_pixel(0, 0).0, COLOURS.of(Label::F));
        // Every code a decision map holds is named in the strip, in its colour.
        let entries = strip_entries(&COLOURS);
        for label in Label::ALL.into_iter().filter(|&l| l != Label::Edge) {
            assert!(
                entries.contains(&(COLOURS.of(label), strip_name(label))),
                "{label:?}"
            );
        }
        // The first swatch (F) sits in the strip at x 3..11.
        let swatch_y = 30 + (STRIP_PX - SWATCH_PX) / 2 + SWATCH_PX / 2;
        assert_eq!(picture.get_pixel(6, swatch_y).0, COLOURS.of(Label::F));
    }

    #[test]
    fn an_ego_outside_the_window_is_left_out_and_a_short_grid_is_refused() {
        let window = Window::new(4, 4, 1.0).unwrap();
        let decisions = vec![Label::Unknown; window.len()];
        let picture = frame_picture(&window, &decisions, [-50.0, 2.0], &COLOURS).unwrap();
        assert!(
            (0..4).all(|x| (0..4).all(|y| picture.get_pixel(x, y).0 == [0, 0, 0])),
            "no mark on the map"
        );
        assert!(frame_picture(&window, &decisions[1..], [0.0, 0.0], &COLOURS).is_err());
    }
}
