//! The `evigrid bench` harness: how fast one fusion step is, against named baselines.
//!
//! A perception grid is only useful if it keeps up with the sensor. This crate measures, in one
//! process and on one machine state, the library's step against two baselines:
//! - [`copy`]: the memory floor, a STREAM-like pass over the bytes of a step that reads and
//!   writes the whole state (the library's step skips planes it knows hold +0, and reports the
//!   bytes it did move);
//! - [`naive`]: SPEC §5 written plainly (array of structs, dense loops over all pairs of focal
//!   sets), checked against the library before it is timed.
//!
//! The key design decision: every case runs once per *round*, and rounds repeat after a warm-up,
//! so each ratio is a median of per-round ratios taken moments apart: a noisy neighbour slows
//! both sides of a ratio alike.
//!
//! ```
//! use evigrid_bench::{BenchOptions, run};
//!
//! let options = BenchOptions { sizes: vec![32], rounds: 2, ..BenchOptions::default() };
//! let report = run(&options, |_| {})?;
//! // The fraction of the memory floor the one-thread step reaches.
//! assert!(report.windows[0].ratio("copy/step@1").is_some_and(|r| r > 0.0));
//! # Ok::<(), evigrid_bench::BenchError>(())
//! ```
#![deny(missing_docs)]

pub mod copy;
pub mod drive_run;
pub mod naive;
pub mod real;
pub mod workload;

use evigrid::{Params, PerceptionGrid};
use serde::Serialize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Window sizes, in cells per side. By default 200 and 1000 (issue 5).
    pub sizes: Vec<usize>,
    /// Timed rounds after one warm-up round. By default 7.
    pub rounds: usize,
    /// Rounds in which the naive step runs (it is ~100× slower). By default 3.
    pub naive_rounds: usize,
    /// The real inputs for `sensor`, `prior` and `frame`; `None` skips those cases.
    pub real: Option<real::RealInputs>,
    /// Cell size for the real-data cases, metres. By default 0.2.
    pub cell_size_m: f64,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            sizes: vec![200, 1000],
            rounds: 7,
            naive_rounds: 3,
            real: None,
            cell_size_m: 0.2,
        }
    }
}

/// Errors of a bench run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    /// A size or round count of zero.
    #[error("invalid bench option: {0}")]
    InvalidOption(String),
    /// The library's step and the naive step disagree: the timing would compare different work.
    #[error("the naive step differs from the library's by {difference} (tolerance 1e-5)")]
    NaiveDisagrees {
        /// Largest absolute difference found.
        difference: f32,
    },
    /// Real inputs could not be prepared.
    #[error(transparent)]
    Real(#[from] real::RealError),
    /// The thread pool could not be built.
    #[error("cannot build a thread pool: {0}")]
    ThreadPool(String),
}

/// One timed case on one window size.
#[derive(Clone, Debug, Serialize)]
pub struct CaseTiming {
    /// Case name: `copy`, `naive`, `step`, `sensor`, `prior`, `frame`, `ground`, `odometry`, with
    /// `@1` (one thread) or
    /// `@N` (all N threads).
    pub case: String,
    /// Median milliseconds per run.
    pub median_ms: f64,
    /// Cells per second at the median.
    pub cells_per_second: f64,
}

/// All cases on one window size.
#[derive(Clone, Debug, Serialize)]
pub struct WindowReport {
    /// Cells per side.
    pub size: usize,
    /// Cells in the window.
    pub cells: usize,
    /// Threads of the "all threads" cases.
    pub threads: usize,
    /// The inputs of `step` and `naive`: `"real"` (the SensorGrid of the real scan and the
    /// GISGrid of the real map, as `frame` sees them) or `"random"` (random grids whose map
    /// context changes every 8 cells on average: a worst case for the kernel).
    pub step_inputs: &'static str,
    /// Observed cells (non-vacuous SensorGrid) in the step's inputs, as a fraction.
    pub observed_fraction: f64,
    /// Bytes one step reads plus writes if it reads and writes the whole state (the copy floor's
    /// traffic).
    pub bytes_moved_per_step: usize,
    /// Bytes the library's step actually read and wrote, on the last timed step: it skips the
    /// planes it knows hold +0 in a block (`StepStats::state_bytes_moved`).
    pub bytes_step_moved: u64,
    /// Bytes of state per window cell: PerceptionGrid + SensorGrid + GisGrid (independent of the
    /// drive's length).
    pub state_bytes_per_cell: f64,
    /// The timings.
    pub timings: Vec<CaseTiming>,
    /// Paired ratios: median over rounds of `time(a) / time(b)`.
    pub ratios: Vec<(String, f64)>,
    /// The ratios that have a target ([`target_of`]), with the target and whether it is met.
    pub checks: Vec<RatioCheck>,
}

/// A ratio against its target.
#[derive(Clone, Debug, Serialize)]
pub struct RatioCheck {
    /// Ratio name.
    pub ratio: String,
    /// Measured value.
    pub value: f64,
    /// The target.
    pub target: Target,
    /// Whether the value meets it.
    pub met: bool,
}

impl WindowReport {
    /// The ratio with this name (`"copy/step"`, `"naive/step"`, …).
    pub fn ratio(&self, name: &str) -> Option<f64> {
        self.ratios.iter().find(|(n, _)| n == name).map(|(_, r)| *r)
    }

    /// The timing of one case.
    pub fn timing(&self, case: &str) -> Option<&CaseTiming> {
        self.timings.iter().find(|t| t.case == case)
    }
}

/// A target a ratio should meet (issue 5 of the project): at least or at most a bound.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Target {
    /// `true`: the ratio should be at least `bound`; `false`: at most.
    pub at_least: bool,
    /// The bound.
    pub bound: f64,
}

impl Target {
    /// Whether `value` meets the target.
    pub fn is_met(&self, value: f64) -> bool {
        if self.at_least {
            value >= self.bound
        } else {
            value <= self.bound
        }
    }
}

impl std::fmt::Display for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let op = if self.at_least { "≥" } else { "≤" };
        write!(f, "{op} {}", self.bound)
    }
}

/// The target of a ratio by name, if it has one: `copy/step@1` ≥ 0.75, `naive/step@1` ≥ 100,
/// `step@1/step@N` ≥ 1.6, `(sensor+prior)/step@1` ≤ 1, `frame@N/copy@N` ≤ 2. The targets are
/// stated for 1000 × 1000 cells; smaller windows are shown against them for comparison.
pub fn target_of(ratio: &str) -> Option<Target> {
    let (at_least, bound) = match ratio {
        "copy/step@1" => (true, 0.75),
        "naive/step@1" => (true, 100.0),
        "step@1/step@N" => (true, 1.6),
        "(sensor+prior)/step@1" => (false, 1.0),
        "frame@N/copy@N" => (false, 2.0),
        _ => return None,
    };
    Some(Target { at_least, bound })
}

/// A bench run.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// One report per window size.
    pub windows: Vec<WindowReport>,
    /// Largest difference between the naive step and the library's on random cells.
    pub naive_max_difference: f32,
    /// False when the bench was stopped before its last round ([`run_until`]): the windows
    /// report the rounds measured (a window with none is left out).
    pub complete: bool,
}

/// Runs the bench. `progress` receives a short description of each round as it starts.
///
/// # Errors
/// Invalid options, a naive step that disagrees with the library, or real inputs that cannot be
/// read.
pub fn run(options: &BenchOptions, progress: impl FnMut(&str)) -> Result<BenchReport, BenchError> {
    run_until(options, &AtomicBool::new(false), progress)
}

/// [`run`] that stops between two rounds once `stop` is raised (a signal): the report of the
/// rounds measured, [`BenchReport::complete`] false.
///
/// # Errors
/// As [`run`].
pub fn run_until(
    options: &BenchOptions,
    stop: &AtomicBool,
    mut progress: impl FnMut(&str),
) -> Result<BenchReport, BenchError> {
    if options.sizes.contains(&0) || options.rounds == 0 {
        return Err(BenchError::InvalidOption(
            "sizes and rounds must be positive".into(),
        ));
    }
    let params = Params::default();
    let naive_max_difference = workload::max_difference_after_steps(&params, 256, 20, 11);
    if naive_max_difference.is_nan() || naive_max_difference >= 1e-5 {
        return Err(BenchError::NaiveDisagrees {
            difference: naive_max_difference,
        });
    }
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| BenchError::ThreadPool(e.to_string()))?;
    let threads = rayon::current_num_threads();
    let mut windows = Vec::new();
    let mut complete = true;
    for &size in &options.sizes {
        if stop.load(Ordering::Relaxed) {
            complete = false;
            break;
        }
        let mut cases = Cases::new(size, &params, options, threads)?;
        let mut rounds: Vec<Vec<(String, f64)>> = Vec::new();
        for round in 0..=options.rounds {
            if stop.load(Ordering::Relaxed) {
                complete = false;
                break;
            }
            progress(&format!("{size}×{size}: round {round}/{}", options.rounds));
            let with_naive = round >= 1 && round <= options.naive_rounds;
            let times = cases.round(&one_thread, with_naive)?;
            if round > 0 {
                rounds.push(times);
            }
        }
        if rounds.is_empty() {
            break;
        }
        windows.push(cases.report(&rounds));
    }
    Ok(BenchReport {
        windows,
        naive_max_difference,
        complete,
    })
}

/// The state every case of one window size works on.
struct Cases<'a> {
    size: usize,
    threads: usize,
    params: &'a Params,
    pg: PerceptionGrid,
    sg: evigrid::SensorGrid,
    gg: evigrid::GisGrid,
    naive: naive::NaiveGrid,
    floor: copy::CopyFloor,
    real: Option<real::RealCases>,
    /// `StepStats::state_bytes_moved` of the last timed step.
    step_bytes_moved: u64,
    /// One grid and one single-thread pool per thread, for `apart@N`.
    apart: Vec<(PerceptionGrid, rayon::ThreadPool)>,
}

impl<'a> Cases<'a> {
    fn new(
        size: usize,
        params: &'a Params,
        options: &BenchOptions,
        threads: usize,
    ) -> Result<Self, BenchError> {
        let real = match &options.real {
            Some(inputs) => Some(real::RealCases::new(inputs, size, options.cell_size_m)?),
            None => None,
        };
        // The step's inputs: what the real scan and map give at the map's centre, else random
        // grids (every block of cells then holds several map contexts: a worst case).
        let (sg, gg) = match &real {
            Some(real) => (
                real.step_sensor_grid().clone(),
                real.step_gis_grid().clone(),
            ),
            None => {
                let mut rng = workload::SplitMix64::new(size as u64);
                let sg = workload::random_sensor_grid(size, size, &mut rng);
                (sg, workload::random_gis_grid(size, size, &mut rng))
            }
        };
        let pg = PerceptionGrid::new(size, size);
        let naive = naive::NaiveGrid::from_perception(&pg);
        let apart = (0..threads)
            .map(|_| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .build()
                    .map_err(|e| BenchError::ThreadPool(e.to_string()))?;
                Ok((pg.clone(), pool))
            })
            .collect::<Result<_, BenchError>>()?;
        Ok(Cases {
            size,
            threads,
            params,
            pg,
            sg,
            gg,
            naive,
            floor: copy::CopyFloor::new(size * size),
            real,
            step_bytes_moved: 0,
            apart,
        })
    }

    /// Runs every case once; returns (case, seconds).
    fn round(
        &mut self,
        one_thread: &rayon::ThreadPool,
        with_naive: bool,
    ) -> Result<Vec<(String, f64)>, BenchError> {
        let n = self.threads;
        let mut times = Vec::new();
        let size = self.size;
        let (pg, sg, gg, params) = (&mut self.pg, &self.sg, &self.gg, self.params);
        let floor = &mut self.floor;
        times.push((
            "copy@1".into(),
            one_thread.install(|| time(|| floor.run(size))),
        ));
        // How long this machine takes to get every thread of an idle pool running: not part of
        // any case below, which start with the threads awake (see `wake_threads`).
        times.push((format!("wake@{n}"), time(wake_threads)));
        wake_threads();
        times.push((format!("copy@{n}"), time(|| floor.run(size))));
        let mut stats = evigrid::StepStats::default();
        times.push((
            "step@1".into(),
            one_thread.install(|| time(|| stats = evigrid::step(pg, sg, gg, params, 0.1))),
        ));
        self.step_bytes_moved = stats.state_bytes_moved;
        wake_threads();
        times.push((
            format!("step@{n}"),
            time(|| evigrid::step(pg, sg, gg, params, 0.1)),
        ));
        let apart = step_apart(&mut self.apart, sg, gg, params);
        times.push((
            format!("apart@{n}"),
            apart.iter().copied().fold(0.0, f64::max),
        ));
        times.push((
            format!("apart-fastest@{n}"),
            apart.iter().copied().fold(f64::INFINITY, f64::min),
        ));
        times.push((format!("ideal@{n}"), ideal_parallel_time(&apart)));
        if with_naive {
            let naive = &mut self.naive;
            times.push(("naive@1".into(), time(|| naive.step(sg, gg, params, 0.1))));
        }
        if let Some(real) = &mut self.real {
            times.extend(real.round(one_thread, n)?);
        }
        Ok(times)
    }

    fn report(&self, rounds: &[Vec<(String, f64)>]) -> WindowReport {
        let cells = self.size * self.size;
        let mut names: Vec<String> = Vec::new();
        for (name, _) in rounds.iter().flatten() {
            if !names.contains(name) {
                names.push(name.clone());
            }
        }
        let timings = names
            .iter()
            .map(|name| {
                let seconds = median(rounds.iter().filter_map(|r| lookup(r, name)).collect());
                CaseTiming {
                    case: name.clone(),
                    median_ms: seconds * 1e3,
                    cells_per_second: cells as f64 / seconds,
                }
            })
            .collect();
        let n = self.threads;
        let pairs = [
            ("copy/step@1", "copy@1".to_string(), "step@1".to_string()),
            ("copy/step@N", format!("copy@{n}"), format!("step@{n}")),
            ("naive/step@1", "naive@1".into(), "step@1".into()),
            ("step@1/step@N", "step@1".into(), format!("step@{n}")),
            ("apart@N/step@1", format!("apart@{n}"), "step@1".into()),
            (
                "apart@N/apart-fastest@N",
                format!("apart@{n}"),
                format!("apart-fastest@{n}"),
            ),
            ("step@1/ideal@N", "step@1".into(), format!("ideal@{n}")),
            ("ideal@N/step@N", format!("ideal@{n}"), format!("step@{n}")),
            (
                "(sensor+prior)/step@1",
                "sensor+prior@1".into(),
                "step@1".into(),
            ),
            ("frame@N/copy@N", format!("frame@{n}"), format!("copy@{n}")),
            ("ground@1/step@1", "ground@1".into(), "step@1".into()),
            ("odometry@1/step@1", "odometry@1".into(), "step@1".into()),
        ];
        let ratios: Vec<(String, f64)> = pairs
            .iter()
            .filter_map(|(label, a, b)| {
                let per_round: Vec<f64> = rounds
                    .iter()
                    .filter_map(|r| Some(lookup(r, a)? / lookup(r, b)?))
                    .collect();
                (!per_round.is_empty()).then(|| (label.to_string(), median(per_round)))
            })
            .collect();
        let floor = &self.floor;
        let observed = self
            .sg
            .m_free()
            .iter()
            .zip(self.sg.m_occupied())
            .filter(|(free, occupied)| **free + **occupied > 0.0)
            .count();
        WindowReport {
            size: self.size,
            cells,
            step_inputs: if self.real.is_some() {
                "real"
            } else {
                "random"
            },
            observed_fraction: observed as f64 / cells as f64,
            threads: n,
            bytes_moved_per_step: floor.bytes_moved(),
            bytes_step_moved: self.step_bytes_moved,
            state_bytes_per_cell: state_bytes(&self.pg, &self.sg, &self.gg) as f64 / cells as f64,
            timings,
            checks: ratios
                .iter()
                .filter_map(|(ratio, value)| {
                    let target = target_of(ratio)?;
                    Some(RatioCheck {
                        ratio: ratio.clone(),
                        value: *value,
                        target,
                        met: target.is_met(*value),
                    })
                })
                .collect(),
            ratios,
        }
    }
}

/// Bytes the three grids of the pipeline hold.
fn state_bytes(pg: &PerceptionGrid, sg: &evigrid::SensorGrid, gg: &evigrid::GisGrid) -> usize {
    pg.state_bytes() + sg.state_bytes() + std::mem::size_of_val(gg.context.as_slice())
}

fn lookup(round: &[(String, f64)], name: &str) -> Option<f64> {
    round.iter().find(|(n, _)| n == name).map(|(_, t)| *t)
}

/// Seconds each of N one-thread steps took, run at once, each on its own grid and thread.
///
/// Nothing is shared but the machine, so the slowest of them over `step@1` (`apart@N/step@1`)
/// says how much slower one step runs when every core runs one: 1 where memory and the cores
/// keep up, more where they are shared (with each other, or with other tenants of a virtual
/// machine). The slowest over the fastest (`apart@N/apart-fastest@N`) says how unequal the
/// cores were: the same work at the same moment, 1 on equal cores. [`ideal_parallel_time`]
/// turns the N times into an estimate of the fastest `step@N` the cores allowed.
fn step_apart(
    grids: &mut [(PerceptionGrid, rayon::ThreadPool)],
    sg: &evigrid::SensorGrid,
    gg: &evigrid::GisGrid,
    params: &Params,
) -> Vec<f64> {
    let start = std::sync::Barrier::new(grids.len());
    std::thread::scope(|scope| {
        let runs: Vec<_> = grids
            .iter_mut()
            .map(|(grid, pool)| {
                let start = &start;
                scope.spawn(move || {
                    start.wait();
                    pool.install(|| time(|| evigrid::step(grid, sg, gg, params, 0.1)))
                })
            })
            .collect();
        runs.into_iter()
            .map(|run| {
                run.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
            .collect()
    })
}

/// The time of one step shared among cores that each step a whole grid in `apart[k]` seconds
/// when all run at once: each core takes the share of the cells its speed allows, so that all
/// finish together, at 1 / Σ 1/apart[k].
///
/// This is what the cores gave in that moment, as a `step@N` time. On an idle machine with
/// equal cores it is `step@1 / N`; where a core is slowed (by another tenant of a virtual
/// machine, or by memory that does not keep up), it is more, and `step@1/ideal@N` is the
/// speed-up the machine allowed. `ideal@N/step@N` is the share of it the step reached: about 1
/// when the work is shared well. It is an estimate, not a bound: N grids move more memory than
/// one, so a step on one grid can beat it a little.
fn ideal_parallel_time(apart: &[f64]) -> f64 {
    1.0 / apart.iter().map(|seconds| 1.0 / seconds).sum::<f64>()
}

/// Runs a no-op on every thread of the current pool and returns once all have run it, so that
/// the next parallel case starts with its threads awake.
///
/// On this kind of virtual machine a thread that slept for a few milliseconds usually runs again
/// within 0.1 ms, but now and then only after 2-4 ms (the hypervisor reschedules an idle virtual
/// CPU at its next tick; `wake@N` in the report is the median). Timed into a 10 ms case, that
/// latency would be measured instead of the kernel.
pub fn wake_threads() {
    rayon::broadcast(|_| ());
}

/// Seconds one call of `f` takes.
pub fn time<R>(f: impl FnOnce() -> R) -> f64 {
    let start = Instant::now();
    std::hint::black_box(f());
    start.elapsed().as_secs_f64()
}

/// Median of a non-empty list (mean of the middle two for an even count); NaN for an empty one.
pub fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len().is_multiple_of(2) {
        (values[mid - 1] + values[mid]) / 2.0
    } else {
        values[mid]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(vec![]).is_nan());
    }

    #[test]
    fn a_small_run_reports_every_synthetic_case_and_ratio() -> Result<(), BenchError> {
        let options = BenchOptions {
            sizes: vec![48],
            rounds: 2,
            naive_rounds: 1,
            ..BenchOptions::default()
        };
        let report = run(&options, |_| {})?;
        let window = &report.windows[0];
        for case in ["copy@1", "step@1", "naive@1"] {
            assert!(window.timing(case).is_some(), "missing {case}");
        }
        for ratio in [
            "copy/step@1",
            "naive/step@1",
            "step@1/step@N",
            "apart@N/step@1",
            "apart@N/apart-fastest@N",
            "step@1/ideal@N",
            "ideal@N/step@N",
        ] {
            let value = window.ratio(ratio);
            assert!(value.is_some_and(|r| r > 0.0), "{ratio}: {value:?}");
        }
        // 32 mass planes, ζ, ∅_FO, ∅_OF (4 B each), seen (1 B), non-zero plane bits (8 B per
        // 64 cells); SensorGrid 8 B and 1 B per 64 cells; GisGrid 1 B.
        assert_eq!(window.state_bytes_per_cell, 150.140625);
        let moved = window.bytes_step_moved as usize;
        assert!(moved > 0 && moved < window.bytes_moved_per_step, "{moved}");
        Ok(())
    }

    #[test]
    fn ideal_parallel_time_shares_the_cells_by_speed() {
        // Equal cores: the step in N parts.
        assert_eq!(ideal_parallel_time(&[0.01, 0.01]), 0.005);
        // One core at 0.5 speed does a third of the cells: 20 ms alone on the fast one, 13.3 ms.
        let shared = ideal_parallel_time(&[0.02, 0.04]);
        assert!((shared - 0.04 / 3.0).abs() < 1e-12, "{shared}");
        assert_eq!(ideal_parallel_time(&[0.01]), 0.01);
    }

    #[test]
    fn targets_say_at_least_or_at_most() {
        let floor = target_of("copy/step@1");
        assert!(floor.is_some_and(|t| t.is_met(0.75) && !t.is_met(0.74)));
        let frame = target_of("frame@N/copy@N");
        assert!(frame.is_some_and(|t| t.is_met(2.0) && !t.is_met(2.01)));
        assert_eq!(target_of("copy/step@N"), None);
        let naive = target_of("naive/step@1").map(|t| t.to_string());
        assert_eq!(naive.as_deref(), Some("≥ 100"));
    }

    #[test]
    fn a_raised_stop_ends_the_bench_between_rounds() -> Result<(), BenchError> {
        let options = BenchOptions {
            sizes: vec![16, 32],
            rounds: 5,
            naive_rounds: 0,
            ..BenchOptions::default()
        };
        let stop = AtomicBool::new(false);
        let mut started = Vec::new();
        // Raised as round 2 of the first window starts: it runs, round 3 does not.
        let report = run_until(&options, &stop, |round| {
            started.push(round.to_string());
            if round.ends_with("round 2/5") {
                stop.store(true, Ordering::Relaxed);
            }
        })?;
        assert_eq!(
            started,
            ["16×16: round 0/5", "16×16: round 1/5", "16×16: round 2/5"]
        );
        assert!(!report.complete);
        assert_eq!(report.windows.len(), 1);
        assert_eq!(report.windows[0].size, 16);
        Ok(())
    }

    #[test]
    fn zero_sizes_are_rejected() {
        let options = BenchOptions {
            sizes: vec![0],
            ..BenchOptions::default()
        };
        assert!(matches!(
            run(&options, |_| {}),
            Err(BenchError::InvalidOption(_))
        ));
    }
}
