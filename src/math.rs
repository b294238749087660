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

/// The rotation vector (axis × angle, rad) of the rotation matrix `m`: the angle from its
/// antisymmetric part and trace by atan2, so that a matrix a rounding error away from
/// orthonormal near no turn at all gives a tiny vector, never NaN (an arccosine of a cosine a
/// hair above one does); near a half turn, the rotation nearest `m`.
pub fn rotation_vector(m: &nalgebra::Matrix3<f64>) -> nalgebra::Vector3<f64> {
    let v = nalgebra::Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) * 0.5;
    let (sin, cos) = (v.norm(), ((m.trace() - 1.0) * 0.5).clamp(-1.0, 1.0));
    if cos < -0.99 {
        return nalgebra::Rotation3::from_matrix_eps(m, 1e-12, 100, nalgebra::Rotation3::identity()).scaled_axis();
    }
    if sin == 0.0 {
        return nalgebra::Vector3::zeros();
    }
    v * (sin.atan2(cos) / sin)
}
