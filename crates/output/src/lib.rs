//! output: pictures, exports and files of the evigrid method, kept apart from the method.
//!
//! The `evigrid` crate computes grids and decisions and writes no file; this crate turns them
//! into what a person or another tool reads, so that embedding the method pulls in no image
//! encoder. The key design decision: every file goes through one function, [`write_atomic`]
//! (a temporary file beside the target, then a rename; the temporary removed on any error), so a
//! reader never sees half a file, whichever command wrote it.
//!
//! - Pictures after the paper's Fig. 2, north-up, one pixel per cell: the decision map
//!   ([`decision_image`]), the pignistic view ([`pignistic_image`], betP of eq 15 weighted
//!   colours) and the trace of moving objects ([`trace_image`]); colours in [`ClassColours`]
//!   ([`ClassColours::OKABE_ITO`] the colour-blind-safe one, checked with [`palette`]).
//! - Figures for people ([`figure`]): those pictures enlarged ([`readable_scale`]), side by side,
//!   with map outlines and the ego's path ([`Overlay`]), a [`Legend`], a scale bar and a north
//!   arrow; text in an embedded DejaVu Sans ([`text`]).
//! - Exports: [`OccupancyGridExport`] after ROS `nav_msgs/OccupancyGrid` (0 free, 100 occupied,
//!   −1 unknown, plus each cell's [`Label`](evigrid::Label) code), and [`write_masses`],
//!   every focal set's mass as one `f32` field per cell after `foxglove.Grid`.
//!
//! ```
//! use evigrid::{Label, Window};
//! use output::{ClassColours, OccupancyGridExport, decision_image};
//!
//! let window = Window::new(2, 1, 0.5)?;
//! let decisions = [Label::F, Label::M];
//! let image = decision_image(&window, &decisions, &ClassColours::THREE_CLASSES)?;
//! assert_eq!(image.get_pixel(1, 0).0, [230, 0, 0]); // moving: red
//! let export = OccupancyGridExport::new(&window, &decisions, "map")?;
//! assert_eq!(export.data, [0, 100]);
//! assert_eq!(export.classes, [1, 5]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

mod atomic;
mod error;
mod export;
mod figure;
pub mod palette;
#[cfg(test)]
mod testing;
pub mod text;
mod views;

pub use atomic::{write_atomic, write_png, write_png_fast};
pub use error::{MAX_FIGURE_PIXELS, OutputError};
pub use export::{
    GridField, GridInfo, GridOrigin, MassesDescription, OccupancyGridExport, count_decisions,
    focal_set_name, write_masses,
};
pub use figure::{
    Legend, OUTLINE, Overlay, PATH, READABLE_SIDE_PX, class_name, figure, readable_scale,
};
pub use views::{ClassColours, decision_image, pignistic_image, trace_image};
