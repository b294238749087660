//! Small numerical helpers that the twin and the calibration both use (they live below both).

/// Median of the non-NaN values of `v` (mean of the two middle values for even counts);
/// `NaN` when there are none.
pub fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    let m = s.len() / 2;
    if s.len() % 2 == 1 {
        s[m]
    } else {
        0.5 * (s[m - 1] + s[m])
    }
}

/// Legendre polynomials P2..P4 and their derivatives at v. (P0, a constant, is the sensor's
/// length offset; P1, a gain error, is a uniform scale of every measured length, which the
/// geometry and the offset absorb almost entirely: the data cannot tell it apart.)
pub fn legendre(v: f64) -> ([f64; 3], [f64; 3]) {
    let v2 = v * v;
    (
        [0.5 * (3.0 * v2 - 1.0), 0.5 * (5.0 * v2 * v - 3.0 * v), 0.125 * (35.0 * v2 * v2 - 30.0 * v2 + 3.0)],
        [3.0 * v, 0.5 * (15.0 * v2 - 3.0), 0.125 * (140.0 * v2 * v - 60.0 * v)],
    )
}
