//! The application around the library: the studies (the demo, the benchmark sweeps and the
//! paper's run, feature `studies`), the `prt` command line and the window (feature `app`: clap,
//! indicatif, eframe), which call them.

#[cfg(feature = "app")]
pub mod cli;
pub mod studies;
#[cfg(feature = "app")]
pub mod viewer;
