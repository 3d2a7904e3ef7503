//! # wavelet-prt
//!
//! All-frequency precomputed radiance transfer: a scene is baked once, for a fixed view, into each
//! pixel's light transport against the texels of a cube map; at run time any HDR environment
//! relights it. Following Ng, Ramamoorthi & Hanrahan (SIGGRAPH 2003), transport rows are
//! Haar-transformed per cube face and sparsified, the light is Haar-transformed and only its K most
//! important terms are kept, and relighting is a sparse product. Beside it runs the low-order
//! spherical-harmonics path (Sloan, Kautz & Snyder 2002), so the two can be compared on the same
//! pixels.
//!
//! ```text
//! scene.toml ──bake──▶ transport file (sparse Haar rows, SH rows, metadata)
//! env.exr/.hdr ──▶ cube map (6·N², area-averaged) ──▶ Haar ──▶ K-term selection ──▶ sparse light
//!                                                 └──▶ SH projection (order n)
//! transport × light ──relight──▶ linear RGB image ──▶ EXR / PNG, metrics against a reference
//! ```
//!
//! Every numeric convention (axes, lat-long, cube faces, SH, Haar) is fixed in [`conventions`].
//! The front door, [`api`], loads, bakes, opens, relights and measures in a few calls.
#![warn(missing_docs)]

pub mod api;
#[cfg(feature = "studies")]
pub mod app;
pub mod bake;
pub mod conventions;
pub mod draw;
pub mod env;
pub mod error;
pub mod files;
pub mod flags;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod math;
pub mod medium;
pub mod names;
pub mod output;
pub mod relight;
pub mod scene;
pub mod store;
#[cfg(test)]
pub(crate) mod test_support;
pub mod volume;

pub use api::{Cancel, Environment, Relighter};
pub use error::{PrtError, Result};
