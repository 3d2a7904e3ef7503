//! A mesh resident on the GPU for the raster (`shaders/raster.wgsl`): per vertex its position,
//! texture coordinate and albedo-map slot, per triangle its three vertices, the albedo maps'
//! tables, and the storage buffer of per-vertex colours the raster reads.

use wgpu::util::DeviceExt;

use crate::draw::lobe::{lobe_samples, lobe_taps};
use crate::draw::raster::check_mesh;
use crate::draw::shading::{GlossMesh, Texturing};
use crate::error::{PrtError, Result};
use crate::gpu::GpuDevice as Gpu;
use crate::scene::albedo_map::wrap_code;
use crate::scene::tessellate::VertexMesh;
use crate::scene::texture::Filter;
use crate::scene::visibility::{NO_ROW, Visibility};
use glam::Vec3;

/// Bytes of one vertex's colour in a colour buffer (`vec4<f32>`), and of one pixel of the
/// raster's colour format.
pub(super) const TEXEL_BYTES: u32 = 16;

/// A vertex's map slot in the shader when it has no albedo map.
const NO_MAP: u32 = u32::MAX;
/// Words (`u32`) of one vertex in the shader's vertex table: position, texture coordinate, slot,
/// shading normal, material.
const VERTEX_WORDS: usize = 10;

/// Where the lobe's tables sit in the gloss buffer and their shape, as the shader's view
/// uniform takes them: `[visibility N, the most taps a material takes, materials, words a
/// row]`, then the offsets of the lobes, the bits, each material's `[first tap word, taps]` and
/// the rows' light shares (the vertices' rows start at 0, the taps follow them). All zero
/// without visibility.
pub(super) type LobeShape = [u32; 8];

/// The gloss buffer's words and their shape for `gloss`: the visibility's vertex rows, lobe
/// taps, lobes and bits.
fn gloss_tables(gloss: Option<&GlossMesh>, vertices: usize) -> (Vec<u32>, LobeShape) {
    match gloss.map(|g| g.visibility) {
        Some(vis) => {
            let mut words: Vec<u32> = (0..vertices)
                .map(|v| vis.row_index(v).unwrap_or(NO_ROW))
                .collect();
            // Each material's taps, as many as its width asks for (none for a diffuse one).
            let counts = lobe_samples(vis);
            let mut first = Vec::with_capacity(counts.len());
            for (m, &count) in counts.iter().enumerate() {
                first.push(words.len() as u32);
                if let Some((_, alpha)) = vis.lobe(m as u32) {
                    let taps = lobe_taps(alpha, count);
                    words.extend(taps.iter().flatten().map(|x| x.to_bits()));
                }
            }
            let lobes_at = words.len() as u32;
            words.extend(vis.lobes.iter().flatten().map(|x| x.to_bits()));
            let bits_at = words.len() as u32;
            words.extend(&vis.bits);
            let taps_at = words.len() as u32;
            for (f, &count) in first.iter().zip(&counts) {
                words.extend([*f, count as u32]);
            }
            let shares_at = words.len() as u32;
            words.extend(vis.light_shares.iter().map(|x| x.to_bits()));
            let shape = [
                vis.n as u32,
                counts.iter().copied().max().unwrap_or(0) as u32,
                vis.lobes.len() as u32,
                Visibility::words(vis.n) as u32,
                lobes_at,
                bits_at,
                taps_at,
                shares_at,
            ];
            (words, shape)
        }
        None => (vec![0], [0; 8]),
    }
}

/// A mesh resident on the GPU, in storage buffers as `shaders/raster.wgsl` reads them: per vertex
/// its position, texture coordinate and albedo-map slot, per triangle its three vertices, and the
/// albedo maps (the maps, their levels and their texels).
pub struct GpuMesh {
    pub(super) table: wgpu::Buffer,
    pub(super) indices: wgpu::Buffer,
    pub(super) maps: wgpu::Buffer,
    pub(super) levels: wgpu::Buffer,
    pub(super) texels: wgpu::Buffer,
    pub(super) vertices: u32,
    pub(super) index_count: u32,
    /// The visibility's tables (one word without gloss).
    pub(super) gloss: wgpu::Buffer,
    /// The lobe's tables in `gloss` where the bake keeps visibility.
    pub(super) lobe_shape: LobeShape,
    /// Light columns a glossy vertex keeps a share of (0 without).
    pub(super) light_columns: u32,
}

/// The shader's map, level and texel tables.
type MapTables = (Vec<[u32; 4]>, Vec<[u32; 4]>, Vec<[u32; 2]>);

/// The albedo maps of `texturing` as the shader's three tables: per map (first level, level
/// count, sampler flags, 0), per level (first texel, width, height, 0), and the texels packed
/// two to a `u32` pair.
fn map_tables(texturing: Option<&Texturing>) -> MapTables {
    let (mut maps, mut levels, mut texels) = (Vec::new(), Vec::new(), Vec::new());
    for map in texturing.map_or(&[][..], |t| t.maps) {
        let flags = wrap_code(map.wrap[0])
            | wrap_code(map.wrap[1]) << 2
            | ((map.filter == Filter::Nearest) as u32) << 4;
        maps.push([levels.len() as u32, map.levels.len() as u32, flags, 0]);
        for l in &map.levels {
            levels.push([texels.len() as u32, l.width, l.height, 0]);
            texels.extend(
                l.texels
                    .iter()
                    .map(|t| [t[0] as u32 | (t[1] as u32) << 16, t[2] as u32]),
            );
        }
    }
    (maps, levels, texels)
}

impl GpuMesh {
    /// Uploads a mesh, checked as [`check_mesh`] checks it (finite positions, indices in range).
    pub fn new(gpu: &Gpu, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<GpuMesh> {
        GpuMesh::textured(gpu, positions, triangles, None)
    }

    /// Uploads a mesh with its texturing, if any: each drawn pixel of a textured vertex's
    /// triangles is multiplied by its albedo map, as the CPU twin does.
    pub fn textured(
        gpu: &Gpu,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        texturing: Option<&Texturing>,
    ) -> Result<GpuMesh> {
        GpuMesh::glossy(gpu, positions, triangles, texturing, None)
    }

    /// Uploads a per-vertex bake's mesh: its texturing and its gloss.
    pub fn of_bake(gpu: &Gpu, mesh: &VertexMesh) -> Result<GpuMesh> {
        GpuMesh::glossy(
            gpu,
            &mesh.positions,
            &mesh.triangles,
            Texturing::of(mesh).as_ref(),
            GlossMesh::of(mesh),
        )
    }

    /// Uploads a mesh with its texturing and its gloss, if any: each drawn pixel of a glossy
    /// vertex's triangles adds its lobe against the light, as the CPU twin does.
    pub fn glossy(
        gpu: &Gpu,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        texturing: Option<&Texturing>,
        gloss: Option<GlossMesh>,
    ) -> Result<GpuMesh> {
        check_mesh(positions, triangles, None)?;
        if let Some(t) = texturing {
            t.check(positions.len())?;
        }
        if let Some(g) = &gloss {
            // The same check as the CPU's draws make ([`GlossMesh::check`]).
            g.check(positions.len())?;
        }
        let index_count = u32::try_from(triangles.len() * 3).map_err(|_| {
            PrtError::invalid(
                "triangles",
                format!("{} triangles: too many to draw at once", triangles.len()),
            )
        })?;
        let max = gpu.max_binding_bytes();
        let bytes = (positions.len() as u64 * VERTEX_WORDS as u64 * 4).max(index_count as u64 * 4);
        if bytes > max {
            return Err(PrtError::invalid(
                "mesh",
                format!("{bytes} bytes in one binding; the device binds at most {max}"),
            ));
        }
        let (maps, levels, texels) = map_tables(texturing);
        let texel_bytes = texels.len() as u64 * 8;
        if texel_bytes > gpu.max_binding_bytes() {
            return Err(PrtError::invalid(
                "albedo maps",
                format!(
                    "{texel_bytes} bytes of texels with their mip levels; the device binds at \
                     most {} (draw on the CPU with --device cpu)",
                    gpu.max_binding_bytes()
                ),
            ));
        }
        let (gloss_words, lobe_shape) = gloss_tables(gloss.as_ref(), positions.len());
        if gloss_words.len() as u64 * 4 > gpu.max_binding_bytes() {
            return Err(PrtError::invalid(
                "gloss",
                format!(
                    "{} words of visibility; too many for one binding",
                    gloss_words.len()
                ),
            ));
        }
        let mut table = Vec::with_capacity(positions.len() * VERTEX_WORDS);
        for (v, p) in positions.iter().enumerate() {
            let (uv, slot) = match texturing {
                Some(t) => (t.uvs[v].to_array(), t.slot(v).unwrap_or(NO_MAP)),
                None => ([0.0; 2], NO_MAP),
            };
            table.extend([p.x, p.y, p.z, uv[0], uv[1]].map(f32::to_bits));
            table.push(slot);
            let (n, m) = match &gloss {
                Some(g) => (g.normals[v], g.materials[v]),
                None => (Vec3::Z, u32::MAX),
            };
            table.extend([n.x, n.y, n.z].map(f32::to_bits));
            table.push(m);
        }
        // Storage buffers; wgpu rejects empty initialised buffers for some uses: keep at least
        // one element.
        let buffer = |label, contents: &[u8]| {
            let mut data = contents.to_vec();
            data.resize(data.len().max(16), 0);
            gpu.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: &data,
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        Ok(GpuMesh {
            table: buffer("raster vertices", bytemuck::cast_slice(&table)),
            indices: buffer("raster indices", bytemuck::cast_slice(triangles)),
            maps: buffer("raster albedo maps", bytemuck::cast_slice(&maps)),
            levels: buffer("raster albedo levels", bytemuck::cast_slice(&levels)),
            texels: buffer("raster albedo texels", bytemuck::cast_slice(&texels)),
            vertices: positions.len() as u32,
            index_count,
            gloss: buffer("raster gloss", bytemuck::cast_slice(&gloss_words)),
            lobe_shape,
            light_columns: gloss.map_or(0, |g| g.visibility.columns as u32),
        })
    }

    /// Vertices of the mesh.
    pub fn vertex_count(&self) -> usize {
        self.vertices as usize
    }

    /// Whether the mesh's gloss is visibility, whose lobe the raster draws from a light.
    pub fn has_lobe(&self) -> bool {
        self.lobe_shape[1] > 0
    }

    /// Triangles of the mesh.
    pub fn triangle_count(&self) -> usize {
        self.index_count as usize / 3
    }
}

/// Uploads per-vertex colours into a storage buffer of `vec4<f32>` (alpha 1), the layout
/// [`super::raster::GpuRaster::draw`] reads. Non-finite colours are an error.
pub fn upload_colours(gpu: &Gpu, colours: &[[f32; 3]]) -> Result<wgpu::Buffer> {
    crate::draw::raster::check_colours(colours)?;
    let (bytes, max) = (
        colours.len() as u64 * TEXEL_BYTES as u64,
        gpu.max_binding_bytes(),
    );
    if bytes > max {
        return Err(PrtError::invalid(
            "colours",
            format!("{bytes} bytes; the device binds at most {max}"),
        ));
    }
    let mut data: Vec<[f32; 4]> = colours.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect();
    if data.is_empty() {
        data.push([0.0; 4]);
    }
    Ok(crate::gpu::buffer_with(
        &gpu.device,
        "raster colours",
        bytemuck::cast_slice(&data),
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    ))
}
