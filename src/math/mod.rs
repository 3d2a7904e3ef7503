//! The mathematics every stage shares: real spherical harmonics, the per-face Haar transform, cube
//! map texels and their solid angles, and seeded sampling. Nothing here knows of scenes or files.

pub mod cubemap;
pub mod haar;
pub mod sampling;
pub mod sh;
