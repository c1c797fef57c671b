//! uavloc's end-to-end tests, one module per scenario: they run the real `uavloc` binary and its real
//! processes over real iceoryx2 services (and Unix sockets), and foreign clients with the official
//! bindings.
//!
//! One test binary (not one per scenario): each would link everything again, ≈ 40 s of a clean build's
//! CPU. Tests of one scenario run in parallel; tests of two scenarios never at the same time
//! ([`common::scenario`]), as when each scenario was its own binary: a timing-sensitive scenario (real
//! time, soak, the kill storm) never shares the machine with another scenario's load.
//!
//! Run one scenario: `cargo test --release --test e2e crash_restart::` (the module name). The kill storm
//! is a target of its own, `cargo test --release --test kill_storm` (`tests/kill_storm.rs`, the same
//! harness): its long version is what reliability runs are made of.

mod common;

mod bad_config;
mod bad_messages;
mod bench_ipc;
mod bench_latency;
mod bench_planner;
mod cli_calculator;
mod collision;
mod crash_restart;
mod external_frontend;
mod flying;
mod fusion_consistency;
mod geographic;
mod launch_default;
mod launch_faults;
mod monitor_backpressure;
mod paper_experiments;
mod permissions;
mod readme_commands;
mod realtime;
mod record_replay;
mod reliability_table;
mod shutdown;
mod simulate_closed_loop;
mod soak;
mod staleness;
mod standalone;
mod stop_continue;
mod swap_planner;
mod wire_layout;
