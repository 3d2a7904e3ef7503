//! The mathematics every stage shares: real spherical harmonics (and their table at a cube's
//! texels), the per-face Haar transform, cube map texels and their solid angles (and the
//! quadrature over a texel), seeded sampling, and the magnitude that ranks an RGB coefficient.
//! Nothing here knows of scenes or files.

pub mod cube_pyramid;
pub mod cubemap;
pub mod haar;
pub mod sampling;
pub mod sh;
pub mod texel_quadrature;
pub mod texel_sh;
pub mod zonal;

/// Magnitude used to rank an RGB coefficient: Rec. 709 luminance weights on absolute values, so
/// channels of opposite sign do not cancel.
#[inline]
pub fn rgb_magnitude(c: [f32; 3]) -> f32 {
    0.2126 * c[0].abs() + 0.7152 * c[1].abs() + 0.0722 * c[2].abs()
}
