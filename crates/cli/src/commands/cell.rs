//! `evigrid cell`: one cell through a sequence of observations, step by step.
//!
//! To see what the method does with a given context, parameters and observation history: the
//! cell is a 1 × 1 grid run through the same kernel as every grid (`evigrid::step`).

use crate::exit::BadInput;
use anyhow::Context as _;
use clap::{Args, ValueEnum};
use evigrid::motion::{MotionMass, combine};
use evigrid::{GisGrid, N_SETS, Params, PerceptionGrid, SensorGrid, betp, class, decide};
use geodata::MapContext;
use serde::Serialize;
use std::path::PathBuf;

/// Masses below this are not listed (they are f32 rounding, not evidence).
const SHOWN_MASS: f32 = 1e-6;

/// Arguments of `evigrid cell`.
#[derive(Debug, Args)]
pub struct CellArgs {
    /// Map context of the cell (the GISGrid prior).
    #[arg(long, value_enum, default_value_t = ContextArg::None)]
    context: ContextArg,
    /// Parameters as TOML (SPEC §7 layout, any subset); defaults otherwise.
    #[arg(long, value_name = "FILE.toml")]
    config: Option<PathBuf>,
    /// Time between steps, seconds.
    #[arg(
        long,
        default_value_t = 0.1,
        value_name = "SECONDS",
        allow_hyphen_values = true
    )]
    dt: f64,
    /// Observations, comma-separated: `free` (m(F) = μ_F), `occupied` (m(O) = μ_O), `none`
    /// (vacuous), an explicit `mF/mO` pair such as `0.6/0.1`; `X+moving` or `X+static` adds the
    /// motion stage's evidence (m({M}) = motion.mu_moving, or m(Ω∖{M}) = motion.mu_static, as
    /// the `evigrid` method combines it after the step); `X*N` repeats X N times.
    #[arg(long, required = true, value_name = "LIST", allow_hyphen_values = true)]
    observe: String,
    /// Print a JSON array, one object per step, instead of a table.
    #[arg(long)]
    json: bool,
}

/// The map context given on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum ContextArg {
    /// Inside a building: prior β_B on {I}.
    Building,
    /// On the road surface: prior β_R on {F, S, M}.
    Road,
    /// Mapped area outside buildings and roads: prior β_T on {F, U, S, M}.
    Other,
    /// Beside a building (the `evigrid` method's boundary-aware prior): β_B on {F, I}.
    BuildingEdge,
    /// No map: vacuous prior.
    None,
}

impl From<ContextArg> for MapContext {
    fn from(c: ContextArg) -> MapContext {
        match c {
            ContextArg::Building => MapContext::Building,
            ContextArg::Road => MapContext::Road,
            ContextArg::Other => MapContext::Other,
            ContextArg::BuildingEdge => MapContext::BuildingEdge,
            ContextArg::None => MapContext::Unknown,
        }
    }
}

/// One observation: the SensorGrid masses m(F), m(O) of the cell, and the motion evidence the
/// cell's cluster gave it, if any.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
struct Observation {
    free: f64,
    occupied: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    motion: Option<Motion>,
}

/// The motion stage's verdict on the cell's cluster (`docs/motion.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
enum Motion {
    /// A moving track: m({M}) = `motion.mu_moving` (at full confidence).
    Moving,
    /// A static track: m(Ω∖{M}) = `motion.mu_static`.
    Static,
}

/// What one step left in the cell.
#[derive(Debug, Serialize)]
struct StepRecord {
    step: usize,
    observation: Observation,
    mass: Vec<SetMass>,
    betp: ClassProbabilities,
    zeta: f64,
    conflict_fo: f64,
    conflict_of: f64,
    decision: &'static str,
}

#[derive(Debug, Serialize)]
struct SetMass {
    set: Vec<String>,
    m: f64,
}

#[derive(Debug, Serialize)]
#[allow(non_snake_case)]
struct ClassProbabilities {
    F: f64,
    I: f64,
    U: f64,
    S: f64,
    M: f64,
}

/// Runs `evigrid cell`.
pub fn run(args: CellArgs) -> anyhow::Result<()> {
    let params = crate::input::read_params(args.config.as_deref())?;
    if !(args.dt >= 0.0 && args.dt.is_finite()) {
        return Err(BadInput::new(format!(
            "--dt {}: must be a finite number of seconds ≥ 0",
            args.dt
        )));
    }
    let observations = parse_observations(&args.observe, &params)?;
    let records = simulate(&observations, args.context.into(), &params, args.dt);
    let out = if args.json {
        serde_json::to_string_pretty(&records).context("writing JSON")? + "\n"
    } else {
        table(&records)
    };
    crate::out!("{out}");
    Ok(())
}

/// Most observations one `--observe` list may expand to: far more steps than a cell needs to
/// converge (discounting forgets within tens), small enough to print.
const MAX_OBSERVATIONS: usize = 100_000;

/// Parses `free*2,occupied,0.6/0.1,none`.
fn parse_observations(list: &str, params: &Params) -> anyhow::Result<Vec<Observation>> {
    let mut observations = Vec::new();
    for item in list.split(',').map(str::trim) {
        let bad = |why: &str| BadInput::new(format!("--observe: {item:?}: {why}"));
        let (token, repeat) = match item.rsplit_once('*') {
            Some((token, n)) => {
                let n: usize = n
                    .trim()
                    .parse()
                    .map_err(|_| bad("the repeat count after `*` must be a whole number"))?;
                if n == 0 {
                    return Err(bad("the repeat count must be at least 1"));
                }

                (token.trim(), n)
            }
            None => (item, 1),
        };
        let (token, motion) = match token.rsplit_once('+') {
            Some((t, "moving")) => (t.trim(), Some(Motion::Moving)),
            Some((t, "static")) => (t.trim(), Some(Motion::Static)),
            Some(_) => return Err(bad("the motion after `+` must be `moving` or `static`")),
            None => (token, None),
        };
        let observation = match token {
            "free" => Observation {
                free: params.sensor.mu_free,
                occupied: 0.0,
                motion,
            },
            "occupied" => Observation {
                free: 0.0,
                occupied: params.sensor.mu_occupied,
                motion,
            },
            "none" => Observation {
                free: 0.0,
                occupied: 0.0,
                motion,
            },
            pair => {
                let Some((f, o)) = pair.split_once('/') else {
                    return Err(bad(
                        "expected free, occupied, none or an mF/mO pair such as 0.6/0.1",
                    ));
                };
                let parse = |s: &str| s.trim().parse::<f64>().ok().filter(|x| x.is_finite());
                let (Some(free), Some(occupied)) = (parse(f), parse(o)) else {
                    return Err(bad("mF and mO must be numbers"));
                };
                if free < 0.0 || occupied < 0.0 {
                    return Err(bad("masses must not be negative"));
                }
                if free + occupied > 1.0 + 1e-9 {
                    return Err(bad("mF + mO must not exceed 1"));
                }
                Observation {
                    free,
                    occupied,
                    motion,
                }
            }
        };
        if repeat > MAX_OBSERVATIONS - observations.len() {
            return Err(bad(&format!(
                "the list expands to more than {MAX_OBSERVATIONS} observations"
            )));
        }
        observations.extend(std::iter::repeat_n(observation, repeat));
    }
    Ok(observations)
}

/// Runs the observations through a 1 × 1 grid and records each step.
fn simulate(
    observations: &[Observation],
    context: MapContext,
    params: &Params,
    dt_s: f64,
) -> Vec<StepRecord> {
    let mut pg = PerceptionGrid::new(1, 1);
    let mut sg = SensorGrid::new(1, 1);
    let mut gg = GisGrid::new(1, 1);
    gg.context[0] = context;
    let mut records = Vec::with_capacity(observations.len());
    for (k, observation) in observations.iter().enumerate() {
        sg.m_free_mut()[0] = observation.free as f32;
        sg.m_occupied_mut()[0] = observation.occupied as f32;
        evigrid::step(&mut pg, &sg, &gg, params, dt_s);
        if let Some(motion) = observation.motion {
            // As the `evigrid` method does after the step: the motion belief combined
            // conjunctively, its conflict following the residual policy.
            let evidence = match motion {
                Motion::Moving => MotionMass::Moving(params.motion.mu_moving as f32),
                Motion::Static => MotionMass::Static(params.motion.mu_static as f32),
            };
            let mut masses = pg.cell_masses(0);
            combine(&mut masses, evidence, params.fusion.residual);
            pg.set_cell_masses(0, &masses);
        }
        let masses = pg.cell_masses(0);
        let p = betp(&masses);
        let seen = pg.seen()[0] != 0;
        records.push(StepRecord {
            step: k + 1,
            observation: *observation,
            mass: (0..N_SETS)
                .filter(|&set| masses[set] >= SHOWN_MASS)
                .map(|set| SetMass {
                    set: set_letters(set),
                    m: short(masses[set]),
                })
                .collect(),
            betp: ClassProbabilities {
                F: short(p[0]),
                I: short(p[1]),
                U: short(p[2]),
                S: short(p[3]),
                M: short(p[4]),
            },
            zeta: short(pg.zeta()[0]),
            conflict_fo: short(pg.conflict_fo()[0]),
            conflict_of: short(pg.conflict_of()[0]),
            decision: decide(&masses, seen, params.decision.unknown_threshold).name(),
        });
    }
    records
}

/// The class letters of a set, in frame order (∅ is the empty list).
fn set_letters(set: usize) -> Vec<String> {
    class::LETTERS
        .iter()
        .enumerate()
        .filter(|(k, _)| set & (1 << k) != 0)
        .map(|(_, c)| c.to_string())
        .collect()
}

/// An f32 as the f64 with the same shortest decimal form (0.7_f32 → 0.7, not 0.699999988).
fn short(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// The records as an aligned table, one row per step.
fn table(records: &[StepRecord]) -> String {
    let mut out = format!(
        "{:>4}  {:>11}  {:>6} {:>6} {:>6} {:>6} {:>6}  {:>6} {:>6} {:>6}  {:<8}  {}\n",
        "step", "observed", "betP F", "I", "U", "S", "M", "ζ", "∅FO", "∅OF", "decision", "masses"
    );
    for r in records {
        let motion = match r.observation.motion {
            Some(Motion::Moving) => "+M",
            Some(Motion::Static) => "+¬M",
            None => "",
        };
        let observed = format!(
            "{:.2}/{:.2}{motion}",
            r.observation.free, r.observation.occupied
        );
        let masses: Vec<String> = r
            .mass
            .iter()
            .map(|sm| {
                let name = if sm.set.len() == 5 {
                    "Ω".to_string()
                } else if sm.set.is_empty() {
                    "∅".to_string()
                } else {
                    format!("{{{}}}", sm.set.join(","))
                };
                format!("{name}={:.4}", sm.m)
            })
            .collect();
        let b = &r.betp;
        out += &format!(
            "{:>4}  {:>11}  {:>6.4} {:>6.4} {:>6.4} {:>6.4} {:>6.4}  {:>6.4} {:>6.4} {:>6.4}  {:<8}  {}\n",
            r.step,
            observed,
            b.F,
            b.I,
            b.U,
            b.S,
            b.M,
            r.zeta,
            r.conflict_fo,
            r.conflict_of,
            r.decision,
            masses.join(" ")
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observation_list_expands_repeats_and_pairs() -> anyhow::Result<()> {
        let p = Params::default();
        let obs = parse_observations("free*2, occupied,none,0.6/0.1", &p)?;
        assert_eq!(obs.len(), 5);
        assert_eq!(
            obs[1],
            Observation {
                free: 0.7,
                occupied: 0.0,
                motion: None,
            }
        );
        assert_eq!(
            obs[2],
            Observation {
                free: 0.0,
                occupied: 0.8,
                motion: None,
            }
        );
        assert_eq!(
            obs[3],
            Observation {
                free: 0.0,
                occupied: 0.0,
                motion: None,
            }
        );
        assert_eq!(
            obs[4],
            Observation {
                free: 0.6,
                occupied: 0.1,
                motion: None,
            }
        );
        Ok(())
    }

    #[test]
    fn bad_observations_are_rejected() {
        let p = Params::default();
        for bad in [
            "fre",
            "free*0",
            "free*x",
            "free*1000000000000",
            "free*60000,occupied*60000",
            "0.7/0.4",
            "-0.1/0.2",
            "a/b",
            "0.5",
            "",
        ] {
            assert!(parse_observations(bad, &p).is_err(), "{bad}");
        }
    }

    #[test]
    fn set_letters_follow_bit_order() {
        assert_eq!(set_letters(0b10101), ["F", "U", "M"]);
        assert!(set_letters(0).is_empty());
    }

    #[test]
    fn motion_evidence_is_combined_after_the_step() -> anyhow::Result<()> {
        let p = Params::default();
        let obs = parse_observations("free*5,occupied,occupied+moving,occupied+static", &p)?;
        assert_eq!(obs[6].motion, Some(Motion::Moving));
        assert_eq!(obs[7].motion, Some(Motion::Static));
        let records = simulate(&obs, MapContext::Road, &p, 0.1);
        // The car appeared on a road seen free: M by the paper's conflict rule, more M with the
        // motion stage's evidence, and not M once a static track says so.
        let m = |k: usize| records[k].betp.M;
        assert_eq!(records[5].decision, "M");
        assert!(m(6) > m(5), "{} vs {}", m(6), m(5));
        assert!(m(7) < 0.5 * m(6), "{} vs {}", m(7), m(6));
        assert_ne!(records[7].decision, "M");
        Ok(())
    }

    #[test]
    fn beside_a_building_free_is_free_and_a_return_is_the_building() -> anyhow::Result<()> {
        let p = Params::default();
        let obs = parse_observations("free*3,occupied*3", &p)?;
        let records = simulate(&obs, ContextArg::BuildingEdge.into(), &p, 0.1);
        // In the building's own context the free space would be decided I (β_B on {I} wins
        // over the sensor's m(F)); beside it, the prior {F, I} leaves the choice to the sensor.
        assert_eq!(records[2].decision, "F");
        assert_eq!(records[5].decision, "I");
        let inside = simulate(&obs, MapContext::Building, &p, 0.1);
        assert_eq!(inside[2].decision, "I");
        Ok(())
    }
}
