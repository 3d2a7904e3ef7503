//! A small glTF 2.0 writer for the tests: a ground quad with a checker texture, a box under a
//! transformed parent, a camera; written as `.glb`, as `.gltf` with external files, or as
//! `.gltf` with base64 data URIs.

use std::path::{Path, PathBuf};

use serde_json::{Value, json};

/// One binary buffer and the JSON that describes it, built up object by object.
#[derive(Default)]
pub struct GltfBuilder {
    pub bin: Vec<u8>,
    pub views: Vec<Value>,
    pub accessors: Vec<Value>,
    pub images: Vec<(Vec<u8>, String)>,
    pub json: serde_json::Map<String, Value>,
}

/// The checker the tests texture the ground with, `side` x `side` texels. Texel (x, y) (x to
/// the right, y down from the top-left) codes its place, so that a flip or a swap of the axes
/// shows: red `40 + 180 x / (side - 1)`, green `40 + 180 y / (side - 1)`, and blue a checker,
/// dark (40) where x + y is even and light (220) where it is odd; all sRGB.
pub fn checker_png(side: u32) -> Vec<u8> {
    let img = image::RgbImage::from_fn(side, side, |x, y| image::Rgb(checker_texel(side, x, y)));
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// The sRGB bytes of texel (x, y) of [`checker_png`].
pub fn checker_texel(side: u32, x: u32, y: u32) -> [u8; 3] {
    let ramp = |v: u32| (40 + 180 * v / (side - 1).max(1)) as u8;
    [
        ramp(x),
        ramp(y),
        if (x + y).is_multiple_of(2) { 40 } else { 220 },
    ]
}

/// Makes the checker material metallic (factor 0.5, roughness 0.6) through a
/// metallic-roughness texture (the same image, read linearly: roughness from green, metal from
/// blue), so that the glossy lobe's colour and width change from texel to texel too.
pub fn with_metal(b: &mut GltfBuilder) {
    let m = &mut b.json.get_mut("materials").unwrap()[0]["pbrMetallicRoughness"];
    m["metallicRoughnessTexture"] = json!({"index": 0});
    m["metallicFactor"] = json!(0.5);
    m["roughnessFactor"] = json!(0.6);
}

impl GltfBuilder {
    fn align(&mut self) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }

    /// A buffer view over `bytes`; returns its index.
    pub fn view(&mut self, bytes: &[u8]) -> usize {
        self.align();
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        self.views.len() - 1
    }

    /// A float accessor of `kind` ("VEC2", "VEC3") over `values`; returns its index.
    pub fn floats(&mut self, values: &[f32], kind: &str, components: usize) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let mut a = json!({
            "bufferView": view, "componentType": 5126, "count": values.len() / components,
            "type": kind
        });
        if kind == "VEC3" {
            let min: Vec<f32> = (0..3)
                .map(|k| {
                    values
                        .iter()
                        .skip(k)
                        .step_by(3)
                        .copied()
                        .fold(f32::INFINITY, f32::min)
                })
                .collect();
            let max: Vec<f32> = (0..3)
                .map(|k| {
                    values
                        .iter()
                        .skip(k)
                        .step_by(3)
                        .copied()
                        .fold(f32::NEG_INFINITY, f32::max)
                })
                .collect();
            a["min"] = json!(min);
            a["max"] = json!(max);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// A u16 index accessor; returns its index.
    pub fn indices(&mut self, values: &[u16]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5123, "count": values.len(), "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }

    /// A mesh primitive's attributes from positions, normals and texture coordinates.
    pub fn primitive(
        &mut self,
        positions: &[[f32; 3]],
        normal: [f32; 3],
        uvs: Option<&[[f32; 2]]>,
        indices: &[u16],
        material: usize,
    ) -> Value {
        let p: Vec<f32> = positions.iter().flatten().copied().collect();
        let n: Vec<f32> = positions.iter().flat_map(|_| normal).collect();
        let pa = self.floats(&p, "VEC3", 3);
        let na = self.floats(&n, "VEC3", 3);
        let ia = self.indices(indices);
        let mut attributes = json!({"POSITION": pa, "NORMAL": na});
        if let Some(uvs) = uvs {
            let t: Vec<f32> = uvs.iter().flatten().copied().collect();
            attributes["TEXCOORD_0"] = json!(self.floats(&t, "VEC2", 2));
        }
        json!({"attributes": attributes, "indices": ia, "material": material})
    }

    /// Sets a top-level array or object.
    pub fn set(&mut self, key: &str, value: Value) {
        self.json.insert(key.into(), value);
    }

    /// The document's JSON, with the buffer given by `buffer` and the images as `image`
    /// (each: index, PNG bytes) returns them.
    fn document(
        &mut self,
        buffer: Value,
        mut image: impl FnMut(&mut Self, usize) -> Value,
    ) -> Value {
        let images: Vec<Value> = (0..self.images.len()).map(|i| image(self, i)).collect();
        let mut root = self.json.clone();
        root.insert("asset".into(), json!({"version": "2.0"}));
        root.insert("buffers".into(), json!([buffer]));
        root.insert("bufferViews".into(), json!(self.views));
        root.insert("accessors".into(), json!(self.accessors));
        if !images.is_empty() {
            root.insert("images".into(), json!(images));
        }
        Value::Object(root)
    }

    /// Writes `name.glb` in `dir`, images in buffer views.
    pub fn write_glb(mut self, dir: &Path, name: &str) -> PathBuf {
        let images = self.images.clone();
        let views: Vec<usize> = images.iter().map(|(b, _)| self.view(b)).collect();
        self.align();
        let len = self.bin.len();
        let doc = self.document(
            json!({"byteLength": len}),
            |_, i| json!({"bufferView": views[i], "mimeType": images[i].1}),
        );
        let out = pack_glb(&serde_json::to_vec(&doc).unwrap(), &self.bin);
        let path = dir.join(format!("{name}.glb"));
        std::fs::write(&path, out).unwrap();
        path
    }

    /// Writes `name.gltf` in `dir`, with the buffer and images beside it as files.
    pub fn write_gltf(mut self, dir: &Path, name: &str) -> PathBuf {
        std::fs::write(dir.join(format!("{name} data.bin")), &self.bin).unwrap();
        let len = self.bin.len();
        let doc = self.document(
            json!({"byteLength": len, "uri": format!("{name}%20data.bin")}),
            |b, i| {
                let file = format!("{name}_image{i}.png");
                std::fs::write(dir.join(&file), &b.images[i].0).unwrap();
                json!({"uri": file})
            },
        );
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
        path
    }

    /// Writes `name.gltf` in `dir` with the buffer and images as base64 data URIs.
    pub fn write_embedded(mut self, dir: &Path, name: &str) -> PathBuf {
        let len = self.bin.len();
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        let doc = self.document(
            json!({"byteLength": len, "uri": uri}),
            |b, i| json!({"uri": format!("data:image/png;base64,{}", base64(&b.images[i].0))}),
        );
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        path
    }
}

/// A `.glb` container of a JSON chunk (padded with spaces) and a binary chunk, every length
/// right.
pub fn pack_glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut json = json.to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin);
    out
}

/// Standard base64 with padding.
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = c
            .iter()
            .enumerate()
            .fold(0u32, |acc, (i, &b)| acc | (b as u32) << (16 - 8 * i));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// The box's faces: a unit cube's six quads, corners wound outwards, each as 4 corners.
pub fn cube_faces() -> Vec<[[f32; 3]; 4]> {
    let (l, h) = (-0.5f32, 0.5f32);
    vec![
        [[l, l, h], [h, l, h], [h, h, h], [l, h, h]], // +Z
        [[h, l, l], [l, l, l], [l, h, l], [h, h, l]], // -Z
        [[h, l, h], [h, l, l], [h, h, l], [h, h, h]], // +X
        [[l, l, l], [l, l, h], [l, h, h], [l, h, l]], // -X
        [[l, h, h], [h, h, h], [h, h, l], [l, h, l]], // +Y
        [[l, l, l], [h, l, l], [h, l, h], [l, l, h]], // -Y
    ]
}

/// The scene the tests use: a 4 x 4 ground at y = 0 whose UVs span the checker once (u along
/// +x, v along +z, so texel (0, 0) is the corner at (-2, 0, -2)), and a grey unit box under a
/// parent node that is rotated 90° about Y (its matrix exact), scaled by 0.5 and moved to
/// (0.5, 0, 0), so that it stands on the ground with corners at x in {0.25, 0.75}, y in {0, 0.5},
/// z in {-0.25, 0.25}; a camera at (0, 4, 3) looks down at the origin. `nearest` picks the checker's filter.
pub fn test_scene(checker_side: u32, nearest: bool) -> GltfBuilder {
    let mut b = GltfBuilder::default();
    let ground = [
        [-2.0, 0.0, -2.0],
        [2.0, 0.0, -2.0],
        [2.0, 0.0, 2.0],
        [-2.0, 0.0, 2.0],
    ];
    let uvs = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    // Wound so that the normal, (c1 - c0) x (c2 - c0), is +Y.
    let ground_prim = b.primitive(&ground, [0.0, 1.0, 0.0], Some(&uvs), &[0, 2, 1, 0, 3, 2], 0);
    let mut box_prims = Vec::new();
    for face in cube_faces() {
        let [a, bb, c, _] = face;
        let e1 = glam::Vec3::from(bb) - glam::Vec3::from(a);
        let e2 = glam::Vec3::from(c) - glam::Vec3::from(a);
        let n = e1.cross(e2).normalize().to_array();
        box_prims.push(b.primitive(&face, n, None, &[0, 1, 2, 0, 2, 3], 1));
    }
    b.images
        .push((checker_png(checker_side), "image/png".into()));
    let filter = if nearest { 9728 } else { 9729 };
    b.set(
        "samplers",
        json!([{"magFilter": filter, "minFilter": filter}]),
    );
    b.set("textures", json!([{"source": 0, "sampler": 0}]));
    b.set(
        "materials",
        json!([
            {"name": "checker", "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 1.0}},
            {"name": "grey", "pbrMetallicRoughness": {
                "baseColorFactor": [0.6, 0.5, 0.4, 1.0], "metallicFactor": 0.0,
                "roughnessFactor": 0.5}}
        ]),
    );
    b.set(
        "meshes",
        json!([{"name": "ground", "primitives": [ground_prim]}, {"name": "box", "primitives": box_prims}]),
    );
    b.set(
        "cameras",
        json!([{"name": "above", "type": "perspective",
                "perspective": {"yfov": 0.9, "aspectRatio": 1.5, "znear": 0.1}}]),
    );
    // The camera at (0, 4, 3) looking at the origin: its -Z axis along (0, -4, -3) / 5.
    let (s, c) = (0.8f32, 0.6f32);
    b.set(
        "nodes",
        json!([
            {"name": "ground", "mesh": 0},
            {"name": "parent", "matrix": [0.0, 0.0, -0.5, 0.0,  0.0, 0.5, 0.0, 0.0,
                                          0.5, 0.0, 0.0, 0.0,  0.5, 0.0, 0.0, 1.0],
             "children": [2]},
            {"name": "box", "mesh": 1, "translation": [0.0, 0.5, 0.0]},
            {"name": "eye", "camera": 0,
             "matrix": [1.0, 0.0, 0.0, 0.0,  0.0, c, -s, 0.0,  0.0, s, c, 0.0,  0.0, 4.0, 3.0, 1.0]}
        ]),
    );
    b.set("scenes", json!([{"nodes": [0, 1, 3]}]));
    b.set("scene", json!(0));
    b
}
