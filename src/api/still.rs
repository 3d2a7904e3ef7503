//! Where a per-vertex bake's still is seen from: the bake's camera, moved and resized as the
//! command line's `--eye --target --up --width --height` say, and checked before any work.

use crate::draw::vertex;
use crate::error::Result;
use crate::scene::Camera;
use crate::store::transport::{Domain, Transport};
use glam::Vec3;

/// Where a per-vertex bake is drawn from: its bake's camera with what is given here replaced,
/// as `prt relight --eye --target --up --width --height` take it. A moved camera stays upright:
/// its up is `up`, else the world's +Y ([`crate::draw::vertex::WORLD_UP`]), not the scene
/// camera's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Still {
    /// Camera position (default: the scene's camera).
    pub eye: Option<Vec3>,
    /// The point it looks at (default: the scene's target).
    pub target: Option<Vec3>,
    /// The up direction of a camera moved by `eye` or `target`.
    pub up: Option<Vec3>,
    /// Image width (default: the scene's).
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    pub height: Option<u32>,
}

/// Bytes a pixel of a per-vertex still takes at the peak of a relight: the drawn colours, depth
/// and coverage, the environment behind, the composite and the encoded output. Measured: 27
/// bytes a pixel between 2048² and 4096² (peak resident memory), rounded up.
const STILL_BYTES_PER_PIXEL: u64 = 32;

impl Still {
    /// The camera of a still of `t`: `None` for a per-pixel bake, whose view is fixed (an error
    /// when anything is given for one); the bake's camera with what is given replaced for a
    /// per-vertex bake, checked, and refused before any work when its image would not fit in
    /// memory.
    pub fn camera(&self, t: &Transport) -> Result<Option<Camera>> {
        let moved = self.eye.is_some() || self.target.is_some() || self.up.is_some();
        let given = moved || self.width.is_some() || self.height.is_some();
        if t.attached.domain == Domain::View {
            if given {
                vertex::mesh_of(t)?;
            }
            return Ok(None);
        }
        let mut c = vertex::bake_camera(t)?;
        if moved {
            let (eye, target) = (self.eye.unwrap_or(c.eye), self.target.unwrap_or(c.target));
            c = vertex::moved_camera(&c, eye, target, self.up);
        }
        c.width = self.width.unwrap_or(c.width);
        c.height = self.height.unwrap_or(c.height);
        c.validate()?;
        crate::files::check_memory(
            "--width/--height",
            &format!(
                "a {} x {} still ({STILL_BYTES_PER_PIXEL} bytes a pixel)",
                c.width, c.height
            ),
            c.width as u64 * c.height as u64 * STILL_BYTES_PER_PIXEL,
        )?;
        Ok(Some(c))
    }
}
