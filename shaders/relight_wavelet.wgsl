// The tiled sparse wavelet product over dense strips. A tile's rows are stored in blocks of at
// most BLOCK_ROWS rows; a block's column (coefficient j) is cut into strips of 8 rows, each kept
// whole (its place in the block and 8 values, zero where a row has no entry), and every value is
// the stored integer times the scale of the block's column. For each kept light term
// (coefficient j, RGB value L), the workgroup walks column j's strips in every block of its tile:
// each thread takes values of the strips in turn, and each adds integer x (scale x L) to its row's
// accumulator. A column holds each row at most once and blocks hold different rows, so the
// threads of one term never collide; a barrier separates terms. Then each thread sums the rows
// of the pixel it owns.
//
// A relight with many terms is run in batches of terms, one dispatch each (see
// TERMS_PER_DISPATCH on the Rust side): a batch reads light[params.term_base ..] and, after the
// first, adds its image to the image so far.
//
// Accumulators live in workgroup memory when the tile has at most params.shared_rows rows (the
// usual case: one row per pixel and material seen), else in the global `acc` buffer.

// Per row: the row's dot product with the light (xyz), for tiles with too many rows.
@group(0) @binding(3) var<storage, read_write> acc: array<vec4<f32>>;
// The strips of this chunk: their places in their blocks, four bytes to a word, then from word
// params.values_base on their values, eight a strip, packed as params.format says.
@group(0) @binding(5) var<storage, read> strips: array<u32>;
// Per block of this chunk and coefficient: two words, the first strip (within the chunk), and
// the count of strips with the column's scale code in bits 8..15.
@group(0) @binding(6) var<storage, read> slots: array<u32>;
// Kept light terms: RGB in xyz, coefficient index (bitcast) in w.
@group(0) @binding(7) var<storage, read> light: array<vec4<f32>>;
// The scale of every code: scale(code) = scales[code / 4][code % 4].
@group(0) @binding(8) var<uniform> scales: array<vec4<f32>, 64>;

// 16 KiB, the workgroup storage every WebGPU device offers.
const SHARED_ROWS: u32 = 1024u;
var<workgroup> shared_acc: array<vec4<f32>, SHARED_ROWS>;

// Rows of a strip.
const STRIP_ROWS: u32 = 8u;

// The place in its block of strip s: its rows are place * 8 .. place * 8 + 8.
fn place(s: u32) -> u32 {
    return (strips[s >> 2u] >> ((s & 3u) * 8u)) & 0xffu;
}

// Stored value i of the chunk (value v of strip s is i = 8 s + v): the integer, or the float.
fn value(i: u32) -> f32 {
    let base = params.values_base;
    if (params.format == 0u) {
        // Move the byte to the top, then shift back with its sign.
        let w = strips[base + (i >> 2u)];
        return f32(bitcast<i32>(w << (24u - (i & 3u) * 8u)) >> 24u);
    }
    if (params.format == 1u) {
        let w = strips[base + (i >> 1u)];
        return f32(bitcast<i32>(w << (16u - (i & 1u) * 16u)) >> 16u);
    }
    return bitcast<f32>(strips[base + i]);
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
    let stride = 2u * params.coeffs;
    for (var k = 0u; k < params.terms; k = k + 1u) {
        let term = light[params.term_base + k];
        let j = bitcast<u32>(term.w);
        for (var b = b0; b < b1; b = b + 1u) {
            let slot = (b - params.block_base) * stride + 2u * j;
            let s0 = slots[slot];
            let count = slots[slot + 1u] & 0xffu;
            if (count == 0u) {
                continue;
            }
            let code = (slots[slot + 1u] >> 8u) & 0xffu;
            let l = term.xyz * scales[code / 4u][code % 4u];
            let row_base = (b - b0) * BLOCK_ROWS;
            // A strip of the last, partial block may reach past the tile's rows (as zeros).
            let block_rows = min(BLOCK_ROWS, n - row_base);
            for (var e = lid; e < count * STRIP_ROWS; e = e + WORKGROUP) {
                let s = s0 + e / STRIP_ROWS;
                let r = place(s) * STRIP_ROWS + e % STRIP_ROWS;
                if (r >= block_rows) {
                    continue;
                }
                let row = row_base + r;
                let add = vec4<f32>(value(s * STRIP_ROWS + e % STRIP_ROWS) * l, 0.0);
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
