//! Pictures of an evaluation: a confusion-matrix heat map per variant and a per-class IoU bar
//! chart, as plain [`RgbImage`]s (the caller encodes and writes them).
//!
//! No font library is available, so labels are drawn with a tiny built-in 5 × 7 bitmap font
//! ([`draw_text`]): digits, the letters A–Z (lower case is drawn as upper case), space and
//! `. - % ?`. Any other character is drawn as `?`.
//!
//! # Confusion heat map ([`confusion_heatmap`])
//! ```text
//!   TITLE (variant name)
//!        F    I    U    S    M    O    ?      ← predicted class (? = no decision)
//!   F  [ 75 ][ 25 ][  0 ] ...                 ← one row per truth class
//!   I  [    ][    ] ...
//! ```
//! Rows are truth F, I, U, S, M; columns are predictions F, I, U, S, M, O (occupied, static, not
//! resolved: two-class baselines), ? (unknown). A cell's shade goes from white (0 % of its row)
//! to dark blue (100 % of its row) and it shows the row percentage, rounded. A row without any
//! truth cell is grey. Row normalisation shows per-class recall on the diagonal whatever the
//! class frequencies (free cells outnumber moving ones by orders of magnitude).
//!
//! # Per-class IoU chart ([`per_class_iou_chart`])
//! Five groups F, I, U, S, M from left to right; in each group one bar per variant in the given
//! order, coloured by the variant's index in [`PALETTE`] (Okabe–Ito colours, distinguishable with
//! colour-blindness). Bar height is the IoU on a 0–1 axis with grey grid lines every 0.25; an
//! undefined IoU (class absent from truth and prediction) is a short grey stub below the axis. A
//! legend (colour swatch, variant name) is on the right.

use crate::metrics::{ConfusionMatrix, TRUTH_NAMES};
use crate::report::{EvalReport, VariantReport};
use image::{Rgb, RgbImage};

/// Width of a glyph of the built-in font, pixels at scale 1.
pub const GLYPH_WIDTH: u32 = 5;
/// Height of a glyph of the built-in font, pixels at scale 1.
pub const GLYPH_HEIGHT: u32 = 7;
/// Horizontal advance per character, pixels at scale 1 (glyph plus one blank column).
pub const GLYPH_ADVANCE: u32 = GLYPH_WIDTH + 1;

/// Colours of the variants' bars, in order (Okabe & Ito 2008, colour-blind safe).
pub const PALETTE: [Rgb<u8>; 8] = [
    Rgb([0, 114, 178]),   // blue
    Rgb([230, 159, 0]),   // orange
    Rgb([0, 158, 115]),   // bluish green
    Rgb([204, 121, 167]), // reddish purple
    Rgb([213, 94, 0]),    // vermillion
    Rgb([86, 180, 233]),  // sky blue
    Rgb([240, 228, 66]),  // yellow
    Rgb([0, 0, 0]),       // black
];

/// Background of every picture.
pub const BACKGROUND: Rgb<u8> = Rgb([255, 255, 255]);
/// Colour of labels on a light background.
pub const INK: Rgb<u8> = Rgb([0, 0, 0]);
/// Heat-map colour of a fraction of 1 (a fraction f mixes white and this linearly).
pub const HEAT_FULL: Rgb<u8> = Rgb([8, 48, 107]);
/// Heat-map colour of a row with no truth cell.
pub const EMPTY_ROW: Rgb<u8> = Rgb([200, 200, 200]);
/// Colour of grid lines and of undefined-IoU stubs.
pub const GRID_GREY: Rgb<u8> = Rgb([190, 190, 190]);

/// Rows of a glyph, top to bottom; bit 4 is the leftmost of the 5 columns.
// One glyph per line keeps the bitmaps readable; rustfmt would split each over three lines.
#[rustfmt::skip]
fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        '0' => [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110],
        '1' => [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110],
        '2' => [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111],
        '3' => [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110],
        '4' => [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010],
        '5' => [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110],
        '6' => [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110],
        '7' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000],
        '8' => [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110],
        '9' => [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100],
        'A' => [0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001],
        'B' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110],
        'C' => [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110],
        'D' => [0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100],
        'E' => [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111],
        'F' => [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000],
        'G' => [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111],
        'H' => [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001],
        'I' => [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110],
        'J' => [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100],
        'K' => [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001],
        'L' => [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111],
        'M' => [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001],
        'N' => [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001],
        'O' => [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110],
        'P' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000],
        'Q' => [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101],
        'R' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001],
        'S' => [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110],
        'T' => [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100],
        'U' => [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110],
        'V' => [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100],
        'W' => [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010],
        'X' => [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001],
        'Y' => [0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100],
        'Z' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111],
        ' ' => [0; 7],
        '.' => [0, 0, 0, 0, 0, 0b01100, 0b01100],
        '-' => [0, 0, 0, 0b11111, 0, 0, 0],
        '%' => [0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011],
        _ => [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0, 0b00100], // '?'
    }
}

/// Width in pixels of `text` drawn at `scale` (no trailing blank column).
pub fn text_width(text: &str, scale: u32) -> u32 {
    let n = text.chars().count() as u32;
    (n * GLYPH_ADVANCE).saturating_sub(1) * scale
}

/// Draws `text` with its top-left corner at (`x`, `y`), each font pixel a `scale` × `scale`
/// square. Pixels falling outside the image are skipped.
pub fn draw_text(image: &mut RgbImage, x: i64, y: i64, text: &str, scale: u32, colour: Rgb<u8>) {
    let scale = i64::from(scale.max(1));
    for (k, c) in text.chars().enumerate() {
        let left = x + k as i64 * i64::from(GLYPH_ADVANCE) * scale;
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..GLYPH_WIDTH {
                if bits & (1 << (GLYPH_WIDTH - 1 - col)) != 0 {
                    fill_rect(
                        image,
                        left + i64::from(col) * scale,
                        y + row as i64 * scale,
                        scale as u32,
                        scale as u32,
                        colour,
                    );
                }
            }
        }
    }
}

/// Fills a rectangle, clipped to the image.
fn fill_rect(image: &mut RgbImage, x: i64, y: i64, width: u32, height: u32, colour: Rgb<u8>) {
    let x0 = x.clamp(0, i64::from(image.width())) as u32;
    let y0 = y.clamp(0, i64::from(image.height())) as u32;
    let x1 = (x + i64::from(width)).clamp(0, i64::from(image.width())) as u32;
    let y1 = (y + i64::from(height)).clamp(0, i64::from(image.height())) as u32;
    for py in y0..y1 {
        for px in x0..x1 {
            image.put_pixel(px, py, colour);
        }
    }
}

/// White mixed with [`HEAT_FULL`] in proportion `fraction` (clamped to [0, 1]; NaN is 0).
pub fn heat_colour(fraction: f64) -> Rgb<u8> {
    let f = if fraction.is_nan() {
        0.0
    } else {
        fraction.clamp(0.0, 1.0)
    };
    let mix = |full: u8| (255.0 + (f64::from(full) - 255.0) * f).round() as u8;
    Rgb([mix(HEAT_FULL[0]), mix(HEAT_FULL[1]), mix(HEAT_FULL[2])])
}

/// Labels of the heat map's columns: predictions F, I, U, S, M, O and unknown (`?`).
const PREDICTED_LABELS: [&str; 7] = ["F", "I", "U", "S", "M", "O", "?"];

/// Geometry of the confusion heat map, pixels.
pub mod heatmap_layout {
    /// Width of a matrix cell.
    pub const CELL_WIDTH: u32 = 44;
    /// Height of a matrix cell.
    pub const CELL_HEIGHT: u32 = 30;
    /// Scale of the font for labels and percentages.
    pub const FONT_SCALE: u32 = 2;
    /// Left edge of the matrix (room for the row labels).
    pub const LEFT: u32 = 32;
    /// Top edge of the matrix (room for the title and the column labels).
    pub const TOP: u32 = 56;
    /// Outer margin on the right and at the bottom.
    pub const MARGIN: u32 = 8;
}

/// The confusion heat map of `matrix` with `title` above it (layout in the module docs and
/// [`heatmap_layout`]): matrix cell (truth t, prediction p) covers
/// `x ∈ [LEFT + p·CELL_WIDTH, LEFT + (p+1)·CELL_WIDTH)`, `y ∈ [TOP + t·CELL_HEIGHT, …)`.
pub fn confusion_heatmap(title: &str, matrix: &ConfusionMatrix) -> RgbImage {
    use heatmap_layout::*;
    let columns = PREDICTED_LABELS.len() as u32;
    let rows = TRUTH_NAMES.len() as u32;
    let width = (LEFT + columns * CELL_WIDTH + MARGIN).max(text_width(title, FONT_SCALE) + 16);
    let height = TOP + rows * CELL_HEIGHT + MARGIN;
    let mut image = RgbImage::from_pixel(width, height, BACKGROUND);
    let glyph_h = GLYPH_HEIGHT * FONT_SCALE;
    draw_text(&mut image, 8, 6, title, FONT_SCALE, INK);
    for (p, label) in PREDICTED_LABELS.iter().enumerate() {
        let x = LEFT + p as u32 * CELL_WIDTH + (CELL_WIDTH - text_width(label, FONT_SCALE)) / 2;
        draw_text(
            &mut image,
            i64::from(x),
            i64::from(TOP - glyph_h - 6),
            label,
            FONT_SCALE,
            INK,
        );
    }
    for (t, row) in matrix.counts.iter().enumerate() {
        let top = TOP + t as u32 * CELL_HEIGHT;
        let label = TRUTH_NAMES[t];
        draw_text(
            &mut image,
            i64::from((LEFT - text_width(label, FONT_SCALE)) / 2),
            i64::from(top + (CELL_HEIGHT - glyph_h) / 2),
            label,
            FONT_SCALE,
            INK,
        );
        let total: u64 = row.iter().sum();
        for (p, &count) in row.iter().enumerate() {
            let left = LEFT + p as u32 * CELL_WIDTH;
            if total == 0 {
                fill_rect(
                    &mut image,
                    i64::from(left),
                    i64::from(top),
                    CELL_WIDTH,
                    CELL_HEIGHT,
                    EMPTY_ROW,
                );
                continue;
            }
            let fraction = count as f64 / total as f64;
            fill_rect(
                &mut image,
                i64::from(left),
                i64::from(top),
                CELL_WIDTH,
                CELL_HEIGHT,
                heat_colour(fraction),
            );
            // White on the darker half of the scale keeps the number readable.
            let ink = if fraction > 0.5 { BACKGROUND } else { INK };
            let text = format!("{}", (fraction * 100.0).round() as u32);
            draw_text(
                &mut image,
                i64::from(left + (CELL_WIDTH - text_width(&text, FONT_SCALE)) / 2),
                i64::from(top + (CELL_HEIGHT - glyph_h) / 2),
                &text,
                FONT_SCALE,
                ink,
            );
        }
    }
    image
}

/// Geometry of the per-class IoU chart, pixels.
pub mod chart_layout {
    /// Width of one bar.
    pub const BAR_WIDTH: u32 = 14;
    /// Gap between two bars of a group.
    pub const BAR_GAP: u32 = 2;
    /// Gap between two groups (and before the first one).
    pub const GROUP_GAP: u32 = 20;
    /// Height of the 0–1 axis.
    pub const PLOT_HEIGHT: u32 = 200;
    /// Left edge of the plot area (room for the tick labels).
    pub const LEFT: u32 = 40;
    /// Top edge of the plot area (the IoU = 1 line).
    pub const TOP: u32 = 12;
    /// Room below the axis for the class labels.
    pub const BOTTOM: u32 = 34;
    /// Font scale of the class labels (tick labels and the legend use scale 1 … 2, see code).
    pub const FONT_SCALE: u32 = 2;
    /// Height of a stub marking an undefined IoU, below the axis.
    pub const STUB_HEIGHT: u32 = 3;
}

/// The per-class IoU bar chart of `series` (name, IoU of F, I, U, S, M); layout in the module
/// docs and [`chart_layout`]. Group g starts at `x = LEFT + GROUP_GAP + g·(n·(BAR_WIDTH+BAR_GAP)
/// + GROUP_GAP)`, bar v of it `v·(BAR_WIDTH+BAR_GAP)` further right; the axis (IoU 0) is the row
/// `y = TOP + PLOT_HEIGHT`, and a bar of IoU u covers the `round(u·PLOT_HEIGHT)` rows above it.
pub fn per_class_iou_chart(series: &[(&str, [Option<f64>; 5])]) -> RgbImage {
    use chart_layout::*;
    let n = series.len().max(1) as u32;
    let group_width = n * (BAR_WIDTH + BAR_GAP);
    let plot_right = LEFT + GROUP_GAP + 5 * (group_width + GROUP_GAP);
    let legend_left = plot_right + 12;
    let legend_text_width = series
        .iter()
        .map(|(name, _)| text_width(name, FONT_SCALE))
        .max()
        .unwrap_or(0);
    let width = legend_left + 20 + legend_text_width + 12;
    let axis_y = TOP + PLOT_HEIGHT;
    let legend_height = 10 + series.len() as u32 * 22;
    let height = (axis_y + BOTTOM).max(TOP + legend_height);
    let mut image = RgbImage::from_pixel(width, height, BACKGROUND);

    // Grid lines every 0.25 with tick labels at 0, 0.5 and 1.
    for k in 0..=4u32 {
        let y = axis_y - k * PLOT_HEIGHT / 4;
        let colour = if k == 0 { INK } else { GRID_GREY };
        fill_rect(
            &mut image,
            i64::from(LEFT),
            i64::from(y),
            plot_right - LEFT,
            1,
            colour,
        );
        if k % 2 == 0 {
            let label = ["0", "", "0.5", "", "1"][k as usize];
            draw_text(
                &mut image,
                i64::from(LEFT - 6 - text_width(label, 1)),
                i64::from(y) - i64::from(GLYPH_HEIGHT / 2),
                label,
                1,
                INK,
            );
        }
    }
    fill_rect(
        &mut image,
        i64::from(LEFT),
        i64::from(TOP),
        1,
        PLOT_HEIGHT + 1,
        INK,
    );

    for (g, class) in TRUTH_NAMES.iter().enumerate() {
        let group_left = LEFT + GROUP_GAP + g as u32 * (group_width + GROUP_GAP);
        for (v, (_, ious)) in series.iter().enumerate() {
            let x = group_left + v as u32 * (BAR_WIDTH + BAR_GAP);
            match ious[g] {
                Some(iou) if iou.is_finite() => {
                    let bar = (iou.clamp(0.0, 1.0) * f64::from(PLOT_HEIGHT)).round() as u32;
                    fill_rect(
                        &mut image,
                        i64::from(x),
                        i64::from(axis_y - bar),
                        BAR_WIDTH,
                        bar,
                        PALETTE[v % PALETTE.len()],
                    );
                }
                _ => fill_rect(
                    &mut image,
                    i64::from(x),
                    i64::from(axis_y + 2),
                    BAR_WIDTH,
                    STUB_HEIGHT,
                    GRID_GREY,
                ),
            }
        }
        let label_x = group_left + (group_width - text_width(class, FONT_SCALE)) / 2;
        draw_text(
            &mut image,
            i64::from(label_x),
            i64::from(axis_y + 2 + STUB_HEIGHT + 6),
            class,
            FONT_SCALE,
            INK,
        );
    }

    for (v, (name, _)) in series.iter().enumerate() {
        let y = TOP + v as u32 * 22;
        fill_rect(
            &mut image,
            i64::from(legend_left),
            i64::from(y),
            14,
            14,
            PALETTE[v % PALETTE.len()],
        );
        draw_text(
            &mut image,
            i64::from(legend_left + 20),
            i64::from(y),
            name,
            FONT_SCALE,
            INK,
        );
    }
    image
}

/// [`confusion_heatmap`] of a variant's confusion matrix over the cells in view (the headline
/// mask), titled with the variant's name.
pub fn variant_heatmap(variant: &VariantReport) -> RgbImage {
    confusion_heatmap(variant.variant.name(), &variant.confusion_visible)
}

/// [`per_class_iou_chart`] of every variant of `report` (cells in view), in the report's order.
pub fn report_iou_chart(report: &EvalReport) -> RgbImage {
    let series: Vec<(&str, [Option<f64>; 5])> = report
        .variants
        .iter()
        .map(|v| {
            let mut ious = [None; 5];
            for (out, class) in ious.iter_mut().zip(&v.scores_visible.classes) {
                *out = class.iou;
            }
            (v.variant.name(), ious)
        })
        .collect();
    per_class_iou_chart(&series)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel(image: &RgbImage, x: u32, y: u32) -> Rgb<u8> {
        *image.get_pixel(x, y)
    }

    #[test]
    fn heat_colour_mixes_white_and_dark_blue() {
        assert_eq!(heat_colour(0.0), Rgb([255, 255, 255]));
        assert_eq!(heat_colour(1.0), HEAT_FULL);
        // 255 + (8 − 255)·0.75 = 69.75 → 70; 255 + (48 − 255)·0.75 = 99.75 → 100;
        // 255 + (107 − 255)·0.75 = 144.
        assert_eq!(heat_colour(0.75), Rgb([70, 100, 144]));
        assert_eq!(heat_colour(f64::NAN), Rgb([255, 255, 255]));
        assert_eq!(heat_colour(7.0), HEAT_FULL);
    }

    #[test]
    fn heatmap_cells_are_shaded_by_row_fraction() {
        use heatmap_layout::*;
        let mut m = ConfusionMatrix::default();
        // Truth F: 3 predicted F, 1 predicted I → 75 % and 25 %.
        m.counts[0][0] = 3;
        m.counts[0][1] = 1;
        // Truth M: all 10 predicted unknown (column 6).
        m.counts[4][6] = 10;
        // Truth I, U, S: no cells → grey rows.
        let image = confusion_heatmap("kurdej2013", &m);
        assert_eq!(image.width(), LEFT + 7 * CELL_WIDTH + MARGIN);
        assert_eq!(image.height(), TOP + 5 * CELL_HEIGHT + MARGIN);
        // A point in a cell's corner, away from its centred number.
        let corner =
            |t: u32, p: u32| pixel(&image, LEFT + p * CELL_WIDTH + 2, TOP + t * CELL_HEIGHT + 2);
        assert_eq!(corner(0, 0), Rgb([70, 100, 144])); // 0.75, see heat_colour test
        // 255 + (8 − 255)·0.25 = 193.25 → 193; 255 − 207/4 = 203.25 → 203; 255 − 37 = 218.
        assert_eq!(corner(0, 1), Rgb([193, 203, 218]));
        assert_eq!(corner(0, 2), BACKGROUND);
        assert_eq!(corner(4, 6), HEAT_FULL);
        assert_eq!(corner(4, 0), BACKGROUND);
        for t in 1..4 {
            for p in 0..7 {
                assert_eq!(corner(t, p), EMPTY_ROW);
            }
        }
        // The 100 % cell prints "100" in white, centred: the '1' glyph's stem (column 2, rows
        // 0–6) sits at x = left + (44 − 34)/2 + 2·2, y = top + (30 − 14)/2.
        let left = LEFT + 6 * CELL_WIDTH + 5;
        let top = TOP + 4 * CELL_HEIGHT + 8;
        assert_eq!(pixel(&image, left + 4, top + 2), BACKGROUND);
        assert_eq!(pixel(&image, left + 4, top + 12), BACKGROUND);
        // The '1' has no pixel in its column 0 at row 0: the cell's shade shows through.
        assert_eq!(pixel(&image, left, top), HEAT_FULL);
        // Row label 'F' of truth F: its top bar spans the whole glyph width at row 0.
        let label_left = (LEFT - text_width("F", FONT_SCALE)) / 2;
        let label_top = TOP + (CELL_HEIGHT - GLYPH_HEIGHT * FONT_SCALE) / 2;
        for dx in 0..GLYPH_WIDTH * FONT_SCALE {
            assert_eq!(pixel(&image, label_left + dx, label_top), INK);
        }
        // Row 1 of 'F' has only its first column set.
        assert_eq!(pixel(&image, label_left, label_top + 2), INK);
        assert_eq!(pixel(&image, label_left + 2, label_top + 2), BACKGROUND);
    }

    #[test]
    fn chart_bars_have_iou_heights_and_variant_colours() {
        use chart_layout::*;
        let series = [
            (
                "kurdej2013",
                [Some(1.0), Some(0.5), None, Some(0.0), Some(0.25)],
            ),
            (
                "log-odds",
                [Some(0.5), Some(0.0), None, Some(0.0), Some(0.75)],
            ),
        ];
        let image = per_class_iou_chart(&series);
        let group_width = 2 * (BAR_WIDTH + BAR_GAP);
        let bar_x = |g: u32, v: u32| {
            LEFT + GROUP_GAP + g * (group_width + GROUP_GAP) + v * (BAR_WIDTH + BAR_GAP) + 1
        };
        let axis = TOP + PLOT_HEIGHT;
        // Class F, variant 0: IoU 1 fills the rows axis−200 … axis−1.
        assert_eq!(pixel(&image, bar_x(0, 0), axis - 1), PALETTE[0]);
        assert_eq!(pixel(&image, bar_x(0, 0), axis - PLOT_HEIGHT), PALETTE[0]);
        // Class F, variant 1: IoU 0.5 → 100 rows: row axis−100 coloured, axis−101 not.
        assert_eq!(pixel(&image, bar_x(0, 1), axis - 100), PALETTE[1]);
        assert_ne!(pixel(&image, bar_x(0, 1), axis - 101), PALETTE[1]);
        // Class M: 0.25 → 50 rows for variant 0, 0.75 → 150 rows for variant 1.
        assert_eq!(pixel(&image, bar_x(4, 0), axis - 50), PALETTE[0]);
        assert_ne!(pixel(&image, bar_x(4, 0), axis - 51), PALETTE[0]);
        assert_eq!(pixel(&image, bar_x(4, 1), axis - 150), PALETTE[1]);
        // Class U undefined for both: grey stub below the axis, nothing above it.
        assert_eq!(pixel(&image, bar_x(2, 0), axis + 3), GRID_GREY);
        assert_ne!(pixel(&image, bar_x(2, 0), axis - 1), PALETTE[0]);
        // IoU 0 draws nothing above the axis and no stub.
        assert_eq!(pixel(&image, bar_x(3, 1), axis - 1), BACKGROUND);
        assert_eq!(pixel(&image, bar_x(3, 1), axis + 3), BACKGROUND);
        // The axis itself is black.
        assert_eq!(pixel(&image, LEFT + 2, axis), INK);
        // Legend swatches in the variants' colours, right of the plot.
        let legend_left = LEFT + GROUP_GAP + 5 * (group_width + GROUP_GAP) + 12;
        assert_eq!(pixel(&image, legend_left + 7, TOP + 7), PALETTE[0]);
        assert_eq!(pixel(&image, legend_left + 7, TOP + 22 + 7), PALETTE[1]);
        assert!(image.width() > legend_left + 20 + text_width("log-odds", FONT_SCALE));
    }

    #[test]
    fn text_is_clipped_not_panicking_and_unknown_characters_draw_a_question_mark() {
        let mut image = RgbImage::from_pixel(8, 8, BACKGROUND);
        draw_text(&mut image, -3, -3, "É%", 3, INK);
        draw_text(&mut image, 100, 100, "x", 1, INK);
        let mut a = RgbImage::from_pixel(6, 8, BACKGROUND);
        let mut b = RgbImage::from_pixel(6, 8, BACKGROUND);
        draw_text(&mut a, 0, 0, "~", 1, INK);
        draw_text(&mut b, 0, 0, "?", 1, INK);
        assert_eq!(a, b);
        // Lower case is drawn as upper case.
        let mut c = RgbImage::from_pixel(6, 8, BACKGROUND);
        let mut d = RgbImage::from_pixel(6, 8, BACKGROUND);
        draw_text(&mut c, 0, 0, "m", 1, INK);
        draw_text(&mut d, 0, 0, "M", 1, INK);
        assert_eq!(c, d);
        assert_eq!(text_width("", 2), 0);
        assert_eq!(text_width("ab", 2), 22);
    }

    #[test]
    fn empty_series_still_draws_an_axis() {
        let image = per_class_iou_chart(&[]);
        assert!(image.width() > chart_layout::LEFT && image.height() > chart_layout::TOP);
    }
}
