//! photonlab: a research testbed for physically based global illumination with
//! photon mapping, with every strategy (sampler, accelerator, Russian roulette,
//! integrator) a plug-in chosen by name. See ARCHITECTURE.md for the data flow.

/// `print!` to stdout that never panics: once stdout is closed (`photonlab … | head`)
/// the rest of the output is dropped and the work goes on, so files the command
/// writes are not lost, where `print!` would panic mid-run.
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($t)*);
    }};
}

/// `println!` that never panics (see `out!`).
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

pub mod accel;
pub mod accumulate;
pub mod bench;
pub mod camera;
pub mod cli;
pub mod compare;
pub mod config;
pub mod experiment;
pub mod film;
pub mod fuzz;
pub mod geometry;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod param;
pub mod photon;
pub mod pipeline;
pub mod plot;
pub mod progress;
pub mod registry;
pub mod rr;
pub mod sampler;
pub mod scene;
pub mod stats;
pub mod texture;
pub mod world;
