//! The learned length correctors of the Evo-NPH method: a graph Kolmogorov–Arnold network
//! (GKAN) over the serial chain, and the matched-size ReLU perceptron of its ablation V2.
//!
//! # GKAN
//!
//! The graph has one node per joint, ordered base to flange. Every joint angle is mapped onto a
//! uniform grid, `t_j = G·(q_j − lo_j)/(hi_j − lo_j)` clamped to `[0, G]` (the range of the
//! training poses; outside it the correction is held constant, with zero gradient). One layer
//! of learnable cubic B-spline edge functions, in two kinds:
//!
//! * a **node edge** per joint, `φ_j(t_j)` on `grid` intervals (`grid + 3` coefficients);
//! * a **chain edge** from each joint `i` to each of its distal neighbours `j > i` (among the
//!   first `chain_joints` joints): the proximal joint's feature passes down the chain and meets
//!   the distal one in a bivariate spline `ψ_ij(t_i, t_j)` on `edge_grid` intervals per axis
//!   (`(edge_grid + 3)²` coefficients). This is where configuration coupling lives (the gravity
//!   torque on joint 2 depends on joints 2 and 3 together, ...).
//!
//! The output, the length correction in mm, is the sum of all edge functions. It is linear in
//! the coefficients: at fixed joint angles (the training poses during DS-ADE) the spline bases
//! are computed once ([`Gkan::basis_row`]) and a network evaluation is one dot product. Its
//! gradient with respect to the joint angles is analytic (derivatives of the bases times the
//! grid scale).
//!
//! The default shape (grid 4, edge grid 2, chain edges among joints 1–5) has 6·7 + 10·25 = 292
//! coefficients; with the 25 identifiable geometric parameters of the IRB 120 (Hayati form) the
//! unified decision vector has 317 dimensions (over 200, as in the paper).
//!
//! # MLP (ablation V2)
//!
//! `6 → h → 1` with ReLU hidden units on the same scaled inputs (mapped to `[−1, 1]`);
//! `8h + 1` weights, `h` chosen to match the GKAN's count. Not linear in its weights.

use serde::{Deserialize, Serialize};

/// Cubic uniform B-spline bases on `g` intervals at grid coordinate `t ∈ [0, g]`: index of the
/// first non-zero basis, the four values and their derivatives with respect to `t`.
fn cubic(t: f64, g: usize) -> (usize, [f64; 4], [f64; 4]) {
    let s = (t.floor().max(0.0) as usize).min(g - 1);
    let u = t - s as f64;
    let v = 1.0 - u;
    let b = [v * v * v / 6.0, (3.0 * u * u * u - 6.0 * u * u + 4.0) / 6.0, (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) / 6.0, u * u * u / 6.0];
    let d = [-v * v / 2.0, (3.0 * u * u - 4.0 * u) / 2.0, (-3.0 * u * u + 2.0 * u + 1.0) / 2.0, u * u / 2.0];
    (s, b, d)
}

/// The shape of a GKAN (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GkanShape {
    /// Intervals of each node edge's grid.
    pub grid: usize,
    /// Intervals per axis of each chain edge's grid.
    pub edge_grid: usize,
    /// Chain edges connect every pair `i < j` among the first `chain_joints` joints.
    pub chain_joints: usize,
}

impl Default for GkanShape {
    fn default() -> Self {
        GkanShape { grid: 4, edge_grid: 2, chain_joints: 5 }
    }
}

/// A graph KAN length corrector (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Gkan {
    /// Joint-angle range mapped onto the grid, rad (per joint).
    pub lo: Vec<f64>,
    /// Upper end of each joint's grid range, rad (see `lo`).
    pub hi: Vec<f64>,
    /// Intervals of each node edge's grid.
    pub grid: usize,
    /// Intervals per axis of each chain edge's grid.
    pub edge_grid: usize,
    /// Chain edges `[proximal, distal]`.
    pub edges: Vec<[usize; 2]>,
    /// Node-edge coefficients (joint by joint), then chain-edge coefficients (edge by edge,
    /// proximal index major), mm.
    pub coef: Vec<f64>,
}

impl Gkan {
    /// A network with zero coefficients whose grid spans `[lo, hi]` per joint.
    pub fn new(shape: GkanShape, lo: Vec<f64>, hi: Vec<f64>) -> Gkan {
        let n = lo.len();
        let c = shape.chain_joints.min(n);
        let edges = (0..c).flat_map(|i| (i + 1..c).map(move |j| [i, j])).collect();
        let mut g = Gkan { lo, hi, grid: shape.grid.max(1), edge_grid: shape.edge_grid.max(1), edges, coef: Vec::new() };
        g.coef = vec![0.0; g.n_coef()];
        g
    }
    /// Grid range from training poses: each joint's min and max, widened by 2 % (at least 1e-3 rad).
    pub fn range_of(qs: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
        let n = qs.first().map_or(0, |q| q.len());
        (0..n)
            .map(|j| {
                let (lo, hi) = qs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| (a.min(q[j]), b.max(q[j])));
                let pad = (0.02 * (hi - lo)).max(1e-3);
                (lo - pad, hi + pad)
            })
            .unzip()
    }
    /// Number of joints (nodes).
    pub fn n_joints(&self) -> usize {
        self.lo.len()
    }
    fn node_len(&self) -> usize {
        self.grid + 3
    }
    fn edge_len(&self) -> usize {
        (self.edge_grid + 3) * (self.edge_grid + 3)
    }
    /// Number of coefficients: `grid + 3` per node edge, `(edge_grid + 3)²` per chain edge.
    pub fn n_coef(&self) -> usize {
        self.n_joints() * self.node_len() + self.edges.len() * self.edge_len()
    }
    /// Grid coordinate of joint `j` on a grid of `g` intervals and dt/dq (0 when clamped).
    fn coord(&self, j: usize, q: f64, g: usize) -> (f64, f64) {
        let scale = g as f64 / (self.hi[j] - self.lo[j]);
        let t = (q - self.lo[j]) * scale;
        if t <= 0.0 {
            (0.0, 0.0)
        } else if t >= g as f64 {
            (g as f64, 0.0)
        } else {
            (t, scale)
        }
    }
    /// Visits every non-zero basis product at `q`: (coefficient index, value, gradient term
    /// `(joint, d value/dq_joint)` pairs).
    fn visit(&self, q: &[f64], mut f: impl FnMut(usize, f64, [(usize, f64); 2])) {
        let nl = self.node_len();
        for j in 0..self.n_joints() {
            let (t, dt) = self.coord(j, q[j], self.grid);
            let (s, b, d) = cubic(t, self.grid);
            for a in 0..4 {
                f(j * nl + s + a, b[a], [(j, d[a] * dt), (j, 0.0)]);
            }
        }
        let (eg, el) = (self.edge_grid, self.edge_len());
        let base = self.n_joints() * nl;
        for (e, &[i, j]) in self.edges.iter().enumerate() {
            let (ti, dti) = self.coord(i, q[i], eg);
            let (tj, dtj) = self.coord(j, q[j], eg);
            let (si, bi, di) = cubic(ti, eg);
            let (sj, bj, dj) = cubic(tj, eg);
            for a in 0..4 {
                for c in 0..4 {
                    let k = base + e * el + (si + a) * (eg + 3) + sj + c;
                    f(k, bi[a] * bj[c], [(i, di[a] * dti * bj[c]), (j, bi[a] * dj[c] * dtj)]);
                }
            }
        }
    }
    /// The bases at `q` as a dense row (len [`Gkan::n_coef`]): the correction is `row · coef`.
    pub fn basis_row(&self, q: &[f64], row: &mut [f64]) {
        row.iter_mut().for_each(|v| *v = 0.0);
        self.visit(q, |k, b, _| row[k] += b);
    }
    /// Correction (mm) at `q` with coefficients `coef`.
    pub fn value_with(&self, coef: &[f64], q: &[f64]) -> f64 {
        let mut f = 0.0;
        self.visit(q, |k, b, _| f += coef[k] * b);
        f
    }
    /// Correction (mm) and its q-gradient (mm/rad) into `g`.
    pub fn value_grad(&self, q: &[f64], g: &mut [f64]) -> f64 {
        g.iter_mut().for_each(|v| *v = 0.0);
        let mut f = 0.0;
        self.visit(q, |k, b, d| {
            let c = self.coef[k];
            f += c * b;
            for (j, dv) in d {
                g[j] += c * dv;
            }
        });
        f
    }
    /// Second differences of the coefficients along every spline axis (rows of a sparse
    /// roughness operator D: `Σ (D c)²` penalises wiggly edge functions).
    pub fn roughness_rows(&self) -> Vec<[(usize, f64); 3]> {
        let mut rows = Vec::new();
        let nl = self.node_len();
        for j in 0..self.n_joints() {
            for a in 0..nl.saturating_sub(2) {
                let k = j * nl + a;
                rows.push([(k, 1.0), (k + 1, -2.0), (k + 2, 1.0)]);
            }
        }
        let m = self.edge_grid + 3;
        let base = self.n_joints() * nl;
        for e in 0..self.edges.len() {
            let at = |a: usize, c: usize| base + e * m * m + a * m + c;
            for a in 0..m {
                for c in 0..m - 2 {
                    rows.push([(at(a, c), 1.0), (at(a, c + 1), -2.0), (at(a, c + 2), 1.0)]);
                    rows.push([(at(c, a), 1.0), (at(c + 1, a), -2.0), (at(c + 2, a), 1.0)]);
                }
            }
        }
        rows
    }
    /// Consistency of a deserialised network with a model of `n_joints` joints.
    pub fn validate(&self, n_joints: usize) -> Result<(), String> {
        let ok = self.lo.len() == n_joints
            && self.hi.len() == n_joints
            && self.lo.iter().zip(&self.hi).all(|(l, h)| l.is_finite() && h.is_finite() && h > l)
            && (1..=64).contains(&self.grid)
            && (1..=16).contains(&self.edge_grid)
            && self.edges.iter().all(|[i, j]| i < j && *j < n_joints)
            && self.coef.len() == self.n_coef()
            && self.coef.iter().all(|v| v.is_finite());
        if ok {
            Ok(())
        } else {
            Err("the GKAN corrector is inconsistent".into())
        }
    }
}

/// A `n → h → 1` ReLU perceptron length corrector (ablation V2), inputs scaled to `[−1, 1]`
/// over `[lo, hi]` (clamped). `w` holds, per hidden unit `k`: `n` input weights, its bias and
/// its output weight; then the output bias (`h·(n + 2) + 1` values).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mlp {
    /// Lower end of each joint's input range, rad (maps to −1).
    pub lo: Vec<f64>,
    /// Upper end of each joint's input range, rad (maps to 1).
    pub hi: Vec<f64>,
    /// Number of hidden units `h`.
    pub hidden: usize,
    /// The weights, mm (layout in the type's docs).
    pub w: Vec<f64>,
}

impl Mlp {
    /// A perceptron with `hidden` units, zero weights, over the input ranges `[lo, hi]` (rad).
    pub fn new(hidden: usize, lo: Vec<f64>, hi: Vec<f64>) -> Mlp {
        let n = lo.len();
        Mlp { lo, hi, hidden, w: vec![0.0; hidden * (n + 2) + 1] }
    }
    /// Hidden units whose weight count is closest to `n_weights`.
    pub fn matched_hidden(n_weights: usize, n_joints: usize) -> usize {
        ((n_weights.saturating_sub(1)) as f64 / (n_joints + 2) as f64).round().max(1.0) as usize
    }
    /// Number of weights, `h·(n + 2) + 1`.
    pub fn n_weights(&self) -> usize {
        self.hidden * (self.lo.len() + 2) + 1
    }
    fn scaled(&self, q: &[f64], x: &mut [f64; 8], dx: &mut [f64; 8]) {
        for j in 0..self.lo.len() {
            let s = 2.0 / (self.hi[j] - self.lo[j]);
            let v = (q[j] - self.lo[j]) * s - 1.0;
            (x[j], dx[j]) = if v <= -1.0 {
                (-1.0, 0.0)
            } else if v >= 1.0 {
                (1.0, 0.0)
            } else {
                (v, s)
            };
        }
    }
    /// Output (mm) with weights `w`; gradients with respect to the weights (`gw`) and the joint
    /// angles (`gq`) when given.
    pub fn eval(&self, w: &[f64], q: &[f64], mut gw: Option<&mut [f64]>, mut gq: Option<&mut [f64]>) -> f64 {
        let n = self.lo.len();
        let (mut x, mut dx) = ([0.0; 8], [0.0; 8]);
        self.scaled(q, &mut x, &mut dx);
        if let Some(g) = gq.as_deref_mut() {
            g.iter_mut().for_each(|v| *v = 0.0);
        }
        let stride = n + 2;
        let mut out = w[self.hidden * stride];
        for k in 0..self.hidden {
            let u = &w[k * stride..(k + 1) * stride];
            let z = u[n] + (0..n).map(|j| u[j] * x[j]).sum::<f64>();
            let a = z.max(0.0);
            out += u[n + 1] * a;
            if let Some(g) = gw.as_deref_mut() {
                let gk = &mut g[k * stride..(k + 1) * stride];
                let on = if z > 0.0 { u[n + 1] } else { 0.0 };
                for j in 0..n {
                    gk[j] = on * x[j];
                }
                gk[n] = on;
                gk[n + 1] = a;
            }
            if z > 0.0 {
                if let Some(g) = gq.as_deref_mut() {
                    for j in 0..n {
                        g[j] += u[n + 1] * u[j] * dx[j];
                    }
                }
            }
        }
        if let Some(g) = gw {
            g[self.hidden * stride] = 1.0;
        }
        out
    }
    /// Checks that the stored network fits an arm of `n_joints` joints (at most 8) and holds only
    /// finite values; the error says it is inconsistent.
    pub fn validate(&self, n_joints: usize) -> Result<(), String> {
        let ok = self.lo.len() == n_joints
            && n_joints <= 8
            && self.hi.len() == n_joints
            && self.lo.iter().zip(&self.hi).all(|(l, h)| l.is_finite() && h.is_finite() && h > l)
            && (1..=4096).contains(&self.hidden)
            && self.w.len() == self.n_weights()
            && self.w.iter().all(|v| v.is_finite());
        if ok {
            Ok(())
        } else {
            Err("the MLP corrector is inconsistent".into())
        }
    }
}

impl crate::calib::correctors::correct::Correct for Gkan {
    fn label(&self) -> String {
        format!("gkan ({} coefficients, {} chain edges)", self.n_coef(), self.edges.len())
    }
    fn n_weights(&self) -> usize {
        self.n_coef()
    }
    fn correction_mm(&self, q: &[f64], _inp: &crate::calib::effects::RowInputs) -> f64 {
        self.value_with(&self.coef, q)
    }
    fn correction_grad_mm(&self, q: &[f64], _inp: &crate::calib::effects::RowInputs, g: &mut [f64]) -> f64 {
        self.value_grad(q, g)
    }
}

impl crate::calib::correctors::correct::Correct for Mlp {
    fn label(&self) -> String {
        format!("mlp ({} hidden ReLU units)", self.hidden)
    }
    fn n_weights(&self) -> usize {
        Mlp::n_weights(self)
    }
    fn correction_mm(&self, q: &[f64], _inp: &crate::calib::effects::RowInputs) -> f64 {
        self.eval(&self.w, q, None, None)
    }
    fn correction_grad_mm(&self, q: &[f64], _inp: &crate::calib::effects::RowInputs, g: &mut [f64]) -> f64 {
        self.eval(&self.w, q, None, Some(g))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_bases_are_a_partition_of_unity_with_exact_derivatives() {
        for k in 0..=40 {
            let t = 4.0 * k as f64 / 40.0;
            let (_, b, d) = cubic(t, 4);
            assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(d.iter().sum::<f64>().abs() < 1e-12);
            let h = 1e-6;
            if t > h && t < 4.0 - h && (t - t.round()).abs() > 1e-3 {
                let (s1, bp, _) = cubic(t + h, 4);
                let (s0, bm, _) = cubic(t - h, 4);
                assert_eq!(s0, s1);
                for a in 0..4 {
                    assert!(((bp[a] - bm[a]) / (2.0 * h) - d[a]).abs() < 1e-7);
                }
            }
        }
    }

    #[test]
    fn gkan_counts_rows_and_roughness() {
        let g = Gkan::new(GkanShape::default(), vec![-1.0; 6], vec![1.0; 6]);
        assert_eq!(g.edges.len(), 10);
        assert_eq!(g.n_coef(), 6 * 7 + 10 * 25);
        g.validate(6).unwrap();
        // Value = basis row · coefficients.
        let mut g = g;
        g.coef.iter_mut().enumerate().for_each(|(k, c)| *c = ((k as f64) * 0.7).sin());
        let q = [0.3, -0.2, 0.5, 0.9, -0.7, 0.1];
        let mut row = vec![0.0; g.n_coef()];
        g.basis_row(&q, &mut row);
        let dot: f64 = row.iter().zip(&g.coef).map(|(a, b)| a * b).sum();
        assert!((dot - g.value_with(&g.coef, &q)).abs() < 1e-12);
        // A constant function has no roughness.
        let flat = vec![1.0; g.n_coef()];
        assert!(g.roughness_rows().iter().all(|r| r.iter().map(|(k, w)| flat[*k] * w).sum::<f64>().abs() < 1e-12));
        // Corrupt files are refused.
        let mut bad = g.clone();
        bad.coef.pop();
        assert!(bad.validate(6).is_err());
        bad = g.clone();
        bad.edges.push([3, 2]);
        assert!(bad.validate(6).is_err());
    }

    #[test]
    fn mlp_weight_gradient_matches_finite_differences() {
        let mut m = Mlp::new(5, vec![-1.0; 6], vec![1.0; 6]);
        m.w.iter_mut().enumerate().for_each(|(k, c)| *c = ((k as f64) * 1.3).sin());
        assert_eq!(m.n_weights(), 41);
        assert_eq!(Mlp::matched_hidden(292, 6), 36);
        let q = [0.3, -0.2, 0.5, 0.9, -0.7, 0.1];
        let mut gw = vec![0.0; m.n_weights()];
        m.eval(&m.w, &q, Some(&mut gw), None);
        for k in 0..m.n_weights() {
            let (mut a, mut b) = (m.w.clone(), m.w.clone());
            a[k] += 1e-6;
            b[k] -= 1e-6;
            let fd = (m.eval(&a, &q, None, None) - m.eval(&b, &q, None, None)) / 2e-6;
            assert!((fd - gw[k]).abs() < 1e-6, "weight {k}: {fd} vs {}", gw[k]);
        }
    }
}
