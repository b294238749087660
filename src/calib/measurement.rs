//! What the instrument reads on each row, as a calibration model predicts it from the tool point
//! the kinematic chain gives: the reading, its derivatives, and the instrument's placement
//! parameters. One place per measurement type; [`CalibModel`](super::model::CalibModel) appends
//! the placement parameters after the chain's and asks the measurement for the reading.
//!
//! | type | per row | placement parameters (internal units: m) |
//! |---|---|---|
//! | `length` | a draw-wire's cable length `L` | exit point (base frame, 3), length offset (1), tool point (flange frame, 3) |
//!
//! The placement is split in two: the instrument's own parameters (where it sits and its reading
//! offset) and the **target** on the flange (the tool point the cable is hooked to, or the
//! reflector a tracker follows), which the chain carries to the base frame. Derivatives are
//! analytic; the model chains them with the point Jacobian and checks the whole against finite
//! differences.
//!
//! Adding a measurement type (a tracker's 3-D point, a 6-D pose) means one variant here with its
//! reading dimension, parameters, reading and derivatives; the rows' residual vectors, the
//! correctors' output dimension and the dataset columns follow from [`Measurement::dim`].

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Names of the draw-wire's placement parameters, in parameter order.
pub const CABLE_PARAMS: [&str; 7] = ["exit.x", "exit.y", "exit.z", "length_offset", "tool.x", "tool.y", "tool.z"];

/// A measurement type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Measurement {
    /// The cable length of a draw-wire sensor: |tool point − exit point| + length offset.
    #[default]
    Length,
}

impl Measurement {
    /// Every measurement type.
    pub const ALL: [Measurement; 1] = [Measurement::Length];

    /// The name in result files and messages.
    pub fn name(self) -> &'static str {
        match self {
            Measurement::Length => "length",
        }
    }

    /// Values per row (1 for a length).
    pub fn dim(self) -> usize {
        match self {
            Measurement::Length => 1,
        }
    }

    /// The placement parameters' names, the instrument's own first, then the target's.
    pub fn placement_names(self) -> &'static [&'static str] {
        match self {
            Measurement::Length => &CABLE_PARAMS,
        }
    }

    /// Number of placement parameters.
    pub fn n_placement(self) -> usize {
        self.placement_names().len()
    }

    /// Index (among the placement parameters) of the target's first coordinate; the target is
    /// the last three.
    pub fn target_index(self) -> usize {
        self.n_placement() - 3
    }

    /// Index (among the placement parameters) of the constant every reading carries, if the
    /// instrument has one (the draw-wire's length offset).
    pub fn offset_index(self) -> Option<usize> {
        match self {
            Measurement::Length => Some(3),
        }
    }

    /// The reading(s) `y` (m) of target point `p` (base frame, m) for the instrument's own
    /// placement parameters `own` (the placement without the target).
    pub fn reading(self, own: &[f64], p: &Vector3<f64>, y: &mut [f64]) {
        match self {
            Measurement::Length => y[0] = (p - Vector3::new(own[0], own[1], own[2])).norm() + own[3],
        }
    }

    /// [`Self::reading`] with its derivatives: `dy_dp[i]` is ∂y_i/∂p (one row per reading
    /// value) and `dy_down` (row-major, `dim × own.len()`) is ∂y/∂own.
    pub fn reading_grad(self, own: &[f64], p: &Vector3<f64>, y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]) {
        match self {
            Measurement::Length => {
                let d = p - Vector3::new(own[0], own[1], own[2]);
                let dist = d.norm().max(1e-12);
                let u = d / dist;
                y[0] = dist + own[3];
                dy_dp[0] = u;
                dy_down[..4].copy_from_slice(&[-u.x, -u.y, -u.z, 1.0]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reading_derivatives_match_finite_differences() {
        for m in Measurement::ALL {
            let n_own = m.target_index();
            let own: Vec<f64> = (0..n_own).map(|k| 0.3 * (k as f64 * 0.7).sin() + 0.1).collect();
            let p = Vector3::new(0.41, -0.22, 0.35);
            let d = m.dim();
            let (mut y, mut dy_dp, mut dy_down) = (vec![0.0; d], vec![Vector3::zeros(); d], vec![0.0; d * n_own]);
            m.reading_grad(&own, &p, &mut y, &mut dy_dp, &mut dy_down);
            let mut plain = vec![0.0; d];
            m.reading(&own, &p, &mut plain);
            assert!(y.iter().zip(&plain).all(|(a, b)| (a - b).abs() < 1e-15), "{}: {y:?} vs {plain:?}", m.name());
            let h = 1e-7;
            let (mut yp, mut ym) = (vec![0.0; d], vec![0.0; d]);
            for axis in 0..3 {
                let mut e = Vector3::zeros();
                e[axis] = h;
                m.reading(&own, &(p + e), &mut yp);
                m.reading(&own, &(p - e), &mut ym);
                for i in 0..d {
                    let fd = (yp[i] - ym[i]) / (2.0 * h);
                    assert!((fd - dy_dp[i][axis]).abs() < 1e-7, "{} dy{i}/dp{axis}: {fd} vs {}", m.name(), dy_dp[i][axis]);
                }
            }
            for k in 0..n_own {
                let (mut a, mut b) = (own.clone(), own.clone());
                a[k] += h;
                b[k] -= h;
                m.reading(&a, &p, &mut yp);
                m.reading(&b, &p, &mut ym);
                for i in 0..d {
                    let fd = (yp[i] - ym[i]) / (2.0 * h);
                    assert!((fd - dy_down[i * n_own + k]).abs() < 1e-7, "{} dy{i}/down{k}: {fd} vs {}", m.name(), dy_down[i * n_own + k]);
                }
            }
        }
    }

    #[test]
    fn the_target_is_the_last_three_placement_parameters() {
        for m in Measurement::ALL {
            let names = m.placement_names();
            assert_eq!(&names[m.target_index()..], &["tool.x", "tool.y", "tool.z"], "{}", m.name());
        }
    }
}
