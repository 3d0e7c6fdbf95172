//! `evigrid mass`: a calculator for belief functions given as JSON files.
//!
//! ```text
//! evigrid mass combine --rule dempster A.json B.json [C.json ...]
//! evigrid mass discount --alpha 0.1 A.json
//! evigrid mass discount --context a=0.4 --context h+r=0.1 A.json
//! evigrid mass discount --class-rate a=0.1 --class-rate b=0.5 --set-rate max A.json
//! evigrid mass pignistic A.json
//! evigrid mass transform --to commonality A.json
//! ```
//!
//! Each file holds `{"frame": [...], "mass": [{"set": [...], "m": ...}, ...]}`; `-` reads standard
//! input. Results go to standard output as JSON (the default) or, with `--table`, as an aligned
//! table. Bad input exits with status 2 and one line on standard error naming the file and the
//! problem. All the arithmetic is the `belief` crate's.

mod json;

use std::path::PathBuf;

use anyhow::Result;
use belief::{
    BeliefError, ClassRateDiscount, ClassicalDiscount, Combination, Conjunctive,
    ContextualDiscount, Dempster, Discounting, Disjunctive, DuboisPrade, Frame, Mass, Set, SetRate,
    Yager,
};
use clap::{ArgGroup, Args, Subcommand, ValueEnum};

use crate::exit::BadInput;
use json::{Input, read_input};

/// Subcommands of `evigrid mass`.
#[derive(Debug, Subcommand)]
pub enum MassCommand {
    /// Combine two or more mass functions on the same frame.
    ///
    /// Associative rules are applied left to right; Yager and Dubois–Prade use their n-ary form
    /// for more than two inputs.
    Combine(CombineArgs),
    /// Discount a mass function: classical (--alpha), contextual (--context, Mercier et al. 2008)
    /// or by class rates (--class-rate).
    Discount(DiscountArgs),
    /// The pignistic probability of each element (normalised by 1 − m(∅)).
    Pignistic(SingleArgs),
    /// Belief, plausibility, commonality or implicability of every subset.
    Transform(TransformArgs),
}

/// Output format shared by every `evigrid mass` subcommand.
#[derive(Debug, Args)]
pub struct OutputArgs {
    /// Print an aligned table for people instead of JSON.
    #[arg(long, conflicts_with = "json")]
    table: bool,
    /// Print JSON (the default; the flag only makes it explicit).
    #[arg(long)]
    json: bool,
}

/// Arguments of `evigrid mass combine`.
#[derive(Debug, Args)]
pub struct CombineArgs {
    /// The combination rule.
    #[arg(long, value_enum)]
    rule: Rule,
    /// Mass function files (JSON), at least two; `-` is standard input.
    #[arg(required = true, num_args = 2..)]
    inputs: Vec<PathBuf>,
    #[command(flatten)]
    output: OutputArgs,
}

/// The combination rules of SPEC §1.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum Rule {
    /// Unnormalised conjunctive rule (conflict stays on ∅).
    Conjunctive,
    /// Dempster's rule: conjunctive, normalised.
    Dempster,
    /// Disjunctive rule.
    Disjunctive,
    /// Yager's rule: conjunctive, conflict to Ω.
    Yager,
    /// Dubois–Prade rule: conflicting products to the union.
    DuboisPrade,
}

/// Arguments of `evigrid mass discount`: exactly one of the three modes.
#[derive(Debug, Args)]
#[command(group(ArgGroup::new("mode").required(true).args(["alpha", "context", "class_rate"])))]
pub struct DiscountArgs {
    /// Classical discounting rate α in [0, 1]: every set keeps 1 − α of its mass, the rest goes
    /// to Ω.
    #[arg(long)]
    alpha: Option<f64>,
    /// A context SET=RATE of contextual discounting, elements of SET joined by `+` (`h+r=0.1`);
    /// repeat for several contexts.
    #[arg(long, value_name = "SET=RATE")]
    context: Vec<String>,
    /// A class rate ELEMENT=RATE of class-rate discounting (SPEC §5 step 3); give one per element.
    #[arg(long, value_name = "ELEMENT=RATE")]
    class_rate: Vec<String>,
    /// How a set's rate follows from its classes' rates, with --class-rate [default: max].
    #[arg(long, value_enum)]
    set_rate: Option<SetRateArg>,
    /// The mass function file (JSON); `-` is standard input.
    input: PathBuf,
    #[command(flatten)]
    output: OutputArgs,
}

/// `set_rate` of SPEC §5 step 3.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum SetRateArg {
    /// The smallest rate of the set's classes.
    Min,
    /// The largest rate of the set's classes.
    Max,
    /// The mean rate of the set's classes.
    Mean,
}

/// Arguments of a subcommand that reads one mass function.
#[derive(Debug, Args)]
pub struct SingleArgs {
    /// The mass function file (JSON); `-` is standard input.
    input: PathBuf,
    #[command(flatten)]
    output: OutputArgs,
}

/// Arguments of `evigrid mass transform`.
#[derive(Debug, Args)]
pub struct TransformArgs {
    /// The function to compute.
    #[arg(long, value_enum)]
    to: Function,
    /// The mass function file (JSON); `-` is standard input.
    input: PathBuf,
    #[command(flatten)]
    output: OutputArgs,
}

/// The set functions of `evigrid mass transform`.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum Function {
    /// bel(A) = Σ m(B) over non-empty B ⊆ A.
    Belief,
    /// pl(A) = Σ m(B) over B meeting A.
    Plausibility,
    /// q(A) = Σ m(B) over B ⊇ A.
    Commonality,
    /// b(A) = Σ m(B) over B ⊆ A, ∅ included.
    Implicability,
}

impl Function {
    fn name(self) -> &'static str {
        match self {
            Function::Belief => "belief",
            Function::Plausibility => "plausibility",
            Function::Commonality => "commonality",
            Function::Implicability => "implicability",
        }
    }
}

/// Runs one `evigrid mass` subcommand.
pub fn run(command: MassCommand) -> Result<()> {
    match command {
        MassCommand::Combine(args) => combine(&args),
        MassCommand::Discount(args) => discount(&args),
        MassCommand::Pignistic(args) => pignistic(&args),
        MassCommand::Transform(args) => transform(&args),
    }
}

fn combine(args: &CombineArgs) -> Result<()> {
    if args.inputs.iter().filter(|p| p.as_os_str() == "-").count() > 1 {
        return Err(BadInput::new("-: standard input can be read only once"));
    }
    let inputs = args
        .inputs
        .iter()
        .map(|path| read_input(path))
        .collect::<Result<Vec<Input>>>()?;
    let Some((first, rest)) = inputs.split_first() else {
        return Err(BadInput::new("mass combine: no input files"));
    };
    for input in rest {
        if input.mass.frame() != first.mass.frame() {
            return Err(BadInput::new(format!(
                "{}: frame {} differs from frame {} of {}",
                input.label,
                input.mass.frame(),
                first.mass.frame(),
                first.label
            )));
        }
    }
    let rule: &dyn Combination<f64> = match args.rule {
        Rule::Conjunctive => &Conjunctive,
        Rule::Dempster => &Dempster,
        Rule::Disjunctive => &Disjunctive,
        Rule::Yager => &Yager,
        Rule::DuboisPrade => &DuboisPrade,
    };
    let masses: Vec<Mass<f64>> = inputs.iter().map(|i| i.mass.clone()).collect();
    let combined = rule.combine_all(&masses).map_err(|e| {
        let labels: Vec<&str> = inputs.iter().map(|i| i.label.as_str()).collect();
        let problem = e.describe_combination_in(first.mass.frame());
        BadInput::new(format!("{}: {problem}", labels.join(", ")))
    })?;
    print_mass(&combined, &args.output)
}

fn discount(args: &DiscountArgs) -> Result<()> {
    if args.set_rate.is_some() && args.class_rate.is_empty() {
        return Err(BadInput::new("--set-rate: applies only with --class-rate"));
    }
    let input = read_input(&args.input)?;
    let frame = input.mass.frame();
    let discounted = if let Some(alpha) = args.alpha {
        ClassicalDiscount::new(alpha)
            .and_then(|d| d.discount(&input.mass))
            .map_err(|e| BadInput::new(format!("--alpha {alpha}: {e}")))?
    } else if !args.context.is_empty() {
        let contexts = args
            .context
            .iter()
            .map(|arg| parse_assignment("--context", arg, frame, &input.label))
            .collect::<Result<Vec<(Set, f64)>>>()?;
        for (arg, &(_, rate)) in args.context.iter().zip(&contexts) {
            check_rate("--context", arg, rate)?;
        }
        ContextualDiscount::new(contexts)
            .and_then(|d| d.discount(&input.mass))
            .map_err(|e| BadInput::new(format!("--context: {e}")))?
    } else {
        class_rate_discount(args, &input)?
    };
    print_mass(&discounted, &args.output)
}

fn class_rate_discount(args: &DiscountArgs, input: &Input) -> Result<Mass<f64>> {
    let frame = input.mass.frame();
    let mut rates: Vec<Option<f64>> = vec![None; frame.len()];
    for arg in &args.class_rate {
        let (set, rate) = parse_assignment("--class-rate", arg, frame, &input.label)?;
        check_rate("--class-rate", arg, rate)?;
        let element = (0..frame.len())
            .find(|&k| set == Set::from_bits(1 << k))
            .ok_or_else(|| BadInput::new(format!("--class-rate {arg}: name one element")))?;
        if rates[element].replace(rate).is_some() {
            return Err(BadInput::new(format!(
                "--class-rate {arg}: element {} is given twice",
                frame.names()[element]
            )));
        }
    }
    let rates = rates
        .iter()
        .zip(frame.names())
        .map(|(rate, name)| {
            rate.ok_or_else(|| {
                BadInput::new(format!(
                    "--class-rate: no rate for element {name} of {frame}"
                ))
            })
        })
        .collect::<Result<Vec<f64>>>()?;
    let set_rate = match args.set_rate {
        Some(SetRateArg::Min) => SetRate::Min,
        Some(SetRateArg::Max) | None => SetRate::Max,
        Some(SetRateArg::Mean) => SetRate::Mean,
    };
    ClassRateDiscount::new(rates, set_rate)
        .and_then(|d| d.discount(&input.mass))
        .map_err(|e| BadInput::new(format!("--class-rate: {e}")))
}

/// Parses `a+b=0.3` into the set {a, b} of `frame` and the number 0.3.
fn parse_assignment(flag: &str, arg: &str, frame: &Frame, label: &str) -> Result<(Set, f64)> {
    let (names, rate) = arg
        .rsplit_once('=')
        .ok_or_else(|| BadInput::new(format!("{flag} {arg}: expected SET=RATE, as in a+b=0.1")))?;
    let rate: f64 = rate
        .trim()
        .parse()
        .map_err(|_| BadInput::new(format!("{flag} {arg}: rate {rate:?} is not a number")))?;
    let names: Vec<&str> = names.split('+').map(str::trim).collect();
    let set = frame.set(&names).map_err(|e| match e {
        BeliefError::UnknownElement { name, .. } => BadInput::new(format!(
            "{flag} {arg}: element {name:?} is not in the frame {frame} of {label}"
        )),
        other => BadInput::new(format!("{flag} {arg}: {other}")),
    })?;
    Ok((set, rate))
}

fn check_rate(flag: &str, arg: &str, rate: f64) -> Result<()> {
    if (0.0..=1.0).contains(&rate) {
        Ok(())
    } else {
        Err(BadInput::new(format!(
            "{flag} {arg}: rate {rate} is not in [0, 1]"
        )))
    }
}

fn pignistic(args: &SingleArgs) -> Result<()> {
    let input = read_input(&args.input)?;
    let frame = input.mass.frame();
    let betp = input.mass.pignistic().map_err(|e| {
        BadInput::new(format!(
            "{}: {}",
            input.label,
            e.describe_pignistic_in(frame)
        ))
    })?;
    if args.output.table {
        json::print(&json::pignistic_table(frame, &betp))
    } else {
        json::print(&json::pignistic_json(frame, &betp)?)
    }
}

fn transform(args: &TransformArgs) -> Result<()> {
    let input = read_input(&args.input)?;
    let m = &input.mass;
    let function = match args.to {
        Function::Belief => m.belief(),
        Function::Plausibility => m.plausibility(),
        Function::Commonality => m.commonality(),
        Function::Implicability => m.implicability(),
    };
    let name = args.to.name();
    if args.output.table {
        json::print(&json::set_function_table(name, &function))
    } else {
        json::print(&json::set_function_json(name, &function)?)
    }
}

fn print_mass(mass: &Mass<f64>, output: &OutputArgs) -> Result<()> {
    if output.table {
        json::print(&json::mass_table(mass))
    } else {
        json::print(&json::mass_json(mass)?)
    }
}
