//! Wavefront OBJ meshes: vertices, normals and faces read with every index checked, placed in
//! the world by a scene shape's transform.

use super::*;

/// A flat-shaded triangle, or `None` when it has no area (it could never be hit, and has no
/// normal).
pub(super) fn flat_triangle(vertices: [Vec3; 3], material: u32) -> Option<Triangle> {
    let [a, b, c] = vertices;
    let n = (b - a).cross(c - a).normalize_or_zero();
    (n != Vec3::ZERO).then_some(Triangle {
        vertices,
        normals: [n; 3],
        uvs: [Vec2::ZERO; 3],
        material,
    })
}

// ---------------------------------------------------------------------------------------------
// OBJ reading: only what shading needs (positions, normals, faces); texture coordinates,
// groups and materials are skipped.

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ObjTriangle {
    pub(super) positions: [u32; 3],
    /// Indices into `ObjData::normals`, when every corner of the face named one.
    pub(super) normals: Option<[u32; 3]>,
}

#[derive(Debug, Default)]
pub(super) struct ObjData {
    pub(super) positions: Vec<Vec3>,
    pub(super) normals: Vec<Vec3>,
    pub(super) triangles: Vec<ObjTriangle>,
}

/// Resolves a 1-based (or negative, relative to the end) OBJ index against `count` elements
/// defined so far.
fn obj_index(token: &str, count: usize, what: &str) -> std::result::Result<u32, String> {
    let i: i64 = token
        .parse()
        .map_err(|_| format!("bad {what} index `{token}`"))?;
    let resolved = match i {
        0 => return Err(format!("{what} index 0 (OBJ indices start at 1)")),
        i if i > 0 => i - 1,
        i => count as i64 + i,
    };
    if resolved < 0 || resolved >= count as i64 || resolved > i64::from(u32::MAX) {
        return Err(format!(
            "{what} index {i} out of range ({count} defined so far)"
        ));
    }
    Ok(resolved as u32)
}

fn obj_vec3<'t>(
    fields: &mut impl Iterator<Item = &'t str>,
    what: &str,
) -> std::result::Result<Vec3, String> {
    let mut v = [0.0f32; 3];
    for c in &mut v {
        let token = fields
            .next()
            .ok_or_else(|| format!("{what} needs 3 coordinates"))?;
        *c = token
            .parse()
            .map_err(|_| format!("bad {what} coordinate `{token}`"))?;
        if !c.is_finite() {
            return Err(format!("{what} coordinate `{token}` is not finite"));
        }
    }
    Ok(Vec3::from_array(v))
}

/// Parses OBJ text: `v`, `vn` and `f` (polygons fan-triangulated; `v`, `v/vt`, `v//vn` and
/// `v/vt/vn` corners; negative indices). Errors name the file and line.
pub(super) fn parse_obj(bytes: &[u8], path: &Path) -> Result<ObjData> {
    let text = String::from_utf8_lossy(bytes);
    let mut obj = ObjData::default();
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    for (line_index, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or_default();
        let mut fields = line.split_whitespace();
        let Some(tag) = fields.next() else { continue };
        let outcome = match tag {
            "v" => obj_vec3(&mut fields, "vertex").map(|p| obj.positions.push(p)),
            "vn" => obj_vec3(&mut fields, "normal").map(|n| obj.normals.push(n)),
            "f" => {
                corners.clear();
                let parsed: std::result::Result<(), String> = fields.try_for_each(|corner| {
                    let mut parts = corner.split('/');
                    let v = obj_index(
                        parts.next().unwrap_or_default(),
                        obj.positions.len(),
                        "vertex",
                    )?;
                    let _texture = parts.next();
                    let n = match parts.next() {
                        Some(t) if !t.is_empty() => {
                            Some(obj_index(t, obj.normals.len(), "normal")?)
                        }
                        _ => None,
                    };
                    corners.push((v, n));
                    Ok(())
                });
                parsed.and_then(|()| {
                    if corners.len() < 3 {
                        return Err(format!(
                            "a face needs at least 3 corners, got {}",
                            corners.len()
                        ));
                    }
                    for k in 1..corners.len() - 1 {
                        let tri = [corners[0], corners[k], corners[k + 1]];
                        let normals = match tri.map(|(_, n)| n) {
                            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                            _ => None,
                        };
                        obj.triangles.push(ObjTriangle {
                            positions: tri.map(|(v, _)| v),
                            normals,
                        });
                    }
                    Ok(())
                })
            }
            _ => Ok(()),
        };
        if let Err(message) = outcome {
            return Err(PrtError::file(
                path,
                format!("line {}: {message}", line_index + 1),
            ));
        }
    }
    Ok(obj)
}

/// Object-to-world transform of a mesh: `translate * rotate_y * scale`.
pub(super) struct MeshTransform {
    pub(super) scale: f32,
    pub(super) rotation: Mat3,
    pub(super) translate: Vec3,
}

impl MeshTransform {
    pub(super) fn point(&self, p: Vec3) -> Vec3 {
        self.translate + self.rotation * (self.scale * p)
    }
}

/// World-space triangles of a mesh, with shading normals chosen as the module documents:
/// welded area-weighted normals when `smooth`, else the file's `vn` where a face has them, else
/// the geometric normal. Triangles without area are dropped.
pub(super) fn mesh_triangles(
    obj: &ObjData,
    transform: &MeshTransform,
    smooth: bool,
    material: u32,
) -> Vec<Triangle> {
    let world: Vec<Vec3> = obj.positions.iter().map(|&p| transform.point(p)).collect();

    // Welding is by exact object-space position, because OBJ exporters duplicate vertices
    // along patch seams (the teapot) and those copies must share one normal.
    let smooth_normals: Vec<Vec3> = if smooth {
        let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
        let welded: Vec<u32> = obj
            .positions
            .iter()
            .map(|p| {
                // Adding 0.0 turns -0.0 into 0.0 so both weld together.
                let key = (*p + Vec3::ZERO).to_array().map(f32::to_bits);
                let next = weld.len() as u32;
                *weld.entry(key).or_insert(next)
            })
            .collect();
        let mut sums = vec![Vec3::ZERO; weld.len()];
        for tri in &obj.triangles {
            let [a, b, c] = tri.positions.map(|i| world[i as usize]);
            // The unnormalised cross product is twice the area: area weighting for free.
            let n = (b - a).cross(c - a);
            for i in tri.positions {
                sums[welded[i as usize] as usize] += n;
            }
        }
        welded
            .iter()
            .map(|&w| sums[w as usize].normalize_or_zero())
            .collect()
    } else {
        Vec::new()
    };

    let mut out = Vec::with_capacity(obj.triangles.len());
    for tri in &obj.triangles {
        let vertices = tri.positions.map(|i| world[i as usize]);
        let Some(mut t) = flat_triangle(vertices, material) else {
            continue;
        };
        let geometric = t.normals[0];
        let pick = |n: Vec3| if n == Vec3::ZERO { geometric } else { n };
        if smooth {
            t.normals = tri.positions.map(|i| pick(smooth_normals[i as usize]));
        } else if let Some(ns) = tri.normals {
            t.normals = ns
                .map(|i| pick((transform.rotation * obj.normals[i as usize]).normalize_or_zero()));
        }
        out.push(t);
    }
    out
}
