//! Images that vary a material over a surface (glTF's base-colour and metallic-roughness
//! textures): eight bits a channel as the file stores them, decoded to linear values through a
//! 256-entry table, and sampled at a texture coordinate with the glTF sampler's wrap and
//! magnification modes.
//!
//! Coordinates follow glTF: (0, 0) is the top-left corner of the image, u grows to the right and
//! v downwards, and texel (x, y) covers `[x, x + 1) / width × [y, y + 1) / height`.

use glam::{Vec2, Vec3};

/// How a coordinate outside [0, 1) finds a texel (glTF's `wrapS` and `wrapT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// The image tiles the plane (glTF's default).
    Repeat,
    /// The image tiles the plane, every other copy mirrored.
    MirroredRepeat,
    /// The edge texels extend outwards.
    ClampToEdge,
}

impl Wrap {
    /// The texel index that integer index `i` of a row of `n` texels reads.
    #[inline]
    fn index(self, i: i64, n: u32) -> usize {
        let n = n as i64;
        let j = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::MirroredRepeat => {
                let k = i.rem_euclid(2 * n);
                if k < n { k } else { 2 * n - 1 - k }
            }
            Wrap::ClampToEdge => i.clamp(0, n - 1),
        };
        j as usize
    }
}

/// How a sample between texel centres is formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    /// The texel the coordinate falls in.
    Nearest,
    /// Bilinear interpolation of the four nearest texel centres, in linear values.
    Linear,
}

/// What the stored eight-bit values encode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// sRGB-encoded colour (base colour): decoded with the sRGB transfer function.
    Srgb,
    /// Linear data (metallic and roughness): `value / 255`.
    Linear,
}

/// Largest accepted texture side, in texels.
pub const MAX_TEXTURE_SIDE: u32 = 16384;

/// A decoded texture with its sampler.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// What messages call it: the file's image name or URI.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major RGB, top row first, as stored.
    texels: Vec<[u8; 3]>,
    /// Linear value of each stored byte.
    decode: [f32; 256],
    /// Wrap along u and along v.
    pub wrap: [Wrap; 2],
    /// Magnification filter, which point samples use.
    pub filter: Filter,
    /// What the bytes encode.
    pub encoding: Encoding,
}

/// The sRGB transfer function's inverse (IEC 61966-2-1) for a value in [0, 1].
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Texture {
    /// A texture from row-major RGB bytes, top row first; `None` when the size is zero, above
    /// [`MAX_TEXTURE_SIDE`] or does not match the data.
    pub fn new(
        name: String,
        width: u32,
        height: u32,
        texels: Vec<[u8; 3]>,
        encoding: Encoding,
    ) -> Option<Texture> {
        let sides_ok =
            (1..=MAX_TEXTURE_SIDE).contains(&width) && (1..=MAX_TEXTURE_SIDE).contains(&height);
        if !sides_ok || texels.len() != width as usize * height as usize {
            return None;
        }
        let decode = std::array::from_fn(|b| {
            let v = b as f32 / 255.0;
            match encoding {
                Encoding::Srgb => srgb_to_linear(v),
                Encoding::Linear => v,
            }
        });
        Some(Texture {
            name,
            width,
            height,
            texels,
            decode,
            wrap: [Wrap::Repeat; 2],
            filter: Filter::Linear,
            encoding,
        })
    }

    /// The linear value of texel (x, y), indices already wrapped.
    #[inline]
    fn texel(&self, x: usize, y: usize) -> Vec3 {
        let t = self.texels[y * self.width as usize + x];
        Vec3::new(
            self.decode[t[0] as usize],
            self.decode[t[1] as usize],
            self.decode[t[2] as usize],
        )
    }

    /// The linear RGB value at texture coordinate `uv` with the texture's filter and wrap
    /// modes. A non-finite coordinate reads texel (0, 0).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        // Far outside [0, 1] f32 has no fractional bits left; keep the indices in i64 range.
        let x = (uv.x as f64).clamp(-1e12, 1e12) * self.width as f64;
        let y = (uv.y as f64).clamp(-1e12, 1e12) * self.height as f64;
        let [wu, wv] = self.wrap;
        match self.filter {
            Filter::Nearest => self.texel(
                wu.index(x.floor() as i64, self.width),
                wv.index(y.floor() as i64, self.height),
            ),
            Filter::Linear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let xs = [wu.index(x0, self.width), wu.index(x0 + 1, self.width)];
                let ys = [wv.index(y0, self.height), wv.index(y0 + 1, self.height)];
                let top = self.texel(xs[0], ys[0]).lerp(self.texel(xs[1], ys[0]), fx);
                let bottom = self.texel(xs[0], ys[1]).lerp(self.texel(xs[1], ys[1]), fx);
                top.lerp(bottom, fy)
            }
        }
    }

    /// The mean linear value over all texels.
    pub fn mean(&self) -> Vec3 {
        let mut sum = [0.0f64; 3];
        for t in &self.texels {
            for k in 0..3 {
                sum[k] += self.decode[t[k] as usize] as f64;
            }
        }
        let n = self.texels.len().max(1) as f64;
        Vec3::new(
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
        )
    }

    /// Bytes of texel data held.
    pub fn bytes(&self) -> usize {
        self.texels.len() * 3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        // 2 x 2: black, white / white, black, stored as sRGB.
        let texels = vec![[0; 3], [255; 3], [255; 3], [0; 3]];
        Texture::new("checker".into(), 2, 2, texels, Encoding::Srgb).unwrap()
    }

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // Mid-grey 0.5 encodes 0.2140 linear (IEC 61966-2-1).
        assert!((srgb_to_linear(0.5) - 0.21404).abs() < 1e-4);
        let t = Texture::new("g".into(), 1, 1, vec![[128, 128, 128]], Encoding::Srgb).unwrap();
        assert!((t.sample(Vec2::splat(0.5)).x - 0.21586).abs() < 1e-4);
        let t = Texture::new("g".into(), 1, 1, vec![[128, 128, 128]], Encoding::Linear).unwrap();
        assert!((t.sample(Vec2::splat(0.5)).x - 128.0 / 255.0).abs() < 1e-6);
    }

    #[test]
    fn the_origin_is_the_top_left_texel() {
        let mut t = checker();
        t.filter = Filter::Nearest;
        // Top-left texel black, top-right white, bottom-left white.
        assert_eq!(t.sample(Vec2::new(0.25, 0.25)), Vec3::ZERO);
        assert_eq!(t.sample(Vec2::new(0.75, 0.25)), Vec3::ONE);
        assert_eq!(t.sample(Vec2::new(0.25, 0.75)), Vec3::ONE);
        assert_eq!(t.sample(Vec2::new(0.75, 0.75)), Vec3::ZERO);
    }

    #[test]
    fn wrap_modes_fold_coordinates_as_gltf_says() {
        let texels = (0..4u8).map(|i| [i * 60; 3]).collect();
        let mut t = Texture::new("row".into(), 4, 1, texels, Encoding::Linear).unwrap();
        t.filter = Filter::Nearest;
        let at = |t: &Texture, u: f32| (t.sample(Vec2::new(u, 0.5)).x * 255.0 / 60.0).round();
        // Texel 0 covers u in [0, 0.25); u = 1.1 is texel 0 again when repeating.
        assert_eq!(at(&t, 1.1), 0.0);
        assert_eq!(at(&t, -0.1), 3.0);
        t.wrap[0] = Wrap::MirroredRepeat;
        assert_eq!(at(&t, 1.1), 3.0);
        assert_eq!(at(&t, -0.1), 0.0);
        assert_eq!(at(&t, 2.1), 0.0);
        t.wrap[0] = Wrap::ClampToEdge;
        assert_eq!(at(&t, 1.1), 3.0);
        assert_eq!(at(&t, -5.0), 0.0);
    }

    #[test]
    fn bilinear_interpolates_between_texel_centres() {
        let mut t = checker();
        t.wrap = [Wrap::ClampToEdge; 2];
        // At texel centres the texel's own value; half-way between two it is their mean.
        assert_eq!(t.sample(Vec2::new(0.25, 0.25)), Vec3::ZERO);
        assert!((t.sample(Vec2::new(0.5, 0.25)).x - 0.5).abs() < 1e-6);
        // The centre of the image is the mean of all four.
        assert!((t.sample(Vec2::splat(0.5)).x - 0.5).abs() < 1e-6);
        // Repeating wraps the interpolation across the edge.
        t.wrap = [Wrap::Repeat; 2];
        assert!((t.sample(Vec2::new(0.0, 0.25)).x - 0.5).abs() < 1e-6);
        assert_eq!(t.sample(Vec2::new(f32::NAN, 0.25)), t.sample(Vec2::ZERO));
        assert_eq!(t.mean(), Vec3::splat(0.5));
    }

    #[test]
    fn sizes_are_checked() {
        assert!(Texture::new("x".into(), 0, 1, vec![], Encoding::Linear).is_none());
        assert!(Texture::new("x".into(), 2, 2, vec![[0; 3]; 3], Encoding::Linear).is_none());
    }
}
