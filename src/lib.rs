//! photonlab: a research testbed for physically based global illumination with
//! photon mapping, with every strategy (sampler, accelerator, Russian roulette,
//! integrator) a plug-in chosen by name. See ARCHITECTURE.md for the data flow.

pub mod accel;
pub mod bench;
pub mod camera;
pub mod cli;
pub mod config;
pub mod experiment;
pub mod film;
pub mod gather;
pub mod geometry;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod photon;
pub mod pipeline;
pub mod plot;
pub mod registry;
pub mod render;
pub mod rr;
pub mod sampler;
pub mod scene;
pub mod stats;
pub mod world;
