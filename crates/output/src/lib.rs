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
//!   colours) and the trace of moving objects ([`trace_image`]); colours in [`ClassColours`],
//!   one palette for every output ([`COLOURS`], the colour-blind-safe Okabe–Ito one, checked
//!   with [`palette`]).
//! - The pictures' pixels, [`raster::RgbImage`], and their files: PNG through the `png` crate,
//!   the demo's animated GIF through the `gif` crate ([`raster::GifAnimation`]).
//! - Figures for people ([`figure`]): those pictures enlarged ([`readable_scale`]), side by side,
//!   with map outlines and the ego's path ([`Overlay`]), a [`Legend`], a scale bar and a north
//!   arrow; text in an embedded DejaVu Sans ([`text`]). A run's per-frame pictures
//!   ([`frame_picture`]): the decision map with the ego marked and a legend strip.
//! - Exports ([`write_grid_exports`]): [`OccupancyGridExport`], ROS 2 `nav_msgs/OccupancyGrid`
//!   exactly (0 free, 100 occupied, −1 unknown), each cell's [`Label`](evigrid::Label) code in
//!   [`ClassesExport`], [`write_masses`] (every focal set's mass as one little-endian `f32` field
//!   per cell, `foxglove.Grid`'s JSON layout), the nav2 `map_server` pair ([`nav2`]) and the
//!   decision map georeferenced for GIS ([`georef`]).
//! - The run as a Foxglove-ready MCAP recording ([`mcap::McapRecorder`]).
//! - The one output-folder policy ([`out_dir`]): a folder evigrid did not write is refused,
//!   one it wrote is cleared of the last run's files first.
//! - Sinks ([`sink::FrameSink`]): where a session's frames go (the recording, the per-frame
//!   pictures, `frames.jsonl`, the final figures of [`run_figures`] and the exports), chosen by
//!   the caller.
//!
//! ```
//! use evigrid::{Label, Window};
//! use output::{ClassColours, OccupancyGridExport, RosTime, decision_image};
//!
//! let window = Window::new(2, 1, 0.5)?;
//! let decisions = [Label::F, Label::M];
//! let image = decision_image(&window, &decisions, &ClassColours::THREE_CLASSES)?;
//! assert_eq!(image.get_pixel(1, 0).0, [230, 0, 0]); // moving: red
//! let export = OccupancyGridExport::new(&window, &decisions, "map", RosTime { sec: 0, nanosec: 0 })?;
//! assert_eq!(export.data, [0, 100]);
//! assert_eq!(output::ClassesExport::new(&window, &decisions)?.data, [1, 5]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

mod atomic;
mod error;
mod export;
mod figure;
mod frame;
pub mod georef;
pub mod geotiff;
mod indexed;
pub mod mcap;
pub mod nav2;
pub mod out_dir;
pub mod palette;
pub mod raster;
pub mod run_figures;
pub mod sink;
#[cfg(test)]
mod testing;
pub mod text;
mod views;
mod whole_lines;

pub use atomic::{AtomicFile, stop_temporaries, write_atomic, write_png, write_png_fast};
pub use error::{MAX_FIGURE_PIXELS, OutputError};
pub use export::{
    CLASS_CODES, ClassesExport, FoxgloveTime, GridExports, GridField, GridInfo, MassesDescription,
    OccupancyGridExport, Point, Pose, Quaternion, RosHeader, RosTime, Vector2, count_decisions,
    file_names, focal_set_name, write_grid_exports, write_masses,
};
pub use figure::{
    Legend, OUTLINE, Overlay, PATH, PIGNISTIC_MIXES, READABLE_SIDE_PX, class_name, figure,
    mixed_colour, readable_scale,
};
pub use frame::{STRIP_LABELS, STRIP_PX, frame_picture, strip_entries, strip_name};
pub use indexed::{write_decision_png, write_indexed_png};
pub use views::{COLOURS, ClassColours, decision_image, pignistic_image, trace_image};
pub use whole_lines::{WholeLines, stop_records};
