// The tiled sparse wavelet product. A tile's rows are stored in blocks of at most BLOCK_ROWS rows;
// inside a block, each coefficient's entries are (row byte, integer) pairs whose value is the
// integer times the scale of the block's column. For each kept light term (coefficient j, RGB
// value L), the workgroup walks column j of every block of its tile: every entry adds
// integer x (scale x L) to its row's accumulator. A column holds each row at most once and blocks
// hold different rows, so the threads of one term never collide; a barrier separates terms. Then
// each thread sums the rows of the pixel it owns.
//
// A relight with many terms is run in batches of terms, one dispatch each (see
// TERMS_PER_DISPATCH on the Rust side): a batch reads light[params.term_base ..] and, after the
// first, adds its image to the image so far.
//
// Accumulators live in workgroup memory when the tile has at most params.shared_rows rows (the
// usual case: one row per pixel and material seen), else in the global `acc` buffer.

// Per row: the row's dot product with the light (xyz), for tiles with too many rows.
@group(0) @binding(3) var<storage, read_write> acc: array<vec4<f32>>;
// Entries of this chunk, packed as params.format says.
@group(0) @binding(5) var<storage, read> entries: array<u32>;
// Per block of this chunk: coeffs + 1 column pointers (entry indices within the chunk), then the
// coeffs scale codes, four bytes to a word.
@group(0) @binding(6) var<storage, read> col_ptr: array<u32>;
// Kept light terms: RGB in xyz, coefficient index (bitcast) in w.
@group(0) @binding(7) var<storage, read> light: array<vec4<f32>>;
// The scale of every code: scale(code) = scales[code / 4][code % 4].
@group(0) @binding(8) var<uniform> scales: array<vec4<f32>, 64>;

// 16 KiB, the workgroup storage every WebGPU device offers.
const SHARED_ROWS: u32 = 1024u;
var<workgroup> shared_acc: array<vec4<f32>, SHARED_ROWS>;

// The row (inside its block) and the stored integer or float of entry e.
fn entry(e: u32) -> vec2<f32> {
    if (params.format == 0u) {
        let half = entries[e >> 1u] >> ((e & 1u) * 16u);
        // Bits 8..15 hold the signed byte: move them to the top, then shift back with sign.
        return vec2<f32>(f32(half & 0xffu), f32(bitcast<i32>(half << 16u) >> 24u));
    }
    if (params.format == 1u) {
        let w = entries[e];
        return vec2<f32>(f32(w & 0xffu), f32(bitcast<i32>(w) >> 16u));
    }
    return vec2<f32>(f32(entries[2u * e]), bitcast<f32>(entries[2u * e + 1u]));
}

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let tile = tile_of(wid);
    if (tile == NO_TILE) {
        return;
    }
    let r0 = tile_rows[tile];
    let n = tile_rows[tile + 1u] - r0;
    let b0 = tile_rows[params.block_table + tile];
    let b1 = tile_rows[params.block_table + tile + 1u];
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
    let stride = params.coeffs + 1u + (params.coeffs + 3u) / 4u;
    for (var k = 0u; k < params.terms; k = k + 1u) {
        let term = light[params.term_base + k];
        let j = bitcast<u32>(term.w);
        for (var b = b0; b < b1; b = b + 1u) {
            let base = (b - params.block_base) * stride;
            let e0 = col_ptr[base + j];
            let e1 = col_ptr[base + j + 1u];
            if (e0 == e1) {
                continue;
            }
            let code = (col_ptr[base + params.coeffs + 1u + j / 4u] >> ((j % 4u) * 8u)) & 0xffu;
            let l = term.xyz * scales[code / 4u][code % 4u];
            let row_base = (b - b0) * BLOCK_ROWS;
            for (var e = e0 + lid; e < e1; e = e + WORKGROUP) {
                let rv = entry(e);
                let row = row_base + u32(rv.x);
                let add = vec4<f32>(rv.y * l, 0.0);
                if (in_shared) {
                    shared_acc[row] = shared_acc[row] + add;
                } else {
                    acc[r0 + row] = acc[r0 + row] + add;
                }
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
    if (params.accumulate != 0u) {
        image[pixel] = image[pixel] + vec4<f32>(sum, 0.0);
    } else {
        image[pixel] = vec4<f32>(sum, 1.0);
    }
}
