//! Mutation fuzzing of every parser evigrid runs on user input, on stable Rust.
//!
//! There is no coverage instrumentation on stable, so the fuzzer makes up for it with
//! format-aware mutations: besides libFuzzer's byte edits it replaces numbers with the values
//! that break size arithmetic (`4294967296`, `18446744073709551615`, `NaN`, `1e308`), swaps words
//! and lines, and keeps accepted mutants so the corpus drifts into each format's corners. Every
//! run is reproducible from its seed.
//!
//! Two ways to run it:
//! - `cargo test -p evigrid-fuzz`: a bounded smoke run of every target, in CI.
//! - `cargo run --release -p evigrid-fuzz -- --seconds 600`: a long run, each finding written to
//!   a directory (see `docs/fuzzing.md`). Run it under `ulimit -v` so that an allocation beyond
//!   the budget aborts the process instead of the machine, and replay with the printed seed.

#![deny(missing_docs)]

pub mod mutate;
pub mod runner;
pub mod targets;

pub use runner::{Budget, Finding, Report, run};
pub use targets::{Scratch, TARGETS, Target, target};
