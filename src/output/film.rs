//! Images the engine produces: linear RGB float pixels, written as OpenEXR (linear) or PNG
//! (exposure, then the sRGB curve), atomically. Also the tone mapping shared by PNG output, the
//! contact sheet and the viewer.

use std::path::Path;
use std::sync::{Mutex, PoisonError};

use crate::error::{PrtError, Result};

/// One image made ahead of its use, its memory already written ([`Image::make_ahead`]).
static AHEAD: Mutex<Option<Image>> = Mutex::new(None);

/// A linear RGB image, row-major, y growing downwards.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Linear RGB radiance, row-major.
    pub pixels: Vec<[f32; 3]>,
}

/// How linear radiance becomes display values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToneMap {
    /// Exposure in stops: values are multiplied by 2^exposure before the curve.
    pub exposure: f32,
    /// How exposed values above 1 are brought into range before the sRGB curve.
    pub curve: ToneCurve,
}

impl Default for ToneMap {
    fn default() -> Self {
        ToneMap {
            exposure: 0.0,
            curve: ToneCurve::Clip,
        }
    }
}

impl ToneMap {
    /// Exposure only, clipping at 1 (what PNG output and the contact sheet use).
    pub fn exposure(exposure: f32) -> ToneMap {
        ToneMap {
            exposure,
            curve: ToneCurve::Clip,
        }
    }
}

/// The display curve applied per channel to exposed linear values, before the sRGB encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum ToneCurve {
    /// Values above 1 clip: faithful below 1, what an error comparison wants.
    #[default]
    Clip,
    /// Reinhard's x / (1 + x) (Reinhard et al. 2002): never clips, flattens highlights.
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve (2015): a toe and a soft shoulder.
    Aces,
}

impl ToneCurve {
    /// Every curve, in the order of [`ToneCurve::index`].
    pub const ALL: [ToneCurve; 3] = [ToneCurve::Clip, ToneCurve::Reinhard, ToneCurve::Aces];

    /// The curve's name for display, as the viewer lists it.
    pub fn name(self) -> &'static str {
        match self {
            ToneCurve::Clip => "clip",
            ToneCurve::Reinhard => "Reinhard",
            ToneCurve::Aces => "ACES (fit)",
        }
    }

    /// The index the display shader switches on (`shaders/tonemap.wgsl`).
    pub fn index(self) -> u32 {
        self as u32
    }

    /// The curve at an exposed linear value `x >= 0`.
    #[inline]
    pub fn apply(self, x: f32) -> f32 {
        match self {
            ToneCurve::Clip => x,
            ToneCurve::Reinhard => x / (1.0 + x),
            ToneCurve::Aces => {
                (x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
            }
        }
    }
}

/// The sRGB transfer curve of a linear value in [0, 1].
#[inline]
pub fn srgb_encode(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

impl ToneMap {
    /// 8-bit sRGB of a linear pixel.
    #[inline]
    pub fn apply(&self, p: [f32; 3]) -> [u8; 3] {
        let s = self.exposure.exp2();
        p.map(|v| (srgb_encode(self.curve.apply((v * s).max(0.0))) * 255.0 + 0.5) as u8)
    }

    /// An exposure that maps the 99th percentile of luminance over `mask`ed pixels to 0.9, or
    /// lower where that would take the 99th percentile of their brightest channel above 0.95: a
    /// few very bright pixels do not darken the rest, and coloured light (a warm lamp on the
    /// ground) does not clip in its strongest channel. At most 1% of the lit pixels clip.
    pub fn auto(image: &Image, mask: Option<&[f32]>) -> ToneMap {
        let lum = |p: &[f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
        let (mut lums, mut tops): (Vec<f32>, Vec<f32>) = image
            .pixels
            .iter()
            .enumerate()
            .filter(|(i, _)| mask.is_none_or(|m| m[*i] > 0.0))
            .map(|(_, p)| (lum(p), p[0].max(p[1]).max(p[2])))
            .filter(|(l, top)| l.is_finite() && top.is_finite() && *l > 0.0)
            .unzip();
        if lums.is_empty() {
            return ToneMap::default();
        }
        let scale = (AUTO_LUMINANCE / percentile(&mut lums, AUTO_PERCENTILE))
            .min(AUTO_CHANNEL / percentile(&mut tops, AUTO_PERCENTILE));
        ToneMap::exposure(scale.log2())
    }

    /// The fraction of the `mask`ed pixels (all with `None`) this tone map brings to white in
    /// some channel.
    pub fn clipped_fraction(&self, image: &Image, mask: Option<&[f32]>) -> f64 {
        let s = self.exposure.exp2();
        let (mut shown, mut clipped) = (0usize, 0usize);
        for (i, p) in image.pixels.iter().enumerate() {
            if mask.is_some_and(|m| m[i] <= 0.0) {
                continue;
            }
            shown += 1;
            if p.iter().any(|v| self.curve.apply((v * s).max(0.0)) >= 1.0) {
                clipped += 1;
            }
        }
        if shown == 0 {
            0.0
        } else {
            clipped as f64 / shown as f64
        }
    }
}

/// The percentile of the lit pixels [`ToneMap::auto`] exposes for.
pub const AUTO_PERCENTILE: f32 = 0.99;
/// Where [`ToneMap::auto`] puts that percentile's luminance, before the curve.
pub const AUTO_LUMINANCE: f32 = 0.9;
/// The highest [`ToneMap::auto`] puts that percentile's brightest channel, before the curve.
pub const AUTO_CHANNEL: f32 = 0.95;

/// The value at fraction `q` of `values` (not empty), reordering them.
pub fn percentile(values: &mut [f32], q: f32) -> f32 {
    let k = ((values.len() as f32 * q) as usize).min(values.len() - 1);
    *values.select_nth_unstable_by(k, f32::total_cmp).1
}

impl Image {
    /// A black image: the one made ahead for this size, if there is one.
    pub fn new(width: usize, height: usize) -> Self {
        if let Ok(mut ahead) = AHEAD.try_lock()
            && let Some(image) = ahead.take_if(|i| i.width == width && i.height == height)
        {
            return image;
        }
        Image {
            width,
            height,
            pixels: vec![[0.0; 3]; width * height],
        }
    }

    /// Makes a black image of this size, its pages already written, for the process's next
    /// [`Image::new`] of that size. A fresh allocation is mapped a page at a time as it is first
    /// written; a caller that knows it will soon need an image (`prt relight`, while the transport
    /// loads) thus takes those faults off the product that fills it. On a 512² bake they were
    /// half of a fresh process's first product.
    pub fn make_ahead(width: usize, height: usize) {
        // Hidden from the optimiser, which could otherwise drop the writes of zeros over memory
        // it knows is zeroed.
        let mut pixels = std::hint::black_box(vec![[0.0f32; 3]; width * height]);
        pixels.fill([0.0; 3]);
        let image = Image {
            width,
            height,
            pixels,
        };
        *AHEAD.lock().unwrap_or_else(PoisonError::into_inner) = Some(image);
    }

    /// 8-bit sRGB bytes, RGB interleaved.
    pub fn to_srgb8(&self, tone: ToneMap) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| tone.apply(*p)).collect()
    }

    /// The first pixel with a NaN or infinite channel, as (x, y, value).
    pub fn first_non_finite(&self) -> Option<(usize, usize, f32)> {
        let w = self.width.max(1);
        self.pixels.iter().enumerate().find_map(|(i, p)| {
            p.iter()
                .find(|v| !v.is_finite())
                .map(|&v| (i % w, i / w, v))
        })
    }

    /// An error when a pixel is NaN or infinite: `what` names the image ("the relit image").
    /// Inputs are finite, so such a pixel means a value on the way that 32-bit floats do not
    /// hold; the message lists what can cause one, the materials among them.
    pub fn check_finite(&self, what: &str) -> Result<()> {
        match self.first_non_finite() {
            None => Ok(()),
            Some((x, y, v)) => Err(PrtError::invalid(
                what,
                format!(
                    "pixel (x = {x}, y = {y}) is {v}: a value on the way is not finite in 32-bit \
                     floats (a material whose lobe is not finite there, an environment or a \
                     light far too bright, or a damaged file)"
                ),
            )),
        }
    }

    /// Writes `.exr` (linear float) or `.png` (tone-mapped sRGB), chosen by the extension. An
    /// image with a NaN or infinite pixel is refused, not written.
    pub fn save(&self, path: &Path, tone: ToneMap) -> Result<()> {
        if let Some((x, y, v)) = self.first_non_finite() {
            return Err(PrtError::file(
                path,
                format!("not written: pixel (x = {x}, y = {y}) is {v}"),
            ));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("exr") => write_atomically(path, |file| self.write_exr(file, path)),
            Some("png") => write_png(path, self.width, self.height, &self.to_srgb8(tone)),
            _ => Err(PrtError::file(
                path,
                "unknown image type: use a .exr (linear) or .png (tone-mapped) file name",
            )),
        }
    }

    /// Writes the image as OpenEXR into `file`, the temporary file of `path`.
    fn write_exr(&self, file: std::fs::File, path: &Path) -> Result<()> {
        use exr::prelude::{Image as Exr, SpecificChannels, Vec2, WritableImage};
        let w = self.width;
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let p = self.pixels[y * w + x];
            (p[0], p[1], p[2])
        });
        Exr::from_channels((self.width, self.height), channels)
            .write()
            .to_buffered(std::io::BufWriter::new(file))
            .map_err(|e| PrtError::file(path, format!("writing OpenEXR: {e}")))
    }

    /// Reads a linear image written by [`Image::save`] (EXR only).
    pub fn load_exr(path: &Path) -> Result<Image> {
        let (width, height, pixels) = read_exr(path, check_image_size)?;
        let img = Image {
            width,
            height,
            pixels,
        };
        if let Some((x, y, v)) = img.first_non_finite() {
            return Err(PrtError::file(
                path,
                format!("pixel (x = {x}, y = {y}) is {v}: an image must be finite"),
            ));
        }
        Ok(img)
    }
}

/// Largest accepted image to compare: the largest image this program writes (16384²), checked
/// from the header before any pixel is allocated.
pub const MAX_IMAGE_PIXELS: usize = 16384 * 16384;
/// Largest accepted image file: the largest image in uncompressed 32-bit RGBA, and its header.
pub const MAX_IMAGE_BYTES: u64 = MAX_IMAGE_PIXELS as u64 * 16 + (64 << 20);

/// Reads the first RGB(A) layer of an OpenEXR file. Its channels and size are checked from the
/// header (`check_size(path, width, height)`) before any pixel is allocated, and the pixels are
/// reserved without aborting when memory is short.
pub fn read_exr(
    path: &Path,
    check_size: fn(&Path, usize, usize) -> Result<()>,
) -> Result<(usize, usize, Vec<[f32; 3]>)> {
    let (file, _) = crate::files::open_regular(path, MAX_IMAGE_BYTES, "OpenEXR image")?;
    read_exr_from(std::io::BufReader::new(file), path, check_size)
}

/// [`read_exr`] of the OpenEXR bytes `source` holds (a file, or bytes built into the binary),
/// named `path` in messages.
pub fn read_exr_from(
    mut source: impl std::io::Read + std::io::Seek + Send,
    path: &Path,
    check_size: fn(&Path, usize, usize) -> Result<()>,
) -> Result<(usize, usize, Vec<[f32; 3]>)> {
    use exr::prelude::{ReadChannels as _, ReadLayers as _};
    let exr_err = |e: exr::error::Error| PrtError::file(path, format!("OpenEXR: {e}"));
    let meta = exr::meta::MetaData::read_from_buffered(&mut source, false).map_err(exr_err)?;
    source
        .seek(std::io::SeekFrom::Start(0))
        .map_err(|e| PrtError::io(path, e))?;
    let has = |h: &exr::meta::header::Header, name: &str| {
        h.channels
            .list
            .iter()
            .any(|c| c.name.eq_case_insensitive(name))
    };
    // The layer the reader takes: the first with red, green and blue.
    let Some(header) = meta
        .headers
        .iter()
        .find(|h| ["R", "G", "B"].iter().all(|c| has(h, c)))
    else {
        let layers: Vec<String> = meta
            .headers
            .iter()
            .map(|h| {
                let names: Vec<String> = h
                    .channels
                    .list
                    .iter()
                    .map(|c| crate::files::printable(&c.name.to_string()))
                    .collect();
                names.join(", ")
            })
            .collect();
        return Err(PrtError::file(
            path,
            format!(
                "OpenEXR: no layer has R, G and B channels (the file's channels: {}); \
                 save it as RGB or RGBA",
                if layers.is_empty() {
                    "none".to_string()
                } else {
                    layers.join("; ")
                }
            ),
        ));
    };
    let (w, h) = (header.layer_size.width(), header.layer_size.height());
    check_size(path, w, h)?;
    let reserved = std::cell::RefCell::new(Some(reserve_pixels(path, w, h)?));
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            move |res, _| {
                let mut px = reserved.borrow_mut().take().unwrap_or_default();
                // The layer read is the one checked: the same size, so nothing is allocated here.
                px.resize(res.width() * res.height(), [0.0; 3]);
                px
            },
            move |px: &mut Vec<[f32; 3]>,
                  pos: exr::prelude::Vec2<usize>,
                  (r, g, b, _a): (f32, f32, f32, f32)| {
                if let Some(p) = px.get_mut(pos.y() * w + pos.x()) {
                    *p = [r, g, b];
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(source)
        .map_err(exr_err)?;
    let size = image.layer_data.size;
    if (size.width(), size.height()) != (w, h) {
        return Err(PrtError::file(
            path,
            "OpenEXR layer size changed while reading",
        ));
    }
    Ok((w, h, image.layer_data.channel_data.pixels))
}

/// A table of `w` x `h` pixels of black, reserved with `try_reserve`: an error naming `path`
/// when memory is short, never an abort.
pub fn reserve_pixels(path: &Path, w: usize, h: usize) -> Result<Vec<[f32; 3]>> {
    let n = w.saturating_mul(h);
    let mut px: Vec<[f32; 3]> = Vec::new();
    px.try_reserve_exact(n).map_err(|_| {
        PrtError::file(
            path,
            format!(
                "a {w} x {h} image needs {:.1} GiB, which this process cannot have",
                (n as f64 * 12.0) / (1u64 << 30) as f64
            ),
        )
    })?;
    px.resize(n, [0.0; 3]);
    Ok(px)
}

/// An image size is at least 1 x 1 and at most [`MAX_IMAGE_PIXELS`].
pub fn check_image_size(path: &Path, w: usize, h: usize) -> Result<()> {
    if w == 0 || h == 0 || w.saturating_mul(h) > MAX_IMAGE_PIXELS {
        return Err(PrtError::file(
            path,
            format!("image size {w} x {h} is empty or above {MAX_IMAGE_PIXELS} pixels"),
        ));
    }
    Ok(())
}

/// Writes 8-bit RGB bytes as a PNG, atomically ([`write_atomically`]).
pub fn write_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    use image::ImageEncoder;
    write_atomically(path, |file| {
        let mut w = std::io::BufWriter::new(file);
        image::codecs::png::PngEncoder::new(&mut w)
            .write_image(
                rgb,
                width as u32,
                height as u32,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|e| PrtError::file(path, format!("writing PNG: {e}")))?;
        std::io::Write::flush(&mut w).map_err(|e| PrtError::io(path, e))
    })
}

pub use crate::files::write_atomically;

#[cfg(test)]
mod tests {
    use super::*;

    /// An image made ahead is the next one of its size, black; other sizes do not take it.
    #[test]
    fn an_image_made_ahead_is_taken_by_the_next_of_its_size() {
        // A size no other test makes.
        let (w, h) = (7, 1013);
        Image::make_ahead(w, h);
        let other = Image::new(w + 1, h);
        assert_eq!(other.pixels.len(), (w + 1) * h);
        assert!(AHEAD.lock().unwrap().as_ref().is_some_and(|i| i.width == w));
        let image = Image::new(w, h);
        assert_eq!(
            (image.width, image.height, image.pixels.len()),
            (w, h, w * h)
        );
        assert!(image.pixels.iter().all(|p| *p == [0.0; 3]));
        assert!(AHEAD.lock().unwrap().is_none(), "taken");
        assert_eq!(Image::new(w, h), image, "and made anew after");
    }

    #[test]
    fn tone_curves_are_monotone_and_map_zero_to_zero() {
        for c in ToneCurve::ALL {
            assert_eq!(c.apply(0.0), 0.0, "{c:?}");
            let mut last = 0.0;
            for i in 1..2000 {
                let y = c.apply(i as f32 * 0.01);
                assert!(y >= last, "{c:?} falls at {i}");
                last = y;
            }
        }
        assert_eq!(ToneCurve::Reinhard.apply(1.0), 0.5);
        assert!(ToneCurve::Reinhard.apply(1e6) < 1.0);
        // The ACES fit shoulders towards 1 without clipping early.
        let a = ToneCurve::Aces;
        assert!(a.apply(0.5) < 0.7 && a.apply(8.0) > 0.95);
    }

    /// A warm lamp's hot spot over a dim, bluish ground: exposed from luminance alone, the
    /// lamp's red channel clips over 1.7% of the image (measured); the automatic exposure clips
    /// 0.9%, and still shows the ground.
    #[test]
    fn auto_exposure_leaves_a_lamp_lit_ground_unclipped() {
        let (w, h) = (100, 100);
        let mut image = Image::new(w, h);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let d2 = ((x - 30.0).powi(2) + (y - 40.0).powi(2)) / 36.0;
            let k = 3.0 / (1.0 + d2);
            *p = [0.05 + k, 0.06 + 0.62 * k, 0.08 + 0.32 * k];
        }
        let tone = ToneMap::auto(&image, None);
        let clipped = tone.clipped_fraction(&image, None);
        assert!(clipped < 0.01, "{:.2}% of the pixels clip", clipped * 100.0);
        // The ground far from the lamp is not crushed to black.
        let far = tone.apply(image.pixels[w * h - 1]);
        assert!(far.iter().all(|&v| v > 40), "{far:?}");
        // Exposed for luminance alone, as before, the lamp's red clips over more.
        let mut lum: Vec<f32> = image
            .pixels
            .iter()
            .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
            .collect();
        let by_luminance = ToneMap::exposure((0.9 / percentile(&mut lum, 0.99)).log2());
        assert!(by_luminance.clipped_fraction(&image, None) > 0.015);
        // Grey images keep the luminance rule; a mask leaves the rest out.
        let grey = Image {
            width: 2,
            height: 1,
            pixels: vec![[0.5; 3], [100.0; 3]],
        };
        let masked = ToneMap::auto(&grey, Some(&[1.0, 0.0]));
        assert!((masked.exposure - (0.9f32 / 0.5).log2()).abs() < 1e-6);
        assert_eq!(masked.clipped_fraction(&grey, Some(&[1.0, 0.0])), 0.0);
    }

    #[test]
    fn clip_curve_is_plain_exposure() {
        let t = ToneMap::exposure(1.0);
        assert_eq!(t.apply([0.25, 0.0, 10.0]), [188, 0, 255]);
        let r = ToneMap {
            curve: ToneCurve::Reinhard,
            ..t
        };
        // 10 · 2 = 20 → 20/21 → 250 after the sRGB curve: below white, where clip gives 255.
        assert_eq!(r.apply([10.0, 0.0, 0.0])[0], 250);
    }
}
