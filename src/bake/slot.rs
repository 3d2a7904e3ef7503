//! The rows one pixel keeps of each material it sees: the diffuse lobe's and, for a glossy
//! material, the GGX lobe's, summed plainly or weighed per camera sub-sample for a textured one.

use super::{brdf, tint};

/// The rows of one material seen in a pixel: its diffuse lobe's and, when glossy, its GGX
/// lobe's; summed plainly for a constant material and weighed by each sub-sample's own colour
/// for a textured one ([`tint::TintedRow`]).
pub(super) struct Slot {
    pub(super) material: u32,
    diffuse: Vec<f32>,
    glossy: Option<Vec<f32>>,
    tinted: Option<(tint::TintedRow, Option<tint::TintedRow>)>,
}

impl Slot {
    pub(super) fn new(material: u32, texels: usize, glossy: bool, textured: bool) -> Slot {
        let tinted = textured.then(|| {
            (
                tint::TintedRow::new(texels),
                glossy.then(|| tint::TintedRow::new(texels)),
            )
        });
        let plain = |on: bool| {
            if on && !textured {
                vec![0.0; texels]
            } else {
                Vec::new()
            }
        };
        Slot {
            material,
            diffuse: plain(true),
            glossy: (glossy && !textured).then(|| plain(true)),
            tinted,
        }
    }

    /// Where one sub-sample's diffuse and GGX rows go: the sums themselves for a constant
    /// material, `scratch` cleared for a textured one (then [`Slot::fold_sample`]).
    pub(super) fn rows_for_sample<'s>(
        &'s mut self,
        scratch: &'s mut [Vec<f32>; 2],
    ) -> (&'s mut [f32], Option<&'s mut [f32]>) {
        match &self.tinted {
            None => (&mut self.diffuse, self.glossy.as_deref_mut()),
            Some((_, glossy)) => {
                let glossy = glossy.is_some();
                let [d, g] = scratch;
                d.fill(0.0);
                if glossy {
                    g.fill(0.0);
                }
                (d, glossy.then_some(&mut g[..]))
            }
        }
    }

    /// Adds a textured material's sub-sample rows, left in `scratch`, with its colours.
    pub(super) fn fold_sample(&mut self, lobes: &brdf::Lobes, scratch: &[Vec<f32>; 2]) {
        if let Some((diffuse, glossy)) = &mut self.tinted {
            diffuse.add(lobes.albedo, &scratch[0]);
            if let Some(g) = glossy {
                g.add(lobes.specular, &scratch[1]);
            }
        }
    }

    /// The (RGB weight, row) pairs of the pixel: the material's colours with the plain sums, or
    /// a textured material's tinted rows.
    pub(super) fn finish(self, material: &crate::scene::Material) -> Vec<([f32; 3], Vec<f32>)> {
        match self.tinted {
            Some((diffuse, glossy)) => {
                let mut rows = diffuse.finish();
                rows.extend(glossy.into_iter().flat_map(tint::TintedRow::finish));
                rows
            }
            None => {
                let specular = material.glossy_lobe().map(|(s, _)| s.to_array());
                std::iter::once((material.albedo().to_array(), self.diffuse))
                    .chain(self.glossy.zip(specular).map(|(row, s)| (s, row)))
                    .collect()
            }
        }
    }
}
