// Display tone mapping: linear RGBA32F radiance times 2^exposure, then the sRGB curve, into the
// RGBA8 texture egui samples.
struct Params {
    scale: f32,
    width: u32,
    height: u32,
    pad: u32,
}
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var linear_image: texture_2d<f32>;
@group(0) @binding(2) var display: texture_storage_2d<rgba8unorm, write>;

fn srgb(x: f32) -> f32 {
    let c = clamp(x, 0.0, 1.0);
    if c <= 0.0031308 {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let p = textureLoad(linear_image, vec2<i32>(id.xy), 0).rgb * params.scale;
    textureStore(display, vec2<i32>(id.xy), vec4<f32>(srgb(p.r), srgb(p.g), srgb(p.b), 1.0));
}
