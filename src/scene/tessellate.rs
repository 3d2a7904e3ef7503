//! The scene as an indexed vertex mesh, for per-vertex transport: every quad and mesh welded into
//! shared vertices (a corner keeps one vertex per distinct shading normal, so creases stay
//! sharp, and one per texture coordinate on a texture's seams), every sphere made an icosphere, and every edge longer than a target length split at
//! its midpoint until none is, so that shadows have vertices to land on. Open shapes (with a
//! boundary edge, such as a quad) get a twin of every vertex and triangle facing the other way,
//! since surfaces are two-sided (CONVENTIONS.md) and the two sides see different light. Vertices
//! are sorted in Morton order of their positions, so a block of consecutive vertices is a compact
//! patch whose transport rows share coefficients.
//!
//! A textured material's vertices carry their texture coordinates (midpoints take the mean of
//! their edge's ends), and the mesh carries each such material's [`AlbedoMap`]: the bake stores
//! those vertices' irradiance, and the raster multiplies it by the map per pixel.
//!
//! [`VertexMesh::tessellate_refined`] (`scene::refine`) spends the same number of vertices
//! unevenly, more of them where shadows fall.

use std::collections::HashMap;

use glam::{Vec2, Vec3};

use super::albedo_map::AlbedoMap;
use super::visibility::Visibility;
use super::{Scene, Triangle};
use crate::error::{PrtError, Result};

/// Cells along each side of the octahedral map of normal directions that orders a mesh's
/// vertices before their positions do ([`VertexMesh::tessellate`]).
const NORMAL_CELLS: u64 = 4;

/// Most vertices a tessellation may make; a finer one is surely a typo in the edge length.
pub const MAX_VERTICES: usize = 1 << 24;

/// Most vertices the default edge length makes ([`VertexMesh::default_edge_length`]), where the
/// scene allows: about 0.3 GB of transport at N = 32.
pub const DEFAULT_MAX_VERTICES: usize = 150_000;

/// Rounds of edge splitting at most: each halves the longest edges, so 40 rounds refine any
/// edge the coordinate limit allows to below a millionth of it.
const MAX_ROUNDS: usize = 40;

/// An indexed triangle mesh with a shading normal, a material and a texture coordinate per
/// vertex, and the albedo maps of its textured materials.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexMesh {
    /// World-space positions.
    pub positions: Vec<Vec3>,
    /// Unit shading normals: the side of the surface each vertex's light is baked for.
    pub normals: Vec<Vec3>,
    /// Index into [`Scene::materials`] of each vertex.
    pub materials: Vec<u32>,
    /// Texture coordinate of each vertex: zero unless its material has an albedo map.
    pub uvs: Vec<Vec2>,
    /// Corner indices, counter-clockwise seen from the side the normals face.
    pub triangles: Vec<[u32; 3]>,
    /// The albedo map of every textured material the vertices use, by material index: those
    /// vertices' light is baked for a white surface, and the raster multiplies it by the map.
    pub albedo_maps: Vec<AlbedoMap>,
    /// Which cube texels each glossy vertex sees, when its glossy light is drawn per pixel from
    /// the light itself ([`Visibility`]); the bake makes it once the vertex order is final.
    pub visibility: Option<Box<Visibility>>,
}

impl VertexMesh {
    /// The edge length of a per-vertex bake when none is given: the scene's `edge_length`, else
    /// 1/160 of the diagonal of its bounds (about 100,000 vertices for the demo scene), made
    /// longer where that would split the scene into more than [`DEFAULT_MAX_VERTICES`]: a model
    /// of many small parts on its own (no ground around it) has a short diagonal for its area.
    pub fn default_edge_length(scene: &Scene) -> f32 {
        if let Some(e) = scene.edge_length {
            return e;
        }
        let (lo, hi) = scene.bounds();
        let mut edge = ((hi - lo).length() / 160.0).max(1e-6);
        // The count falls about as the square of the length grows; a few rounds settle it.
        for _ in 0..4 {
            match VertexMesh::tessellate(scene, edge) {
                Ok(m) if m.vertex_count() > DEFAULT_MAX_VERTICES => {
                    let over = m.vertex_count() as f32 / (0.8 * DEFAULT_MAX_VERTICES as f32);
                    edge *= over.sqrt();
                }
                _ => break,
            }
        }
        edge
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Welds, refines and orders the surfaces of `scene` so that no edge is longer than
    /// `edge_length` (scene units).
    pub fn tessellate(scene: &Scene, edge_length: f32) -> Result<VertexMesh> {
        check_edge_length(scene, edge_length)?;
        let maps = albedo_maps(scene);
        let textured: Vec<bool> = maps.iter().map(Option::is_some).collect();
        let pieces = pieces(scene, edge_length, &textured)?;
        assemble(pieces, maps)
    }

    /// The index into [`VertexMesh::albedo_maps`] of each material's map (by material index, up
    /// to the last material that has one), `None` for a material without.
    pub fn map_slots(&self) -> Vec<Option<u32>> {
        let materials = self
            .albedo_maps
            .iter()
            .flat_map(|a| &a.materials)
            .max()
            .map_or(0, |&m| m as usize + 1);
        let mut slots = vec![None; materials];
        for (i, map) in self.albedo_maps.iter().enumerate() {
            for &m in &map.materials {
                slots[m as usize] = Some(i as u32);
            }
        }
        slots
    }

    /// Whether vertex `v`'s light is baked for a white surface, its albedo left to the raster.
    pub fn is_textured(&self, v: usize) -> bool {
        let m = self.materials[v];
        self.albedo_maps.iter().any(|a| a.materials.contains(&m))
    }

    /// Checks the mesh's own consistency (lengths, indices, finite unit normals, materials below
    /// `materials`), as a loader must before using it: the first problem, in words.
    pub fn problem(&self, materials: usize) -> Option<String> {
        let v = self.positions.len();
        if self.normals.len() != v || self.materials.len() != v || self.uvs.len() != v {
            return Some(format!(
                "{v} positions but {} normals, {} materials and {} texture coordinates",
                self.normals.len(),
                self.materials.len(),
                self.uvs.len()
            ));
        }
        if let Some(i) = self.uvs.iter().position(|t| !t.is_finite()) {
            return Some(format!("vertex {i} has texture coordinate {}", self.uvs[i]));
        }
        let mut seen = std::collections::HashSet::new();
        if let Some(m) = self
            .albedo_maps
            .iter()
            .flat_map(|a| &a.materials)
            .find(|&&m| m as usize >= materials || !seen.insert(m))
        {
            return Some(format!(
                "an albedo map of material {m} (of {materials}), or two of one material"
            ));
        }
        if self.albedo_maps.iter().any(|a| a.materials.is_empty()) {
            return Some("an albedo map of no material".into());
        }
        if let Some(t) = self
            .triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= v))
        {
            return Some(format!("triangle {t:?} indexes past the {v} vertices"));
        }
        if let Some(m) = self.materials.iter().find(|&&m| m as usize >= materials) {
            return Some(format!("material {m} of {materials}"));
        }
        if let Some(i) = (0..v).find(|&i| {
            !self.positions[i].is_finite()
                || !self.normals[i].is_finite()
                || (self.normals[i].length() - 1.0).abs() > 1e-3
        }) {
            return Some(format!(
                "vertex {i} is at {} with normal {}",
                self.positions[i], self.normals[i]
            ));
        }
        None
    }

    /// Adds a vertex and returns its index.
    fn push(&mut self, position: Vec3, normal: Vec3, material: u32, uv: Vec2) -> u32 {
        self.positions.push(position);
        self.normals.push(normal);
        self.materials.push(material);
        self.uvs.push(uv);
        (self.positions.len() - 1) as u32
    }

    /// The triangles of one shape as corner indices into shared vertices: corners with the same
    /// position and normal, and for a textured material (`textured[material]`) the same texture
    /// coordinate, become one vertex.
    fn weld(&mut self, tris: &[Triangle], textured: &[bool]) -> Vec<[u32; 3]> {
        // Position, normal and texture coordinate bits.
        type Corner = ([u32; 3], [u32; 3], [u32; 2]);
        let mut seen: HashMap<Corner, u32> = HashMap::new();
        tris.iter()
            .map(|t| {
                let mapped = textured.get(t.material as usize).copied().unwrap_or(false);
                std::array::from_fn(|k| {
                    let uv = if mapped { t.uvs[k] } else { Vec2::ZERO };
                    let key = (
                        bits(t.vertices[k]),
                        bits(t.normals[k]),
                        (uv + Vec2::ZERO).to_array().map(f32::to_bits),
                    );
                    *seen
                        .entry(key)
                        .or_insert_with(|| self.push(t.vertices[k], t.normals[k], t.material, uv))
                })
            })
            .collect()
    }

    /// The 12 vertices and 20 faces of an icosahedron inscribed in a sphere.
    fn icosahedron(&mut self, center: Vec3, radius: f32, material: u32) -> Vec<[u32; 3]> {
        let first = self.positions.len() as u32;
        for d in icosahedron_directions() {
            self.push(center + radius * d, d, material, Vec2::ZERO);
        }
        ICOSAHEDRON_FACES
            .iter()
            .map(|f| f.map(|i| first + i))
            .collect()
    }

    /// Appends a shape's vertices and triangles (indices into its own vertices), and for an
    /// open shape a twin of each of its vertices with the normal reversed and of each triangle
    /// wound the other way.
    fn add_shape(&mut self, shape: VertexMesh, open: bool) {
        let first = self.positions.len() as u32;
        let count = shape.vertex_count() as u32;
        self.positions.extend(&shape.positions);
        self.normals.extend(&shape.normals);
        self.materials.extend(&shape.materials);
        self.uvs.extend(&shape.uvs);
        let front = shape.triangles.iter().map(|t| t.map(|i| first + i));
        self.triangles.extend(front);
        if open {
            for i in 0..count as usize {
                self.push(
                    shape.positions[i],
                    -shape.normals[i],
                    shape.materials[i],
                    shape.uvs[i],
                );
            }
            let back = first + count;
            let back = shape
                .triangles
                .iter()
                .map(|&[a, b, c]| [a + back, c + back, b + back]);
            self.triangles.extend(back);
        }
    }

    /// The same mesh with its vertices sorted by the direction their normals face (one of
    /// [`NORMAL_CELLS`]² cells of the octahedral map), then by the Morton code of their positions
    /// (ties by their previous order). Vertices next to one another then see nearly the same
    /// light, so their transport rows share coefficients and fill the 8-row strips they are
    /// stored in ([`crate::store::transport::strips`]): the two sides of an open surface, at the
    /// same points, would otherwise alternate, and the strips of the demo's per-vertex bake were
    /// half empty.
    fn morton_ordered(self) -> VertexMesh {
        let lo = self.positions.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
        let hi = self
            .positions
            .iter()
            .fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
        let scale = ((1u32 << 21) - 1) as f32 / (hi - lo).max_element().max(f32::MIN_POSITIVE);
        let code = |p: Vec3| {
            let q = ((p - lo) * scale).to_array().map(|v| v as u64);
            (0..21).fold(0u64, |c, b| {
                c | ((q[0] >> b & 1) << (3 * b))
                    | ((q[1] >> b & 1) << (3 * b + 1))
                    | ((q[2] >> b & 1) << (3 * b + 2))
            })
        };
        // The octahedral map of the unit sphere onto [-1, 1]², cut into cells.
        let cell = |n: Vec3| {
            let n = n / n.abs().element_sum().max(f32::MIN_POSITIVE);
            let (x, y) = if n.z >= 0.0 {
                (n.x, n.y)
            } else {
                (
                    (1.0 - n.y.abs()) * n.x.signum(),
                    (1.0 - n.x.abs()) * n.y.signum(),
                )
            };
            let at =
                |v: f32| (((v + 1.0) * 0.5 * NORMAL_CELLS as f32) as u64).min(NORMAL_CELLS - 1);
            at(x) * NORMAL_CELLS + at(y)
        };
        let mut order: Vec<u32> = (0..self.positions.len() as u32).collect();
        order.sort_by_key(|&i| {
            let i = i as usize;
            (cell(self.normals[i]), code(self.positions[i]))
        });
        let mut new_index = vec![0u32; order.len()];
        for (new, &old) in order.iter().enumerate() {
            new_index[old as usize] = new as u32;
        }
        let pick = |v: &[Vec3]| order.iter().map(|&i| v[i as usize]).collect();
        VertexMesh {
            positions: pick(&self.positions),
            normals: pick(&self.normals),
            materials: order.iter().map(|&i| self.materials[i as usize]).collect(),
            uvs: order.iter().map(|&i| self.uvs[i as usize]).collect(),
            triangles: self
                .triangles
                .iter()
                .map(|t| t.map(|i| new_index[i as usize]))
                .collect(),
            albedo_maps: self.albedo_maps,
            // Rows of the old order; none yet while the mesh is being made.
            visibility: None,
        }
    }
}

/// One shape of the scene tessellated on its own, before the twin of an open one: its vertices
/// and triangles (indices into its own vertices), whether it is open, and the sphere it lies on.
pub(super) struct Piece {
    pub(super) mesh: VertexMesh,
    pub(super) open: bool,
    pub(super) sphere: Option<(Vec3, f32)>,
}

impl Piece {
    /// Vertices the piece takes in the whole mesh: its own, and as many twins if it is open.
    pub(super) fn vertices(&self) -> usize {
        self.mesh.vertex_count() * (1 + self.open as usize)
    }
}

/// Refuses an edge length that is not a positive length, or that would split `scene` into far
/// more than [`MAX_VERTICES`] vertices, before any work.
pub(super) fn check_edge_length(scene: &Scene, edge_length: f32) -> Result<()> {
    if !(edge_length.is_finite() && edge_length > 0.0) {
        return Err(PrtError::invalid(
            "edge length",
            format!("{edge_length}; it must be a finite length > 0"),
        ));
    }
    // About how many vertices the length asks for (a triangle's edges end between half the
    // length and the length).
    let area: f64 = scene
        .triangles
        .iter()
        .map(|t| t.area() as f64)
        .chain(
            scene
                .spheres
                .iter()
                .map(|s| 4.0 * std::f64::consts::PI * (s.radius as f64).powi(2)),
        )
        .sum();
    let estimate = area / (0.433 * (edge_length as f64 / 2.0).powi(2)) / 2.0;
    if estimate > 4.0 * MAX_VERTICES as f64 {
        return Err(PrtError::invalid(
            "edge length",
            format!(
                "{edge_length} is too fine for surfaces of area {area:.3e}: about {estimate:.1e} \
                 vertices, past the limit of {MAX_VERTICES}"
            ),
        ));
    }
    Ok(())
}

/// The albedo map of every material of `scene` (`None` for an untextured one).
pub(super) fn albedo_maps(scene: &Scene) -> Vec<Option<AlbedoMap>> {
    (0..scene.materials.len() as u32)
        .map(|m| AlbedoMap::of_material(scene, m))
        .collect()
}

/// Every quad, mesh and sphere of `scene` welded and split until no edge is longer than
/// `edge_length`, one [`Piece`] each in the scene's order; the vertices of textured materials
/// (`textured[material]`) keep their texture coordinates.
pub(super) fn pieces(scene: &Scene, edge_length: f32, textured: &[bool]) -> Result<Vec<Piece>> {
    let mut pieces = Vec::new();
    // Vertices of the pieces so far, twins included.
    let mut before = 0;
    for range in &scene.surfaces {
        let tris = &scene.triangles[range.clone()];
        let open = has_boundary(tris);
        // A closed mesh whose normals point inside would be baked for its dark inner side.
        let turned: Vec<Triangle>;
        let tris = if !open && normals_point_inside(tris) {
            turned = tris.iter().map(Triangle::turned).collect();
            &turned[..]
        } else {
            tris
        };
        let mut mesh = VertexMesh::default();
        let corners = mesh.weld(tris, textured);
        let tris = Refiner::new(&mut mesh, edge_length, None, before).run(corners)?;
        mesh.triangles = tris;
        let piece = Piece {
            mesh,
            open,
            sphere: None,
        };
        before += piece.vertices();
        pieces.push(piece);
    }
    for s in &scene.spheres {
        let mut mesh = VertexMesh::default();
        let corners = mesh.icosahedron(s.center, s.radius, s.material);
        let sphere = Some((s.center, s.radius));
        let tris = Refiner::new(&mut mesh, edge_length, sphere, before).run(corners)?;
        mesh.triangles = tris;
        let piece = Piece {
            mesh,
            open: false,
            sphere,
        };
        before += piece.vertices();
        pieces.push(piece);
    }
    Ok(pieces)
}

/// The pieces in one mesh, each open one followed by its twin, with the albedo maps of the
/// materials its vertices use, in Morton order.
pub(super) fn assemble(pieces: Vec<Piece>, maps: Vec<Option<AlbedoMap>>) -> Result<VertexMesh> {
    let mut mesh = VertexMesh::default();
    for piece in pieces {
        mesh.add_shape(piece.mesh, piece.open);
    }
    if mesh.positions.is_empty() {
        return Err(PrtError::invalid(
            "per-vertex bake",
            "the scene has no surfaces to put vertices on",
        ));
    }
    let mut used = vec![false; maps.len()];
    for &m in &mesh.materials {
        used[m as usize] = true;
    }
    // One map for materials whose maps are the same (such as two that share a texture).
    for map in maps
        .into_iter()
        .enumerate()
        .filter(|(m, _)| used[*m])
        .filter_map(|(_, map)| map)
    {
        match mesh.albedo_maps.iter_mut().find(|a| a.same_image(&map)) {
            Some(same) => same.materials.extend(map.materials),
            None => mesh.albedo_maps.push(map),
        }
    }
    Ok(mesh.morton_ordered())
}

/// The closed surfaces of `scene` whose shading normals point into the volume they enclose (faces
/// wound inward, as exporters sometimes write them), by name: a per-vertex bake turns them
/// outward, since it bakes the side the normals face and the inner side of a closed mesh sees
/// nothing. A per-pixel bake needs no turn: it shades the side the camera ray arrives on.
pub fn inward_surfaces(scene: &Scene) -> Vec<&str> {
    scene
        .surfaces
        .iter()
        .zip(&scene.surface_names)
        .filter(|(range, _)| {
            let tris = &scene.triangles[(*range).clone()];
            !has_boundary(tris) && normals_point_inside(tris)
        })
        .map(|(_, name)| name.as_str())
        .collect()
}

/// Whether the shading normals of a closed surface point inside it: by the divergence theorem
/// the flux of the position through a closed surface, ∮ (x − o) · n dA, is 3 times its volume,
/// positive with outward normals and negative with inward ones, whatever o.
fn normals_point_inside(tris: &[Triangle]) -> bool {
    let Some(o) = tris.first().map(|t| t.vertices[0].as_dvec3()) else {
        return false;
    };
    let flux: f64 = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.vertices.map(|v| v.as_dvec3());
            let area = 0.5 * (b - a).cross(c - a).length();
            let n = (t.normals[0] + t.normals[1] + t.normals[2]).as_dvec3();
            let centroid = (a + b + c) / 3.0;
            area * n.normalize_or_zero().dot(centroid - o)
        })
        .sum();
    flux < 0.0
}

/// A vector's bit pattern, with −0 as +0, as a hash key.
pub(super) fn bits(v: Vec3) -> [u32; 3] {
    (v + Vec3::ZERO).to_array().map(f32::to_bits)
}

/// Whether some edge of `tris` (by corner positions) belongs to only one triangle.
fn has_boundary(tris: &[Triangle]) -> bool {
    let mut edges: HashMap<([u32; 3], [u32; 3]), u32> = HashMap::new();
    for t in tris {
        for k in 0..3 {
            let (a, b) = (bits(t.vertices[k]), bits(t.vertices[(k + 1) % 3]));
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    edges.values().any(|&n| n == 1)
}

/// Splits every edge longer than the target at its midpoint, once per edge (shared by the
/// triangles on both sides, so the mesh stays watertight), until no edge is longer.
pub(super) struct Refiner<'a> {
    mesh: &'a mut VertexMesh,
    edge: f32,
    /// A sphere's centre and radius: midpoints go onto it, with its exact normal.
    sphere: Option<(Vec3, f32)>,
    midpoints: HashMap<(u32, u32), u32>,
    /// Vertices of the whole tessellation before this mesh's, for its limit.
    before: usize,
}

impl<'a> Refiner<'a> {
    pub(super) fn new(
        mesh: &'a mut VertexMesh,
        edge: f32,
        sphere: Option<(Vec3, f32)>,
        before: usize,
    ) -> Self {
        Refiner {
            mesh,
            edge,
            sphere,
            midpoints: HashMap::new(),
            before,
        }
    }

    /// The midpoint vertex of edge (a, b) if the edge is too long.
    fn split(&mut self, a: u32, b: u32) -> Option<u32> {
        let m = &self.mesh;
        let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
        (pa.distance(pb) > self.edge).then(|| self.midpoint(a, b))
    }

    /// The midpoint vertex of edge (a, b), made once: on the sphere, or halfway with the ends'
    /// mean normal and texture coordinate; the material of its lower-indexed end.
    pub(super) fn midpoint(&mut self, a: u32, b: u32) -> u32 {
        let (a, b) = (a.min(b), a.max(b));
        if let Some(&i) = self.midpoints.get(&(a, b)) {
            return i;
        }
        let m = &self.mesh;
        let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
        let mid = (pa + pb) * 0.5;
        let (na, nb) = (m.normals[a as usize], m.normals[b as usize]);
        let (p, n) = match self.sphere {
            Some((c, r)) => {
                let n = (mid - c).normalize_or(na);
                (c + r * n, n)
            }
            None => (mid, (na + nb).normalize_or(na)),
        };
        let material = m.materials[a as usize];
        let uv = (m.uvs[a as usize] + m.uvs[b as usize]) * 0.5;
        let i = self.mesh.push(p, n, material, uv);
        self.midpoints.insert((a, b), i);
        i
    }

    fn run(&mut self, mut tris: Vec<[u32; 3]>) -> Result<Vec<[u32; 3]>> {
        for _ in 0..MAX_ROUNDS {
            let mut next = Vec::with_capacity(tris.len() * 2);
            let mut changed = false;
            for t in tris {
                let mids = [0, 1, 2].map(|k| self.split(t[k], t[(k + 1) % 3]));
                changed |= mids.iter().any(Option::is_some);
                subdivide(t, mids, None, &mut next);
            }
            tris = next;
            if self.before + self.mesh.positions.len() > MAX_VERTICES {
                return Err(PrtError::invalid(
                    "edge length",
                    format!(
                        "{} is too fine: the tessellation passes {MAX_VERTICES} vertices",
                        self.edge
                    ),
                ));
            }
            if !changed {
                return Ok(tris);
            }
        }
        Ok(tris)
    }
}

/// Appends to `next` the triangles that replace `t` once the edges with a midpoint in `mids`
/// are split (edge k runs from corner k to k + 1): two for one edge, four alike for three. For
/// two, the new edges meet at the midpoint of edge `first` where it is one of them (it is split
/// from the opposite corner first), else at the second's in winding order.
pub(super) fn subdivide(
    t: [u32; 3],
    mids: [Option<u32>; 3],
    first: Option<usize>,
    next: &mut Vec<[u32; 3]>,
) {
    let split = mids.iter().filter(|m| m.is_some()).count();
    // Turned so that the split edges come first.
    let turn = match split {
        1 => mids.iter().position(Option::is_some).unwrap_or(0),
        2 => mids
            .iter()
            .position(Option::is_none)
            .map_or(0, |k| (k + 1) % 3),
        _ => 0,
    };
    let [a, b, c] = [0, 1, 2].map(|k| t[(k + turn) % 3]);
    let [mab, mbc, mca] = [0, 1, 2].map(|k| mids[(k + turn) % 3].unwrap_or(u32::MAX));
    match split {
        0 => next.push(t),
        1 => next.extend([[a, mab, c], [mab, b, c]]),
        2 if first == Some(turn) => next.extend([[a, mab, c], [mab, b, mbc], [mab, mbc, c]]),
        2 => next.extend([[mab, b, mbc], [a, mab, mbc], [a, mbc, c]]),
        _ => next.extend([[a, mab, mca], [mab, b, mbc], [mca, mbc, c], [mab, mbc, mca]]),
    }
}

/// The unit vertex directions of an icosahedron: (±1, ±g, 0) and its cyclic turns, g the golden
/// ratio, normalised.
pub(crate) fn icosahedron_directions() -> [Vec3; 12] {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    [
        [-1.0, g, 0.0],
        [1.0, g, 0.0],
        [-1.0, -g, 0.0],
        [1.0, -g, 0.0],
        [0.0, -1.0, g],
        [0.0, 1.0, g],
        [0.0, -1.0, -g],
        [0.0, 1.0, -g],
        [g, 0.0, -1.0],
        [g, 0.0, 1.0],
        [-g, 0.0, -1.0],
        [-g, 0.0, 1.0],
    ]
    .map(|d| Vec3::from(d).normalize())
}

/// The icosahedron's faces over [`icosahedron_directions`], wound outward (counter-clockwise seen
/// from outside).
pub(crate) const ICOSAHEDRON_FACES: [[u32; 3]; 20] = [
    [0, 11, 5],
    [0, 5, 1],
    [0, 1, 7],
    [0, 7, 10],
    [0, 10, 11],
    [1, 5, 9],
    [5, 11, 4],
    [11, 10, 2],
    [10, 7, 6],
    [7, 1, 8],
    [3, 9, 4],
    [3, 4, 2],
    [3, 2, 6],
    [3, 6, 8],
    [3, 8, 9],
    [4, 9, 5],
    [2, 4, 11],
    [6, 2, 10],
    [8, 6, 7],
    [9, 8, 1],
];

#[cfg(test)]
mod tests {
    use super::*;

    /// Sums over the tessellated 2 x 2 quad in f32 against their exact totals (vector areas of
    /// ±4 Y, a boundary 16 long): a few hundred pieces whose running sums reach 4 and 16, so
    /// rounding of order 1e-5 at worst.
    const QUAD_TILING_SUM: f32 = 1e-4;
    /// A sphere vertex's distance from the centre against the radius 0.5: positions are the centre
    /// plus the radius times a unit direction in f32, a few ulps of coordinates up to 1.5.
    const ON_THE_SPHERE: f32 = 1e-5;
    /// A sphere vertex's normal against (p − c) / r recomputed from its f32 position: subtracting
    /// the centre exposes the position's rounding, a few ulps of 1.5 over 0.5, ~1e-6.
    const EXACT_NORMAL: f32 = 1e-4;
    /// The vector areas of the closed icosphere's triangles, summed in f32: they cancel exactly
    /// on a closed surface, so only the rounding of thousands of cross products and their sum
    /// remains.
    const CLOSED_VECTOR_AREA: f32 = 1e-3;

    fn scene(shapes: &str) -> Scene {
        let text = crate::test_support::grey_scene_text([0.0, 2.0, 5.0], 40.0, 8, shapes);
        Scene::from_toml_str(&text, std::path::Path::new("t.toml")).unwrap()
    }

    const QUAD: &str = "[[shape]]\ntype = \"quad\"\ncorners = [[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], \
                        [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]]\nmaterial = \"m\"\n";
    const SPHERE: &str =
        "[[shape]]\ntype = \"sphere\"\ncenter = [0.0, 1.0, 0.0]\nradius = 0.5\nmaterial = \"m\"\n";

    fn edges(m: &VertexMesh) -> impl Iterator<Item = (u32, u32)> + '_ {
        m.triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
    }

    fn area(m: &VertexMesh, t: &[u32; 3]) -> Vec3 {
        let p = t.map(|i| m.positions[i as usize]);
        0.5 * (p[1] - p[0]).cross(p[2] - p[0])
    }

    #[test]
    fn a_quad_is_split_below_the_edge_length_on_both_sides_without_losing_area() {
        let m = VertexMesh::tessellate(&scene(QUAD), 0.3).unwrap();
        assert!(m.problem(1).is_none());
        assert!(
            edges(&m)
                .all(|(a, b)| { m.positions[a as usize].distance(m.positions[b as usize]) <= 0.3 })
        );
        // Both sides tile the 2 x 2 quad: up-facing triangles sum to +4 Y, down-facing to −4 Y,
        // each wound to face its vertices' normals.
        let (mut up, mut down) = (Vec3::ZERO, Vec3::ZERO);
        for t in &m.triangles {
            let a = area(&m, t);
            let n = m.normals[t[0] as usize];
            assert!(a.dot(n) > 0.0, "a triangle wound against its normals");
            assert!(t.iter().all(|&i| m.normals[i as usize] == n));
            if n.y > 0.0 { up += a } else { down += a }
        }
        assert!(
            (up - Vec3::new(0.0, 4.0, 0.0)).length() < QUAD_TILING_SUM,
            "{up}"
        );
        assert!(
            (down + Vec3::new(0.0, 4.0, 0.0)).length() < QUAD_TILING_SUM,
            "{down}"
        );
        // Watertight: every interior edge of one side is shared by exactly two triangles.
        let mut count: HashMap<(u32, u32), u32> = HashMap::new();
        for (a, b) in edges(&m) {
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
        let boundary: f32 = count
            .iter()
            .filter(|(_, n)| **n == 1)
            .map(|((a, b), _)| m.positions[*a as usize].distance(m.positions[*b as usize]))
            .sum();
        assert!(
            (boundary - 16.0).abs() < QUAD_TILING_SUM,
            "boundary length {boundary} (2 sides x 8)"
        );
        assert!(count.values().all(|&n| n <= 2));
    }

    #[test]
    fn a_sphere_becomes_a_closed_icosphere_on_its_surface_with_exact_normals() {
        let s = scene(SPHERE);
        let m = VertexMesh::tessellate(&s, 0.1).unwrap();
        let c = Vec3::new(0.0, 1.0, 0.0);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!(((*p - c).length() - 0.5).abs() < ON_THE_SPHERE);
            assert!((*n - (*p - c) / 0.5).length() < EXACT_NORMAL);
        }
        // Closed and outward: no twin, the triangles' vector areas sum to zero, and their volume
        // is close to the sphere's.
        let total: Vec3 = m.triangles.iter().map(|t| area(&m, t)).sum();
        assert!(total.length() < CLOSED_VECTOR_AREA, "{total}");
        let volume: f32 = m
            .triangles
            .iter()
            .map(|t| area(&m, t).dot(m.positions[t[0] as usize] - c) / 3.0)
            .sum();
        let exact = 4.0 / 3.0 * std::f32::consts::PI * 0.125;
        assert!(
            volume > 0.95 * exact && volume < exact,
            "{volume} of {exact}"
        );
        assert!(
            edges(&m)
                .all(|(a, b)| { m.positions[a as usize].distance(m.positions[b as usize]) <= 0.1 })
        );
    }

    #[test]
    fn the_default_edge_length_keeps_a_dense_scene_within_the_vertex_budget() {
        // Forty 1 x 1 quads stacked 0.01 apart: a short diagonal for their area, so 1/160 of it
        // would split them into about 700,000 vertices.
        let quads: String = (0..40)
            .map(|k| {
                let y = k as f32 * 0.01;
                format!(
                    "[[shape]]\ntype = \"quad\"\ncorners = [[0.0, {y}, 0.0], [0.0, {y}, 1.0], \
                     [1.0, {y}, 1.0], [1.0, {y}, 0.0]]\nmaterial = \"m\"\n"
                )
            })
            .collect();
        let s = scene(&quads);
        let (lo, hi) = s.bounds();
        let plain = (hi - lo).length() / 160.0;
        let edge = VertexMesh::default_edge_length(&s);
        assert!(edge > plain, "{edge} against {plain}");
        let n = VertexMesh::tessellate(&s, edge).unwrap().vertex_count();
        assert!(
            (DEFAULT_MAX_VERTICES / 3..=DEFAULT_MAX_VERTICES).contains(&n),
            "{n} vertices at {edge}"
        );
        // A scene within the budget keeps 1/160 of its diagonal.
        let one = scene(QUAD);
        let (lo, hi) = one.bounds();
        assert_eq!(
            VertexMesh::default_edge_length(&one),
            (hi - lo).length() / 160.0
        );
    }

    #[test]
    fn vertices_come_in_morton_order_and_a_finer_length_makes_more() {
        let s = scene(&format!("{QUAD}{SPHERE}"));
        let coarse = VertexMesh::tessellate(&s, 0.5).unwrap();
        let fine = VertexMesh::tessellate(&s, 0.1).unwrap();
        assert!(fine.vertex_count() > 8 * coarse.vertex_count());
        // Morton order keeps neighbours near: consecutive vertices are on average far closer
        // than two far apart in the order (half the vertices apart).
        let n = fine.vertex_count();
        let p = &fine.positions;
        let step: f32 = p.windows(2).map(|w| w[0].distance(w[1])).sum::<f32>() / (n - 1) as f32;
        let far: f32 = (0..n)
            .map(|i| p[i].distance(p[(i + n / 2) % n]))
            .sum::<f32>()
            / n as f32;
        assert!(step < 0.15 * far, "mean step {step}, far apart {far}");
        // The quad is open, so both its sides are baked, at the same points: vertices facing
        // one way come together, so consecutive vertices face apart only where the order passes
        // from one cell of normal directions to the next.
        let apart = fine
            .normals
            .windows(2)
            .filter(|w| w[0].dot(w[1]) < 0.0)
            .count();
        assert!(apart < 16, "{apart} turns between consecutive vertices");
        let e = VertexMesh::tessellate(&s, 0.0).unwrap_err().to_string();
        assert!(
            e.contains("edge length") && e.contains("finite length > 0"),
            "{e}"
        );
        assert!(
            VertexMesh::tessellate(&s, 1e-6).is_err(),
            "too many vertices"
        );
    }
}
