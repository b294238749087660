//! The logging resolution of a column of numbers, read from its decimals.

/// The logging step of `values`: the largest power of ten 10⁻ᵏ (k = 0..=6) of which every
/// value is a whole multiple; `None` when they carry more than six decimals (or none is finite).
pub fn logging_step(values: impl Iterator<Item = f64> + Clone) -> Option<f64> {
    logging_decimals(values).map(|k| 10f64.powi(-(k as i32)))
}

/// The decimals k of [`logging_step`] (its step is 10⁻ᵏ).
pub fn logging_decimals(values: impl Iterator<Item = f64> + Clone) -> Option<usize> {
    if !values.clone().any(|v| v.is_finite()) {
        return None;
    }
    (0..=6)
        .find(|k| {
            let step = 10f64.powi(-k);
            values.clone().filter(|v| v.is_finite()).all(|v| ((v / step) - (v / step).round()).abs() < 1e-6)
        })
        .map(|k| k as usize)
}
