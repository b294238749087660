//! Pipeline stage "truth comparison": the value each parameter of a calibration model should
//! reach, computed from the truth alone.
//!
//! A D-H or Hayati parameter is not one of the twin's frame errors, so "the truth" of a model
//! parameter is its truth-equivalent value. It is found in two fits, both started from the truth,
//! never from the estimate under test (a calibration stuck in a wrong basin must not be able to
//! agree with its own "truth"):
//!
//! 1. **Map**: the true frame errors (truth.json) are expressed in the model's parametrisation by
//!    fitting the model's flange pose (three points per pose) to the true arm's, from the nominal
//!    model with the true sensor placement.
//! 2. **Equivalent**: with the calibration's non-identifiable parameters held where the
//!    calibration held them, the model is fitted to the noise-free lengths of the same poses
//!    (`length_true_mm`), starting from the mapped truth. What the effects (compliance,
//!    thermal, ...) add to the lengths, a rigid model absorbs here just as it does in the
//!    calibration.

use crate::calib::fit::{ReadingFit, Samples};
use crate::calib::model::CalibModel;
use crate::dataset::truth::TruthFile;
use crate::optim::{LeastSquares, LevenbergMarquardt, NoObserver};
use crate::robot::kinematics::{Chain, FkWork, PointJacobian};
use crate::robot::Robot;
use nalgebra::{DMatrix, Vector3};

/// The model's flange fitted to the true arm's flange: three points per pose, mm.
struct PoseMatch<'a> {
    model: &'a CalibModel,
    /// True positions of the three points per pose, m.
    target: Vec<[Vector3<f64>; 3]>,
    q: &'a [Vec<f64>],
    local: [Vector3<f64>; 3],
}

impl PoseMatch<'_> {
    fn eval(&self, x: &[f64], mut f: impl FnMut(usize, usize, &PointJacobian)) {
        let chain = &self.model.chain;
        let nc = self.model.n_chain();
        let mut ws = FkWork::new(chain);
        let mut jac = PointJacobian::new(chain);
        for (i, q) in self.q.iter().enumerate() {
            chain.forward(q, &x[..nc], 1.0, &mut ws);
            for (a, local) in self.local.iter().enumerate() {
                chain.point_jacobian(&ws, chain.flange(), local, &mut jac);
                f(i, a, &jac);
            }
        }
    }
}

impl LeastSquares for PoseMatch<'_> {
    fn n_params(&self) -> usize {
        self.model.n_params()
    }
    fn n_residuals(&self) -> usize {
        9 * self.q.len()
    }
    fn residuals(&self, x: &[f64], r: &mut [f64]) {
        self.eval(x, |i, a, jac| {
            let d = crate::units::to_mm(jac.point - self.target[i][a]);
            for c in 0..3 {
                r[9 * i + 3 * a + c] = d[c];
            }
        });
    }
    fn jacobian(&self, x: &[f64], j: &mut DMatrix<f64>) {
        j.fill(0.0);
        self.eval(x, |i, a, jac| {
            for (k, d) in jac.dparam.iter().enumerate() {
                for c in 0..3 {
                    j[(9 * i + 3 * a + c, k)] = crate::units::to_mm(d[c]);
                }
            }
        });
    }
}

/// The true frame errors of `robot` (internal units) from a truth file, by parameter name.
fn true_frame_params(robot: &Robot, truth: &TruthFile) -> Option<Vec<f64>> {
    robot.param_names().iter().zip(robot.param_kinds()).map(|(n, kind)| Some(kind.from_file(*truth.parameters.get(n)?))).collect()
}

/// Step 1: the truth in the model's parametrisation (chain deviations and true sensor).
pub fn map_truth(model: &CalibModel, robot: &Robot, truth: &TruthFile, q: &[Vec<f64>]) -> Option<Vec<f64>> {
    let p_true = true_frame_params(robot, truth)?;
    let true_chain: Chain = robot.error_chain();
    let tool = crate::units::to_m(Vector3::from(truth.tool.point_mm));
    let local = [tool, tool + Vector3::new(0.1, 0.0, 0.0), tool + Vector3::new(0.0, 0.1, 0.0)];
    let mut ws = FkWork::new(&true_chain);
    let target = q
        .iter()
        .map(|qi| {
            true_chain.forward(qi, &p_true, 1.0, &mut ws);
            let f = true_chain.frame(&ws, true_chain.flange());
            [f.point(&local[0]), f.point(&local[1]), f.point(&local[2])]
        })
        .collect();
    let nc = model.n_chain();
    let mut x = model.nominal.clone();
    x[..nc].iter_mut().for_each(|v| *v = 0.0);
    let placement = truth.placement();
    if placement.measurement != model.measurement {
        return None;
    }
    model.set_placement(&mut x, &placement);
    let fixed: Vec<bool> = (0..model.n_params()).map(|k| k >= nc).collect();
    let problem = PoseMatch { model, target, q, local };
    let lm = LevenbergMarquardt::budget(200);
    let mapped = lm.minimize(&problem, &x, &fixed, &mut NoObserver).x;
    mapped.iter().all(|v| v.is_finite()).then_some(mapped)
}

/// Steps 1 and 2: the truth-equivalent parameter vector of a calibration that held the
/// parameters `fixed` at the values in `x0`, on the training poses `clean` (noise-free lengths).
/// `None` when the truth file does not describe `robot`'s parameters.
pub fn truth_equivalent(model: &CalibModel, robot: &Robot, truth: &TruthFile, clean: &Samples, x0: &[f64], fixed: &[bool]) -> Option<Vec<f64>> {
    let mut x = map_truth(model, robot, truth, &clean.q)?;
    for k in 0..x.len() {
        if fixed[k] {
            x[k] = x0[k];
        }
    }
    let fit = ReadingFit { model, data: clean };
    let lm = LevenbergMarquardt::budget(500);
    let eq = lm.minimize(&fit, &x, fixed, &mut NoObserver).x;
    eq.iter().all(|v| v.is_finite()).then_some(eq)
}
