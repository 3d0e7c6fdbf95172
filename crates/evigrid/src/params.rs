//! Every parameter of the method in one structure, read from and written to TOML (SPEC §7).
//!
//! A TOML file may set any subset of the parameters: the rest keep their defaults. Unknown keys
//! are rejected (a misspelt key would otherwise be silently ignored), and [`Params::validate`]
//! rejects out-of-range values with a [`ParamsError`] naming the parameter by its TOML path.
//!
//! ```
//! use evigrid::Params;
//!
//! let params = Params::from_toml_str(
//!     "[fusion]\ndiscount_per_second = 0.2\n[map]\nbeta_road = 0.6\n",
//! )?;
//! assert_eq!(params.map.beta_road, 0.6);
//! assert_eq!(params.fusion.discount_per_second.moving, 0.2);
//! assert_eq!(params.sensor.mu_free, 0.7); // default
//! // Printed with the results it produced, and read back unchanged.
//! assert_eq!(Params::from_toml_str(&params.to_toml_string()?)?, params);
//! # Ok::<(), evigrid::ParamsError>(())
//! ```

use serde::{Deserialize, Deserializer, Serialize};

/// Why a parameter set was rejected.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ParamsError {
    /// A parameter of the local ground model is out of range (named by the ground crate).
    #[error("sensor.{0}")]
    Ground(#[from] ground::GroundParamsError),
    /// A window whose grids would not fit the memory budget (or whose cell count overflows).
    #[error(
        "window.width_cells x window.height_cells = {width} x {height}: the grids would need \
         {needed}, over the {budget_mib} MiB memory budget (at most {max_cells} cells, \
         e.g. {max_side} x {max_side})"
    )]
    WindowTooLarge {
        /// Requested width, cells.
        width: usize,
        /// Requested height, cells.
        height: usize,
        /// Memory the window's grids would take, as printed (`16 EiB or more` on overflow).
        needed: String,
        /// [`MEMORY_BUDGET_BYTES`] in MiB.
        budget_mib: u64,
        /// Most cells the budget allows.
        max_cells: u64,
        /// Side of the largest square window the budget allows.
        max_side: u64,
    },
    /// A mass, confidence, rate, step or threshold outside `[0, 1]` (or not a number).
    #[error("{name} = {value} is outside [0, 1]")]
    OutOfUnitRange {
        /// TOML path of the parameter, e.g. `map.beta_road`.
        name: &'static str,
        /// The rejected value.
        value: f64,
    },
    /// A length that must be strictly positive and finite.
    #[error("{name} = {value} must be positive and finite")]
    NotPositive {
        /// TOML path of the parameter, e.g. `grid.cell_size_m`.
        name: &'static str,
        /// The rejected value.
        value: f64,
    },
    /// Two parameters that must be ordered are not.
    #[error("{low_name} = {low} must be below {high_name} = {high}")]
    Misordered {
        /// TOML path of the parameter that must be the smaller.
        low_name: &'static str,
        /// Its value.
        low: f64,
        /// TOML path of the parameter that must be the larger.
        high_name: &'static str,
        /// Its value.
        high: f64,
    },
    /// A parameter that is not a number (`nan` in TOML), wherever it sits, even in a section
    /// whose value another key overrides.
    #[error("{name} = nan: every parameter must be a number")]
    NotANumber {
        /// TOML path of the parameter, e.g. `sensor.ground.min_range_m`.
        name: String,
    },
    /// A length below its physical lower bound.
    #[error("{name} = {value:e} is below {min}, the smallest value that makes sense")]
    BelowMinimum {
        /// TOML path of the parameter, e.g. `grid.cell_size_m`.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// The lower bound.
        min: f64,
    },
    /// A window without cells.
    #[error("window.width_cells = {width}, window.height_cells = {height}: the window is empty")]
    EmptyWindow {
        /// Requested width, cells.
        width: usize,
        /// Requested height, cells.
        height: usize,
    },
    /// The text is not TOML, has an unknown key or a value of the wrong type.
    #[error("{message}")]
    Parse {
        /// The TOML reader's message (it names the key and the line).
        message: String,
    },
    /// The parameters could not be written as TOML (does not happen for valid parameters).
    #[error("cannot write parameters as TOML: {message}")]
    Write {
        /// The TOML writer's message.
        message: String,
    },
}

/// All parameters of evigrid, one section per stage (SPEC §7).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Cell geometry.
    pub grid: GridParams,
    /// Size of the live window that follows the vehicle.
    pub window: WindowParams,
    /// Sensor model (SPEC §3).
    pub sensor: SensorParams,
    /// Map prior, the GISGrid (SPEC §4).
    pub map: MapParams,
    /// Discounting and fusion (SPEC §5 steps 3-4).
    pub fusion: FusionParams,
    /// Occupancy accumulator ζ (SPEC §5 step 5).
    pub accumulator: AccumulatorParams,
    /// Decision (SPEC §6).
    pub decision: DecisionParams,
    /// Motion evidence of the `evigrid` fusion variant (`docs/motion.md`; not in SPEC, unused
    /// by the paper's method).
    pub motion: MotionParams,
    /// Pose refinement in the front end (`docs/motion.md`, "Pose refinement"; not in SPEC).
    pub localisation: LocalisationParams,
}

impl Params {
    /// Reads parameters from TOML text in the SPEC §7 layout and validates them.
    ///
    /// Any subset of the keys may be given; the others keep their defaults.
    ///
    /// # Errors
    /// [`ParamsError::Parse`] for malformed TOML, an unknown key or a value of the wrong type;
    /// the range errors of [`Params::validate`].
    pub fn from_toml_str(text: &str) -> Result<Self, ParamsError> {
        let params: Params = toml::from_str(text).map_err(|e| ParamsError::Parse {
            message: e.to_string().trim().replace('\n', " "),
        })?;
        params.validate()?;
        Ok(params)
    }

    /// Writes every parameter (defaults included) as TOML in the SPEC §7 layout, so that a result
    /// can be printed with the parameters that produced it and reproduced from them.
    ///
    /// # Errors
    /// [`ParamsError::Write`] if the TOML writer fails (it does not for finite values).
    pub fn to_toml_string(&self) -> Result<String, ParamsError> {
        toml::to_string(self).map_err(|e| ParamsError::Write {
            message: e.to_string(),
        })
    }

    /// Checks every parameter's range.
    ///
    /// # Errors
    /// The first offending parameter, by its TOML path: [`ParamsError::OutOfUnitRange`] for
    /// μ, β, α, δ, γ and the unknown threshold outside `[0, 1]`; [`ParamsError::NotPositive`] for
    /// a non-positive cell size, sensor length or `sensor.min_neighbourhood_returns`;
    /// [`ParamsError::EmptyWindow`]; [`ParamsError::Misordered`] for a count above its largest
    /// value or an empty obstacle height band.
    pub fn validate(&self) -> Result<(), ParamsError> {
        if let Some(name) = first_nan(self) {
            return Err(ParamsError::NotANumber { name });
        }
        positive("grid.cell_size_m", self.grid.cell_size_m)?;
        if self.grid.cell_size_m < MIN_CELL_SIZE_M {
            return Err(ParamsError::BelowMinimum {
                name: "grid.cell_size_m",
                value: self.grid.cell_size_m,
                min: MIN_CELL_SIZE_M,
            });
        }
        if self.window.width_cells == 0 || self.window.height_cells == 0 {
            return Err(ParamsError::EmptyWindow {
                width: self.window.width_cells,
                height: self.window.height_cells,
            });
        }
        check_window_size(self.window.width_cells, self.window.height_cells)?;
        let s = &self.sensor;
        unit("sensor.mu_free", s.mu_free)?;
        unit("sensor.mu_occupied", s.mu_occupied)?;
        positive("sensor.angular_resolution_deg", s.angular_resolution_deg)?;
        positive("sensor.max_range_m", s.max_range_m)?;
        positive("sensor.ground_band_m", s.ground_band_m)?;
        positive(
            "sensor.min_neighbourhood_returns",
            f64::from(s.min_neighbourhood_returns),
        )?;
        // Above nine cells' worth of 16-bit counts no cell could ever be kept.
        at_most(
            "sensor.min_neighbourhood_returns",
            s.min_neighbourhood_returns as usize,
            MAX_NEIGHBOURHOOD_RETURNS,
        )?;
        if !(s.min_range_m >= 0.0 && s.min_range_m < s.max_range_m) {
            return Err(ParamsError::Misordered {
                low_name: "sensor.min_range_m",
                low: s.min_range_m,
                high_name: "sensor.max_range_m",
                high: s.max_range_m,
            });
        }
        finite("sensor.min_obstacle_height_m", s.min_obstacle_height_m)?;
        finite("sensor.max_obstacle_height_m", s.max_obstacle_height_m)?;
        if s.min_obstacle_height_m >= s.max_obstacle_height_m {
            return Err(ParamsError::Misordered {
                low_name: "sensor.min_obstacle_height_m",
                low: s.min_obstacle_height_m,
                high_name: "sensor.max_obstacle_height_m",
                high: s.max_obstacle_height_m,
            });
        }
        unit("map.beta_building", self.map.beta_building)?;
        unit("map.beta_road", self.map.beta_road)?;
        unit("map.beta_other", self.map.beta_other)?;
        let rates = &self.fusion.discount_per_second;
        unit("fusion.discount_per_second.F", rates.free)?;
        unit("fusion.discount_per_second.I", rates.mapped_infrastructure)?;
        unit(
            "fusion.discount_per_second.U",
            rates.unmapped_infrastructure,
        )?;
        unit("fusion.discount_per_second.S", rates.stopped)?;
        unit("fusion.discount_per_second.M", rates.moving)?;
        let a = &self.accumulator;
        unit("accumulator.delta_inc", a.delta_inc)?;
        unit("accumulator.delta_dec", a.delta_dec)?;
        unit("accumulator.gamma_occupied", a.gamma_occupied)?;
        unit("accumulator.gamma_conflict", a.gamma_conflict)?;
        unit(
            "decision.unknown_threshold",
            self.decision.unknown_threshold,
        )?;
        self.motion.validate()?;
        self.localisation.validate(&self.sensor)?;
        // Last: the sensor's own keys are named first when they are what is wrong.
        self.sensor.ground_params().validate()?;
        Ok(())
    }
}

/// Memory the grids of a window may take: the fusion's state of every cell must fit in RAM next
/// to the scan, the map and the outputs, on the laptops and vehicle computers evigrid runs on.
/// At [`WINDOW_BYTES_PER_CELL`] this allows about 8 million cells (2 837 × 2 837, 1.4 km at
/// 0.5 m); the real-time target is 1 000 × 1 000.
pub const MEMORY_BUDGET_BYTES: u64 = 1536 << 20;

/// Bytes every window cell costs across the pipeline's grids: the PerceptionGrid's 32 mass
/// planes, ζ and the two conflicts (f32), its seen flag, the SensorGrid's two masses, the
/// GISGrid context, the decision and the moving trace, plus room for the motion stage's
/// per-cell buffers (16 bytes today). A test holds it above what the pipeline allocates.
pub const WINDOW_BYTES_PER_CELL: u64 = 32 * 4 + 3 * 4 + 1 + 2 * 4 + 1 + 1 + 1 + 48;

/// Checks that a `width × height` window fits [`MEMORY_BUDGET_BYTES`] (with checked arithmetic:
/// a count that overflows is refused too). Used by [`Params::validate`] and by every tool that
/// sizes grids from user input.
///
/// # Errors
/// [`ParamsError::WindowTooLarge`].
pub fn check_window_size(width: usize, height: usize) -> Result<(), ParamsError> {
    let bytes = (width as u64)
        .checked_mul(height as u64)
        .and_then(|cells| cells.checked_mul(WINDOW_BYTES_PER_CELL));
    match bytes {
        Some(bytes) if bytes <= MEMORY_BUDGET_BYTES => Ok(()),
        _ => {
            let max_cells = MEMORY_BUDGET_BYTES / WINDOW_BYTES_PER_CELL;
            Err(ParamsError::WindowTooLarge {
                width,
                height,
                needed: bytes.map_or_else(
                    || "16 EiB or more".to_string(),
                    |b| format!("{} MiB", b.div_ceil(1 << 20)),
                ),
                budget_mib: MEMORY_BUDGET_BYTES >> 20,
                max_cells,
                max_side: max_cells.isqrt(),
            })
        }
    }
}

/// The smallest cell, metres: 1 cm, below a lidar's own range noise (a few centimetres), so a
/// smaller cell only splits one return's evidence between cells it cannot tell apart.
pub const MIN_CELL_SIZE_M: f64 = 0.01;

/// The TOML path of the first parameter that is NaN, if any, found in the serialised form so
/// that no key is forgotten (nor one that a later key overrides, as `[sensor.ground]`'s ranges).
fn first_nan(params: &Params) -> Option<String> {
    fn walk(value: &toml::Value, path: &str) -> Option<String> {
        match value {
            toml::Value::Float(x) if x.is_nan() => Some(path.to_string()),
            toml::Value::Table(table) => table.iter().find_map(|(key, value)| {
                let path = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                walk(value, &path)
            }),
            toml::Value::Array(items) => items
                .iter()
                .enumerate()
                .find_map(|(k, item)| walk(item, &format!("{path}[{k}]"))),
            _ => None,
        }
    }
    walk(&toml::Value::try_from(params).ok()?, "")
}

fn unit(name: &'static str, value: f64) -> Result<(), ParamsError> {
    // `contains` is false for NaN, so a NaN is rejected too.
    if (0.0..=1.0).contains(&value) {
        Ok(())
    } else {
        Err(ParamsError::OutOfUnitRange { name, value })
    }
}

fn positive(name: &'static str, value: f64) -> Result<(), ParamsError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(ParamsError::NotPositive { name, value })
    }
}

/// A finite value ≥ 0; a negative one, NaN or ∞ is reported as below the minimum 0.
fn non_negative(name: &'static str, value: f64) -> Result<(), ParamsError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ParamsError::BelowMinimum {
            name,
            value,
            min: 0.0,
        })
    }
}

/// The largest `sensor.min_neighbourhood_returns`: nine cells of 65,535 returns each.
const MAX_NEIGHBOURHOOD_RETURNS: usize = 9 * u16::MAX as usize;

/// A count above its largest value, reported as misordered against that value.
fn at_most(name: &'static str, value: usize, high: usize) -> Result<(), ParamsError> {
    if value <= high {
        Ok(())
    } else {
        Err(ParamsError::Misordered {
            low_name: name,
            low: value as f64,
            high_name: "its largest value",
            high: high as f64,
        })
    }
}

fn finite(name: &'static str, value: f64) -> Result<(), ParamsError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ParamsError::NotPositive { name, value })
    }
}

/// Cell geometry (SPEC §2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GridParams {
    /// Side of a square cell, metres. By default 0.5 m (paper IV-D).
    pub cell_size_m: f64,
}

impl Default for GridParams {
    fn default() -> Self {
        Self { cell_size_m: 0.5 }
    }
}

/// Size of the window of cells that follows the vehicle (SPEC §2). Memory is proportional to it
/// (about 150 bytes per cell for the three grids) and independent of the drive's length.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WindowParams {
    /// Number of columns (west to east). By default 320 cells, 160 m at 0.5 m cells: the useful
    /// range of a Velodyne HDL-64E on each side (provisional, to be tuned on the benchmark).
    pub width_cells: usize,
    /// Number of rows (south to north). By default 320 cells (provisional, as `width_cells`).
    pub height_cells: usize,
}

impl Default for WindowParams {
    fn default() -> Self {
        Self {
            width_cells: 320,
            height_cells: 320,
        }
    }
}

/// Sensor model: how one scan becomes a SensorGrid (SPEC §3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorParams {
    /// μ_F, the mass on {F} of a cell a ray crosses before its first obstacle. By default 0.7
    /// (paper IV-D; kept by the tuning on simulated drives over Helsinki and Kouvola, see
    /// docs/tuning.md).
    pub mu_free: f64,
    /// μ_O, the mass on {O} of a cell holding an obstacle return. By default 0.8 (paper IV-D; kept
    /// by the tuning on simulated drives over Helsinki and Kouvola, see docs/tuning.md).
    pub mu_occupied: f64,
    /// Width of an angular sector, degrees. By default 0.5°, about the angle of a 0.5 m cell
    /// seen from 57 m (provisional, to be tuned on the benchmark).
    pub angular_resolution_deg: f64,
    /// Lowest height above the ground of an obstacle point, metres. By default 0.3 m
    /// (provisional, to be tuned on the benchmark).
    pub min_obstacle_height_m: f64,
    /// Highest height above the ground of an obstacle point, metres: higher points (branches,
    /// bridges) do not block the way. By default 2.5 m (provisional, to be tuned on the benchmark).
    pub max_obstacle_height_m: f64,
    /// Fewest obstacle returns a cell and its eight neighbours must hold together for the cell
    /// to be occupied, with a 3-D ground model (`local` or `plane`; with `none`, a planar
    /// scanner's, every return counts as SPEC §3 says). Fewer are stray returns: dropped, and
    /// they do not stop the free space of their sector. By default 4: on KITTI 0013 half the
    /// occupied cells hold three returns or more on their own, and a surface continues into
    /// the cells around; a 2 m pole at 60 m gets four of a 64-beam lidar (0.4° between beams);
    /// while the HDL-64E's phantom returns in KITTI (top lasers, zero
    /// intensity, about 2 m up in mid-road 4–15 m ahead) come one to three together (README,
    /// "Stray returns"). 1 is the SPEC §3 rule; a 16-beam lidar may want 2 (its beams are 2°
    /// apart: a pedestrian at 60 m gets two or three returns).
    pub min_neighbourhood_returns: u32,
    /// Returns farther than this are ignored, metres. By default 60 m (provisional, to be tuned on
    /// the benchmark).
    pub max_range_m: f64,
    /// With a planar scanner (`ground_model = "none"`), the directions in which the scan met
    /// nothing within `max_range_m` are seen empty up to that range: a sector whose return lies
    /// beyond it, and a run of sectors without any return inside the scanner's field of view
    /// (a gap between sectors with returns, except the widest, which is where the scanner does
    /// not look; at least two sectors and three of the scan's mean ray spacings wide). These
    /// cells get no mass (SPEC §3 leaves them vacuous): only the motion stage's seen tests read
    /// them ([`crate::SensorGrid::clear_cells`]), so that a car sliding sideways 50 m off, with
    /// open road behind it, is seen to leave its cells. By default true (docs/motion.md,
    /// "Seen empty without a return"); false for a scanner whose rays go unanswered within range
    /// (dark or glossy surfaces), where a gap is not empty space.
    pub empty_without_return: bool,
    /// How returns are split into obstacle and ground points: `"local"` (3-D lidar: a local
    /// ground height per polar cell, `[sensor.ground]`), `"plane"` (3-D lidar: one ground plane
    /// per scan) or `"none"` (planar or multi-layer scanner: every return is an obstacle). By
    /// default `"local"`: on KITTI raw drive 0013 (frames 80–119) the plane called 37 % of a
    /// scan's points and 52 % of the observed cells obstacles (median over frames), the local
    /// model 27 % and 18 %, with the same ego-path figure (README, "Ground model").
    pub ground_model: GroundModel,
    /// Half-thickness of the ground band, metres: returns within it of the fitted plane are
    /// ground returns. By default 0.2 m (provisional: above the HDL-64E's range noise, below a
    /// kerb; to be tuned on the benchmark).
    pub ground_band_m: f64,
    /// Returns closer than this (horizontal distance from the sensor) are dropped, metres: the
    /// vehicle's own body and invalid zero-range returns. By default 2.0 m (provisional: a roof
    /// lidar on a car; 0 for a bumper-mounted scanner).
    pub min_range_m: f64,
    /// The local ground model of [`GroundModel::Local`] (`[sensor.ground]`). Its obstacle heights
    /// and ranges are not read: the sensor model hands it the four of this section, so that one
    /// key decides each.
    pub ground: ground::GroundParams,
}

impl SensorParams {
    /// The local ground model's parameters with this section's obstacle heights and ranges.
    pub fn ground_params(&self) -> ground::GroundParams {
        ground::GroundParams {
            min_obstacle_height_m: self.min_obstacle_height_m,
            max_obstacle_height_m: self.max_obstacle_height_m,
            min_range_m: self.min_range_m,
            max_range_m: self.max_range_m,
            ..self.ground.clone()
        }
    }
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            mu_free: 0.7,
            mu_occupied: 0.8,
            angular_resolution_deg: 0.5,
            min_obstacle_height_m: 0.3,
            max_obstacle_height_m: 2.5,
            min_neighbourhood_returns: 4,
            max_range_m: 60.0,
            empty_without_return: true,
            ground_model: GroundModel::Local,
            ground_band_m: 0.2,
            min_range_m: 2.0,
            ground: ground::GroundParams::default(),
        }
    }
}

/// How a scan's points are split into obstacle and ground points (SPEC §3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GroundModel {
    /// Planar or multi-layer scanner: every return is an obstacle; there are no ground returns.
    None,
    /// 3-D lidar: fit a ground plane to each scan; obstacles lie between the obstacle heights
    /// above it, ground returns within the ground band of it.
    Plane,
    /// 3-D lidar on real streets: a local ground height per polar cell, grown outward from the
    /// sensor with slope limits (crate `ground`, parameters in `[sensor.ground]`). Holds on
    /// slopes, crowned roads and kerbs where one plane per scan turns ground rings into
    /// obstacles. The default.
    #[default]
    Local,
}

/// Confidence in the map, per context (SPEC §4, eq 34-38).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MapParams {
    /// β_B, mass on {I} in a building cell. By default 0.9 (the paper gives none; kept by the
    /// tuning on simulated drives over Helsinki and Kouvola, which found the scores flat in
    /// it, see docs/tuning.md).
    pub beta_building: f64,
    /// β_R, mass on {F, S, M} in a road cell. By default 0.6 (tuned on simulated drives over
    /// Helsinki and Kouvola, see docs/tuning.md; 0.8 before tuning).
    pub beta_road: f64,
    /// β_T, mass on {F, U, S, M} in the intermediate space. By default 0.7 (kept by the tuning
    /// on simulated drives over Helsinki and Kouvola, see docs/tuning.md).
    pub beta_other: f64,
}

impl Default for MapParams {
    fn default() -> Self {
        Self {
            beta_building: 0.9,
            beta_road: 0.6,
            beta_other: 0.7,
        }
    }
}

/// How the previous PerceptionGrid is discounted before fusion (SPEC §5 step 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DiscountMode {
    /// One rate for every focal set (eq 13-14): the `set_rate` aggregate of the class rates, which
    /// is the rate itself when `discount_per_second` is a single number.
    Classical,
    /// Each focal set A ≠ Ω keeps 1 − α_A of its mass and gives the rest to Ω, α_A being the
    /// `set_rate` aggregate of the rates of the classes in A (Kurdej & Cherfaoui 2013).
    ClassRates,
    /// Contextual discounting with the singleton contexts {F}, …, {M} (Mercier, Quost & Denœux
    /// 2008): mass on A moves to supersets A ∪ {θ}, not to Ω.
    Mercier,
}

/// How `class_rates` derives the rate of a focal set from the rates of its classes.
///
/// The per-second rates are aggregated, then converted to the step's rate, so that the rate of
/// every set, not only of the singletons, composes exactly over time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SetRate {
    /// The smallest rate of the set's classes (optimistic: a set fades as slowly as its most
    /// lasting class).
    Min,
    /// The largest rate (conservative: anything that may be moving fades fast).
    Max,
    /// The mean of the classes' rates (proportional).
    Mean,
}

/// Where the residual conflict of the fusion goes (SPEC §5 step 4), and the mass that the
/// specialisation moves from {M} to ∅ (step 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResidualPolicy {
    /// Added to m(Ω), as Yager's rule: the paper's "roughly equivalent to Yager's rule".
    ToOmega,
    /// Stays on ∅ (open world, transferable belief model); m(∅) then accumulates.
    Keep,
    /// Removed, and the other masses rescaled to sum to 1, as Dempster's rule. If nothing is
    /// left to rescale, the cell falls back to `to_omega` (vacuous) and the event is counted.
    Normalise,
}

/// What a step does to a cell the scan did not observe (its SensorGrid is vacuous).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnobservedCells {
    /// SPEC §5 as written: every step runs on every cell, so an unobserved cell is discounted
    /// and fused again with the map prior (SG' = GG), and its accumulator and specialisation
    /// run.
    Fuse,
    /// Only step 3 (discounting): a scan says nothing about a cell it did not reach, and the
    /// map prior is not counted again as if it were new evidence. ζ keeps its value and the
    /// conflict masses are 0.
    DiscountOnly,
}

/// One discount rate per class of Ω_PG, per second, each in `[0, 1]`.
///
/// In TOML either a single number (every class) or a table `{ F = .., I = .., U = .., S = .., M = .. }`
/// in which missing classes keep their default.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClassRates {
    /// Rate of F, free space.
    #[serde(rename = "F")]
    pub free: f64,
    /// Rate of I, mapped infrastructure.
    #[serde(rename = "I")]
    pub mapped_infrastructure: f64,
    /// Rate of U, unmapped infrastructure.
    #[serde(rename = "U")]
    pub unmapped_infrastructure: f64,
    /// Rate of S, stopped objects.
    #[serde(rename = "S")]
    pub stopped: f64,
    /// Rate of M, moving objects.
    #[serde(rename = "M")]
    pub moving: f64,
}

impl ClassRates {
    /// The same rate for every class.
    pub fn uniform(rate: f64) -> Self {
        Self {
            free: rate,
            mapped_infrastructure: rate,
            unmapped_infrastructure: rate,
            stopped: rate,
            moving: rate,
        }
    }

    /// The rates in frame order F, I, U, S, M (bit 0 to bit 4).
    pub fn as_array(&self) -> [f64; 5] {
        [
            self.free,
            self.mapped_infrastructure,
            self.unmapped_infrastructure,
            self.stopped,
            self.moving,
        ]
    }
}

impl Default for ClassRates {
    /// Free space changes quickly (objects move in); buildings almost never; unmapped
    /// infrastructure rarely; a stopped object may leave; a moving object is gone within a second
    /// (90 % of its mass discounted per second, about 21 % per 10 Hz scan). By default F 0.5, I
    /// 0.05, U 0.2, S 0.3, M 0.9 per second (kept by the tuning on simulated drives over
    /// Helsinki and Kouvola, see docs/tuning.md).
    fn default() -> Self {
        Self {
            free: 0.5,
            mapped_infrastructure: 0.05,
            unmapped_infrastructure: 0.2,
            stopped: 0.3,
            moving: 0.9,
        }
    }
}

/// Accepts `discount_per_second = 0.2` as well as `discount_per_second = { M = 0.9, .. }`.
fn class_rates_from_number_or_table<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<ClassRates, D::Error> {
    struct Visitor;
    impl<'de> serde::de::Visitor<'de> for Visitor {
        type Value = ClassRates;

        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("a rate per second, or a table of rates per class F, I, U, S, M")
        }

        fn visit_f64<E: serde::de::Error>(self, rate: f64) -> Result<ClassRates, E> {
            Ok(ClassRates::uniform(rate))
        }

        fn visit_i64<E: serde::de::Error>(self, rate: i64) -> Result<ClassRates, E> {
            Ok(ClassRates::uniform(rate as f64))
        }

        fn visit_u64<E: serde::de::Error>(self, rate: u64) -> Result<ClassRates, E> {
            Ok(ClassRates::uniform(rate as f64))
        }

        fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<ClassRates, A::Error> {
            ClassRates::deserialize(serde::de::value::MapAccessDeserializer::new(map))
        }
    }
    deserializer.deserialize_any(Visitor)
}

/// Discounting and fusion (SPEC §5 steps 3-4, 6).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FusionParams {
    /// Discounting mode. By default `class_rates` (SPEC §5 step 3 decision).
    pub discount_mode: DiscountMode,
    /// Rate of a set from its classes' rates (`class_rates` and `classical`). By default `max`, so
    /// that every set that may hold a moving object fades at M's rate (provisional, to be tuned on
    /// the benchmark).
    pub set_rate: SetRate,
    /// Discount rate per second of each class, α_1s; a step of `dt` seconds applies
    /// α(dt) = 1 − (1 − α_1s)^dt. By default F 0.5, I 0.05, U 0.2, S 0.3, M 0.9 (kept by the tuning
    /// on simulated drives over Helsinki and Kouvola, see docs/tuning.md).
    #[serde(deserialize_with = "class_rates_from_number_or_table")]
    pub discount_per_second: ClassRates,
    /// Residual conflict policy. By default `to_omega` (SPEC §5 step 4 decision).
    pub residual: ResidualPolicy,
    /// What happens to cells the scan did not observe. By default `fuse` (SPEC §5).
    pub unobserved: UnobservedCells,
}

impl Default for FusionParams {
    fn default() -> Self {
        Self {
            discount_mode: DiscountMode::ClassRates,
            set_rate: SetRate::Max,
            discount_per_second: ClassRates::default(),
            residual: ResidualPolicy::ToOmega,
            unobserved: UnobservedCells::Fuse,
        }
    }
}

/// The occupancy accumulator ζ (eq 24-27).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AccumulatorParams {
    /// δ_inc, added to ζ when the cell is steadily occupied. By default 0.01: a hundred steadily
    /// occupied scans (10 s at 10 Hz) make ζ = 1 (tuned on simulated drives over Helsinki and
    /// Kouvola, see docs/tuning.md; 0.1 before tuning). A small ζ already tips {S, M} towards S in
    /// the decision, while a large one erases the {M} mass of slow or long moving objects.
    pub delta_inc: f64,
    /// δ_dec, removed from ζ on conflict. By default 0.3 (kept by the tuning on simulated
    /// drives over Helsinki and Kouvola, see docs/tuning.md).
    pub delta_dec: f64,
    /// γ_O, the m(O) a cell needs to count as occupied. By default 0.5 (kept by the tuning
    /// on simulated drives over Helsinki and Kouvola, see docs/tuning.md).
    pub gamma_occupied: f64,
    /// γ_∅, the conflict ∅_FO + ∅_OF above which ζ decreases. By default 0.2 (kept by the tuning
    /// on simulated drives over Helsinki and Kouvola, see docs/tuning.md).
    pub gamma_conflict: f64,
}

impl Default for AccumulatorParams {
    fn default() -> Self {
        Self {
            delta_inc: 0.01,
            delta_dec: 0.3,
            gamma_occupied: 0.5,
            gamma_conflict: 0.2,
        }
    }
}

/// Decision (SPEC §6).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DecisionParams {
    /// A cell with m(Ω) above this is `unknown`. By default 0.5 (SPEC §6).
    pub unknown_threshold: f64,
}

impl Default for DecisionParams {
    fn default() -> Self {
        Self {
            unknown_threshold: 0.5,
        }
    }
}

/// Motion evidence of the `evigrid` fusion variant: clusters of the scan's occupied cells,
/// registered against the last frames' occupied cells, filtered per track by a constant-velocity
/// Kalman filter, and turned into mass on {M} (moving) or Ω∖{M} (static) (`docs/motion.md`).
///
/// By default the values measured on the shipped scenarios (`docs/motion.md`, "Parameters").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MotionParams {
    /// Frames back a cluster is registered against, 1-8 (slow objects need several). By
    /// default 8.
    pub history_frames: usize,
    /// Whether the eight frames kept are thinned: the last four, the even-numbered ones up to
    /// eight frames back and every fourth up to sixteen back (1.3-1.6 s at 10 Hz instead of
    /// 0.8 s), so that a slow object's shift grows to whole cells (`docs/motion.md`, "A
    /// longer history for slow objects"). By default false.
    pub history_thinned: bool,
    /// Whether a return's cell of a cluster judged static (or stopped) that was seen free, and
    /// never held a return, in the frames kept takes moving evidence instead (`mu_moving`): an
    /// object that entered space seen empty beside a static one it is joined with (a walker
    /// beside a wall; `docs/motion.md`, "A newcomer beside a static object"). By default true,
    /// adopted on the validation drives (dynamic accuracy 0.7883 → 0.7905, moving IoU 0.5551 →
    /// 0.5546); false is the rule before.
    pub static_part_entered: bool,
    /// Largest shift searched, cells, in each axis (1-16). By default 6 (3 m at 0.5 m cells).
    pub search_radius_cells: usize,
    /// Fastest object, m/s: limits the shift searched against each past frame. By default 25.
    pub max_speed_mps: f64,
    /// A shift is a match when at least this fraction of the cluster's cells land on cells
    /// occupied in the past frame, `[0, 1]`. By default 0.5.
    pub match_fraction: f64,
    /// A non-zero shift is preferred to zero only if it matches this fraction of the cluster's
    /// cells more (at least one cell), `[0, 1]`. By default 0.15, chosen on the tuning drives
    /// (a crawling car sliding along its own length beats zero only by the cells at its ends;
    /// 0.25 before, `docs/motion.md`, "A car's corner, and the margin of a crawl").
    pub shift_margin_fraction: f64,
    /// The most cells that margin may ask for, ≥ 0 (0: no cap). A long object sliding along
    /// itself (a bus side-on) beats zero only by the cells at its ends, whose count does not
    /// grow with its length as the fraction's margin does. By default 2, chosen on the tuning
    /// drives (0: no cap, the behaviour before; `docs/motion.md`, "A bus sliding along itself:
    /// the margin's cap").
    pub shift_margin_max_cells: f64,
    /// Below this speed, m/s, a track counts as not moving. By default 0.5.
    pub min_speed_mps: f64,
    /// Standard deviation of a track's acceleration, m/s² (the filter's process noise). By
    /// default 3.
    pub accel_sigma_mps2: f64,
    /// Standard deviation of a registered shift, cells (quantisation and change of the visible
    /// face). By default 0.5.
    pub shift_sigma_cells: f64,
    /// A cluster joins the nearest track predicted within this distance, m. By default 2
    /// (1.5 won on the tuning drives of the new scenes, by 0.002 of moving IoU and DA, but
    /// split a long track of KITTI raw 0013 in two: `docs/motion.md`, "Parameters re-chosen
    /// on the new scenes").
    pub gate_m: f64,
    /// A track unseen for longer than this, s, is dropped. By default 1.
    pub max_coast_s: f64,
    /// Registrations a track needs before its cells get mass on {M} (a one-frame shift can be
    /// a cluster matched to another object's past), 1-8. By default 1.
    pub moving_after_measurements: usize,
    /// A track slower than `min_speed_mps` counts as static once the standard deviation of its
    /// speed, √(σx² + σy²), is below this, m/s. By default 1.
    pub static_sigma_mps: f64,
    /// Largest mass on {M} given to a moving track's cells, `[0, 1]`. By default 1,
    /// re-chosen on the 17 tuning drives of the new scenes and adopted on validation
    /// (`docs/motion.md`, "Parameters re-chosen on the new scenes"); 0.8 before.
    pub mu_moving: f64,
    /// Mass on Ω∖{M} given to a static track's cells, `[0, 1]`. By default 0.9.
    pub mu_static: f64,
    /// Distance, m, a track must have travelled while judged moving (its net displacement, so
    /// a static object's jitter does not add up) to count as a mobile object: once static
    /// again, its cells get mass `mu_static` on {S} (stopped) instead of Ω∖{M}. By default 2.
    pub mobile_after_travel_m: f64,
    /// Time, s, a track must have been judged moving, besides `mobile_after_travel_m`, before
    /// it counts as a mobile object (S once stopped): a short track that ends beside static
    /// cells leaves them static. By default 1.
    pub mobile_after_moving_s: f64,
    /// Frames a track must have been judged moving before it is reported in the moving-object
    /// list (`MotionStage::moving_objects`); below this, or without a measured velocity, or
    /// with an existence probability under 0.9, it is held back. By default 3.
    pub report_after_moving_frames: usize,
    /// Whether held-back objects are listed too, with `held_back: true`. By default false.
    pub report_held_back: bool,
    /// Frames a track must have been judged moving before its velocity is a prior of the
    /// registration of the cluster it predicts into (`docs/motion.md`, "The track's own
    /// prediction"): against a past frame where no shift beats zero clearly, the shift the
    /// track predicts (its velocity × the frame's span, give or take a cell) is taken when it
    /// explains the cluster at least as well as zero and its move is seen on as many cells as
    /// a clear shift's (`shift_margin_fraction`); zero explaining the cluster better where the
    /// predicted shift is at least `stop_evidence_cells` long is the evidence of a stop and
    /// ends the prior for that registration. By default 1, with `stop_evidence_cells` 1.5,
    /// chosen on the tuning drives among 1, 2, 3 and 5 and adopted on the validation drives
    /// (dynamic accuracy 0.802 → 0.810, moving IoU 0.535 → 0.534); 0 turns it off.
    pub prior_after_moving_frames: usize,
    /// How long, in cells, the shift a registration predicts for a newer past frame must be
    /// for zero explaining that frame better to count as the evidence of a stop (a shift off
    /// the line of the newer frames then ends the search on them; `docs/motion.md`, "The
    /// track's own prediction"), and for the prior of `prior_after_moving_frames` to be
    /// refuted. A shorter predicted shift is no evidence: a slow object's ends quantised to
    /// whole cells may read zero or one cell. By default 1.5, chosen on the tuning drives among
    /// 0.5, 1, 1.5 and 2 with `prior_after_moving_frames`; 0.5 is the rule before this key (any
    /// predicted shift that rounds to a cell); `> 0`.
    pub stop_evidence_cells: f64,
    /// Cells of the intermediate space (context T) this close to a building cell, in cells
    /// (4-neighbour steps, 0-4), take the context "beside a building", prior {F, I}: the map
    /// prior by the cell centre misses cells cut by a façade, and a footprint is drawn or
    /// placed with an error of the order of a metre. By default 2 (1 m at the default cell).
    pub building_margin_cells: usize,
    /// How far, in cells (`[0, 1]`), the `evigrid` method moves each obstacle return along its
    /// ray before it takes the return's cell as occupied, and how far beyond the nearest return
    /// of a sector its rays mark cells free: a cell is occupied when its centre lies behind the
    /// surface the return came from, seen from the sensor, not merely when a return falls
    /// inside it (issue 30's truth: a cell is what covers its centre). 0: the SPEC §3
    /// SensorGrid. `kurdej2013` always uses the SPEC §3 grid. By default 0.6, chosen on the
    /// tuning drives (`docs/motion.md`, "Returns placed by cell centre"): half a cell would
    /// move a return in the near half of its cell nowhere and one in the far half into the
    /// next cell, exactly so along the grid's axes; 0.6 found more moving cells at a small
    /// cost in dynamic accuracy then. By default 0.5 since the surface placement (which
    /// pushes only the returns behind their sector's nearest surface, and the free space's
    /// reach), re-chosen on the 17 tuning drives of the new scenes and adopted on validation
    /// (`docs/motion.md`, "Parameters re-chosen on the new scenes").
    pub return_depth_cells: f64,
    /// How the `evigrid` method places a return that lies on the nearest surface of its
    /// direction (`return_depth_cells` > 0): `false` moves it `return_depth_cells` along its
    /// own ray (above); `true`, the default since issue 30, draws the surface through the
    /// nearest returns of fine sectors of 0.1° (neighbours joined when at most 2 m apart) and
    /// occupies each cell around a return whose centre lies behind the surface its own ray
    /// meets, at most `surface_depth_cells` from it (`docs/motion.md`, "Returns placed by the
    /// surface"). A slanted face (a car's side) covers cell centres beside the ray of each of
    /// its returns, which the push along the ray misses or overshoots. Returns farther than a
    /// cell behind the nearest of their fine sector are still pushed along their ray.
    pub placed_by_surface: bool,
    /// With `placed_by_surface`: how far behind the surface, square to it, a cell centre is
    /// still the object's, in cells (`(0, 8]`). By default 5 (2.5 m at the default cell),
    /// re-chosen on the 17 tuning drives of the new scenes and adopted on validation
    /// (`docs/motion.md`, "Parameters re-chosen on the new scenes"); 3 before, chosen with
    /// `surface_pose_sigmas` once the silhouette's end had lost its face
    /// (`surface_silhouette_faces`; 2 before that, "The silhouette's end").
    pub surface_depth_cells: f64,
    /// With `placed_by_surface`: a cell centre up to this many standard deviations of the
    /// pose's estimated error ([`FrontEnd::pose_sigma`](crate::FrontEnd::pose_sigma), at the
    /// cell's range: √(σ² + (r·σ_θ)²)) in front of the surface is still occupied, since the
    /// truth lies in the world's frame and the scan is placed with the pose used. By default
    /// 0.1875, re-chosen on the 17 tuning drives of the new scenes and adopted on validation
    /// (`docs/motion.md`, "Parameters re-chosen on the new scenes"); 0.09375 before (the
    /// largest moving IoU whose dynamic accuracy stayed within 0.02 of the default's on the
    /// old scenes, "The surface's pose tolerance under pose error"), 0.375 before that, 0.25
    /// before that.
    pub surface_pose_sigmas: f64,
    /// With `placed_by_surface`: past the last return of a silhouette (the ray's neighbour on
    /// the other side farther, or none: that ray went past the object), a face square to the
    /// ray within half a ray spacing, as before issue 30's object work. `false`, the
    /// default: no surface there, so the cells radially behind a silhouette's last return are
    /// not occupied; a surface's end behind a nearer return (an occluded end) keeps its face.
    /// Chosen on the validation drives with the two parameters above (`docs/motion.md`,
    /// "The silhouette's end").
    pub surface_silhouette_faces: bool,
    /// With `placed_by_surface`: where the two returns either side of a ray lie on two faces
    /// that meet in a convex corner in front of the segment between them (each face drawn
    /// through its return and the next one beyond it, the corner at most half the segment's
    /// length in front of it), the ray meets those faces up to the corner instead of the
    /// segment, which cuts a car's corner off. Measured on the tuning drives and not kept
    /// (`docs/motion.md`, "A car's corner, and the margin of a crawl").
    pub surface_convex_corners: bool,
    /// With `placed_by_surface`: the motion stage registers each cluster on the cells of the
    /// returns themselves (the SPEC §3 grid: the faces the scanner saw, one cell deep) and
    /// remembers those in its history, while the cells placed by the surface take the
    /// evidence. `true`, the default: the surface's cells, up to `surface_depth_cells` deep,
    /// overlap their own shifted copy over most of a slow car's move, so that its shift
    /// reads zero (`docs/motion.md`, "Registering on the returns"). `false`: registered on
    /// the placed cells.
    pub surface_register_on_returns: bool,
    /// A registered shift no longer than this many standard deviations of the apparent
    /// shift the pose's error gives a static cluster at its range (√2 · √(σ² + (r·σ_θ)²) per
    /// axis, σ and σ_θ the front end's [`FrontEnd::pose_sigma`](crate::FrontEnd::pose_sigma)
    /// estimate) is not taken as motion: the frame reads zero shift (`docs/motion.md`,
    /// "Gating by the pose's own error"). 0, the default, turns the gate off. 3, with the
    /// refinement's gate at 1 m / 2°, won moving IoU on the validation drives but cost dynamic
    /// accuracy 0.05 on every set, more than the 0.02 the tuning rule allows: an option.
    pub pose_gate_sigmas: f64,
    /// A track's cells are moving only once its net displacement as registered (the first
    /// registration's velocity times its mean span, then each registration's velocity times
    /// the frame's interval, summed) is longer than this many standard deviations of the
    /// apparent displacement the pose's error gives a static object at its range (√2 ·
    /// √(σ² + (r·σ_θ)²), σ and σ_θ the front end's
    /// [`FrontEnd::pose_sigma`](crate::FrontEnd::pose_sigma) estimate): a parked car whose
    /// registered shifts jitter with the pose stays within that, a mover's displacement grows
    /// (`docs/motion.md`, "A static track under pose error: its net displacement"). Before
    /// that a fast track gives no evidence. By default 1.5, re-chosen on the 17 tuning drives
    /// of the new scenes and adopted on validation (`docs/motion.md`, "Parameters re-chosen on
    /// the new scenes"); 2 before, chosen on the old scenes among 2 and 3 (moving IoU 0.5655 →
    /// 0.5675, dynamic accuracy 0.7907 → 0.7886 on validation); 0 turns the test off.
    pub displaced_pose_sigmas: f64,
    /// The object layer (`docs/motion.md`, "An object layer"): each moving track whose
    /// heading is known (from its velocity) gets an oriented rectangle fitted to its returns,
    /// its extent kept over the frames in the object's own frame, anchored on the faces the
    /// sensor sees; the track's cells whose centre lies inside take the moving evidence, its
    /// placed cells outside do not. `true`, the default (chosen on the tuning drives, adopted
    /// on validation); `false`: every placed cell of the track's cluster, as before.
    pub object_layer: bool,
    /// With `object_layer`: m(Ω∖{M}) given to a moving track's placed cells whose centre lies
    /// outside its rectangle (0: no evidence, they keep what the SPEC §5 step made of them,
    /// mostly M: the free→occupied conflict). 0.9, the default, is `mu_static`.
    pub object_outside_static: f64,
    /// With `object_layer`: whether `object_outside_static` is fused into the perception grid
    /// (`true`: it persists into later frames, where the car that covers the cell next meets
    /// it and takes frames to be M there) or only decides the cell this frame (`false`, the
    /// default: the grid keeps what the SPEC §5 step made of it; chosen on the tuning drives,
    /// adopted on validation, `docs/motion.md`, "The outside label as this frame's
    /// decision").
    pub object_outside_fused: bool,
    /// With `object_layer`: the heading is taken from the track's velocity only when its
    /// uncertainty, √(σx² + σy²) over the speed, is at most the tangent of this angle, degrees.
    pub object_heading_max_deg: f64,
    /// With `object_layer`: the faces' direction is the one, in whole degrees within this many
    /// of the velocity's heading, that gives the returns the smallest box (0: the velocity's
    /// heading).
    pub object_heading_fit_deg: f64,
    /// With `object_layer`: an object longer than this (along its heading), metres, is not
    /// fitted (two objects joined, or a wall): its cells keep the evidence of the track.
    pub object_max_length_m: f64,
    /// With `object_layer`: the same across its heading, metres.
    pub object_max_width_m: f64,
    /// With `object_layer`: how far outside the rectangle, metres, a cell centre still counts
    /// as inside (added to `surface_pose_sigmas` times the pose's error at its range).
    pub object_margin_m: f64,
    /// With `object_layer`: a small road user's depth, metres. An object whose extents along
    /// and across its heading, the largest seen over the frames kept, are both under 1 m
    /// (a pedestrian, not a car seen end-on: a car's face spans more) reaches this far beyond
    /// the faces the sensor sees, where it was left open before (`docs/motion.md`, "A small
    /// road user's depth"); 0: open, as before. At most 1 m.
    pub object_small_depth_m: f64,
    /// With `object_layer`: also fit a moving track whose velocity's heading is not sure
    /// (σ over the speed above the tangent of `object_heading_max_deg`), the faces' direction
    /// searched over every direction (the returns' smallest box, ±45° of the velocity's);
    /// false: such a track has no rectangle and its cells keep the track's evidence.
    pub object_fit_unsure_heading: bool,
    /// With `object_layer`: how far beyond the far sides of a rectangle (those reached by an
    /// extent seen, not anchored on a face the sensor sees, and a silhouette's ends), metres,
    /// a cell centre still counts as inside: the largest extent seen is a lower bound.
    pub object_far_margin_m: f64,
    /// A track judged moving whose cells that moved (those its registration explains) span
    /// more than this, metres (the diagonal of their box along east and north), gives no
    /// moving evidence: no road user is that large, and a façade or a row of parked cars that
    /// a scan's pose error shifted is (`docs/motion.md`, "Static things under pose error: too
    /// large to move"). Such a track takes m(Ω∖{M}) = `mu_static` instead, as a static
    /// track's cells. By default 8, chosen on the tuning drives among 6, 8, 10 and 13 and
    /// adopted on the validation drives (moving IoU 0.5725 → 0.6015, dynamic accuracy 0.7442
    /// → 0.7406); 0: off.
    pub moving_max_extent_m: f64,
    /// A cluster read at zero against every past frame in its fit moves after all when at
    /// least this many of them lean: a non-zero shift explained more of it than zero (not
    /// clearly more) and its move is seen on the margin's cells; every frame must lie within
    /// a cell of the line through the frames' readings, which must reach a whole cell and
    /// `displaced_pose_sigmas` σ of the pose's apparent shift (`docs/motion.md`, "Leaning
    /// frames: a slow slide"); 0: off. At most 8 (more than `history_frames` never moves
    /// one). By default 2.
    pub weak_shift_frames: usize,
    /// With `moving_max_extent_m`: a track whose cells that moved span more than that keeps
    /// its moving evidence when they span at most this many metres across its velocity (a
    /// bus or a truck driving along its length is at most about 3 m wide; a façade that a
    /// scan's pose error shifts moves across its own length, `docs/motion.md`, "Buses and
    /// trucks: the extent across the motion"). By default 4 (with `moving_max_length_m`
    /// 13), chosen on the 24 tuning drives among 3, 4 and 5 m, then 13 and 16 m, and adopted
    /// on the 12 validation drives (moving IoU 0.6132 → 0.6133, dynamic accuracy 0.7553 →
    /// 0.7608); 0: off (every such track is too large).
    pub moving_max_across_m: f64,
    /// With `moving_max_across_m`: the most a narrow mover's cells that moved may span (the
    /// diagonal of their box, as `moving_max_extent_m`), metres: a 12 × 2.55 m bus spans
    /// about 13 m on 0.5 m cells, a façade sliding along its own length under a scan's pose
    /// error 15–50 m. By default 13; 0: no bound.
    pub moving_max_length_m: f64,
    /// With `moving_max_across_m`: when the track's velocity σ (√(σ_x² + σ_y²)) is at least
    /// this share of its speed, the span across is also measured across the moved cells' own
    /// long axis (the principal axis of their centres) and the lesser of the two is taken, so
    /// that a slow bus whose heading is unsure is still measured across its width
    /// (`docs/motion.md`, "A slow bus: the span across its own axis"). By default 1, chosen
    /// on the 24 tuning drives among 0.5, 0.6, 0.75 and 1 (and always), adopted on the 12
    /// validation drives (moving IoU 0.6709 → 0.6730, dynamic accuracy 0.7977 → 0.8004); 0:
    /// off (across the velocity only, as before).
    pub moving_across_own_axis_unsure: f64,
    /// The SPEC §5 step's own M where the pose's error explains it: a cell of this frame's
    /// clusters that takes no moving evidence (its track was never registered or is uncertain,
    /// or it holds a return that the placed grid does not occupy) and is decided M is decided
    /// again with m(Ω∖{M}) = `mu_static`, this frame only, when this many σ of the pose's
    /// apparent shift at its cluster's range, √2·√(σ² + (r·σ_θ)²), reach half a cell
    /// (`docs/motion.md`, "The step's own M under pose error"). By default 6, chosen on the
    /// tuning drives between 3 and 6 (2, 3, 4, 6 and always for a first form that also took
    /// tracks held by the displacement test) and adopted on the validation drives (moving IoU
    /// 0.6158 → 0.6217, dynamic accuracy 0.7652 → 0.7607); 0: off.
    pub unsupported_pose_sigmas: f64,
    /// Standard deviation of the jerk, m/s³, that drives a track's acceleration in its
    /// filter: the velocity follows the acceleration, and a registration (the mean velocity
    /// over the past frames it fits) is read as the velocity half its mean span ago, so that a
    /// braking car is seen to stop when it stops, not up to a second later
    /// (`docs/motion.md`, "A braking car's stop: the filter's acceleration"). Only the part
    /// of the acceleration that slows the track down or turns it is kept. By default 1,
    /// chosen on the tuning drives among 0.25, 0.5, 0.75, 1, 1.5, 2 and 5 and adopted on the
    /// validation drives (moving IoU 0.6158 → 0.6163, dynamic accuracy 0.7652 → 0.7594); 0:
    /// off (constant velocity, each registration read as the velocity now).
    pub jerk_sigma_mps3: f64,
    /// A cluster whose newer past frames all read zero while an older one shows a clear move
    /// off their line that does not restart the fit (a stop, or a move the newer frames hid)
    /// is not measured this frame instead of being read static on the newer frames
    /// (`docs/motion.md`, "Newer frames that read zero against an older move"); only for a
    /// move longer than `displaced_pose_sigmas` σ of the apparent shift the pose's error
    /// gives a static cluster at its range. By default true (false: the rule before).
    pub contradicted_unmeasured: bool,
    /// Whether a stopped track's m({S}) is fused into the perception grid (`true`: it
    /// persists into later frames, the rule before) or only decides its cells this frame
    /// (`false`, the default: the grid keeps what the SPEC §5 step made of them, so a car
    /// pulling away from a stop meets no stopped mass there once its move is measured;
    /// `docs/motion.md`, "A stop's label as this frame's decision").
    pub stopped_fused: bool,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            history_frames: 8,
            history_thinned: false,
            static_part_entered: true,
            search_radius_cells: 6,
            max_speed_mps: 25.0,
            match_fraction: 0.5,
            shift_margin_fraction: 0.15,
            shift_margin_max_cells: 2.0,
            min_speed_mps: 0.5,
            accel_sigma_mps2: 3.0,
            shift_sigma_cells: 0.5,
            gate_m: 2.0,
            max_coast_s: 1.0,
            moving_after_measurements: 1,
            static_sigma_mps: 1.0,
            mu_moving: 1.0,
            mu_static: 0.9,
            mobile_after_travel_m: 2.0,
            mobile_after_moving_s: 1.0,
            report_after_moving_frames: 3,
            report_held_back: false,
            prior_after_moving_frames: 1,
            stop_evidence_cells: 1.5,
            building_margin_cells: 2,
            return_depth_cells: 0.5,
            placed_by_surface: true,
            surface_depth_cells: 5.0,
            surface_pose_sigmas: 0.1875,
            surface_silhouette_faces: false,
            surface_convex_corners: false,
            surface_register_on_returns: true,
            pose_gate_sigmas: 0.0,
            displaced_pose_sigmas: 1.5,
            object_layer: true,
            object_outside_static: 0.9,
            object_outside_fused: false,
            object_heading_max_deg: 40.0,
            object_heading_fit_deg: 15.0,
            object_max_length_m: 10.0,
            object_max_width_m: 3.0,
            object_margin_m: 0.0,
            object_small_depth_m: 0.6,
            object_fit_unsure_heading: true,
            object_far_margin_m: 0.15,
            moving_max_extent_m: 8.0,
            weak_shift_frames: 2,
            moving_max_across_m: 4.0,
            moving_max_length_m: 13.0,
            moving_across_own_axis_unsure: 1.0,
            unsupported_pose_sigmas: 6.0,
            jerk_sigma_mps3: 1.0,
            contradicted_unmeasured: true,
            stopped_fused: false,
        }
    }
}

impl MotionParams {
    /// Checks every range.
    ///
    /// # Errors
    /// The first offending parameter by its TOML path (`motion.…`).
    pub fn validate(&self) -> Result<(), ParamsError> {
        for (name, value) in [
            ("motion.history_frames", self.history_frames),
            ("motion.search_radius_cells", self.search_radius_cells),
            (
                "motion.moving_after_measurements",
                self.moving_after_measurements,
            ),
        ] {
            if value == 0 {
                return Err(ParamsError::NotPositive { name, value: 0.0 });
            }
        }
        at_most("motion.history_frames", self.history_frames, 8)?;
        at_most("motion.search_radius_cells", self.search_radius_cells, 16)?;
        at_most("motion.weak_shift_frames", self.weak_shift_frames, 8)?;
        at_most(
            "motion.building_margin_cells",
            self.building_margin_cells,
            4,
        )?;
        at_most(
            "motion.moving_after_measurements",
            self.moving_after_measurements,
            8,
        )?;
        positive("motion.max_speed_mps", self.max_speed_mps)?;
        unit("motion.match_fraction", self.match_fraction)?;
        unit("motion.shift_margin_fraction", self.shift_margin_fraction)?;
        non_negative("motion.shift_margin_max_cells", self.shift_margin_max_cells)?;
        positive("motion.min_speed_mps", self.min_speed_mps)?;
        positive("motion.accel_sigma_mps2", self.accel_sigma_mps2)?;
        non_negative("motion.jerk_sigma_mps3", self.jerk_sigma_mps3)?;
        positive("motion.shift_sigma_cells", self.shift_sigma_cells)?;
        positive("motion.gate_m", self.gate_m)?;
        positive("motion.static_sigma_mps", self.static_sigma_mps)?;
        positive("motion.max_coast_s", self.max_coast_s)?;
        positive("motion.mobile_after_travel_m", self.mobile_after_travel_m)?;
        positive("motion.mobile_after_moving_s", self.mobile_after_moving_s)?;
        positive("motion.stop_evidence_cells", self.stop_evidence_cells)?;
        unit("motion.mu_moving", self.mu_moving)?;
        unit("motion.mu_static", self.mu_static)?;
        unit("motion.return_depth_cells", self.return_depth_cells)?;
        unit("motion.object_outside_static", self.object_outside_static)?;
        positive("motion.object_heading_max_deg", self.object_heading_max_deg)?;
        at_most_f64(
            "motion.object_heading_max_deg",
            self.object_heading_max_deg,
            80.0,
        )?;
        at_most_f64(
            "motion.object_heading_fit_deg",
            self.object_heading_fit_deg,
            45.0,
        )?;
        // NaN and ∞ are refused by the bound above.
        non_negative("motion.object_heading_fit_deg", self.object_heading_fit_deg)?;
        positive("motion.object_max_length_m", self.object_max_length_m)?;
        positive("motion.object_max_width_m", self.object_max_width_m)?;
        non_negative("motion.object_margin_m", self.object_margin_m)?;
        at_most_f64(
            "motion.object_small_depth_m",
            self.object_small_depth_m,
            1.0,
        )?;
        non_negative("motion.object_small_depth_m", self.object_small_depth_m)?;
        non_negative("motion.object_far_margin_m", self.object_far_margin_m)?;
        positive("motion.surface_depth_cells", self.surface_depth_cells)?;
        at_most_f64("motion.surface_depth_cells", self.surface_depth_cells, 8.0)?;
        non_negative("motion.surface_pose_sigmas", self.surface_pose_sigmas)?;
        // 0 turns the gate off; otherwise positive and finite.
        if self.pose_gate_sigmas != 0.0 {
            positive("motion.pose_gate_sigmas", self.pose_gate_sigmas)?;
        }
        non_negative("motion.displaced_pose_sigmas", self.displaced_pose_sigmas)?;
        non_negative("motion.moving_max_extent_m", self.moving_max_extent_m)?;
        non_negative("motion.moving_max_across_m", self.moving_max_across_m)?;
        non_negative("motion.moving_max_length_m", self.moving_max_length_m)?;
        non_negative(
            "motion.moving_across_own_axis_unsure",
            self.moving_across_own_axis_unsure,
        )?;
        non_negative(
            "motion.unsupported_pose_sigmas",
            self.unsupported_pose_sigmas,
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_nan_anywhere_is_refused_and_named() -> Result<(), Box<dyn std::error::Error>> {
        // `[sensor.ground]`'s ranges are overridden by `[sensor]`'s: issue 31 found them
        // accepting NaN, and the summary then holding `null`.
        for key in [
            "min_range_m",
            "max_range_m",
            "min_obstacle_height_m",
            "max_obstacle_height_m",
        ] {
            let text = format!("[sensor.ground]\n{key} = nan\n");
            let params: Params = toml::from_str(&text)?;
            let error = params.validate().err().map(|e| e.to_string());
            assert_eq!(
                error.as_deref(),
                Some(
                    format!("sensor.ground.{key} = nan: every parameter must be a number").as_str()
                )
            );
        }
        Ok(())
    }

    #[test]
    fn a_cell_below_a_centimetre_is_refused() -> Result<(), Box<dyn std::error::Error>> {
        let params: Params = toml::from_str("[grid]\ncell_size_m = 1e-300\n")?;
        let error = params.validate().err().map(|e| e.to_string());
        assert_eq!(
            error.as_deref(),
            Some("grid.cell_size_m = 1e-300 is below 0.01, the smallest value that makes sense")
        );
        let params: Params = toml::from_str("[grid]\ncell_size_m = 0.01\n")?;
        params.validate()?;
        Ok(())
    }

    #[test]
    fn motion_defaults_are_valid_and_ranges_are_checked() {
        let p = Params::default();
        assert_eq!(p.motion.history_frames, 8);
        p.validate().unwrap_or_else(|e| panic!("{e}"));
        for (text, name) in [
            ("[motion]\nhistory_frames = 9\n", "motion.history_frames"),
            (
                "[motion]\nweak_shift_frames = 9\n",
                "motion.weak_shift_frames",
            ),
            (
                "[motion]\nsurface_depth_cells = 8.5\n",
                "motion.surface_depth_cells",
            ),
            (
                "[motion]\nsurface_depth_cells = 0\n",
                "motion.surface_depth_cells",
            ),
            (
                "[motion]\nsurface_pose_sigmas = -0.5\n",
                "motion.surface_pose_sigmas",
            ),
            (
                "[motion]\ndisplaced_pose_sigmas = -1\n",
                "motion.displaced_pose_sigmas",
            ),
            ("[motion]\nhistory_frames = 0\n", "motion.history_frames"),
            (
                "[motion]\nsearch_radius_cells = 0\n",
                "motion.search_radius_cells",
            ),
            (
                "[motion]\nbuilding_margin_cells = 5\n",
                "motion.building_margin_cells",
            ),
            ("[motion]\nmu_moving = 1.5\n", "motion.mu_moving"),
            ("[motion]\nmin_speed_mps = -1.0\n", "motion.min_speed_mps"),
            ("[motion]\ngate_m = nan\n", "motion.gate_m"),
            (
                "[motion]\nmobile_after_travel_m = 0.0\n",
                "motion.mobile_after_travel_m",
            ),
            (
                "[motion]\nstop_evidence_cells = 0.0\n",
                "motion.stop_evidence_cells",
            ),
            (
                "[motion]\nobject_outside_static = 1.5\n",
                "motion.object_outside_static",
            ),
            (
                "[motion]\nobject_heading_max_deg = 85\n",
                "motion.object_heading_max_deg",
            ),
            (
                "[motion]\nobject_heading_fit_deg = -1\n",
                "motion.object_heading_fit_deg",
            ),
            (
                "[motion]\nobject_heading_fit_deg = 50\n",
                "motion.object_heading_fit_deg",
            ),
            (
                "[motion]\nobject_max_width_m = 0\n",
                "motion.object_max_width_m",
            ),
            (
                "[motion]\nobject_margin_m = -0.1\n",
                "motion.object_margin_m",
            ),
            (
                "[motion]\nobject_small_depth_m = -0.1\n",
                "motion.object_small_depth_m",
            ),
            (
                "[motion]\nobject_small_depth_m = 1.5\n",
                "motion.object_small_depth_m",
            ),
            (
                "[motion]\nobject_small_depth_m = nan\n",
                "motion.object_small_depth_m",
            ),
            (
                "[motion]\nobject_far_margin_m = -0.1\n",
                "motion.object_far_margin_m",
            ),
        ] {
            match Params::from_toml_str(text) {
                Ok(_) => panic!("{text} accepted"),
                Err(e) => assert!(e.to_string().contains(name), "{text}: {e}"),
            }
        }
        let p = Params::from_toml_str("[motion]\nmu_static = 0.3\n").unwrap_or_default();
        assert_eq!(p.motion.mu_static, 0.3);
    }

    #[test]
    fn localisation_is_on_by_default_and_its_keys_are_named() {
        let p = Params::default();
        assert_eq!(p.localisation.refinement, PoseRefinement::ScanToMap);
        let off = Params::from_toml_str("[localisation]\nrefinement = \"none\"\n")
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(off.localisation.refinement, PoseRefinement::None);
        assert!(matches!(
            Params::from_toml_str("[localisation]\nrefinement = \"gps\"\n"),
            Err(ParamsError::Parse { .. })
        ));
        for (text, name) in [
            (
                "[localisation]\nvoxel_size_m = 0\n",
                "localisation.voxel_size_m",
            ),
            (
                "[localisation]\nvoxel_size_m = 1e-9\n",
                "localisation.voxel_size_m",
            ),
            (
                "[localisation]\nplanar_voxel_size_m = -0.25\n",
                "localisation.planar_voxel_size_m",
            ),
            (
                "[localisation]\nmax_correction_m = nan\n",
                "localisation.max_correction_m",
            ),
            (
                "[localisation]\nmax_correction_deg = 200\n",
                "localisation.max_correction_deg",
            ),
            (
                "[localisation]\nprior_weight = 1.5\n",
                "localisation.prior_weight",
            ),
            (
                "[localisation]\nconvergence_tolerance = 0\n",
                "localisation.convergence_tolerance",
            ),
        ] {
            match Params::from_toml_str(text) {
                Ok(_) => panic!("{text} accepted"),
                Err(e) => assert!(e.to_string().contains(name), "{text}: {e}"),
            }
        }
        // The section's defaults are values the refiner accepts.
        let refine = p.localisation.refine_params(&p.sensor);
        assert_eq!(refine.convergence_tolerance, 1e-4);
        assert!(odometry::PoseRefiner::new(refine).is_ok());
        let loose =
            Params::from_toml_str("[localisation]\nconvergence_tolerance = 3e-3\n").expect("valid");
        assert_eq!(
            loose
                .localisation
                .refine_params(&loose.sensor)
                .convergence_tolerance,
            3e-3
        );
    }

    type TestResult = Result<(), Box<dyn std::error::Error>>;

    #[test]
    fn defaults_are_valid_and_documented_values() -> TestResult {
        let p = Params::default();
        p.validate()?;
        assert_eq!(p.grid.cell_size_m, 0.5);
        assert_eq!((p.sensor.mu_free, p.sensor.mu_occupied), (0.7, 0.8));
        assert_eq!(p.fusion.discount_mode, DiscountMode::ClassRates);
        assert_eq!(p.fusion.residual, ResidualPolicy::ToOmega);
        Ok(())
    }

    #[test]
    fn windows_beyond_the_memory_budget_are_refused_before_allocating() {
        // The reproducers of issue 15: 2^32 wrapped width × height to 0 and panicked; 100000²
        // and 5000² aborted or took over 6 GB.
        for (w, h) in [
            (1 << 32, 1),
            (usize::MAX, 2),
            (100_000, 100_000),
            (5000, 5000),
        ] {
            let text = format!("[window]\nwidth_cells = {w}\nheight_cells = {h}\n");
            match Params::from_toml_str(&text) {
                Err(ParamsError::WindowTooLarge { width, height, .. }) => {
                    assert_eq!((width, height), (w, h));
                }
                other => panic!("{w} x {h}: {other:?}"),
            }
        }
        let message = check_window_size(5000, 5000).map_err(|e| e.to_string());
        assert_eq!(
            message,
            Err(
                "window.width_cells x window.height_cells = 5000 x 5000: the grids would need \
                 4769 MiB, over the 1536 MiB memory budget (at most 8053063 cells, e.g. 2837 x \
                 2837)"
                    .to_string()
            )
        );
        assert!(
            check_window_size(usize::MAX, usize::MAX)
                .is_err_and(|e| e.to_string().contains("16 EiB"))
        );
        // The real-time target and the largest square fit.
        check_window_size(1000, 1000).unwrap_or_else(|e| panic!("{e}"));
        check_window_size(2837, 2837).unwrap_or_else(|e| panic!("{e}"));
    }

    #[test]
    fn empty_file_gives_defaults() -> TestResult {
        assert_eq!(Params::from_toml_str("")?, Params::default());
        Ok(())
    }

    #[test]
    fn spec_layout_is_read_in_full() -> TestResult {
        let text = r#"
[grid]
cell_size_m = 0.25
[sensor]
mu_free = 0.6
mu_occupied = 0.75
[map]
beta_building = 0.95
beta_road = 0.85
beta_other = 0.5
[fusion]
discount_mode = "mercier"
set_rate = "mean"
discount_per_second = { F = 0.1, I = 0.2, U = 0.3, S = 0.4, M = 0.5 }
residual = "normalise"
[accumulator]
delta_inc = 0.2
delta_dec = 0.4
gamma_occupied = 0.6
gamma_conflict = 0.1
[decision]
unknown_threshold = 0.7
"#;
        let p = Params::from_toml_str(text)?;
        assert_eq!(p.grid.cell_size_m, 0.25);
        assert_eq!(p.sensor.mu_occupied, 0.75);
        assert_eq!(p.map.beta_other, 0.5);
        assert_eq!(p.fusion.discount_mode, DiscountMode::Mercier);
        assert_eq!(p.fusion.set_rate, SetRate::Mean);
        assert_eq!(
            p.fusion.discount_per_second.as_array(),
            [0.1, 0.2, 0.3, 0.4, 0.5]
        );
        assert_eq!(p.fusion.residual, ResidualPolicy::Normalise);
        assert_eq!(p.accumulator.delta_dec, 0.4);
        assert_eq!(p.accumulator.gamma_conflict, 0.1);
        assert_eq!(p.decision.unknown_threshold, 0.7);
        // Untouched sections keep their defaults.
        assert_eq!(p.window, WindowParams::default());
        Ok(())
    }

    #[test]
    fn partial_file_keeps_other_defaults() -> TestResult {
        let p = Params::from_toml_str("[accumulator]\ndelta_inc = 0.25\n")?;
        let mut expected = Params::default();
        expected.accumulator.delta_inc = 0.25;
        assert_eq!(p, expected);
        Ok(())
    }

    #[test]
    fn discount_rate_accepts_a_number_or_a_partial_table() -> TestResult {
        let p = Params::from_toml_str("[fusion]\ndiscount_per_second = 0.3\n")?;
        assert_eq!(p.fusion.discount_per_second, ClassRates::uniform(0.3));
        let p = Params::from_toml_str("[fusion]\ndiscount_per_second = 1\n")?;
        assert_eq!(p.fusion.discount_per_second, ClassRates::uniform(1.0));
        let p = Params::from_toml_str("[fusion]\ndiscount_per_second = { M = 0.99 }\n")?;
        let expected = ClassRates {
            moving: 0.99,
            ..ClassRates::default()
        };
        assert_eq!(p.fusion.discount_per_second, expected);
        Ok(())
    }

    #[test]
    fn unknown_keys_are_rejected_with_their_name() {
        for text in [
            "[grid]\ncell_size = 0.5\n",
            "[nonsense]\n",
            "[fusion]\ndiscount_per_second = { X = 0.1 }\n",
        ] {
            let err = Params::from_toml_str(text).err();
            let message = err.map(|e| e.to_string()).unwrap_or_default();
            assert!(message.contains("unknown field"), "{text}: {message}");
        }
    }

    #[test]
    fn wrong_value_type_and_enum_name_are_rejected() {
        for text in [
            "[fusion]\nresidual = \"sideways\"\n",
            "[fusion]\ndiscount_per_second = \"fast\"\n",
            "[sensor]\nmu_free = \"high\"\n",
        ] {
            assert!(
                matches!(Params::from_toml_str(text), Err(ParamsError::Parse { .. })),
                "{text}"
            );
        }
    }

    #[test]
    fn each_out_of_range_parameter_is_named() {
        let cases = [
            ("[sensor]\nmu_free = 1.5", "sensor.mu_free"),
            (
                "[sensor.ground]\nmax_slope = -0.1",
                "sensor.ground.max_slope",
            ),
            ("[sensor]\nmu_occupied = -0.1", "sensor.mu_occupied"),
            ("[map]\nbeta_building = 2", "map.beta_building"),
            ("[map]\nbeta_road = -1", "map.beta_road"),
            ("[map]\nbeta_other = 1.01", "map.beta_other"),
            (
                "[fusion]\ndiscount_per_second = 1.5",
                "fusion.discount_per_second.F",
            ),
            (
                "[fusion]\ndiscount_per_second = { M = -0.5 }",
                "fusion.discount_per_second.M",
            ),
            (
                "[fusion]\ndiscount_per_second = { S = nan }",
                "fusion.discount_per_second.S",
            ),
            ("[accumulator]\ndelta_inc = 1.1", "accumulator.delta_inc"),
            ("[accumulator]\ndelta_dec = -0.1", "accumulator.delta_dec"),
            (
                "[accumulator]\ngamma_occupied = 3",
                "accumulator.gamma_occupied",
            ),
            (
                "[accumulator]\ngamma_conflict = -3",
                "accumulator.gamma_conflict",
            ),
            (
                "[decision]\nunknown_threshold = 1.5",
                "decision.unknown_threshold",
            ),
            ("[grid]\ncell_size_m = 0", "grid.cell_size_m"),
            ("[grid]\ncell_size_m = -0.5", "grid.cell_size_m"),
            ("[grid]\ncell_size_m = inf", "grid.cell_size_m"),
            ("[window]\nwidth_cells = 0", "window.width_cells"),
            ("[window]\nheight_cells = 0", "window.height_cells"),
            (
                "[sensor]\nangular_resolution_deg = 0",
                "sensor.angular_resolution_deg",
            ),
            ("[sensor]\nmax_range_m = -1", "sensor.max_range_m"),
            (
                "[sensor]\nmin_neighbourhood_returns = 0",
                "sensor.min_neighbourhood_returns",
            ),
            (
                "[sensor]\nmin_neighbourhood_returns = 1000000",
                "sensor.min_neighbourhood_returns",
            ),
            (
                "[sensor]\nmin_obstacle_height_m = 3.0",
                "sensor.min_obstacle_height_m",
            ),
        ];
        for (text, name) in cases {
            match Params::from_toml_str(text) {
                Ok(_) => panic!("{text} accepted"),
                Err(e) => {
                    assert!(!matches!(e, ParamsError::Parse { .. }), "{text}: {e}");
                    assert!(e.to_string().contains(name), "{text}: {e}");
                }
            }
        }
    }

    #[test]
    fn boundary_values_are_accepted() -> TestResult {
        let p = Params::from_toml_str(
            "[map]\nbeta_road = 0\nbeta_building = 1\n[fusion]\ndiscount_per_second = 0\n",
        )?;
        assert_eq!(p.map.beta_road, 0.0);
        Ok(())
    }

    #[test]
    fn toml_round_trip_preserves_every_value() -> TestResult {
        let mut p = Params::default();
        p.fusion.discount_mode = DiscountMode::Mercier;
        p.fusion.set_rate = SetRate::Min;
        p.fusion.residual = ResidualPolicy::Keep;
        p.fusion.discount_per_second.stopped = 0.125;
        p.window.width_cells = 17;
        let text = p.to_toml_string()?;
        assert!(text.contains("[fusion]"), "{text}");
        assert!(text.contains("discount_mode = \"mercier\""), "{text}");
        assert_eq!(Params::from_toml_str(&text)?, p);
        Ok(())
    }

    /// The rows of the parameter table of `docs/motion.md` headed `## Parameters (`[section]`)`:
    /// each key of the first column (several may share a row, comma-separated, as may their
    /// defaults) with its documented default, the first word of the second column.
    fn documented_defaults(doc: &str, section: &str) -> Vec<(String, String)> {
        let heading = format!("## Parameters (`[{section}]`)");
        let mut rows = Vec::new();
        let Some(start) = doc.find(&heading) else {
            return rows;
        };
        let table = doc[start + heading.len()..]
            .lines()
            .skip_while(|line| !line.starts_with('|'))
            .take_while(|line| line.starts_with('|'))
            .skip(2);
        for row in table {
            let columns: Vec<&str> = row.split('|').map(str::trim).collect();
            let (Some(keys), Some(defaults)) = (columns.get(1), columns.get(2)) else {
                continue;
            };
            let keys = keys.split(',').map(|key| key.trim().trim_matches('`'));
            let defaults = defaults.split(',').map(|value| {
                value
                    .split_whitespace()
                    .next()
                    .unwrap_or_default()
                    .to_string()
            });
            rows.extend(keys.map(str::to_string).zip(defaults));
        }
        rows
    }

    /// Every key of `value` (a section's defaults, serialised) is in the table with its default,
    /// and the table names no key the section does not have.
    fn check_table(doc: &str, section: &str, value: toml::Value) {
        let toml::Value::Table(defaults) = value else {
            panic!("[{section}] does not serialise to a table");
        };
        let rows = documented_defaults(doc, section);
        assert!(!rows.is_empty(), "docs/motion.md has no [{section}] table");
        for (key, documented) in &rows {
            let Some(default) = defaults.get(key) else {
                panic!("docs/motion.md documents [{section}] {key}, which params.rs has not");
            };
            let same = match default {
                toml::Value::Float(x) => documented.parse::<f64>().ok() == Some(*x),
                toml::Value::Integer(n) => documented.parse::<i64>().ok() == Some(*n),
                toml::Value::Boolean(b) => documented.parse::<bool>().ok() == Some(*b),
                toml::Value::String(text) => documented.trim_matches('"') == text,
                other => panic!("[{section}] {key} = {other}: no rule to compare it"),
            };
            assert!(
                same,
                "docs/motion.md: [{section}] {key} documented {documented}, default {default}"
            );
        }
        for key in defaults.keys() {
            assert!(
                rows.iter().any(|(row, _)| row == key),
                "[{section}] {key} is missing from docs/motion.md's table"
            );
        }
    }

    #[test]
    fn the_parameter_tables_of_the_docs_hold_every_key_with_its_default() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/motion.md");
        let doc = std::fs::read_to_string(path).expect("docs/motion.md is readable");
        let motion = toml::Value::try_from(MotionParams::default()).expect("serialises");
        check_table(&doc, "motion", motion);
        let localisation =
            toml::Value::try_from(LocalisationParams::default()).expect("serialises");
        check_table(&doc, "localisation", localisation);
    }

    #[test]
    fn the_table_check_reads_a_table_and_its_shared_rows() {
        let doc = "## Parameters (`[motion]`)\n\ntext\n\n| key | default |\n|---|---|\n\
                   | `a` | 0 (off) | x |\n| `b`, `c` | 10, 3 | y |\n\nafter\n| `d` | 1 |\n";
        let rows = documented_defaults(doc, "motion");
        let expected = [("a", "0"), ("b", "10"), ("c", "3")];
        assert_eq!(rows.len(), expected.len());
        for ((key, value), (want_key, want_value)) in rows.iter().zip(expected) {
            assert_eq!((key.as_str(), value.as_str()), (want_key, want_value));
        }
        assert!(documented_defaults(doc, "localisation").is_empty());
    }
}

/// Pose refinement (`[localisation]`): whether the front end trusts the pose it is given, or
/// registers each scan against a local map of the previous scans with that pose as the prior
/// (`docs/motion.md`, "Pose refinement"). Not in SPEC, and on by default: the pose is
/// registered, not trusted alone. With `refinement = "none"` the front end is exactly the paper's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalisationParams {
    /// `"none"`: the pose given is used as it is. `"scan_to_map"`: it is the prior of a
    /// registration against the previous scans (crate `odometry`, [`odometry::PoseRefiner`]).
    /// By default `"scan_to_map"`.
    pub refinement: PoseRefinement,
    /// Edge of the local map's voxels for 3-D scans, metres; a scan is downsampled at half of
    /// it for the map and at 1.5 times it for the registration. By default 1 (KISS-ICP's
    /// choice; on KITTI's 64-beam scans 0.25 m takes 131 ms a frame against 22 ms for the same
    /// corrections, `docs/motion.md`).
    pub voxel_size_m: f64,
    /// The same for planar scans (every point in a band of heights 5 cm wide): by default 0.25,
    /// measured on the simulated planar scanner. The drive's first scan decides which applies.
    pub planar_voxel_size_m: f64,
    /// A registration that moves the position farther than this from the given pose is refused
    /// and the given pose kept, metres. By default 1, `odometry`'s (chosen with the
    /// constant-velocity start on the tuning drives; 0.5 refused one scan in twelve with 0.2 m
    /// of noise per axis, `docs/motion.md`, "Pose refinement").
    pub max_correction_m: f64,
    /// A registration that turns the heading by more than this is refused, degrees. By default
    /// 2, `odometry`'s.
    pub max_correction_deg: f64,
    /// `blend = "fixed"`: fraction of the way from the registered pose back to the given one,
    /// `[0, 1]`: keeps the map from drifting with the first scans' error. By default 0.2 (chosen with the
    /// constant-velocity start on the tuning drives).
    pub prior_weight: f64,
    /// The registration stops when an update moves the pose by less than this (metres and
    /// radians as one 6-vector's norm). By default 1e-4. 1e-3 halves the iterations on KITTI
    /// 0013 (23 a scan against 44, poses within 3 cm) but turns a parked car's cell moving in
    /// the still planar scene of `tests/scenarios.rs` (`docs/benchmarks.md`).
    pub convergence_tolerance: f64,
    /// Where the registration starts: `"prior"`, the given pose, or `"constant_velocity"`, a
    /// prediction from the last two registered poses ([`odometry::RefineStart`]). By default
    /// `"constant_velocity"` (`docs/motion.md`, "Pose refinement").
    pub start: RefinementStart,
    /// How the registered pose and the given one are combined: `"information"`, a filter on
    /// the map frame's offset that pulls towards the given pose in the directions the scan does
    /// not constrain (along a corridor) and hardly in those it does, or `"fixed"`,
    /// `prior_weight` of the way back in every direction ([`odometry::RefineBlend`]). By
    /// default `"information"` (chosen on the validation drives, `docs/motion.md`, "Pose
    /// refinement").
    pub blend: RefinementBlend,
    /// `blend = "information"`: σ of the given position per axis, metres (with `prior_sigma =
    /// "estimated"`, an upper bound). By default 0.2 (chosen with the next three on the tuning
    /// drives).
    pub prior_sigma_m: f64,
    /// `blend = "information"`: σ of the given rotation, degrees (with `prior_sigma =
    /// "estimated"`, an upper bound). By default 0.5.
    pub prior_sigma_deg: f64,
    /// `blend = "information"`: σ of the registration in a direction every pair constrains,
    /// metres. By default 0.01.
    pub registration_sigma_m: f64,
    /// `blend = "information"`: σ of the registration's start per axis, metres (what it is
    /// off by in a direction the scan does not constrain). By default 0.2.
    pub prediction_sigma_m: f64,
    /// `blend = "information"`: `"fixed"`, the given pose's σ are `prior_sigma_m` and
    /// `prior_sigma_deg`, or `"estimated"`, from the given poses' own scan-to-scan jitter
    /// ([`odometry::PriorSigma`]). By default `"estimated"` (chosen on the validation drives,
    /// `docs/motion.md`, "The given pose's σ from its own jitter").
    pub prior_sigma: PriorSigmaSource,
}

/// Where the pose refinement takes the given pose's σ from (`[localisation] prior_sigma`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PriorSigmaSource {
    /// `prior_sigma_m` and `prior_sigma_deg`.
    Fixed,
    /// Lowered below `prior_sigma_m` and `prior_sigma_deg` when the given poses' second
    /// differences show less jitter.
    #[default]
    Estimated,
}

impl From<odometry::PriorSigma> for PriorSigmaSource {
    fn from(source: odometry::PriorSigma) -> Self {
        match source {
            odometry::PriorSigma::Estimated => Self::Estimated,
            _ => Self::Fixed,
        }
    }
}

/// How the pose refinement combines the registered and the given pose (`[localisation]
/// blend`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RefinementBlend {
    /// `prior_weight` of the way back to the given pose.
    Fixed,
    /// Weighted by what the scan constrains and how wrong the given pose can be.
    #[default]
    Information,
}

impl From<odometry::RefineBlend> for RefinementBlend {
    fn from(blend: odometry::RefineBlend) -> Self {
        match blend {
            odometry::RefineBlend::Information => Self::Information,
            _ => Self::Fixed,
        }
    }
}

impl Default for LocalisationParams {
    fn default() -> Self {
        let refine = odometry::RefineParams::default();
        Self {
            refinement: PoseRefinement::ScanToMap,
            voxel_size_m: refine.voxel_size_m,
            planar_voxel_size_m: refine.planar_voxel_size_m,
            max_correction_m: refine.max_correction_m,
            max_correction_deg: refine.max_correction_deg,
            prior_weight: refine.prior_weight,
            convergence_tolerance: refine.convergence_tolerance,
            start: RefinementStart::from(refine.start),
            blend: RefinementBlend::from(refine.blend),
            prior_sigma_m: refine.prior_sigma_m,
            prior_sigma_deg: refine.prior_sigma_deg,
            registration_sigma_m: refine.registration_sigma_m,
            prediction_sigma_m: refine.prediction_sigma_m,
            prior_sigma: PriorSigmaSource::from(refine.prior_sigma),
        }
    }
}

/// How the front end obtains the pose it builds the SensorGrid with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PoseRefinement {
    /// The pose given with the scan, as it is (the paper).
    None,
    /// The pose given refined by registering the scan against the previous scans.
    #[default]
    ScanToMap,
}

/// Where the pose refinement's registration starts (`[localisation] start`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RefinementStart {
    /// From the pose given with the scan.
    Prior,
    /// From a constant-velocity prediction of the poses used for the last two registered
    /// scans.
    #[default]
    ConstantVelocity,
}

impl From<odometry::RefineStart> for RefinementStart {
    fn from(start: odometry::RefineStart) -> Self {
        match start {
            odometry::RefineStart::ConstantVelocity => Self::ConstantVelocity,
            _ => Self::Prior,
        }
    }
}

impl LocalisationParams {
    /// The refiner's parameters: these, with the sensor's ranges.
    pub fn refine_params(&self, sensor: &SensorParams) -> odometry::RefineParams {
        odometry::RefineParams {
            max_range_m: sensor.max_range_m,
            min_range_m: sensor.min_range_m,
            voxel_size_m: self.voxel_size_m,
            planar_voxel_size_m: self.planar_voxel_size_m,
            max_correction_m: self.max_correction_m,
            max_correction_deg: self.max_correction_deg,
            prior_weight: self.prior_weight,
            convergence_tolerance: self.convergence_tolerance,
            start: match self.start {
                RefinementStart::Prior => odometry::RefineStart::Prior,
                RefinementStart::ConstantVelocity => odometry::RefineStart::ConstantVelocity,
            },
            blend: match self.blend {
                RefinementBlend::Fixed => odometry::RefineBlend::Fixed,
                RefinementBlend::Information => odometry::RefineBlend::Information,
            },
            prior_sigma_m: self.prior_sigma_m,
            prior_sigma_deg: self.prior_sigma_deg,
            registration_sigma_m: self.registration_sigma_m,
            prediction_sigma_m: self.prediction_sigma_m,
            prior_sigma: match self.prior_sigma {
                PriorSigmaSource::Fixed => odometry::PriorSigma::Fixed,
                PriorSigmaSource::Estimated => odometry::PriorSigma::Estimated,
            },
            ..odometry::RefineParams::default()
        }
    }

    /// Checks every range.
    ///
    /// # Errors
    /// The first offending parameter by its TOML path (`localisation.…`).
    pub fn validate(&self, sensor: &SensorParams) -> Result<(), ParamsError> {
        for (name, voxel) in [
            ("localisation.voxel_size_m", self.voxel_size_m),
            ("localisation.planar_voxel_size_m", self.planar_voxel_size_m),
        ] {
            positive(name, voxel)?;
            if sensor.max_range_m / voxel > 1.0e6 {
                return Err(ParamsError::Misordered {
                    low_name: "sensor.max_range_m / 1e6",
                    low: sensor.max_range_m / 1.0e6,
                    high_name: name,
                    high: voxel,
                });
            }
        }
        positive("localisation.max_correction_m", self.max_correction_m)?;
        positive("localisation.max_correction_deg", self.max_correction_deg)?;
        at_most_f64(
            "localisation.max_correction_deg",
            self.max_correction_deg,
            180.0,
        )?;
        unit("localisation.prior_weight", self.prior_weight)?;
        positive(
            "localisation.convergence_tolerance",
            self.convergence_tolerance,
        )?;
        for (name, sigma) in [
            ("localisation.prior_sigma_m", self.prior_sigma_m),
            ("localisation.prior_sigma_deg", self.prior_sigma_deg),
            (
                "localisation.registration_sigma_m",
                self.registration_sigma_m,
            ),
            ("localisation.prediction_sigma_m", self.prediction_sigma_m),
        ] {
            positive(name, sigma)?;
        }
        Ok(())
    }
}

fn at_most_f64(name: &'static str, value: f64, high: f64) -> Result<(), ParamsError> {
    if value <= high {
        Ok(())
    } else {
        Err(ParamsError::Misordered {
            low_name: name,
            low: value,
            high_name: "its largest value",
            high,
        })
    }
}
