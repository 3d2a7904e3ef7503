//! Reading the transport file (format version 9, laid out in the [module docs](super); versions
//! 3 to 6, which stored columns, into strips; version 7, whose slots are whole only when full, as
//! stored): reading and validating all of it, and reading only its header and small tables for
//! `prt info`. Every size and index is checked before anything is sliced or allocated.

use std::io::Read;
use std::path::Path;

use safetensors::tensor::Dtype;
use serde::{Deserialize, Serialize};

use super::legacy::{Columns, strips_of_columns};
use super::reader::TensorReader;
use super::strips::{Layout, STRIP_ROWS};
use super::tensors::{FileTensors, MapTensors, MeshTensors, Tensor, VisibilityTensors, read_all};
use super::*;
use crate::error::{PrtError, Result};
use crate::scene::albedo_map::from_table;
use crate::scene::visibility::Visibility;
use crate::store::container::{self, check_meta_seal};

impl Transport {
    /// Reads and fully validates a transport file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with_progress(path, &|_, _| {})
    }

    /// [`Transport::load`], calling `progress(bytes read, file size)` as the file comes in (the
    /// viewer shows it; validation after the read is quick).
    pub fn load_with_progress(path: &Path, progress: &dyn Fn(u64, u64)) -> Result<Self> {
        let Header {
            meta,
            version,
            checksum: stored,
            tensors,
            data_start,
            file,
        } = read_header(path)?;
        // One pass over the tensors in name order (the order the checksum covers them), each
        // read straight into its table: memory holds the transport once and no copy of the file.
        // Shapes are checked once the checksum has passed.
        let mut reader = TensorReader::new(path, &tensors, data_start, file, progress)?;
        let (w, h) = (meta.width as usize, meta.height as usize);
        let (tx, ty) = tile_grid(w, h);
        let tiles = tx * ty;
        let c = 6 * (meta.identity.cube_n as usize).pow(2);
        let FileTensors {
            albedo: (albedo_shape, albedo),
            map_tables,
            col_count,
            col_scale: (scale_shape, col_scale),
            coverage: (coverage_shape, coverage),
            entries,
            light_tables,
            mesh,
            mesh_uv,
            row_pixel: (pixel_shape, row_pixel),
            row_scale: (row_scale_shape, row_scale),
            row_weight: (weight_shape, row_weight),
            sh: (sh_shape, sh),
            strip_tables,
            tile_row_start: (start_shape, tile_row_start),
            tile_stats: (stats_shape, tile_stats),
            transport_magnitude: (magnitude_shape, transport_magnitude),
            visibility,
        } = read_all(&mut reader, &meta, version)?;
        let map_count = meta
            .per_vertex
            .as_ref()
            .map_or(0, |p| p.albedo_maps as usize);
        let columns = meta.light_columns();
        check_checksum(path, &stored, reader.checksum())?;
        let expect = |name: &str, shape: &[usize], want: &[usize]| -> Result<()> {
            if shape != want {
                return Err(PrtError::file(
                    path,
                    format!("tensor `{name}` has shape {shape:?}, expected {want:?}"),
                ));
            }
            Ok(())
        };
        let bad = |m: String| PrtError::file(path, m);
        expect("tile_row_start", &start_shape, &[tiles + 1])?;
        let r = pixel_shape.first().copied().unwrap_or(0);
        expect("row_pixel", &pixel_shape, &[r])?;
        // The block tables follow from the tiles' row counts, checked before anything is sized
        // by them.
        let (tile_block_start, block_row_start) = block_tables(&tile_row_start, r).map_err(bad)?;
        let blocks = block_row_start.len() - 1;
        expect("row_weight", &weight_shape, &[r, 3])?;
        expect("row_scale", &row_scale_shape, &[r])?;
        expect("col_scale", &scale_shape, &[blocks, c])?;
        let (tx, _) = tile_grid(w, h);
        let layout = Layout::of(&tile_block_start, tx);
        let strips = match (entries, col_count, strip_tables) {
            (
                Some(((entry_shape, entry_row), (value_shape, values))),
                Some((count_shape, counts)),
                _,
            ) => {
                expect("col_count", &count_shape, &[blocks, c])?;
                let nnz = entry_shape.first().copied().unwrap_or(0);
                expect("entry_row", &entry_shape, &[nnz])?;
                expect("entry_value", &value_shape, &[nnz])?;
                let columns = Columns {
                    block_row_start: &block_row_start,
                    c,
                    counts: &counts,
                    codes: &col_scale,
                    rows: &entry_row,
                };
                strips_of_columns(layout, columns, &values).map_err(bad)?
            }
            (_, _, Some(((count_shape, counts), (place_shape, place), (value_shape, values)))) => {
                expect("strip_count", &count_shape, &[blocks, c])?;
                let strips = place_shape.first().copied().unwrap_or(0);
                expect("strip_place", &place_shape, &[strips])?;
                expect("strip_value", &value_shape, &[strips, STRIP_ROWS])?;
                Strips::from_tables(layout, &counts, &col_scale, place, values).map_err(bad)?
            }
            _ => return Err(bad("neither columns nor strips were read".into())),
        };
        expect(
            "sh",
            &sh_shape,
            &[r, (meta.identity.sh_order as usize).pow(2)],
        )?;
        expect("albedo", &albedo_shape, &[h, w, 3])?;
        expect("coverage", &coverage_shape, &[h, w])?;
        expect("transport_magnitude", &magnitude_shape, &[c])?;
        expect("tile_stats", &stats_shape, &[tiles, 3])?;
        let lights = light_columns(light_tables, (columns, w, h), &expect)?;
        let mesh = match (&meta.per_vertex, mesh) {
            (Some(pv), Some(tables)) => Some(
                MeshTables {
                    tables,
                    uv: mesh_uv,
                    maps: map_tables,
                }
                .into_mesh(pv, map_count, &expect, &bad)?,
            ),
            _ => None,
        };
        let mesh = with_visibility(mesh, visibility, meta.identity.cube_n as usize, &expect)
            .map_err(|e| bad(e.to_string()))?;
        let t = Transport {
            meta,
            tile_row_start,
            row_pixel,
            row_weight,
            row_scale,
            tile_block_start,
            block_row_start,
            strips,
            sh,
            albedo,
            coverage,
            transport_magnitude,
            tile_stats,
            domain: Domain::from_mesh(mesh),
            lights,
        };
        t.validate().map_err(bad)?;
        Ok(t)
    }
}

/// Reads only the safetensors header and our metadata, checking that the declared tensors fill the
/// file exactly and that the format and version are ours; allocates nothing proportional to the
/// data.
pub fn read_header_meta(path: &Path) -> Result<TransportMeta> {
    read_header(path).map(|h| h.meta)
}

/// The format version of the transport file `path`, its header checked as [`read_header_meta`]
/// checks it.
pub fn read_format_version(path: &Path) -> Result<u32> {
    read_header(path).map(|h| h.version)
}

/// The header and the small tables, for `prt info`: the metadata, checked as
/// [`read_header_meta`] does, and the tile and strip-count tables (column counts before version
/// 7), checked against each other and against the strips (entries) the header declares. The
/// strips, nearly all of the file, are neither read nor checked (their checksum needs them all).
pub fn read_summary(path: &Path) -> Result<TransportMeta> {
    let Header {
        meta,
        version,
        tensors,
        data_start,
        file,
        ..
    } = read_header(path)?;
    let mut reader = TensorReader::new(path, &tensors, data_start, file, &|_, _| {})?;
    let legacy = version < 7;
    // Read in name order: `col_count` (versions 3 to 6) before `strip_count` before
    // `tile_row_start`.
    let col_counts: Option<(_, Vec<u16>)> = if legacy {
        Some(reader.read("col_count", Dtype::U16)?)
    } else {
        None
    };
    let strip_counts: Option<(_, Vec<u8>)> = if legacy {
        None
    } else {
        Some(reader.read("strip_count", Dtype::U8)?)
    };
    let (_, starts): (_, Vec<u32>) = reader.read("tile_row_start", Dtype::U32)?;
    // The large tensors are only counted; their bytes need the whole file's checksum.
    let count = |name: &str, bytes_each: u64| -> Result<usize> {
        let (_, shape, start, end) = reader.locate(name)?;
        let elements = shape.iter().try_fold(1u64, |n, &d| n.checked_mul(d as u64));
        match shape[..] {
            [n, ..] if elements.and_then(|e| e.checked_mul(bytes_each)) == Some(end - start) => {
                Ok(n)
            }
            _ => Err(PrtError::file(
                path,
                format!("tensor `{name}` of shape {shape:?} does not fill its bytes"),
            )),
        }
    };
    let rows = count("row_pixel", 4)?;
    let (tx, ty) = tile_grid(meta.width as usize, meta.height as usize);
    if starts.len() != tx * ty + 1 {
        return Err(PrtError::file(
            path,
            "tile tables do not match the image size",
        ));
    }
    let (_, block_rows) = block_tables(&starts, rows).map_err(|m| PrtError::file(path, m))?;
    let c = 6 * meta.identity.cube_n as usize * meta.identity.cube_n as usize;
    let blocks = block_rows.len() - 1;
    match (col_counts, strip_counts) {
        (Some((_, counts)), _) => {
            let nnz = count("entry_row", 1)?;
            if counts.len() != blocks * c {
                return Err(PrtError::file(
                    path,
                    "column counts do not match the blocks and coefficients",
                ));
            }
            column_pointers(&counts, &block_rows, c, nnz).map_err(|m| PrtError::file(path, m))?;
        }
        (_, Some((_, counts))) => {
            let strips = count("strip_place", 1)?;
            let counted: u64 = counts.iter().map(|&n| n as u64).sum();
            if counts.len() != blocks * c {
                return Err(PrtError::file(
                    path,
                    "strip counts do not match the blocks and coefficients",
                ));
            }
            if counted != strips as u64 {
                return Err(PrtError::file(
                    path,
                    format!("strip counts add up to {counted} strips but the file stores {strips}"),
                ));
            }
        }
        _ => {}
    }
    Ok(meta)
}

/// What [`read_header`] gives: the checked metadata, the stored tensor checksum, the header's
/// tensor entries (name to dtype, shape and offsets), where the tensor data starts, and the open
/// file.
struct Header {
    meta: TransportMeta,
    version: u32,
    checksum: String,
    tensors: serde_json::Map<String, serde_json::Value>,
    data_start: u64,
    file: std::fs::File,
}

/// The error for a file that is no transport at all: what it is when its first bytes tell
/// ([`container::what_else`]), else `why`.
fn not_a_transport(path: &Path, why: String) -> PrtError {
    PrtError::file(
        path,
        container::what_else(path, container::TRANSPORT).unwrap_or(why),
    )
}

/// [`read_header_meta`], with what the rest of a reader needs (see [`Header`]).
fn read_header(path: &Path) -> Result<Header> {
    let (mut f, file_len) = crate::files::open_regular(path, u64::MAX, "transport")?;
    let mut len8 = [0u8; 8];
    f.read_exact(&mut len8)
        .map_err(|_| not_a_transport(path, "too short to be a transport file".into()))?;
    let header_len = u64::from_le_bytes(len8);
    if header_len > MAX_HEADER_BYTES || header_len + 8 > file_len {
        return Err(not_a_transport(
            path,
            format!("header length {header_len} does not fit a file of {file_len} bytes"),
        ));
    }
    let mut header = vec![0u8; header_len as usize];
    f.read_exact(&mut header)
        .map_err(|e| PrtError::file(path, format!("reading header: {e}")))?;
    let json: serde_json::Value = serde_json::from_slice(&header)
        .map_err(|e| not_a_transport(path, format!("header is not JSON: {e}")))?;
    let obj = json
        .as_object()
        .ok_or_else(|| PrtError::file(path, "header is not a JSON object"))?;
    let info = obj
        .get("__metadata__")
        .and_then(|m| m.as_object())
        .ok_or_else(|| PrtError::file(path, "no metadata: not a wavelet-prt transport file"))?;
    let text = info
        .get("meta")
        .and_then(|v| v.as_str())
        .ok_or_else(|| PrtError::file(path, "not a wavelet-prt transport file (no `meta`)"))?;
    container::check_metadata_entries(info.keys()).map_err(|m| PrtError::file(path, m))?;
    let value: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| PrtError::file(path, format!("metadata `meta` is not JSON: {e}")))?;
    let format = value.get("format").and_then(|v| v.as_str());
    if let Some(e) = container::other_format(path, format, container::TRANSPORT) {
        return Err(e);
    }
    if format != Some(FORMAT_NAME) {
        return Err(PrtError::file(
            path,
            "not a wavelet-prt transport file (metadata `format`)",
        ));
    }
    let version = value.get("format_version").and_then(|v| v.as_u64());
    match version {
        Some(v) if (OLDEST_VERSION as u64..=FORMAT_VERSION as u64).contains(&v) => {}
        Some(v) if v < OLDEST_VERSION as u64 => {
            return Err(PrtError::file(
                path,
                format!(
                    "format_version {v} was written by an older build (16-bit float values); \
                     this build reads versions {OLDEST_VERSION} to {FORMAT_VERSION}: bake the scene again with \
                     `prt bake`"
                ),
            ));
        }
        _ => {
            return Err(PrtError::file(
                path,
                format!(
                    "format_version {}; this build reads versions {OLDEST_VERSION} to \
                     {FORMAT_VERSION}",
                    version.map(|v| v.to_string()).unwrap_or("?".into())
                ),
            ));
        }
    }
    check_meta_seal(text).map_err(|m| PrtError::file(path, m))?;
    let header: FileHeader = serde_json::from_value(value)
        .map_err(|e| PrtError::file(path, format!("metadata `meta`: {e}")))?;
    container::check_known_keys(text, &header).map_err(|m| PrtError::file(path, m))?;
    let known = tensor_names(header.format_version, &header.meta);
    if let Some(name) = obj
        .keys()
        .find(|k| *k != "__metadata__" && !known.contains(&k.as_str()))
    {
        return Err(PrtError::file(
            path,
            format!(
                "unknown tensor `{}`: a transport file holds {}",
                crate::files::printable(name),
                known.join(", ")
            ),
        ));
    }
    let mut data_end = 0u64;
    for (name, t) in obj.iter().filter(|(k, _)| *k != "__metadata__") {
        let end = t
            .get("data_offsets")
            .and_then(|o| o.get(1))
            .and_then(|e| e.as_u64())
            .ok_or_else(|| PrtError::file(path, format!("tensor `{name}` has no data_offsets")))?;
        data_end = data_end.max(end);
    }
    if 8 + header_len + data_end != file_len {
        return Err(PrtError::file(
            path,
            format!(
                "tensors need {} bytes but the file has {file_len}: truncated or padded",
                8 + header_len + data_end
            ),
        ));
    }
    check_meta(&header.meta).map_err(|m| PrtError::file(path, m))?;
    Ok(Header {
        meta: header.meta,
        version: header.format_version,
        checksum: header.checksum,
        tensors: obj.clone(),
        data_start: 8 + header_len,
        file: f,
    })
}

/// The one metadata entry of a file: format, version, checksum and the [`TransportMeta`]
/// (`meta_checksum` follows them in the text, see [`container::seal_meta`]).
#[derive(Serialize, Deserialize)]
pub(super) struct FileHeader {
    pub format: String,
    pub format_version: u32,
    /// Of the tensors (see [`container::checksum`]).
    pub checksum: String,
    #[serde(flatten)]
    pub meta: TransportMeta,
}

fn check_meta(m: &TransportMeta) -> std::result::Result<(), String> {
    // A per-vertex bake's image is one tile wide and as tall as its vertices need.
    let tallest = match m.per_vertex {
        Some(_) => crate::scene::tessellate::MAX_VERTICES.div_ceil(TILE) as u32,
        None => 16384,
    };
    if m.width == 0 || m.height == 0 || m.width > 16384 || m.height > tallest {
        return Err(format!(
            "image size {} x {} out of range",
            m.width, m.height
        ));
    }
    if m.tile as usize != TILE {
        return Err(format!("tile size {}; this build uses {TILE}", m.tile));
    }
    crate::math::cubemap::validate_n(m.identity.cube_n as usize).map_err(|e| e.to_string())?;
    if m.identity.sh_order == 0 || m.identity.sh_order as usize > crate::math::sh::MAX_ORDER {
        return Err(format!("SH order {} out of range", m.identity.sh_order));
    }
    if let Some([i, n]) = m.identity.shard {
        // A bake cuts at most one shard per band of tile rows.
        let (_, bands) = tile_grid(m.width as usize, m.height as usize);
        if n == 0 || i >= n || n as usize > bands {
            return Err(format!(
                "shard {i}/{n}: a shard is I/COUNT with I < COUNT <= {bands} (the image's \
                 bands of tile rows)"
            ));
        }
    }
    if !(m.identity.threshold.is_finite() && m.identity.threshold >= 0.0) {
        return Err(format!(
            "threshold {} must be finite and >= 0",
            m.identity.threshold
        ));
    }
    let columns = m.light_columns();
    if columns > crate::scene::light::MAX_LIGHT_COLUMNS {
        return Err(format!(
            "{columns} light columns; a transport holds at most {}",
            crate::scene::light::MAX_LIGHT_COLUMNS
        ));
    }
    if let Some(i) =
        (0..m.lights.len()).find(|&i| m.lights[..i].iter().any(|o| o.name == m.lights[i].name))
    {
        return Err(format!("two lights are called `{}`", m.lights[i].name));
    }
    let c = &m.camera;
    if !c
        .eye
        .iter()
        .chain(&c.target)
        .chain(&c.up)
        .all(|v| v.is_finite())
        || !c.fov_y_deg.is_finite()
    {
        return Err("camera: every number must be finite".into());
    }
    Ok(())
}

/// Names of the tensors in a file of `version` with `meta`, in the order the checksum covers
/// them: those of every file, a per-vertex bake's mesh, its albedo maps and visibility, and the
/// local lights' columns.
pub(super) fn tensor_names(version: u32, meta: &TransportMeta) -> Vec<&'static str> {
    let pv = meta.per_vertex.as_ref();
    let per_vertex = pv.is_some();
    let albedo_maps = pv.is_some_and(|p| p.albedo_maps > 0);
    let lights = meta.light_columns() > 0;
    let mut names: Vec<&str> = TENSOR_NAMES.to_vec();
    if version < 7 {
        names.extend(["col_count", "entry_row", "entry_value"]);
    } else {
        names.extend(["strip_count", "strip_place", "strip_value"]);
    }
    if per_vertex {
        names.extend(MESH_TENSOR_NAMES);
    }
    if albedo_maps {
        names.extend([
            "albedo_map",
            "albedo_map_material",
            "albedo_texel",
            "mesh_uv",
        ]);
    }
    if lights {
        names.extend(["light_scale", "light_value"]);
    }
    if per_vertex && meta.identity.visibility {
        names.extend(["visibility_bits", "visibility_lobe", "visibility_vertex"]);
    }
    names.sort();
    names
}

/// The tensors of a per-vertex bake's mesh.
const MESH_TENSOR_NAMES: [&str; 4] = [
    "mesh_material",
    "mesh_normal",
    "mesh_position",
    "mesh_triangle",
];

/// The tensors of every file, besides its Haar matrix's (strips from version 7, columns
/// before).
const TENSOR_NAMES: [&str; 10] = [
    "albedo",
    "col_scale",
    "coverage",
    "row_pixel",
    "row_scale",
    "row_weight",
    "sh",
    "tile_row_start",
    "tile_stats",
    "transport_magnitude",
];

/// An error unless the checksum computed over the tensors, `computed`, is the one stored.
fn check_checksum(path: &Path, stored: &str, computed: u64) -> Result<()> {
    let sum = format!("{computed:016x}");
    if sum != stored {
        return Err(PrtError::file(
            path,
            format!("checksum mismatch (stored {stored}, computed {sum}): the file is corrupted"),
        ));
    }
    Ok(())
}

/// The light columns of `columns` lights over a `w` x `h` image from their tables as read
/// (their shapes checked by `expect`); none without tables.
fn light_columns(
    tables: Option<(Tensor<f32>, Tensor<u16>)>,
    (columns, w, h): (usize, usize, usize),
    expect: ShapeCheck,
) -> Result<LightColumns> {
    let Some(((ss, scale), (vs, values))) = tables else {
        return Ok(LightColumns::empty(w, h));
    };
    expect("light_scale", &ss, &[columns, h])?;
    expect("light_value", &vs, &[columns, 3, h, w])?;
    Ok(LightColumns {
        width: w,
        height: h,
        scale,
        values,
    })
}

/// `mesh` with the visibility tables read (their shapes checked by `expect`), if any: an
/// error for tables without a per-vertex mesh.
fn with_visibility(
    mesh: Option<VertexMesh>,
    tables: Option<VisibilityTensors>,
    n: usize,
    expect: ShapeCheck,
) -> Result<Option<VertexMesh>> {
    let Some(((bs, bits), (ls, lobes), (vs, vertices))) = tables else {
        return Ok(mesh);
    };
    let mut mesh = mesh.ok_or_else(|| {
        PrtError::invalid("visibility", "stored for a bake that is not per vertex")
    })?;
    let g = vs.first().copied().unwrap_or(0);
    expect("visibility_vertex", &vs, &[g])?;
    expect("visibility_bits", &bs, &[g, Visibility::words(n)])?;
    let m = ls.first().copied().unwrap_or(0);
    expect("visibility_lobe", &ls, &[m, 4])?;
    mesh.visibility = Some(Box::new(Visibility::new(
        n,
        mesh.vertex_count(),
        vertices,
        bits,
        lobes,
    )?));
    Ok(Some(mesh))
}

/// Checks a tensor's shape against what it must be: (name, shape, expected).
type ShapeCheck<'a> = &'a dyn Fn(&str, &[usize], &[usize]) -> Result<()>;

/// The tensors of a per-vertex bake's mesh as read, before their shapes are checked.
struct MeshTables {
    /// The vertices' materials, normals and positions, and the triangles.
    tables: MeshTensors,
    /// The vertices' texture coordinates, with albedo maps.
    uv: Option<Tensor<glam::Vec2>>,
    /// The albedo maps' table, their materials and their texels.
    maps: Option<MapTensors>,
}

impl MeshTables {
    /// The mesh of `pv`'s vertices and triangles (with `map_count` albedo maps), every tensor's
    /// shape checked by `expect` and the albedo maps' tables by their reader (errors by `bad`).
    fn into_mesh(
        self,
        pv: &PerVertexMeta,
        map_count: usize,
        expect: ShapeCheck,
        bad: &dyn Fn(String) -> PrtError,
    ) -> Result<VertexMesh> {
        let ((ms, materials), (ns, normals), (ps, positions), (ts, triangles)) = self.tables;
        let (v, t) = (pv.vertices as usize, pv.triangles as usize);
        expect("mesh_position", &ps, &[v, 3])?;
        expect("mesh_normal", &ns, &[v, 3])?;
        expect("mesh_material", &ms, &[v])?;
        expect("mesh_triangle", &ts, &[t, 3])?;
        let (uvs, albedo_maps) = match (self.uv, self.maps) {
            (Some((us, uvs)), Some(((ms, table), (os, owners), (xs, texels)))) => {
                expect("mesh_uv", &us, &[v, 2])?;
                expect("albedo_map", &ms, &[map_count, 5])?;
                let n = os.first().copied().unwrap_or(0);
                expect("albedo_map_material", &os, &[n, 2])?;
                let n = xs.first().copied().unwrap_or(0);
                expect("albedo_texel", &xs, &[n, 3])?;
                (uvs, from_table(&table, &owners, texels).map_err(bad)?)
            }
            _ => (vec![glam::Vec2::ZERO; v], Vec::new()),
        };
        Ok(VertexMesh {
            positions,
            normals,
            materials,
            uvs,
            triangles,
            albedo_maps,
            visibility: None,
        })
    }
}
