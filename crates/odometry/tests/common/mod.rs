//! Test support shared by the integration tests and the bench.

#![allow(dead_code)]

pub mod scene;
