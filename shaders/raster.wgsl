// Draws a mesh with one colour per vertex (Gouraud shading), the GPU twin of the CPU rasteriser
// in src/draw/raster.rs. The colours are read from a storage buffer of vec4<f32> per vertex,
// indexed by the vertex's index, so a relit buffer can be drawn without leaving the GPU. Clip
// space (`clip_from_world`) puts x right and y up over the film, w the forward distance from the
// eye and z the near distance, so the depth is near / w: reversed depth, cleared to 0 and tested
// with `greater`. Coverage is the alpha.
//
// The hardware decides which pixels a triangle covers and which triangle is nearest; what a pixel
// shows is computed here as the CPU twin computes it. The draw is not indexed: corner k of
// triangle t is vertex `indices[3t + k]`, read from storage, and each fragment knows its triangle
// (a flat varying). It reads the triangle's three vertices and takes the barycentrics of the
// point its pixel centre's ray hits on the triangle's plane, in the camera's frame. That is
// perspective-correct interpolation, but from the vertices as given rather than from corners
// snapped to the rasteriser's sub-pixel grid, and through clipping without new vertices: GPUs
// differ in both (an NVIDIA H100 moved colours by up to 9e-3 where lavapipe agreed with the CPU to
// 1e-4), so the hardware's own interpolation would make the twins disagree on some GPUs.
//
// A vertex with an albedo map (its slot is not NO_MAP) has its colour multiplied per pixel by the
// map, read as src/scene/albedo_map.rs reads it: texels fetched and filtered here in f32 rather
// than by a sampler, whose filtering precision differs between GPUs, with the level of detail
// taken from the texture coordinate's fine derivatives. Those are taken here too, as on the CPU:
// the coordinate at the other pixels of the 2 x 2 quad, on the same triangle (extrapolated past
// its edges), rather than whatever the quad's neighbours hold.

// A glossy per-vertex bake with visibility (view.lobe.y, the most taps a material takes, above 0)
// keeps which
// cube texels each glossy vertex sees, one bit a texel in Morton order. A fragment evaluates the
// material's GGX lobe for its interpolated normal and its own direction to the eye by filtered
// importance sampling against the light's pyramid (binding 8) and the three vertices' visible
// shares at the matching level, interpolated with the barycentrics, as src/draw/lobe.rs does: the
// taps, the level choice, the weights and the Morton walk are those of src/draw/lobe.rs and
// src/math/cube_pyramid.rs, written again here.
//
// The local lights the relight lit add their highlights to the lobe, as src/draw/lobe/lights.rs
// draws them: each lit column's emitter (packed after the pyramid's nodes in binding 8) sampled
// once for a delta light, or on a 4 x 4 grid with the lobe's own taps that reach it under the
// power heuristic for a sized one, times the column's weight and the share of the light the
// triangle's vertices see (stored after the taps in `gloss`), interpolated. The emitters'
// sampling and hits are those of src/scene/light.rs, the GGX terms those of src/scene/brdf.rs,
// written again here in f32.

struct View {
    clip_from_world: mat4x4<f32>,
    // The camera's frame (src/draw/raster.rs, Frame): the eye, then the film's right and up
    // axes with half the film's width and height at unit distance in their w, and the view
    // direction.
    eye: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    forward: vec4<f32>,
    // The image's width and height in pixels, then where in each pixel this pass samples, from
    // its centre, in pixels (y down): the film is shifted by as much, so the hardware's pixel
    // centre is the sample.
    size: vec4<f32>,
    // The face size of the light's pyramid (0 without a light), the lit light columns, where
    // in `light` their emitters start, and the light columns a vertex keeps a share of.
    pyramid: vec4<u32>,
    // A bake with visibility: its cube's face size, the most taps a material takes, the materials
    // and the words of a vertex's bits; then where in `gloss` the lobes, the bits and each
    // material's [first tap word, taps] start, and the light shares (each vertex's row, or
    // NO_ROW, is at its index, the taps after the rows). All zero without visibility.
    lobe: vec4<u32>,
    lobe_at: vec4<u32>,
};

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> colours: array<vec4<f32>>;
// Per albedo map: its first entry in `levels`, its level count, and its sampler (wrap along u in
// bits 0-1 and along v in bits 2-3: 0 repeat, 1 mirrored repeat, 2 clamp; bit 4 nearest
// magnification).
@group(0) @binding(2) var<storage, read> maps: array<vec4<u32>>;
// Per level: its first texel, width and height.
@group(0) @binding(3) var<storage, read> levels: array<vec4<u32>>;
// Per texel: red | green << 16, then blue, sixteen-bit fractions of one.
@group(0) @binding(4) var<storage, read> texels: array<vec2<u32>>;
// Per vertex, VERTEX_WORDS words: the position's x, y and z and the texture coordinate's u and v
// (f32 bits), the albedo map's slot, the shading normal's x, y and z (f32 bits) and the material.
@group(0) @binding(5) var<storage, read> vertices: array<u32>;
// Per triangle, its three vertices.
@group(0) @binding(6) var<storage, read> indices: array<u32>;
// A glossy bake's visibility (one word without one): the vertices' rows, then per material its taps (the half vector in the
// normal's frame and D(h) (n.h), f32 bits), the materials' lobes (specular colour and alpha), and
// the rows' bits.
@group(0) @binding(7) var<storage, read> gloss: array<u32>;
// The light's pyramid: each node's mean radiance, level 0 (the texels, Morton order) first;
// then LIGHT_VEC4S a lit light column: its weight and kind, then its emitter's fields (see
// src/draw/gpu/raster.rs, `pack_light`).
@group(0) @binding(8) var<storage, read> light: array<vec4<f32>>;

const NO_MAP: u32 = 0xffffffffu;
const NO_ROW: u32 = 0xffffffffu;
const PI: f32 = 3.141592653589793;
const VERTEX_WORDS: u32 = 10u;
const UNORM: f32 = 1.0 / 65535.0;
// Largest texel coordinate read: past it f32 holds no fraction, and the index must fit an i32.
const COORD_LIMIT: f32 = 1073741824.0;
// A lit light column's vec4s in `light`, and the side of a sized light's grid of samples.
const LIGHT_VEC4S: u32 = 6u;
const LIGHT_GRID: u32 = 4u;
const TAU: f32 = 6.283185307179586;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) triangle: u32,
};

fn position_of(v: u32) -> vec3<f32> {
    let o = v * VERTEX_WORDS;
    return vec3<f32>(
        bitcast<f32>(vertices[o]),
        bitcast<f32>(vertices[o + 1u]),
        bitcast<f32>(vertices[o + 2u]),
    );
}

fn normal_of(v: u32) -> vec3<f32> {
    let o = v * VERTEX_WORDS + 6u;
    return vec3<f32>(
        bitcast<f32>(vertices[o]),
        bitcast<f32>(vertices[o + 1u]),
        bitcast<f32>(vertices[o + 2u]),
    );
}

// The bits of x's low half spread to the even bit positions.
fn spread(v: u32) -> u32 {
    var x = v & 0xffffu;
    x = (x | (x << 8u)) & 0x00ff00ffu;
    x = (x | (x << 4u)) & 0x0f0f0f0fu;
    x = (x | (x << 2u)) & 0x33333333u;
    return (x | (x << 1u)) & 0x55555555u;
}

// A direction's face and its position on it from -1 to 1, as src/math/cubemap.rs
// (dir_to_face_st).
struct FacePoint {
    face: u32,
    s: f32,
    t: f32,
}

fn face_point(d: vec3<f32>) -> FacePoint {
    let a = abs(d);
    if a.x >= a.y && a.x >= a.z {
        return FacePoint(select(1u, 0u, d.x >= 0.0), select(d.z, -d.z, d.x >= 0.0) / a.x, -d.y / a.x);
    } else if a.y >= a.z {
        return FacePoint(select(3u, 2u, d.y >= 0.0), d.x / a.y, select(-d.z, d.z, d.y >= 0.0) / a.y);
    }
    return FacePoint(select(5u, 4u, d.z >= 0.0), select(-d.x, d.x, d.z >= 0.0) / a.z, -d.y / a.z);
}

// The Morton index of the texel of an n-cube that holds face point p.
fn point_to_morton(n: u32, p: FacePoint) -> u32 {
    let col = min(u32((p.s + 1.0) * 0.5 * f32(n)), n - 1u);
    let row = min(u32((p.t + 1.0) * 0.5 * f32(n)), n - 1u);
    return p.face * n * n + (spread(col) | (spread(row) << 1u));
}

// The light's mean radiance about face point p at level `level`: bilinear between the centres of
// the four nodes of its face nearest it, held at the face's edge, as src/math/cube_pyramid.rs
// (CubePyramid::bilinear).
fn light_bilinear(p: FacePoint, level: u32) -> vec3<f32> {
    var at = 0u;
    for (var k = 0u; k < level; k++) {
        let side = view.pyramid.x >> k;
        at += 6u * side * side;
    }
    let side = view.pyramid.x >> level;
    let last = f32(side - 1u);
    let x = clamp((p.s + 1.0) * 0.5 * f32(side) - 0.5, 0.0, last);
    let y = clamp((p.t + 1.0) * 0.5 * f32(side) - 0.5, 0.0, last);
    let c0 = u32(x);
    let r0 = u32(y);
    let c = vec2<u32>(spread(c0), spread(min(c0 + 1u, side - 1u)));
    let r = vec2<u32>(spread(r0), spread(min(r0 + 1u, side - 1u))) << vec2<u32>(1u);
    let fc = x - f32(c0);
    let fr = y - f32(r0);
    let base = at + p.face * side * side;
    return light[base + (c.x | r.x)].rgb * ((1.0 - fr) * (1.0 - fc))
        + light[base + (c.y | r.x)].rgb * ((1.0 - fr) * fc)
        + light[base + (c.x | r.y)].rgb * (fr * (1.0 - fc))
        + light[base + (c.y | r.y)].rgb * (fr * fc);
}

// The open share of the level-`level` node holding Morton index m in visibility row `row` (1 for a
// vertex without bits).
fn open_share(row: u32, m: u32, level: u32) -> f32 {
    if row == NO_ROW {
        return 1.0;
    }
    let base = view.lobe_at.y + row * view.lobe.w;
    let len = 1u << (2u * level);
    let start = (m >> (2u * level)) << (2u * level);
    var ones = 0u;
    if len < 32u {
        ones = countOneBits((gloss[base + start / 32u] >> (start % 32u)) & ((1u << len) - 1u));
    } else {
        for (var w = start / 32u; w < (start + len) / 32u; w++) {
            ones += countOneBits(gloss[base + w]);
        }
    }
    return f32(ones) / f32(len);
}

// The light about lobe direction l (face point p, Morton index ml) times the interpolated open
// share of its node at pyramid level `level`, the visibility read at the level of the same texel
// size. The texels are the light itself, constant over each; a coarser level is read bilinearly
// about l.
fn lobe_at_level(p: FacePoint, ml: u32, mv: u32, level: u32, rows: vec3<u32>, b: vec3<f32>)
    -> vec3<f32> {
    let tl = countTrailingZeros(view.pyramid.x);
    let tv = countTrailingZeros(view.lobe.x);
    let vl = min(max(level + tv, tl) - tl, tv);
    let open = b.x * open_share(rows.x, mv, vl) + b.y * open_share(rows.y, mv, vl)
        + b.z * open_share(rows.z, mv, vl);
    if level == 0u {
        return light[ml].rgb * open;
    }
    return light_bilinear(p, level) * open;
}

// The mean of light times open share about direction l at fractional level x (clamped to the
// pyramid's levels), between the two levels about it.
fn lobe_read(l: vec3<f32>, x: f32, rows: vec3<u32>, b: vec3<f32>) -> vec3<f32> {
    let p = face_point(l);
    let ml = point_to_morton(view.pyramid.x, p);
    var mv = ml;
    if view.lobe.x != view.pyramid.x {
        mv = point_to_morton(view.lobe.x, p);
    }
    let top = countTrailingZeros(view.pyramid.x);
    let xc = clamp(x, 0.0, f32(top));
    let lo = u32(floor(xc));
    let f = xc - floor(xc);
    let below = lobe_at_level(p, ml, mv, lo, rows, b);
    if f > 0.0 && lo < top {
        return below * (1.0 - f) + lobe_at_level(p, ml, mv, lo + 1u, rows, b) * f;
    }
    return below;
}

// Three f32 of the gloss buffer from word `at`.
fn gloss_vec3(at: u32) -> vec3<f32> {
    return vec3<f32>(
        bitcast<f32>(gloss[at]),
        bitcast<f32>(gloss[at + 1u]),
        bitcast<f32>(gloss[at + 2u]),
    );
}

// Smith's masking of GGX with alpha squared a2 at cosine c.
fn smith_g1(c: f32, a2: f32) -> f32 {
    return 2.0 * c / (c + sqrt(a2 + (1.0 - a2) * c * c));
}

// The glossy light of a point of the triangle with `corners` at barycentrics `bary` of a bake with
// visibility, seen along `v` (unit, towards the eye): each tap's direction l = 2 (v.h) h - v
// weighed by f cos / pdf, G1(l) G1(v) (v.h) / ((n.v) (n.h)) for GGX.
fn lobe_light(corners: vec3<u32>, bary: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let m = vertices[corners.x * VERTEX_WORDS + 9u];
    if m >= view.lobe.z {
        return vec3<f32>(0.0);
    }
    let at = view.lobe_at.x + m * 4u;
    let specular = gloss_vec3(at);
    let alpha = bitcast<f32>(gloss[at + 3u]);
    if !(specular.x > 0.0 || specular.y > 0.0 || specular.z > 0.0) {
        return vec3<f32>(0.0);
    }
    let sum = normal_of(corners.x) * bary.x + normal_of(corners.y) * bary.y
        + normal_of(corners.z) * bary.z;
    if !(dot(sum, sum) > 0.0) {
        return vec3<f32>(0.0);
    }
    let n = normalize(sum);
    let nv = dot(n, v);
    if nv <= 0.0 {
        return vec3<f32>(0.0);
    }
    let rows = vec3<u32>(gloss[corners.x], gloss[corners.y], gloss[corners.z]);
    let a2 = alpha * alpha;
    let g1v = smith_g1(nv, a2);
    let frame = orthonormal_pair(n);
    let t = frame[0];
    let s = frame[1];
    // The material's own taps: as many as its lobe's width asks for.
    let first = gloss[view.lobe_at.z + m * 2u];
    let taps = gloss[view.lobe_at.z + m * 2u + 1u];
    let count = f32(taps);
    let side = f32(view.pyramid.x);
    let texel = 4.0 * PI / (6.0 * side * side);
    var total = vec3<f32>(0.0);
    for (var k = 0u; k < taps; k++) {
        let o = first + k * 4u;
        let th = gloss_vec3(o);
        let d_nh = bitcast<f32>(gloss[o + 3u]);
        let h = t * th.x + s * th.y + n * th.z;
        let vh = dot(v, h);
        if vh <= 0.0 {
            continue;
        }
        let l = h * (2.0 * vh) - v;
        let nl = dot(n, l);
        if nl <= 0.0 {
            continue;
        }
        let weight = smith_g1(nl, a2) * g1v * vh / (nv * th.z);
        // The footprint 1 / (M pdf), pdf = D (n.h) / (4 v.h).
        let footprint = 4.0 * vh / (count * d_nh);
        let x = 0.5 * log2(footprint / texel);
        total += lobe_read(l, x, rows, bary) * weight;
    }
    let env = specular * total / count;
    if view.pyramid.y == 0u {
        return env;
    }
    let p = position_of(corners.x) * bary.x + position_of(corners.y) * bary.y
        + position_of(corners.z) * bary.z;
    let here = Surface(p, n, v, a2, nv, g1v, t, s);
    return env + specular * local_lights(corners, bary, here, first, taps);
}

// Two unit vectors that make an orthonormal frame with unit n, as glam's
// Vec3::any_orthonormal_pair builds them (Duff et al. 2017).
fn orthonormal_pair(n: vec3<f32>) -> array<vec3<f32>, 2> {
    let sign = select(1.0, -1.0, (bitcast<u32>(n.z) & 0x80000000u) != 0u);
    let ka = -1.0 / (sign + n.z);
    let kb = n.x * n.y * ka;
    return array<vec3<f32>, 2>(
        vec3<f32>(1.0 + sign * n.x * n.x * ka, sign * kb, -sign * n.x),
        vec3<f32>(kb, sign + n.y * n.y * ka, -n.y),
    );
}

// A point of a glossy triangle seen from the eye: where it is, its unit normal, its unit
// direction to the eye, alpha squared, n.v, G1(v), and the normal's frame.
struct Surface {
    p: vec3<f32>,
    n: vec3<f32>,
    v: vec3<f32>,
    a2: f32,
    nv: f32,
    g1v: f32,
    t: vec3<f32>,
    s: vec3<f32>,
};

// A direction towards a light, the light it brings over its density (irradiance at normal
// incidence for a delta light), its density in solid angle (0 for a delta light), and whether
// any light comes (src/scene/light.rs, LightSample).
struct LightSample {
    dir: vec3<f32>,
    weight: f32,
    pdf: f32,
    ok: bool,
};

// Vec4 k of lit light column i.
fn light_vec4(i: u32, k: u32) -> vec4<f32> {
    return light[view.pyramid.z + i * LIGHT_VEC4S + k];
}

// pbrt-v4's smoothstep, 0 at a, 1 at b.
fn smooth_step(a: f32, b: f32, x: f32) -> f32 {
    if a == b {
        return select(1.0, 0.0, x < a);
    }
    let t = clamp((x - a) / (b - a), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// Column i's kind: 0 a point, 1 a spot, 2 a distant light, 3 a quad.
fn light_kind(i: u32) -> u32 {
    return bitcast<u32>(light_vec4(i, 0u).w);
}

// Whether column i is a delta light: a point, a spot or a sun without a disc.
fn light_is_delta(i: u32) -> bool {
    let kind = light_kind(i);
    return kind < 2u || (kind == 2u && light_vec4(i, 3u).w <= 0.0);
}

// Emitter::sample of column i from p with the uniform numbers u.
fn light_sample(i: u32, p: vec3<f32>, u: vec2<f32>) -> LightSample {
    let kind = light_kind(i);
    let a = light_vec4(i, 1u);
    let b = light_vec4(i, 2u);
    let c = light_vec4(i, 3u);
    let d = light_vec4(i, 4u);
    let none = LightSample(vec3<f32>(0.0), 0.0, 0.0, false);
    if kind == 2u {
        let solid_angle = c.w;
        if solid_angle <= 0.0 {
            return LightSample(a.xyz, d.w, 0.0, true);
        }
        // Uniform over the disc's cone: 1 - cos uniform in [0, 1 - cos alpha].
        let w = clamp(u.x, 0.0, 1.0) * (solid_angle / TAU);
        let cos_t = 1.0 - w;
        let sin_t = sqrt(max(w * (2.0 - w), 0.0));
        let phi = TAU * u.y;
        let frame = orthonormal_pair(a.xyz);
        let dir = normalize(frame[0] * (sin_t * cos(phi)) + frame[1] * (sin_t * sin(phi))
            + a.xyz * cos_t);
        return LightSample(dir, d.w * solid_angle, 1.0 / solid_angle, true);
    }
    var q = a.xyz;
    if kind == 3u {
        let e0 = light_vec4(i, 3u).xyz;
        let e1 = light_vec4(i, 4u).xyz;
        let e2 = light_vec4(i, 5u).xyz;
        let total = c.w + d.w;
        if b.w > 0.5 {
            q = a.xyz + e0 * u.x + e2 * u.y;
        } else {
            let split = c.w / total;
            var ea = e1;
            var eb = e2;
            var x = (u.x - split) / (1.0 - split);
            if u.x < split {
                ea = e0;
                eb = e1;
                x = u.x / split;
            }
            let r = sqrt(min(x, 1.0));
            q = a.xyz + ea * (r * (1.0 - u.y)) + eb * (r * u.y);
        }
    }
    let to = q - p;
    let r2 = dot(to, to);
    if r2 <= 0.0 {
        return none;
    }
    let dir = to / sqrt(r2);
    if kind == 0u {
        return LightSample(dir, 1.0 / r2, 0.0, true);
    }
    if kind == 1u {
        let fall = smooth_step(b.w, c.w, dot(b.xyz, -dir));
        return LightSample(dir, fall / r2, 0.0, fall > 0.0);
    }
    let cos_light = dot(b.xyz, -dir);
    if cos_light <= 0.0 {
        return none;
    }
    let pdf = r2 / ((c.w + d.w) * cos_light);
    return LightSample(dir, 1.0 / pdf, pdf, true);
}

// Emitter::hit of column i from p along unit dir: (1 where it meets the light, the radiance,
// the density light_sample would have drawn dir with), zero for a miss or a delta light.
fn light_hit(i: u32, p: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    let kind = light_kind(i);
    let a = light_vec4(i, 1u);
    let b = light_vec4(i, 2u);
    let c = light_vec4(i, 3u);
    let d = light_vec4(i, 4u);
    if kind == 2u {
        let x = cross(dir, a.xyz);
        let inside = dot(dir, a.xyz) > 0.0 && dot(x, x) <= b.w * b.w;
        if c.w > 0.0 && inside {
            return vec3<f32>(1.0, d.w, 1.0 / c.w);
        }
        return vec3<f32>(0.0);
    }
    if kind != 3u {
        return vec3<f32>(0.0);
    }
    let cos_light = -dot(b.xyz, dir);
    if cos_light <= 0.0 {
        return vec3<f32>(0.0);
    }
    let t = dot(b.xyz, a.xyz - p) / dot(b.xyz, dir);
    if !(t > 0.0 && t < 3.0e38) {
        return vec3<f32>(0.0);
    }
    let q = p + dir * t - a.xyz;
    let e0 = c.xyz;
    let e1 = d.xyz;
    let e2 = light_vec4(i, 5u).xyz;
    if in_triangle(q, e0, e1) || in_triangle(q, e1, e2) {
        return vec3<f32>(1.0, 1.0, t * t / ((c.w + d.w) * cos_light));
    }
    return vec3<f32>(0.0);
}

// Whether q lies in the triangle (0, a, b) of its plane (barycentric test).
fn in_triangle(q: vec3<f32>, a: vec3<f32>, b: vec3<f32>) -> bool {
    let aa = dot(a, a);
    let ab = dot(a, b);
    let bb = dot(b, b);
    let qa = dot(q, a);
    let qb = dot(q, b);
    let det = aa * bb - ab * ab;
    let s = (bb * qa - ab * qb) / det;
    let r = (aa * qb - ab * qa) / det;
    return s >= 0.0 && r >= 0.0 && s + r <= 1.0;
}

// GGX's distribution for a half vector h of any length about unit n (src/scene/brdf.rs): the
// sine from |n x h|, not 1 - cos^2.
fn ggx_d(n: vec3<f32>, h: vec3<f32>, a2: f32) -> f32 {
    let c = dot(n, h);
    if c <= 0.0 {
        return 0.0;
    }
    let x = cross(n, h);
    let den = (a2 * c * c + dot(x, x)) / dot(h, h);
    if den > 0.0 {
        return a2 / (PI * den * den);
    }
    return 0.0;
}

// f cos of GGX towards unit l at the surface, per unit of specular colour.
fn ggx_cosine(at: Surface, l: vec3<f32>) -> f32 {
    let nl = dot(at.n, l);
    if nl <= 0.0 || at.nv <= 0.0 {
        return 0.0;
    }
    return ggx_d(at.n, l + at.v, at.a2) * smith_g1(nl, at.a2) * at.g1v / (4.0 * at.nv);
}

// The density of GGX's sampling of unit l at the surface: D (n.h) / (4 v.h).
fn ggx_pdf(at: Surface, l: vec3<f32>) -> f32 {
    let h = l + at.v;
    let len = length(h);
    if len <= 0.0 || dot(at.n, l) <= 0.0 {
        return 0.0;
    }
    let vh = abs(dot(at.v, h)) / len;
    let nh = dot(at.n, h) / len;
    if vh <= 0.0 || nh <= 0.0 {
        return 0.0;
    }
    return ggx_d(at.n, h, at.a2) * nh / (4.0 * vh);
}

// The power heuristic's weight of a density against another, each times its sample count.
fn mis(own: f32, other: f32) -> f32 {
    let a = own * own;
    let b = other * other;
    return select(0.0, a / (a + b), a + b > 0.0);
}

// Vertex v's share of light column col: 1 without a row or a share kept.
fn light_share(v: u32, col: u32) -> f32 {
    let row = gloss[v];
    if row == NO_ROW || col >= view.pyramid.w {
        return 1.0;
    }
    return bitcast<f32>(gloss[view.lobe_at.w + row * view.pyramid.w + col]);
}

// The lit columns' highlights at the surface point, per unit of specular colour, with the
// material's taps (from word `first`, `taps` of them).
fn local_lights(corners: vec3<u32>, bary: vec3<f32>, at: Surface, first: u32, taps: u32)
    -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var i = 0u; i < view.pyramid.y; i++) {
        let col = bitcast<u32>(light_vec4(i, 1u).w);
        let share = bary.x * light_share(corners.x, col) + bary.y * light_share(corners.y, col)
            + bary.z * light_share(corners.z, col);
        if share <= 0.0 {
            continue;
        }
        var h = 0.0;
        if light_is_delta(i) {
            let sample = light_sample(i, at.p, vec2<f32>(0.5));
            if sample.ok && dot(at.n, sample.dir) > 0.0 {
                h = ggx_cosine(at, sample.dir) * sample.weight;
            }
        } else {
            h = sized_light(i, at, first, taps);
        }
        sum += light_vec4(i, 0u).xyz * (h * share);
    }
    return sum;
}

// The integral of f cos L over sized column i: its grid of samples and the lobe's taps that
// reach it, under the power heuristic.
fn sized_light(i: u32, at: Surface, first: u32, taps: u32) -> f32 {
    let lights = f32(LIGHT_GRID * LIGHT_GRID);
    let own = f32(taps);
    var acc = 0.0;
    for (var k = 0u; k < LIGHT_GRID * LIGHT_GRID; k++) {
        let u = (vec2<f32>(f32(k % LIGHT_GRID), f32(k / LIGHT_GRID)) + 0.5) / f32(LIGHT_GRID);
        let sample = light_sample(i, at.p, u);
        if !sample.ok || dot(at.n, sample.dir) <= 0.0 {
            continue;
        }
        let f = ggx_cosine(at, sample.dir);
        if f > 0.0 {
            let brdf = ggx_pdf(at, sample.dir);
            acc += f * sample.weight * mis(lights * sample.pdf, own * brdf) / lights;
        }
    }
    for (var k = 0u; k < taps; k++) {
        let o = first + k * 4u;
        let th = gloss_vec3(o);
        let d_nh = bitcast<f32>(gloss[o + 3u]);
        let h = at.t * th.x + at.s * th.y + at.n * th.z;
        let vh = dot(at.v, h);
        let l = h * (2.0 * vh) - at.v;
        let nl = dot(at.n, l);
        if vh <= 0.0 || nl <= 0.0 {
            continue;
        }
        let hit = light_hit(i, at.p, l);
        if hit.x == 0.0 {
            continue;
        }
        let weight = smith_g1(nl, at.a2) * at.g1v * vh / (at.nv * th.z);
        let brdf = d_nh / (4.0 * vh);
        acc += weight * hit.y * mis(own * brdf, lights * hit.z) / own;
    }
    return acc;
}

fn uv_of(v: u32) -> vec2<f32> {
    let o = v * VERTEX_WORDS;
    return vec2<f32>(bitcast<f32>(vertices[o + 3u]), bitcast<f32>(vertices[o + 4u]));
}

@vertex
fn vertex(@builtin(vertex_index) corner: u32) -> Varyings {
    var out: Varyings;
    out.position = view.clip_from_world * vec4<f32>(position_of(indices[corner]), 1.0);
    out.triangle = corner / 3u;
    return out;
}

// A point in the camera's frame: along the film's right, the film's up and the view direction.
fn camera_coords(p: vec3<f32>) -> vec3<f32> {
    let q = p - view.eye.xyz;
    return vec3<f32>(dot(q, view.right.xyz), dot(q, view.up.xyz), dot(q, view.forward.xyz));
}

// The texel index that integer index i of a row of n reads.
fn wrap_index(mode: u32, i: i32, n: i32) -> i32 {
    switch mode {
        case 1u: {
            let k = ((i % (2 * n)) + 2 * n) % (2 * n);
            return select(2 * n - 1 - k, k, k < n);
        }
        case 2u: {
            return clamp(i, 0, n - 1);
        }
        default: {
            return ((i % n) + n) % n;
        }
    }
}

fn fetch(level: vec4<u32>, flags: u32, x: f32, y: f32) -> vec3<f32> {
    let xi = wrap_index(flags & 3u, i32(x), i32(level.y));
    let yi = wrap_index((flags >> 2u) & 3u, i32(y), i32(level.z));
    let t = texels[level.x + u32(yi) * level.y + u32(xi)];
    return vec3<f32>(f32(t.x & 0xffffu), f32(t.x >> 16u), f32(t.y & 0xffffu)) * UNORM;
}

// Linear interpolation written as the CPU twin's (glam's lerp), not as mix().
fn lerp3(a: vec3<f32>, b: vec3<f32>, t: f32) -> vec3<f32> {
    return a + (b - a) * t;
}

fn read_level(level: vec4<u32>, flags: u32, uv: vec2<f32>, nearest: bool) -> vec3<f32> {
    let x = clamp(uv.x * f32(level.y), -COORD_LIMIT, COORD_LIMIT);
    let y = clamp(uv.y * f32(level.z), -COORD_LIMIT, COORD_LIMIT);
    if nearest {
        return fetch(level, flags, floor(x), floor(y));
    }
    let xs = x - 0.5;
    let ys = y - 0.5;
    let x0 = floor(xs);
    let y0 = floor(ys);
    let fx = xs - x0;
    let fy = ys - y0;
    let top = lerp3(fetch(level, flags, x0, y0), fetch(level, flags, x0 + 1.0, y0), fx);
    let bottom = lerp3(
        fetch(level, flags, x0, y0 + 1.0),
        fetch(level, flags, x0 + 1.0, y0 + 1.0),
        fx,
    );
    return lerp3(top, bottom, fy);
}

fn albedo(slot: u32, uv: vec2<f32>, dx: vec2<f32>, dy: vec2<f32>) -> vec3<f32> {
    let map = maps[slot];
    let first = levels[map.x];
    let size = vec2<f32>(f32(first.y), f32(first.z));
    let rho = max(length(dx * size), length(dy * size));
    var lod = 0.0;
    if rho > 1.0 {
        lod = log2(rho);
    }
    lod = min(lod, f32(map.y - 1u));
    if lod <= 0.0 {
        return read_level(first, map.z, uv, (map.z & 16u) != 0u);
    }
    let k = floor(lod);
    let blend = lod - k;
    let next = min(u32(k) + 1u, map.y - 1u);
    let a = read_level(levels[map.x + u32(k)], map.z, uv, false);
    let b = read_level(levels[map.x + next], map.z, uv, false);
    return a + (b - a) * blend;
}

// The texture coordinate on the triangle (camera-frame corners a, b, c) where the ray through
// film position `film` meets its plane: inside the triangle or extrapolated past its edges.
fn uv_at(film: vec2<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, uvs: array<vec2<f32>, 3>)
    -> vec2<f32> {
    let d = vec3<f32>(film, 1.0);
    let w = vec3<f32>(dot(d, cross(b, c)), dot(d, cross(c, a)), dot(d, cross(a, b)));
    return (uvs[0] * w.x + uvs[1] * w.y + uvs[2] * w.z) / (w.x + w.y + w.z);
}

// The film position, at unit forward distance, of the sample of the pixel whose centre is at
// `pixel`.
fn film_at(pixel: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(
        (2.0 * (pixel.x + view.size.z) / view.size.x - 1.0) * view.right.w,
        (1.0 - 2.0 * (pixel.y + view.size.w) / view.size.y) * view.up.w,
    );
}

@fragment
fn fragment(in: Varyings) -> @location(0) vec4<f32> {
    let first = in.triangle * 3u;
    let corners = vec3<u32>(indices[first], indices[first + 1u], indices[first + 2u]);
    let a = camera_coords(position_of(corners.x));
    let b = camera_coords(position_of(corners.y));
    let c = camera_coords(position_of(corners.z));
    // The pixel centre's direction (the fragment's position is its pixel's centre).
    let d = vec3<f32>(film_at(in.position.xy), 1.0);
    let w = vec3<f32>(dot(d, cross(b, c)), dot(d, cross(c, a)), dot(d, cross(a, b)));
    let sum = w.x + w.y + w.z;
    // Only a triangle seen edge-on can cover a pixel whose ray misses its plane: the CPU draws
    // nothing there either.
    if !(sum > 0.0) {
        discard;
    }
    let bary = w / sum;
    var colour = colours[corners.x].rgb * bary.x + colours[corners.y].rgb * bary.y
        + colours[corners.z].rgb * bary.z;
    let slot = vertices[corners.x * VERTEX_WORDS + 5u];
    if slot != NO_MAP {
        let uvs = array<vec2<f32>, 3>(uv_of(corners.x), uv_of(corners.y), uv_of(corners.z));
        let uv = uvs[0] * bary.x + uvs[1] * bary.y + uvs[2] * bary.z;
        // Fine derivatives, as dpdxFine and dpdyFine take them, but on this triangle whatever
        // covers the quad's other pixels: the odd pixel of the quad's pair minus the even one.
        let pixel = floor(in.position.xy);
        let odd = vec2<bool>((u32(pixel.x) & 1u) == 1u, (u32(pixel.y) & 1u) == 1u);
        let across = uv_at(
            film_at(in.position.xy + vec2<f32>(select(1.0, -1.0, odd.x), 0.0)), a, b, c, uvs);
        let down = uv_at(
            film_at(in.position.xy + vec2<f32>(0.0, select(1.0, -1.0, odd.y))), a, b, c, uvs);
        let dx = select(across - uv, uv - across, odd.x);
        let dy = select(down - uv, uv - down, odd.y);
        colour = colour * albedo(slot, uv, dx, dy);
    }
    if view.lobe.y > 0u {
        let dir = view.right.xyz * d.x + view.up.xyz * d.y + view.forward.xyz;
        colour = max(colour + lobe_light(corners, bary, -normalize(dir)), vec3<f32>(0.0));
    }
    return vec4<f32>(colour, 1.0);
}
