//! Light approximation: the Haar coefficients of a cube map and the K best of them by one of three
//! weightings (Ng et al. 2003). The SH light vector of the same cube map is
//! [`crate::math::texel_sh::TexelShBasis::project_light`].
//!
//! RGB shares one index set, chosen on a luminance-like magnitude, so the relight kernel reads each
//! kept transport column once for all three channels.

use crate::error::{PrtError, Result};
use crate::math::cubemap::CubeMap;
use crate::math::haar;
use crate::math::rgb_magnitude;

/// How light coefficients are ranked before the K largest are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[derive(strum::IntoStaticStr, strum::Display, strum::VariantArray)]
#[strum(serialize_all = "kebab-case")]
pub enum Weighting {
    /// By magnitude alone: the best K-term approximation of the light in L2.
    #[strum(serialize = "none")]
    Unweighted,
    /// By magnitude times the solid angle of the coefficient's support: favours coarse, bright
    /// features (Ng et al. 2003, "area-weighted").
    Area,
    /// By magnitude times the average magnitude of the matching transport coefficient over the
    /// image: favours what the scene can actually show (Ng et al. 2003, "transport-weighted").
    Transport,
}

impl Weighting {
    /// All weightings, in the order they are reported.
    pub const ALL: [Weighting; 3] = [Weighting::Unweighted, Weighting::Area, Weighting::Transport];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

crate::named!(Weighting, "weighting", ["unweighted" => Weighting::Unweighted]);

/// Indices of the `k` largest priorities, ascending. Ties go to the lower index, so the choice is
/// deterministic.
pub fn select_top_k(priority: &[f32], k: usize) -> Vec<u32> {
    let k = k.min(priority.len());
    let mut order: Vec<u32> = (0..priority.len() as u32).collect();
    if k < order.len() && k > 0 {
        let by_priority = |a: &u32, b: &u32| {
            priority[*b as usize]
                .total_cmp(&priority[*a as usize])
                .then(a.cmp(b))
        };
        order.select_nth_unstable_by(k - 1, by_priority);
    }
    order.truncate(k);
    order.sort_unstable();
    order
}

/// A sparse RGB light vector in the Haar basis: the kept terms, ascending by coefficient index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SparseLight {
    /// Coefficient indices, ascending.
    pub indices: Vec<u32>,
    /// Their RGB values.
    pub values: Vec<[f32; 3]>,
}

impl SparseLight {
    /// Number of kept terms.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// True when no term is kept.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }
}

/// The Haar coefficients of a cube map, with the per-coefficient support areas cached for
/// area-weighted selection.
#[derive(Clone, Debug)]
pub struct WaveletLight {
    /// Face size N.
    pub n: usize,
    /// All 6 N² coefficients, layout of [`crate::math::haar`].
    pub coeffs: Vec<[f32; 3]>,
}

impl WaveletLight {
    /// Transforms a cube map. The sums run in f64: a coefficient is up to N times the largest
    /// texel, which f32 sums would overflow for a map near the f32 range; one that does not fit
    /// an f32 at the end is an error, not an infinity.
    pub fn from_cube(cube: &CubeMap) -> Result<Self> {
        let mut wide: Vec<[f64; 3]> = cube.texels.iter().map(|t| t.map(f64::from)).collect();
        haar::forward_cube(&mut wide, cube.n)?;
        if let Some(c) = wide
            .iter()
            .flatten()
            .find(|c| !c.is_finite() || c.abs() > f32::MAX as f64)
        {
            return Err(PrtError::invalid(
                "environment",
                format!(
                    "a Haar coefficient of its light is {c:.3e}, beyond 32-bit floats: the map \
                     is far too bright (scale it down)"
                ),
            ));
        }
        let coeffs = wide.iter().map(|c| c.map(|v| v as f32)).collect();
        Ok(WaveletLight { n: cube.n, coeffs })
    }

    /// The cube map these are the coefficients of (the inverse transform, in f64).
    pub fn to_cube(&self) -> Result<CubeMap> {
        let mut wide: Vec<[f64; 3]> = self.coeffs.iter().map(|c| c.map(f64::from)).collect();
        haar::inverse_cube(&mut wide, self.n)?;
        Ok(CubeMap {
            n: self.n,
            texels: wide.iter().map(|t| t.map(|v| v as f32)).collect(),
        })
    }

    /// Keeps the `k` best terms by `weighting`. `transport_magnitude` (one value per coefficient)
    /// is needed for [`Weighting::Transport`]; `support_area` (see
    /// [`haar::support_solid_angles`]) for [`Weighting::Area`].
    pub fn select(
        &self,
        k: usize,
        weighting: Weighting,
        support_area: &[f32],
        transport_magnitude: Option<&[f32]>,
    ) -> Result<SparseLight> {
        let total = self.coeffs.len();
        crate::flags::terms(k, self.n)?;
        let weights: Option<&[f32]> = match weighting {
            Weighting::Unweighted => None,
            Weighting::Area => Some(support_area),
            Weighting::Transport => Some(transport_magnitude.ok_or_else(|| {
                PrtError::invalid(
                    "weighting",
                    "transport weighting needs per-coefficient transport magnitudes",
                )
            })?),
        };
        if let Some(w) = weights
            && w.len() != total
        {
            return Err(PrtError::invalid(
                "weights",
                format!("{} weights for {total} coefficients", w.len()),
            ));
        }
        let priority: Vec<f32> = match weights {
            None => self.coeffs.iter().map(|c| rgb_magnitude(*c)).collect(),
            Some(w) => self
                .coeffs
                .iter()
                .zip(w)
                .map(|(c, w)| rgb_magnitude(*c) * w)
                .collect(),
        };
        let indices = select_top_k(&priority, k);
        let values = indices.iter().map(|&i| self.coeffs[i as usize]).collect();
        Ok(SparseLight { indices, values })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_k_is_deterministic_and_sorted() {
        let p = [1.0, 5.0, 5.0, 0.5, 3.0, 5.0];
        assert_eq!(select_top_k(&p, 2), vec![1, 2]);
        assert_eq!(select_top_k(&p, 4), vec![1, 2, 4, 5]);
        assert_eq!(select_top_k(&p, 6), vec![0, 1, 2, 3, 4, 5]);
    }

    #[test]
    fn k_out_of_range_is_an_error() {
        let cube = CubeMap::constant(2, [1.0; 3]).unwrap();
        let light = WaveletLight::from_cube(&cube).unwrap();
        let area = vec![1.0; 24];
        for k in [0, 25] {
            let e = light
                .select(k, Weighting::Unweighted, &area, None)
                .unwrap_err()
                .to_string();
            assert!(e.contains("K = "), "{e}");
        }
        let e = light
            .select(3, Weighting::Transport, &area, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("transport"), "{e}");
    }
}
