// Draws a mesh with one colour per vertex (Gouraud shading), the GPU twin of the CPU rasteriser
// in src/relight/raster.rs. The colours are read from a storage buffer of vec4<f32> per vertex,
// indexed by the vertex's index (an indexed draw's vertex_index is the index value), so a relit
// buffer can be drawn without leaving the GPU. Clip space (`clip_from_world`) puts x right and y
// up over the film, w the forward distance from the eye and z the near distance, so the depth is
// near / w: reversed depth, cleared to 0 and tested with `greater`. Coverage is the alpha.
//
// A vertex with an albedo map (its slot is not NO_MAP) has its colour multiplied per pixel by the
// map, read as src/scene/albedo_map.rs reads it: texels fetched and filtered here in f32 rather
// than by a sampler, whose filtering precision differs between GPUs, with the level of detail
// taken from the fine derivatives of the texture coordinate.

struct View {
    clip_from_world: mat4x4<f32>,
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

const NO_MAP: u32 = 0xffffffffu;
const UNORM: f32 = 1.0 / 65535.0;
// Largest texel coordinate read: past it f32 holds no fraction, and the index must fit an i32.
const COORD_LIMIT: f32 = 1073741824.0;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    // Perspective-correct, like the CPU twin's barycentrics of the hit point.
    @location(0) colour: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) @interpolate(flat) slot: u32,
};

@vertex
fn vertex(
    @location(0) position: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) slot: u32,
    @builtin(vertex_index) index: u32,
) -> Varyings {
    var out: Varyings;
    out.position = view.clip_from_world * vec4<f32>(position, 1.0);
    out.colour = colours[index].rgb;
    out.uv = uv;
    out.slot = slot;
    return out;
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

@fragment
fn fragment(in: Varyings) -> @location(0) vec4<f32> {
    // Taken before any branch: derivatives need the whole quad.
    let dx = dpdxFine(in.uv);
    let dy = dpdyFine(in.uv);
    var colour = in.colour;
    if in.slot != NO_MAP {
        colour = colour * albedo(in.slot, in.uv, dx, dy);
    }
    return vec4<f32>(colour, 1.0);
}
