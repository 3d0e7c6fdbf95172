//! Pictures of an evaluation: a confusion-matrix heat map per variant and a per-class IoU bar
//! chart, as plain [`RgbImage`]s (the caller encodes and writes them). Text is the embedded
//! DejaVu Sans of [`output::text`], anti-aliased.
//!
//! # Confusion heat map ([`confusion_heatmap`])
//! ```text
//!   Confusion: <variant>, cells in view (% of each truth row)
//!                          prediction
//!                     F    I    U    S    M    O  unknown
//!  t  F  free       [75%][25%][ 0%] ...                   ← one row per truth class
//!  r  I  mapped …   [   ][   ] ...
//! ```
//! Rows are truth F, I, U, S, M (axis title "truth", names spelled out); columns are predictions
//! F, I, U, S, M, O (occupied, static, not resolved: two-class baselines), unknown (axis title
//! "prediction"). A cell's shade goes from white (0 % of its row) to dark blue (100 % of its
//! row) and it shows the row percentage, rounded. A row without any truth cell is grey. Row
//! normalisation shows per-class recall on the diagonal whatever the class frequencies (free
//! cells outnumber moving ones by orders of magnitude).
//!
//! # Per-class IoU chart ([`per_class_iou_chart`])
//! Five groups F, I, U, S, M from left to right (named under the axis, axis title "class"); in
//! each group one bar per variant in the given order, coloured by the variant's index in
//! [`PALETTE`] (Okabe–Ito colours, distinguishable with colour-blindness), its value printed
//! above it. Bar height is the IoU on a 0–1 axis (y title "IoU") with grey grid lines and tick
//! labels every 0.25; an undefined IoU (class absent from truth and prediction) is a short grey
//! stub below the axis marked "n/a". A legend (colour swatch, variant name) is on the right.

use crate::metrics::{ConfusionMatrix, TRUTH_NAMES};
use crate::report::{EvalReport, VariantReport};
use output::raster::{Rgb, RgbImage};
use output::text::{draw_text, draw_text_centred, draw_text_vertical, line_height, text_width};

/// Colours of the variants' bars, in order (Okabe & Ito 2008, colour-blind safe).
pub const PALETTE: [Rgb; 8] = [
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
pub const BACKGROUND: Rgb = Rgb([255, 255, 255]);
/// Colour of labels on a light background.
pub const INK: Rgb = Rgb([0, 0, 0]);
/// Heat-map colour of a fraction of 1 (a fraction f mixes white and this linearly).
pub const HEAT_FULL: Rgb = Rgb([8, 48, 107]);
/// Heat-map colour of a row with no truth cell.
pub const EMPTY_ROW: Rgb = Rgb([200, 200, 200]);
/// Colour of grid lines and of undefined-IoU stubs.
pub const GRID_GREY: Rgb = Rgb([190, 190, 190]);

/// Font sizes, pixels: titles, axis titles, labels, small print.
const TITLE_PX: f32 = 20.0;
const AXIS_PX: f32 = 17.0;
const LABEL_PX: f32 = 15.0;
const SMALL_PX: f32 = 12.0;

/// The names of the truth classes F, I, U, S, M for people.
pub const CLASS_NAMES: [&str; 5] = [
    "free",
    "mapped infrastructure",
    "unmapped infrastructure",
    "stopped",
    "moving",
];

/// Fills a rectangle, clipped to the image.
fn fill_rect(image: &mut RgbImage, x: i64, y: i64, width: u32, height: u32, colour: Rgb) {
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
pub fn heat_colour(fraction: f64) -> Rgb {
    let f = if fraction.is_nan() {
        0.0
    } else {
        fraction.clamp(0.0, 1.0)
    };
    let mix = |full: u8| (255.0 + (f64::from(full) - 255.0) * f).round() as u8;
    Rgb([
        mix(HEAT_FULL.0[0]),
        mix(HEAT_FULL.0[1]),
        mix(HEAT_FULL.0[2]),
    ])
}

/// Labels of the heat map's columns: predictions F, I, U, S, M, O and unknown.
const PREDICTED_LABELS: [&str; 7] = ["F", "I", "U", "S", "M", "O", "unknown"];

/// Geometry of the confusion heat map, pixels.
pub mod heatmap_layout {
    /// Width of a matrix cell.
    pub const CELL_WIDTH: u32 = 64;
    /// Height of a matrix cell.
    pub const CELL_HEIGHT: u32 = 36;
    /// Left edge of the matrix (room for the axis title and the row labels).
    pub const LEFT: u32 = 250;
    /// Top edge of the matrix (room for the title, the axis title and the column labels).
    pub const TOP: u32 = 100;
    /// Outer margin on the right; room for the key at the bottom.
    pub const MARGIN: u32 = 12;
    /// Room below the matrix for the key of the column letters.
    pub const BOTTOM: u32 = 36;
}

/// The confusion heat map of `matrix` with `title` above it (layout in the module docs and
/// [`heatmap_layout`]): matrix cell (truth t, prediction p) covers
/// `x ∈ [LEFT + p·CELL_WIDTH, LEFT + (p+1)·CELL_WIDTH)`, `y ∈ [TOP + t·CELL_HEIGHT, …)`.
pub fn confusion_heatmap(title: &str, matrix: &ConfusionMatrix) -> RgbImage {
    use heatmap_layout::*;
    let columns = PREDICTED_LABELS.len() as u32;
    let rows = TRUTH_NAMES.len() as u32;
    let title = format!("Confusion: {title}, cells in view (% of each truth row)");
    let key = "O: occupied, class not resolved (two-class baselines)";
    let width = (LEFT + columns * CELL_WIDTH + MARGIN)
        .max(text_width(&title, TITLE_PX) + 2 * MARGIN)
        .max(text_width(key, SMALL_PX) + LEFT);
    let height = TOP + rows * CELL_HEIGHT + BOTTOM;
    let mut image = RgbImage::from_pixel(width, height, BACKGROUND);
    let label_h = i64::from(line_height(LABEL_PX));
    draw_text(&mut image, i64::from(MARGIN), 8, &title, TITLE_PX, INK);
    let matrix_centre_x = i64::from(LEFT + columns * CELL_WIDTH / 2);
    draw_text_centred(&mut image, matrix_centre_x, 40, "prediction", AXIS_PX, INK);
    for (p, label) in PREDICTED_LABELS.iter().enumerate() {
        let centre = LEFT + p as u32 * CELL_WIDTH + CELL_WIDTH / 2;
        let y = i64::from(TOP) - label_h - 6;
        draw_text_centred(&mut image, i64::from(centre), y, label, LABEL_PX, INK);
    }
    let matrix_centre_y = i64::from(TOP + rows * CELL_HEIGHT / 2);
    draw_text_vertical(
        &mut image,
        i64::from(MARGIN),
        matrix_centre_y,
        "truth",
        AXIS_PX,
        INK,
    );
    for (t, row) in matrix.counts.iter().enumerate() {
        let top = TOP + t as u32 * CELL_HEIGHT;
        let label = format!("{}  {}", TRUTH_NAMES[t], CLASS_NAMES[t]);
        let text_top = i64::from(top + CELL_HEIGHT / 2) - label_h / 2;
        draw_text(&mut image, 40, text_top, &label, LABEL_PX, INK);
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
            let text = format!("{}%", (fraction * 100.0).round() as u32);
            let centre = i64::from(left + CELL_WIDTH / 2);
            draw_text_centred(&mut image, centre, text_top, &text, LABEL_PX, ink);
        }
    }
    let key_y = i64::from(TOP + rows * CELL_HEIGHT + 10);
    draw_text(&mut image, i64::from(LEFT), key_y, key, SMALL_PX, INK);
    image
}

/// Geometry of the per-class IoU chart, pixels.
pub mod chart_layout {
    /// Width of one bar.
    pub const BAR_WIDTH: u32 = 30;
    /// Gap between two bars of a group.
    pub const BAR_GAP: u32 = 4;
    /// Gap between two groups (and before the first one).
    pub const GROUP_GAP: u32 = 36;
    /// Height of the 0–1 axis.
    pub const PLOT_HEIGHT: u32 = 300;
    /// Left edge of the plot area (room for the axis title and the tick labels).
    pub const LEFT: u32 = 80;
    /// Top edge of the plot area (the IoU = 1 line; room for the title and values above it).
    pub const TOP: u32 = 64;
    /// Room below the axis for the class labels and the axis title.
    pub const BOTTOM: u32 = 100;
    /// Height of a stub marking an undefined IoU, below the axis.
    pub const STUB_HEIGHT: u32 = 3;
    /// Vertical distance between two legend entries.
    pub const LEGEND_STEP: u32 = 26;
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
    let legend_left = plot_right + 16;
    let legend_text_width = series
        .iter()
        .map(|(name, _)| text_width(name, LABEL_PX))
        .max()
        .unwrap_or(0);
    let title = "Per-class IoU, cells in view";
    let width = (legend_left + 24 + legend_text_width + 16).max(text_width(title, TITLE_PX) + 32);
    let axis_y = TOP + PLOT_HEIGHT;
    let legend_height = 10 + series.len() as u32 * LEGEND_STEP;
    let height = (axis_y + BOTTOM).max(TOP + legend_height);
    let mut image = RgbImage::from_pixel(width, height, BACKGROUND);
    draw_text(&mut image, 16, 10, title, TITLE_PX, INK);
    draw_iou_axis(&mut image, plot_right);
    for (g, class) in TRUTH_NAMES.iter().enumerate() {
        let group_left = LEFT + GROUP_GAP + g as u32 * (group_width + GROUP_GAP);
        for (v, (_, ious)) in series.iter().enumerate() {
            let x = group_left + v as u32 * (BAR_WIDTH + BAR_GAP);
            draw_iou_bar(&mut image, x, ious[g], PALETTE[v % PALETTE.len()]);
        }
        draw_class_name(
            &mut image,
            group_left + group_width / 2,
            class,
            CLASS_NAMES[g],
        );
    }
    let axis_title_y = i64::from(axis_y + BOTTOM) - i64::from(line_height(AXIS_PX)) - 6;
    let plot_centre = i64::from((LEFT + plot_right) / 2);
    draw_text_centred(&mut image, plot_centre, axis_title_y, "class", AXIS_PX, INK);
    draw_chart_legend(&mut image, series, legend_left);
    image
}

/// The IoU axis of the chart, its plot area ending at `plot_right`: grid lines and tick labels
/// every 0.25, the axis line and its title.
fn draw_iou_axis(image: &mut RgbImage, plot_right: u32) {
    use chart_layout::*;
    let axis_y = TOP + PLOT_HEIGHT;
    let small_h = i64::from(line_height(SMALL_PX));
    for k in 0..=4u32 {
        let y = axis_y - k * PLOT_HEIGHT / 4;
        let colour = if k == 0 { INK } else { GRID_GREY };
        fill_rect(
            image,
            i64::from(LEFT),
            i64::from(y),
            plot_right - LEFT,
            1,
            colour,
        );
        let label = ["0", "0.25", "0.5", "0.75", "1"][k as usize];
        let x = i64::from(LEFT) - 8 - i64::from(text_width(label, SMALL_PX));
        draw_text(image, x, i64::from(y) - small_h / 2, label, SMALL_PX, INK);
    }
    fill_rect(
        image,
        i64::from(LEFT),
        i64::from(TOP),
        1,
        PLOT_HEIGHT + 1,
        INK,
    );
    let centre_y = i64::from(TOP + PLOT_HEIGHT / 2);
    draw_text_vertical(image, 14, centre_y, "IoU", AXIS_PX, INK);
}

/// One bar with its left edge at `x`: the IoU's height in `colour` with its value above, or
/// for an undefined IoU a grey stub below the axis marked "n/a".
fn draw_iou_bar(image: &mut RgbImage, x: u32, iou: Option<f64>, colour: Rgb) {
    use chart_layout::*;
    let axis_y = TOP + PLOT_HEIGHT;
    let small_h = i64::from(line_height(SMALL_PX));
    let centre = i64::from(x + BAR_WIDTH / 2);
    match iou {
        Some(iou) if iou.is_finite() => {
            let bar = (iou.clamp(0.0, 1.0) * f64::from(PLOT_HEIGHT)).round() as u32;
            fill_rect(
                image,
                i64::from(x),
                i64::from(axis_y - bar),
                BAR_WIDTH,
                bar,
                colour,
            );
            let value = format!("{iou:.2}");
            let y = i64::from(axis_y - bar) - small_h - 2;
            draw_text_centred(image, centre, y, &value, SMALL_PX, INK);
        }
        _ => {
            fill_rect(
                image,
                i64::from(x),
                i64::from(axis_y + 2),
                BAR_WIDTH,
                STUB_HEIGHT,
                GRID_GREY,
            );
            let y = i64::from(axis_y) - small_h - 2;
            draw_text_centred(image, centre, y, "n/a", SMALL_PX, INK);
        }
    }
}

/// A group's class under the axis, centred on `centre`: its letter, then its `name` one word a
/// line, so that long names do not run into the next group's.
fn draw_class_name(image: &mut RgbImage, centre: u32, letter: &str, name: &str) {
    use chart_layout::*;
    let axis_y = TOP + PLOT_HEIGHT;
    let small_h = i64::from(line_height(SMALL_PX));
    let centre = i64::from(centre);
    let y = i64::from(axis_y + 2 + STUB_HEIGHT + 6);
    draw_text_centred(image, centre, y, letter, LABEL_PX, INK);
    let mut name_y = y + i64::from(line_height(LABEL_PX));
    for word in name.split(' ') {
        draw_text_centred(image, centre, name_y, word, SMALL_PX, INK);
        name_y += small_h;
    }
}

/// The legend at `legend_left`: a swatch of each variant's colour and its name.
fn draw_chart_legend(image: &mut RgbImage, series: &[(&str, [Option<f64>; 5])], legend_left: u32) {
    use chart_layout::*;
    for (v, (name, _)) in series.iter().enumerate() {
        let y = TOP + v as u32 * LEGEND_STEP;
        fill_rect(
            image,
            i64::from(legend_left),
            i64::from(y),
            16,
            16,
            PALETTE[v % PALETTE.len()],
        );
        draw_text(
            image,
            i64::from(legend_left + 24),
            i64::from(y),
            name,
            LABEL_PX,
            INK,
        );
    }
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

    fn pixel(image: &RgbImage, x: u32, y: u32) -> Rgb {
        image.get_pixel(x, y)
    }

    /// Pixels in the rectangle that are neither of the two given colours (text's ink and its
    /// anti-aliased edge).
    fn inked(image: &RgbImage, x: u32, y: u32, w: u32, h: u32, not: [Rgb; 2]) -> usize {
        (y..y + h)
            .flat_map(|py| (x..x + w).map(move |px| (px, py)))
            .filter(|&(px, py)| !not.contains(&pixel(image, px, py)))
            .count()
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
    fn heatmap_cells_are_shaded_by_row_fraction_and_labelled() {
        use heatmap_layout::*;
        let mut m = ConfusionMatrix::default();
        // Truth F: 3 predicted F, 1 predicted I → 75 % and 25 %.
        m.counts[0][0] = 3;
        m.counts[0][1] = 1;
        // Truth M: all 10 predicted unknown (column 6).
        m.counts[4][6] = 10;
        // Truth I, U, S: no cells → grey rows.
        let image = confusion_heatmap("kurdej2013", &m);
        assert!(image.width() >= LEFT + 7 * CELL_WIDTH + MARGIN);
        assert_eq!(image.height(), TOP + 5 * CELL_HEIGHT + BOTTOM);
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
        // The 100 % cell prints its number in white: white and blends of white over the cell's
        // shade, in its middle, none in an empty cell of the same row.
        let (cx, cy) = (LEFT + 6 * CELL_WIDTH + 8, TOP + 4 * CELL_HEIGHT + 6);
        let text = inked(
            &image,
            cx,
            cy,
            CELL_WIDTH - 16,
            CELL_HEIGHT - 12,
            [HEAT_FULL, HEAT_FULL],
        );
        assert!(text > 30, "{text}");
        assert_eq!(pixel(&image, cx + 20, cy + 2), HEAT_FULL);
        // Row labels, axis titles and the title carry ink; the matrix's left margin does.
        let names = inked(&image, 40, TOP, LEFT - 50, 5 * CELL_HEIGHT, [BACKGROUND; 2]);
        assert!(names > 500, "{names}");
        let truth_title = inked(&image, MARGIN, TOP, 24, 5 * CELL_HEIGHT, [BACKGROUND; 2]);
        assert!(truth_title > 40, "{truth_title}");
        let prediction = inked(&image, LEFT, 36, 7 * CELL_WIDTH, 24, [BACKGROUND; 2]);
        assert!(prediction > 40, "{prediction}");
    }

    #[test]
    fn chart_bars_have_iou_heights_variant_colours_and_values() {
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
        // Class F, variant 0: IoU 1 fills the rows axis−300 … axis−1.
        assert_eq!(pixel(&image, bar_x(0, 0), axis - 1), PALETTE[0]);
        assert_eq!(pixel(&image, bar_x(0, 0), axis - PLOT_HEIGHT), PALETTE[0]);
        // Class F, variant 1: IoU 0.5 → 150 rows: row axis−150 coloured, axis−151 not.
        assert_eq!(pixel(&image, bar_x(0, 1), axis - 150), PALETTE[1]);
        assert_ne!(pixel(&image, bar_x(0, 1), axis - 151), PALETTE[1]);
        // Class M: 0.25 → 75 rows for variant 0, 0.75 → 225 rows for variant 1.
        assert_eq!(pixel(&image, bar_x(4, 0), axis - 75), PALETTE[0]);
        assert_ne!(pixel(&image, bar_x(4, 0), axis - 76), PALETTE[0]);
        assert_eq!(pixel(&image, bar_x(4, 1), axis - 225), PALETTE[1]);
        // The value is printed just above a bar: ink in the 16 rows above variant 1's M bar.
        let above = inked(
            &image,
            bar_x(4, 1) - 1,
            axis - 225 - 18,
            BAR_WIDTH,
            16,
            [BACKGROUND, GRID_GREY],
        );
        assert!(above > 20, "{above}");
        // Class U undefined for both: grey stub below the axis, nothing above it.
        assert_eq!(pixel(&image, bar_x(2, 0), axis + 3), GRID_GREY);
        assert_ne!(pixel(&image, bar_x(2, 0), axis - 1), PALETTE[0]);
        // IoU 0 draws nothing above the axis and no stub.
        assert_eq!(pixel(&image, bar_x(3, 1), axis - 1), BACKGROUND);
        assert_eq!(pixel(&image, bar_x(3, 1), axis + 3), BACKGROUND);
        // The axis itself is black.
        assert_eq!(pixel(&image, LEFT + 2, axis), INK);
        // The y title "IoU" left of the tick labels.
        let y_title = inked(&image, 10, TOP, 26, PLOT_HEIGHT, [BACKGROUND; 2]);
        assert!(y_title > 40, "{y_title}");
        // Legend swatches in the variants' colours, right of the plot.
        let legend_left = LEFT + GROUP_GAP + 5 * (group_width + GROUP_GAP) + 16;
        assert_eq!(pixel(&image, legend_left + 8, TOP + 8), PALETTE[0]);
        assert_eq!(
            pixel(&image, legend_left + 8, TOP + LEGEND_STEP + 8),
            PALETTE[1]
        );
        assert!(image.width() > legend_left + 24 + text_width("log-odds", LABEL_PX));
    }

    #[test]
    fn empty_series_still_draws_an_axis() {
        let image = per_class_iou_chart(&[]);
        assert!(image.width() > chart_layout::LEFT && image.height() > chart_layout::TOP);
    }
}
