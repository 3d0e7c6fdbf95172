//! `evigrid.mass`: the `belief` crate's calculator on mass functions handed over from Python.
//!
//! The Python layer (`python/evigrid/mass.py`) turns the user's dicts into [`MassArg`]s, plain
//! tuples of names and numbers, and builds dicts from what these functions return. The checks
//! and messages follow `evigrid mass` (`crates/cli/src/commands/mass`), input by input, so that a
//! script and the command line reject the same inputs in the same words, with the input's label
//! where the command line names the file.

use belief::{
    BeliefError, ClassRateDiscount, ClassicalDiscount, Combination, Conjunctive,
    ContextualDiscount, Dempster, Discounting, Disjunctive, DuboisPrade, Frame, Mass, Set, SetRate,
    Yager,
};
use pyo3::prelude::*;

use crate::error::input_error;

/// Focal sets as (element names, mass) pairs.
type Focal = Vec<(Vec<String>, f64)>;

/// A mass function as the Python layer passes it: the label that names it in messages (a file,
/// or the argument), the frame's element names in order, and its focal sets. A set listed
/// twice, an unknown name, a negative or non-finite mass or a sum other than one is an error.
#[derive(FromPyObject)]
pub struct MassArg(String, Vec<String>, Focal);

/// A checked mass function with its label.
struct Input {
    label: String,
    mass: Mass<f64>,
}

impl MassArg {
    /// Builds and checks the mass function; every problem is an `InputError` naming the label.
    fn parse(self) -> PyResult<Input> {
        let MassArg(label, names, focal) = self;
        let frame =
            Frame::new(names).map_err(|e| input_error(format!("{label}: bad frame: {e}")))?;
        let mut listed: Vec<Set> = Vec::with_capacity(focal.len());
        for (names, _) in &focal {
            let set = frame
                .set(names)
                .map_err(|e| input_error(format!("{label}: {}", e.describe_in(&frame))))?;
            if listed.contains(&set) {
                return Err(input_error(format!(
                    "{label}: set {} is listed twice",
                    frame.set_label(set)
                )));
            }
            listed.push(set);
        }
        let pairs = listed.into_iter().zip(focal.iter().map(|(_, m)| *m));
        let mass = Mass::from_focal(&frame, pairs)
            .map_err(|e| input_error(format!("{label}: {}", e.describe_in(&frame))))?;
        Ok(Input { label, mass })
    }
}

/// A mass function as the Python layer builds its dict from: the frame's names and the focal
/// sets in increasing bitmask order, zeros left out (the layout `evigrid mass` prints).
type MassOut = (Vec<String>, Focal);

fn mass_out(mass: &Mass<f64>) -> MassOut {
    let frame = mass.frame();
    let focal = mass
        .focal_sets()
        .map(|(set, m)| (names_of(frame, set), m))
        .collect();
    (frame.names().to_vec(), focal)
}

fn names_of(frame: &Frame, set: Set) -> Vec<String> {
    frame.names_of(set).into_iter().map(str::to_owned).collect()
}

/// The calculator's functions, the submodule `evigrid._evigrid.mass`.
#[pymodule]
pub mod mass {
    use super::*;

    /// Checks a mass function; returns it with its focal sets in bitmask order, zeros left out.
    #[pyfunction]
    fn check(m: MassArg) -> PyResult<MassOut> {
        Ok(mass_out(&m.parse()?.mass))
    }

    /// Combines two or more mass functions on one frame by `rule`: `conjunctive`, `dempster`,
    /// `disjunctive`, `yager` or `dubois-prade`. Associative rules apply left to right; Yager and
    /// Dubois–Prade use their n-ary form for more than two inputs.
    #[pyfunction]
    fn combine(rule: &str, inputs: Vec<MassArg>) -> PyResult<MassOut> {
        let rule: &dyn Combination<f64> = match rule {
            "conjunctive" => &Conjunctive,
            "dempster" => &Dempster,
            "disjunctive" => &Disjunctive,
            "yager" => &Yager,
            "dubois-prade" | "dubois_prade" => &DuboisPrade,
            other => {
                return Err(input_error(format!(
                    "rule {other:?}: expected one of conjunctive, dempster, disjunctive, yager, \
                     dubois-prade"
                )));
            }
        };
        if inputs.len() < 2 {
            return Err(input_error(format!(
                "combine: {} mass function(s) given, at least two needed",
                inputs.len()
            )));
        }
        let inputs = inputs
            .into_iter()
            .map(MassArg::parse)
            .collect::<PyResult<Vec<Input>>>()?;
        let Some((first, rest)) = inputs.split_first() else {
            return Err(input_error("combine: no mass function given"));
        };
        for input in rest {
            if input.mass.frame() != first.mass.frame() {
                return Err(input_error(format!(
                    "{}: frame {} differs from frame {} of {}",
                    input.label,
                    input.mass.frame(),
                    first.mass.frame(),
                    first.label
                )));
            }
        }
        let masses: Vec<Mass<f64>> = inputs.iter().map(|i| i.mass.clone()).collect();
        let combined = rule.combine_all(&masses).map_err(|e| {
            let labels: Vec<&str> = inputs.iter().map(|i| i.label.as_str()).collect();
            let problem = e.describe_combination_in(first.mass.frame());
            input_error(format!("{}: {problem}", labels.join(", ")))
        })?;
        Ok(mass_out(&combined))
    }

    /// Discounts a mass function by exactly one mode: classical (`alpha`), contextual
    /// (`contexts`, Mercier et al. 2008: (set, rate) pairs) or by class rates (`class_rates`:
    /// (element, rate) pairs, one per element, with `set_rate` `min`, `max` (the default) or
    /// `mean`).
    #[pyfunction]
    #[pyo3(signature = (m, alpha=None, contexts=None, class_rates=None, set_rate=None))]
    fn discount(
        m: MassArg,
        alpha: Option<f64>,
        contexts: Option<Vec<(Vec<String>, f64)>>,
        class_rates: Option<Vec<(String, f64)>>,
        set_rate: Option<&str>,
    ) -> PyResult<MassOut> {
        let modes = [alpha.is_some(), contexts.is_some(), class_rates.is_some()];
        if modes.iter().filter(|&&given| given).count() != 1 {
            return Err(input_error(
                "discount: give exactly one of alpha, contexts and class_rates",
            ));
        }
        if set_rate.is_some() && class_rates.is_none() {
            return Err(input_error("set_rate: applies only with class_rates"));
        }
        let input = m.parse()?;
        let frame = input.mass.frame();
        let discounted = if let Some(alpha) = alpha {
            ClassicalDiscount::new(alpha)
                .and_then(|d| d.discount(&input.mass))
                .map_err(|e| input_error(format!("alpha {alpha}: {e}")))?
        } else if let Some(contexts) = contexts {
            let contexts = contexts
                .iter()
                .map(|(names, rate)| {
                    let given = format!("contexts {}={rate}", names.join("+"));
                    let set = frame.set(names).map_err(|e| match e {
                        BeliefError::UnknownElement { name, .. } => input_error(format!(
                            "{given}: element {name:?} is not in the frame {frame} of {}",
                            input.label
                        )),
                        other => input_error(format!("{given}: {other}")),
                    })?;
                    check_rate(&given, *rate)?;
                    Ok((set, *rate))
                })
                .collect::<PyResult<Vec<(Set, f64)>>>()?;
            ContextualDiscount::new(contexts)
                .and_then(|d| d.discount(&input.mass))
                .map_err(|e| input_error(format!("contexts: {e}")))?
        } else {
            class_rate_discount(&input, class_rates.unwrap_or_default(), set_rate)?
        };
        Ok(mass_out(&discounted))
    }

    /// The pignistic probability of each element, in frame order (normalised by 1 − m(∅)).
    #[pyfunction]
    fn pignistic(m: MassArg) -> PyResult<Vec<(String, f64)>> {
        let input = m.parse()?;
        let frame = input.mass.frame();
        let betp = input.mass.pignistic().map_err(|e| {
            input_error(format!(
                "{}: {}",
                input.label,
                e.describe_pignistic_in(frame)
            ))
        })?;
        Ok(frame.names().iter().cloned().zip(betp).collect())
    }

    /// The set function `to` (`belief`, `plausibility`, `commonality` or `implicability`) on
    /// every subset, in increasing bitmask order.
    #[pyfunction]
    fn transform(m: MassArg, to: &str) -> PyResult<Focal> {
        let input = m.parse()?;
        let mass = &input.mass;
        let function = match to {
            "belief" => mass.belief(),
            "plausibility" => mass.plausibility(),
            "commonality" => mass.commonality(),
            "implicability" => mass.implicability(),
            other => {
                return Err(input_error(format!(
                    "to {other:?}: expected one of belief, plausibility, commonality, \
                     implicability"
                )));
            }
        };
        let frame = mass.frame();
        Ok(frame
            .subsets()
            .map(|set| (names_of(frame, set), function.get(set)))
            .collect())
    }
}

/// Class-rate discounting (SPEC §5 step 3) with one rate per element of the frame.
fn class_rate_discount(
    input: &Input,
    class_rates: Vec<(String, f64)>,
    set_rate: Option<&str>,
) -> PyResult<Mass<f64>> {
    let frame = input.mass.frame();
    let mut rates: Vec<Option<f64>> = vec![None; frame.len()];
    for (name, rate) in &class_rates {
        let given = format!("class_rates {name}={rate}");
        let element = frame.element(name).map_err(|_| {
            input_error(format!(
                "{given}: element {name:?} is not in the frame {frame} of {}",
                input.label
            ))
        })?;
        check_rate(&given, *rate)?;
        if rates[element].replace(*rate).is_some() {
            return Err(input_error(format!(
                "{given}: element {name} is given twice"
            )));
        }
    }
    let rates = rates
        .iter()
        .zip(frame.names())
        .map(|(rate, name)| {
            rate.ok_or_else(|| {
                input_error(format!(
                    "class_rates: no rate for element {name} of {frame}"
                ))
            })
        })
        .collect::<PyResult<Vec<f64>>>()?;
    let set_rate = match set_rate {
        Some("min") => SetRate::Min,
        Some("max") | None => SetRate::Max,
        Some("mean") => SetRate::Mean,
        Some(other) => {
            return Err(input_error(format!(
                "set_rate {other:?}: expected min, max or mean"
            )));
        }
    };
    ClassRateDiscount::new(rates, set_rate)
        .and_then(|d| d.discount(&input.mass))
        .map_err(|e| input_error(format!("class_rates: {e}")))
}

/// A rate must lie in [0, 1].
fn check_rate(given: &str, rate: f64) -> PyResult<()> {
    if (0.0..=1.0).contains(&rate) {
        Ok(())
    } else {
        Err(input_error(format!(
            "{given}: rate {rate} is not in [0, 1]"
        )))
    }
}
