// Display tone mapping: linear RGBA32F radiance plus the environment behind the scene weighted by
// the part of the pixel the radiance leaves open (1 - alpha), times 2^exposure, a display curve (0 clip,
// 1 Reinhard, 2 the ACES fit; `ToneCurve` in src/film.rs), then the sRGB curve, into the RGBA8
// texture egui samples.
struct Params {
    scale: f32,
    width: u32,
    height: u32,
    curve: u32,
}
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var linear_image: texture_2d<f32>;
@group(0) @binding(2) var display: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(3) var behind: texture_2d<f32>;

fn srgb(x: f32) -> f32 {
    let c = clamp(x, 0.0, 1.0);
    if c <= 0.0031308 {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

fn curve(x: f32) -> f32 {
    if params.curve == 1u {
        return x / (1.0 + x);
    }
    if params.curve == 2u {
        return clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    }
    return x;
}

fn display_value(x: f32) -> f32 {
    return srgb(curve(max(x * params.scale, 0.0)));
}

@compute @workgroup_size(WG_X, WG_Y)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    // A per-pixel relight writes alpha 0 over a behind already weighted by its uncovered
    // fraction; a drawn mesh writes its coverage over the whole environment.
    let drawn = textureLoad(linear_image, vec2<i32>(id.xy), 0);
    let p = drawn.rgb + (1.0 - drawn.a) * textureLoad(behind, vec2<i32>(id.xy), 0).rgb;
    textureStore(display, vec2<i32>(id.xy), vec4<f32>(display_value(p.r), display_value(p.g), display_value(p.b), 1.0));
}
