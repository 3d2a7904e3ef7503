//! The application around the library: the `prt` command line, the demo, the benchmark sweeps and
//! the window. The command line and the window need the `app` feature (clap, indicatif, eframe);
//! the demo and the sweeps are plain library code that they call.

pub mod bench;
#[cfg(feature = "app")]
pub mod cli;
pub mod demo;
pub mod dusk;
pub mod gloss_bench;
pub mod gloss_orbit;
pub mod lights_bench;
pub mod orbit;
pub mod paper;
pub mod truck;
#[cfg(feature = "app")]
pub mod viewer;
pub mod volume_orders;
