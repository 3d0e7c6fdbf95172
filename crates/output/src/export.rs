//! Exports of the decided grid and of its masses, for ROS and Foxglove.

use std::io::Write;
use std::path::Path;

use evigrid::{Label, N_SETS, OMEGA, PerceptionGrid, Window, class};
use serde::Serialize;

use crate::atomic::write_atomic;
use crate::error::{OutputError, check_len};

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
/// y north): 0 free, 100 occupied (any of I, U, S, M, O), −1 unknown. `classes` holds the decided
/// class of each cell in the same order, as [`Label`]'s codes: 0 unknown, 1 F, 2 I, 3 U,
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
    /// [`OutputError::Size`] if `decisions` does not have the window's size.
    pub fn new(window: &Window, decisions: &[Label], frame_id: &str) -> Result<Self, OutputError> {
        check_len("decisions", decisions.len(), window)?;
        let mut data = Vec::with_capacity(window.len());
        let mut classes = Vec::with_capacity(window.len());
        for span in window.world_order_spans() {
            for &decision in &decisions[span] {
                data.push(match decision {
                    Label::Unknown => -1,
                    Label::F => 0,
                    // Edge is truth only (a building's boundary band): static and occupied in part.
                    Label::I | Label::U | Label::S | Label::M | Label::O | Label::Edge => 100,
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
    /// [`OutputError::Json`] or [`OutputError::Io`], naming `path`.
    pub fn write(&self, path: &Path) -> Result<(), OutputError> {
        let text = serde_json::to_vec(self).map_err(|source| OutputError::Json {
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
/// [`OutputError`] naming the file, or [`OutputError::Size`] if the grid does not have the
/// window's size.
pub fn write_masses(
    window: &Window,
    grid: &PerceptionGrid,
    frame_id: &str,
    json_path: &Path,
) -> Result<(), OutputError> {
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
    let text = serde_json::to_vec_pretty(&description).map_err(|source| OutputError::Json {
        path: json_path.to_path_buf(),
        source,
    })?;
    write_atomic(json_path, |file| file.write_all(&text))
}

/// Counts cells per decision of the method: `[unknown, F, I, U, S, M]`, the six codes it
/// decides. [`Label::O`] decides no class of Ω_PG, so a cell labelled O (by a two-class baseline;
/// the method never says it) is counted as unknown.
pub fn count_decisions(decisions: &[Label]) -> [usize; 6] {
    let mut counts = [0usize; 6];
    for &d in decisions {
        let code = if d == Label::O { Label::Unknown } else { d };
        counts[code as usize] += 1;
    }
    counts
}

// Ω is the last plane: the masses export relies on bitmask order ending with it.
const _: () = assert!(OMEGA == N_SETS - 1);

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::{decisions, window};
    use std::fs;

    #[test]
    fn occupancy_export_is_row_major_from_the_origin() {
        let w = window();
        let d = decisions(&w, |col, row| match (col, row) {
            (10, -1) => Label::F,
            (11, -1) => Label::S,
            (12, 0) => Label::I,
            _ => Label::Unknown,
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
    fn decisions_are_counted_by_code() {
        use Label::*;
        let counts = count_decisions(&[F, F, M, Unknown, S, O, I, U, U]);
        assert_eq!(counts, [2, 2, 1, 2, 1, 1]);
        assert_eq!(counts.iter().sum::<usize>(), 9);
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
}
