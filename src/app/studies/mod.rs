//! The studies: the demo and its scenes ([`demo`], with [`orbit`], [`gloss_orbit`], [`dusk`] and
//! [`truck`]), the error, time and storage sweeps ([`bench`], [`gloss_bench`], [`lights_bench`],
//! [`volume_orders`]) and the paper's measurements ([`paper`]): each bakes, relights and measures
//! through the library, and writes its tables, plots and sheets.

pub mod bench;
pub mod demo;
pub mod dusk;
pub mod gloss_bench;
pub mod gloss_orbit;
pub mod lights_bench;
pub mod orbit;
pub mod paper;
pub mod truck;
pub mod volume_orders;
