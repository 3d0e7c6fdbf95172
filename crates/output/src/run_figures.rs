//! The figures a drive's run writes for people (`evigrid run`, `evigrid demo`, the session's
//! final outputs): the views of the paper's Fig. 2 enlarged, with the map's outlines, the ego's
//! path, a legend, a scale bar and a north arrow ([`crate::figure`]), in the colour-blind-safe
//! Okabe–Ito class colours.

use crate::raster::RgbImage;
use evigrid::{GisGrid, Label, MovingTrace, PerceptionGrid, Window};

use crate::{
    ClassColours, Legend, OutputError, Overlay, decision_image, figure, pignistic_image,
    readable_scale, trace_image,
};

/// Attribution the map's licence requires wherever the map is shown.
pub const OSM_ATTRIBUTION: &str = "Map data © OpenStreetMap contributors, ODbL";

/// The class colours of every figure.
pub const COLOURS: ClassColours = crate::views::COLOURS;

/// How to read each view, under its legend: the decision view.
pub const DECISION_NOTE: &str = "colour: the class decided (SPEC §6)";
/// Under the pignistic view's legend.
pub const PIGNISTIC_NOTE: &str = "colour: class colours mixed by betP";
/// Under the trace view's legend.
pub const TRACE_NOTE: &str = "every cell ever decided moving: M";

/// A window's final state, as the views need it.
pub struct Views<'a> {
    /// The window.
    pub window: &'a Window,
    /// Masses.
    pub perception: &'a PerceptionGrid,
    /// Decisions, storage order.
    pub decisions: &'a [Label],
    /// Every cell ever decided moving.
    pub trace: &'a MovingTrace,
    /// The motion stage of the `evigrid` method, whose cell velocities are drawn as arrows.
    pub motion: Option<&'a evigrid::motion::MotionStage>,
}

/// Cells slower than this draw no arrow, m/s.
pub const MIN_ARROW_SPEED_MPS: f32 = 0.5;
/// One arrow per block of this many cells a side, so that a car shows one or two arrows.
pub const ARROW_BLOCK_CELLS: usize = 6;

/// The velocity arrows of a motion stage: one per block of [`ARROW_BLOCK_CELLS`]² cells, at the
/// first moving cell of the block (world order), `(position, velocity)` in metres and m/s.
pub fn velocity_arrows(
    window: &Window,
    motion: Option<&evigrid::motion::MotionStage>,
) -> Vec<([f64; 2], [f64; 2])> {
    let Some(motion) = motion else {
        return Vec::new();
    };
    let (east, north) = (motion.velocity_east(), motion.velocity_north());
    let (width, s) = (window.width(), window.cell_size_m());
    let mut taken = std::collections::HashSet::new();
    let mut arrows = Vec::new();
    for (k, storage) in window.world_order_spans().flatten().enumerate() {
        let (Some(&vx), Some(&vy)) = (east.get(storage), north.get(storage)) else {
            continue;
        };
        if vx.hypot(vy) < MIN_ARROW_SPEED_MPS {
            continue;
        }
        let (row, col) = (k / width, k % width);
        if !taken.insert((row / ARROW_BLOCK_CELLS, col / ARROW_BLOCK_CELLS)) {
            continue;
        }
        let x = (window.first_col() as f64 + col as f64 + 0.5) * s;
        let y = (window.first_row() as f64 + row as f64 + 0.5) * s;
        arrows.push(([x, y], [f64::from(vx), f64::from(vy)]));
    }
    arrows
}

/// The three final figures, named `decision.png`, `pignistic.png`, `trace.png`, each enlarged to
/// [`readable_scale`] with `gis`'s outlines (when there is a map) and `path`.
pub fn final_figures(
    views: &Views<'_>,
    gis: Option<&GisGrid>,
    path: &[[f64; 2]],
) -> Result<Vec<(&'static str, RgbImage)>, OutputError> {
    let window = views.window;
    let arrows = velocity_arrows(window, views.motion);
    let overlay = Overlay {
        gis,
        path,
        velocities: &arrows,
    };
    let scale = readable_scale(window);
    let one = |title: &str, cells: RgbImage, legend: Legend| {
        figure(window, &[(title, &cells)], &overlay, &legend, scale)
    };
    let classes = |note: &str| Legend::classes(&COLOURS, false, note);
    Ok(vec![
        (
            "decision.png",
            one(
                "decision",
                decision_image(window, views.decisions, &COLOURS)?,
                classes(DECISION_NOTE),
            )?,
        ),
        (
            "pignistic.png",
            one(
                "pignistic probability betP",
                pignistic_image(window, views.perception, &COLOURS)?,
                Legend::pignistic(&COLOURS, PIGNISTIC_NOTE),
            )?,
        ),
        (
            "trace.png",
            one(
                "trace of moving objects",
                trace_image(window, views.decisions, views.trace, &COLOURS)?,
                classes(TRACE_NOTE),
            )?,
        ),
    ])
}
