//! What the instrument reads on each row, as a calibration model predicts it from the target
//! point the kinematic chain gives: the reading, its derivatives, the instrument's placement
//! parameters and how to place it from nominal target points. One module per measurement type,
//! each implementing [`Instrument`]; [`Measurement`] names them and [`Measurement::def`] is the
//! registry. [`CalibModel`](crate::calib::model::CalibModel) appends the placement parameters after the
//! chain's and asks the measurement for the reading.
//!
//! | type | per row (dataset columns, mm) | placement parameters (internal units: m, rad) |
//! |---|---|---|
//! | `length` ([`length`]) | a draw-wire's cable length `L` | exit point (base frame, 3), length offset (1), tool point (flange frame, 3) |
//! | `point` ([`point`]) | a laser tracker's target position `x, y, z` | base-to-tracker translation (3) and rotation (3), target point (flange frame, 3) |
//!
//! The placement is split in two: the instrument's own parameters (where it sits and its reading
//! offset) and the **target** on the flange (the tool point the cable is hooked to, or the
//! reflector a tracker follows), which the chain carries to the base frame. Derivatives are
//! analytic; the tests below check every type against finite differences.
//!
//! Adding a measurement type means one module implementing [`Instrument`] and its variant with
//! its line in [`Measurement::def`]; the rows' residual vectors follow from [`Measurement::dim`].

pub mod length;
pub mod point;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub use length::CABLE_PARAMS;

/// Largest reading dimension and number of instrument parameters of any measurement type (stack
/// buffers of the hot loops).
pub const MAX_DIM: usize = 6;
pub const MAX_OWN: usize = 12;

/// One measurement type: what an instrument reads of a target point.
pub trait Instrument: Sync {
    /// The name in result files and messages.
    fn name(&self) -> &'static str;
    /// What the instrument is, for messages ("draw-wire cable length").
    fn describe(&self) -> &'static str;
    /// The dataset columns of one reading, in reading order (millimetres).
    fn columns(&self) -> &'static [&'static str];
    /// The placement parameters' names, the instrument's own first, then the target's three.
    fn placement_names(&self) -> &'static [&'static str];
    /// Whether placement parameter `k` is an angle (rad); the others are lengths (m).
    fn placement_is_angle(&self, _k: usize) -> bool {
        false
    }
    /// Index (among the placement parameters) of the constant every reading carries, if the
    /// instrument has one (the draw-wire's length offset).
    fn offset_index(&self) -> Option<usize> {
        None
    }
    /// The reading(s) `y` (m) of target point `p` (base frame, m) for the instrument's own
    /// placement parameters `own` (the placement without the target).
    fn reading(&self, own: &[f64], p: &Vector3<f64>, y: &mut [f64]);
    /// [`Self::reading`] with its derivatives: `dy_dp[i]` is ∂y_i/∂p (one row per reading
    /// value) and `dy_down` (row-major, `dim × own.len()`) is ∂y/∂own.
    fn reading_grad(&self, own: &[f64], p: &Vector3<f64>, y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]);
    /// `None` when value `k` of a reading (mm, as a dataset holds it) is plausible, else what
    /// is wrong with it ("cable length must be positive, found -3").
    fn implausible(&self, k: usize, v_mm: f64) -> Option<String>;
    /// The instrument's own placement from target points `p` (base frame, m, as the nominal
    /// arm puts them) and the readings `y` (m, `dim` per point): the starting guess a
    /// calibration refines. `None` when the points cannot place it.
    fn locate(&self, p: &[Vector3<f64>], y: &[f64]) -> Option<Vec<f64>>;
}

/// A measurement type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Measurement {
    /// The cable length of a draw-wire sensor: |tool point − exit point| + length offset.
    #[default]
    Length,
    /// A laser tracker's 3-D position of its target, in the tracker's frame.
    Point,
}

impl Measurement {
    /// Every measurement type.
    pub const ALL: [Measurement; 2] = [Measurement::Length, Measurement::Point];

    /// The registry: the type's implementation.
    pub fn def(self) -> &'static dyn Instrument {
        match self {
            Measurement::Length => &length::Length,
            Measurement::Point => &point::Point,
        }
    }

    /// The name in result files and messages.
    pub fn name(self) -> &'static str {
        self.def().name()
    }

    /// Values per row (1 for a length, 3 for a point).
    pub fn dim(self) -> usize {
        self.def().columns().len()
    }

    /// The placement parameters' names, the instrument's own first, then the target's.
    pub fn placement_names(self) -> &'static [&'static str] {
        self.def().placement_names()
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

    /// See [`Instrument::offset_index`].
    pub fn offset_index(self) -> Option<usize> {
        self.def().offset_index()
    }

    /// See [`Instrument::reading`].
    pub fn reading(self, own: &[f64], p: &Vector3<f64>, y: &mut [f64]) {
        self.def().reading(own, p, y)
    }

    /// See [`Instrument::reading_grad`].
    pub fn reading_grad(self, own: &[f64], p: &Vector3<f64>, y: &mut [f64], dy_dp: &mut [Vector3<f64>], dy_down: &mut [f64]) {
        self.def().reading_grad(own, p, y, dy_dp, dy_down)
    }

    /// The measurement type with `dim` values per row. Every type has its own dimension (a
    /// test holds it), so rows carry their type in their length.
    pub fn of_dim(dim: usize) -> Option<Measurement> {
        Self::ALL.into_iter().find(|m| m.dim() == dim)
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
            assert!(m.dim() <= MAX_DIM && m.target_index() <= MAX_OWN, "{}", m.name());
        }
    }

    #[test]
    fn every_type_has_its_own_dimension() {
        for m in Measurement::ALL {
            assert_eq!(Measurement::of_dim(m.dim()), Some(m), "{}", m.name());
        }
    }

    #[test]
    fn locate_recovers_the_placement_of_exact_readings() {
        for m in Measurement::ALL {
            let n_own = m.target_index();
            let own: Vec<f64> = (0..n_own).map(|k| 0.2 * (k as f64 * 1.3).cos() + 0.05).collect();
            let pts: Vec<Vector3<f64>> = (0..40)
                .map(|i| Vector3::new(0.3 + 0.2 * (i as f64 * 0.37).sin(), 0.25 * (i as f64 * 0.71).cos(), 0.4 + 0.15 * (i as f64 * 0.23).sin()))
                .collect();
            let mut y = vec![0.0; pts.len() * m.dim()];
            for (p, yi) in pts.iter().zip(y.chunks_mut(m.dim())) {
                m.reading(&own, p, yi);
            }
            let found = m.def().locate(&pts, &y).unwrap_or_else(|| panic!("{}: not located", m.name()));
            for (k, (a, b)) in found.iter().zip(&own).enumerate() {
                assert!((a - b).abs() < 1e-8, "{} own[{k}]: {a} vs {b}", m.name());
            }
        }
    }
}
