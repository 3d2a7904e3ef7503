//! The environment light: maps (files, the bundled ones, procedural suns), their resampling
//! onto the cube map, and the Haar light with its K-term selection and SH projection.

pub mod envmap;
pub mod importance;
pub mod latlong;
pub mod resample;
pub mod select;
