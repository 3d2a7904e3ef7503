// Copies the relit image from its buffer into an RGBA32F storage texture, for display without a
// round trip through the CPU. One thread per pixel. Alpha is 0: a per-pixel relight covers
// nothing beyond what the environment behind it already leaves open (see tonemap.wgsl).

struct Size {
    width: u32,
    height: u32,
};

@group(0) @binding(0) var<uniform> size: Size;
@group(0) @binding(1) var<storage, read> image: array<vec4<f32>>;
@group(0) @binding(2) var target_texture: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(WG_X, WG_Y)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= size.width || id.y >= size.height) {
        return;
    }
    textureStore(target_texture, vec2<i32>(i32(id.x), i32(id.y)), vec4<f32>(image[id.y * size.width + id.x].rgb, 0.0));
}
