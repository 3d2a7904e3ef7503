// Shared by the relight pipelines: parameters, the row and pixel tables, and the pixel pass.
// One workgroup relights one 16 x 16 pixel tile; its 256 threads own the tile's 256 pixels.

struct Params {
    // First tile of this dispatch (global tile index) and how many tiles it covers.
    tile_base: u32,
    tile_count: u32,
    // Workgroups along x in the dispatch grid (tiles beyond 65535 wrap to y).
    dispatch_x: u32,
    // Image width and height, and tiles along x.
    width: u32,
    height: u32,
    tiles_x: u32,
    // Coefficients per row (6 N^2) for the wavelet pass, SH coefficients per stored row for SH.
    coeffs: u32,
    // Light terms in `light` (K, or n^2 for SH).
    terms: u32,
    // How strip values are packed: 0 = q8 (four i8 to a word), 1 = q16 (two i16 to a word),
    // 2 = f32.
    format: u32,
    // First global row of this dispatch's buffers (strips and SH rows are stored per chunk).
    row_base: u32,
    // Tiles with at most this many rows accumulate in workgroup memory (capped by the shader).
    shared_rows: u32,
    // First global block of this dispatch's column tables.
    block_base: u32,
    // Where the tiles' block starts begin in `tile_rows` (after the T + 1 row starts).
    block_table: u32,
    // The wavelet pass takes its terms from light[term_base ..] and, when accumulate is 1, adds
    // its image to what an earlier batch of terms wrote.
    term_base: u32,
    accumulate: u32,
    // Where the strips' values begin in `strips`, in words (after their places).
    values_base: u32,
};

// TILE and WORKGROUP (= TILE * TILE) are defined by the Rust side, which prepends them.

@group(0) @binding(0) var<uniform> params: Params;
// tile_rows[t] .. tile_rows[t + 1] are tile t's rows (global row indices); from
// params.block_table on, the same for its blocks of at most BLOCK_ROWS rows.
@group(0) @binding(1) var<storage, read> tile_rows: array<u32>;
// Per row: RGB weight in xyz, the global pixel index (bitcast) in w.
@group(0) @binding(2) var<storage, read> rows: array<vec4<f32>>;
// Per pixel: linear RGB radiance (xyz). Each pixel belongs to exactly one tile, so only one
// workgroup writes it.
@group(0) @binding(4) var<storage, read_write> image: array<vec4<f32>>;

const NO_PIXEL: u32 = 0xffffffffu;

const NO_TILE: u32 = 0xffffffffu;

// The global tile workgroup `wid` relights, or NO_TILE for the spare workgroups of the dispatch's
// last row. The same for every thread of a workgroup, so returning on it keeps barriers uniform.
fn tile_of(wid: vec3<u32>) -> u32 {
    let local_tile = wid.x + wid.y * params.dispatch_x;
    if (local_tile >= params.tile_count) {
        return NO_TILE;
    }
    return params.tile_base + local_tile;
}

// The image pixel thread `lid` of `tile` owns, or NO_PIXEL past the image's edge.
fn pixel_of(tile: u32, lid: u32) -> u32 {
    let x = (tile % params.tiles_x) * TILE + lid % TILE;
    let y = (tile / params.tiles_x) * TILE + lid / TILE;
    if (x >= params.width || y >= params.height) {
        return NO_PIXEL;
    }
    return y * params.width + x;
}
