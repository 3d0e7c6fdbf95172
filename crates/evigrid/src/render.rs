//! Pictures and exports of the PerceptionGrid (SPEC §6, paper Fig. 2).
//!
//! Images are north-up: image row 0 is the window's northmost row, column 0 its westmost column,
//! one pixel per cell. Three pictures follow the paper's Fig. 2:
//! - the decision map ([`decision_image`]): free green, moving red, static blue (mapped
//!   infrastructure, unmapped infrastructure and stopped objects in three shades of blue with
//!   [`ClassColours::FIVE_CLASSES`], one blue with [`ClassColours::THREE_CLASSES`]), unknown black;
//! - the pignistic view ([`pignistic_image`]): the mean of the class colours weighted by betP
//!   (eq 15), black where the cell was never observed;
//! - the trace of moving objects ([`trace_image`]): the decision map with every cell ever decided
//!   moving during the drive painted red, from a [`MovingTrace`] kept world-fixed in the window.
//!
//! Exports: [`OccupancyGridExport`] follows ROS `nav_msgs/OccupancyGrid` (row-major from the
//! cell at the origin, 0 free, 100 occupied, −1 unknown, plus the decided class of each cell),
//! and [`write_masses`] writes every focal set's mass as one `f32` field per cell, laid out as a
//! `foxglove.Grid` (a JSON description beside a raw little-endian binary). Every file is written
//! to a temporary name and renamed, so a reader never sees half a file.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use image::{Rgb, RgbImage};
use serde::Serialize;

use crate::decision::{Decision, betp};
use crate::trace::MovingTrace;
use crate::grids::{N_SETS, OMEGA, PerceptionGrid, class};
use crate::window::Window;

/// Why a picture or an export could not be written. Every variant names the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// Writing or renaming the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Encoding the PNG failed.
    #[error("{path}: {source}")]
    Image {
        /// The file.
        path: PathBuf,
        /// The encoder's error.
        source: image::ImageError,
    },
    /// Serialising JSON failed.
    #[error("{path}: {source}")]
    Json {
        /// The file.
        path: PathBuf,
        /// The serialiser's error.
        source: serde_json::Error,
    },
    /// A buffer does not have one entry per window cell.
    #[error("{what} holds {len} cells, the window {expected}")]
    Size {
        /// Which buffer.
        what: &'static str,
        /// Its length.
        len: usize,
        /// The window's cell count.
        expected: usize,
    },
}

/// The colour of each decision: unknown, then the classes F, I, U, S, M.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClassColours {
    /// Unknown (never observed, or too ignorant).
    pub unknown: [u8; 3],
    /// Classes F, I, U, S, M in frame order.
    pub classes: [[u8; 3]; 5],
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
    };

    /// As [`THREE_CLASSES`](Self::THREE_CLASSES) with the static classes told apart by shade:
    /// mapped infrastructure I dark blue, unmapped infrastructure U mid blue, stopped S light
    /// blue.
    pub const FIVE_CLASSES: Self = Self {
        unknown: [0, 0, 0],
        classes: [
            [0, 190, 0],
            [20, 30, 150],
            [40, 100, 255],
            [140, 200, 255],
            [230, 0, 0],
        ],
    };

    /// The colour of a decision.
    pub fn of(&self, decision: Decision) -> [u8; 3] {
        match decision {
            Decision::Unknown => self.unknown,
            Decision::F => self.classes[0],
            Decision::I => self.classes[1],
            Decision::U => self.classes[2],
            Decision::S => self.classes[3],
            Decision::M => self.classes[4],
        }
    }
}

fn check_len(what: &'static str, len: usize, window: &Window) -> Result<(), RenderError> {
    if len == window.len() {
        Ok(())
    } else {
        Err(RenderError::Size {
            what,
            len,
            expected: window.len(),
        })
    }
}

/// Paints one pixel per cell, north-up, with `colour(storage_index)`.
fn paint(window: &Window, mut colour: impl FnMut(usize) -> [u8; 3]) -> RgbImage {
    let (w, h) = (window.width() as u32, window.height() as u32);
    let mut image = RgbImage::new(w, h);
    let mut pixel = 0u32;
    // World-order spans run south to north, west to east; image rows run north to south.
    for span in window.world_order_spans() {
        for idx in span {
            let (x, row_from_south) = (pixel % w, pixel / w);
            image.put_pixel(x, h - 1 - row_from_south, Rgb(colour(idx)));
            pixel += 1;
        }
    }
    image
}

/// The decision map: one colour per decided class (`decisions` in storage order, as
/// [`crate::decision::decide_grid`] fills it).
///
/// # Errors
///
/// [`RenderError::Size`] if `decisions` does not have one entry per window cell.
pub fn decision_image(
    window: &Window,
    decisions: &[Decision],
    colours: &ClassColours,
) -> Result<RgbImage, RenderError> {
    check_len("decisions", decisions.len(), window)?;
    Ok(paint(window, |idx| colours.of(decisions[idx])))
}

/// The pignistic view: per cell the mean of the five class colours weighted by betP (eq 15),
/// black for cells never observed.
///
/// # Errors
///
/// [`RenderError::Size`] if the grid does not have the window's size.
pub fn pignistic_image(
    window: &Window,
    grid: &PerceptionGrid,
    colours: &ClassColours,
) -> Result<RgbImage, RenderError> {
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
/// [`RenderError::Size`] if `decisions` or the trace do not have the window's size.
pub fn trace_image(
    window: &Window,
    decisions: &[Decision],
    trace: &MovingTrace,
    colours: &ClassColours,
) -> Result<RgbImage, RenderError> {
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

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename.
///
/// # Errors
///
/// [`RenderError::Io`] naming `path`.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> std::io::Result<()>,
) -> Result<(), RenderError> {
    let io = |source| RenderError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(format!(".tmp-{}", std::process::id()));
    let temporary = path.with_file_name(name);
    let result = (|| {
        let mut file = fs::File::create(&temporary)?;
        write(&mut file)?;
        file.flush()?;
        fs::rename(&temporary, path)
    })();
    if result.is_err() {
        // Best effort: the temporary may not exist; the write error is what matters.
        let _ = fs::remove_file(&temporary);
    }
    result.map_err(io)
}

/// Writes a PNG atomically.
///
/// # Errors
///
/// [`RenderError::Image`] or [`RenderError::Io`], naming `path`.
pub fn write_png(image: &RgbImage, path: &Path) -> Result<(), RenderError> {
    let mut encoded = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut encoded),
            image::ImageFormat::Png,
        )
        .map_err(|source| RenderError::Image {
            path: path.to_path_buf(),
            source,
        })?;
    write_atomic(path, |file| file.write_all(&encoded))
}

/// A position in the `geometry_msgs/Pose` layout (orientation is the identity: the grid is
/// axis-aligned with the map frame).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridOrigin {
    /// Position `{x, y, z}` of the south-west corner of cell (0, 0), metres.
    pub position: [f64; 3],
    /// Orientation quaternion `[x, y, z, w]`.
    pub orientation: [f64; 4],
}

/// `nav_msgs/MapMetaData`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridInfo {
    /// Cell side, metres.
    pub resolution: f64,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The corner of the first cell in the map frame.
    pub origin: GridOrigin,
}

/// The decided grid in `nav_msgs/OccupancyGrid` layout, as JSON.
///
/// `data` holds one value per cell, row-major from the cell at the origin (south-west, x east,
/// y north): 0 free, 100 occupied (any of I, U, S, M), −1 unknown. `classes` holds the decided
/// class of each cell in the same order, as [`Decision`]'s codes: 0 unknown, 1 F, 2 I, 3 U,
/// 4 S, 5 M.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OccupancyGridExport {
    /// Frame of the map's local metric coordinates.
    pub frame_id: String,
    /// Grid geometry.
    pub info: GridInfo,
    /// Occupancy per cell.
    pub data: Vec<i8>,
    /// Decided class per cell.
    pub classes: Vec<u8>,
}

/// The grid's geometry in ROS terms.
fn grid_info(window: &Window) -> GridInfo {
    let s = window.cell_size_m();
    GridInfo {
        resolution: s,
        width: window.width(),
        height: window.height(),
        origin: GridOrigin {
            position: [
                window.first_col() as f64 * s,
                window.first_row() as f64 * s,
                0.0,
            ],
            orientation: [0.0, 0.0, 0.0, 1.0],
        },
    }
}

impl OccupancyGridExport {
    /// The export of `decisions` (storage order) over the window, in frame `frame_id`.
    ///
    /// # Errors
    ///
    /// [`RenderError::Size`] if `decisions` does not have the window's size.
    pub fn new(
        window: &Window,
        decisions: &[Decision],
        frame_id: &str,
    ) -> Result<Self, RenderError> {
        check_len("decisions", decisions.len(), window)?;
        let mut data = Vec::with_capacity(window.len());
        let mut classes = Vec::with_capacity(window.len());
        for span in window.world_order_spans() {
            for &decision in &decisions[span] {
                data.push(match decision {
                    Decision::Unknown => -1,
                    Decision::F => 0,
                    Decision::I | Decision::U | Decision::S | Decision::M => 100,
                });
                classes.push(decision as u8);
            }
        }
        Ok(Self {
            frame_id: frame_id.to_string(),
            info: grid_info(window),
            data,
            classes,
        })
    }

    /// Writes the export as JSON, atomically.
    ///
    /// # Errors
    ///
    /// [`RenderError::Json`] or [`RenderError::Io`], naming `path`.
    pub fn write(&self, path: &Path) -> Result<(), RenderError> {
        let text = serde_json::to_vec(self).map_err(|source| RenderError::Json {
            path: path.to_path_buf(),
            source,
        })?;
        write_atomic(path, |file| file.write_all(&text))
    }
}

/// One field of a `foxglove.Grid`-style description.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridField {
    /// Field name: the focal set's class letters in frame order (`F`, `FI`, …, `FIUSM` for Ω),
    /// `empty` for ∅, or `zeta`, `conflict_fo`, `conflict_of`.
    pub name: String,
    /// Byte offset inside a cell.
    pub offset: usize,
    /// Always `FLOAT32` (little-endian).
    #[serde(rename = "type")]
    pub kind: &'static str,
}

/// The description of a masses file, after `foxglove.Grid`: `data_file` holds `row_count` rows
/// of `row_stride` bytes, row 0 at the origin (south), each row `column_count` cells of
/// `cell_stride` bytes, each cell the `fields` at their offsets.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MassesDescription {
    /// Frame of the map's local metric coordinates.
    pub frame_id: String,
    /// Geometry, as in the occupancy grid export.
    pub info: GridInfo,
    /// Columns (`info.width`).
    pub column_count: usize,
    /// Rows (`info.height`).
    pub row_count: usize,
    /// Bytes per cell.
    pub cell_stride: usize,
    /// Bytes per row.
    pub row_stride: usize,
    /// Fields of a cell.
    pub fields: Vec<GridField>,
    /// File name of the binary data, beside the description.
    pub data_file: String,
}

/// Name of a focal set of Ω_PG by its class letters, `empty` for ∅.
pub fn focal_set_name(set: usize) -> String {
    if set == 0 {
        return "empty".to_string();
    }
    class::LETTERS
        .iter()
        .enumerate()
        .filter(|(k, _)| set & (1 << k) != 0)
        .map(|(_, c)| *c)
        .collect()
}

/// Writes the full masses of the grid: `<stem>.json` (a [`MassesDescription`]) and `<stem>.bin`
/// (the cells), both atomically. Fields are the 32 focal sets in bitmask order (so Ω = `FIUSM`
/// is field 31), then ζ, ∅_FO and ∅_OF.
///
/// # Errors
///
/// [`RenderError`] naming the file, or [`RenderError::Size`] if the grid does not have the
/// window's size.
pub fn write_masses(
    window: &Window,
    grid: &PerceptionGrid,
    frame_id: &str,
    json_path: &Path,
) -> Result<(), RenderError> {
    check_len("perception grid", grid.len(), window)?;
    let bin_path = json_path.with_extension("bin");
    let mut fields: Vec<GridField> = (0..N_SETS)
        .map(|set| GridField {
            name: focal_set_name(set),
            offset: 4 * set,
            kind: "FLOAT32",
        })
        .collect();
    for (k, name) in ["zeta", "conflict_fo", "conflict_of"]
        .into_iter()
        .enumerate()
    {
        fields.push(GridField {
            name: name.to_string(),
            offset: 4 * (N_SETS + k),
            kind: "FLOAT32",
        });
    }
    let cell_stride = 4 * fields.len();
    let description = MassesDescription {
        frame_id: frame_id.to_string(),
        info: grid_info(window),
        column_count: window.width(),
        row_count: window.height(),
        cell_stride,
        row_stride: cell_stride * window.width(),
        fields,
        data_file: bin_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
    };
    let mut data = Vec::with_capacity(cell_stride * window.len());
    let planes: Vec<&[f32]> = (0..N_SETS)
        .map(|set| grid.plane(set))
        .chain([grid.zeta(), grid.conflict_fo(), grid.conflict_of()])
        .collect();
    for span in window.world_order_spans() {
        for idx in span {
            for plane in &planes {
                data.extend_from_slice(&plane[idx].to_le_bytes());
            }
        }
    }
    write_atomic(&bin_path, |file| file.write_all(&data))?;
    let text = serde_json::to_vec_pretty(&description).map_err(|source| RenderError::Json {
        path: json_path.to_path_buf(),
        source,
    })?;
    write_atomic(json_path, |file| file.write_all(&text))
}

/// Counts cells per decision: `[unknown, F, I, U, S, M]`.
pub fn count_decisions(decisions: &[Decision]) -> [usize; 6] {
    let mut counts = [0usize; 6];
    for &d in decisions {
        counts[d as usize] += 1;
    }
    counts
}

// Ω is the last plane: the masses export relies on bitmask order ending with it.
const _: () = assert!(OMEGA == N_SETS - 1);

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A 3 × 2 window at cells (10..13, -1..1), scrolled so storage and world order differ.
    fn window() -> Window {
        let mut w = Window::new(3, 2, 0.5).unwrap();
        w.move_to(10, -1);
        w
    }

    /// Decisions in storage order from a function of the global cell.
    fn decisions(w: &Window, f: impl Fn(i64, i64) -> Decision) -> Vec<Decision> {
        (0..w.len())
            .map(|idx| {
                let c = w.cell_of_storage(idx).unwrap();
                f(c.col, c.row)
            })
            .collect()
    }

    #[test]
    fn images_are_north_up_and_west_left() {
        let w = window();
        // South-west cell (10, -1) moving, north-east cell (12, 0) free, the rest unknown.
        let d = decisions(&w, |col, row| match (col, row) {
            (10, -1) => Decision::M,
            (12, 0) => Decision::F,
            (11, 0) => Decision::U,
            _ => Decision::Unknown,
        });
        let image = decision_image(&w, &d, &ClassColours::FIVE_CLASSES).unwrap();
        assert_eq!(image.dimensions(), (3, 2));
        assert_eq!(image.get_pixel(0, 1).0, [230, 0, 0]);
        assert_eq!(image.get_pixel(2, 0).0, [0, 190, 0]);
        assert_eq!(image.get_pixel(1, 0).0, [40, 100, 255]);
        assert_eq!(image.get_pixel(1, 1).0, [0, 0, 0]);
        let three = decision_image(&w, &d, &ClassColours::THREE_CLASSES).unwrap();
        assert_eq!(three.get_pixel(1, 0).0, [40, 80, 255]);
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
        let mut sg = crate::grids::SensorGrid::new(1, 1);
        sg.m_free_mut()[0] = 0.7;
        let gg = crate::grids::GisGrid::new(1, 1);
        crate::step::step(&mut pg, &sg, &gg, &crate::Params::default(), 0.1);
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
        let d = decisions(
            &w,
            |col, _| if col == 10 { Decision::M } else { Decision::F },
        );
        trace.record(&d);
        let later = decisions(&w, |_, _| Decision::F);
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
    fn occupancy_export_is_row_major_from_the_origin() {
        let w = window();
        let d = decisions(&w, |col, row| match (col, row) {
            (10, -1) => Decision::F,
            (11, -1) => Decision::S,
            (12, 0) => Decision::I,
            _ => Decision::Unknown,
        });
        let export = OccupancyGridExport::new(&w, &d, "map").unwrap();
        assert_eq!(export.data, vec![0, 100, -1, -1, -1, 100]);
        assert_eq!(export.classes, vec![1, 4, 0, 0, 0, 2]);
        // Origin: corner of cell (10, -1) at 0.5 m cells.
        assert_eq!(export.info.origin.position, [5.0, -0.5, 0.0]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grid.json");
        export.write(&path).unwrap();
        let back: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
        assert_eq!(back["info"]["width"], 3);
        assert_eq!(back["data"][1], 100);
        // Only the final file is left behind.
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn masses_export_has_one_field_per_focal_set() {
        let w = window();
        let mut pg = PerceptionGrid::new(3, 2);
        let mut m = [0.0f32; N_SETS];
        m[class::F] = 0.25;
        m[OMEGA] = 0.75;
        // The cell at the origin, (10, -1).
        let origin_idx = w.storage_index(10, -1).unwrap();
        pg.set_cell_masses(origin_idx, &m);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("masses.json");
        write_masses(&w, &pg, "map", &path).unwrap();
        let description: serde_json::Value =
            serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
        assert_eq!(description["fields"][31]["name"], "FIUSM");
        assert_eq!(description["fields"][3]["name"], "FI");
        assert_eq!(description["cell_stride"], 35 * 4);
        let data = fs::read(dir.path().join("masses.bin")).unwrap();
        assert_eq!(data.len(), 6 * 35 * 4);
        let field = |cell: usize, k: usize| {
            let at = cell * 140 + 4 * k;
            f32::from_le_bytes([data[at], data[at + 1], data[at + 2], data[at + 3]])
        };
        assert_eq!((field(0, 1), field(0, 31)), (0.25, 0.75));
        assert_eq!((field(1, 1), field(1, 31)), (0.0, 1.0));
    }

    #[test]
    fn png_is_written_atomically() {
        let w = window();
        let d = vec![Decision::F; w.len()];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.png");
        write_png(
            &decision_image(&w, &d, &ClassColours::THREE_CLASSES).unwrap(),
            &path,
        )
        .unwrap();
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!(back.get_pixel(2, 1).0, [0, 190, 0]);
        let bad = dir.path().join("missing-dir/d.png");
        assert!(matches!(
            write_png(
                &decision_image(&w, &d, &ClassColours::THREE_CLASSES).unwrap(),
                &bad
            ),
            Err(RenderError::Io { .. })
        ));
    }
}
