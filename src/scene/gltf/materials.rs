//! glTF materials as this engine's: `pbrMetallicRoughness` factors and textures, each texture
//! decoded once (its size checked before decoding) with its sampler's wrap and filter modes, and
//! what the bake does not use noted.

use glam::Vec4;

use super::{GltfMaterial, MAX_TEXELS, Reader, printable};
use crate::error::Result;
use crate::scene::TexturedMaterial;
use crate::scene::texture::{Encoding, Filter, Texture, Wrap};

impl Reader<'_> {
    /// This engine's index of glTF material `index` (`None`: the default material).
    pub(super) fn material(&mut self, index: Option<usize>) -> Result<u32> {
        if let Some(&m) = self.st.material_index.get(&index) {
            return Ok(m);
        }
        let (name, base, metallic, roughness, base_tex, mr_tex) = match index {
            None => ("default".to_string(), Vec4::ONE, 1.0, 1.0, None, None),
            Some(i) => {
                let m = self
                    .doc
                    .materials()
                    .nth(i)
                    .expect("validated material index");
                let field = format!("materials[{i}]");
                self.note_ignored(&m);
                let pbr = m.pbr_metallic_roughness();
                let base = Vec4::from(pbr.base_color_factor());
                let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
                for (what, v) in [("metallicFactor", metallic), ("roughnessFactor", roughness)] {
                    if !(0.0..=1.0).contains(&v) {
                        return Err(self.error(
                            format!("{field}.pbrMetallicRoughness.{what}"),
                            format!("must be in [0, 1], got {v}"),
                        ));
                    }
                }
                if !(base.is_finite()
                    && base.cmpge(Vec4::ZERO).all()
                    && base.cmple(Vec4::ONE).all())
                {
                    return Err(self.error(
                        format!("{field}.pbrMetallicRoughness.baseColorFactor"),
                        format!("each channel must be in [0, 1], got {base}"),
                    ));
                }
                let base_tex = match pbr.base_color_texture() {
                    Some(info) => self.texture(&info, Encoding::Srgb, &field)?,
                    None => None,
                };
                let mr_tex = match pbr.metallic_roughness_texture() {
                    Some(info) => self.texture(&info, Encoding::Linear, &field)?,
                    None => None,
                };
                let name = m
                    .name()
                    .map(printable)
                    .unwrap_or_else(|| format!("material {i}"));
                (name, base, metallic, roughness, base_tex, mr_tex)
            }
        };
        let maps = TexturedMaterial {
            base_color: base.truncate(),
            base_color_texture: base_tex,
            metallic,
            roughness,
            metallic_roughness_texture: mr_tex,
            diffuse_only: false,
        };
        let textured = base_tex.is_some() || mr_tex.is_some();
        let material = maps.mean(&self.out.textures);
        self.out.materials.push(GltfMaterial {
            name,
            material,
            maps: textured.then_some(maps),
        });
        let m = (self.out.materials.len() - 1) as u32;
        self.st.material_index.insert(index, m);
        Ok(m)
    }

    /// Lists what a material has that the bake does not use.
    fn note_ignored(&mut self, m: &gltf::Material) {
        let name = m
            .name()
            .map(printable)
            .unwrap_or_else(|| format!("{}", m.index().unwrap_or(0)));
        let mut add = |what: &str| {
            self.out.ignored.insert(format!("{what} (material {name})"));
        };
        if m.emissive_factor() != [0.0; 3] || m.emissive_texture().is_some() {
            add("emission");
        }
        if m.normal_texture().is_some() {
            add("normal map");
        }
        if m.occlusion_texture().is_some() {
            add("occlusion texture (the bake computes occlusion)");
        }
        if m.alpha_mode() != gltf::material::AlphaMode::Opaque {
            add("alpha (the surface is opaque)");
        }
    }

    /// This engine's texture for a material's texture reference, decoded on first use.
    pub(super) fn texture(
        &mut self,
        info: &gltf::texture::Info,
        encoding: Encoding,
        field: &str,
    ) -> Result<Option<u32>> {
        if info.tex_coord() != 0 {
            self.out.ignored.insert(format!(
                "TEXCOORD_{} (textures are read through TEXCOORD_0)",
                info.tex_coord()
            ));
            return Ok(None);
        }
        let t = info.texture();
        // Textures that share an image and a sampler share one decoded copy.
        let key = (
            t.source().index(),
            t.sampler().index(),
            encoding == Encoding::Srgb,
        );
        if let Some(&i) = self.st.texture_index.get(&key) {
            return Ok(Some(i));
        }
        let image = t.source();
        let img_field = format!("images[{}]", image.index());
        // The image's bytes: a range of a shared buffer, or a URI's.
        let (bytes, range) = match image.source() {
            gltf::image::Source::View { view, .. } => (
                self.st.buffers[view.buffer().index()].clone(),
                view.offset()..view.offset() + view.length(),
            ),
            gltf::image::Source::Uri { uri, .. } => {
                let b = self.uri_bytes(uri, &format!("{img_field}.uri"))?;
                let n = b.len();
                (b, 0..n)
            }
        };
        let name = image
            .name()
            .map(printable)
            .unwrap_or_else(|| format!("image {}", image.index()));
        let file = self.path;
        let decode_error = |e: String| crate::error::PrtError::Scene {
            path: file.to_path_buf(),
            line: None,
            field: img_field.clone(),
            message: format!("{name}: {e} (used by {field})"),
        };
        let open = || {
            image::ImageReader::new(std::io::Cursor::new(&bytes[range.clone()]))
                .with_guessed_format()
                .map_err(|e| decode_error(e.to_string()))
        };
        // The size from the header, against what the file's textures may still take, before
        // anything is decoded.
        let (w, h) = open()?
            .into_dimensions()
            .map_err(|e| decode_error(e.to_string()))?;
        let texels = w as u64 * h as u64;
        if texels > self.limits.texels_left {
            return Err(decode_error(format!(
                "{w} x {h} texels take the scene's textures past {MAX_TEXELS} texels"
            )));
        }
        let mut reader = open()?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(crate::scene::texture::MAX_TEXTURE_SIDE);
        limits.max_image_height = Some(crate::scene::texture::MAX_TEXTURE_SIDE);
        limits.max_alloc = Some(1 << 30);
        reader.limits(limits);
        let decoded = reader
            .decode()
            .map_err(|e| decode_error(e.to_string()))?
            .into_rgb8();
        self.limits.texels_left -= texels;
        let (w, h) = decoded.dimensions();
        let texels = decoded
            .into_raw()
            .chunks_exact(3)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        let mut texture = Texture::new(name.clone(), w, h, texels, encoding)
            .ok_or_else(|| decode_error(format!("a {w} x {h} image cannot be a texture")))?;
        let sampler = t.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        };
        texture.wrap = [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())];
        texture.filter = match sampler.mag_filter() {
            Some(gltf::texture::MagFilter::Nearest) => Filter::Nearest,
            _ => Filter::Linear,
        };
        self.out.textures.push(texture);
        let i = (self.out.textures.len() - 1) as u32;
        self.st.texture_index.insert(key, i);
        Ok(Some(i))
    }
}
