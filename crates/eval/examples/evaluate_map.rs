//! Scores every variant on a simulated drive over a map file.
//!
//! ```text
//! cargo run --release -p evigrid-eval --example evaluate_map -- MAP [SCENARIO.toml] [SEEDS]
//! ```
//! SEEDS is a comma-separated list (default `1`). Prints the Markdown report on stdout.

use eval::{EvalConfig, Variant, evaluate};
use sim::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(map_path) = args.first() else {
        return Err("usage: evaluate_map MAP [SCENARIO.toml] [SEEDS]".into());
    };
    let map = geodata::load_map(map_path, &geodata::LoadOptions::default())?.map;
    let scenario = match args.get(1) {
        Some(path) => Scenario::from_toml(&std::fs::read_to_string(path)?)?,
        None => Scenario::default(),
    };
    let seeds: Vec<u64> = match args.get(2) {
        Some(list) => list.split(',').map(str::parse).collect::<Result<_, _>>()?,
        None => vec![1],
    };
    let report = evaluate(
        &map,
        &scenario,
        &Variant::ALL,
        &seeds,
        &EvalConfig::default(),
        &mut |p| {
            if p.frame == p.frames {
                eprintln!("seed {}/{} done", p.seed_index + 1, p.seeds);
            }
        },
    )?;
    println!("{}", report.to_markdown());
    Ok(())
}
