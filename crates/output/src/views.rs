//! Pictures of the PerceptionGrid (SPEC §6, paper Fig. 2).
//!
//! Images are north-up: image row 0 is the window's northmost row, column 0 its westmost column,
//! one pixel per cell. Three pictures follow the paper's Fig. 2:
//! - the decision map ([`decision_image`]): one colour per class, in [`COLOURS`] (the
//!   Okabe–Ito palette) wherever evigrid draws or exports classes;
//! - the pignistic view ([`pignistic_image`]): the mean of the class colours weighted by betP
//!   (eq 15), black where the cell was never observed;
//! - the trace of moving objects ([`trace_image`]): the decision map with every cell ever decided
//!   moving during the drive painted red, from a [`MovingTrace`] kept world-fixed in the window.

use crate::raster::RgbImage;
use evigrid::{Label, MovingTrace, PerceptionGrid, Window, betp};

use crate::error::{OutputError, check_len};

/// The class colours of every picture, export and recording evigrid writes: figures, per-frame
/// pictures, the GeoTIFF and georeferenced PNG ([`crate::georef::GIS_COLOURS`]), the Foxglove
/// grid's colour fields and the demo page. One palette, so that a class reads the same
/// wherever a person meets it (checked by `palette`'s tests).
pub const COLOURS: ClassColours = ClassColours::OKABE_ITO;

/// The colour of each label: unknown, the classes F, I, U, S, M, and the unresolved occupied O
/// of the two-class baselines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClassColours {
    /// Unknown (never observed, or too ignorant).
    pub unknown: [u8; 3],
    /// Classes F, I, U, S, M in frame order.
    pub classes: [[u8; 3]; 5],
    /// Occupied, class not resolved ([`Label::O`]; the method never decides it).
    pub occupied: [u8; 3],
}

impl ClassColours {
    /// The paper's Fig. 2 code: free green, moving red, every static class the same blue,
    /// unknown black.
    pub const THREE_CLASSES: Self = Self {
        unknown: [0, 0, 0],
        classes: [
            [0, 190, 0],
            [40, 80, 255],
            [40, 80, 255],
            [40, 80, 255],
            [230, 0, 0],
        ],
        occupied: [40, 80, 255],
    };

    /// As [`THREE_CLASSES`](Self::THREE_CLASSES) with the static classes told apart by shade:
    /// mapped infrastructure I dark blue, unmapped infrastructure U mid blue, stopped S light
    /// blue; an unresolved occupied cell grey.
    pub const FIVE_CLASSES: Self = Self {
        unknown: [0, 0, 0],
        classes: [
            [0, 190, 0],
            [20, 30, 150],
            [40, 100, 255],
            [140, 200, 255],
            [230, 0, 0],
        ],
        occupied: [150, 150, 150],
    };

    /// The readable palette, colour-blind safe (Okabe & Ito 2008, "Color Universal Design"):
    /// free bluish green, mapped infrastructure I blue, unmapped infrastructure U sky blue,
    /// stopped S yellow, moving M vermillion, unknown black, unresolved occupied grey (reddish
    /// purple is left to the ego's path in figures).
    /// I, U and S differ in lightness as well as hue, so they stay apart with deuteranopia and
    /// protanopia (checked in `palette`'s tests by simulating them: every pair of unknown, F, I,
    /// U, S, M at least 20 ΔE apart).
    pub const OKABE_ITO: Self = Self {
        unknown: [0, 0, 0],
        classes: [
            [0, 158, 115],
            [0, 114, 178],
            [86, 180, 233],
            [240, 228, 66],
            [213, 94, 0],
        ],
        occupied: [150, 150, 150],
    };

    /// The colour of a label.
    pub fn of(&self, label: Label) -> [u8; 3] {
        match label {
            Label::Unknown => self.unknown,
            Label::F => self.classes[0],
            Label::I => self.classes[1],
            Label::U => self.classes[2],
            Label::S => self.classes[3],
            Label::M => self.classes[4],
            // Edge, truth only, is drawn as an unresolved occupied cell.
            Label::O | Label::Edge => self.occupied,
        }
    }
}

/// Paints one pixel per cell, north-up, with `colour(storage_index)`.
fn paint(window: &Window, colour: impl FnMut(usize) -> [u8; 3]) -> RgbImage {
    let (w, h) = (window.width() as u32, window.height() as u32);
    let mut image = RgbImage::new(w, h);
    paint_into(window, &mut image, colour);
    image
}

/// Paints one pixel per cell, north-up, with `colour(storage_index)` into the top
/// `window.height()` rows of `image`, which is `window.width()` pixels wide and at least that
/// tall (the frame picture draws its legend strip below).
///
/// Row by row into the image's bytes: the per-frame picture paints 102,400 cells a frame on
/// KITTI, and a pixel's division into column and row plus a checked `put_pixel` were most of
/// its cost (`docs/benchmarks.md`).
pub(crate) fn paint_into(
    window: &Window,
    image: &mut RgbImage,
    mut colour: impl FnMut(usize) -> [u8; 3],
) {
    let (w, h) = (window.width(), window.height());
    debug_assert!(image.width() as usize == w && image.height() as usize >= h);
    let row_bytes = 3 * w;
    let bytes = image.as_raw_mut();
    // World-order spans run south to north, west to east, each within one row (a row is one
    // span, or two where the storage wraps); image rows run north to south.
    let mut pixel = 0usize;
    for span in window.world_order_spans() {
        let (x, row_from_south) = (pixel % w, pixel / w);
        let start = (h - 1 - row_from_south) * row_bytes + 3 * x;
        let len = span.len();
        for (idx, rgb) in span.zip(bytes[start..start + 3 * len].chunks_exact_mut(3)) {
            rgb.copy_from_slice(&colour(idx));
        }
        pixel += len;
    }
}

/// Each label's colour by label code, for painting a decision map cell by cell.
pub(crate) fn colour_table(colours: &ClassColours) -> [[u8; 3]; Label::ALL.len()] {
    let mut table = [[0u8; 3]; Label::ALL.len()];
    for label in Label::ALL {
        table[label as usize] = colours.of(label);
    }
    table
}

/// The decision map: one colour per decided class (`decisions` in storage order, as
/// [`evigrid::decide_grid`] fills it).
///
/// # Errors
///
/// [`OutputError::Size`] if `decisions` does not have one entry per window cell.
pub fn decision_image(
    window: &Window,
    decisions: &[Label],
    colours: &ClassColours,
) -> Result<RgbImage, OutputError> {
    check_len("decisions", decisions.len(), window)?;
    let table = colour_table(colours);
    Ok(paint(window, |idx| table[decisions[idx] as usize]))
}

/// The pignistic view: per cell the mean of the five class colours weighted by betP (eq 15),
/// black for cells never observed.
///
/// # Errors
///
/// [`OutputError::Size`] if the grid does not have the window's size.
pub fn pignistic_image(
    window: &Window,
    grid: &PerceptionGrid,
    colours: &ClassColours,
) -> Result<RgbImage, OutputError> {
    check_len("perception grid", grid.len(), window)?;
    let seen = grid.seen();
    Ok(paint(window, |idx| {
        if seen[idx] == 0 {
            return colours.unknown;
        }
        let p = betp(&grid.cell_masses(idx));
        let mut rgb = [0.0f32; 3];
        for (pk, colour) in p.iter().zip(&colours.classes) {
            for c in 0..3 {
                rgb[c] += pk * f32::from(colour[c]);
            }
        }
        rgb.map(|v| v.round().clamp(0.0, 255.0) as u8)
    }))
}

/// The trace picture: the decision map with every cell of the trace painted in the moving
/// colour.
///
/// # Errors
///
/// [`OutputError::Size`] if `decisions` or the trace do not have the window's size.
pub fn trace_image(
    window: &Window,
    decisions: &[Label],
    trace: &MovingTrace,
    colours: &ClassColours,
) -> Result<RgbImage, OutputError> {
    check_len("decisions", decisions.len(), window)?;
    check_len("moving trace", trace.as_slice().len(), window)?;
    Ok(paint(window, |idx| {
        if trace.as_slice()[idx] {
            colours.classes[4]
        } else {
            colours.of(decisions[idx])
        }
    }))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::atomic::write_png;
    use crate::testing::{decisions, window};

    #[test]
    fn images_are_north_up_and_west_left() {
        let w = window();
        // South-west cell (10, -1) moving, north-east cell (12, 0) free, the rest unknown.
        let d = decisions(&w, |col, row| match (col, row) {
            (10, -1) => Label::M,
            (12, 0) => Label::F,
            (11, 0) => Label::U,
            _ => Label::Unknown,
        });
        let image = decision_image(&w, &d, &ClassColours::FIVE_CLASSES).unwrap();
        assert_eq!(image.dimensions(), (3, 2));
        assert_eq!(image.get_pixel(0, 1).0, [230, 0, 0]);
        assert_eq!(image.get_pixel(2, 0).0, [0, 190, 0]);
        assert_eq!(image.get_pixel(1, 0).0, [40, 100, 255]);
        assert_eq!(image.get_pixel(1, 1).0, [0, 0, 0]);
        let three = decision_image(&w, &d, &ClassColours::THREE_CLASSES).unwrap();
        assert_eq!(three.get_pixel(1, 0).0, [40, 80, 255]);
        // A baseline's unresolved occupied cell: static blue in the paper's code, grey in five.
        assert_eq!(ClassColours::THREE_CLASSES.of(Label::O), [40, 80, 255]);
        assert_eq!(ClassColours::FIVE_CLASSES.of(Label::O), [150, 150, 150]);
        assert!(decision_image(&w, &d[1..], &ClassColours::THREE_CLASSES).is_err());
    }

    #[test]
    fn pignistic_colour_is_the_betp_weighted_mean() {
        let w = Window::new(1, 1, 1.0).unwrap();
        let mut pg = PerceptionGrid::new(1, 1);
        let colours = ClassColours::FIVE_CLASSES;
        // Never observed: black.
        assert_eq!(
            pignistic_image(&w, &pg, &colours)
                .unwrap()
                .get_pixel(0, 0)
                .0,
            [0, 0, 0]
        );
        // One step with the sensor seeing the cell free, no map: m(F) = 0.7, m(Ω) = 0.3, so
        // betP = F 0.76, and 0.06 for each of I, U, S, M.
        let mut sg = evigrid::SensorGrid::new(1, 1);
        sg.m_free_mut()[0] = 0.7;
        let gg = evigrid::GisGrid::new(1, 1);
        evigrid::step(&mut pg, &sg, &gg, &evigrid::Params::default(), 0.1);
        // R = 0.06·(20 + 40 + 140 + 230) = 25.8; G = 0.76·190 + 0.06·(30 + 100 + 200) = 164.2;
        // B = 0.06·(150 + 255 + 255) = 39.6.
        let pixel = pignistic_image(&w, &pg, &colours)
            .unwrap()
            .get_pixel(0, 0)
            .0;
        assert_eq!(pixel, [26, 164, 40]);
    }

    #[test]
    fn trace_keeps_moving_cells_and_forgets_cells_that_leave() {
        let mut w = window();
        let mut trace = MovingTrace::new(w.len());
        let d = decisions(&w, |col, _| if col == 10 { Label::M } else { Label::F });
        trace.record(&d);
        let later = decisions(&w, |_, _| Label::F);
        trace.record(&later);
        assert_eq!(trace.count(), 2);
        let image = trace_image(&w, &later, &trace, &ClassColours::THREE_CLASSES).unwrap();
        assert_eq!(image.get_pixel(0, 0).0, [230, 0, 0]);
        assert_eq!(image.get_pixel(1, 0).0, [0, 190, 0]);
        // Column 10 leaves the window when it moves one cell east; its trace goes with it.
        let entered = w.move_to(11, -1);
        trace.reset_entered(&w, &entered);
        assert_eq!(trace.count(), 0);
    }

    #[test]
    fn png_is_written_atomically() {
        let w = window();
        let d = vec![Label::F; w.len()];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        write_png(
            &decision_image(&w, &d, &ClassColours::THREE_CLASSES).unwrap(),
            &path,
        )
        .unwrap();
        let back = crate::testing::read_rgb(&path);
        assert_eq!(back.get_pixel(2, 1).0, [0, 190, 0]);
        let bad = dir.path().join("missing-dir/d.png");
        assert!(matches!(
            write_png(
                &decision_image(&w, &d, &ClassColours::THREE_CLASSES).unwrap(),
                &bad
            ),
            Err(OutputError::Io { .. })
        ));
    }
}
