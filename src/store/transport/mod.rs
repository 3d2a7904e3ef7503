//! The transport store: the baked sparse Haar transport, the dense SH transport and per-pixel data
//! of one fixed view, in memory and in a documented safetensors file.
//!
//! # Rows, tiles, blocks and columns
//! The image is cut into [`TILE`] x [`TILE`] pixel tiles, row-major over the tile grid. A *row* is
//! one transport vector over the 6 N² Haar coefficients together with the pixel it lights and an RGB
//! weight: a pixel's radiance is `Σ_rows weight ⊙ (row · L)`. A diffuse pixel that sees one material
//! has one row whose weight is the albedo; a pixel whose sub-samples see several materials has one
//! row per material, so the split stays exact. Rows are grouped by tile; inside a tile they may
//! come in any order, and a bake lays them out kind by kind (every pixel's first lobe, then its
//! glossy lobes, then each pixel's interreflection rows together, ...), so that the rows of a
//! strip (below) keep the same coefficients.
//!
//! A tile's rows are cut into *blocks* of at most [`BLOCK_ROWS`] (256) consecutive rows, so a row
//! index inside a block is one byte; a tile of one row per pixel is one block. Inside a block,
//! coefficient j's *column* holds the rows' nonzero values of that coefficient, each the value
//! `integer · scale(code[block, j]) · row_scale[row]` (see [`crate::store::quant`]). The row
//! scale (the row's largest magnitude) puts rows of very different brightness, such as a glossy
//! lobe beside a diffuse row, on one footing before a block's columns share a scale; the kernels
//! apply it once per row, with the weight.
//!
//! A column is stored as *strips*: aligned runs of 8 rows, kept whole (zeros where a row has no
//! entry) when they hold at least one entry, and every strip of its block when at least half of
//! them do ([`strips::stored_whole`]). Whole tile rows are gathered into *groups* of at
//! least 16 blocks and a group's blocks into *bands* of at most 16; a band's strips are stored
//! coefficient by coefficient, and inside a coefficient block by block ([`strips`]). So one
//! worker owns a group's rows with no atomics, and relighting with K terms reads K contiguous
//! runs of each band. Groups and bands follow from `tile_row_start` alone; the *slots* (band,
//! coefficient, block), in that order, each give a strip count and a scale code.
//!
//! # File (format version 9)
//! A safetensors file (readable from Python with `safetensors.numpy.load_file`); its one metadata
//! entry `meta` is JSON: `format = "wavelet-prt transport"`, `format_version`, `checksum` and the
//! fields of [`TransportMeta`]. Tensors (T tiles, R rows, B blocks, C = 6 N² coefficients, S
//! strips):
//!
//! | tensor | dtype, shape | what |
//! |---|---|---|
//! | `tile_row_start` | u32 [T+1] | tile t holds rows `tile_row_start[t] .. tile_row_start[t+1]`; its blocks are those rows in runs of 256 |
//! | `row_pixel`, `row_weight` | u32 \[R\], f32 [R, 3] | the pixel (y · width + x) and RGB weight of each row |
//! | `row_scale` | f32 \[R\] | each row's stored values are relative to this (its largest magnitude) |
//! | `strip_count` | u8 [B, C] | the strips of each slot, slots in (group, band, coefficient, block) order; they follow one another |
//! | `col_scale` | u8 [B, C] | the scale code of each slot, in the same order: `scale = 2^((code − 192) / 4)` |
//! | `strip_place` | u8 \[S\] | each strip's place in its block: rows `8 · place .. 8 · place + 8`, increasing within a slot |
//! | `strip_value` | i8, i16 or f32 [S, 8] | per strip, the integer (`quantization` q8, q16) or the value (f32, scale 1) of each of its rows, 0 where the row has no entry |
//! | `sh` | f32 [R, n²] | SH transport of each row |
//! | `albedo`, `coverage` | f32 [H, W, 3], f32 [H, W] | per pixel: albedo seen, fraction of sub-samples that hit |
//! | `transport_magnitude` | f32 \[C\] | mean magnitude of each coefficient over the rows (transport weighting) |
//! | `tile_stats` | f64 [T, 3] | per tile: energy dropped by thresholding and quantisation, total energy, shadow rays |
//! | `mesh_position`, `mesh_normal`, `mesh_material`, `mesh_triangle` | f32 [V, 3], f32 [V, 3], u32 \[V\], u32 [F, 3] | only per vertex: the mesh ([`VertexMesh`]) |
//! | `mesh_uv`, `albedo_map`, `albedo_map_material`, `albedo_texel` | f32 [V, 2], u32 [M, 5], u32 [K, 2], u16 [X, 3] | only per vertex with textured materials: each vertex's texture coordinate; per albedo map its width, height, wrap along u and v (0 repeat, 1 mirrored repeat, 2 clamp) and filter (0 linear, 1 nearest); per textured material, the material and its map (materials with the same map share it); the maps' level-0 texels in turn, linear albedo as `q / 65535` ([`crate::scene::albedo_map`]) |
//! | `visibility_bits`, `visibility_lobe`, `visibility_vertex` | u32 [G, ⌈6N²/32⌉], f32 [M, 4], u32 \[G\] | only per vertex with `per_vertex.visibility`: per glossy vertex (listed, ascending), a bit a cube texel in Morton order, set where the texel is open; each material's GGX lobe (specular RGB, α; zero for a diffuse one) ([`crate::scene::visibility::Visibility`]) |
//! | `visibility_light` | f32 [G, L] | only per vertex with `per_vertex.visibility` and local lights: per glossy vertex, its visible share of each light column, from 0 to 1, which weighs the light's highlight drawn per pixel |
//! | `light_value`, `light_scale` | u16 [L, 3, H, W], f32 [L, H] | only with local lights: each light column's RGB response per pixel, as fractions `q / 65535` of a scale per (column, pixel row) ([`LightColumns`]) |
//!
//! Version 4 added the local lights (the two `light_` tensors and the metadata's `lights` and
//! `light_samples`); a version 3 file, which has none, is read as before. Version 5 added the
//! texture coordinates and albedo maps of a textured per-vertex bake (and `per_vertex.albedo_maps`
//! in the metadata); older files have none and are read as before. Versions 6 to 9
//! could keep a glossy per-vertex bake's in-out BRDF terms (the `brdf_` tensors and
//! `per_vertex.brdf_stride`, the pixels a vertex took); this build refuses such a file with a
//! message that says how to bake it again, and reads the others. Version 7 stores the Haar matrix as
//! strips; version 8 stores a slot whole when at least half its block's strips hold entries, its
//! other strips as zeros (version 7 kept only the strips that hold an entry, and still loads:
//! a reused bake of it is written again in this version, its strips made anew); version 9 added
//! the glossy vertices' visibility (the `visibility_` tensors and `per_vertex.visibility`); older
//! files have none and are read as before; version 10 added `visibility_light`, a version 9
//! file with lights is drawn without the lights' highlights, and a reused bake of it is made
//! again; versions 3 to 6
//! stored it as columns, in (block, coefficient) order, blocks in tile
//! order: `col_count` (u16 [B, C], each column's entries), `col_scale` (u8 [B, C]), `entry_row`
//! (u8, each entry's row in its block, increasing within a column) and `entry_value`. They are
//! read into strips. The metadata's `per_vertex.materials` (the scene's material count, which
//! `mesh_material` and `albedo_map_material` index) is absent from files written before it; a map's
//! materials are checked against the vertices'.
//!
//! The `checksum` covers the tensors' bytes in name order and `meta_checksum` the metadata's
//! fields (the JSON of `meta` without `meta_checksum`, as this build writes it), so a flipped bit
//! anywhere is caught; files written before `meta_checksum` existed have none and are read as
//! before. A checksum guards against accidents, not edits: loading checks the header, the sizes
//! and every count, index and value (NaN or infinite floats included) before it allocates
//! anything or trusts any offset, and allocates no more than the file's own tensors hold, but for
//! the slots (8 bytes each in memory, 2 in the file) and, for a file of versions 3 to 6, the
//! strips its columns are made into (at most 8 values for each entry). Writing
//! goes to a temporary file that is renamed into place ([`crate::files`]).

mod assemble;
mod file;
mod groups;
mod legacy;
mod lights;
mod merge;
mod meta;
mod reader;
mod save;
mod stream;
pub mod strips;

#[cfg(test)]
pub(crate) use lights::tests::two_columns;

use std::ops::Range;

use crate::scene::tessellate::VertexMesh;
use crate::store::container;
use crate::store::quant::scale_of;
pub use crate::store::quant::{BLOCK_ROWS, Quantization};
use groups::{PixelTensors, RowTensors, ShTensor};

pub use assemble::{EncodedTile, KeptTiles, RowData, Untiled};
pub use file::{read_format_version, read_header_meta, read_summary};
pub use lights::LightColumns;
pub use merge::shard_of_band;
pub use meta::{
    BakeDomain, BakeIdentity, BakeStats, BounceVisibility, CameraMeta, IndirectSettings,
    PerVertexMeta, TransportMeta,
};
pub use stream::TransportWriter;
pub use strips::Strips;

/// Pixels on a side of a tile.
pub const TILE: usize = 16;
/// Name written in every transport file.
pub const FORMAT_NAME: &str = container::TRANSPORT.name;
/// Version of the layout described in this module.
pub const FORMAT_VERSION: u32 = 10;
/// The oldest version this build reads: versions 3 to 6 store the Haar matrix as columns, which
/// are made into strips as they load; version 3 has no local lights, versions 3 and 4 no albedo
/// maps, versions 3 to 8 no visibility, and versions 3 to 9 no glossy vertex's share of a
/// local light (drawn without the light's highlight).
pub const OLDEST_VERSION: u32 = 3;
/// Largest safetensors header accepted (JSON text), checked before it is read.
const MAX_HEADER_BYTES: u64 = 1 << 24;

/// Stored coefficient values: integers against their column's scale, or lossless floats.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    /// 8-bit integers ([`Quantization::Q8`]).
    Q8(Vec<i8>),
    /// 16-bit integers ([`Quantization::Q16`]).
    Q16(Vec<i16>),
    /// Lossless 32-bit floats, scale 1 ([`Quantization::F32`]).
    F32(Vec<f32>),
}

impl Values {
    /// Empty values of a quantisation.
    pub fn empty(q: Quantization) -> Self {
        match q {
            Quantization::Q8 => Values::Q8(Vec::new()),
            Quantization::Q16 => Values::Q16(Vec::new()),
            Quantization::F32 => Values::F32(Vec::new()),
        }
    }
    /// The quantisation these values are in.
    pub fn quantization(&self) -> Quantization {
        match self {
            Values::Q8(_) => Quantization::Q8,
            Values::Q16(_) => Quantization::Q16,
            Values::F32(_) => Quantization::F32,
        }
    }
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Values::Q8(v) => v.len(),
            Values::Q16(v) => v.len(),
            Values::F32(v) => v.len(),
        }
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Bytes per value.
    pub fn value_bytes(&self) -> usize {
        self.quantization().value_bytes()
    }
    /// Stored value `i` (the integer, or the float) as f32, before its column's scale.
    #[inline]
    pub fn raw(&self, i: usize) -> f32 {
        match self {
            Values::Q8(v) => v[i] as f32,
            Values::Q16(v) => v[i] as f32,
            Values::F32(v) => v[i],
        }
    }
    /// Appends one quantised value.
    fn push(&mut self, q: f32) {
        match self {
            Values::Q8(a) => a.push(q as i8),
            Values::Q16(a) => a.push(q as i16),
            Values::F32(a) => a.push(q),
        }
    }
}

/// A baked view in memory, in the layout of this module. The block tables (`tile_block_start`,
/// `block_row_start`) and the strips' groups and bands are derived from `tile_row_start`.
#[derive(Clone, Debug, PartialEq)]
pub struct Transport {
    /// The header: what was baked, how, and the bake's statistics.
    pub meta: TransportMeta,
    /// Tile t holds rows `tile_row_start[t] .. tile_row_start[t + 1]`.
    pub tile_row_start: Vec<u32>,
    /// The pixel (`y · width + x`) each row lights; the vertex in a per-vertex bake.
    pub row_pixel: Vec<u32>,
    /// The RGB weight of each row.
    pub row_weight: Vec<[f32; 3]>,
    /// Each row's values are stored relative to this.
    pub row_scale: Vec<f32>,
    /// Tile t holds blocks `tile_block_start[t] .. tile_block_start[t + 1]`.
    pub tile_block_start: Vec<u32>,
    /// Block b holds rows `block_row_start[b] .. block_row_start[b + 1]` (global row indices).
    pub block_row_start: Vec<u32>,
    /// The Haar matrix: dense strips of 8 rows in light-major bands of blocks ([`Strips`]).
    pub strips: Strips,
    /// `[rows, n²]` SH transport of each row.
    pub sh: Vec<f32>,
    /// Per pixel: the mean diffuse albedo its sub-samples hit (0 where none hit).
    pub albedo: Vec<[f32; 3]>,
    /// Per pixel: the fraction of its sub-samples that hit geometry, in [0, 1].
    pub coverage: Vec<f32>,
    /// Mean magnitude of each Haar coefficient over the rows (for the transport weighting).
    pub transport_magnitude: Vec<f32>,
    /// Per tile: energy thresholding and quantisation dropped, the rows' total energy, shadow
    /// rays traced.
    pub tile_stats: Vec<[f64; 3]>,
    /// What the file stores beside the rows and the per-pixel tables.
    pub attached: Attached,
}

/// What a transport stores beside its rows and per-pixel tables, each part a file holds or not
/// (the file's tensor groups read, check and write them all): a load, a bake and a merge hand it
/// on whole.
#[derive(Clone, Debug, PartialEq)]
pub struct Attached {
    /// What the rows belong to: the pixels of the baked view, or a mesh's vertices (with their
    /// albedo maps and visibility).
    pub domain: Domain,
    /// The local lights' dense columns (none without local lights; `meta.lights` says which
    /// light each column is).
    pub lights: LightColumns,
}

/// The error of a tensor holding a value that is not finite.
fn non_finite(name: &str) -> String {
    format!("tensor `{name}` holds NaN or infinite values")
}

/// What a transport's rows belong to, and so what can draw it.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Domain {
    /// The pixels of the baked camera's view (`meta.camera`): the image is the relit pixels,
    /// and the camera cannot move.
    #[default]
    View,
    /// The vertices of this mesh, vertex `v` as pixel `v` of an image [`TILE`] wide: the relit
    /// values are vertex colours, drawn from any camera.
    Mesh(VertexMesh),
}

impl Domain {
    /// The mesh of a per-vertex bake; `None` for a view.
    pub fn mesh(&self) -> Option<&VertexMesh> {
        match self {
            Domain::Mesh(mesh) => Some(mesh),
            Domain::View => None,
        }
    }

    /// The domain of a per-vertex bake's mesh, or a view.
    pub fn from_mesh(mesh: Option<VertexMesh>) -> Domain {
        mesh.map_or(Domain::View, Domain::Mesh)
    }
}

impl Attached {
    /// Whether the parts hold anything in the image's pixel rows `rows` (a shard holds nothing
    /// outside its own bands).
    fn holds_rows(&self, rows: Range<usize>) -> bool {
        !self.lights.rows_are_zero(rows)
    }

    /// What a merge of shards fills band by band ([`Attached::copy_rows`]): the domain, which
    /// every shard shares, and the header's `columns` light columns over its `w` x `h` image,
    /// all zero.
    fn emptied(&self, (columns, w, h): (usize, usize, usize)) -> Attached {
        Attached {
            domain: self.domain.clone(),
            lights: LightColumns::zeros(columns, w, h),
        }
    }

    /// Copies `from`'s pixel rows `rows` (a shard's band) into these parts.
    fn copy_rows(&mut self, from: &Attached, rows: Range<usize>) {
        self.lights.copy_rows(&from.lights, rows);
    }
}

/// Tiles along x and y for an image.
pub fn tile_grid(width: usize, height: usize) -> (usize, usize) {
    (width.div_ceil(TILE), height.div_ceil(TILE))
}

/// Blocks a tile of `rows` rows is cut into.
pub fn blocks_of(rows: usize) -> usize {
    rows.div_ceil(BLOCK_ROWS)
}

impl Transport {
    /// The mesh of a per-vertex bake; `None` for a view.
    pub fn mesh(&self) -> Option<&VertexMesh> {
        self.attached.domain.mesh()
    }

    /// Haar coefficients per row, 6 N².
    pub fn coeff_count(&self) -> usize {
        6 * (self.meta.identity.cube_n as usize).pow(2)
    }
    /// Number of pixel tiles.
    pub fn tile_count(&self) -> usize {
        self.tile_row_start.len() - 1
    }
    /// Number of row blocks.
    pub fn block_count(&self) -> usize {
        self.block_row_start.len() - 1
    }
    /// Pixels in the image.
    pub fn pixel_count(&self) -> usize {
        self.meta.width as usize * self.meta.height as usize
    }
    /// SH coefficients per row.
    pub fn sh_count(&self) -> usize {
        (self.meta.identity.sh_order as usize).pow(2)
    }
    /// The blocks of tile `t`.
    #[inline]
    pub fn blocks(&self, t: usize) -> Range<usize> {
        self.tile_block_start[t] as usize..self.tile_block_start[t + 1] as usize
    }
    /// The quantisation of the stored values.
    pub fn quantization(&self) -> Quantization {
        self.strips.values.quantization()
    }
    /// The scale of coefficient `j` in block `b`.
    pub fn scale(&self, b: usize, j: usize) -> f32 {
        scale_of(self.strips.slot(b, j, self.coeff_count()).code)
    }
    /// The entries of coefficient `j` in block `b`: each row (a global row index) and its
    /// decoded value, rows increasing.
    pub fn column(&self, b: usize, j: usize) -> impl Iterator<Item = (usize, f32)> + '_ {
        let slot = self.strips.slot(b, j, self.coeff_count());
        let (scale, r0) = (scale_of(slot.code), self.block_row_start[b] as usize);
        self.strips
            .column(slot)
            .map(move |(r, v)| (r0 + r as usize, v * scale * self.row_scale[r0 + r as usize]))
    }
    /// Stored coefficients (entries) in all.
    pub fn nonzeros(&self) -> u64 {
        self.strips.entry_count()
    }
    /// Bytes of the sparse Haar matrix as stored in the file: the strips, and per (block,
    /// coefficient) a strip count and a scale code.
    pub fn haar_bytes(&self) -> usize {
        self.strips.bytes()
    }
    /// Rows of each block.
    pub fn block_rows(&self) -> Vec<u32> {
        self.block_row_start
            .windows(2)
            .map(|w| w[1] - w[0])
            .collect()
    }

    /// Checks every index and offset, so kernels may index without further checks. Returns a
    /// message naming the first inconsistency.
    pub fn validate(&self) -> std::result::Result<(), String> {
        let m = &self.meta;
        let (w, h) = (m.width as usize, m.height as usize);
        let (tx, ty) = tile_grid(w, h);
        let tiles = tx * ty;
        let c = self.coeff_count();
        let r = self.row_pixel.len();
        if self.tile_row_start.len() != tiles + 1 || self.tile_block_start.len() != tiles + 1 {
            return Err("tile tables do not match the image size".into());
        }
        let (tile_blocks, block_rows) = block_tables(&self.tile_row_start, r)?;
        if tile_blocks != self.tile_block_start || block_rows != self.block_row_start {
            return Err("block tables do not follow from the tiles' rows".into());
        }
        let layout = strips::Layout::of(&self.tile_block_start, tx);
        if self.strips.layout() != layout {
            return Err("the strips' groups and bands do not follow from the tiles' rows".into());
        }
        if self.quantization() != m.identity.quantization {
            return Err(format!(
                "values are {} but the header says {}",
                self.quantization(),
                m.identity.quantization
            ));
        }
        if let Some(p) = self.strips.problem(&self.block_rows(), c) {
            return Err(p);
        }
        if self.row_weight.len() != r
            || self.row_scale.len() != r
            || self.sh.len() != r * self.sh_count()
        {
            return Err("row tables have different lengths".into());
        }
        for t in 0..tiles {
            let (r0, r1) = (
                self.tile_row_start[t] as usize,
                self.tile_row_start[t + 1] as usize,
            );
            let (x0, y0) = ((t % tx) * TILE, (t / tx) * TILE);
            for &p in &self.row_pixel[r0..r1] {
                let (px, py) = (p as usize % w.max(1), p as usize / w.max(1));
                if p as usize >= w * h || px < x0 || px >= x0 + TILE || py < y0 || py >= y0 + TILE {
                    return Err(format!("tile {t}: row pixel {p} lies outside the tile"));
                }
            }
        }
        if !self.sh.iter().all(|x| x.is_finite()) {
            return Err(non_finite(ShTensor::NAME));
        }
        if !self.row_weight.iter().flatten().all(|x| x.is_finite()) {
            return Err(non_finite(RowTensors::WEIGHT));
        }
        if !self.row_scale.iter().all(|x| x.is_finite() && *x > 0.0) {
            return Err(format!(
                "tensor `{}`: every row scale must be finite and positive",
                RowTensors::SCALE
            ));
        }
        if self.albedo.len() != w * h
            || self.coverage.len() != w * h
            || self.transport_magnitude.len() != c
            || self.tile_stats.len() != tiles
        {
            return Err("per-pixel or per-coefficient tables have the wrong length".into());
        }
        for (name, finite) in [
            (
                PixelTensors::ALBEDO,
                self.albedo.iter().flatten().all(|x| x.is_finite()),
            ),
            (
                PixelTensors::COVERAGE,
                self.coverage.iter().all(|x| x.is_finite()),
            ),
            (
                PixelTensors::MAGNITUDE,
                self.transport_magnitude.iter().all(|x| x.is_finite()),
            ),
            (
                RowTensors::TILE_STATS,
                self.tile_stats.iter().flatten().all(|x| x.is_finite()),
            ),
        ] {
            if !finite {
                return Err(non_finite(name));
            }
        }
        if (self.attached.lights.width, self.attached.lights.height) != (w, h) {
            return Err("the light columns are not the image's size".into());
        }
        if let Some(p) = self.attached.lights.problem(m.light_columns()) {
            return Err(p);
        }
        self.validate_mesh()
    }

    /// A per-vertex bake's mesh against its header: one vertex per pixel up to the count, the
    /// counts the header gives, and a consistent mesh; a view has neither mesh nor its header.
    fn validate_mesh(&self) -> std::result::Result<(), String> {
        let (pv, mesh) = match (&self.meta.per_vertex, self.mesh()) {
            (None, None) => return Ok(()),
            (Some(pv), Some(mesh)) => (pv, mesh),
            (Some(_), None) => return Err("a per-vertex header without its mesh".into()),
            (None, Some(_)) => return Err("a mesh without the per-vertex header".into()),
        };
        let v = pv.vertices as usize;
        let pixels = (self.meta.width * self.meta.height) as usize;
        if self.meta.width as usize != TILE || v > pixels || v + TILE <= pixels {
            return Err(format!(
                "{v} vertices do not fill an image {} x {} (it must be {TILE} wide, with only its \
                 last row part empty)",
                self.meta.width, self.meta.height
            ));
        }
        if mesh.vertex_count() != v || mesh.triangles.len() != pv.triangles as usize {
            return Err(format!(
                "the mesh has {} vertices and {} triangles, the header says {v} and {}",
                mesh.vertex_count(),
                mesh.triangles.len(),
                pv.triangles
            ));
        }
        match self.meta.identity.domain.edge_length() {
            Some(e) if e.is_finite() && e > 0.0 => {}
            e => return Err(format!("edge length {e:?}")),
        }
        if pv.image.iter().any(|&s| s == 0 || s > 16384) {
            return Err(format!("image size {:?}", pv.image));
        }
        let materials = groups::mesh_values_problem(pv, mesh)?;
        if let Some(p) = mesh.problem(materials.unwrap_or(u32::MAX as usize)) {
            return Err(format!("mesh: {p}"));
        }
        if mesh.albedo_maps.len() != pv.albedo_maps as usize {
            return Err(format!(
                "{} albedo maps, the header says {}",
                mesh.albedo_maps.len(),
                pv.albedo_maps
            ));
        }
        if let Some(r) = self.row_pixel.iter().find(|&&p| p as usize >= v) {
            return Err(format!("a row of pixel {r}, past the {v} vertices"));
        }
        Ok(())
    }
}

/// The blocks of every tile and the rows of every block, from the tiles' row starts; checks that
/// the starts begin at 0, never decrease and end at `rows`.
fn block_tables(
    tile_row_start: &[u32],
    rows: usize,
) -> std::result::Result<(Vec<u32>, Vec<u32>), String> {
    if tile_row_start.first() != Some(&0) || *tile_row_start.last().unwrap_or(&0) as usize != rows {
        return Err("tile_row_start does not span the rows".into());
    }
    if let Some(t) = tile_row_start.windows(2).position(|w| w[1] < w[0]) {
        return Err(format!("tile {t}: row offsets decrease"));
    }
    let mut tile_blocks = Vec::with_capacity(tile_row_start.len());
    let mut block_rows = vec![0u32];
    tile_blocks.push(0u32);
    for w in tile_row_start.windows(2) {
        let mut start = w[0];
        while start < w[1] {
            start = (start + BLOCK_ROWS as u32).min(w[1]);
            block_rows.push(start);
        }
        tile_blocks.push(block_rows.len() as u32 - 1);
    }
    Ok((tile_blocks, block_rows))
}

/// Where each block's entries start, from the file's per-(block, coefficient) column counts
/// (versions 3 to 6); checks each count against its block's rows and the total against the
/// entries.
fn column_pointers(
    counts: &[u16],
    block_row_start: &[u32],
    c: usize,
    nnz: usize,
) -> std::result::Result<Vec<u64>, String> {
    let blocks = block_row_start.len() - 1;
    if counts.len() != blocks * c {
        return Err(format!(
            "{} column counts for {blocks} blocks of {c} coefficients",
            counts.len()
        ));
    }
    let mut starts = Vec::with_capacity(blocks + 1);
    starts.push(0u64);
    let mut total = 0u64;
    for b in 0..blocks {
        let rows = (block_row_start[b + 1] - block_row_start[b]) as u16;
        for (j, &n) in counts[b * c..(b + 1) * c].iter().enumerate() {
            if n > rows {
                return Err(format!(
                    "block {b}, coefficient {j}: {n} entries in a block of {rows} rows"
                ));
            }
            total += n as u64;
        }
        starts.push(total);
    }
    if total != nnz as u64 {
        return Err(format!(
            "column counts add up to {total} entries but the file stores {nnz}"
        ));
    }
    Ok(starts)
}
