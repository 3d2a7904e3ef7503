// Resolves a multisampled raster: shaders/raster.wgsl draws each sample of every pixel in a pass
// of its own, into one layer of `samples`, and each pixel here is the mean of its layers, summed
// in layer order as the CPU twin sums them (src/draw/raster.rs, rasterize_with). A
// sample that drew nothing holds zero, so the colour comes out premultiplied by the coverage in
// alpha. One triangle covers the target.

@group(0) @binding(0) var samples: texture_2d_array<f32>;

@vertex
fn vertex(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let corner = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(corner * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fragment(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(position.xy);
    let layers = textureNumLayers(samples);
    var sum = textureLoad(samples, pixel, 0, 0);
    for (var k = 1u; k < layers; k++) {
        sum += textureLoad(samples, pixel, i32(k), 0);
    }
    return sum * (1.0 / f32(layers));
}
