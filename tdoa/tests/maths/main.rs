//! The maths checked against independent references, one test binary (a module per concept; one binary
//! links and instantiates the test helpers once: build time):
//! - `chan_estimator`: Chan's two-step WLS — noise-free exactness, Monte Carlo RMSE against the CRLB,
//!   degenerate geometry;
//! - `derivatives`: the analytic derivatives against finite differences;
//! - `fusion`: sequential fusion against the batch estimate and the information form;
//! - `global_crlb`: the global CRLB's five methods against fine quadrature;
//! - `singular_locus`: the geometry where the FIM is singular.

mod chan_estimator;
mod common;
mod derivatives;
mod fusion;
mod global_crlb;
mod singular_locus;
