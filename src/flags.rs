//! The checks of the numbers a user gives: one function per kind of flag, called by every
//! command that takes it (`relight`, `view --screenshot`, `bench`, `volume render`) and by the
//! library calls behind them, so a value is refused the same way, with the same words,
//! wherever it is given. The interactive viewer keeps its sliders in range instead.

use crate::error::{PrtError, Result};

/// Kept wavelet terms K: from 1 to all 6 N² coefficients of a cube of face size `n`.
pub fn terms(k: usize, n: usize) -> Result<()> {
    let total = crate::math::cubemap::texel_count(n);
    if k == 0 || k > total {
        return Err(PrtError::invalid(
            "term count",
            format!("K = {k}; it must be from 1 to 6·N² = {total} for N = {n}"),
        ));
    }
    Ok(())
}

/// An SH order to relight with: from 1 to the order the file was baked with.
pub fn sh_order(order: usize, baked: usize) -> Result<()> {
    if order == 0 || order > baked {
        return Err(PrtError::invalid(
            "SH order",
            format!("{order}; this file was baked up to order {baked}"),
        ));
    }
    Ok(())
}

/// An environment rotation (`yaw`, `pitch`), degrees: any finite angle.
pub fn angle(what: &str, deg: f64) -> Result<()> {
    if !deg.is_finite() {
        return Err(PrtError::invalid(
            what,
            format!("{deg} degrees; an angle must be a finite number"),
        ));
    }
    Ok(())
}

/// An exposure in stops: finite (NaN would make every pixel black).
pub fn exposure(stops: f32) -> Result<()> {
    if !stops.is_finite() {
        return Err(PrtError::invalid(
            "exposure",
            format!("{stops} stops; it must be a finite number"),
        ));
    }
    Ok(())
}

/// A number from `range` (inclusive), such as a sample count: an error names `what`, the value
/// with its `unit` (" pixel footprints", or "") and the range.
pub fn within<T: PartialOrd + std::fmt::Display>(
    what: &str,
    value: T,
    range: std::ops::RangeInclusive<T>,
    unit: &str,
) -> Result<()> {
    if !range.contains(&value) {
        return Err(PrtError::invalid(
            what,
            format!(
                "{value}{unit}; it must be from {} to {}",
                range.start(),
                range.end()
            ),
        ));
    }
    Ok(())
}

/// A fraction in [0, 1], such as the split of a comparison.
pub fn fraction(what: &str, f: f32) -> Result<()> {
    if !(0.0..=1.0).contains(&f) {
        return Err(PrtError::invalid(
            what,
            format!("{f}; expected a fraction from 0 to 1"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_and_out_of_range_values_are_refused() {
        // Each refusal names the value and what it must be.
        let says = |r: Result<()>, words: &[&str]| {
            let e = r.unwrap_err().to_string();
            assert!(words.iter().all(|w| e.contains(w)), "{e}");
        };
        says(terms(0, 4), &["K = 0", "from 1 to 6·N² = 96"]);
        says(terms(97, 4), &["K = 97", "for N = 4"]);
        assert!(terms(96, 4).is_ok());
        says(sh_order(0, 3), &["0;", "up to order 3"]);
        says(sh_order(4, 3), &["4;", "up to order 3"]);
        assert!(sh_order(3, 3).is_ok());
        says(angle("yaw", f64::NAN), &["yaw", "NaN degrees", "finite"]);
        says(angle("yaw", f64::INFINITY), &["inf degrees"]);
        assert!(angle("yaw", -720.0).is_ok());
        says(exposure(f32::NAN), &["NaN stops", "finite"]);
        says(exposure(f32::NEG_INFINITY), &["-inf stops"]);
        assert!(exposure(-3.5).is_ok());
        says(
            fraction("split", f32::NAN),
            &["split", "NaN", "from 0 to 1"],
        );
        says(fraction("split", 1.5), &["1.5", "from 0 to 1"]);
        assert!(fraction("split", 0.0).is_ok());
    }
}
