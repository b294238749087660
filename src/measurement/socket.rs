//! A ball on the flange seated in a socket of an artifact (a printed or machined plate with
//! sockets a known distance apart): no instrument reads anything, the ball's centre is where the
//! socket holds it. Each socket is an unknown point (a station of its own: the rows say which
//! socket, and on which placement of the artifact, they were seated in), the ball's centre on the
//! flange is the target. The model's "reading" is the ball's centre minus the socket's, three
//! values per row, and every row reads zero: a constant-reading constraint. The sockets of one
//! placement are tied by their known spacing ([`crate::calib::model::Spacing`]), which alone
//! gives the arm its scale; the base frame is never seen (every socket moves with it).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// Names of the placement parameters: the socket's centre (base frame) and the ball's centre
/// (flange frame).
pub const SOCKET_PARAMS: [&str; 6] = ["socket.x", "socket.y", "socket.z", "tool.x", "tool.y", "tool.z"];

/// Least rows seated in one socket to place it (and the ball on the flange) from the data.
pub const MIN_ROWS_PER_SOCKET: usize = 3;

/// Least spread of the flange's orientation over one socket's rows (rad, the largest angle
/// between two of them) for the ball's centre on the flange to be found: turning the tool about
/// the ball is what shows where the ball is.
pub const MIN_TURN_RAD: f64 = 0.05;

/// A ball seated in a socket.
pub struct Socket;

impl super::Block for Socket {
    fn name(&self) -> &'static str {
        "socket"
    }
    fn columns(&self) -> &'static [&'static str] {
        &["dx", "dy", "dz"]
    }
    fn placement_names(&self) -> &'static [&'static str] {
        &SOCKET_PARAMS
    }
    fn reading(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64]) {
        for k in 0..3 {
            y[k] = p[0][k] - own[k];
        }
    }
    fn reading_grad(&self, own: &[f64], p: &[Vector3<f64>], y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]) {
        self.reading(own, p, y);
        for i in 0..3 {
            let mut e = Vector3::zeros();
            e[i] = 1.0;
            dy_dp[i] = e;
            let row = &mut dy_down[i * 3..i * 3 + 3];
            row.iter_mut().enumerate().for_each(|(k, v)| *v = if k == i { -1.0 } else { 0.0 });
        }
    }
    fn exact_grad_reading(&self) -> bool {
        true
    }
}

impl super::FileRows for Socket {
    fn describe(&self) -> &'static str {
        "ball seated in a socket"
    }
    super::reads_nothing!();
    fn feature(&self) -> Option<super::FeatureKind> {
        Some(super::FeatureKind::Socket)
    }
}

impl super::Placing for Socket {
    fn frame(&self, own: &[f64]) -> super::InstrumentFrame {
        super::InstrumentFrame { origin: Vector3::new(own[0], own[1], own[2]), axes: None }
    }
    fn panel_titles(&self) -> (&'static str, &'static str) {
        ("Sockets and ball (mm)", "-")
    }
    /// The socket and the ball's centre on the flange by the pivot fit: the point of the flange
    /// that stays still over the rows (least squares of `p_i + R_i·b = s`, linear in `b` and
    /// `s`). `None` with fewer than [`MIN_ROWS_PER_SOCKET`] rows or an orientation that barely
    /// turns.
    fn locate(&self, p: &[Vector3<f64>], rot: &[Matrix3<f64>], _y: &[f64]) -> Option<(Vec<f64>, Vector3<f64>)> {
        let (b, s) = pivot(p, rot)?;
        Some((vec![s.x, s.y, s.z], b))
    }
}

/// The largest angle (rad) between two of the orientations `rot`.
pub fn turn_spread(rot: &[Matrix3<f64>]) -> f64 {
    let angle = |a: &Matrix3<f64>, b: &Matrix3<f64>| (((a.transpose() * b).trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos();
    rot.iter().map(|a| rot.iter().map(|b| angle(a, b)).fold(0.0, f64::max)).fold(0.0, f64::max)
}

/// The pivot fit: the flange point `b` (flange frame) and the fixed point `s` (base frame) with
/// `p_i + R_i·b ≈ s` over the rows (flange origins `p`, rotations `rot`), by least squares.
pub fn pivot(p: &[Vector3<f64>], rot: &[Matrix3<f64>]) -> Option<(Vector3<f64>, Vector3<f64>)> {
    if p.len() < MIN_ROWS_PER_SOCKET || p.len() != rot.len() || turn_spread(rot) < MIN_TURN_RAD {
        return None;
    }
    let n = p.len();
    let mut a = DMatrix::zeros(3 * n, 6);
    let mut rhs = DVector::zeros(3 * n);
    for (i, (pi, ri)) in p.iter().zip(rot).enumerate() {
        for r in 0..3 {
            for c in 0..3 {
                a[(3 * i + r, c)] = ri[(r, c)];
            }
            a[(3 * i + r, 3 + r)] = -1.0;
            rhs[3 * i + r] = -pi[r];
        }
    }
    let x = a.svd(true, true).solve(&rhs, 1e-12).ok()?;
    let (b, s) = (Vector3::new(x[0], x[1], x[2]), Vector3::new(x[3], x[4], x[5]));
    (b.iter().chain(s.iter()).all(|v| v.is_finite())).then_some((b, s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn the_pivot_fit_finds_the_still_point_and_refuses_a_tool_that_does_not_turn() {
        let (b, s) = (Vector3::new(0.01, -0.02, 0.09), Vector3::new(0.4, 0.1, 0.2));
        let rot: Vec<Matrix3<f64>> =
            (0..8).map(|i| Rotation3::from_euler_angles(0.3 * (i as f64).sin(), 0.4 * (i as f64 * 0.7).cos(), i as f64).into_inner()).collect();
        let p: Vec<Vector3<f64>> = rot.iter().map(|r| s - r * b).collect();
        let (fb, fs) = pivot(&p, &rot).expect("placed");
        assert!((fb - b).norm() < 1e-12 && (fs - s).norm() < 1e-12, "{fb:?} {fs:?}");
        let still = vec![rot[0]; 8];
        let p0: Vec<Vector3<f64>> = still.iter().map(|r| s - r * b).collect();
        assert!(pivot(&p0, &still).is_none(), "one orientation cannot tell the ball's centre");
        assert!(pivot(&p[..2], &rot[..2]).is_none());
    }
}
