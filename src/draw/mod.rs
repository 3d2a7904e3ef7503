//! Drawing what a relight gives: a per-vertex bake's relit colours drawn from any camera
//! ([`vertex`], with its orbit and upright cameras), the rasteriser that draws them on the CPU
//! ([`raster`]) and its GPU twin ([`gpu`]), and the environment behind the scene where no
//! geometry is seen ([`background`]).

pub mod background;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod lobe;
pub mod raster;
pub mod sh_gloss;
pub mod shading;
pub mod vertex;
