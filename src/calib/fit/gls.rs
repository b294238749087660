//! The joint angles' logging error as a noise model: generalised least squares over the
//! acquisition's blocks.
//!
//! A controller that logs angles at 0.1° hands the fit angles off by up to 0.05°, and in a sweep
//! the joints that hold are off by the *same* amount on every row of the sweep (and so is a joint
//! swept in increments that are whole multiples of the step: its logged increments are all the
//! same, see [`crate::calib::fit::noise_model::shares_rounding`]; "holds" below covers both). That error is in
//! the inputs, not the reading: through the reading's derivative with respect to the joint
//! angles, g = ∂y/∂q, it puts a shared, configuration-shaped offset on the sweep's readings. A
//! least-squares fit that takes rows as independent lets any flexible term (an eccentricity, a
//! thermal drift, a network) "explain" those offsets, and then they do not repeat on new sweeps.
//!
//! Here the readings of one block (see [`crate::dataset::blocks`]) have the covariance
//!
//! C = σ²·I + v·Σ_{j holds} g_j g_jᵀ + v·Σ_{j moves} diag(g_j²),
//!
//! with v = step²/12 (a uniform rounding error) per joint and σ² the reading's own noise, and the
//! fit minimises the whitened residual W·r with W = s·L⁻¹ (C = L·Lᵀ; s² the mean variance of one
//! value over every row, so whitened residuals stay on a millimetre scale). Within a block, what
//! is shaped like a holding joint's rounding costs the fit little; what repeats across blocks
//! costs it in full. Blocks of one row get the diagonal weight their rounding gives them.
//!
//! [`Samples::gls`](crate::calib::fit::Samples::gls) carries a [`Whitening`]; every fit of
//! [`ReadingFit`](crate::calib::fit::ReadingFit) on those samples whitens its residuals and
//! Jacobian, and a subset of them keeps the factors of its blocks.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The noise model a fit used: the logging step, what it costs one reading value on average
/// (the angle floor) and the reading's own noise it was given, mm.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct NoiseModel {
    /// Logging step of the joint angles, degrees.
    pub angle_step_deg: f64,
    /// RMS of what the logging step costs one reading value (the angle floor), mm.
    pub rounding_mm: f64,
    /// The reading's own noise the model was given, mm.
    pub reading_noise_mm: f64,
    /// RMS of the logging error estimated in the training readings and taken out of them before
    /// the fit (`calibrate`; absent from a diagnosis, whose fits are whitened instead), mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub removed_rms_mm: Option<f64>,
}

/// The shared input error of a set of rows: everything [`Whitening`] needs for any subset.
#[derive(Debug)]
pub struct RoundingModel {
    /// Values per row.
    pub dim: usize,
    /// Joints per row.
    pub joints: usize,
    /// Block of each row (rows of one block are consecutive).
    pub block: Vec<usize>,
    /// ∂y/∂q of each row, mm/rad, row-major (`dim` rows of `joints`).
    pub jq: Vec<Vec<f64>>,
    /// Whether each joint's logging error is shared by the row's block (it holds, or steps evenly).
    pub holds: Vec<Vec<bool>>,
    /// Variance of one joint's logging error, rad².
    pub var_q: f64,
    /// Variance of the reading's own noise per value, mm².
    pub noise_var: f64,
    /// Mean variance of one value over every row, mm²: the scale of the whitened residuals.
    pub scale_var: f64,
}

impl RoundingModel {
    /// The model for rows with blocks `block`, derivatives `jq` and holding joints `holds`, a
    /// logging step of `step_deg` and a reading noise of `noise_var` mm².
    pub fn new(dim: usize, block: Vec<usize>, jq: Vec<Vec<f64>>, holds: Vec<Vec<bool>>, step_deg: f64, noise_var: f64) -> RoundingModel {
        let joints = holds.first().map_or(0, |h| h.len());
        let var_q = step_deg.to_radians().powi(2) / 12.0;
        let rounding: f64 = jq.iter().map(|g| g.iter().map(|d| d * d).sum::<f64>() * var_q).sum::<f64>() / (jq.len() * dim).max(1) as f64;
        RoundingModel { dim, joints, block, jq, holds, var_q, noise_var, scale_var: noise_var + rounding }
    }

    /// The mean variance per value that the logging adds, mm² (the angle floor squared).
    pub fn rounding_var(&self) -> f64 {
        self.scale_var - self.noise_var
    }

    /// The same model with a reading noise of `noise_var` mm².
    pub fn with_noise_var(self, noise_var: f64) -> RoundingModel {
        let rounding = self.rounding_var();
        RoundingModel { noise_var, scale_var: noise_var + rounding, ..self }
    }

    /// The noise model's figures.
    pub fn summary(&self, step: f64) -> NoiseModel {
        NoiseModel { angle_step_deg: step, rounding_mm: self.rounding_var().sqrt(), reading_noise_mm: self.noise_var.sqrt(), removed_rms_mm: None }
    }
}

/// The whitening of one set of rows of a [`RoundingModel`]: a factor per run of consecutive
/// rows of one block.
#[derive(Clone, Debug)]
pub struct Whitening {
    /// The rounding model whitened.
    pub model: Arc<RoundingModel>,
    /// The model's row of each of these rows.
    pub rows: Vec<usize>,
    /// First value and W = s·L⁻¹ of each run.
    runs: Vec<(usize, DMatrix<f64>)>,
}

impl Whitening {
    /// The whitening of `rows` (the model's rows, in order).
    pub fn new(model: Arc<RoundingModel>, rows: Vec<usize>) -> Whitening {
        let mut runs = Vec::new();
        let mut k = 0;
        while k < rows.len() {
            let b = model.block[rows[k]];
            let end = (k..rows.len()).find(|&e| model.block[rows[e]] != b).unwrap_or(rows.len());
            runs.push((k * model.dim, factor(&model, &rows[k..end])));
            k = end;
        }
        Whitening { model, rows, runs }
    }

    /// The whitening of rows `idx` of these rows.
    pub fn subset(&self, idx: &[usize]) -> Whitening {
        Whitening::new(self.model.clone(), idx.iter().map(|&i| self.rows[i]).collect())
    }

    /// Whitens residuals (one per value, these rows in order) in place.
    pub fn apply(&self, r: &mut [f64]) {
        for (start, w) in &self.runs {
            let n = w.nrows();
            let v = DVector::from_column_slice(&r[*start..start + n]);
            let out = w * v;
            r[*start..start + n].copy_from_slice(out.as_slice());
        }
    }

    /// The logging error in residuals `r` (mm, unwhitened, one per value of these rows): per
    /// run, the offset of each joint that holds (one for the run) and of each joint that moves
    /// (one per row) that the model expects given `r` (its conditional mean, v·gᵀ·C⁻¹·r), each
    /// clamped to half the logging step, as what they put on each value, mm. `r` less this is
    /// what remains for a model of the arm to explain.
    pub fn rounding_estimate(&self, r: &[f64]) -> Vec<f64> {
        let m = &self.model;
        let (d, nj) = (m.dim, m.joints);
        let half = (12.0 * m.var_q).sqrt() / 2.0;
        let mut out = vec![0.0; r.len()];
        for (start, w) in &self.runs {
            let n = w.nrows();
            let rows = &self.rows[start / d..(start + n) / d];
            // C⁻¹·r = Wᵀ·W·r / s².
            let wr = w * DVector::from_column_slice(&r[*start..start + n]);
            let cr = w.transpose() * wr / m.scale_var;
            for j in 0..nj {
                let g = |a: usize| m.jq[rows[a / d]][(a % d) * nj + j];
                // One offset for the run where the joint holds, one per row where it moves.
                let size = if m.holds[rows[0]][j] { n } else { d };
                let groups = (0..n / size).map(|k| k * size..(k + 1) * size);
                for range in groups {
                    let delta = (m.var_q * range.clone().map(|a| g(a) * cr[a]).sum::<f64>()).clamp(-half, half);
                    for a in range {
                        out[start + a] += g(a) * delta;
                    }
                }
            }
        }
        out
    }

    /// Whitens the rows of a Jacobian (one row per value) in place.
    pub fn apply_rows(&self, j: &mut DMatrix<f64>) {
        for (start, w) in &self.runs {
            let n = w.nrows();
            if n == 1 {
                j.row_mut(*start).scale_mut(w[(0, 0)]);
                continue;
            }
            let block = j.rows(*start, n).into_owned();
            j.rows_mut(*start, n).copy_from(&(w * block));
        }
    }
}

/// W = s·L⁻¹ for the rows `rows` of one block.
fn factor(m: &RoundingModel, rows: &[usize]) -> DMatrix<f64> {
    let (d, nj) = (m.dim, m.joints);
    let n = rows.len() * d;
    let mut c = DMatrix::<f64>::identity(n, n) * m.noise_var;
    for j in 0..nj {
        // The joint's derivative over the run's values.
        let g: Vec<f64> = rows.iter().flat_map(|&i| (0..d).map(move |v| m.jq[i][v * nj + j])).collect();
        if m.holds[rows[0]][j] {
            for a in 0..n {
                for b in 0..n {
                    c[(a, b)] += m.var_q * g[a] * g[b];
                }
            }
        } else {
            // One row's values share the row's error of a moving joint.
            for (r, _) in rows.iter().enumerate() {
                for a in r * d..(r + 1) * d {
                    for b in r * d..(r + 1) * d {
                        c[(a, b)] += m.var_q * g[a] * g[b];
                    }
                }
            }
        }
    }
    let s = m.scale_var.sqrt();
    match c.clone().cholesky() {
        Some(ch) => {
            let l = ch.l();
            let inv = l.solve_lower_triangular(&DMatrix::identity(n, n)).unwrap_or_else(|| DMatrix::identity(n, n));
            inv * s
        }
        // Not positive definite (cannot happen with σ² > 0): the rows weighted as they are.
        None => DMatrix::identity(n, n),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whitening_inverts_the_block_covariance() {
        // Two blocks of three rows (one value each) and one of one row; joint 0 holds in the
        // first block, moves in the second.
        let block = vec![0, 0, 0, 1, 1, 1, 2];
        let jq: Vec<Vec<f64>> = (0..7).map(|i| vec![100.0 + 10.0 * i as f64, -50.0 + 3.0 * i as f64]).collect();
        let holds = vec![vec![true, true], vec![true, true], vec![true, true], vec![false, true], vec![false, true], vec![false, true], vec![false, false]];
        let m = Arc::new(RoundingModel::new(1, block, jq.clone(), holds, 0.1, 1e-4));
        let w = Whitening::new(m.clone(), (0..7).collect());
        // W·C·Wᵀ = s²·I on each block.
        let v = m.var_q;
        let cov = |rows: &[usize], hold0: bool| {
            let n = rows.len();
            DMatrix::from_fn(n, n, |a, b| {
                let (i, k) = (rows[a], rows[b]);
                let shared1 = jq[i][1] * jq[k][1] * v;
                let shared0 = if hold0 || a == b { jq[i][0] * jq[k][0] * v } else { 0.0 };
                shared0 + shared1 + if a == b { 1e-4 } else { 0.0 }
            })
        };
        for ((start, f), (rows, hold0)) in w.runs.iter().zip([(vec![0, 1, 2], true), (vec![3, 4, 5], false)]) {
            assert_eq!(*start, rows[0]);
            let id = f * cov(&rows, hold0) * f.transpose() / m.scale_var;
            assert!((id - DMatrix::identity(3, 3)).abs().max() < 1e-9);
        }
        // A subset keeps its blocks' factors; applying to residuals and to a Jacobian agree.
        let sub = w.subset(&[3, 4, 5]);
        let mut r = vec![1.0, -2.0, 0.5];
        let mut j = DMatrix::from_column_slice(3, 1, &r);
        sub.apply(&mut r);
        sub.apply_rows(&mut j);
        assert!((DVector::from_column_slice(&r) - j.column(0)).abs().max() < 1e-12);
        assert!((w.runs[1].1.clone() - sub.runs[0].1.clone()).abs().max() < 1e-12);
    }

    #[test]
    fn the_rounding_estimate_finds_a_sweeps_shared_offset_up_to_half_a_step() {
        // One block of 12 rows (one value each) in which joint 0 holds and joint 1 moves: the
        // residuals are joint 0's shared offset δ through its derivative, plus a little noise.
        let n = 12;
        let jq: Vec<Vec<f64>> = (0..n).map(|i| vec![400.0 + 30.0 * (i as f64 * 0.7).sin(), 200.0 - 10.0 * i as f64]).collect();
        let holds = vec![vec![true, false]; n];
        let step = 0.1;
        let m = Arc::new(RoundingModel::new(1, vec![0; n], jq.clone(), holds, step, 1e-4));
        let w = Whitening::new(m, (0..n).collect());
        let half = step.to_radians() / 2.0;
        for delta in [0.3 * half, -0.8 * half, 3.0 * half] {
            let r: Vec<f64> = (0..n).map(|i| jq[i][0] * delta + 1e-3 * ((i * 7 % 5) as f64 - 2.0)).collect();
            let u = w.rounding_estimate(&r);
            // What remains is the noise, where |δ| is within half a step; beyond, the offset is
            // taken out up to half a step only.
            let expected = delta.clamp(-half, half);
            for i in 0..n {
                assert!((u[i] - jq[i][0] * expected).abs() < 0.05 * (jq[i][0] * half).abs(), "δ {delta}: row {i}: {} against {}", u[i], jq[i][0] * expected);
            }
        }
    }
}
