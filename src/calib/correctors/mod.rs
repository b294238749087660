//! Non-geometric correctors: what a calibrated model adds to its geometric length prediction.
//!
//! A calibrated model is a geometric backbone (a [`CalibModel`](crate::calib::model::CalibModel) and its parameter vector) plus a
//! *corrector* of what the backbone cannot represent. Every corrector implements [`Correct`]:
//! its length correction in mm at commanded joint angles `q` (rad) and the row's inputs
//! ([`RowInputs`]: time, temperature, joint torques, backlash flanks), and the gradient of that
//! correction with respect to `q` (mm/rad), analytically. `predict`, `compare` and `ik` only ever
//! talk to this trait, so a new corrector needs nothing else.
//!
//! Two families implement it:
//! * learned correctors, stored in a calibration result as one serialisable [`Corrector`] value
//!   (today the Gaussian RBF network; the papers' networks join the enum);
//! * the physical effect blocks of the model itself, seen through [`EffectCorrection`]: the
//!   length change that the effects (compliance, backlash, thermal drift, eccentricity, sensor
//!   nonlinearity) cause relative to the same geometry without them.
//!
//! [`gradient_error`] checks any corrector's gradient against central finite differences.

use crate::calib::correctors::gkan::{Gkan, Mlp};
use crate::calib::correctors::rbf::RbfNetwork;
use crate::calib::effects::RowInputs;
use serde::{Deserialize, Serialize};

pub mod awnn;
mod correct;
pub mod gkan;
pub mod rbf;

pub use correct::{gradient_error, Correct, EffectCorrection};

/// A learned corrector as stored in result.json (`"corrector": {"kind": "rbf", ...}`).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Corrector {
    /// Gaussian RBF network on the joint angles, fitted to the geometric fit's residuals.
    Rbf(RbfNetwork),
    /// Graph KAN over the serial chain (Evo-NPH, see [`gkan`]).
    Gkan(Gkan),
    /// ReLU perceptron of the GKAN's size (Evo-NPH ablation V2).
    Mlp(Mlp),
    /// Adaptive wavelet network (or its MLP / Morlet ablations) learned from the EKF's
    /// innovations (method pso-ekf-awnn, see [`awnn`]).
    Awnn(crate::calib::correctors::awnn::Awnn),
    /// One corrector per reading value of a measurement with several (a tracker's x, y, z).
    Values(PerValue),
}

/// One corrector per reading value (`values[c]` corrects value `c`), for a measurement of
/// several values per row.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PerValue {
    /// The correctors, one per reading value in reading order.
    pub values: Vec<Corrector>,
}

impl Correct for PerValue {
    fn label(&self) -> String {
        format!("{} per reading value", self.values.first().map(|c| c.as_correct().label()).unwrap_or_default())
    }
    fn n_weights(&self) -> usize {
        self.values.iter().map(|c| c.as_correct().n_weights()).sum()
    }
    /// The first value's correction (the one-value API; see [`Self::corrections_mm`]).
    fn correction_mm(&self, q: &[f64], inp: &RowInputs) -> f64 {
        self.values.first().map_or(0.0, |c| c.as_correct().correction_mm(q, inp))
    }
    fn correction_grad_mm(&self, q: &[f64], inp: &RowInputs, g: &mut [f64]) -> f64 {
        self.values.first().map_or(0.0, |c| c.as_correct().correction_grad_mm(q, inp, g))
    }
    fn dim(&self) -> usize {
        self.values.len()
    }
    fn corrections_mm(&self, q: &[f64], inp: &RowInputs, out: &mut [f64]) {
        for (o, c) in out.iter_mut().zip(&self.values) {
            *o = c.as_correct().correction_mm(q, inp);
        }
    }
    fn corrections_grad_mm(&self, q: &[f64], inp: &RowInputs, out: &mut [f64], g: &mut [f64]) {
        let n = q.len();
        for (c, (o, v)) in out.iter_mut().zip(&self.values).enumerate() {
            *o = v.as_correct().correction_grad_mm(q, inp, &mut g[c * n..(c + 1) * n]);
        }
    }
}

impl Corrector {
    /// The corrector of a reading whose values have these correctors, one each: the corrector
    /// itself for one value (a cable length), [`Corrector::Values`] for several.
    pub fn of_values(mut values: Vec<Corrector>) -> Corrector {
        if values.len() == 1 {
            values.swap_remove(0)
        } else {
            Corrector::Values(PerValue { values })
        }
    }

    /// The corrector's kind, as messages name it.
    pub fn name(&self) -> &'static str {
        match self {
            Corrector::Rbf(_) => "RBF network",
            Corrector::Gkan(_) => "graph KAN",
            Corrector::Mlp(_) => "perceptron",
            Corrector::Awnn(_) => "wavelet network",
            Corrector::Values(v) => v.values.first().map_or("per-value corrector", Corrector::name),
        }
    }

    /// The corrector as a [`Correct`].
    pub fn as_correct(&self) -> &dyn Correct {
        match self {
            Corrector::Rbf(n) => n,
            Corrector::Gkan(n) => n,
            Corrector::Mlp(n) => n,
            Corrector::Awnn(n) => n,
            Corrector::Values(v) => v,
        }
    }
    /// Checks a deserialised corrector against the model it belongs to (a hand-edited or
    /// truncated file must not produce NaN predictions silently).
    pub fn validate(&self, n_joints: usize) -> Result<(), String> {
        match self {
            Corrector::Rbf(n) => {
                let ok = n.input_scale.len() == n_joints
                    && n.centers.len() == n.widths.len()
                    && n.centers.len() == n.weights.len()
                    && n.centers.iter().all(|c| c.len() == n_joints && c.iter().all(|v| v.is_finite()))
                    && n.widths.iter().chain(&n.input_scale).all(|v| v.is_finite() && *v > 0.0)
                    && n.weights.iter().all(|v| v.is_finite())
                    && n.bias.is_finite();
                if ok {
                    Ok(())
                } else {
                    Err("the RBF corrector is inconsistent".into())
                }
            }
            Corrector::Gkan(n) => n.validate(n_joints),
            Corrector::Mlp(n) => n.validate(n_joints),
            Corrector::Awnn(n) => n.validate(n_joints),
            Corrector::Values(v) => {
                if v.values.is_empty() || v.values.iter().any(|c| matches!(c, Corrector::Values(_))) {
                    return Err("the per-value corrector must hold one plain corrector per reading value".into());
                }
                v.values.iter().try_for_each(|c| c.validate(n_joints))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::correctors::rbf::RbfOptions;
    use crate::calib::effects::{EffectBlock, EffectKind, ThermalDrive};
    use crate::calib::model::{CalibModel, DrawWireGuess};
    use crate::robot::Robot;

    fn configurations() -> Vec<Vec<f64>> {
        (0..8).map(|k| (0..6).map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin() * 1.5).collect()).collect()
    }

    #[test]
    fn rbf_gradient_matches_finite_differences() {
        let qs = configurations();
        let train: Vec<Vec<f64>> = (0..60).map(|k| (0..6).map(|j| ((k * 11 + j * 5) as f64 * 0.23).cos() * 1.4).collect()).collect();
        let y: Vec<f64> = train.iter().map(|q| 0.05 * q[1].sin() + 0.02 * (q[2] * q[4]).cos()).collect();
        let net = RbfNetwork::fit(&train, &y, &RbfOptions { centers: 12, ..Default::default() }).unwrap();
        let c = Corrector::Rbf(net);
        c.validate(6).unwrap();
        let inp = RowInputs::default();
        let err = gradient_error(c.as_correct(), &qs, &inp, 1e-6);
        assert!(err < 1e-6, "relative gradient error {err}");
        // The value agrees with the network's own prediction.
        let Corrector::Rbf(net) = &c else { unreachable!() };
        let mut g = [0.0; 6];
        assert!((c.as_correct().correction_grad_mm(&qs[0], &inp, &mut g) - net.predict(&qs[0])).abs() < 1e-12);
    }

    #[test]
    fn gkan_and_mlp_gradients_match_finite_differences() {
        use crate::calib::correctors::gkan::GkanShape;
        let qs = configurations();
        let (lo, hi) = Gkan::range_of(&qs);
        let mut g = Gkan::new(GkanShape { grid: 5, edge_grid: 2, chain_joints: 6 }, lo.clone(), hi.clone());
        g.coef.iter_mut().enumerate().for_each(|(k, c)| *c = 0.05 * ((k as f64) * 0.77).sin());
        let c = Corrector::Gkan(g);
        c.validate(6).unwrap();
        let inp = RowInputs::default();
        // Inside the grid (the configurations span it; clamping happens only at the ends).
        let inner: Vec<Vec<f64>> = qs.iter().map(|q| q.iter().zip(lo.iter().zip(&hi)).map(|(v, (l, h))| 0.9 * v + 0.05 * (l + h)).collect()).collect();
        let err = gradient_error(c.as_correct(), &inner, &inp, 1e-6);
        assert!(err < 1e-6, "GKAN relative gradient error {err}");
        let mut m = Mlp::new(7, lo, hi);
        m.w.iter_mut().enumerate().for_each(|(k, c)| *c = ((k as f64) * 1.1).cos());
        let c = Corrector::Mlp(m);
        c.validate(6).unwrap();
        let err = gradient_error(c.as_correct(), &inner, &inp, 1e-7);
        assert!(err < 1e-5, "MLP relative gradient error {err}");
        // Both survive a round trip through result.json's representation.
        let text = serde_json::to_string(&c).unwrap();
        let back: Corrector = serde_json::from_str(&text).unwrap();
        assert!((back.as_correct().correction_mm(&inner[0], &inp) - c.as_correct().correction_mm(&inner[0], &inp)).abs() < 1e-12);
    }

    #[test]
    fn effect_correction_gradient_matches_finite_differences() {
        let robot = Robot::irb120();
        let guess = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.062, 0.004, -0.003] };
        let mut m = CalibModel::dh(&robot, &guess, true);
        for j in 0..6 {
            m.add_effect(EffectBlock::joint(EffectKind::Compliance, j), 3600.0);
            m.add_effect(EffectBlock::joint(EffectKind::Backlash, j), 3600.0);
            m.add_effect(EffectBlock::joint(EffectKind::Eccentricity, j), 3600.0);
        }
        let thermal = Some(ThermalDrive::Temperature { ref_c: 21.0, sensor_lag: false });
        m.add_effect(EffectBlock { kind: EffectKind::Thermal, joint: None, thermal, range_m: None }, 3600.0);
        m.add_effect(EffectBlock { kind: EffectKind::Nonlinearity, joint: None, thermal: None, range_m: Some([0.4, 1.6]) }, 3600.0);
        let mut x = m.nominal.clone();
        for k in m.first_effect()..x.len() {
            x[k] += 2e-4 * ((k as f64) * 1.3).sin();
        }
        let inp = RowInputs {
            t_s: Some(900.0),
            temp_c: Some(24.5),
            torque: vec![1.0, -30.0, 12.0, 0.8, -0.6, 0.1],
            side: vec![1.0, -1.0, 1.0, -1.0, 1.0, 1.0],
            ..Default::default()
        };
        let c = EffectCorrection::new(&m, &x);
        let err = gradient_error(&c, &configurations(), &inp, 1e-6);
        assert!(err < 1e-6, "relative gradient error {err}");
        // It is the whole non-geometric part: geometry + correction = the full prediction.
        let q = &configurations()[3];
        let mut w = m.work();
        let full = m.length(&x, q, &inp, &mut w) * 1e3;
        let mut x_geo = x.clone();
        x_geo[m.first_effect()..].copy_from_slice(&m.nominal[m.first_effect()..]);
        let geo = m.length(&x_geo, q, &inp, &mut w) * 1e3;
        let corr = c.correction_mm(q, &inp);
        assert!(corr.abs() > 1e-3 && (geo + corr - full).abs() < 1e-9, "{geo} + {corr} vs {full}");
        // The model's q-gradient itself (every effect on) against finite differences.
        let mut g = [0.0; 6];
        m.length_grad_q(&x, q, &inp, &mut w, &mut g);
        for j in 0..6 {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += 1e-7;
            qm[j] -= 1e-7;
            let fd = (m.length(&x, &qp, &inp, &mut w) - m.length(&x, &qm, &inp, &mut w)) / 2e-7;
            assert!((fd - g[j]).abs() < 1e-7 * (1.0 + g[j].abs()), "joint {j}: {fd} vs {}", g[j]);
        }
    }
}
