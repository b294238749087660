//! Axis ticks and ranges, shared by the HTML report's SVG plots and the Rerun plots.

/// Finite `(min, max)` of `values`, widened by `pad` of the span on both sides (a zero span
/// becomes ±0.5, or ±10 % of the value); `None` without finite values.
pub fn padded_range(values: impl IntoIterator<Item = f64>, pad: f64) -> Option<(f64, f64)> {
    let (lo, hi) = values.into_iter().filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let span = hi - lo;
    if span <= f64::EPSILON * lo.abs().max(hi.abs()).max(1e-300) {
        let h = if lo == 0.0 { 0.5 } else { 0.1 * lo.abs() };
        return Some((lo - h, hi + h));
    }
    Some((lo - pad * span, hi + pad * span))
}

/// About `n` "nice" tick values (1, 2, 5 × 10^k steps) inside `[lo, hi]`.
pub fn nice_ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) || n == 0 {
        return Vec::new();
    }
    let raw = (hi - lo) / n.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    // The 1-2-5 step whose tick count is closest to n (the larger step on a tie).
    let count = |step: f64| ((hi / step).floor() - (lo / step).ceil() + 1.0).max(0.0);
    let step = [10.0, 5.0, 2.0, 1.0, 0.5].iter().map(|m| m * mag).fold(f64::NAN, |best, s| {
        if best.is_nan() || (count(s) - n as f64).abs() < (count(best) - n as f64).abs() {
            s
        } else {
            best
        }
    });
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).map(|v| if v.abs() < step * 1e-9 { 0.0 } else { v }).collect()
}

/// A tick value printed with as few decimals as its step needs.
pub fn tick_label(v: f64, ticks: &[f64]) -> String {
    let step = ticks.windows(2).map(|w| (w[1] - w[0]).abs()).fold(f64::INFINITY, f64::min);
    let decimals = if step.is_finite() && step > 0.0 { (-step.log10().floor()).clamp(0.0, 6.0) as usize } else { 2 };
    format!("{v:.decimals$}")
}
