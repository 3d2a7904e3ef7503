//! The local light columns a glossy per-vertex bake's highlights are drawn from, packed as
//! `shaders/raster.wgsl` reads them after the light's pyramid: the GPU twin of
//! [`crate::draw::lobe::LitColumn`].

use glam::Vec3;

use crate::draw::lobe::LitColumn;
use crate::scene::light::Emitter;

/// Vec4s a lit light column takes in the light buffer (`LIGHT_VEC4S` of `shaders/raster.wgsl`).
pub(super) const LIGHT_VEC4S: usize = 6;

/// A lit light column as `shaders/raster.wgsl` reads it: its weight and kind (0 a point, 1 a
/// spot, 2 a distant light, 3 a quad), then its position (a point's or a spot's), first corner
/// (a quad's) or direction to the light and its column's index; the axis or normal with the
/// outer cone's cosine, whether a quad is a parallelogram (1 or 0) or a disc's half-angle sine;
/// the first edge with the inner cone's cosine, the first triangle's area or the disc's solid
/// angle; the second edge with the second triangle's area or the disc's radiance; the third edge.
pub(super) fn pack_light(lit: &LitColumn) -> [[f32; 4]; LIGHT_VEC4S] {
    let w = lit.weight;
    let column = f32::from_bits(lit.column as u32);
    let head = |kind: u32| [w.x, w.y, w.z, f32::from_bits(kind)];
    let v = |p: Vec3, x: f32| [p.x, p.y, p.z, x];
    let zero = [0.0; 4];
    match lit.emitter {
        Emitter::Point { position } => [head(0), v(position, column), zero, zero, zero, zero],
        Emitter::Spot {
            position,
            axis,
            cos_outer,
            cos_inner,
        } => [
            head(1),
            v(position, column),
            v(axis, cos_outer),
            v(Vec3::ZERO, cos_inner),
            zero,
            zero,
        ],
        Emitter::Directional {
            to_light,
            sin_half,
            solid_angle,
            radiance,
        } => [
            head(2),
            v(to_light, column),
            v(Vec3::ZERO, sin_half),
            v(Vec3::ZERO, solid_angle),
            v(Vec3::ZERO, radiance),
            zero,
        ],
        Emitter::Quad {
            normal,
            origin,
            parallelogram,
            edges,
            areas,
        } => [
            head(3),
            v(origin, column),
            v(normal, parallelogram as u8 as f32),
            v(edges[0], areas[0]),
            v(edges[1], areas[1]),
            v(edges[2], 0.0),
        ],
    }
}
