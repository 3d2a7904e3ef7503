// SH relighting: each thread owns one pixel of the tile and dots the SH transport of that
// pixel's rows with the SH light itself, so no thread waits on another.

// SH rows of this chunk, params.coeffs values per row, starting at global row params.row_base.
@group(0) @binding(5) var<storage, read> sh: array<f32>;
// SH light: RGB in xyz, params.terms of them.
@group(0) @binding(7) var<storage, read> light: array<vec4<f32>>;

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let tile = tile_of(wid);
    if (tile == NO_TILE) {
        return;
    }
    let pixel = pixel_of(tile, lid);
    if (pixel == NO_PIXEL) {
        return;
    }
    var sum = vec3<f32>(0.0);
    for (var r = tile_rows[tile]; r < tile_rows[tile + 1u]; r = r + 1u) {
        let row = rows[r];
        if (bitcast<u32>(row.w) != pixel) {
            continue;
        }
        let base = (r - params.row_base) * params.coeffs;
        var dot = vec3<f32>(0.0);
        for (var i = 0u; i < params.terms; i = i + 1u) {
            dot = dot + sh[base + i] * light[i].xyz;
        }
        sum = sum + row.xyz * dot;
    }
    image[pixel] = vec4<f32>(sum, 1.0);
}
