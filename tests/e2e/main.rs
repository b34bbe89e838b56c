//! End-to-end tests, one module per topic, all in one test binary: every integration-test
//! binary is linked (with the release profile's thin LTO) on its own, so one binary instead of
//! one per file saves most of the build time of `cargo test --release`.
//!
//! The modules share one process and run on parallel test threads, so no test may change
//! process-wide state (environment, current directory, signal handlers, rayon's global pool):
//! renders that need a thread count build their own pool (`common::render_with_threads`), the
//! command-line tests run the binary as a child, and a test that measures the whole process
//! runs itself alone in a child process (`common::run_alone`).

mod adaptive;
mod alpha;
mod animation;
mod anisotropy;
mod caustics;
mod cli;
mod cli_errors;
mod cli_import_errors;
mod common;
mod cornell;
mod deform;
mod denoise;
mod determinism;
mod environment;
mod farm;
mod filters;
mod furnace;
mod fuzz_regressions;
mod geometry_import;
// The examples' error measures (`examples/common/`), tested here.
#[allow(dead_code)]
#[path = "../../examples/common/image_error.rs"]
mod image_error;
mod import;
mod import_robust;
mod instancing;
mod interrupt;
mod large_obj;
mod light_units;
mod materials;
mod memory;
mod meshopt;
mod mis;
mod next_event;
mod orthographic;
mod placement;
mod sampler;
mod shipped_scenes;
mod texture_filtering;
mod textures;
mod transmission;
mod unlit;
mod vertex_colors;
mod volume;
