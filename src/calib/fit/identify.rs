//! Identifiability of a model's parameters from a given set of poses.
//!
//! The Jacobian of the predicted lengths is scaled column by column (unit norm, so that millimetres
//! and degrees compare), then:
//! * its singular values give the rank and the condition number,
//! * the right singular vectors of the (numerically) zero singular values are the parameter
//!   combinations the data cannot see,
//! * a greedy Gram–Schmidt pass in the model's parameter order picks the identifiable set: a
//!   parameter is kept when its column is not (within tolerance) a combination of those kept before.
//!   The rest are fixed at their nominal values and named.

use super::ReadingFit;
use crate::optim::LeastSquares;
use nalgebra::DMatrix;
use serde::Serialize;

/// A parameter combination the data cannot see: the right singular vector of a (numerically) zero
/// singular value of the scaled Jacobian.
#[derive(Clone, Debug, Serialize)]
pub struct Combination {
    /// Singular value relative to the largest.
    pub relative_singular_value: f64,
    /// Largest components of the right singular vector, by parameter name.
    pub terms: Vec<(String, f64)>,
}

/// What a set of poses can identify of a model's parameters (see the module docs).
#[derive(Clone, Debug, Serialize)]
pub struct Identifiability {
    /// Number of parameters of the model.
    pub n_params: usize,
    /// Rows of the data (poses); the Jacobian has one row per reading value.
    pub n_poses: usize,
    /// Numerical rank of the scaled Jacobian.
    pub rank: usize,
    /// Relative threshold below which a singular value, or a column's residual norm, counts as
    /// zero.
    pub tolerance: f64,
    /// Condition number of the full scaled Jacobian (inf when rank-deficient).
    pub condition_full: f64,
    /// Largest over smallest singular value of the full scaled Jacobian, finite even when it is
    /// numerically rank-deficient: how ill-posed the fit of every parameter would be.
    pub condition_all: f64,
    /// Condition number of the scaled Jacobian of the identifiable parameters.
    pub condition_identifiable: f64,
    /// Singular values of the scaled Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// Names of the parameters fitted.
    pub identifiable: Vec<String>,
    /// Names of the parameters held at their nominal values.
    pub fixed: Vec<String>,
    /// Parameter combinations the data cannot see (null space), strongest terms first.
    pub invisible: Vec<Combination>,
    /// Joints (1-based) that do not move in the data and were held at their median angle for
    /// the analysis (see [`crate::calib::pipeline::identify`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub still_joints: Vec<usize>,
    /// Index mask: true = fixed.
    #[serde(skip)]
    pub fixed_mask: Vec<bool>,
}

/// A column whose norm is below this fraction of the largest is rounding, not a parameter the
/// data see (a still joint's axis: its exponential is the identity up to 1e-16), and is zero
/// for the analysis: scaled to unit length it would look like any other.
const ROUNDING_COLUMN: f64 = 1e-12;

/// The Jacobian with unit columns, and the columns' norms (zero for a column of rounding).
fn scaled(j: &DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    let mut s = j.clone();
    let largest = j.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
    let mut norms = Vec::with_capacity(j.ncols());
    for mut c in s.column_iter_mut() {
        let mut n = c.norm();
        if n <= ROUNDING_COLUMN * largest {
            n = 0.0;
            c.fill(0.0);
        }
        norms.push(n);
        if n > 0.0 {
            c /= n;
        }
    }
    (s, norms)
}

fn condition(m: &DMatrix<f64>) -> f64 {
    if m.ncols() == 0 {
        return 1.0;
    }
    let sv = m.clone().svd(false, false).singular_values;
    let max = sv.max();
    let min = sv.min();
    if min <= 0.0 {
        f64::INFINITY
    } else {
        max / min
    }
}

/// Analyses the Jacobian `j` (poses × parameters). `always_fixed` parameters are fixed regardless
/// (e.g. chosen by the user); `tol` is the relative singular value / residual-norm threshold.
/// `priority` is the order in which parameters are offered to the identifiable set (earlier ones
/// are kept, later ones fixed when they repeat what is already there); empty = model order.
pub fn analyse(j: &DMatrix<f64>, names: &[String], always_fixed: &[bool], tol: f64, priority: &[usize]) -> Identifiability {
    let (m, n) = j.shape();
    let (s, norms) = scaled(j);
    let svd = s.clone().svd(false, true);
    let mut sv: Vec<f64> = svd.singular_values.iter().copied().collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    let smax = sv.first().copied().unwrap_or(0.0).max(1e-300);
    let rank = sv.iter().filter(|v| **v > tol * smax).count();
    let condition_full = if rank < n { f64::INFINITY } else { smax / sv[n - 1] };

    let invisible = invisible_combinations(&svd, &norms, names, tol * smax, smax);

    // Greedy selection in parameter order.
    let mut basis: Vec<nalgebra::DVector<f64>> = Vec::new();
    let mut fixed_mask = vec![false; n];
    let order: Vec<usize> = if priority.len() == n { priority.to_vec() } else { (0..n).collect() };
    for &k in &order {
        if always_fixed.get(k).copied().unwrap_or(false) || norms[k] == 0.0 {
            fixed_mask[k] = true;
            continue;
        }
        let mut v = s.column(k).into_owned();
        for _ in 0..2 {
            for b in &basis {
                let p = b.dot(&v);
                v -= b * p;
            }
        }
        let r = v.norm();
        if r > tol && basis.len() < m {
            basis.push(v / r);
        } else {
            fixed_mask[k] = true;
        }
    }
    fix_weak_combinations(&s, &order, tol, &mut fixed_mask);
    let keep: Vec<usize> = (0..n).filter(|k| !fixed_mask[*k]).collect();
    let sub = DMatrix::from_fn(m, keep.len(), |r, c| s[(r, keep[c])]);
    Identifiability {
        n_params: n,
        n_poses: m,
        rank,
        tolerance: tol,
        condition_full,
        condition_all: if sv.last().is_some_and(|v| *v > 0.0) { smax / sv[sv.len() - 1] } else { f64::INFINITY },
        condition_identifiable: condition(&sub),
        singular_values: sv.iter().map(|v| v / smax).collect(),
        identifiable: keep.iter().map(|k| names[*k].clone()).collect(),
        fixed: (0..n).filter(|k| fixed_mask[*k]).map(|k| names[k].clone()).collect(),
        invisible,
        still_joints: Vec::new(),
        fixed_mask,
    }
}

/// The null space's combinations (the right singular vectors whose singular value is at most
/// `threshold`, their six largest terms above 0.05), and each zero column on its own.
fn invisible_combinations(
    svd: &nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
    norms: &[f64],
    names: &[String],
    threshold: f64,
    smax: f64,
) -> Vec<Combination> {
    let mut invisible = Vec::new();
    if let Some(vt) = &svd.v_t {
        for (i, sigma) in svd.singular_values.iter().enumerate() {
            if *sigma <= threshold {
                let row = vt.row(i);
                let mut terms: Vec<(String, f64)> = row.iter().enumerate().filter(|(_, v)| v.abs() > 0.05).map(|(k, v)| (names[k].clone(), *v)).collect();
                terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
                terms.truncate(6);
                invisible.push(Combination { relative_singular_value: sigma / smax, terms });
            }
        }
    }
    for (k, nrm) in norms.iter().enumerate() {
        if *nrm == 0.0 && !invisible.iter().any(|c| c.terms.len() == 1 && c.terms[0].0 == names[k]) {
            invisible.push(Combination { relative_singular_value: 0.0, terms: vec![(names[k].clone(), 1.0)] });
        }
    }
    invisible
}

/// The greedy pass bounds each column's distance from the span of those before it, not the
/// conditioning of the set: a combination of several kept columns of the scaled Jacobian `s`
/// can still be nearly invisible. While the set's smallest singular value is below `tol` of its
/// largest, fixes the parameter latest in priority (`order`) among those that make up that
/// combination.
fn fix_weak_combinations(s: &DMatrix<f64>, order: &[usize], tol: f64, fixed_mask: &mut [bool]) {
    let n = fixed_mask.len();
    let mut rank_of = vec![0; n];
    for (i, &k) in order.iter().enumerate() {
        rank_of[k] = i;
    }
    // S = QR with orthonormal Q: any set of S's columns has the singular values of the same
    // columns of R, a small square matrix.
    let r_factor = s.clone().qr().r();
    loop {
        let keep: Vec<usize> = (0..n).filter(|k| !fixed_mask[*k]).collect();
        if keep.len() < 2 {
            break;
        }
        let sub = DMatrix::from_fn(r_factor.nrows(), keep.len(), |r, c| r_factor[(r, keep[c])]);
        let svd = sub.svd(false, true);
        let Some(vt) = svd.v_t.as_ref() else { break };
        let (imin, smin) = svd.singular_values.iter().enumerate().fold((0, f64::INFINITY), |a, (i, v)| if *v < a.1 { (i, *v) } else { a });
        let smax = svd.singular_values.max();
        if smin >= tol * smax {
            break;
        }
        let v = vt.row(imin);
        let vmax = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let drop = (0..keep.len()).filter(|&c| v[c].abs() >= 0.1 * vmax).max_by_key(|&c| rank_of[keep[c]]).expect("a unit vector has a largest entry");
        fixed_mask[keep[drop]] = true;
    }
}

/// Stage "identifiability": which parameters these poses determine (the rest are fixed where
/// the start put them). Sensor parameters come first: they are the unknowns of every set-up,
/// while the robot's own parameters have nominal values.
///
/// A joint that does not move in the data ([`still_joints`]) is held at its median angle for
/// the analysis: its jitter (a few encoder counts) would otherwise make its own and its
/// neighbours' parameters look identifiable, and a fit would then buy accuracy through a lever
/// the data cannot see. The tool point absorbs what is fixed. An effect's time constant or lag,
/// which acts only through its size, is judged at a plausible size
/// ([`CalibModel::identifiability_point`](crate::calib::model::CalibModel::identifiability_point)).
pub fn identify(fit: &ReadingFit, x: &[f64], tol: f64) -> Identifiability {
    let nc = fit.model.n_chain();
    let priority: Vec<usize> = (nc..fit.model.n_params()).chain(0..nc).collect();
    let still = still_joints(&fit.data.q);
    let held;
    let data = if still.is_empty() {
        fit.data
    } else {
        let mut d = fit.data.clone();
        for &j in &still {
            let med = crate::stats::median(&d.q.iter().map(|q| q[j]).collect::<Vec<f64>>());
            d.q.iter_mut().for_each(|q| q[j] = med);
        }
        held = d;
        &held
    };
    let at = fit.model.identifiability_point(x);
    let mut id = analyse(&jacobian(&ReadingFit { model: fit.model, data }, &at), &fit.model.names, &vec![false; fit.model.n_params()], tol, &priority);
    id.still_joints = still.iter().map(|j| j + 1).collect();
    // Rows, not residuals: a tracker's row gives three.
    id.n_poses = fit.data.len();
    id
}

/// A joint whose angle spans less than this (degrees) over the rows does not move: a few
/// encoder counts of jitter, which moves a tool point 1 m out by under 1 mm.
pub const STILL_SPAN_DEG: f64 = 0.05;

/// The joints (0-based) that do not move in `q` (rad): span below [`STILL_SPAN_DEG`].
pub fn still_joints(q: &[Vec<f64>]) -> Vec<usize> {
    let n = q.first().map_or(0, |r| r.len());
    (0..n)
        .filter(|&j| {
            let (lo, hi) = q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(r[j]), hi.max(r[j])));
            (hi - lo).to_degrees() < STILL_SPAN_DEG
        })
        .collect()
}

fn jacobian(fit: &ReadingFit, x: &[f64]) -> DMatrix<f64> {
    // The spacings' rows too (a known spacing is what makes the arm's scale identifiable), not
    // the pulls' (a prior says nothing of what the rows see).
    let mut j = DMatrix::zeros(fit.data.y.len() + fit.model.n_spacing_residuals(), fit.model.n_params());
    LeastSquares::jacobian(fit, x, &mut j);
    j
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_dependent_columns_and_names_them() {
        // c2 = c0 + c1: one of the three is unidentifiable; c3 is zero.
        let m = 20;
        let j = DMatrix::from_fn(m, 4, |r, c| {
            let t = r as f64 * 0.3;
            match c {
                0 => t.sin(),
                1 => t.cos(),
                2 => t.sin() + t.cos(),
                _ => 0.0,
            }
        });
        let names: Vec<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
        let id = analyse(&j, &names, &[false; 4], 1e-8, &[]);
        assert_eq!(id.rank, 2);
        assert_eq!(id.identifiable, vec!["a", "b"]);
        assert_eq!(id.fixed, vec!["c", "d"]);
        assert!(id.condition_full.is_infinite());
        assert!(id.condition_identifiable < 10.0);
        assert!(id.invisible.iter().any(|c| c.terms.iter().any(|t| t.0 == "c")));
    }
}
