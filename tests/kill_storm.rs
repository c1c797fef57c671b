//! The kill storm as a test target of its own: `cargo test --release --test kill_storm` runs the quick
//! storm, the cases the storms found and, alone, the long storm. The scenario is
//! `tests/e2e/kill_storm.rs` with the harness of the end-to-end tests (`tests/e2e/common`); it is not
//! also a module of the `e2e` binary, so `cargo test` runs it once.

#[path = "e2e/common/mod.rs"]
mod common;

#[path = "e2e/kill_storm.rs"]
mod kill_storm;
