//! The light a glossy lobe is drawn from per pixel ([`crate::draw::lobe`]): what a relight
//! request stands for, on a cube finer than the transport's where the light was prepared with
//! one ([`LightContext::lobe_n`]), so that small bright lights stay sharp in highlights. The
//! request acts on it as on the diffuse product: K kept terms keep the same share of the finer
//! cube's Haar terms, SH orders reconstruct it from the same coefficients, so the kept-term
//! slider and SH against wavelets reach the highlights too.

use super::{PreparedLight, RelightRequest, Terms, light_sh_order};
use crate::env::select::{WaveletLight, Weighting};
use crate::error::Result;
use crate::math::cube_pyramid::CubePyramid;
use crate::math::cubemap::{CubeMap, texel_count};
use crate::relight::LightContext;
use crate::store::transport::Transport;

/// Face size of the lobe's light when the transport keeps visibility (or the transport's N, if
/// finer). A lobe of roughness 0.2 reflects a studio's lamps 11% off at N = 32 and 3.3% off at
/// 64 against the map itself; on the glossy sphere under the studio, the drawn image is 14.7%,
/// 13.9% and 20.8% from the path tracer at N = 32, 9.7%, 8.6% and 19.6% at 64 and 9.2%, 8.1%
/// and 19.4% at 128, while the demo's teapot under the sunrise, whose small sun the lobe's
/// directions sample worse the sharper it is, went from 11.3% at 32 to 12.7% at 64 and 128.
pub const LOBE_N: usize = 64;

/// The pyramid of the light `req` relights `t` with under `light` (`None`: the environment off),
/// which a per-vertex bake with visibility draws its glossy lobes from; `None` for any other
/// transport, which needs none.
pub fn lobe_light(
    t: &Transport,
    ctx: &LightContext,
    light: Option<&PreparedLight>,
    req: &RelightRequest,
) -> Result<Option<CubePyramid>> {
    if t.mesh().is_none_or(|m| m.visibility.is_none()) {
        return Ok(None);
    }
    let cube = match light {
        None => CubeMap::constant(ctx.lobe_n.unwrap_or(ctx.n), [0.0; 3])?,
        Some(light) => match &light.lobe {
            None => Terms::of(t, ctx, light, req)?.cube(ctx.n)?,
            Some(fine) => fine_cube(ctx, light, fine, req)?,
        },
    };
    Ok(Some(CubePyramid::new(&cube)?))
}

/// The light of `req` on the finer cube of `fine`: every term; K terms as the same share of the
/// finer cube's, ranked by the same weighting (transport weighting, whose magnitudes are the
/// transport's at its own N, by area); an SH order's reconstruction at the finer texels.
fn fine_cube(
    ctx: &LightContext,
    light: &PreparedLight,
    fine: &WaveletLight,
    req: &RelightRequest,
) -> Result<CubeMap> {
    let n = fine.n;
    match *req {
        RelightRequest::Full => fine.to_cube(),
        RelightRequest::Wavelet { k, weighting } => {
            let k = (k * (n / ctx.n).pow(2)).min(texel_count(n));
            let weighting = match weighting {
                Weighting::Transport => Weighting::Area,
                w => w,
            };
            let kept = fine.select(k, weighting, &ctx.lobe_support, None)?;
            Terms::Wavelet(kept).cube(n)
        }
        RelightRequest::Sh { order } | RelightRequest::ShLight { order } => {
            Terms::Sh(light_sh_order(&light.sh, order, ctx.sh_order)?).cube(n)
        }
    }
}
