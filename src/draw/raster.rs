//! Drawing a mesh with one linear RGB colour per vertex from any camera: Gouraud shading with a
//! depth test, the CPU twin of [`crate::draw::gpu::raster`] (the tests compare the two).
//!
//! A pixel is covered when the ray of [`Camera::ray`] through its centre hits a triangle that
//! faces the eye (its right-handed winding normal `(b − a) × (c − a)` points towards the eye) at
//! a forward distance of at least [`NEAR`]; the nearest such hit wins, and the pixel takes the
//! vertex colours interpolated with the barycentrics of that 3D hit point (perspective-correct;
//! the GPU twin takes the same barycentrics in its fragment shader rather than trusting the
//! hardware's interpolation). Nothing is projected before the test, so triangles that straddle the eye
//! plane need no clipping to be drawn right: each pixel intersects its own ray with the
//! triangle's plane (homogeneous rasterisation). Only the bounding box that limits the pixels
//! tried is taken from the part of the triangle in front of the near plane.
//!
//! A textured mesh ([`Texturing`]) multiplies each drawn pixel by its material's albedo map,
//! read at the pixel's perspective-correct texture coordinate with the level of detail of
//! [`crate::scene::albedo_map::AlbedoMap::lod`]. The coordinate's screen derivatives are those a GPU's fine derivatives take
//! (`dpdxFine`, `dpdyFine`): differences across the pixel's aligned 2 × 2 quad, each pixel of it
//! interpolated (or extrapolated) on the same triangle. So the twins read the same texels.
//!
//! With several samples a pixel ([`rasterize_with`], at the standard rotated-grid
//! positions of [`FOUR_SAMPLES`], or [`SIXTEEN_SAMPLES`] for stills) each sample is drawn as a
//! pixel centre is, shifted by its offset, and a pixel is the mean of its samples: RGB
//! premultiplied by the coverage, the share of its samples drawn. The GPU twin draws the same
//! samples in passes of their own.
//!
//! The work is split in bands of rows run in parallel; each band draws the triangles whose boxes
//! reach it, in index order, so the first of two hits at exactly the same depth wins, as with the
//! GPU's strict depth test. A band finds each pixel's nearest hit first and shades it after, so
//! a glossy light ([`ViewDependent`]) is asked once a drawn pixel, never for a hit that a nearer
//! one hides later.

use glam::{DMat4, DVec2, DVec3, DVec4, Mat4, Vec3};
use rayon::prelude::*;

use crate::draw::shading::{Texturing, ViewDependent};
use crate::error::{PrtError, Result};
use crate::output::film::Image;
use crate::scene::Camera;

/// The nearest forward distance from the eye (along the view direction) that is drawn, in scene
/// units; both twins clip there. A hit nearer than this is not drawn.
pub const NEAR: f32 = 1e-3;

/// Rows of one band of pixels, the unit of parallel work.
const BAND_ROWS: usize = 8;

/// What a rasterised mesh gives: the image (black where nothing is drawn) and per-pixel
/// coverage (1 drawn, 0 not), both row-major with y growing downwards.
#[derive(Clone, Debug, PartialEq)]
pub struct Raster {
    /// The vertex colours interpolated over the drawn triangles, black where nothing is drawn.
    pub image: Image,
    /// Per pixel: 1 where a triangle is drawn, 0 elsewhere.
    pub coverage: Vec<f32>,
}

/// Checks that every per-vertex colour is finite (the CPU and GPU rasterisers draw none that
/// is not).
pub fn check_colours(colours: &[[f32; 3]]) -> Result<()> {
    match colours
        .iter()
        .position(|c| c.iter().any(|v| !v.is_finite()))
    {
        Some(i) => Err(PrtError::invalid(
            format!("colours[{i}]"),
            format!("must be finite, got {:?}", colours[i]),
        )),
        None => Ok(()),
    }
}

/// Checks a mesh: finite positions, at most `u32::MAX` vertices and triangles, every index in
/// range, and when `colours` is given one finite colour per vertex. Errors name the first bad
/// element.
pub fn check_mesh(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    colours: Option<&[[f32; 3]]>,
) -> Result<()> {
    for (what, n) in [
        ("positions", positions.len()),
        ("triangles", triangles.len()),
    ] {
        if n > u32::MAX as usize {
            return Err(PrtError::invalid(
                what,
                format!("{n} of them; at most {} fit u32 indices", u32::MAX),
            ));
        }
    }
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(PrtError::invalid(
            format!("positions[{i}]"),
            format!("must be finite, got {}", positions[i]),
        ));
    }
    if let Some((t, tri)) = triangles
        .iter()
        .enumerate()
        .find(|(_, tri)| tri.iter().any(|&v| v as usize >= positions.len()))
    {
        return Err(PrtError::invalid(
            format!("triangles[{t}]"),
            format!(
                "indices {tri:?} out of range for {} vertices",
                positions.len()
            ),
        ));
    }
    if let Some(colours) = colours {
        if colours.len() != positions.len() {
            return Err(PrtError::invalid(
                "colours",
                format!(
                    "{} colours for {} vertices; expected one per vertex",
                    colours.len(),
                    positions.len()
                ),
            ));
        }
        check_colours(colours)?;
    }
    Ok(())
}

/// The camera's frame as both rasterisers take it, computed as [`Camera::ray`] computes it (in
/// f32): the eye, the film's right and up axes and the view direction (a left-handed basis:
/// right × up = −forward), and half the film's width and height at unit forward distance. A
/// pixel centre's direction is `(film_x, film_y, 1)` in that basis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The eye.
    pub eye: Vec3,
    /// The film's right axis.
    pub right: Vec3,
    /// The film's up axis.
    pub up: Vec3,
    /// The view direction.
    pub forward: Vec3,
    /// Half the film's width at unit forward distance.
    pub half_w: f32,
    /// Half the film's height at unit forward distance.
    pub half_h: f32,
}

impl Frame {
    /// The frame of `camera`.
    pub fn new(camera: &Camera) -> Frame {
        let (forward, right, up) = camera.frame();
        let tan_half = (camera.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = camera.width as f32 / camera.height as f32;
        Frame {
            eye: camera.eye,
            right,
            up,
            forward,
            half_w: tan_half * aspect,
            half_h: tan_half,
        }
    }
}

/// The CPU's view: [`Frame`] widened to f64, and the image size.
#[derive(Clone, Copy, Debug)]
struct View {
    eye: DVec3,
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    /// Half the film's width and height at unit forward distance.
    half_w: f64,
    half_h: f64,
    width: usize,
    height: usize,
    /// Where in each pixel this view samples, from the pixel's centre, in pixels (y down).
    offset: DVec2,
}

impl View {
    fn new(camera: &Camera, offset: [f32; 2]) -> View {
        let f = Frame::new(camera);
        View {
            eye: f.eye.as_dvec3(),
            right: f.right.as_dvec3(),
            up: f.up.as_dvec3(),
            forward: f.forward.as_dvec3(),
            half_w: f.half_w as f64,
            half_h: f.half_h as f64,
            width: camera.width as usize,
            height: camera.height as usize,
            offset: DVec2::new(offset[0] as f64, offset[1] as f64),
        }
    }

    /// Camera coordinates of `p`: along the film's right, the film's up and the view direction.
    /// The basis is left-handed (right × up = −forward).
    fn camera_coords(&self, p: Vec3) -> DVec3 {
        let q = p.as_dvec3() - self.eye;
        DVec3::new(q.dot(self.right), q.dot(self.up), q.dot(self.forward))
    }

    /// The film coordinate at unit forward distance of column `x`'s sample.
    fn film_x(&self, x: usize) -> f64 {
        (2.0 * (x as f64 + 0.5 + self.offset.x) / self.width as f64 - 1.0) * self.half_w
    }

    /// The film coordinate at unit forward distance of row `y`'s sample (up is positive).
    fn film_y(&self, y: usize) -> f64 {
        (1.0 - 2.0 * (y as f64 + 0.5 + self.offset.y) / self.height as f64) * self.half_h
    }

    /// The film position, in pixels, of a camera-space point in front of the eye.
    fn pixel_of(self, q: DVec3) -> (f64, f64) {
        let x = (q.x / (q.z * self.half_w) + 1.0) * 0.5 * self.width as f64;
        let y = (1.0 - q.y / (q.z * self.half_h)) * 0.5 * self.height as f64;
        (x, y)
    }
}

/// The clip-space transform that puts a world point where [`Camera::ray`] sees it: NDC x right
/// and y up over the film (wgpu's viewport puts NDC y = 1 on texture row 0, the film's top), w
/// the forward distance from the eye and z the constant [`NEAR`], so depth is `NEAR / w`
/// (reversed depth: 1 on the near plane, falling towards 0 at infinity, where f32 keeps its
/// relative precision at every distance) and the clip volume's `0 <= z <= w` is exactly
/// `w >= NEAR`. With an `offset` (in pixels from a pixel's centre, y down; see
/// [`sample_offsets`]) the film is shifted so that each pixel's sample at that offset lands on the
/// pixel centre the hardware rasterises at. Built in f64, rounded to f32 once.
pub fn clip_from_world(camera: &Camera, offset: [f32; 2]) -> Mat4 {
    let v = View::new(camera, offset);
    let row = |axis: DVec3, scale: f64| {
        let a = axis / scale;
        DVec4::new(a.x, a.y, a.z, -a.dot(v.eye))
    };
    let w = row(v.forward, 1.0);
    // NDC x falls by 2 offset.x / width, NDC y (up) rises by 2 offset.y / height.
    let (sx, sy) = (
        2.0 * v.offset.x / v.width as f64,
        2.0 * v.offset.y / v.height as f64,
    );
    let rows = [
        row(v.right, v.half_w) - w * sx,
        row(v.up, v.half_h) + w * sy,
        DVec4::new(0.0, 0.0, 0.0, NEAR as f64),
        w,
    ];
    DMat4::from_cols(rows[0], rows[1], rows[2], rows[3])
        .transpose()
        .as_mat4()
}

/// A triangle ready to draw: what each pixel's test needs, and the pixels it may cover.
struct Setup {
    /// In camera coordinates, with a pixel's direction `d = (film_x, film_y, 1)`: the edge
    /// functions are `d · edges[k]` (`b × c`, `c × a`, `a × b`), all non-negative inside; their
    /// sum `s` is `d · n`, the barycentrics are `d · edges[k] / s` and the hit's forward distance
    /// is `volume / s`.
    edges: [DVec3; 3],
    /// `a · (b × c)` in camera coordinates: positive when the triangle faces the eye.
    volume: f64,
    /// Whether part of the triangle is nearer than [`NEAR`], so hits need the near test.
    clipped: bool,
    /// Inclusive pixel ranges the triangle may cover.
    x: [u16; 2],
    y: [u16; 2],
    /// Index of the triangle, for its vertex colours.
    triangle: u32,
}

/// Sets up triangle `index` (`corners` indexes `positions`), or `None` when it faces away, is
/// degenerate, lies entirely nearer than [`NEAR`] or misses the film.
fn setup(view: &View, positions: &[Vec3], corners: [u32; 3], index: u32) -> Option<Setup> {
    let [a, b, c] = corners.map(|i| view.camera_coords(positions[i as usize]));
    let edges = [b.cross(c), c.cross(a), a.cross(b)];
    // In the left-handed camera basis the triple product changes sign: positive here is a world
    // normal pointing towards the eye (a · ((b − a) × (c − a)) = a · (b × c)).
    let volume = a.dot(edges[0]);
    if !(volume > 0.0 && volume.is_finite()) {
        return None;
    }
    // The part of the triangle at z >= NEAR (one clip of a triangle keeps at most 4 corners).
    let near = NEAR as f64;
    let corners = [a, b, c];
    let mut kept = [DVec3::ZERO; 4];
    let mut n = 0;
    for k in 0..3 {
        let (p, q) = (corners[k], corners[(k + 1) % 3]);
        if p.z >= near {
            kept[n] = p;
            n += 1;
        }
        if (p.z >= near) != (q.z >= near) {
            kept[n] = p.lerp(q, (near - p.z) / (q.z - p.z));
            n += 1;
        }
    }
    if n == 0 {
        return None;
    }
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for q in &kept[..n] {
        let (x, y) = view.pixel_of(*q);
        lo = lo.min(DVec2::new(x, y));
        hi = hi.max(DVec2::new(x, y));
    }
    // Pixels whose centres may lie in the box, widened a little: the per-pixel test is exact,
    // the box only has to be conservative.
    const SLACK: f64 = 1e-3;
    let range = |lo: f64, hi: f64, offset: f64, size: usize| -> Option<[u16; 2]> {
        let first = (lo - 0.5 - offset - SLACK).ceil().max(0.0);
        let last = (hi - 0.5 - offset + SLACK).floor().min(size as f64 - 1.0);
        (first <= last).then_some([first as u16, last as u16])
    };
    Some(Setup {
        edges,
        volume,
        clipped: corners.iter().any(|p| p.z < near),
        x: range(lo.x, hi.x, view.offset.x, view.width)?,
        y: range(lo.y, hi.y, view.offset.y, view.height)?,
        triangle: index,
    })
}

/// What a drawing shades its triangles with: one colour a vertex, the albedo maps of textured
/// triangles, and a glossy bake's light.
#[derive(Clone, Copy)]
struct Shading<'a> {
    triangles: &'a [[u32; 3]],
    colours: &'a [[f32; 3]],
    texturing: Option<&'a Texturing<'a>>,
    gloss: Option<&'a dyn ViewDependent>,
}

/// Draws the triangles `bin` (indices into `setups`) into one band of pixels starting at row
/// `y0`, its colours and coverage, with a depth buffer of the band's size. The nearest triangle
/// of each pixel is found first and shaded after ([`shade_band`]), so a pixel hidden later by a
/// nearer triangle costs no shading: a glossy lobe's is most of a frame's time.
fn draw_band(
    view: &View,
    film_x: &[f64],
    setups: &[Setup],
    bin: &[u32],
    shading: Shading,
    y0: usize,
    (pixels, coverage): (&mut [[f32; 3]], &mut [f32]),
) {
    let rows = pixels.len() / view.width;
    let mut depth = vec![f64::INFINITY; pixels.len()];
    // Per pixel, the nearest triangle's setup and its edge functions there.
    let mut nearest: Vec<Option<(u32, [f64; 3])>> = vec![None; pixels.len()];
    let near = NEAR as f64;
    for &si in bin {
        let s = &setups[si as usize];
        let [e0, e1, e2] = s.edges;
        let first_row = (s.y[0] as usize).max(y0);
        let last_row = (s.y[1] as usize).min(y0 + rows - 1);
        for y in first_row..=last_row {
            let fy = view.film_y(y);
            let r = [e0.y * fy + e0.z, e1.y * fy + e1.z, e2.y * fy + e2.z];
            let row = (y - y0) * view.width;
            let (x0, x1) = (s.x[0] as usize, s.x[1] as usize);
            for (x, &fx) in (x0..).zip(&film_x[x0..=x1]) {
                let w = [e0.x * fx + r[0], e1.x * fx + r[1], e2.x * fx + r[2]];
                let sum = w[0] + w[1] + w[2];
                if w[0] < 0.0 || w[1] < 0.0 || w[2] < 0.0 || sum <= 0.0 {
                    continue;
                }
                let z = s.volume / sum;
                let i = row + x;
                if (s.clipped && z < near) || z >= depth[i] {
                    continue;
                }
                depth[i] = z;
                nearest[i] = Some((si, w));
            }
        }
    }
    shade_band(
        view,
        film_x,
        setups,
        &nearest,
        shading,
        y0,
        (pixels, coverage),
    );
}

/// Shades each pixel of a band whose nearest triangle `nearest` holds (its setup and the edge
/// functions `w` at the pixel): the vertex colours interpolated by `w`, times the albedo map's
/// texel for a textured triangle, plus a glossy bake's light.
fn shade_band(
    view: &View,
    film_x: &[f64],
    setups: &[Setup],
    nearest: &[Option<(u32, [f64; 3])>],
    shading: Shading,
    y0: usize,
    (pixels, coverage): (&mut [[f32; 3]], &mut [f32]),
) {
    let Shading {
        triangles,
        colours,
        texturing,
        gloss,
    } = shading;
    for (i, hit) in nearest.iter().enumerate() {
        let Some((si, w)) = *hit else {
            continue;
        };
        let (x, y) = (i % view.width, y0 + i / view.width);
        let (fx, fy) = (film_x[x], view.film_y(y));
        let s = &setups[si as usize];
        let [e0, e1, e2] = s.edges;
        let sum = w[0] + w[1] + w[2];
        let tri = triangles[s.triangle as usize];
        let cs = tri.map(|v| DVec3::from(colours[v as usize].map(f64::from)));
        let c = (cs[0] * w[0] + cs[1] * w[1] + cs[2] * w[2]) / sum;
        // The triangle's map and corner coordinates, if textured.
        let mapped = texturing.and_then(|t| {
            let map = &t.maps[t.slot(tri[0] as usize)? as usize];
            Some((map, tri.map(|v| t.uvs[v as usize].as_dvec2())))
        });
        let albedo = match mapped {
            Some((map, uvs)) => {
                // The coordinate at a film position, interpolated on this triangle.
                let uv_at = |fx: f64, fy: f64| {
                    let d = DVec3::new(fx, fy, 1.0);
                    let w = [e0.dot(d), e1.dot(d), e2.dot(d)];
                    ((uvs[0] * w[0] + uvs[1] * w[1] + uvs[2] * w[2]) / (w[0] + w[1] + w[2]))
                        .as_vec2()
                };
                let uv = ((uvs[0] * w[0] + uvs[1] * w[1] + uvs[2] * w[2]) / sum).as_vec2();
                // Fine derivatives: the odd pixel of the quad's pair minus the even one.
                let (across, down) = (uv_at(view.film_x(x ^ 1), fy), uv_at(fx, view.film_y(y ^ 1)));
                let dx = if x % 2 == 0 { across - uv } else { uv - across };
                let dy = if y % 2 == 0 { down - uv } else { uv - down };
                map.sample(uv, map.lod(dx, dy))
            }
            None => Vec3::ONE,
        };
        let mut colour = c.as_vec3() * albedo;
        if let Some(g) = gloss {
            let dir = view.right * fx + view.up * fy + view.forward;
            let b = w.map(|x| x / sum);
            // SH transfer's truncated series can undershoot: radiance stays non-negative.
            colour = (colour + g.shade(tri, b, -dir.normalize()).as_vec3()).max(Vec3::ZERO);
        }
        pixels[i] = colour.to_array();
        coverage[i] = 1.0;
    }
}

/// Draws the mesh (`triangles` index `positions`; `colours` has one linear RGB colour per vertex)
/// as `camera` sees it: see the module documentation for what is drawn. Errors on an invalid
/// camera or mesh ([`check_mesh`]); never panics on input.
pub fn rasterize(
    camera: &Camera,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    colours: &[[f32; 3]],
) -> Result<Raster> {
    rasterize_with(
        camera,
        positions,
        triangles,
        colours,
        DrawOptions::samples(1),
    )
}

/// Samples a pixel that `prt relight` and the viewer draw a per-vertex bake with.
pub const DRAW_SAMPLES: u32 = 4;

/// The standard positions of 4 samples in a pixel (Vulkan's, Direct3D's and Metal's for 4x
/// multisampling: a rotated grid), from the pixel's centre, in pixels with y down.
pub const FOUR_SAMPLES: [[f32; 2]; 4] = [
    [-0.125, -0.375],
    [0.375, -0.125],
    [-0.375, 0.125],
    [0.125, 0.375],
];

/// 16 samples in a pixel, from its centre, in pixels with y down: one in each cell of a 4 × 4
/// grid, and one in each of the 16 columns and 16 rows of the pixel (the canonical arrangement
/// of Chiu, Shirley & Wang 1994's multi-jittered sampling, unjittered): sample `4i + j` at
/// column `4i + j` and row `4j + i`. For stills, where a highlight or an edge smaller than a
/// pixel needs more than [`FOUR_SAMPLES`] to reach the pixel's mean.
pub const SIXTEEN_SAMPLES: [[f32; 2]; 16] = {
    let mut out = [[0.0f32; 2]; 16];
    let mut k = 0;
    while k < 16 {
        let (i, j) = (k / 4, k % 4);
        out[k] = [
            (4 * i + j) as f32 / 16.0 + 1.0 / 32.0 - 0.5,
            (4 * j + i) as f32 / 16.0 + 1.0 / 32.0 - 0.5,
        ];
        k += 1;
    }
    out
};

/// Where `samples` samples lie in a pixel, from its centre: the centre alone for 1, the standard
/// rotated grid ([`FOUR_SAMPLES`]) for 4, [`SIXTEEN_SAMPLES`] for 16; any other count is an
/// error.
pub fn sample_offsets(samples: u32) -> Result<&'static [[f32; 2]]> {
    match samples {
        1 => Ok(&[[0.0, 0.0]]),
        4 => Ok(&FOUR_SAMPLES),
        16 => Ok(&SIXTEEN_SAMPLES),
        _ => Err(PrtError::invalid(
            "samples",
            format!("{samples} a pixel; 1, 4 or 16 are drawn"),
        )),
    }
}

/// What a drawn pixel takes beside its interpolated vertex colour, and the samples it is drawn
/// with ([`rasterize_with`]).
#[derive(Clone, Copy)]
pub struct DrawOptions<'a> {
    /// The albedo maps each pixel of a textured triangle is multiplied by (see the module
    /// documentation).
    pub texturing: Option<&'a Texturing<'a>>,
    /// A bake's view-dependent light, added per sample.
    pub gloss: Option<&'a dyn ViewDependent>,
    /// Samples a pixel ([`sample_offsets`]): 1, 4 or 16.
    pub samples: u32,
}

impl DrawOptions<'_> {
    /// `samples` samples a pixel, with neither albedo maps nor view-dependent light.
    pub fn samples(samples: u32) -> Self {
        DrawOptions {
            texturing: None,
            gloss: None,
            samples,
        }
    }
}

/// Draws as [`rasterize`] does, with what `options` adds: each sample is drawn as a pixel centre
/// would be (its own depth test, its colour, texture coordinate and view-dependent light at its
/// own ray, the texture's derivatives from the same sample of the quad's other pixels), and a
/// pixel is the mean of its samples, black where a sample draws nothing: RGB is then
/// premultiplied by the coverage, the fraction of the samples drawn. Errors as [`rasterize`]
/// does, on tables that do not fit the mesh, and on a sample count other than 1, 4 or 16.
pub fn rasterize_with(
    camera: &Camera,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    colours: &[[f32; 3]],
    options: DrawOptions,
) -> Result<Raster> {
    let DrawOptions {
        texturing,
        gloss,
        samples,
    } = options;
    let offsets = sample_offsets(samples)?;
    camera.validate()?;
    check_mesh(positions, triangles, Some(colours))?;
    if let Some(t) = texturing {
        t.check(positions.len())?;
    }
    if let Some(g) = gloss {
        g.check(positions.len())?;
    }
    let mut sum: Option<Raster> = None;
    for &offset in offsets {
        let r = draw(
            &View::new(camera, offset),
            positions,
            triangles,
            colours,
            texturing,
            gloss,
        )?;
        match &mut sum {
            None => sum = Some(r),
            Some(s) => {
                for (a, b) in s.image.pixels.iter_mut().zip(&r.image.pixels) {
                    for k in 0..3 {
                        a[k] += b[k];
                    }
                }
                for (a, b) in s.coverage.iter_mut().zip(&r.coverage) {
                    *a += b;
                }
            }
        }
    }
    let mut r = sum.expect("at least one sample");
    if offsets.len() > 1 {
        let scale = 1.0 / offsets.len() as f32;
        for p in &mut r.image.pixels {
            *p = p.map(|v| v * scale);
        }
        for c in &mut r.coverage {
            *c *= scale;
        }
    }
    Ok(r)
}

/// Pixels of a drawing from which its buffers are checked against the memory this process can
/// have (reading /proc for every small frame would weigh on its time).
const CHECKED_PIXELS: usize = 1 << 20;

/// `n` copies of `value` for a buffer of a drawing (`what`): from [`CHECKED_PIXELS`] on, an
/// error rather than an abort when this process cannot have them.
fn filled<T: Clone>(what: &str, n: usize, value: T) -> Result<Vec<T>> {
    if n < CHECKED_PIXELS {
        return Ok(vec![value; n]);
    }
    crate::files::try_filled("camera.width/height", what, n, value)
}

/// Draws a checked mesh at `view`'s sample of every pixel; an error when this process cannot
/// have the image's memory.
fn draw(
    view: &View,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    colours: &[[f32; 3]],
    texturing: Option<&Texturing>,
    gloss: Option<&dyn ViewDependent>,
) -> Result<Raster> {
    let (w, h) = (view.width, view.height);
    let setups: Vec<Setup> = triangles
        .par_iter()
        .enumerate()
        .filter_map(|(i, &tri)| setup(view, positions, tri, i as u32))
        .collect();
    let bands = h.div_ceil(BAND_ROWS);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (i, s) in setups.iter().enumerate() {
        for bin in &mut bins[s.y[0] as usize / BAND_ROWS..=s.y[1] as usize / BAND_ROWS] {
            bin.push(i as u32);
        }
    }
    let film_x: Vec<f64> = (0..w).map(|x| view.film_x(x)).collect();
    let what = format!("a {w} x {h} drawing");
    let mut image = Image {
        width: w,
        height: h,
        pixels: filled(&what, w * h, [0.0f32; 3])?,
    };
    let mut coverage = filled(&what, w * h, 0.0f32)?;
    image
        .pixels
        .par_chunks_mut(w * BAND_ROWS)
        .zip(coverage.par_chunks_mut(w * BAND_ROWS))
        .zip(&bins)
        .enumerate()
        .for_each(|(band, ((pixels, cov), bin))| {
            let shading = Shading {
                triangles,
                colours,
                texturing,
                gloss,
            };
            draw_band(
                view,
                &film_x,
                &setups,
                bin,
                shading,
                band * BAND_ROWS,
                (pixels, cov),
            );
        });
    Ok(Raster { image, coverage })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative error of an affine colour interpolated by the rasteriser against the colour's
    /// function at the test's own ray hit: the vertex colours and the pixels are f32 and the
    /// camera ray is built in f32, so the two hits and values agree to a few f32 ulps (~1e-6).
    const AFFINE_COLOUR_REL: f64 = 1e-4;

    fn camera(eye: Vec3, target: Vec3, width: u32, height: u32) -> Camera {
        Camera {
            eye,
            target,
            up: Vec3::Y,
            fov_y_deg: 50.0,
            width,
            height,
        }
    }

    /// The nearest front-facing hit of pixel (x, y)'s [`Camera::ray`] at a forward distance of
    /// at least [`NEAR`], by plain ray casting: (triangle, hit point).
    fn ray_cast(
        cam: &Camera,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        x: usize,
        y: usize,
    ) -> Option<(usize, DVec3)> {
        ray_cast_at(cam, positions, triangles, x as f32 + 0.5, y as f32 + 0.5)
    }

    /// [`ray_cast`] of the ray through film position (`px`, `py`), in pixels.
    fn ray_cast_at(
        cam: &Camera,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        px: f32,
        py: f32,
    ) -> Option<(usize, DVec3)> {
        let ray = cam.ray(px, py);
        let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
        let forward = cam.frame().0.as_dvec3();
        let mut best: Option<(usize, DVec3, f64)> = None;
        for (t, tri) in triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|v| positions[v as usize].as_dvec3());
            let n = (b - a).cross(c - a);
            if n.dot(o - a) <= 0.0 || n.dot(d) == 0.0 {
                continue;
            }
            let dist = n.dot(a - o) / n.dot(d);
            let p = o + d * dist;
            let inside = [(a, b), (b, c), (c, a)]
                .iter()
                .all(|&(u, v)| (v - u).cross(p - u).dot(n) >= 0.0);
            let depth = dist * d.dot(forward);
            if inside && dist > 0.0 && depth >= NEAR as f64 && best.is_none_or(|b| depth < b.2) {
                best = Some((t, p, depth));
            }
        }
        best.map(|(t, p, _)| (t, p))
    }

    /// A few triangles at several depths and slants, two overlapping, one crossing the eye plane
    /// (the eye is at z = 3 looking down −z), and a quad.
    fn scene() -> (Camera, Vec<Vec3>, Vec<[u32; 3]>) {
        let cam = camera(Vec3::new(0.1, 0.4, 3.0), Vec3::new(0.0, 0.0, 0.0), 48, 32);
        let positions = vec![
            // A slanted triangle.
            Vec3::new(-1.3, -0.7, 0.2),
            Vec3::new(0.9, -0.9, -0.8),
            Vec3::new(0.1, 1.1, -0.3),
            // One in front of it, overlapping.
            Vec3::new(-0.6, -0.2, 1.0),
            Vec3::new(0.7, 0.1, 0.9),
            Vec3::new(-0.2, 0.8, 1.3),
            // Ground reaching behind the eye.
            Vec3::new(-6.0, -0.5, 8.0),
            Vec3::new(6.0, -0.5, 8.0),
            Vec3::new(0.3, -0.5, -9.0),
            // A tilted quad: two triangles sharing a diagonal.
            Vec3::new(0.8, -0.6, -0.5),
            Vec3::new(1.8, -0.4, -1.0),
            Vec3::new(1.7, 0.7, -0.9),
            Vec3::new(0.9, 0.5, -0.4),
        ];
        let triangles = vec![[0, 1, 2], [3, 4, 5], [6, 7, 8], [9, 10, 11], [9, 11, 12]];
        (cam, positions, triangles)
    }

    #[test]
    fn a_flat_colour_draws_exactly_where_rays_hit() {
        let (cam, positions, triangles) = scene();
        let colour = [0.3, 1.7, 0.05];
        let r = rasterize(&cam, &positions, &triangles, &vec![colour; positions.len()]).unwrap();
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut drawn = 0;
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let hit = ray_cast(&cam, &positions, &triangles, x, y).is_some();
                assert_eq!(r.coverage[i] == 1.0, hit, "pixel ({x}, {y})");
                let want = if hit { colour } else { [0.0; 3] };
                assert_eq!(r.image.pixels[i], want, "pixel ({x}, {y})");
                assert!(r.coverage[i] == 0.0 || r.coverage[i] == 1.0);
                drawn += hit as usize;
            }
        }
        assert!(drawn > w * h / 4 && drawn < w * h, "{drawn} pixels drawn");
    }

    #[test]
    fn an_affine_colour_is_interpolated_at_the_hit_point() {
        let (cam, positions, triangles) = scene();
        let m = glam::DMat3::from_cols_array(&[0.3, -0.2, 0.5, 0.1, 0.4, -0.3, -0.25, 0.15, 0.2]);
        let offset = DVec3::new(2.0, 1.5, 2.5);
        let colour = |p: DVec3| m * p + offset;
        let colours: Vec<[f32; 3]> = positions
            .iter()
            .map(|p| colour(p.as_dvec3()).as_vec3().to_array())
            .collect();
        let r = rasterize(&cam, &positions, &triangles, &colours).unwrap();
        let w = cam.width as usize;
        let mut seen = vec![0; triangles.len()];
        for (i, px) in r.image.pixels.iter().enumerate() {
            let hit = ray_cast(&cam, &positions, &triangles, i % w, i / w);
            assert_eq!(r.coverage[i] == 1.0, hit.is_some(), "pixel {i}");
            if let Some((t, p)) = hit {
                seen[t] += 1;
                let want = colour(p);
                for k in 0..3 {
                    let err = (px[k] as f64 - want[k]).abs() / want[k].abs();
                    assert!(
                        err < AFFINE_COLOUR_REL,
                        "pixel {i}: {px:?}, expected {want}"
                    );
                }
            }
        }
        assert!(seen.iter().all(|&n| n > 20), "pixels per triangle {seen:?}");
    }

    #[test]
    fn several_samples_draw_the_mean_of_what_rays_through_them_hit() {
        let (cam, positions, triangles) = scene();
        let colour = |p: DVec3| DVec3::new(1.0 + 0.2 * p.x, 1.5 - 0.3 * p.y, 1.2 + 0.1 * p.z);
        let colours: Vec<[f32; 3]> = positions
            .iter()
            .map(|p| colour(p.as_dvec3()).as_vec3().to_array())
            .collect();
        let w = cam.width as usize;
        let draw = |samples| {
            let options = DrawOptions::samples(samples);
            rasterize_with(&cam, &positions, &triangles, &colours, options)
        };
        for samples in [4, 16] {
            let offsets = sample_offsets(samples).unwrap();
            let r = draw(samples).unwrap();
            let mut partial = 0;
            for (i, px) in r.image.pixels.iter().enumerate() {
                let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                let hits: Vec<DVec3> = offsets
                    .iter()
                    .filter_map(|o| ray_cast_at(&cam, &positions, &triangles, x + o[0], y + o[1]))
                    .map(|(_, p)| p)
                    .collect();
                let n = offsets.len();
                assert_eq!(r.coverage[i], hits.len() as f32 / n as f32, "pixel {i}");
                partial += (1..n).contains(&hits.len()) as usize;
                let want = hits.iter().map(|&p| colour(p)).sum::<DVec3>() / n as f64;
                for k in 0..3 {
                    let err = (px[k] as f64 - want[k]).abs() / want[k].abs().max(1.0);
                    assert!(
                        err < AFFINE_COLOUR_REL,
                        "{samples} samples, pixel {i}: {px:?}, expected {want}"
                    );
                }
            }
            // The edges are antialiased: many pixels are partly covered.
            assert!(
                partial > 40,
                "{samples} samples: {partial} partly covered pixels"
            );
        }
        // One sample is the plain raster.
        let one = draw(1).unwrap();
        assert_eq!(
            one,
            rasterize(&cam, &positions, &triangles, &colours).unwrap()
        );
        for samples in [0, 2, 3, 8, 32] {
            let e = draw(samples).unwrap_err();
            assert!(e.to_string().contains("samples"), "{e}");
        }
    }

    /// The 16 samples lie one to each cell of a 4 × 4 grid and one to each of the pixel's 16
    /// columns and rows, symmetric about its centre.
    #[test]
    fn sixteen_samples_stratify_the_pixel_by_cells_columns_and_rows() {
        let (mut cells, mut columns, mut rows) = ([0; 16], [0; 16], [0; 16]);
        let mut mean = [0.0f32; 2];
        for [x, y] in SIXTEEN_SAMPLES {
            assert!(x.abs() < 0.5 && y.abs() < 0.5, "({x}, {y})");
            let fine = |v: f32| ((v + 0.5) * 16.0).floor() as usize;
            let (c, r) = (fine(x), fine(y));
            cells[(r / 4) * 4 + c / 4] += 1;
            columns[c] += 1;
            rows[r] += 1;
            mean = [mean[0] + x / 16.0, mean[1] + y / 16.0];
        }
        assert_eq!((cells, columns, rows), ([1; 16], [1; 16], [1; 16]));
        assert!(mean[0].abs() < 1e-6 && mean[1].abs() < 1e-6, "{mean:?}");
    }

    /// More samples come nearer the share of a partly covered pixel that a surface covers: over
    /// the test scene's edge pixels, 16 samples are nearer a 32 × 32 grid of rays than 4 are
    /// (measured: a squared error of 0.14 against 0.76 over 678 pixels).
    #[test]
    fn sixteen_samples_come_nearer_the_covered_share_than_four() {
        let (cam, positions, triangles) = scene();
        let colours = vec![[1.0f32; 3]; positions.len()];
        let w = cam.width as usize;
        let draw = |samples| {
            rasterize_with(
                &cam,
                &positions,
                &triangles,
                &colours,
                DrawOptions::samples(samples),
            )
            .unwrap()
        };
        let (four, sixteen) = (draw(4), draw(16));
        let (mut e4, mut e16, mut edges) = (0.0f64, 0.0f64, 0);
        for i in 0..four.coverage.len() {
            if four.coverage[i] == 1.0 && sixteen.coverage[i] == 1.0 {
                continue;
            }
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let grid = 32;
            let hit = (0..grid * grid)
                .filter(|k| {
                    let (sx, sy) = ((k % grid) as f32 + 0.5, (k / grid) as f32 + 0.5);
                    let (px, py) = (x + sx / grid as f32, y + sy / grid as f32);
                    ray_cast_at(&cam, &positions, &triangles, px, py).is_some()
                })
                .count() as f64
                / (grid * grid) as f64;
            e4 += (four.coverage[i] as f64 - hit).powi(2);
            e16 += (sixteen.coverage[i] as f64 - hit).powi(2);
            edges += 1;
        }
        eprintln!("{edges} edge pixels: squared error {e4} with 4 samples, {e16} with 16");
        assert!(edges > 40, "{edges} edge pixels");
        assert!(
            e16 < 0.5 * e4,
            "16 samples {e16}, 4 samples {e4} over {edges} pixels"
        );
    }

    #[test]
    fn back_faces_are_culled_and_their_twins_drawn() {
        let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 16, 16);
        let positions = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let colours = [[1.0; 3]; 3];
        // Counter-clockwise seen from +z: the normal +z points at the eye.
        let front = rasterize(&cam, &positions, &[[0, 1, 2]], &colours).unwrap();
        let back = rasterize(&cam, &positions, &[[0, 2, 1]], &colours).unwrap();
        assert!(front.coverage.iter().sum::<f32>() > 30.0);
        assert!(back.coverage.iter().all(|&c| c == 0.0));
        assert!(back.image.pixels.iter().all(|p| *p == [0.0; 3]));
        // A two-sided surface: the side facing the eye shows, whichever comes first.
        let colours = [[1.0; 3], [1.0; 3], [1.0; 3], [2.0; 3], [2.0; 3], [2.0; 3]];
        let doubled: Vec<Vec3> = positions.iter().chain(&positions).copied().collect();
        for order in [[[0, 1, 2], [3, 5, 4]], [[3, 5, 4], [0, 1, 2]]] {
            let r = rasterize(&cam, &doubled, &order, &colours).unwrap();
            assert_eq!(r.coverage, front.coverage);
            assert_eq!(r.image, front.image);
        }
    }

    #[test]
    fn a_triangle_through_the_eye_plane_draws_only_its_part_in_front() {
        // Looking horizontally over a ground triangle that passes under and behind the eye: it
        // can only show below the horizon (a triangle projected through the eye plane would wrap
        // around above it).
        let cam = camera(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, -1.0), 40, 30);
        let positions = [
            Vec3::new(-8.0, 0.0, 6.0),
            Vec3::new(8.0, 0.0, 6.0),
            Vec3::new(0.5, 0.0, -12.0),
        ];
        let r = rasterize(&cam, &positions, &[[0, 1, 2]], &[[1.0; 3]; 3]).unwrap();
        let w = cam.width as usize;
        for (i, &c) in r.coverage.iter().enumerate() {
            let hit = ray_cast(&cam, &positions, &[[0, 1, 2]], i % w, i / w).is_some();
            assert_eq!(c == 1.0, hit, "pixel ({}, {})", i % w, i / w);
            if i / w < 15 {
                assert_eq!(c, 0.0, "above the horizon at pixel {i}");
            }
        }
        // Every pixel of the lowest row sees the ground, which runs under the eye.
        assert!(r.coverage[29 * w..].iter().all(|&c| c == 1.0));
        // Behind the eye altogether: nothing.
        let behind = positions.map(|p| Vec3::new(p.x, p.y, p.z.abs() + 0.5));
        let r = rasterize(&cam, &behind, &[[0, 2, 1]], &[[1.0; 3]; 3]).unwrap();
        assert!(r.coverage.iter().all(|&c| c == 0.0));
    }

    #[test]
    fn hits_nearer_than_the_near_plane_are_not_drawn() {
        // A floor 0.2 mm under the eye: the rows that see it within NEAR of the eye (the bottom
        // ones, looking steeply down) stay empty, those nearer the horizon see it.
        let cam = camera(Vec3::ZERO, Vec3::NEG_Z, 20, 40);
        let y = -2e-4;
        let positions = [
            Vec3::new(-5.0, y, 5.0),
            Vec3::new(5.0, y, 5.0),
            Vec3::new(0.0, y, -50.0),
        ];
        let r = rasterize(&cam, &positions, &[[0, 1, 2]], &[[1.0; 3]; 3]).unwrap();
        let rows: Vec<f32> = r.coverage.chunks(20).map(|row| row.iter().sum()).collect();
        assert!(rows[..20].iter().all(|&n| n == 0.0), "{rows:?}");
        // Row 28 looks down by 0.198 per unit ahead, meeting the floor 1.01 mm ahead; row 29 by
        // 0.221, 0.90 mm ahead.
        assert!(rows[20..29].iter().all(|&n| n == 20.0), "{rows:?}");
        assert!(rows[29..].iter().all(|&n| n == 0.0), "{rows:?}");
        // Rolled, the near plane crosses the film aslant, through the triangle's bounding box.
        let rolled = Camera {
            up: Vec3::new(0.5, 1.0, 0.0),
            ..cam
        };
        for cam in [cam, rolled] {
            let r = rasterize(&cam, &positions, &[[0, 1, 2]], &[[1.0; 3]; 3]).unwrap();
            for (i, &c) in r.coverage.iter().enumerate() {
                let hit = ray_cast(&cam, &positions, &[[0, 1, 2]], i % 20, i / 20).is_some();
                assert_eq!(c == 1.0, hit, "pixel ({}, {})", i % 20, i / 20);
            }
        }
    }

    /// A quad's two triangles.
    type Quad = [[u32; 3]; 2];

    /// A 24² camera looking down −z at two square quads, a large one at z = 0 (vertices 0–3)
    /// and a small one in front of it at z = 0.5 (vertices 4–7), each as two triangles.
    fn two_quads() -> (Camera, Vec<Vec3>, Quad, Quad) {
        let cam = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 24, 24);
        let quad =
            |z: f32, s: f32| [(-s, -s), (s, -s), (s, s), (-s, s)].map(|(x, y)| Vec3::new(x, y, z));
        let positions: Vec<Vec3> = quad(0.0, 1.0).into_iter().chain(quad(0.5, 0.5)).collect();
        (
            cam,
            positions,
            [[0, 1, 2], [0, 2, 3]],
            [[4, 5, 6], [4, 6, 7]],
        )
    }

    #[test]
    fn the_nearest_hit_wins_whatever_the_order() {
        let (cam, positions, far, near) = two_quads();
        let colours: Vec<[f32; 3]> = (0..8).map(|i| [(i / 4) as f32 + 1.0; 3]).collect();
        let a = rasterize(&cam, &positions, &[far, near].concat(), &colours).unwrap();
        let b = rasterize(&cam, &positions, &[near, far].concat(), &colours).unwrap();
        assert_eq!(a, b);
        // The centre sees the near quad, a corner the far one.
        assert_eq!(a.image.pixels[12 * 24 + 12], [2.0; 3]);
        assert_eq!(a.image.pixels[5 * 24 + 5], [1.0; 3]);
        assert!(a.image.pixels.iter().filter(|p| p[0] == 2.0).count() > 16);
    }

    /// A view-dependent light that counts the points it shades and adds the triangle's first
    /// vertex index.
    struct Counting(std::sync::atomic::AtomicUsize);

    impl ViewDependent for Counting {
        fn check(&self, _: usize) -> Result<()> {
            Ok(())
        }

        fn shade(&self, tri: [u32; 3], _: [f64; 3], _: DVec3) -> DVec3 {
            self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            DVec3::splat(tri[0] as f64)
        }
    }

    #[test]
    fn a_pixel_is_shaded_once_by_its_nearest_triangle_whatever_the_order() {
        let (cam, positions, far, near) = two_quads();
        let colours = vec![[0.0f32; 3]; 8];
        for order in [[far, near].concat(), [near, far].concat()] {
            let gloss = Counting(0.into());
            let glossy = DrawOptions {
                gloss: Some(&gloss),
                ..DrawOptions::samples(1)
            };
            let r = rasterize_with(&cam, &positions, &order, &colours, glossy).unwrap();
            let covered = r.coverage.iter().filter(|&&c| c == 1.0).count();
            // The far quad drawn first is hidden in the centre: its shading there is not asked.
            assert_eq!(gloss.0.into_inner(), covered);
            assert_eq!(r.image.pixels[12 * 24 + 12], [4.0; 3]);
            assert_eq!(r.image.pixels[5 * 24 + 5], [0.0; 3]);
        }
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let (cam, positions, triangles) = scene();
        let colours = vec![[1.0; 3]; positions.len()];
        let err = |p: &[Vec3], t: &[[u32; 3]], c: &[[f32; 3]], cam: &Camera| {
            rasterize(cam, p, t, c).unwrap_err().to_string()
        };
        let e = err(
            &positions,
            &[[0, 1, positions.len() as u32]],
            &colours,
            &cam,
        );
        assert!(e.contains("triangles[0]"), "{e}");
        let e = err(&positions, &triangles, &colours[1..], &cam);
        assert!(e.contains("colours"), "{e}");
        let mut nan = positions.clone();
        nan[4].y = f32::NAN;
        let e = err(&nan, &triangles, &colours, &cam);
        assert!(e.contains("positions[4]"), "{e}");
        let mut inf = colours.clone();
        inf[2][1] = f32::INFINITY;
        let e = err(&positions, &triangles, &inf, &cam);
        assert!(e.contains("colours[2]"), "{e}");
        let bad_cam = Camera {
            width: 0,
            ..cam.clone()
        };
        let e = err(&positions, &triangles, &colours, &bad_cam);
        assert!(e.contains("width"), "{e}");
        // Degenerate triangles and an empty mesh draw nothing.
        let r = rasterize(&cam, &positions, &[[0, 0, 1], [2, 2, 2]], &colours).unwrap();
        assert!(r.coverage.iter().all(|&c| c == 0.0));
        let r = rasterize(&cam, &[], &[], &[]).unwrap();
        assert_eq!(r.coverage.len(), 48 * 32);
    }

    #[test]
    fn clip_space_puts_each_hit_on_its_pixel_centre() {
        let cam = Camera {
            up: Vec3::new(0.2, 1.0, 0.1),
            ..camera(Vec3::new(1.0, 2.0, 5.0), Vec3::new(-0.5, 0.3, 0.0), 64, 40)
        };
        let forward = cam.frame().0.as_dvec3();
        // With a sample offset, the ray through the pixel's sample lands on its centre.
        for offset in std::iter::once([0.0; 2]).chain(FOUR_SAMPLES) {
            let m = clip_from_world(&cam, offset).as_dmat4();
            for (x, y, dist) in [(0, 0, 0.01), (63, 39, 3.0), (17, 30, 12.0), (40, 5, 100.0)] {
                let ray = cam.ray(x as f32 + 0.5 + offset[0], y as f32 + 0.5 + offset[1]);
                let p = ray.origin.as_dvec3() + ray.dir.as_dvec3() * dist;
                let clip = m * p.extend(1.0);
                let ndc = clip.truncate() / clip.w;
                let want_x = 2.0 * (x as f64 + 0.5) / 64.0 - 1.0;
                let want_y = 1.0 - 2.0 * (y as f64 + 0.5) / 40.0;
                // f32 rounding of the matrix and of the ray, the eye offset's over the forward
                // distance.
                let tol =
                    4.0 * f32::EPSILON as f64 * (1.0 + (1.0 + cam.eye.length() as f64) / clip.w);
                assert!(
                    (ndc.x - want_x).abs() < tol,
                    "{ndc} at ({x}, {y}), {offset:?}"
                );
                assert!(
                    (ndc.y - want_y).abs() < tol,
                    "{ndc} at ({x}, {y}), {offset:?}"
                );
                let depth = NEAR as f64 / (dist * ray.dir.as_dvec3().dot(forward));
                assert!((ndc.z - depth).abs() < tol * depth, "{} vs {depth}", ndc.z);
            }
        }
    }
}
