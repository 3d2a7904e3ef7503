// The tiled sparse wavelet product. For each kept light term (coefficient j, RGB value L), the
// workgroup walks column j of its tile: every entry adds value x L to its row's accumulator. A
// column holds each row at most once, so the threads of one column never collide; a barrier
// separates columns. Then each thread sums the rows of the pixel it owns.
//
// Accumulators live in workgroup memory when the tile has at most params.shared_rows rows (the
// usual case: one row per pixel and material seen), else in the global `acc` buffer.

// Per row: the row's dot product with the light (xyz), for tiles with too many rows.
@group(0) @binding(3) var<storage, read_write> acc: array<vec4<f32>>;
// Entries of this chunk: packed (row | f16 << 16) or (row, f32 bits) pairs, see params.packed.
@group(0) @binding(5) var<storage, read> entries: array<u32>;
// Column pointers of this chunk's tiles: (coeffs + 1) per tile, entry indices within the chunk.
@group(0) @binding(6) var<storage, read> col_ptr: array<u32>;
// Kept light terms: RGB in xyz, coefficient index (bitcast) in w.
@group(0) @binding(7) var<storage, read> light: array<vec4<f32>>;

// 16 KiB, the workgroup storage every WebGPU device offers.
const SHARED_ROWS: u32 = 1024u;
var<workgroup> shared_acc: array<vec4<f32>, SHARED_ROWS>;

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let local_tile = tile_of(wid);
    if (local_tile >= params.tile_count) {
        return;
    }
    let tile = params.tile_base + local_tile;
    let r0 = tile_rows[tile];
    let n = tile_rows[tile + 1u] - r0;
    let in_shared = n <= min(params.shared_rows, SHARED_ROWS);
    for (var r = lid; r < n; r = r + WORKGROUP) {
        if (in_shared) {
            shared_acc[r] = vec4<f32>(0.0);
        } else {
            acc[r0 + r] = vec4<f32>(0.0);
        }
    }
    workgroupBarrier();
    storageBarrier();
    let ptr_base = local_tile * (params.coeffs + 1u);
    for (var k = 0u; k < params.terms; k = k + 1u) {
        let term = light[k];
        let j = bitcast<u32>(term.w);
        let e0 = col_ptr[ptr_base + j];
        let e1 = col_ptr[ptr_base + j + 1u];
        for (var e = e0 + lid; e < e1; e = e + WORKGROUP) {
            var row: u32;
            var value: f32;
            if (params.packed == 1u) {
                let w = entries[e];
                row = w & 0xffffu;
                value = unpack2x16float(w).y;
            } else {
                row = entries[2u * e];
                value = bitcast<f32>(entries[2u * e + 1u]);
            }
            let add = vec4<f32>(value * term.xyz, 0.0);
            if (in_shared) {
                shared_acc[row] = shared_acc[row] + add;
            } else {
                acc[r0 + row] = acc[r0 + row] + add;
            }
        }
        workgroupBarrier();
        storageBarrier();
    }
    let pixel = pixel_of(tile, lid);
    if (pixel == NO_PIXEL) {
        return;
    }
    var sum = vec3<f32>(0.0);
    for (var r = 0u; r < n; r = r + 1u) {
        let row = rows[r0 + r];
        if (bitcast<u32>(row.w) == pixel) {
            var a: vec4<f32>;
            if (in_shared) {
                a = shared_acc[r];
            } else {
                a = acc[r0 + r];
            }
            sum = sum + row.xyz * a.xyz;
        }
    }
    image[pixel] = vec4<f32>(sum, 1.0);
}
