//! The fuzz targets: every parser evigrid runs on user input, fed arbitrary bytes.
//!
//! A target returns whether the input was accepted; what matters is that it returns at all,
//! without a panic, an abort on a huge allocation or a hang. Parsers that read paths are fed
//! through a scratch file, as the CLI feeds them.

use std::path::{Path, PathBuf};

use drive::poses::{self, KittiOdometryContext, PoseFormat};
use geodata::{CellWindow, ContextRaster, LoadOptions, MapContext};

/// Per-run state a target may use: a scratch directory for path-based readers.
#[derive(Debug)]
pub struct Scratch {
    dir: tempfile::TempDir,
}

impl Scratch {
    /// A fresh scratch directory, removed when dropped.
    ///
    /// # Errors
    /// The temporary directory cannot be created.
    pub fn new() -> std::io::Result<Self> {
        // In memory where the system has it: path-based targets write a file per execution.
        let shm = Path::new("/dev/shm");
        let dir = if shm.is_dir() {
            tempfile::tempdir_in(shm).or_else(|_| tempfile::tempdir())?
        } else {
            tempfile::tempdir()?
        };
        Ok(Self { dir })
    }

    /// Writes `bytes` to the scratch file `name` and returns its path; `None` if the write
    /// failed (then the execution is skipped, not counted as a finding).
    fn file(&self, name: &str, bytes: &[u8]) -> Option<PathBuf> {
        let path = self.dir.path().join(name);
        std::fs::write(&path, bytes).ok().map(|()| path)
    }
}

/// One parser under test.
#[derive(Clone, Copy, Debug)]
pub struct Target {
    /// Name on the command line and in reports.
    pub name: &'static str,
    /// What the target parses.
    pub about: &'static str,
    /// Runs the parser on one input; `true` if it was accepted.
    pub run: fn(&[u8], &Scratch) -> bool,
    /// The hand-made seed inputs, valid or nearly so.
    pub seeds: fn() -> Vec<Vec<u8>>,
    /// Files of the shared data (relative to `EVIGRID_SHARED`) added to the seeds when present.
    pub shared_seeds: &'static [&'static str],
    /// Longest mutant tried, bytes.
    pub max_len: usize,
}

/// Every target, in the order of the smoke run.
pub const TARGETS: &[Target] = &[
    Target {
        name: "pcd",
        about: "PCD v0.7 scans, ascii and binary",
        run: run_pcd,
        seeds: seeds_pcd,
        shared_seeds: &["data/lidar/kitti-city-22/0000000000.pcd"],
        max_len: 1 << 16,
    },
    Target {
        name: "kitti-bin",
        about: "KITTI Velodyne .bin scans (x y z reflectance, f32 little endian)",
        run: run_kitti_bin,
        seeds: seeds_kitti_bin,
        shared_seeds: &[],
        max_len: 1 << 12,
    },
    Target {
        name: "map",
        about: "vector maps (OSM XML, OSM PBF, GeoJSON, gzip), loaded, projected and rasterised",
        run: run_map,
        seeds: seeds_map,
        shared_seeds: &["data/osm/bavarian-village.osm", "data/osm/kouvola.osm.pbf"],
        max_len: 1 << 18,
    },
    Target {
        name: "poses",
        about: "pose files: evigrid (local and WGS84), TUM, KITTI odometry; format detection",
        run: run_poses,
        seeds: seeds_poses,
        shared_seeds: &[],
        max_len: 1 << 12,
    },
    Target {
        name: "kitti-raw-text",
        about: "KITTI raw text files: OXTS packets, calibration, timestamps",
        run: run_kitti_raw_text,
        seeds: seeds_kitti_raw_text,
        shared_seeds: &[
            "data/lidar/kitti-raw-0013/2011_09_26/calib_imu_to_velo.txt",
            "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync/oxts/data/0000000000.txt",
        ],
        max_len: 1 << 12,
    },
    Target {
        name: "odometry",
        about: "lidar odometry and the pose refinement on a mutated scan (PCD or KITTI .bin) \
                registered three times, the odometry's poses written as TUM and KITTI odometry \
                and read back",
        run: run_odometry,
        seeds: seeds_odometry,
        shared_seeds: &[],
        max_len: 1 << 14,
    },
    Target {
        name: "bag",
        about: "ROS 2 MCAP recordings: opened (topics, tf, odometry, fixes), three scans decoded",
        run: run_bag,
        seeds: seeds_bag,
        shared_seeds: &[],
        max_len: 1 << 18,
    },
    Target {
        name: "params",
        about: "parameter files (TOML in SPEC §7's layout), validated, a pipeline built from them",
        run: run_params,
        seeds: seeds_params,
        shared_seeds: &[],
        max_len: 1 << 13,
    },
    Target {
        name: "scenario",
        about: "simulator scenarios (TOML), validated",
        run: run_scenario,
        seeds: seeds_scenario,
        shared_seeds: &[],
        max_len: 1 << 13,
    },
];

/// The target called `name`.
pub fn target(name: &str) -> Option<&'static Target> {
    TARGETS.iter().find(|t| t.name == name)
}

/// The seeds of `target`: the hand-made ones and the shared files found under `shared`.
pub fn seeds(target: &Target, shared: Option<&Path>) -> Vec<Vec<u8>> {
    let mut seeds = (target.seeds)();
    if let Some(shared) = shared {
        seeds.extend(
            target
                .shared_seeds
                .iter()
                .filter_map(|rel| std::fs::read(shared.join(rel)).ok()),
        );
    }
    seeds
}

// ---------------------------------------------------------------------------------------------
// Scans

fn run_pcd(bytes: &[u8], _: &Scratch) -> bool {
    drive::scan::parse_pcd(bytes, Path::new("fuzz.pcd")).is_ok()
}

fn seeds_pcd() -> Vec<Vec<u8>> {
    let header = |data: &str, fields: &str, size: &str, ty: &str, count: &str, n: usize| {
        format!(
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {fields}\nSIZE {size}\n\
             TYPE {ty}\nCOUNT {count}\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n\
             DATA {data}\n"
        )
    };
    let ascii = header(
        "ascii",
        "x y z intensity",
        "4 4 4 4",
        "F F F F",
        "1 1 1 1",
        3,
    ) + "1.5 -2.25 0.5 7\n10 0 -1.7 0\n-3 4 2 255\n";
    let mut binary = header("binary", "x y z", "4 4 4", "F F F", "1 1 1", 2).into_bytes();
    for v in [1.0f32, 2.0, 0.5, -7.5, 3.25, -1.0] {
        binary.extend_from_slice(&v.to_le_bytes());
    }
    let mut doubles = header("binary", "x y z", "8 8 8", "F F F", "1 1 1", 1).into_bytes();
    for v in [4.0f64, -2.0, 1.0] {
        doubles.extend_from_slice(&v.to_le_bytes());
    }
    let compressed = header("binary_compressed", "x y z", "4 4 4", "F F F", "1 1 1", 1)
        .into_bytes()
        .into_iter()
        .chain([8, 0, 0, 0, 12, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8])
        .collect();
    vec![ascii.into_bytes(), binary, doubles, compressed]
}

fn run_kitti_bin(bytes: &[u8], _: &Scratch) -> bool {
    drive::scan::parse_kitti_bin(bytes, Path::new("fuzz.bin")).is_ok()
}

fn seeds_kitti_bin() -> Vec<Vec<u8>> {
    let points = [
        [5.0f32, 1.0, -1.7, 0.1],
        [12.5, -3.0, 0.4, 0.9],
        [f32::NAN, 0.0, 0.0, 0.0],
    ];
    vec![
        points
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
    ]
}

// ---------------------------------------------------------------------------------------------
// Maps

fn run_map(bytes: &[u8], _: &Scratch) -> bool {
    let Ok(loaded) = geodata::load_map_from_bytes(bytes, &LoadOptions::default()) else {
        return false;
    };
    // Rasterising is where a hostile extent or polygon would bite: build the index and fill one
    // window at the origin, as the first frame of a run does.
    let raster = ContextRaster::new(&loaded.map);
    let window = CellWindow {
        first_col: -32,
        first_row: -32,
        width: 64,
        height: 64,
        cell_size_m: 0.5,
    };
    let mut out = vec![MapContext::Unknown; window.len()];
    raster.fill(&window, &mut out);
    true
}

const TINY_OSM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6" generator="evigrid-fuzz">
  <bounds minlat="60.0" minlon="25.0" maxlat="60.001" maxlon="25.002"/>
  <node id="1" lat="60.0002" lon="25.0002"/>
  <node id="2" lat="60.0002" lon="25.0006"/>
  <node id="3" lat="60.0005" lon="25.0006"/>
  <node id="4" lat="60.0005" lon="25.0002"/>
  <node id="5" lat="60.0001" lon="25.0000"/>
  <node id="6" lat="60.0001" lon="25.0020"/>
  <way id="10">
    <nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
    <tag k="building" v="yes"/>
  </way>
  <way id="11">
    <nd ref="5"/><nd ref="6"/>
    <tag k="highway" v="residential"/><tag k="lanes" v="2"/>
  </way>
  <relation id="20">
    <member type="way" ref="10" role="outer"/>
    <tag k="type" v="multipolygon"/><tag k="building" v="yes"/>
  </relation>
</osm>
"#;

const TINY_GEOJSON: &str = r#"{"type":"FeatureCollection","features":[
 {"type":"Feature","properties":{"building":"yes"},"geometry":{"type":"Polygon","coordinates":
  [[[25.0002,60.0002],[25.0006,60.0002],[25.0006,60.0005],[25.0002,60.0005],[25.0002,60.0002]]]}},
 {"type":"Feature","properties":{"highway":"primary","width":"7"},"geometry":{"type":"LineString",
  "coordinates":[[25.0,60.0001],[25.002,60.0001]]}},
 {"type":"Feature","properties":{"area:highway":"yes"},"geometry":{"type":"MultiPolygon",
  "coordinates":[[[[25.0,60.0],[25.001,60.0],[25.001,60.00005],[25.0,60.0]]]]}}
]}
"#;

fn seeds_map() -> Vec<Vec<u8>> {
    vec![TINY_OSM.into(), TINY_GEOJSON.into()]
}

// ---------------------------------------------------------------------------------------------
// Poses

fn run_poses(bytes: &[u8], scratch: &Scratch) -> bool {
    let Some(path) = scratch.file("poses.txt", bytes) else {
        return false;
    };
    let times = [0.0, 0.1, 0.2];
    let kitti = KittiOdometryContext {
        times: &times,
        cam0_from_velo: nalgebra::Isometry3::identity(),
    };
    let projection = |lat: f64, lon: f64| (lon * 1000.0, lat * 1000.0);
    let detected = PoseFormat::detect(&path).ok();
    let track = poses::read_pose_track(&path, None, Some(&kitti), Some(&projection));
    // Every reader, not only the detected one: a file that looks like one format is fed to the
    // others too.
    let _ = poses::read_tum(&path);
    let _ = poses::read_evigrid(&path);
    let times_ok = poses::read_kitti_times(&path).is_ok();
    if let Ok(track) = &track {
        // Interpolation at and past the ends of whatever was accepted.
        let (first, last) = track.span();
        for t in [first, (first + last) / 2.0, last, last + 1.0, f64::NAN] {
            let _ = track.at(t);
        }
    }
    (detected.is_some() && track.is_ok()) || times_ok
}

fn seeds_poses() -> Vec<Vec<u8>> {
    vec![
        b"# evigrid poses\n0.0 10 20 0 0 0 0.1\n0.1 10.8 20.1 0 0.001 0 0.12\n0.2 11.6 20.2 0 0 0 0.14\n"
            .to_vec(),
        b"# frame: wgs84\n0.0 60.17 24.94 20 0 0 1.5\n0.1 60.17001 24.94002 20 0 0 1.5\n".to_vec(),
        b"0.0 1 2 3 0 0 0 1\n0.1 1.5 2 3 0 0 0.0998 0.995\n0.2 2 2 3 0 0 0.1987 0.9801\n".to_vec(),
        b"1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0.8\n0.995 0 0.0998 0 0 1 0 0 -0.0998 0 0.995 1.6\n"
            .to_vec(),
        b"0.0\n0.103\n0.207\n".to_vec(),
    ]
}

// ---------------------------------------------------------------------------------------------
// Odometry and its outputs

fn run_odometry(bytes: &[u8], scratch: &Scratch) -> bool {
    let scan = drive::scan::parse_pcd(bytes, Path::new("fuzz.pcd"))
        .or_else(|_| drive::scan::parse_kitti_bin(bytes, Path::new("fuzz.bin")));
    let Ok(scan) = scan else {
        return false;
    };
    let Ok(mut odometry) = odometry::Odometry::new(odometry::OdometryParams::default()) else {
        return false;
    };
    // The same scan three times, the third shifted as if the sensor moved.
    let shifted: Vec<[f32; 3]> = scan
        .points_in_sensor
        .iter()
        .map(|p| [p[0] - 0.5, p[1], p[2]])
        .collect();
    let mut times = Vec::new();
    for (k, points) in [&scan.points_in_sensor, &scan.points_in_sensor, &shifted]
        .into_iter()
        .enumerate()
    {
        let time = 0.1 * k as f64;
        if odometry.register(points, time).is_ok() {
            times.push(time);
        }
    }
    refine_three_scans(&[&scan.points_in_sensor, &scan.points_in_sensor, &shifted]);
    let Ok(track) = poses::PoseTrack::new(times, odometry.poses().to_vec()) else {
        return false;
    };
    // What `evigrid odometry` writes must read back (or be refused with a reason, never panic).
    let mut tum = Vec::new();
    let mut kitti = Vec::new();
    let written = poses::write_tum(&mut tum, &track).is_ok()
        && poses::write_kitti_odometry(&mut kitti, &track, &nalgebra::Isometry3::identity())
            .is_ok();
    if let Some(path) = scratch.file("odometry.tum", &tum) {
        let _ = poses::read_tum(&path);
    }
    if let Some(path) = scratch.file("odometry.kitti", &kitti) {
        let _ = poses::read_kitti_odometry(&path, track.times(), &nalgebra::Isometry3::identity());
    }
    written
}

/// The pose refinement over the same scans, with given poses that follow the shift: the third
/// scan starts ICP from the constant-velocity prediction of the first two. Whatever the scans,
/// the pose it returns is finite (a NaN pose would poison every grid after it).
fn refine_three_scans(scans: &[&Vec<[f32; 3]>]) {
    let Ok(mut refiner) = odometry::PoseRefiner::new(odometry::RefineParams::default()) else {
        return;
    };
    for (k, points) in scans.iter().enumerate() {
        let time = 0.1 * k as f64;
        let prior = nalgebra::Isometry3::translation(0.25 * k as f64, 0.0, 0.0);
        let refined = refiner.refine_and_insert(points, &prior, time);
        let pose = refined.world_from_sensor;
        assert!(
            pose.translation.vector.iter().all(|v| v.is_finite())
                && pose.rotation.coords.iter().all(|v| v.is_finite()),
            "the refinement returned a non-finite pose for scan {k}"
        );
    }
}

fn seeds_odometry() -> Vec<Vec<u8>> {
    // A corner of two walls and a floor, 0.5 m apart: enough points to start the map.
    let mut text = String::new();
    let mut n = 0;
    for i in 0..12 {
        for j in 0..6 {
            let (a, b) = (f64::from(i) * 0.5, f64::from(j) * 0.5);
            for [x, y, z] in [
                [8.0, a - 3.0, b - 1.5],
                [a + 2.0, 6.0, b - 1.5],
                [a + 2.0, b - 1.0, -1.7],
            ] {
                text.push_str(&format!("{x} {y} {z}\n"));
                n += 1;
            }
        }
    }
    let pcd = format!(
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n\
         WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA ascii\n{text}"
    );
    vec![pcd.into_bytes()]
}

// ---------------------------------------------------------------------------------------------
// ROS 2 recordings

fn run_bag(bytes: &[u8], scratch: &Scratch) -> bool {
    let Some(path) = scratch.file("fuzz.mcap", bytes) else {
        return false;
    };
    let Ok(bag) = drive::BagDrive::open(&path, &drive::BagOptions::default()) else {
        return false;
    };
    let projection = |lat: f64, lon: f64| (lon * 1000.0, lat * 1000.0);
    let _ = bag.poses().track(&projection);
    if let Ok(scans) = bag.scans() {
        for scan in scans.take(3) {
            let _ = scan;
        }
    }
    true
}

fn seeds_bag() -> Vec<Vec<u8>> {
    vec![include_bytes!("../../drive/tests/fixtures/kitti-0013.mcap").to_vec()]
}

// ---------------------------------------------------------------------------------------------
// KITTI raw text files

fn run_kitti_raw_text(bytes: &[u8], scratch: &Scratch) -> bool {
    let text = String::from_utf8_lossy(bytes);
    let path = Path::new("fuzz.txt");
    let mut accepted = false;
    for (i, line) in text.lines().enumerate() {
        accepted |= drive::oxts::parse_oxts_line(path, i + 1, line).is_ok();
        accepted |= drive::timestamp::parse_timestamp(line).is_ok();
    }
    if let Some(file) = scratch.file("kitti.txt", bytes) {
        accepted |= drive::calib::read_rigid_calib(&file).is_ok();
        accepted |= drive::calib::read_odometry_cam0_from_velo(&file).is_ok();
        accepted |= drive::timestamp::read_timestamps(&file).is_ok();
        accepted |= drive::oxts::read_oxts_packet(&file).is_ok();
    }
    accepted
}

fn seeds_kitti_raw_text() -> Vec<Vec<u8>> {
    let oxts: Vec<String> = (0..30)
        .map(|k| match k {
            0 => "49.0123456789".to_string(),
            1 => "8.4321".to_string(),
            2 => "112.5".to_string(),
            25..=29 => "4".to_string(),
            _ => format!("{:.6}", 0.01 * k as f64),
        })
        .collect();
    vec![
        (oxts.join(" ") + "\n").into_bytes(),
        b"calib_time: 01-Jan-2020 00:00:00\nR: 1 0 0 0 1 0 0 0 1\nT: -0.8 0.3 -0.8\n".to_vec(),
        b"P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 0 -1 0 0 0 0 -1 -0.08 1 0 0 -0.27\n".to_vec(),
        b"2011-09-26 13:10:59.442711794\n2011-09-26 13:10:59.546276717\n".to_vec(),
    ]
}

// ---------------------------------------------------------------------------------------------
// Parameters and scenarios

/// Windows up to this many cells are actually built by the params target; larger valid ones
/// are only validated (building them would measure the allocator, not the parser).
const MAX_BUILT_CELLS: usize = 1 << 16;

fn run_params(bytes: &[u8], _: &Scratch) -> bool {
    let Ok(text) = std::str::from_utf8(bytes) else {
        return false;
    };
    let Ok(params) = evigrid::Params::from_toml_str(text) else {
        return false;
    };
    let cells = params
        .window
        .width_cells
        .checked_mul(params.window.height_cells);
    if cells.is_some_and(|c| c <= MAX_BUILT_CELLS) {
        let _ = evigrid::Pipeline::new(params, None);
    }
    true
}

fn seeds_params() -> Vec<Vec<u8>> {
    let defaults = evigrid::Params::default()
        .to_toml_string()
        .unwrap_or_default();
    vec![
        defaults.into_bytes(),
        b"[grid]\ncell_size_m = 0.5\n[window]\nwidth_cells = 64\nheight_cells = 48\n".to_vec(),
        b"[sensor]\nground_model = \"local\"\n[sensor.ground]\n".to_vec(),
    ]
}

fn run_scenario(bytes: &[u8], _: &Scratch) -> bool {
    std::str::from_utf8(bytes).is_ok_and(|text| sim::Scenario::from_toml(text).is_ok())
}

fn seeds_scenario() -> Vec<Vec<u8>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios");
    let mut seeds: Vec<Vec<u8>> = std::fs::read_dir(&dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|entry| entry.path())
        .filter(|path| path.extension().is_some_and(|e| e == "toml"))
        .filter_map(|path| std::fs::read(path).ok())
        .collect();
    seeds.sort();
    seeds
}
