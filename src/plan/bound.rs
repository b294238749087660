//! How good any design could be: a certified lower bound on the mean prediction variance (the I
//! criterion, [`prediction_variance`](super::design::prediction_variance)) that any set of `n`
//! candidates of a pool can reach.
//!
//! A set of n candidates is a design putting weight 1/n on each, and its information matrix is n
//! times that design's M(ξ) = Σ ξ_c A_cᵀA_c (plus the ridge ε/n the set's own value carries, R).
//! For any two weightings ξ, ξ* the Cauchy–Schwarz inequality gives
//! Φ(ξ)² ≤ Φ(ξ*) · (Σ ξ*_c φ_c(ξ) + tr(Q R)), with Φ(ξ) = trace((M(ξ) + R)⁻¹W),
//! Q = (M + R)⁻¹W(M + R)⁻¹ and φ_c = trace(A_c Q A_cᵀ): so Φ(ξ*) ≥ Φ(ξ)² / (max_c φ_c + tr(QR))
//! for every ξ*, every n-set among them — whatever ξ is. That bound is certified; how tight it
//! is depends on ξ. The multiplicative algorithm (ξ_c ← ξ_c φ_c/Φ, normalised) drives ξ toward
//! the optimum, where max_c φ_c = Φ; it stops when the gap max φ/Φ − 1 is below [`GAP`] (or
//! after [`MAX_ITERATIONS`]: the bound holds at any gap, only looser).
//!
//! How many random poses a value is worth ([`random_equivalent`]) is an estimate, not a
//! certificate: the median of random draws.

use super::design::{Pool, RIDGE};
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::Serialize;

/// The equivalence gap at which the bound stops tightening: the bound is then within 1 % of
/// the optimum over all weightings.
pub const GAP: f64 = 0.01;
/// Most iterations of the multiplicative algorithm.
pub const MAX_ITERATIONS: usize = 2000;
const EXPONENT: f64 = 1.0;
/// Every this many iterations, every candidate is judged.
const FULL_EVERY: usize = 25;
/// Between full iterations, candidates holding at least this share of a uniform weight, or
/// drawing weight, are updated.
const ACTIVE: f64 = 1e-2;

/// The best any set of `n` candidates of a pool can do, on the I criterion's scale.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Bound {
    /// No set of n candidates has a smaller mean prediction variance than this (certified).
    pub lower: f64,
    /// The smallest mean prediction variance a weighting of the pool reached (n times the
    /// weighting's information; a set of n candidates reaches it only if the weights allow).
    pub reached: f64,
    /// The equivalence gap at the end, max φ / Φ − 1.
    pub gap: f64,
    /// Iterations run.
    pub iterations: usize,
    /// Candidates holding at least 1/(10 n) of the weight at the end.
    pub support: usize,
}

/// Σ ξ_c A_cᵀA_c (no ridge: the weights are positive on every candidate, and the pool
/// identifies every design column).
fn information(pool: &Pool, xi: &[f64], idx: &[usize]) -> DMatrix<f64> {
    let (d, p) = (pool.d, pool.p);
    // The upper triangle, row-major in a flat buffer per thread.
    let acc = |mut m: Vec<f64>, c: &usize| {
        let c = *c;
        let s = xi[c];
        if s > 0.0 {
            for row in pool.rows[c * d * p..(c + 1) * d * p].chunks(p) {
                for i in 0..p {
                    let v = s * row[i];
                    for (mij, rj) in m[i * p + i..(i + 1) * p].iter_mut().zip(&row[i..]) {
                        *mij += v * rj;
                    }
                }
            }
        }
        m
    };
    let add = |mut a: Vec<f64>, b: Vec<f64>| {
        a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
        a
    };
    // Chunks of a fixed size summed in order: the same sum whatever the threads.
    let parts: Vec<Vec<f64>> = idx.par_chunks(256).map(|ch| ch.iter().fold(vec![0.0; p * p], acc)).collect();
    let flat = parts.into_iter().fold(vec![0.0; p * p], add);
    DMatrix::from_fn(p, p, |i, j| if i <= j { flat[i * p + j] } else { flat[j * p + i] })
}

/// φ_c = Σ_rows a Q aᵀ for the candidates `idx`, with `q` symmetric (p×p, flat).
fn directions(pool: &Pool, q: &[f64], idx: &[usize]) -> Vec<f64> {
    let (d, p) = (pool.d, pool.p);
    idx.par_iter()
        .map(|&k| {
            pool.rows[k * d * p..(k + 1) * d * p]
                .chunks(p)
                .map(|a| a.iter().zip(q.chunks(p)).map(|(ai, qi)| ai * qi.iter().zip(a).map(|(x, y)| x * y).sum::<f64>()).sum::<f64>())
                .sum::<f64>()
        })
        .collect()
}

/// The bound for sets of `n` candidates of `pool`, the search started from the set `start`
/// (a plan's: weights half on it, half spread over the pool). Deterministic.
pub fn i_bound(pool: &Pool, n: usize, start: &[usize]) -> Bound {
    let c = pool.len();
    let scale = (n.max(1) * pool.target_dim) as f64;
    let mut xi = vec![if start.is_empty() { 1.0 } else { 0.5 } / c as f64; c];
    for &k in start {
        xi[k] += 0.5 / start.len() as f64;
    }
    let all: Vec<usize> = (0..c).collect();
    let mut out = Bound { lower: 0.0, reached: f64::INFINITY, gap: f64::INFINITY, iterations: 0, support: 0 };
    // Every FULL_EVERY-th iteration judges every candidate (the bound, and which candidates
    // the weight is moving to); in between only those (the rest of M held).
    let (mut active, mut held) = (all.clone(), DMatrix::zeros(pool.p, pool.p));
    for it in 0..MAX_ITERATIONS {
        let full = it % FULL_EVERY == 0;
        let idx = if full { &all } else { &active };
        let ridge = DMatrix::identity(pool.p, pool.p) * (RIDGE / n.max(1) as f64);
        let m = if full { information(pool, &xi, &all) + &ridge } else { &held + information(pool, &xi, &active) + &ridge };
        let Some(chol) = m.cholesky() else {
            break;
        };
        let minv = chol.inverse();
        let phi_all = (&minv * &pool.mean).trace();
        if !(phi_all.is_finite() && phi_all > 0.0) {
            // Nothing to predict (W = 0) or a broken pool: no bound.
            break;
        }
        let q = &minv * &pool.mean * &minv;
        let phi = directions(pool, q.as_slice(), idx);
        out.iterations = it + 1;
        out.reached = out.reached.min(phi_all / scale);
        if full {
            let max_phi = phi.iter().copied().fold(0.0, f64::max);
            out.lower = out.lower.max(phi_all * phi_all / (max_phi + q.trace() * RIDGE / n.max(1) as f64) / scale);
            out.gap = max_phi / phi_all - 1.0;
            if out.gap <= GAP {
                break;
            }
        }
        // The multiplicative step on the candidates judged, their total weight kept.
        let idx = if full { &all } else { &active };
        let before: f64 = idx.iter().map(|&k| xi[k]).sum();
        let mut after = 0.0;
        for (&k, f) in idx.iter().zip(&phi) {
            xi[k] *= (f / phi_all).max(0.0).powf(EXPONENT);
            after += xi[k];
        }
        idx.iter().for_each(|&k| xi[k] *= before / after);
        if full {
            let keep = ACTIVE / c as f64;
            let (a, rest): (Vec<usize>, Vec<usize>) = all.iter().partition(|&&k| xi[k] >= keep || phi[k] > phi_all);
            held = information(pool, &xi, &rest);
            active = a;
        }
    }
    let floor = 0.1 / n.max(1) as f64;
    out.support = xi.iter().filter(|w| **w >= floor).count();
    out
}

/// How many random poses a design is worth: the fewest k (from `n` up to `limit`) whose random
/// sets of k candidates of `pool` (the median of [`super::RANDOM_SETS`] draws from `seed`) have
/// a mean prediction variance at most `value`; `None` when even `limit` do not reach it. Draw r
/// of k poses is the first k of one shuffle of the pool, the same for every k: each draw's
/// variance only falls as k grows (it gains readings), so the median does too, and the
/// bisection over k is exact for these draws.
pub fn random_equivalent(pool: &Pool, n: usize, value: f64, limit: usize, seed: u64) -> Option<usize> {
    let limit = limit.min(pool.len());
    let shuffles: Vec<Vec<usize>> = (0..super::RANDOM_SETS)
        .map(|r| super::random_set(pool.len(), limit, crate::seed::stream_seed(seed, crate::seed::Stream::Plan, 3_000_000 + r as u64)))
        .collect();
    let median = |k: usize| {
        let v: Vec<f64> = shuffles.iter().map(|s| super::design::prediction_variance(&pool.information(&s[..k]), pool)).collect();
        crate::stats::median(&v)
    };
    if limit < n.max(1) || median(limit) > value {
        return None;
    }
    let (mut lo, mut hi) = (n.max(1), limit);
    if median(lo) <= value {
        return Some(lo);
    }
    // median(lo) > value >= median(hi).
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if median(mid) <= value {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// What a plan of `n` poses could be at best, and what it and that best are worth in random
/// feasible poses (predicted, on the I criterion).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Ceiling {
    /// The certified bound for any set of `n` poses of the pool.
    pub bound: Bound,
    /// Random feasible poses whose median predicted variance the plan matches (`None`: more
    /// than `searched_to`).
    pub plan_worth: Option<usize>,
    /// Random feasible poses whose median predicted variance the bound matches: no set of `n`
    /// poses of the pool is worth more (`None`: more than `searched_to`).
    pub best_worth: Option<usize>,
    /// The largest random set tried (8 n, at most the pool).
    pub searched_to: usize,
}

/// The ceiling of the plan `chosen` (its mean prediction variance `value`) over `pool`; why there
/// is none when the plan has fewer reading values than the design has parameters (no set of its
/// size identifies them, and a bound over weightings would not see that), or when the pool gives
/// no finite positive bound (nothing to predict, a singular pool).
pub fn ceiling(pool: &Pool, chosen: &[usize], value: f64, seed: u64) -> Result<Ceiling, String> {
    let n = chosen.len();
    let values = n * pool.d;
    if values < pool.p {
        return Err(format!("{n} poses read {values} values for {} parameters: no set of {n} poses identifies them all (plan more poses)", pool.p));
    }
    let bound = i_bound(pool, n, chosen);
    if !(bound.lower.is_finite() && bound.lower > 0.0 && bound.gap.is_finite()) {
        return Err("the pool gives no finite bound (its information is singular, or nothing to predict)".into());
    }
    let searched_to = (8 * n).min(pool.len());
    Ok(Ceiling {
        plan_worth: random_equivalent(pool, n, value, searched_to, seed),
        best_worth: random_equivalent(pool, n, bound.lower, searched_to, seed),
        bound,
        searched_to,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::design::{criterion, design, prediction_variance};
    use rand::{Rng, SeedableRng};

    fn pool(c: usize, d: usize, p: usize, seed: u64) -> Pool {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        // Candidates of unequal strength, as poses are.
        let rows = (0..c * d * p).map(|i| (rng.random::<f64>() * 2.0 - 1.0) * (1.0 + (i / (d * p)) as f64 % 3.0)).collect();
        Pool::new(rows, d, p)
    }

    #[test]
    fn no_set_of_n_candidates_beats_the_bound_and_the_best_come_close() {
        // Every 3-set of 20 one-value candidates of 3 parameters, against the bound.
        let pl = pool(20, 1, 3, 5);
        let b = i_bound(&pl, 3, &[]);
        assert!(b.gap <= GAP, "{b:?}");
        let mut best = f64::INFINITY;
        for i in 0..20 {
            for j in i + 1..20 {
                for k in j + 1..20 {
                    let v = prediction_variance(&pl.information(&[i, j, k]), &pl);
                    assert!(v >= b.lower * (1.0 - 1e-9), "the set {i},{j},{k} ({v}) beats the bound {b:?}");
                    best = best.min(v);
                }
            }
        }
        assert!(b.lower <= b.reached && b.lower <= best, "{b:?}, best set {best}");
        // A larger pool: the plan and random sets above the bound, the plan within a few %.
        let pl = pool(2000, 3, 8, 6);
        let plan = design(&pl, 12, criterion("i").unwrap(), 8);
        let value = prediction_variance(&pl.information(&plan.chosen), &pl);
        let c = ceiling(&pl, &plan.chosen, value, 1).expect("36 values for 8 parameters");
        assert!(c.bound.lower <= value && value < 1.15 * c.bound.lower, "plan {value}, {c:?}");
        for r in 0..20 {
            let set = crate::plan::random_set(pl.len(), 12, 100 + r);
            assert!(prediction_variance(&pl.information(&set), &pl) > c.bound.lower);
        }
        // What the plan is worth in random poses: more than its own size, no more than the best.
        let (pw, bw) = (c.plan_worth.expect("reached within 8 N"), c.best_worth.expect("reached within 8 N"));
        assert!(12 < pw && pw <= bw, "{c:?}");
        // Fewer values than parameters: no ceiling.
        assert!(ceiling(&pl, &plan.chosen[..2], value, 1).unwrap_err().contains("6 values for 8 parameters"));
    }
}
