//! The CI smoke run: every target, a bounded number of executions, no finding allowed.
//!
//! Bounded by executions, not time, so the run is the same on a slow machine (only slower); the
//! long runs are `evigrid-fuzz --seconds N` (docs/fuzzing.md).

use std::path::PathBuf;
use std::time::Duration;

use fuzz::{Budget, Scratch, TARGETS, run, targets};

/// Executions per target; text targets run in microseconds, the map target in about a
/// millisecond, so the whole smoke run stays within a few seconds at opt-level 2.
const SMOKE_EXECUTIONS: u64 = 4_000;

#[test]
fn every_target_survives_the_smoke_run() -> std::io::Result<()> {
    let shared = std::env::var_os("EVIGRID_SHARED").map(PathBuf::from);
    let scratch = Scratch::new()?;
    let budget = Budget {
        executions: SMOKE_EXECUTIONS,
        duration: Duration::from_secs(120),
    };
    let mut problems = Vec::new();
    for target in TARGETS {
        let seeds = targets::seeds(target, shared.as_deref());
        assert!(!seeds.is_empty(), "{}: no seeds", target.name);
        let report = run(target, &seeds, &scratch, budget, 2026);
        assert!(report.executions > 0, "{}: nothing ran", target.name);
        // A target that accepts nothing exercises only its first check.
        assert!(report.accepted > 0, "{}: no input accepted", target.name);
        problems.extend(report.findings.iter().map(|f| {
            format!(
                "{}: {} (input {:?})",
                target.name,
                f.problem,
                String::from_utf8_lossy(&f.input)
            )
        }));
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    Ok(())
}

#[test]
fn every_seed_is_accepted() -> std::io::Result<()> {
    // The hand-made seeds are valid inputs: if a parser refuses one, the seed or the parser is
    // wrong, and the fuzzer would start from a dead end.
    let scratch = Scratch::new()?;
    for target in TARGETS {
        for (k, seed) in (target.seeds)().iter().enumerate() {
            if target.name == "pcd" && k == 3 {
                continue; // binary_compressed with a made-up payload: a refusal is the answer
            }
            assert!(
                (target.run)(seed, &scratch),
                "{} seed {k} refused: {:?}",
                target.name,
                String::from_utf8_lossy(seed)
            );
        }
    }
    Ok(())
}
