//! The cases on real data: `sensor`, `prior` and `frame`.
//!
//! - `sensor`: the SensorGrid of a real 120k-point HDL-64 scan (ground split included) in the
//!   window;
//! - `prior`: the GISGrid cells that enter the window when it moves 1 m diagonally (10 m/s at the
//!   sensor's 10 Hz), rasterised from a real OSM map;
//! - `frame`: the whole per-frame pipeline (window move, prior, sensor grid, step, decision) with
//!   the vehicle driving 1 m per frame across the map;
//! - `ground`: the local ground segmentation (crate `ground`, the `local` ground model's work) of
//!   the same scan, on its own;
//! - `odometry`: the lidar odometry registering the next of a sequence of consecutive scans (a
//!   real drive: each round one more scan, so the local map and the motion are real).

use evigrid::{
    GisGrid, IsometryMatrix3, MapPrior, Params, Pipeline, PoseExt, SensorGrid, SensorModel, Window,
};
use geodata::ContextRaster;
use std::path::PathBuf;

/// Height of the KITTI HDL-64 above the road, metres (Geiger et al. 2013, set-up figure).
const KITTI_SENSOR_HEIGHT_M: f64 = 1.73;
/// Distance driven per frame: 10 m/s at 10 Hz.
const STEP_PER_FRAME_M: f64 = 1.0;

/// Files of the real-data cases.
#[derive(Clone, Debug)]
pub struct RealInputs {
    /// A lidar scan (PCD or KITTI `.bin`), in the sensor frame.
    pub scan: PathBuf,
    /// A map any of geodata's readers takes.
    pub map: PathBuf,
    /// Consecutive scans of one drive, 0.1 s apart, for the `odometry` case (skipped when
    /// empty; at least two are needed).
    pub odometry_scans: Vec<PathBuf>,
}

/// Why the real inputs could not be prepared.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RealError {
    /// The scan could not be read.
    #[error(transparent)]
    Scan(#[from] drive::ScanError),
    /// The map could not be read.
    #[error(transparent)]
    Map(#[from] geodata::MapError),
    /// The window or parameters are invalid for this size.
    #[error(transparent)]
    Pipeline(#[from] evigrid::PipelineError),
    /// The ground segmentation's parameters are invalid.
    #[error(transparent)]
    Ground(#[from] ground::GroundParamsError),
    /// The odometry refused a scan or its parameters.
    #[error(transparent)]
    Odometry(#[from] odometry::OdometryError),
}

/// Prepared state of the real-data cases for one window size.
pub struct RealCases {
    points: Vec<[f32; 3]>,
    params: Params,
    raster: ContextRaster,
    sensor_model: SensorModel,
    window: Window,
    sensor_grid: SensorGrid,
    gis: GisGrid,
    prior: MapPrior,
    step_sensor: SensorGrid,
    step_gis: GisGrid,
    pipelines: [Pipeline; 2],
    /// Frames driven so far, per pipeline.
    frames: [u32; 2],
    /// Direction of the next `prior` move: ±1.
    prior_direction: i64,
    /// The local ground segmentation of the `ground` case; it takes the scan's points as they
    /// are (a level sensor's own frame is its levelled frame).
    segmenter: ground::GroundSegmenter,
    /// The `odometry` case's scans, in order, and the odometry registering them.
    odometry_scans: Vec<Vec<[f32; 3]>>,
    odometry: Option<odometry::Odometry>,
    /// Scans registered so far by `odometry`.
    registered: usize,
}

impl RealCases {
    /// Loads the scan and the map, and places a `size × size` window of `cell_size_m` cells at
    /// the map's centre.
    ///
    /// # Errors
    /// An unreadable scan or map, or an invalid window.
    pub fn new(inputs: &RealInputs, size: usize, cell_size_m: f64) -> Result<Self, RealError> {
        let scan = drive::read_scan(&inputs.scan)?;
        let loaded = geodata::load_map(&inputs.map, &geodata::LoadOptions::default())?;
        let raster = ContextRaster::new(&loaded.map);
        let mut params = Params::default();
        params.grid.cell_size_m = cell_size_m;
        params.window.width_cells = size;
        params.window.height_cells = size;
        // `frame` replays one scan at moving poses, which a pose refinement would refuse every
        // frame after a full registration; what a refinement costs is the registration of
        // consecutive real scans that the `odometry` case times.
        params.localisation.refinement = evigrid::PoseRefinement::None;
        let mut window =
            Window::new(size, size, cell_size_m).map_err(evigrid::PipelineError::from)?;
        let _ = window.recentre(0.0, 0.0);
        let mut gis = GisGrid::new(size, size);
        let mut prior = MapPrior::new(Some(raster.clone()));
        prior.fill_window(&window, &mut gis);
        let pose = IsometryMatrix3::from_xyz_rpy(0.0, 0.0, KITTI_SENSOR_HEIGHT_M, 0.0, 0.0, 0.0);
        let mut sensor_model = SensorModel::new(params.sensor.clone());
        let mut step_sensor = SensorGrid::new(size, size);
        sensor_model.build(&scan.points_in_sensor, &pose, &window, &mut step_sensor);
        let pipelines = [
            Pipeline::new(params.clone(), Some(raster.clone()))?,
            Pipeline::new(params.clone(), Some(raster.clone()))?,
        ];
        let segmenter = ground::GroundSegmenter::new(params.sensor.ground_params())?;
        let odometry_scans = if inputs.odometry_scans.len() >= 2 {
            inputs
                .odometry_scans
                .iter()
                .map(|p| drive::read_scan(p).map(|s| s.points_in_sensor))
                .collect::<Result<Vec<_>, _>>()?
        } else {
            Vec::new()
        };
        Ok(RealCases {
            segmenter,
            odometry_scans,
            odometry: None,
            registered: 0,
            points: scan.points_in_sensor,
            sensor_model,
            params,
            step_sensor,
            step_gis: gis.clone(),
            raster,
            window,
            sensor_grid: SensorGrid::new(size, size),
            gis,
            prior,
            pipelines,
            frames: [0; 2],
            prior_direction: 1,
        })
    }

    /// The SensorGrid of the scan with the window at the map's centre (before any timed case).
    pub fn step_sensor_grid(&self) -> &SensorGrid {
        &self.step_sensor
    }

    /// The GISGrid of the window at the map's centre (before any timed case).
    pub fn step_gis_grid(&self) -> &GisGrid {
        &self.step_gis
    }

    /// Points in the scan.
    pub fn scan_points(&self) -> usize {
        self.points.len()
    }

    /// Polygons in the map's rasteriser.
    pub fn map_polygons(&self) -> usize {
        self.raster.polygon_count()
    }

    /// Runs each real case once; returns (case, seconds).
    pub fn round(
        &mut self,
        one_thread: &rayon::ThreadPool,
        threads: usize,
    ) -> Result<Vec<(String, f64)>, RealError> {
        let pose = IsometryMatrix3::from_xyz_rpy(0.0, 0.0, KITTI_SENSOR_HEIGHT_M, 0.0, 0.0, 0.0);
        let (model, window, grid) = (&mut self.sensor_model, &self.window, &mut self.sensor_grid);
        let points = &self.points;
        let sensor =
            one_thread.install(|| crate::time(|| model.build(points, &pose, window, grid)));

        let shift = 5 * self.prior_direction;
        self.prior_direction = -self.prior_direction;
        let (prior, gis) = (&mut self.prior, &mut self.gis);
        let window = &mut self.window;
        let prior_s = one_thread.install(|| {
            crate::time(|| {
                let entered =
                    window.move_to(window.first_col() + shift, window.first_row() + shift);
                prior.fill_entered(window, &entered, gis);
            })
        });

        let frame_one = one_thread.install(|| self.frame(0))?;
        crate::wake_threads();
        let frame_all = self.frame(1)?;
        let (segmenter, points) = (&mut self.segmenter, &self.points);
        let ground_s = one_thread.install(|| {
            crate::time(|| {
                segmenter.segment(points);
            })
        });
        let mut times = vec![
            ("sensor@1".into(), sensor),
            ("prior@1".into(), prior_s),
            ("sensor+prior@1".into(), sensor + prior_s),
            ("frame@1".into(), frame_one),
            (format!("frame@{threads}"), frame_all),
            ("ground@1".into(), ground_s),
        ];
        if let Some(seconds) = one_thread.install(|| self.register_next())? {
            times.push(("odometry@1".into(), seconds));
        }
        Ok(times)
    }

    /// Times the registration of the next scan of the sequence; at its end the odometry starts
    /// again, its first scan registered untimed (the first scan only seeds the map).
    fn register_next(&mut self) -> Result<Option<f64>, RealError> {
        let n = self.odometry_scans.len();
        if n < 2 {
            return Ok(None);
        }
        if self.odometry.is_none() || self.registered >= n {
            let mut fresh = odometry::Odometry::new(odometry::OdometryParams::default())?;
            fresh.register(&self.odometry_scans[0], 0.0)?;
            self.odometry = Some(fresh);
            self.registered = 1;
        }
        let k = self.registered;
        let (Some(odometry), Some(points)) = (&mut self.odometry, self.odometry_scans.get(k))
        else {
            return Ok(None);
        };
        let start = std::time::Instant::now();
        odometry.register(points, k as f64 * 0.1)?;
        let seconds = start.elapsed().as_secs_f64();
        self.registered += 1;
        Ok(Some(seconds))
    }

    /// Times one frame of pipeline `which`, the vehicle 1 m further along a diagonal each frame
    /// and back after 40 m, so that it stays on the map.
    fn frame(&mut self, which: usize) -> Result<f64, RealError> {
        let frame = self.frames[which];
        self.frames[which] += 1;
        let along = f64::from(frame % 40) * STEP_PER_FRAME_M;
        let pose =
            IsometryMatrix3::from_xyz_rpy(along, along, KITTI_SENSOR_HEIGHT_M, 0.0, 0.0, 0.785);
        let time_s = f64::from(frame) * 0.1;
        let pipeline = &mut self.pipelines[which];
        let points = &self.points;
        let start = std::time::Instant::now();
        pipeline
            .process(points, &pose, time_s)
            .map_err(RealError::Pipeline)?;
        Ok(start.elapsed().as_secs_f64())
    }

    /// The parameters of the real-data cases.
    pub fn params(&self) -> &Params {
        &self.params
    }
}
