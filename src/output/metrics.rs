//! Image error metrics over the pixels that see geometry (see [`crate::conventions`]): relative L2,
//! RMSE, PSNR, a gradient (Sobolev H1-style) error as Ng et al. 2003 used, and SSIM on tone-mapped
//! luminance as a perceptual measure.

use crate::error::{PrtError, Result};
use crate::output::film::{Image, ToneMap};

/// Errors of an image against a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ErrorReport {
    /// ‖A − R‖₂ / ‖R‖₂ over every channel of the masked pixels.
    pub rel_l2: f64,
    /// Root mean square difference per channel sample.
    pub rmse: f64,
    /// 20 log10(peak / RMSE), peak the largest reference value; infinite when equal. A reference
    /// with no value above 0 that the image differs from is an error, not a figure.
    pub psnr_db: f64,
    /// Relative L2 of the image gradients (forward differences inside the mask).
    pub rel_h1: f64,
    /// 1 − mean SSIM of tone-mapped luminance (0 = identical).
    pub dssim: f64,
}

fn check(a: &Image, r: &Image, mask: Option<&[f32]>) -> Result<()> {
    if a.width != r.width || a.height != r.height {
        return Err(PrtError::invalid(
            "images",
            format!("{}x{} against {}x{}", a.width, a.height, r.width, r.height),
        ));
    }
    if let Some(m) = mask
        && m.len() != r.pixels.len()
    {
        return Err(PrtError::invalid(
            "mask",
            "its size differs from the image's",
        ));
    }
    Ok(())
}

fn covered(mask: Option<&[f32]>, i: usize) -> bool {
    mask.is_none_or(|m| m[i] > 0.0)
}

/// Relative L2 error of `a` against `r` over masked pixels (all pixels without a mask).
pub fn relative_l2(a: &Image, r: &Image, mask: Option<&[f32]>) -> Result<f64> {
    check(a, r, mask)?;
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (i, (pa, pr)) in a.pixels.iter().zip(&r.pixels).enumerate() {
        if !covered(mask, i) {
            continue;
        }
        for k in 0..3 {
            let d = pa[k] as f64 - pr[k] as f64;
            num += d * d;
            den += (pr[k] as f64).powi(2);
        }
    }
    Ok(if den > 0.0 {
        (num / den).sqrt()
    } else if num > 0.0 {
        f64::INFINITY
    } else {
        0.0
    })
}

/// Every metric of this module.
pub fn compare(a: &Image, r: &Image, mask: Option<&[f32]>) -> Result<ErrorReport> {
    check(a, r, mask)?;
    let rel_l2 = relative_l2(a, r, mask)?;
    let (mut sq, mut count, mut peak) = (0.0f64, 0usize, 0.0f64);
    for (i, (pa, pr)) in a.pixels.iter().zip(&r.pixels).enumerate() {
        if !covered(mask, i) {
            continue;
        }
        for k in 0..3 {
            sq += (pa[k] as f64 - pr[k] as f64).powi(2);
            peak = peak.max(pr[k] as f64);
        }
        count += 3;
    }
    let rmse = if count > 0 {
        (sq / count as f64).sqrt()
    } else {
        0.0
    };
    if peak <= 0.0 && rmse > 0.0 {
        return Err(PrtError::invalid(
            "reference",
            format!(
                "it is black (no value above 0) over every compared pixel, so the relative \
                 errors and PSNR are undefined; the image differs from it by RMSE {rmse:.6e}"
            ),
        ));
    }
    let psnr_db = if rmse > 0.0 {
        20.0 * (peak / rmse).log10()
    } else {
        f64::INFINITY
    };
    Ok(ErrorReport {
        rel_l2,
        rmse,
        psnr_db,
        rel_h1: gradient_error(a, r, mask),
        dssim: 1.0 - ssim_luminance(a, r, mask),
    })
}

/// Relative L2 of forward-difference gradients, over pairs of neighbouring masked pixels.
fn gradient_error(a: &Image, r: &Image, mask: Option<&[f32]>) -> f64 {
    let (w, h) = (r.width, r.height);
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !covered(mask, i) {
                continue;
            }
            for j in [(x + 1 < w).then_some(i + 1), (y + 1 < h).then_some(i + w)]
                .into_iter()
                .flatten()
            {
                if !covered(mask, j) {
                    continue;
                }
                for k in 0..3 {
                    let ga = a.pixels[j][k] as f64 - a.pixels[i][k] as f64;
                    let gr = r.pixels[j][k] as f64 - r.pixels[i][k] as f64;
                    num += (ga - gr).powi(2);
                    den += gr * gr;
                }
            }
        }
    }
    if den > 0.0 {
        (num / den).sqrt()
    } else if num > 0.0 {
        // Gradients where the reference has none: as infinitely wrong as relative L2 says.
        f64::INFINITY
    } else {
        0.0
    }
}

/// Mean SSIM (Wang et al. 2004, 8 x 8 windows with stride 4, constants for a [0, 1] range) of the
/// sRGB luminance of both images, both tone-mapped with the reference's automatic exposure.
pub fn ssim_luminance(a: &Image, r: &Image, mask: Option<&[f32]>) -> f64 {
    let tone = ToneMap::auto(r, mask);
    let lum = |img: &Image| -> Vec<f64> {
        img.pixels
            .iter()
            .map(|p| {
                let s = tone.apply(*p);
                (0.2126 * s[0] as f64 + 0.7152 * s[1] as f64 + 0.0722 * s[2] as f64) / 255.0
            })
            .collect()
    };
    let (la, lr) = (lum(a), lum(r));
    let (w, h) = (r.width, r.height);
    const WIN: usize = 8;
    const STRIDE: usize = 4;
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let (mut sum, mut windows) = (0.0, 0usize);
    let mut y = 0;
    while y + WIN <= h {
        let mut x = 0;
        while x + WIN <= w {
            let idx = (y..y + WIN).flat_map(|yy| (x..x + WIN).map(move |xx| yy * w + xx));
            if idx.clone().all(|i| covered(mask, i)) {
                let n = (WIN * WIN) as f64;
                let (ma, mr) = (
                    idx.clone().map(|i| la[i]).sum::<f64>() / n,
                    idx.clone().map(|i| lr[i]).sum::<f64>() / n,
                );
                let (mut va, mut vr, mut cov) = (0.0, 0.0, 0.0);
                for i in idx {
                    va += (la[i] - ma).powi(2);
                    vr += (lr[i] - mr).powi(2);
                    cov += (la[i] - ma) * (lr[i] - mr);
                }
                let (va, vr, cov) = (va / (n - 1.0), vr / (n - 1.0), cov / (n - 1.0));
                sum += ((2.0 * ma * mr + c1) * (2.0 * cov + c2))
                    / ((ma * ma + mr * mr + c1) * (va + vr + c2));
                windows += 1;
            }
            x += STRIDE;
        }
        y += STRIDE;
    }
    if windows == 0 {
        1.0
    } else {
        sum / windows as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative L2 and RMSE of small hand-made images against their closed forms: sums of a few
    /// exact squares, a division and a square root in f64, a few ulps of values below 1.
    const HAND_COMPUTED: f64 = 1e-12;
    /// PSNR in dB (about 20) against its closed form: the log10 of a rounded ratio, times 20,
    /// rounds to a few ulps of 20 (~1e-14); this is a looser absolute bound for a value in dB.
    const HAND_COMPUTED_DB: f64 = 1e-9;

    fn img(values: &[[f32; 3]], w: usize) -> Image {
        Image {
            width: w,
            height: values.len() / w,
            pixels: values.to_vec(),
        }
    }

    #[test]
    fn hand_computed_values() {
        let r = img(&[[1.0, 2.0, 2.0], [0.0, 0.0, 4.0]], 2);
        let a = img(&[[1.0, 2.0, 3.0], [0.0, 0.0, 4.0]], 2);
        // ‖a − r‖ = 1, ‖r‖ = sqrt(1 + 4 + 4 + 16) = 5.
        let e = compare(&a, &r, None).unwrap();
        assert!((e.rel_l2 - 0.2).abs() < HAND_COMPUTED, "{e:?}");
        // RMSE = sqrt(1 / 6); PSNR = 20 log10(4 / RMSE).
        assert!((e.rmse - (1.0f64 / 6.0).sqrt()).abs() < HAND_COMPUTED);
        assert!(
            (e.psnr_db - 20.0 * (4.0 / (1.0f64 / 6.0).sqrt()).log10()).abs() < HAND_COMPUTED_DB
        );
        // Masking out the differing pixel leaves no error.
        let m = [0.0, 1.0];
        assert_eq!(relative_l2(&a, &r, Some(&m)).unwrap(), 0.0);
        // Identical images: zero error, SSIM 1.
        let e = compare(&r, &r, None).unwrap();
        assert_eq!((e.rel_l2, e.rmse, e.rel_h1), (0.0, 0.0, 0.0));
        assert!(e.psnr_db.is_infinite());
    }

    #[test]
    fn a_black_reference_is_an_error_unless_the_image_is_black_too() {
        let black = img(&[[0.0; 3]; 4], 2);
        let lit = img(&[[0.0; 3], [0.0; 3], [0.0, 0.5, 0.0], [0.0; 3]], 2);
        let e = compare(&lit, &black, None).unwrap_err().to_string();
        assert!(e.contains("black") && e.contains("undefined"), "{e}");
        assert_eq!(relative_l2(&lit, &black, None).unwrap(), f64::INFINITY);
        assert_eq!(gradient_error(&lit, &black, None), f64::INFINITY);
        let e = compare(&black, &black, None).unwrap();
        assert_eq!((e.rel_l2, e.rmse, e.rel_h1), (0.0, 0.0, 0.0));
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let r = img(&[[1.0; 3]; 4], 2);
        let a = img(&[[1.0; 3]; 4], 4);
        let e = compare(&a, &r, None).unwrap_err().to_string();
        assert!(e.contains("4x1 against 2x2"), "{e}");
    }
}
