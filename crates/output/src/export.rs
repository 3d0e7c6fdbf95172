//! Exports of the decided grid and of its masses, for ROS and Foxglove, in their messages' exact
//! layouts.

use std::io::Write;
use std::path::Path;

use evigrid::{Label, N_SETS, OMEGA, PerceptionGrid, Window, class};
use serde::Serialize;

use crate::atomic::write_atomic;
use crate::error::{OutputError, check_len};
use crate::mcap::occupancy;

/// `foxglove.NumericType` FLOAT32.
const FLOAT32: u8 = 7;

/// `builtin_interfaces/Time` (ROS 2): seconds and nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct RosTime {
    /// Whole seconds.
    pub sec: u64,
    /// Nanoseconds, 0..10⁹.
    pub nanosec: u32,
}

impl RosTime {
    /// The time of `time_s` seconds, or `None` if it is negative or not finite.
    pub fn from_seconds(time_s: f64) -> Option<Self> {
        let ns = crate::mcap::nanoseconds(time_s)?;
        Some(Self {
            sec: ns / 1_000_000_000,
            // Below 10⁹: fits.
            nanosec: (ns % 1_000_000_000) as u32,
        })
    }
}

/// `std_msgs/Header`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RosHeader {
    /// Time of the last scan fused into the grid.
    pub stamp: RosTime,
    /// Frame of the map's local metric coordinates.
    pub frame_id: String,
}

/// `geometry_msgs/Point`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Point {
    /// Metres.
    pub x: f64,
    /// Metres.
    pub y: f64,
    /// Metres.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

/// `geometry_msgs/Pose`: here always axis-aligned with the map frame (identity orientation).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Pose {
    /// The south-west corner of cell (0, 0), metres.
    pub position: Point,
    /// Identity.
    pub orientation: Quaternion,
}

/// `nav_msgs/MapMetaData`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridInfo {
    /// When the grid was made: the stamp of the header.
    pub map_load_time: RosTime,
    /// Cell side, metres per cell.
    pub resolution: f32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// The corner of the first cell in the map frame.
    pub origin: Pose,
}

/// The decided grid exactly as ROS 2 `nav_msgs/OccupancyGrid`, as JSON (field names and nesting
/// of the message definition, times as `builtin_interfaces/Time`).
///
/// `data` holds one value per cell, row-major from the cell at the origin (south-west, x east,
/// y north): 0 free, 100 occupied (any of I, U, S, M, O), −1 unknown. The decided class of each
/// cell is not part of the message: [`ClassesExport`] holds it in the same order.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OccupancyGridExport {
    /// Stamp and frame.
    pub header: RosHeader,
    /// Grid geometry.
    pub info: GridInfo,
    /// Occupancy per cell.
    pub data: Vec<i8>,
}

/// The decided class of each cell, beside the occupancy grid (`classes.json`): same size and
/// order as [`OccupancyGridExport::data`], codes of [`Label`]: 0 unknown, 1 F, 2 I, 3 U, 4 S,
/// 5 M.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClassesExport {
    /// Code → class name, for a reader without the docs.
    pub codes: [(u8, &'static str); 6],
    /// Columns, as the occupancy grid's `info.width`.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Class code per cell, row-major from the south-west cell.
    pub data: Vec<u8>,
}

/// Class names of the codes 0..=5.
pub const CLASS_CODES: [(u8, &str); 6] = [
    (0, "unknown"),
    (1, "F free"),
    (2, "I mapped infrastructure"),
    (3, "U unmapped infrastructure"),
    (4, "S stopped"),
    (5, "M moving"),
];

/// The origin of the grid: the corner of its south-west cell.
fn origin_pose(window: &Window) -> Pose {
    let s = window.cell_size_m();
    Pose {
        position: Point {
            x: window.first_col() as f64 * s,
            y: window.first_row() as f64 * s,
            z: 0.0,
        },
        orientation: Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        },
    }
}

/// Sizes as the message's `uint32`; a window never comes near 2³² cells a side.
fn dims(window: &Window) -> (u32, u32) {
    let clamp = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    (clamp(window.width()), clamp(window.height()))
}

/// The grid's geometry in ROS terms.
fn grid_info(window: &Window, stamp: RosTime) -> GridInfo {
    let (width, height) = dims(window);
    GridInfo {
        map_load_time: stamp,
        resolution: window.cell_size_m() as f32,
        width,
        height,
        origin: origin_pose(window),
    }
}

impl OccupancyGridExport {
    /// The export of `decisions` (storage order) over the window, in frame `frame_id`, stamped
    /// `stamp`.
    ///
    /// # Errors
    ///
    /// [`OutputError::Size`] if `decisions` does not have the window's size.
    pub fn new(
        window: &Window,
        decisions: &[Label],
        frame_id: &str,
        stamp: RosTime,
    ) -> Result<Self, OutputError> {
        check_len("decisions", decisions.len(), window)?;
        let mut data = Vec::with_capacity(window.len());
        for span in window.world_order_spans() {
            data.extend(decisions[span].iter().map(|&d| occupancy(d)));
        }
        Ok(Self {
            header: RosHeader {
                stamp,
                frame_id: frame_id.to_string(),
            },
            info: grid_info(window, stamp),
            data,
        })
    }

    /// Writes the export as JSON, atomically.
    ///
    /// # Errors
    ///
    /// [`OutputError::Json`] or [`OutputError::Io`], naming `path`.
    pub fn write(&self, path: &Path) -> Result<(), OutputError> {
        write_json(path, self)
    }
}

impl ClassesExport {
    /// The classes of `decisions` (storage order) over the window.
    ///
    /// # Errors
    ///
    /// [`OutputError::Size`] if `decisions` does not have the window's size.
    pub fn new(window: &Window, decisions: &[Label]) -> Result<Self, OutputError> {
        check_len("decisions", decisions.len(), window)?;
        let mut data = Vec::with_capacity(window.len());
        for span in window.world_order_spans() {
            data.extend(decisions[span].iter().map(|&d| d as u8));
        }
        let (width, height) = dims(window);
        Ok(Self {
            codes: CLASS_CODES,
            width,
            height,
            data,
        })
    }

    /// Writes the export as JSON, atomically.
    ///
    /// # Errors
    ///
    /// [`OutputError::Json`] or [`OutputError::Io`], naming `path`.
    pub fn write(&self, path: &Path) -> Result<(), OutputError> {
        write_json(path, self)
    }
}

/// Serialises `value` compactly and writes it atomically.
pub(crate) fn write_json(path: &Path, value: &impl Serialize) -> Result<(), OutputError> {
    let text = serde_json::to_vec(value).map_err(|source| OutputError::Json {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomic(path, |file| file.write_all(&text))
}

/// One field of a `foxglove.Grid` (`foxglove.PackedElementField`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridField {
    /// Field name: the focal set's class letters in frame order (`F`, `FI`, …, `FIUSM` for Ω),
    /// `empty` for ∅, or `zeta`, `conflict_fo`, `conflict_of`.
    pub name: String,
    /// Byte offset inside a cell.
    pub offset: usize,
    /// `foxglove.NumericType`: always 7, FLOAT32 (little-endian).
    #[serde(rename = "type")]
    pub kind: u8,
}

/// `foxglove.Vector2`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Vector2 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
}

/// The masses file's description (`masses.json`): a `foxglove.Grid` in its JSON layout whose
/// `data` is in a separate file (`data_file`, beside it) instead of base64, plus `row_count`
/// and `endianness`. `data_file` holds `row_count` rows of `row_stride` bytes, row 0 at the
/// pose's position (south), each row `column_count` cells of `cell_stride` bytes, each cell the
/// `fields` at their offsets, every value a little-endian IEEE 754 `f32`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MassesDescription {
    /// Time of the last scan fused, `{sec, nsec}` as Foxglove's JSON times.
    pub timestamp: FoxgloveTime,
    /// Frame of the map's local metric coordinates.
    pub frame_id: String,
    /// The south-west corner of the first cell; identity orientation.
    pub pose: Pose,
    /// Columns.
    pub column_count: usize,
    /// Rows (`data_file`'s size over `row_stride`; stated for readers).
    pub row_count: usize,
    /// Cell size, metres.
    pub cell_size: Vector2,
    /// Bytes per row.
    pub row_stride: usize,
    /// Bytes per cell.
    pub cell_stride: usize,
    /// Fields of a cell.
    pub fields: Vec<GridField>,
    /// File name of the binary data, beside the description.
    pub data_file: String,
    /// Always `little`.
    pub endianness: &'static str,
}

/// A time as Foxglove's JSON writes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct FoxgloveTime {
    /// Whole seconds.
    pub sec: u64,
    /// Nanoseconds.
    pub nsec: u32,
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
    stamp: RosTime,
    json_path: &Path,
) -> Result<(), OutputError> {
    check_len("perception grid", grid.len(), window)?;
    let bin_path = json_path.with_extension("bin");
    let mut fields: Vec<GridField> = (0..N_SETS)
        .map(|set| GridField {
            name: focal_set_name(set),
            offset: 4 * set,
            kind: FLOAT32,
        })
        .collect();
    for (k, name) in ["zeta", "conflict_fo", "conflict_of"]
        .into_iter()
        .enumerate()
    {
        fields.push(GridField {
            name: name.to_string(),
            offset: 4 * (N_SETS + k),
            kind: FLOAT32,
        });
    }
    let cell_stride = 4 * fields.len();
    let s = window.cell_size_m();
    let description = MassesDescription {
        timestamp: FoxgloveTime {
            sec: stamp.sec,
            nsec: stamp.nanosec,
        },
        frame_id: frame_id.to_string(),
        pose: origin_pose(window),
        column_count: window.width(),
        row_count: window.height(),
        cell_size: Vector2 { x: s, y: s },
        cell_stride,
        row_stride: cell_stride * window.width(),
        fields,
        endianness: "little",
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

/// What [`write_grid_exports`] exports: the grid after the last frame.
#[derive(Clone, Copy, Debug)]
pub struct GridExports<'a> {
    /// The window.
    pub window: &'a Window,
    /// Decisions, storage order.
    pub decisions: &'a [Label],
    /// Masses.
    pub perception: &'a PerceptionGrid,
    /// Time of the last scan fused, seconds.
    pub time_s: f64,
    /// The local frame's projection, when the run has one (a map, `--origin`, a GNSS drive);
    /// without it the decision map cannot be georeferenced and is not written.
    pub projection: Option<&'a geodata::TransverseMercator>,
}

/// Names of the files [`write_grid_exports`] writes in the output directory.
pub mod file_names {
    /// `nav_msgs/OccupancyGrid` JSON.
    pub const OCCUPANCY: &str = "occupancy.json";
    /// Decided classes per cell.
    pub const CLASSES: &str = "classes.json";
    /// Masses description (`masses.bin` beside it).
    pub const MASSES: &str = "masses.json";
    /// nav2 `map_server` YAML (`map.pgm` beside it).
    pub const NAV2_YAML: &str = "map.yaml";
    /// Georeferenced decision map (`.pgw`, `.prj`, `.png.aux.xml` beside it).
    pub const GEO_PNG: &str = "decision-map.png";
    /// The same map as a GeoTIFF of class codes.
    pub const GEOTIFF: &str = "decision-map.tif";
}

/// Writes the exports of the final grid into `out`: `occupancy.json`, `classes.json`,
/// `masses.json` + `masses.bin`, `map.pgm` + `map.yaml`, and with a projection the georeferenced
/// `decision-map.png` and its side files and `decision-map.tif`. Returns the files written.
///
/// # Errors
///
/// [`OutputError::Time`] if the time cannot be stamped, else as the single exports.
pub fn write_grid_exports(
    out: &Path,
    exports: &GridExports<'_>,
) -> Result<Vec<std::path::PathBuf>, OutputError> {
    let occupancy_path = out.join(file_names::OCCUPANCY);
    let stamp = RosTime::from_seconds(exports.time_s).ok_or_else(|| OutputError::Time {
        path: occupancy_path.clone(),
        time_s: exports.time_s,
    })?;
    let (window, decisions) = (exports.window, exports.decisions);
    OccupancyGridExport::new(window, decisions, crate::mcap::FRAME_MAP, stamp)?
        .write(&occupancy_path)?;
    let classes_path = out.join(file_names::CLASSES);
    ClassesExport::new(window, decisions)?.write(&classes_path)?;
    let masses_path = out.join(file_names::MASSES);
    write_masses(
        window,
        exports.perception,
        crate::mcap::FRAME_MAP,
        stamp,
        &masses_path,
    )?;
    let yaml_path = out.join(file_names::NAV2_YAML);
    crate::nav2::write_nav2_map(window, decisions, &yaml_path)?;
    let mut written = vec![
        occupancy_path,
        classes_path,
        masses_path.with_extension("bin"),
        masses_path,
        yaml_path.with_extension("pgm"),
        yaml_path,
    ];
    if let Some(projection) = exports.projection {
        written.extend(crate::georef::write_georeferenced_png(
            window,
            decisions,
            projection,
            &out.join(file_names::GEO_PNG),
        )?);
        let tiff = out.join(file_names::GEOTIFF);
        crate::geotiff::write_geotiff(window, decisions, projection, &tiff)?;
        written.push(tiff);
    }
    Ok(written)
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
        let stamp = RosTime::from_seconds(12.5).unwrap();
        let export = OccupancyGridExport::new(&w, &d, "map", stamp).unwrap();
        assert_eq!(export.data, vec![0, 100, -1, -1, -1, 100]);
        let classes = ClassesExport::new(&w, &d).unwrap();
        assert_eq!(classes.data, vec![1, 4, 0, 0, 0, 2]);
        // Origin: corner of cell (10, -1) at 0.5 m cells.
        let p = export.info.origin.position;
        assert_eq!((p.x, p.y, p.z), (5.0, -0.5, 0.0));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grid.json");
        export.write(&path).unwrap();
        let back: serde_json::Value = serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
        assert_eq!(back["info"]["width"], 3);
        assert_eq!(back["data"][1], 100);
        assert_eq!(back["header"]["stamp"]["sec"], 12);
        assert_eq!(back["header"]["stamp"]["nanosec"], 500_000_000);
        assert_eq!(back["header"]["frame_id"], "map");
        assert_eq!(back["info"]["origin"]["orientation"]["w"], 1.0);
        assert!(back.get("classes").is_none());
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
        write_masses(&w, &pg, "map", RosTime { sec: 3, nanosec: 0 }, &path).unwrap();
        let description: serde_json::Value =
            serde_json::from_slice(&fs::read(&path).unwrap()).unwrap();
        assert_eq!(description["fields"][31]["name"], "FIUSM");
        assert_eq!(description["fields"][3]["name"], "FI");
        assert_eq!(description["cell_stride"], 35 * 4);
        assert_eq!(description["fields"][0]["type"], 7);
        assert_eq!(description["cell_size"]["x"], 0.5);
        assert_eq!(description["pose"]["position"]["x"], 5.0);
        assert_eq!(description["timestamp"]["sec"], 3);
        assert_eq!(description["endianness"], "little");
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
