//! The fuzz loop: mutate a corpus entry, run the target under `catch_unwind`, record panics and
//! slow inputs; keep some accepted mutants so the corpus drifts deeper into each format.

use std::panic::{self, AssertUnwindSafe};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use crate::mutate::{Rng, mutate};
use crate::targets::{Scratch, Target};

/// How long a run may go on: whichever bound is reached first.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Executions at most.
    pub executions: u64,
    /// Wall time at most.
    pub duration: Duration,
}

/// An input that made the target panic or take too long.
#[derive(Clone, Debug)]
pub struct Finding {
    /// The input.
    pub input: Vec<u8>,
    /// The panic message, or the time it took.
    pub problem: String,
}

/// What one run found.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Executions done.
    pub executions: u64,
    /// Inputs the target accepted.
    pub accepted: u64,
    /// Panics and slow inputs, the first few of each distinct message.
    pub findings: Vec<Finding>,
    /// The longest single execution.
    pub slowest: Duration,
    /// Wall time of the run.
    pub elapsed: Duration,
}

/// One execution slower than this is a finding: the CLI promises an answer, not a hang.
pub const SLOW_EXECUTION: Duration = Duration::from_secs(2);

/// Largest corpus kept per target; accepted mutants are added until it is full.
const MAX_CORPUS: usize = 512;

/// Findings kept per run (the first ones; later ones are counted as executions only).
const MAX_FINDINGS: usize = 32;

/// The message of the last panic, recorded by the hook [`run`] installs.
static LAST_PANIC: Mutex<String> = Mutex::new(String::new());

/// Fuzzes `target` from `seeds` within `budget`, deterministically for a given `seed`.
pub fn run(
    target: &Target,
    seeds: &[Vec<u8>],
    scratch: &Scratch,
    budget: Budget,
    seed: u64,
) -> Report {
    let mut corpus: Vec<Vec<u8>> = if seeds.is_empty() {
        vec![Vec::new()]
    } else {
        seeds.to_vec()
    };
    let mut rng = Rng::new(seed ^ fnv1a(target.name.as_bytes()));
    let mut report = Report::default();
    // The default hook prints a backtrace per caught panic; record the message instead.
    let previous_hook = panic::take_hook();
    panic::set_hook(Box::new(|info| {
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = info.to_string();
        }
    }));
    let start = Instant::now();
    while report.executions < budget.executions && start.elapsed() < budget.duration {
        let base = &corpus[rng.below(corpus.len())];
        let other = &corpus[rng.below(corpus.len())];
        // Seeds themselves run first: a seed that crashes needs no mutation to be found.
        let input = if (report.executions as usize) < seeds.len() {
            seeds[report.executions as usize].clone()
        } else {
            mutate(&mut rng, base, other, target.max_len)
        };
        let began = Instant::now();
        let outcome = panic::catch_unwind(AssertUnwindSafe(|| (target.run)(&input, scratch)));
        let took = began.elapsed();
        report.executions += 1;
        report.slowest = report.slowest.max(took);
        match outcome {
            Ok(accepted) => {
                if accepted {
                    report.accepted += 1;
                    if corpus.len() < MAX_CORPUS && rng.one_in(8) {
                        corpus.push(input.clone());
                    }
                }
                if took > SLOW_EXECUTION {
                    record(
                        &mut report,
                        input,
                        format!("took {:.1} s", took.as_secs_f64()),
                    );
                }
            }
            Err(_) => {
                let message = LAST_PANIC
                    .lock()
                    .map(|m| m.clone())
                    .unwrap_or_else(|_| "panic (message lost)".into());
                record(&mut report, input, message);
            }
        }
    }
    panic::set_hook(previous_hook);
    report.elapsed = start.elapsed();
    report
}

fn record(report: &mut Report, input: Vec<u8>, problem: String) {
    if report.findings.len() < MAX_FINDINGS {
        report.findings.push(Finding { input, problem });
    }
}

/// FNV-1a, to give each target its own random stream from one seed.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn panics_on_bang(bytes: &[u8], _: &Scratch) -> bool {
        assert!(!bytes.contains(&b'!'), "found a bang");
        true
    }

    fn no_seeds() -> Vec<Vec<u8>> {
        Vec::new()
    }

    #[test]
    fn catches_a_panic_and_keeps_going() -> std::io::Result<()> {
        let target = Target {
            name: "bang",
            about: "test",
            run: panics_on_bang,
            seeds: no_seeds,
            shared_seeds: &[],
            max_len: 64,
        };
        let scratch = Scratch::new()?;
        let budget = Budget {
            executions: 100,
            duration: Duration::from_secs(10),
        };
        let report = run(&target, &[b"ok!".to_vec()], &scratch, budget, 1);
        assert_eq!(report.executions, 100);
        // The seed itself panics; the panic is recorded with its message.
        assert!(!report.findings.is_empty());
        assert!(report.findings[0].problem.contains("found a bang"));
        Ok(())
    }
}
