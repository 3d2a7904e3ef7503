// Adds the local lights to a relit image: image += Σ weight ⊙ column over the lights that are on.
// One thread per pixel (or vertex). The columns are 16-bit integers, two to a word, in the layout
// [column, channel, pixel], each a fraction q / 65535 of the scale of its (column, pixel row).
// Alpha is left as it is.

struct Params {
    width: u32,
    height: u32,
    // Lights that are on: entries of `mix`.
    count: u32,
    // Pixels in the image: a channel plane's length.
    pixels: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> values: array<u32>;
@group(0) @binding(2) var<storage, read> scales: array<f32>;
// RGB weight, and the column's index in w (its bits).
@group(0) @binding(3) var<storage, read> mix: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> image: array<vec4<f32>>;

fn fraction_at(i: u32) -> f32 {
    let pair = unpack2x16unorm(values[i >> 1u]);
    return select(pair.x, pair.y, (i & 1u) == 1u);
}

@compute @workgroup_size(WG_X, WG_Y)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let p = id.y * params.width + id.x;
    var sum = vec3<f32>(0.0);
    for (var k = 0u; k < params.count; k = k + 1u) {
        let m = mix[k];
        let column = bitcast<u32>(m.w);
        let scale = scales[column * params.height + id.y];
        let base = column * 3u * params.pixels + p;
        let v = vec3<f32>(fraction_at(base), fraction_at(base + params.pixels), fraction_at(base + 2u * params.pixels));
        sum = sum + m.xyz * v * scale;
    }
    image[p] = image[p] + vec4<f32>(sum, 0.0);
}
