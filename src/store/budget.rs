//! The thresholding budget of a bake: which of a row's Haar coefficients are kept.
//!
//! A row keeps its largest coefficients, by a weighted magnitude `w_j |v_j|`, and drops the rest
//! while the weighted energy dropped, `Σ (w_j v_j)²`, stays within `threshold²` times the weighted
//! energy of a reference row (an unshadowed surface facing up, see `bake`). The weights say what
//! an error costs under real light:
//! - [`Budget::L2`]: `w = 1`, the row's own L2 error (and so the relit error under a light whose
//!   Haar coefficients are all alike).
//! - [`Budget::Area`]: `w` = the solid angle of the coefficient's support, the weight Ng et al.
//!   (2003) gave light coefficients: coarse terms matter most, as under smooth light.
//! - [`Budget::Sun`]: `w = 1/s` for a support of s x s texels. Dropping coefficient j changes each
//!   texel of its support by `|v_j| / s`, so this bounds the error of the row at any single texel,
//!   which is what a small, bright source sees: a sun relights a pixel with the row's value at
//!   the sun's few texels.
//! - [`Budget::Absolute`]: Ng et al.'s plain threshold: every coefficient with
//!   `|v_j| < threshold · ‖reference row‖` is dropped, whatever the rest of the row holds.

use serde::{Deserialize, Serialize};
use strum::{IntoStaticStr, VariantArray};

use crate::math::haar::{coeff_info, support_solid_angles};

/// How the thresholding budget weighs coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[derive(Serialize, Deserialize, IntoStaticStr, strum::Display, VariantArray)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Budget {
    /// Plain L2 error of the row.
    #[default]
    L2,
    /// Weighted by the support solid angle.
    Area,
    /// Weighted by the reciprocal of the support's side: the error at any one texel.
    Sun,
    /// Ng et al.'s absolute threshold on each coefficient.
    Absolute,
}

impl Budget {
    /// Every budget, for sweeps.
    pub const ALL: [Budget; 4] = [Budget::L2, Budget::Area, Budget::Sun, Budget::Absolute];

    /// The name used on the command line and in files.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// The weight of every coefficient of a cube of face size `n` (`None` for the absolute
    /// threshold, which weighs nothing). Normalised to a largest weight of 1.
    pub fn weights(self, n: usize) -> Option<Vec<f32>> {
        let count = 6 * n * n;
        let w: Vec<f64> = match self {
            Budget::L2 => vec![1.0; count],
            Budget::Area => support_solid_angles(n),
            Budget::Sun => (0..count)
                .map(|j| 1.0 / coeff_info(n, j).support as f64)
                .collect(),
            Budget::Absolute => return None,
        };
        let max = w.iter().cloned().fold(0.0f64, f64::max);
        Some(w.iter().map(|v| (v / max) as f32).collect())
    }
}

crate::named!(Budget, "budget");

/// A budget prepared for one cube size: the weights and the weighted energy of the reference row
/// per unit of its plain energy.
#[derive(Clone, Debug)]
pub struct Thresholder {
    budget: Budget,
    threshold: f32,
    weights: Option<Vec<f32>>,
    /// Weighted over plain energy of the reference row.
    weighted_ratio: f64,
}

impl Thresholder {
    /// For rows over a cube of face size `n`; `reference_haar` is the reference row's Haar
    /// coefficients (its plain energy is the scale callers pass to [`Thresholder::sparsify`]).
    pub fn new(budget: Budget, threshold: f32, n: usize, reference_haar: &[f32]) -> Self {
        let weights = budget.weights(n);
        let plain: f64 = reference_haar.iter().map(|&v| (v as f64).powi(2)).sum();
        let weighted: f64 = match &weights {
            Some(w) => reference_haar
                .iter()
                .zip(w)
                .map(|(&v, &w)| (v as f64 * w as f64).powi(2))
                .sum(),
            None => plain,
        };
        Thresholder {
            budget,
            threshold,
            weights,
            weighted_ratio: if plain > 0.0 { weighted / plain } else { 1.0 },
        }
    }

    /// Keeps a row's coefficients as the budget says, `reference_energy` being the plain energy
    /// of the row the budget is relative to. Returns the kept (coefficient, value) pairs ascending
    /// by coefficient, the plain energy dropped and the row's plain energy. `order` is scratch.
    pub fn sparsify(
        &self,
        row: &[f32],
        reference_energy: f64,
        order: &mut Vec<u64>,
    ) -> (Vec<(u32, f32)>, f64, f64) {
        let total = sum_squares(row, |v| v as f64);
        let weight = |j: usize| self.weights.as_ref().map_or(1.0, |w| w[j]);
        // Every non-zero coefficient's key, in coefficient order, each written at the end and
        // counted in when it is not zero (no branch to mispredict).
        order.clear();
        order.resize(row.len(), 0);
        let mut count = 0;
        for (j, &v) in row.iter().enumerate() {
            order[count] = key(v.abs() * weight(j), j as u32);
            count += (v != 0.0) as usize;
        }
        order.truncate(count);
        let mut dropped = 0.0f64;
        let entry = |k: u64| (k as u32, row[k as u32 as usize]);
        let kept: Vec<(u32, f32)> = if self.threshold <= 0.0 {
            order.iter().map(|&k| entry(k)).collect()
        } else if self.budget == Budget::Absolute {
            // Everything below eps goes; the keys are still in coefficient order, and the kept
            // list is sized to what stays, as the tile holds it until it is written.
            let eps = self.threshold as f64 * reference_energy.sqrt();
            let stays = |k: u64| magnitude(k) as f64 >= eps;
            let mut count = 0;
            for &k in order.iter() {
                match stays(k) {
                    true => count += 1,
                    false => dropped += (magnitude(k) as f64).powi(2),
                }
            }
            let mut kept = Vec::with_capacity(count);
            kept.extend(order.iter().filter(|&&k| stays(k)).map(|&k| entry(k)));
            kept
        } else {
            let budget = (self.threshold as f64).powi(2) * reference_energy * self.weighted_ratio;
            let n = smallest_within(order, budget);
            dropped = sum_squares(&order[..n], |k| row[k as u32 as usize] as f64);
            // The rest stay, put back in coefficient order through a bitmap of the row: a
            // pass over its words rather than its coefficients, as most rows keep few.
            let mut bits = vec![0u64; row.len().div_ceil(64)];
            for &k in &order[n..] {
                let j = k as u32 as usize;
                bits[j / 64] |= 1 << (j % 64);
            }
            let mut kept = Vec::with_capacity(order.len() - n);
            for (w, &word) in bits.iter().enumerate() {
                let mut word = word;
                while word != 0 {
                    kept.push(entry((w * 64 + word.trailing_zeros() as usize) as u64));
                    word &= word - 1;
                }
            }
            kept
        };
        (kept, dropped, total)
    }
}

/// A coefficient's magnitude (finite and not negative) and index as one key that orders them
/// by magnitude, then by index: a non-negative float's bits order as it does.
fn key(magnitude: f32, j: u32) -> u64 {
    (magnitude.to_bits() as u64) << 32 | j as u64
}

/// The magnitude of a [`key`].
fn magnitude(key: u64) -> f32 {
    f32::from_bits((key >> 32) as u32)
}

/// Σ f(x)² over `items`, in four sums that run side by side and meet at the end: as one f64
/// sum, each addition waited for the last, and the row's three such sums were a large part of
/// its thresholding.
fn sum_squares<T: Copy>(items: &[T], f: impl Fn(T) -> f64) -> f64 {
    let mut lanes = [0.0f64; 4];
    let chunks = items.chunks_exact(4);
    let tail = chunks.remainder();
    for chunk in chunks {
        for (lane, &x) in lanes.iter_mut().zip(chunk) {
            *lane += f(x) * f(x);
        }
    }
    for (lane, &x) in lanes.iter_mut().zip(tail) {
        *lane += f(x) * f(x);
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
}

/// Reorders `items` so that its first `n` are its `n` smallest by (magnitude, coefficient), and
/// returns the largest `n` whose magnitudes' squares sum to at most `budget`: the prefix that
/// sorting and summing from the smallest would drop, found by selection in expected linear time
/// (a sort was 6–8% of a bake).
fn smallest_within(items: &mut [u64], budget: f64) -> usize {
    // items[..lo] are the lo smallest and all go (their squares sum to `spent`); the last one
    // to go lies in items[lo..hi]; everything from hi on is larger than all before it and stays.
    let (mut lo, mut hi) = (0, items.len());
    let mut spent = 0.0f64;
    while lo < hi {
        let part = &mut items[lo..hi];
        let mid = part.len() / 2;
        part.select_nth_unstable(mid);
        let smaller = sum_squares(&part[..=mid], |k| magnitude(k) as f64);
        if spent + smaller <= budget {
            spent += smaller;
            lo += mid + 1;
        } else {
            // The pivot does not go: either it or one smaller than it overflows the budget.
            hi = lo + mid;
        }
    }
    lo
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row's plain energy as the thresholder returns it against the test's own f64 sum of the
    /// same squares in the same order: a few ulps of a value near 3e-3, if anything.
    const SAME_ENERGY: f64 = 1e-12;
    /// Relative slack on the budget (threshold² times the reference's weighted energy) that a
    /// row's dropped weighted energy must stay within: the thresholder spends its budget in f64
    /// sums of its own order, against a product and quotient of f64 sums, and the test sums the
    /// dropped weighted squares again in another order, so a few f64 ulps may separate the two.
    /// (The thresholder ranks by f32 products |v| w, whose rounding, ~1e-7 of a term, would show
    /// only where a row's dropped energy met its budget to that precision.)
    const BUDGET_ROUNDING: f64 = 1e-9;

    fn row(n: usize) -> Vec<f32> {
        (0..6 * n * n)
            .map(|j| ((j * 7919 % 1000) as f32 / 1000.0 - 0.5) * 0.01)
            .collect()
    }

    /// The sort and greedy sum that [`smallest_within`] replaces: its slow twin.
    fn smallest_within_by_sort(items: &[(f32, u32)], budget: f64) -> Vec<u32> {
        let mut sorted = items.to_vec();
        sorted.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut spent = 0.0f64;
        let mut out = Vec::new();
        for (m, j) in sorted {
            let e = (m as f64).powi(2);
            if spent + e > budget {
                break;
            }
            spent += e;
            out.push(j);
        }
        out.sort_unstable();
        out
    }

    #[test]
    fn selection_drops_what_the_sort_dropped() {
        let mut rng = crate::math::sampling::Rng::new(7, 0);
        for case in 0..400 {
            let n = 1 + (rng.next_u64() % 3000) as usize;
            // Ties too: a few distinct magnitudes in every fourth case.
            let items: Vec<(f32, u32)> = (0..n)
                .map(|j| {
                    let m = if case % 4 == 0 {
                        (rng.next_u64() % 5) as f32 * 1e-3
                    } else {
                        rng.next_f32() * 1e-3
                    };
                    (m, j as u32)
                })
                .collect();
            let energy: f64 = items.iter().map(|&(m, _)| (m as f64).powi(2)).sum();
            let budget = energy * (case % 10) as f64 / 10.0;
            let want = smallest_within_by_sort(&items, budget);
            let mut work: Vec<u64> = items.iter().map(|&(m, j)| key(m, j)).collect();
            let k = smallest_within(&mut work, budget);
            let mut got: Vec<u32> = work[..k].iter().map(|&k| k as u32).collect();
            got.sort_unstable();
            assert_eq!(got, want, "case {case}: n {n}, budget {budget}");
        }
    }

    /// `sparsify` keeps, in coefficient order, every non-zero coefficient but those that the
    /// sort and greedy sum drop, under each weighted budget, on rows with zeros in them.
    #[test]
    fn sparsify_keeps_all_but_what_the_sort_drops() {
        let mut rng = crate::math::sampling::Rng::new(11, 0);
        let n = 8;
        for case in 0..60 {
            let r: Vec<f32> = (0..6 * n * n)
                .map(|_| {
                    let v = (rng.next_f32() - 0.5) * 1e-2;
                    if rng.next_f32() < 0.3 { 0.0 } else { v }
                })
                .collect();
            let energy: f64 = r.iter().map(|&v| (v as f64).powi(2)).sum();
            let t = [0.05f32, 0.2, 0.6][case % 3];
            for budget in [Budget::L2, Budget::Area, Budget::Sun] {
                let th = Thresholder::new(budget, t, n, &r);
                let (kept, _, _) = th.sparsify(&r, energy, &mut Vec::new());
                let w = budget.weights(n).unwrap();
                let items: Vec<(f32, u32)> = (0..r.len())
                    .filter(|&j| r[j] != 0.0)
                    .map(|j| (r[j].abs() * w[j], j as u32))
                    .collect();
                let limit = (t as f64).powi(2) * energy * th.weighted_ratio;
                let gone = smallest_within_by_sort(&items, limit);
                let want: Vec<(u32, f32)> = items
                    .iter()
                    .filter(|(_, j)| gone.binary_search(j).is_err())
                    .map(|&(_, j)| (j, r[j as usize]))
                    .collect();
                assert!(
                    !gone.is_empty() && !want.is_empty(),
                    "case {case}: a trivial row"
                );
                assert_eq!(kept, want, "case {case}, {budget}, threshold {t}");
            }
        }
    }

    /// Each budget keeps the dropped weighted energy within threshold² of the reference's, and
    /// a larger threshold never keeps more.
    #[test]
    fn dropped_weighted_energy_stays_within_the_budget() {
        let n = 8;
        let r = row(n);
        let energy: f64 = r.iter().map(|&v| (v as f64).powi(2)).sum();
        for budget in [Budget::L2, Budget::Area, Budget::Sun] {
            let mut last = usize::MAX;
            for t in [0.01f32, 0.05, 0.2, 0.5] {
                let th = Thresholder::new(budget, t, n, &r);
                let (kept, dropped, total) = th.sparsify(&r, energy, &mut Vec::new());
                assert!((total - energy).abs() < SAME_ENERGY);
                let w = budget.weights(n).unwrap();
                let kept_set: std::collections::HashSet<u32> = kept.iter().map(|k| k.0).collect();
                let dropped_w: f64 = (0..r.len() as u32)
                    .filter(|j| !kept_set.contains(j))
                    .map(|j| (r[j as usize] as f64 * w[j as usize] as f64).powi(2))
                    .sum();
                let ref_w: f64 = r
                    .iter()
                    .zip(&w)
                    .map(|(&v, &w)| (v as f64 * w as f64).powi(2))
                    .sum();
                assert!(dropped_w <= (t as f64).powi(2) * ref_w * (1.0 + BUDGET_ROUNDING));
                assert!(dropped <= energy);
                assert!(kept.len() <= last, "{budget}: {t} keeps more");
                last = kept.len();
            }
        }
    }

    #[test]
    fn absolute_threshold_drops_exactly_the_small_values() {
        let n = 4;
        let r = row(n);
        let energy: f64 = r.iter().map(|&v| (v as f64).powi(2)).sum();
        let t = 0.02f32;
        let th = Thresholder::new(Budget::Absolute, t, n, &r);
        let (kept, _, _) = th.sparsify(&r, energy, &mut Vec::new());
        let eps = t as f64 * energy.sqrt();
        let want: Vec<u32> = (0..r.len() as u32)
            .filter(|&j| r[j as usize] != 0.0 && (r[j as usize].abs() as f64) >= eps)
            .collect();
        assert_eq!(kept.iter().map(|k| k.0).collect::<Vec<_>>(), want);
    }

    #[test]
    fn sun_weights_favour_fine_coefficients_and_area_coarse_ones() {
        let n = 8;
        let sun = Budget::Sun.weights(n).unwrap();
        let area = Budget::Area.weights(n).unwrap();
        // Coefficient 0 is a face's scaling term; the last is a finest-level diagonal detail.
        let last = 6 * n * n - 1;
        assert!(sun[last] > sun[0]);
        assert!(area[last] < area[0]);
    }
}
