//! Small statistics helpers: the Wilcoxon signed-rank test for paired samples, median, mean/std.
//!
//! # Wilcoxon signed-rank test
//!
//! For paired samples `a`, `b` the differences `d_i = a_i − b_i` are formed, zero differences are
//! dropped (Wilcoxon's "wilcox" zero method), and the `n` remaining `|d_i|` are ranked with
//! average ranks for ties. `W+` (`W−`) is the rank sum of the positive (negative) differences,
//! `W+ + W− = n(n+1)/2`, and the statistic is `T = min(W+, W−)`.
//!
//! * **Exact** (`n ≤ 50` and no tied `|d|`): under H₀ every sign pattern is equally likely, so
//!   the null distribution of `W+` is obtained by dynamic programming over the ranks 1..n
//!   (counts of subsets with each rank sum, as `f64`, exact up to 2⁵³ > 2⁵⁰). The two-sided
//!   p-value is `min(1, 2·P(W+ ≤ T))` (the distribution is symmetric).
//! * **Normal approximation** otherwise: `μ = n(n+1)/4`,
//!   `σ² = n(n+1)(2n+1)/24 − Σ_t (t³ − t)/48` over tie groups of size `t`, and
//!   `z = sign(T − μ)·max(|T − μ| − 0.5, 0)/σ` (continuity correction 0.5, never crossing zero),
//!   two-sided `p = erfc(|z|/√2)`. [`wilcoxon_signed_rank_with`] can switch the correction off
//!   (this matches SciPy's default `correction=False`).
//!
//! Reference values (the classic textbook example in the tests, n = 9 with one tie pair):
//! `W+ = 27`, `W− = 18`, `σ² = 71.125`; with continuity correction `z ≈ −0.4743`,
//! `p ≈ 0.6352`; without it `z ≈ −0.5336`, `p ≈ 0.5936`.

pub mod folds;
pub mod metrics;

/// Result of [`wilcoxon_signed_rank`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Wilcoxon {
    /// Number of non-zero differences used.
    pub n: usize,
    /// Rank sum of the positive differences `a − b > 0`.
    pub w_plus: f64,
    /// Rank sum of the negative differences.
    pub w_minus: f64,
    /// `min(W+, W−)`.
    pub statistic: f64,
    /// Normal-approximation z score (`None` when the exact distribution was used).
    pub z: Option<f64>,
    /// Two-sided p-value.
    pub p_value: f64,
    /// Whether the p-value comes from the exact null distribution.
    pub exact: bool,
}

/// Largest `n` for which the exact (tie-free) distribution is used.
pub const WILCOXON_EXACT_MAX_N: usize = 50;

/// Wilcoxon signed-rank test of `a` against `b` (paired), with continuity correction in the
/// normal approximation. See the module docs for the method.
///
/// Errors when the lengths differ, the input is empty, a value is not finite, or every
/// difference is zero.
pub fn wilcoxon_signed_rank(a: &[f64], b: &[f64]) -> Result<Wilcoxon, String> {
    wilcoxon_signed_rank_with(a, b, true)
}

/// [`wilcoxon_signed_rank`] with the continuity correction of the normal approximation
/// selectable (`continuity = false` reproduces SciPy's default). The exact path is unaffected.
pub fn wilcoxon_signed_rank_with(a: &[f64], b: &[f64], continuity: bool) -> Result<Wilcoxon, String> {
    if a.len() != b.len() {
        return Err(format!("wilcoxon: length mismatch ({} vs {})", a.len(), b.len()));
    }
    if a.is_empty() {
        return Err("wilcoxon: empty input".into());
    }
    if a.iter().chain(b).any(|v| !v.is_finite()) {
        return Err("wilcoxon: non-finite value in input".into());
    }
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).filter(|&d| d != 0.0).collect();
    if d.iter().any(|v| !v.is_finite()) {
        return Err("wilcoxon: difference overflows".into());
    }
    let n = d.len();
    if n == 0 {
        return Err("wilcoxon: all differences are zero".into());
    }

    // Average ranks of |d| and tie-group sizes.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| d[i].abs().total_cmp(&d[j].abs()));
    let mut rank = vec![0.0; n];
    let mut tie_term = 0.0; // Σ (t³ − t)
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        while j < n && d[order[j]].abs() == d[order[i]].abs() {
            j += 1;
        }
        let avg = (i + 1 + j) as f64 / 2.0; // mean of ranks i+1..=j
        for &k in &order[i..j] {
            rank[k] = avg;
        }
        let t = (j - i) as f64;
        tie_term += t * t * t - t;
        i = j;
    }
    let w_plus: f64 = (0..n).filter(|&k| d[k] > 0.0).map(|k| rank[k]).sum();
    let w_minus: f64 = (0..n).filter(|&k| d[k] < 0.0).map(|k| rank[k]).sum();
    let statistic = w_plus.min(w_minus);
    let nf = n as f64;

    if n <= WILCOXON_EXACT_MAX_N && tie_term == 0.0 {
        // Without ties all ranks are integers, so the statistic is an integer.
        let p = 2.0 * exact_cdf(n, statistic.round() as usize);
        return Ok(Wilcoxon { n, w_plus, w_minus, statistic, z: None, p_value: p.min(1.0), exact: true });
    }

    let mu = nf * (nf + 1.0) / 4.0;
    let var = nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - tie_term / 48.0;
    if var.is_nan() || var <= 0.0 {
        return Err("wilcoxon: zero variance of the statistic".into());
    }
    let dev = statistic - mu;
    let num = if continuity { dev.signum() * (dev.abs() - 0.5).max(0.0) } else { dev };
    let z = if dev == 0.0 { 0.0 } else { num / var.sqrt() };
    let p = erfc(z.abs() / std::f64::consts::SQRT_2).min(1.0);
    Ok(Wilcoxon { n, w_plus, w_minus, statistic, z: Some(z), p_value: p, exact: false })
}

/// `P(W+ ≤ t)` under H₀ for `n` untied ranks 1..n.
fn exact_cdf(n: usize, t: usize) -> f64 {
    let max = n * (n + 1) / 2;
    // counts[s] = number of subsets of {1..k} with sum s.
    let mut counts = vec![0.0f64; max + 1];
    counts[0] = 1.0;
    for k in 1..=n {
        let top = k * (k + 1) / 2;
        for s in (k..=top).rev() {
            counts[s] += counts[s - k];
        }
    }
    let below: f64 = counts[..=t.min(max)].iter().sum();
    below / 2f64.powi(n as i32)
}

/// Complementary error function, accurate to ~1e-14 relative for the range used by p-values.
///
/// Maclaurin series of `erf` for `|x| < 2`, Laplace continued fraction for larger `x`.
pub fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    if x < 2.0 {
        // erf(x) = 2/√π Σ (−1)^k x^(2k+1) / (k! (2k+1))
        let x2 = x * x;
        let mut term = x; // (−1)^k x^(2k+1)/k!
        let mut sum = x;
        for k in 1..200 {
            term *= -x2 / k as f64;
            let add = term / (2 * k + 1) as f64;
            sum += add;
            if add.abs() < 1e-17 * sum.abs() {
                break;
            }
        }
        return 1.0 - sum * std::f64::consts::FRAC_2_SQRT_PI;
    }
    if x > 27.0 {
        return 0.0; // below the smallest subnormal
    }
    // erfc(x) = e^{−x²}/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + 2/(x + …)))))
    let mut t = x;
    for k in (1..=120).rev() {
        t = x + (k as f64 / 2.0) / t;
    }
    (-x * x).exp() / (std::f64::consts::PI.sqrt() * t)
}

/// Value `c` of every row of `values`, which hold `dim` values per row, row after row (a
/// tracker's x, y, z): one per row.
pub fn value_column(values: &[f64], dim: usize, c: usize) -> Vec<f64> {
    values.iter().skip(c).step_by(dim.max(1)).copied().collect()
}

/// Root mean square of `v` (0 for an empty slice): the one RMS of the project.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Standard deviations per median absolute deviation for Gaussian data.
pub const MAD_TO_SD: f64 = 1.4826;

/// The position error of each row of `dim` residuals (mm): the Euclidean norm of its first
/// three (a point's, or a pose's origin).
pub fn position_errors(values: &[f64], dim: usize) -> Vec<f64> {
    values.chunks(dim.max(1)).map(|c| c.iter().take(3).map(|v| v * v).sum::<f64>().sqrt()).collect()
}

/// The median of `v` and its robust standard deviation ([`MAD_TO_SD`] × the median absolute
/// deviation from it): the one robust scale of the project.
pub fn robust_scale(v: &[f64]) -> (f64, f64) {
    let med = median(v);
    (med, MAD_TO_SD * median(&v.iter().map(|x| (x - med).abs()).collect::<Vec<f64>>()))
}

pub use crate::math::median;

/// The least-squares slope of y against x over the points `(x, y)`; `None` with fewer than
/// three points or fewer than two distinct x.
pub fn slope(points: &[(f64, f64)]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + (x - mx) * (y - my), b + (x - mx) * (x - mx)));
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Mean and sample standard deviation (`n − 1` denominator) of the non-NaN values of `v`.
/// `(NaN, NaN)` when there are none; the std is 0 for a single value.
pub fn mean_std(v: &[f64]) -> (f64, f64) {
    let vals = || v.iter().copied().filter(|x| !x.is_nan());
    let n = vals().count();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let mean = vals().sum::<f64>() / n as f64;
    if n == 1 {
        return (mean, 0.0);
    }
    let ss: f64 = vals().map(|x| (x - mean) * (x - mean)).sum();
    (mean, (ss / (n - 1) as f64).sqrt())
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_floor_below_a_tenth_of_a_micrometre_is_not_judged() {
        let oof = vec![1e-9; 40];
        assert!(short_of_floor(&oof, 1, None, 1e-2), "a real floor: the residuals fall short of it");
        assert!(!short_of_floor(&oof, 1, None, 5e-5), "a noise-free twin's floor: nothing to judge");
    }

    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn erfc_reference_values() {
        let refs = [
            (0.0, 1.0),
            (0.5, 0.4795001221869535),
            (1.0, 0.15729920705028513),
            (1.9, 0.007209570764742524),
            (2.0, 0.004677734981047266),
            (3.0, 2.209049699858544e-05),
            (5.0, 1.537_459_794_428_035e-12),
            (-1.0, 1.8427007929497148),
        ];
        for (x, e) in refs {
            assert!(((erfc(x) - e) / e).abs() < 1e-12, "erfc({x}) = {} vs {e}", erfc(x));
        }
    }

    #[test]
    fn wilcoxon_classic_example() {
        let a = [125.0, 115.0, 130.0, 140.0, 140.0, 115.0, 140.0, 125.0, 140.0, 135.0];
        let b = [110.0, 122.0, 125.0, 120.0, 140.0, 124.0, 123.0, 137.0, 135.0, 145.0];
        let w = wilcoxon_signed_rank(&a, &b).unwrap();
        assert_eq!(w.n, 9);
        assert_eq!((w.w_plus, w.w_minus, w.statistic), (27.0, 18.0, 18.0));
        assert!(!w.exact);
        // σ² = 9·10·19/24 − (2³−2)/48 = 71.125; z = (18 − 22.5 + 0.5)/√71.125
        let z = w.z.unwrap();
        assert!(close(z, -4.0 / 71.125f64.sqrt(), 1e-12), "z = {z}");
        assert!(close(z, -0.4743, 1e-4));
        assert!(close(w.p_value, 0.6352, 1e-4), "p = {}", w.p_value);
        // Without continuity correction (SciPy default): z ≈ −0.5336, p ≈ 0.5936.
        let w = wilcoxon_signed_rank_with(&a, &b, false).unwrap();
        assert!(close(w.z.unwrap(), -0.5336, 1e-4));
        assert!(close(w.p_value, 0.5936, 1e-4), "p = {}", w.p_value);
    }

    #[test]
    fn wilcoxon_exact_small_n() {
        // n = 5, all positive: P(W+ ≤ 0) = 1/32, two-sided p = 1/16.
        let w = wilcoxon_signed_rank(&[1.0, 2.0, 3.0, 4.0, 5.0], &[0.0; 5]).unwrap();
        assert!(w.exact && w.z.is_none());
        assert_eq!((w.n, w.w_plus, w.w_minus, w.statistic), (5, 15.0, 0.0, 0.0));
        assert!(close(w.p_value, 0.0625, 1e-15));
        // n = 6, ranks 1 and 2 negative: T = 3; subsets of {1..6} with sum ≤ 3:
        // {}, {1}, {2}, {3}, {1,2} → 5/64, p = 10/64.
        let d = [-1.0, -2.0, 3.0, 4.0, 5.0, 6.0];
        let w = wilcoxon_signed_rank(&d, &[0.0; 6]).unwrap();
        assert_eq!((w.w_minus, w.statistic), (3.0, 3.0));
        assert!(close(w.p_value, 10.0 / 64.0, 1e-15));
        // Symmetric case caps at 1.
        let w = wilcoxon_signed_rank(&[1.0, -2.0, -3.0, 4.0], &[0.0; 4]).unwrap();
        assert_eq!(w.statistic, 5.0);
        assert_eq!(w.p_value, 1.0);
    }

    #[test]
    fn wilcoxon_exact_matches_brute_force() {
        // n = 12 with a fixed sign pattern: compare the DP with enumeration of 2¹² patterns.
        let d: Vec<f64> = (1..=12).map(|k| if k % 3 == 0 { -(k as f64) } else { k as f64 * 1.0 }).collect();
        let w = wilcoxon_signed_rank(&d, &[0.0; 12]).unwrap();
        let t = w.statistic as usize;
        let below = (0u32..1 << 12).filter(|m| (0..12).filter(|b| m & (1 << b) != 0).map(|b| b + 1).sum::<usize>() <= t).count();
        assert!(close(w.p_value, (2.0 * below as f64 / 4096.0).min(1.0), 1e-15));
    }

    #[test]
    fn wilcoxon_large_n_uses_normal() {
        let a: Vec<f64> = (0..80).map(|i| i as f64 + 0.3).collect();
        let b: Vec<f64> = (0..80).map(|i| i as f64 + if i % 4 == 0 { 1.0 } else { -0.1 * i as f64 / 80.0 }).collect();
        let w = wilcoxon_signed_rank(&a, &b).unwrap();
        assert!(!w.exact && w.z.is_some());
        assert!(w.p_value > 0.0 && w.p_value <= 1.0);
    }

    #[test]
    fn wilcoxon_degenerate_inputs() {
        assert!(wilcoxon_signed_rank(&[], &[]).is_err());
        assert!(wilcoxon_signed_rank(&[1.0], &[1.0, 2.0]).is_err());
        assert!(wilcoxon_signed_rank(&[1.0, f64::NAN], &[1.0, 2.0]).is_err());
        assert!(wilcoxon_signed_rank(&[1.0, 2.0], &[1.0, 2.0]).is_err());
        assert!(wilcoxon_signed_rank(&[f64::MAX], &[-f64::MAX]).is_err());
    }

    #[test]
    fn median_and_mean_std() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&[f64::NAN, 1.0]), 1.0);
        assert!(median(&[]).is_nan());
        let (m, s) = mean_std(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]);
        assert_eq!(m, 5.0);
        assert!(close(s, (32.0f64 / 7.0).sqrt(), 1e-15));
        assert_eq!(mean_std(&[3.0]), (3.0, 0.0));
        assert!(mean_std(&[]).0.is_nan());
    }
}

/// ln Γ(x) for x > 0 (Lanczos approximation, g = 7, nine coefficients; relative error ~1e-15).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x)Γ(1−x) = π / sin(πx).
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised incomplete beta function I_x(a, b), by its continued fraction (modified Lentz),
/// using the symmetry I_x(a, b) = 1 − I_{1−x}(b, a) where the fraction converges slowly.
pub fn incomplete_beta(x: f64, a: f64, b: f64) -> f64 {
    if !(x > 0.0) {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    if x > (a + 1.0) / (a + b + 2.0) {
        return 1.0 - incomplete_beta(1.0 - x, b, a);
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    let tiny = 1e-300;
    let (mut c, mut d) = (1.0, 1.0 - (a + b) * x / (a + 1.0));
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut f = d;
    for m in 1..500 {
        let m = m as f64;
        for k in 0..2 {
            let num = if k == 0 {
                m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m))
            } else {
                -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0))
            };
            d = 1.0 + num * d;
            if d.abs() < tiny {
                d = tiny;
            }
            c = 1.0 + num / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            f *= d * c;
        }
        if (d * c - 1.0).abs() < 1e-15 {
            break;
        }
    }
    (ln_front.exp() * f / a).clamp(0.0, 1.0)
}

/// Upper tail P(F > f) of Fisher's F distribution with (d1, d2) degrees of freedom.
pub fn f_survival(f: f64, d1: f64, d2: f64) -> f64 {
    if !(f > 0.0) {
        return 1.0;
    }
    incomplete_beta(d2 / (d2 + d1 * f), 0.5 * d2, 0.5 * d1)
}

/// Nested least-squares models: the p-value of the F test that the larger model (`rss1`, with
/// `extra` more free parameters and `dof1` residual degrees of freedom) fits better than the
/// smaller one (`rss0`) by more than chance.
pub fn nested_f_test(rss0: f64, rss1: f64, extra: usize, dof1: usize) -> f64 {
    if extra == 0 || dof1 == 0 || !(rss1 > 0.0) || rss0 <= rss1 {
        return 1.0;
    }
    let f = ((rss0 - rss1) / extra as f64) / (rss1 / dof1 as f64);
    f_survival(f, extra as f64, dof1 as f64)
}

/// [`nested_f_test`] for values that come in blocks sharing an error, by the first-order
/// Rao–Scott correction: the statistic divided by the design effect `deff` (≥ 1, see
/// [`design_effect`]) and the residual degrees of freedom counted as `dof1 / deff` independent
/// values. `deff = 1` is [`nested_f_test`].
pub fn nested_f_test_deff(rss0: f64, rss1: f64, extra: usize, dof1: usize, deff: f64) -> f64 {
    let deff = if deff.is_finite() { deff.max(1.0) } else { 1.0 };
    if extra == 0 || dof1 == 0 || !(rss1 > 0.0) || rss0 <= rss1 {
        return 1.0;
    }
    let f = ((rss0 - rss1) / extra as f64) / (rss1 / dof1 as f64) / deff;
    f_survival(f, extra as f64, (dof1 as f64 / deff).max(1.0))
}

/// Below this (mm, a nanometre) a length, an RMSE or a difference of two is numerical, not
/// physical: no arm, instrument or logging resolution reaches it, so nothing is judged on it (a
/// noise-free twin dataset fits to ~1e-9 mm before and after).
pub const NUMERICAL_MM: f64 = 1e-6;

/// Below this floor (mm, a tenth of a micrometre) no held-out RMSE is judged against it: real
/// instruments and logs sit orders of magnitude above; only a noise-free twin's does, whose
/// angles are exactly the logged ones.
pub const MIN_JUDGED_FLOOR_MM: f64 = 1e-4;

/// Whether held-out residuals `oof` (`dim` values per row, in blocks `groups`) fall short of
/// the data's floor `floor_mm` by more than twice their mean square's standard error: no model
/// predicts unseen rows better than the floor, so the held-out rows shared errors with the
/// training rows (the split leaks). Never for a floor of at most [`MIN_JUDGED_FLOOR_MM`].
pub fn short_of_floor(oof: &[f64], dim: usize, groups: Option<&[usize]>, floor_mm: f64) -> bool {
    // A floor below a tenth of a micrometre (a noise-free twin's logging resolution, which its
    // exact angles do not even reach) says nothing a model could fall short of.
    if !(floor_mm > MIN_JUDGED_FLOOR_MM) {
        return false;
    }
    let (ms, se) = mean_square_with_se(oof, dim, groups);
    ms + 2.0 * se < floor_mm * floor_mm
}

/// Mean square of the held-out residuals `oof` (`dim` values per row) and its standard error
/// over the rows' blocks `groups` (each row its own block without them): where rows share
/// errors in blocks the realised mean square of a few dozen sweeps strays from the floor's
/// expectation by tens of percent, and only a shortfall beyond twice that error says a split leaks.
pub fn mean_square_with_se(oof: &[f64], dim: usize, groups: Option<&[usize]>) -> (f64, f64) {
    let n_rows = oof.len() / dim.max(1);
    let block = |i: usize| groups.map_or(i, |g| g[i]);
    let n_blocks = (0..n_rows).map(block).max().map_or(0, |m| m + 1);
    let (mut s, mut n) = (vec![0.0; n_blocks], vec![0.0; n_blocks]);
    for i in 0..n_rows {
        s[block(i)] += oof[i * dim..(i + 1) * dim].iter().map(|r| r * r).sum::<f64>();
        n[block(i)] += dim as f64;
    }
    let total: f64 = n.iter().sum();
    if total == 0.0 {
        return (0.0, 0.0);
    }
    let ms = s.iter().sum::<f64>() / total;
    let used = n.iter().filter(|c| **c > 0.0).count() as f64;
    let var = s.iter().zip(&n).map(|(s, n)| (s - ms * n).powi(2)).sum::<f64>() / (total * total) * used / (used - 1.0).max(1.0);
    (ms, var.sqrt())
}

/// The design effect of values that come in blocks (`groups[i]`: row i's block, `dim` values
/// per row, `r` row-major): 1 + (m̄ − 1)·ρ, with ρ the intra-block correlation of each value
/// column (one-way ANOVA estimator, clamped to [0, 1], averaged over the columns) and m̄ = Σm²/N
/// the size-weighted mean block size. How many times larger the variance of a mean over blocks
/// is than over as many independent rows; 1 when every row is its own block.
pub fn design_effect(r: &[f64], dim: usize, groups: &[usize]) -> f64 {
    let n = groups.len();
    let g = groups.iter().copied().max().map_or(0, |m| m + 1);
    if g < 2 || g >= n || r.len() != n * dim {
        return 1.0;
    }
    let mut sizes = vec![0.0; g];
    for &b in groups {
        sizes[b] += 1.0;
    }
    let nf = n as f64;
    let m0 = (nf - sizes.iter().map(|m| m * m).sum::<f64>() / nf) / (g - 1) as f64;
    let mbar = sizes.iter().map(|m| m * m).sum::<f64>() / nf;
    let mut rho = 0.0;
    for c in 0..dim {
        let mut sums = vec![0.0; g];
        for (i, &b) in groups.iter().enumerate() {
            sums[b] += r[i * dim + c];
        }
        let mean = sums.iter().sum::<f64>() / nf;
        let msb = (0..g).map(|b| sizes[b] * (sums[b] / sizes[b] - mean).powi(2)).sum::<f64>() / (g - 1) as f64;
        let msw = groups.iter().enumerate().map(|(i, &b)| (r[i * dim + c] - sums[b] / sizes[b]).powi(2)).sum::<f64>() / (n - g) as f64;
        let denom = msb + (m0 - 1.0) * msw;
        rho += if denom > 0.0 { ((msb - msw) / denom).clamp(0.0, 1.0) } else { 0.0 };
    }
    1.0 + (mbar - 1.0) * rho / dim as f64
}

#[cfg(test)]
mod f_tests {
    use super::*;

    #[test]
    fn f_distribution_matches_tables() {
        // Reference values: F(1, 10) at 4.9646 → 0.05; F(3, 20) at 3.0984 → 0.05; F(2, 100) at
        // 4.8239 → 0.01 (standard F tables); F(1, d) → t²: P(|t_30| > 2.0423) = 0.05.
        for (f, d1, d2, p) in [(4.9646, 1.0, 10.0, 0.05), (3.0984, 3.0, 20.0, 0.05), (4.8239, 2.0, 100.0, 0.01), (2.0423f64.powi(2), 1.0, 30.0, 0.05)] {
            let got = f_survival(f, d1, d2);
            assert!((got - p).abs() < 2e-4, "F({d1}, {d2}) at {f}: {got} vs {p}");
        }
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12 && (ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
        assert!((incomplete_beta(0.3, 2.0, 3.0) - 0.3483).abs() < 1e-4);
        assert_eq!(nested_f_test(1.0, 1.0, 1, 10), 1.0);
        assert_eq!(nested_f_test_deff(2.0, 1.0, 2, 50, 1.0), nested_f_test(2.0, 1.0, 2, 50));
        assert!(nested_f_test_deff(2.0, 1.0, 2, 50, 5.0) > 10.0 * nested_f_test(2.0, 1.0, 2, 50));
    }

    #[test]
    fn design_effect_of_shared_block_errors() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (blocks, m) = (200, 10);
        let groups: Vec<usize> = (0..blocks * m).map(|i| i / m).collect();
        // Independent rows: about 1. A shared block offset of the rows' own size: rho = 1/2,
        // deff = 1 + 9/2.
        let indep: Vec<f64> = (0..blocks * m).map(|_| rng.random_range(-1.0..1.0)).collect();
        assert!((design_effect(&indep, 1, &groups) - 1.0).abs() < 0.3, "{}", design_effect(&indep, 1, &groups));
        let offsets: Vec<f64> = (0..blocks).map(|_| rng.random_range(-1.0..1.0)).collect();
        let shared: Vec<f64> = (0..blocks * m).map(|i| offsets[i / m] + rng.random_range(-1.0..1.0)).collect();
        let d = design_effect(&shared, 1, &groups);
        assert!((d - 5.5).abs() < 1.0, "{d}");
        // Every row its own block: exactly 1.
        let single: Vec<usize> = (0..50).collect();
        assert_eq!(design_effect(&shared[..50], 1, &single), 1.0);
    }
}

/// Two-sample Kolmogorov–Smirnov test: the largest distance D between the empirical
/// distribution functions of `a` and `b` (non-finite values left out), and the asymptotic
/// p-value of D under "both come from one distribution" (Stephens' small-sample correction of
/// the Kolmogorov distribution). `(NaN, NaN)` when either sample is empty.
pub fn ks_two_sample(a: &[f64], b: &[f64]) -> (f64, f64) {
    let sorted = |v: &[f64]| {
        let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        s.sort_by(f64::total_cmp);
        s
    };
    let (a, b) = (sorted(a), sorted(b));
    if a.is_empty() || b.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let (n, m) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j, mut d) = (0, 0, 0.0_f64);
    while i < a.len() && j < b.len() {
        let x = a[i].min(b[j]);
        while i < a.len() && a[i] <= x {
            i += 1;
        }
        while j < b.len() && b[j] <= x {
            j += 1;
        }
        d = d.max((i as f64 / n - j as f64 / m).abs());
    }
    let ne = n * m / (n + m);
    let lambda = (ne.sqrt() + 0.12 + 0.11 / ne.sqrt()) * d;
    // Q_KS(λ) = 2 Σ (−1)^(k−1) exp(−2 k² λ²); 1 for small λ.
    let p = if lambda < 0.2 {
        1.0
    } else {
        let s: f64 = (1..=100).map(|k| (if k % 2 == 1 { 1.0 } else { -1.0 }) * (-2.0 * (k * k) as f64 * lambda * lambda).exp()).sum();
        (2.0 * s).clamp(0.0, 1.0)
    };
    (d, p)
}

#[cfg(test)]
mod ks_tests {
    #[test]
    fn ks_tells_a_shifted_sample_from_a_like_one() {
        // Deterministic quasi-normal samples (inverse CDF by Box–Muller on a lattice).
        let normal = |n: usize, off: f64, phase: f64| -> Vec<f64> {
            (0..n)
                .map(|k| {
                    let u = ((k as f64 + 0.5) / n as f64 + phase).fract().max(1e-9);
                    let v = ((k as f64 * 0.618_034 + phase) % 1.0).max(1e-9);
                    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos() + off
                })
                .collect()
        };
        let (a, b) = (normal(400, 0.0, 0.0), normal(500, 0.0, 0.37));
        let (d, p) = super::ks_two_sample(&a, &b);
        assert!(d < 0.1 && p > 0.05, "like samples: D {d}, p {p}");
        let (d, p) = super::ks_two_sample(&a, &normal(500, 0.5, 0.37));
        assert!(d > 0.15 && p < 1e-4, "shifted by half a sd: D {d}, p {p}");
        assert_eq!(super::ks_two_sample(&a, &a).0, 0.0);
        assert!(super::ks_two_sample(&[], &a).0.is_nan());
    }
}
