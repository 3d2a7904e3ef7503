//! A per-vertex bake seen from any camera: the relit image of such a bake holds one colour per
//! vertex (vertex `v` is pixel `v`), which [`crate::draw::raster`] draws with Gouraud shading and
//! a depth test, a glossy bake's lobe evaluated per pixel for the direction to the eye, over the
//! environment behind. The orbit
//! camera turns the bake's own camera about its target; every camera a user moves is made upright
//! by [`moved_camera`].

use glam::{Quat, Vec3};

use crate::draw::background::{composite, environment_behind_camera};
use crate::env::envmap::{EnvMap, EnvRotation};
use crate::error::{PrtError, Result};
use crate::output::film::Image;

use crate::draw::lobe::lights::WithLights;
use crate::draw::lobe::{Lobe, lit_columns};
use crate::draw::raster::{DrawOptions, Raster, rasterize_with};
use crate::draw::sh_gloss::ShGloss;
use crate::draw::shading::{GlossMesh, Texturing, ViewDependent};
use crate::math::cube_pyramid::CubePyramid;
use crate::relight::sh_transfer::ShTransfer;
use crate::scene::Camera;
use crate::scene::tessellate::VertexMesh;
use crate::store::transport::Transport;

/// The mesh of a per-vertex bake, or an error saying that the file is a fixed view.
pub fn mesh_of(t: &Transport) -> Result<&VertexMesh> {
    t.mesh().ok_or_else(|| {
        PrtError::invalid(
            "camera",
            "this transport is a per-pixel bake of one fixed view: its camera cannot move (bake \
             the scene with --per-vertex to draw it from any camera)",
        )
    })
}

/// The camera a per-vertex bake was made with (the scene's), at the scene's image size.
pub fn bake_camera(t: &Transport) -> Result<Camera> {
    let pv = t
        .meta
        .per_vertex
        .as_ref()
        .ok_or_else(|| PrtError::invalid("camera", "not a per-vertex bake"))?;
    let c = &t.meta.camera;
    let camera = Camera {
        eye: Vec3::from(c.eye),
        target: Vec3::from(c.target),
        up: Vec3::from(c.up),
        fov_y_deg: c.fov_y_deg,
        width: pv.image[0],
        height: pv.image[1],
    };
    camera.validate()?;
    Ok(camera)
}

/// The world's up axis (+Y, see [`crate::conventions`]): the up of a moved camera unless another
/// is asked for.
pub const WORLD_UP: Vec3 = Vec3::Y;

/// Below this sine of the angle between the view and the up asked for, a moved camera takes
/// another axis as its up: the film's roll would hang on rounding.
const ALONG_UP_SIN: f32 = 1e-3;

/// The camera `base` moved to look from `eye` at `target`, upright: its up is `up` (default
/// [`WORLD_UP`]), or when the view runs along that, the axis least aligned with it (−Z for +Y,
/// the top of the image towards −Z). The field of view and the image size stay `base`'s; `base`'s
/// own up, which may be tilted, is not kept. Every camera a user moves is made here: `--eye`,
/// `--target` and `--up` of `prt relight`, `prt reference`, `prt bench` and `prt gloss`, the
/// viewer's orbit ([`orbit`], [`Orbit::camera`]).
pub fn moved_camera(base: &Camera, eye: Vec3, target: Vec3, up: Option<Vec3>) -> Camera {
    Camera {
        eye,
        target,
        up: upright(target - eye, up.unwrap_or(WORLD_UP)),
        ..base.clone()
    }
}

/// The up of a camera looking along `view` with `up` asked for, as [`moved_camera`] picks it.
pub fn upright(view: Vec3, up: Vec3) -> Vec3 {
    let up = up.normalize_or(WORLD_UP);
    if view.normalize_or_zero().cross(up).length() > ALONG_UP_SIN {
        return up;
    }
    [Vec3::NEG_Z, Vec3::X, Vec3::Y]
        .into_iter()
        .min_by(|a, b| a.dot(up).abs().total_cmp(&b.dot(up).abs()))
        .unwrap_or(Vec3::NEG_Z)
}

/// The highest elevation of an orbiting eye above (or below) its target, degrees: short of the
/// pole, where the up axis would be undefined.
pub const MAX_ELEVATION_DEG: f32 = 85.0;

/// The elevation of `camera`'s eye above its target, degrees.
pub fn elevation_deg(camera: &Camera) -> f32 {
    let offset = camera.eye - camera.target;
    (offset.y / offset.length().max(f32::MIN_POSITIVE))
        .clamp(-1.0, 1.0)
        .asin()
        .to_degrees()
}

/// `camera` turned about its target: the eye swings `azimuth_deg` about the up axis (+Y) and
/// rises `elevation_deg` (kept within [`MAX_ELEVATION_DEG`] of the horizon), at the same
/// distance, upright ([`moved_camera`]).
pub fn orbit(camera: &Camera, azimuth_deg: f32, elevation_deg: f32) -> Camera {
    let offset = camera.eye - camera.target;
    let distance = offset.length();
    let flat = Vec3::new(offset.x, 0.0, offset.z);
    let elevation = (self::elevation_deg(camera) + elevation_deg)
        .clamp(-MAX_ELEVATION_DEG, MAX_ELEVATION_DEG)
        .to_radians();
    let heading = Quat::from_rotation_y(azimuth_deg.to_radians()) * flat.normalize_or(Vec3::Z);
    let dir = heading * elevation.cos() + Vec3::Y * elevation.sin();
    moved_camera(camera, camera.target + dir * distance, camera.target, None)
}

/// Where an orbiting camera is, relative to the bake's camera: turned `azimuth_deg` about the
/// up axis and raised `elevation_deg` about the target (see [`orbit`]), at `distance` times the
/// bake camera's distance from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// Turn about the up axis (+Y), degrees.
    pub azimuth_deg: f32,
    /// Rise of the eye about the target above the bake camera's elevation, degrees.
    pub elevation_deg: f32,
    /// Distance from the target, as a multiple of the bake camera's (within
    /// [`Orbit::DISTANCE`]).
    pub distance: f32,
}

impl Default for Orbit {
    /// The bake's own camera.
    fn default() -> Self {
        Orbit {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            distance: 1.0,
        }
    }
}

impl Orbit {
    /// Nearest and farthest distance, as a multiple of the bake camera's.
    pub const DISTANCE: std::ops::RangeInclusive<f32> = 0.1..=10.0;

    /// Brings the angles and the distance into range: the azimuth into [-180, 180), the
    /// elevation into [-180, 180] (the camera keeps [`orbit`]'s 85° from the poles), the distance
    /// into [`Orbit::DISTANCE`]; a value that is not finite goes back to the default. Returns
    /// whether anything changed.
    pub fn clamp(&mut self) -> bool {
        let before = *self;
        let d = Orbit::default();
        let finite = |v: f32, or: f32| if v.is_finite() { v } else { or };
        self.azimuth_deg =
            (finite(self.azimuth_deg, d.azimuth_deg) + 180.0).rem_euclid(360.0) - 180.0;
        self.elevation_deg = finite(self.elevation_deg, d.elevation_deg).clamp(-180.0, 180.0);
        self.distance = finite(self.distance, d.distance)
            .clamp(*Orbit::DISTANCE.start(), *Orbit::DISTANCE.end());
        *self != before
    }

    /// The elevations that move the eye of `base`: beyond them [`orbit`] stops at
    /// [`MAX_ELEVATION_DEG`].
    pub fn elevation_range(base: &Camera) -> std::ops::RangeInclusive<f32> {
        let e = elevation_deg(base);
        (-MAX_ELEVATION_DEG - e)..=(MAX_ELEVATION_DEG - e)
    }

    /// The camera this orbit makes of `base`.
    pub fn camera(&self, base: &Camera) -> Camera {
        let turned = orbit(base, self.azimuth_deg, self.elevation_deg);
        let eye = turned.target + (turned.eye - turned.target) * self.distance;
        moved_camera(&turned, eye, turned.target, None)
    }
}

impl std::str::FromStr for Orbit {
    type Err = PrtError;

    /// `AZIMUTH,ELEVATION` in degrees, or `AZIMUTH,ELEVATION,DISTANCE` with the distance a
    /// multiple of the bake camera's (within [`Orbit::DISTANCE`]).
    fn from_str(s: &str) -> Result<Orbit> {
        let bad = |why: &str| PrtError::invalid("orbit", format!("`{s}`: {why}"));
        let v: Vec<f32> = s
            .split(',')
            .map(|x| x.trim().parse::<f32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| bad("expected AZIMUTH,ELEVATION[,DISTANCE] in degrees"))?;
        let (azimuth_deg, elevation_deg, distance) = match v[..] {
            [a, e] => (a, e, 1.0),
            [a, e, d] => (a, e, d),
            _ => {
                return Err(bad(
                    "expected two or three numbers, AZIMUTH,ELEVATION[,DISTANCE]",
                ));
            }
        };
        if !v.iter().all(|x| x.is_finite()) {
            return Err(bad("the numbers must be finite"));
        }
        if !Orbit::DISTANCE.contains(&distance) {
            return Err(bad(&format!(
                "the distance must be {} to {} times the bake camera's",
                Orbit::DISTANCE.start(),
                Orbit::DISTANCE.end()
            )));
        }
        let mut orbit = Orbit {
            azimuth_deg,
            elevation_deg,
            distance,
        };
        orbit.clamp();
        Ok(orbit)
    }
}

/// The vertex colours in a per-vertex bake's relit image: each vertex's pixel, its diffuse
/// light.
pub fn vertex_colours<'a>(t: &Transport, relit: &'a Image) -> Result<&'a [[f32; 3]]> {
    let v = mesh_of(t)?.vertex_count();
    relit.pixels.get(..v).ok_or_else(|| {
        PrtError::invalid(
            "relit image",
            format!("{} pixels for {v} vertices", relit.pixels.len()),
        )
    })
}

/// Draws a per-vertex bake relit to `relit` as `camera` sees it, on the CPU: its vertex colours
/// (its diffuse light; see [`vertex_colours`]), its textured materials multiplied by their
/// albedo maps per pixel, the glossy light of a bake with visibility drawn per pixel from `light`
/// (the pyramid of the light the relight used, [`crate::relight::Terms::cube`]; an error without
/// it), with `behind` (the
/// environment and its turn) where no surface is drawn, with `samples` samples a pixel (see
/// [`crate::draw::raster::rasterize_with`]). Also gives the coverage, for masks and tone
/// mapping.
pub fn draw_relit(
    t: &Transport,
    relit: &Image,
    light: Option<&CubePyramid>,
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
    samples: u32,
) -> Result<Raster> {
    draw_relit_lit(t, relit, (light, &[]), camera, behind, samples)
}

/// [`draw_relit`] with the local lights the relight lit: `lights` is the pyramid of the
/// environment's light and the weight of each light column
/// ([`crate::scene::light_mix::LightMix::weights`], empty without local lights). A glossy bake
/// with visibility draws each lit column's highlight per pixel ([`crate::draw::lobe::lights`]);
/// the columns' diffuse light is in `relit` already.
pub fn draw_relit_lit(
    t: &Transport,
    relit: &Image,
    (light, weights): (Option<&CubePyramid>, &[[f32; 3]]),
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
    samples: u32,
) -> Result<Raster> {
    let mesh = mesh_of(t)?;
    let colours = vertex_colours(t, relit)?;
    if let Some(gloss) = GlossMesh::of(mesh) {
        let light = light.ok_or_else(|| {
            PrtError::invalid(
                "light",
                "a glossy bake with visibility draws its highlights from the light: it needs \
                 the light the relight used",
            )
        })?;
        let lobe = lit_lobe(t, (gloss, &mesh.positions), light, weights);
        return draw_mesh(mesh, colours, Some(&lobe), camera, behind, samples);
    }
    draw_mesh(mesh, colours, None, camera, behind, samples)
}

/// Draws a per-vertex bake with visibility relit to `relit` as [`draw_relit`] does, its glossy
/// light by SH glossy transfer instead of the lobe per pixel: `transfer` (made from the bake's
/// visibility) takes `light` (the pyramid of the light the relight used), projected on SH, to each
/// glossy vertex's transferred radiance, which each pixel reflects through its material's lobe
/// ([`crate::draw::sh_gloss`]); the local light columns of `weights` add their highlights per
/// pixel as [`draw_relit_lit`] draws them. An error for a bake without visibility.
pub fn draw_sh_glossy(
    t: &Transport,
    relit: &Image,
    (light, weights): (&CubePyramid, &[[f32; 3]]),
    transfer: &ShTransfer,
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
    samples: u32,
) -> Result<Raster> {
    let mesh = mesh_of(t)?;
    let gloss = GlossMesh::of(mesh).ok_or_else(|| {
        PrtError::invalid(
            "SH transfer",
            "SH glossy transfer draws a bake with visibility: bake a glossy scene with \
             --per-vertex (visibility is its default)",
        )
    })?;
    let colours = vertex_colours(t, relit)?;
    let lights = lit_lobe(t, (gloss, &mesh.positions), light, weights);
    let gloss = ShGloss::new(gloss, transfer, light);
    if lights.is_unlit() {
        return draw_mesh(mesh, colours, Some(&gloss), camera, behind, samples);
    }
    let both = WithLights {
        base: gloss,
        lights,
    };
    draw_mesh(mesh, colours, Some(&both), camera, behind, samples)
}

/// The lobe of a mesh's glossy vertices under `light`, with the highlights at the vertex
/// `positions` of the light columns of `t` that `weights` lights.
fn lit_lobe<'a>(
    t: &Transport,
    (gloss, positions): (GlossMesh<'a>, &'a [Vec3]),
    light: &'a CubePyramid,
    weights: &[[f32; 3]],
) -> Lobe<'a> {
    let lit = lit_columns(&t.meta.lights, weights);
    Lobe::of_widths(gloss, light).with_lights(positions, lit)
}

/// Draws a per-vertex bake with the given vertex `colours` (one per vertex, its glossy terms
/// left out) as [`draw_relit`] does.
pub fn draw(
    t: &Transport,
    colours: &[[f32; 3]],
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
    samples: u32,
) -> Result<Raster> {
    draw_mesh(mesh_of(t)?, colours, None, camera, behind, samples)
}

/// Draws `mesh` with its texturing, `colours` and `gloss`, over what is `behind`.
fn draw_mesh(
    mesh: &VertexMesh,
    colours: &[[f32; 3]],
    gloss: Option<&dyn ViewDependent>,
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
    samples: u32,
) -> Result<Raster> {
    let texturing = Texturing::of(mesh);
    let options = DrawOptions {
        texturing: texturing.as_ref(),
        gloss,
        samples,
    };
    let raster = rasterize_with(camera, &mesh.positions, &mesh.triangles, colours, options)?;
    compose(raster, camera, behind)
}

/// A drawn raster over the environment behind it, where given.
pub fn compose(
    raster: Raster,
    camera: &Camera,
    behind: Option<(&EnvMap, EnvRotation)>,
) -> Result<Raster> {
    let Some((env, rotation)) = behind else {
        return Ok(raster);
    };
    let back = environment_behind_camera(camera, &raster.coverage, env, rotation)?;
    Ok(Raster {
        image: composite(&raster.image, &back),
        coverage: raster.coverage,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The eye of an orbit that does not turn (or only scales the distance) against where it
    /// should be: the elevation goes to an angle and back through f32 trigonometry at distances
    /// up to 5, a few ulps of the coordinates.
    const UNTURNED_EYE: f32 = 1e-5;
    /// A turned eye (a quarter turn, the elevation limit) against the exact one: f32 degrees to
    /// radians, a quaternion rotation and sines at a distance of 5 round a little more, ~1e-6.
    const TURNED_EYE: f32 = 1e-4;

    #[test]
    fn the_orbit_keeps_the_distance_and_the_target_and_turns_the_eye() {
        let c = Camera {
            eye: Vec3::new(0.0, 3.0, 4.0),
            target: Vec3::new(0.0, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 40.0,
            width: 8,
            height: 8,
        };
        let same = orbit(&c, 0.0, 0.0);
        assert!((same.eye - c.eye).length() < UNTURNED_EYE);
        let quarter = orbit(&c, 90.0, 0.0);
        assert!(
            (quarter.eye - Vec3::new(4.0, 3.0, 0.0)).length() < TURNED_EYE,
            "{}",
            quarter.eye
        );
        let up = orbit(&c, 0.0, 90.0);
        assert!((up.eye.length() - 5.0).abs() < TURNED_EYE);
        assert!((up.eye.y / 5.0 - 85f32.to_radians().sin()).abs() < TURNED_EYE);
        assert!(up.validate().is_ok());
    }

    #[test]
    fn a_moved_camera_keeps_the_world_up_whatever_the_base_camera_rolled() {
        let tilted = Camera {
            eye: Vec3::new(0.0, 1.5, 4.0),
            target: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::new(0.0, 0.935, -0.355),
            fov_y_deg: 40.0,
            width: 8,
            height: 6,
        };
        let level = Camera {
            up: Vec3::Y,
            ..tilted.clone()
        };
        let (eye, target) = (Vec3::new(5.0, 2.2, 0.0), Vec3::new(0.0, 0.5, 0.0));
        let a = moved_camera(&tilted, eye, target, None);
        let b = moved_camera(&level, eye, target, None);
        assert_eq!(a, b);
        assert_eq!(a.up, WORLD_UP);
        assert_eq!((a.fov_y_deg, a.width, a.height), (40.0, 8, 6));
        // The film's up is the world's up made orthogonal to the view: no roll.
        let (forward, right, film_up) = a.frame();
        assert!(right.y.abs() < 1e-6, "{right}");
        assert!(film_up.y > 0.0 && film_up.dot(forward).abs() < 1e-6);
        // An up asked for is kept.
        let asked = moved_camera(&tilted, eye, target, Some(Vec3::X * 2.0));
        assert_eq!(asked.up, Vec3::X);
        // Looking straight down the up axis, the top of the image goes to -Z.
        let down = moved_camera(&tilted, Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO, None);
        assert_eq!(down.up, Vec3::NEG_Z);
        assert!(down.validate().is_ok());
        let along_x = moved_camera(&tilted, Vec3::X, Vec3::ZERO, Some(Vec3::X));
        assert!(along_x.validate().is_ok(), "{}", along_x.up);
        // The orbit makes its cameras the same way.
        let o = orbit(&tilted, 30.0, 10.0);
        assert_eq!(o, moved_camera(&tilted, o.eye, o.target, None));
        assert_eq!(Orbit::default().camera(&tilted).up, WORLD_UP);
    }

    #[test]
    fn an_orbit_moves_the_eye_by_its_distance_and_clamps_what_is_out_of_range() {
        let c = Camera {
            eye: Vec3::new(0.0, 0.0, 4.0),
            target: Vec3::new(1.0, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 40.0,
            width: 8,
            height: 8,
        };
        let o = Orbit {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            distance: 0.5,
        };
        let near = o.camera(&c);
        assert!(
            (near.eye - Vec3::new(0.5, 0.0, 2.0)).length() < UNTURNED_EYE,
            "{}",
            near.eye
        );
        assert_eq!(near.target, c.target);
        assert_eq!(Orbit::default().camera(&c).eye, orbit(&c, 0.0, 0.0).eye);
        let mut wild = Orbit {
            azimuth_deg: 540.0,
            elevation_deg: f32::NAN,
            distance: 1e9,
        };
        assert!(wild.clamp());
        assert_eq!(
            wild,
            Orbit {
                azimuth_deg: -180.0,
                elevation_deg: 0.0,
                distance: 10.0
            }
        );
        assert!(!wild.clamp());
        assert_eq!(
            "30,-10".parse::<Orbit>().unwrap(),
            Orbit {
                azimuth_deg: 30.0,
                elevation_deg: -10.0,
                distance: 1.0
            }
        );
        assert_eq!("30,-10,2".parse::<Orbit>().unwrap().distance, 2.0);
        for bad in ["30", "1,2,3,4", "a,b", "1,inf", "1,2,0", "1,2,11"] {
            let e = bad.parse::<Orbit>().unwrap_err().to_string();
            assert!(e.contains("orbit"), "{bad}: {e}");
        }
    }
}
