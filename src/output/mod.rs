//! Images and what is measured on them: linear RGB images and their files (OpenEXR, PNG), tone
//! mapping, error metrics, contact sheets and plots. Every stage that makes an image writes it
//! through here, so this stage imports nothing but the mathematics.

pub mod film;
pub mod metrics;
#[cfg(feature = "studies")]
pub mod plot;
#[cfg(feature = "studies")]
pub mod sheet;
#[cfg(feature = "studies")]
pub mod text;
