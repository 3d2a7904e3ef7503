//! The GPU raster: a mesh resident on the device (`mesh`) drawn with one colour per vertex from
//! any camera ([`raster`]), with the local lights' highlights of a glossy bake (`lights`), on
//! the base device of [`crate::gpu`], so that whatever relit the colours (the relight kernels,
//! or the CPU) the draw is the same.

mod lights;
mod mesh;
pub mod raster;

pub use mesh::{GpuMesh, upload_colours};
pub use raster::GpuRaster;
