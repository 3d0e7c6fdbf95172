//! The command line the evaluation examples share: `MAP SCENARIO.toml [SEEDS] [CONFIG.toml]`.

use eval::EvalConfig;
use evigrid::Params;
use sim::Scenario;

/// What `MAP SCENARIO.toml [SEEDS] [CONFIG.toml]` names, read.
pub struct Inputs {
    pub map: geodata::LocalMap,
    pub scenario: Scenario,
    /// The comma-separated SEEDS, or the scenario's seed and the next (as `evigrid eval
    /// --seeds 2`).
    pub seeds: Vec<u64>,
    /// Default parameters, or CONFIG's.
    pub config: EvalConfig,
}

/// Reads the inputs named on the command line; `example` names the program in the usage error.
pub fn inputs(example: &str) -> Result<Inputs, Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(map_path), Some(scenario_path)) = (args.first(), args.get(1)) else {
        return Err(format!("usage: {example} MAP SCENARIO.toml [SEEDS] [CONFIG.toml]").into());
    };
    let map = geodata::load_map(map_path, &geodata::LoadOptions::default())?.map;
    let scenario = Scenario::from_toml(&std::fs::read_to_string(scenario_path)?)?;
    let seeds = match args.get(2) {
        Some(list) => list.split(',').map(str::parse).collect::<Result<_, _>>()?,
        None => vec![scenario.seed, scenario.seed + 1],
    };
    let mut config = EvalConfig::default();
    if let Some(path) = args.get(3) {
        config.params = Params::from_toml_str(&std::fs::read_to_string(path)?)?;
    }
    Ok(Inputs {
        map,
        scenario,
        seeds,
        config,
    })
}
