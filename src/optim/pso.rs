//! Global-best particle swarm optimisation over a box.
//!
//! Each particle `i` has a position `x_i`, a velocity `v_i` and remembers its personal best
//! `p_i`; the swarm shares the global best `g`. Per iteration `t` of `T`, for every coordinate:
//!
//! ```text
//! w   = w₀ + (w₁ − w₀)·t/(T − 1)                     (inertia, linearly from .0 to .1)
//! v  ← w·v + c₁·r₁·(p_i − x) + c₂·r₂·(g − x),  r₁, r₂ ~ U[0, 1)
//! v  ← clamp(v, −vmax, vmax),  vmax = vmax_fraction·(upper − lower)
//! x  ← x + v
//! ```
//!
//! A coordinate that leaves the box is reflected back into it (mirror at the bound, velocity
//! sign flipped), and clamped if it would still be outside.
//!
//! Costs of the whole swarm are evaluated in parallel with rayon; all random numbers are drawn
//! sequentially on the calling thread in a fixed order and the best is chosen with a fixed
//! tie-break (lowest index), so the result depends only on the seed, not on the thread count.
//! NaN costs count as +∞.
//!
//! Stops after `iterations`, or early when the best cost has not improved by more than
//! `tol·|best|` for `patience` consecutive iterations (`patience = 0` disables this).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::util::{argmin, eval_rows, Stall};
use super::{Bounds, Cost, Event, Observer, Report, Termination};

const METHOD: &str = "pso";

/// Particle swarm settings. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Pso {
    /// Swarm size.
    pub particles: usize,
    /// Maximum number of iterations (swarm moves).
    pub iterations: usize,
    /// Inertia weight, decreasing linearly from `.0` (first iteration) to `.1` (last).
    pub inertia: (f64, f64),
    /// Cognitive (personal-best) acceleration.
    pub c1: f64,
    /// Social (global-best) acceleration.
    pub c2: f64,
    /// Velocity limit as a fraction of each bound's width.
    pub vmax_fraction: f64,
    /// RNG seed (ChaCha8).
    pub seed: u64,
    /// Relative improvement below which an iteration counts as stalled.
    pub tol: f64,
    /// Stalled iterations before stopping (0 = never stop early).
    pub patience: usize,
}

impl Default for Pso {
    fn default() -> Self {
        Pso { particles: 40, iterations: 1000, inertia: (0.9, 0.4), c1: 1.5, c2: 1.5, vmax_fraction: 0.2, seed: 0, tol: 1e-12, patience: 100 }
    }
}

impl Pso {
    /// Minimise `c` over `b`. With `init`, particle 0 starts at `init` (clamped into the box);
    /// the rest start uniformly in the box.
    ///
    /// One [`Event`] per iteration with the global best. `Report::evaluations` counts cost
    /// evaluations; `converged` is true when the run stopped on the stall criterion.
    ///
    /// # Panics
    /// If `b.dim() != c.dim()` or `init` has the wrong length.
    pub fn minimize<C: Cost>(&self, c: &C, b: &Bounds, init: Option<&[f64]>, obs: &mut dyn Observer) -> Report {
        let d = c.dim();
        assert_eq!(b.dim(), d, "bounds have {} dimensions, cost has {d}", b.dim());
        assert_eq!(b.upper.len(), d, "bounds lower/upper lengths differ");
        let np = self.particles.max(1);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);

        let width: Vec<f64> = (0..d).map(|k| b.upper[k] - b.lower[k]).collect();
        let frac = if self.vmax_fraction > 0.0 { self.vmax_fraction } else { 1.0 };
        let vmax: Vec<f64> = width.iter().map(|w| frac * w).collect();

        let mut x = vec![0.0; np * d];
        let mut v = vec![0.0; np * d];
        for (xr, vr) in x.chunks_exact_mut(d).zip(v.chunks_exact_mut(d)) {
            for k in 0..d {
                xr[k] = b.lower[k] + width[k] * rng.random::<f64>();
                vr[k] = vmax[k] * (2.0 * rng.random::<f64>() - 1.0);
            }
        }
        if let Some(x0) = init {
            assert_eq!(x0.len(), d, "init has {} entries, cost has {d} dimensions", x0.len());
            x[..d].copy_from_slice(x0);
            b.clamp(&mut x[..d]);
        }

        let mut fx = vec![0.0; np];
        eval_rows(c, &x, d, &mut fx);
        let mut evaluations = np;
        let mut pbest = x.clone();
        let mut pcost = fx.clone();
        let mut gi = argmin(&pcost);
        let mut gbest = pbest[gi * d..(gi + 1) * d].to_vec();
        let mut gcost = pcost[gi];

        let mut stall = Stall::new(self.tol, self.patience, gcost);
        let mut iterations = 0;
        let mut termination = Termination::Budget;
        let mut reason = "maximum number of iterations reached";
        let (w0, w1) = self.inertia;
        let span = self.iterations.saturating_sub(1).max(1) as f64;

        while iterations < self.iterations {
            let w = w0 + (w1 - w0) * iterations as f64 / span;
            iterations += 1;
            for i in 0..np {
                let row = i * d..(i + 1) * d;
                let (xr, vr, pr) = (&mut x[row.clone()], &mut v[row.clone()], &pbest[row]);
                for k in 0..d {
                    let r1: f64 = rng.random();
                    let r2: f64 = rng.random();
                    let mut vk = w * vr[k] + self.c1 * r1 * (pr[k] - xr[k]) + self.c2 * r2 * (gbest[k] - xr[k]);
                    vk = if vk.is_finite() { vk.clamp(-vmax[k], vmax[k]) } else { 0.0 };
                    let mut xk = xr[k] + vk;
                    if xk < b.lower[k] {
                        xk = 2.0 * b.lower[k] - xk;
                        vk = -vk;
                    } else if xk > b.upper[k] {
                        xk = 2.0 * b.upper[k] - xk;
                        vk = -vk;
                    }
                    xr[k] = xk.clamp(b.lower[k], b.upper[k]);
                    vr[k] = vk;
                }
            }
            eval_rows(c, &x, d, &mut fx);
            evaluations += np;
            for i in 0..np {
                if fx[i] < pcost[i] {
                    pcost[i] = fx[i];
                    pbest[i * d..(i + 1) * d].copy_from_slice(&x[i * d..(i + 1) * d]);
                }
            }
            gi = argmin(&pcost);
            if pcost[gi] < gcost {
                gcost = pcost[gi];
                gbest.copy_from_slice(&pbest[gi * d..(gi + 1) * d]);
            }
            obs.observe(&Event { method: METHOD, iteration: iterations, cost: gcost, x: &gbest });
            if stall.update(gcost) {
                termination = Termination::Stalled;
                reason = "no relative improvement above tol within patience";
                break;
            }
        }

        Report { x: gbest, cost: gcost, iterations, evaluations, termination, reason: reason.to_owned(), covariance: None }
    }
}

#[cfg(test)]
mod tests {
    use super::super::util::testfns::{NanHole, Rosenbrock, Sphere};
    use super::super::NoObserver;
    use super::*;

    fn box5(d: usize) -> Bounds {
        Bounds::new(vec![-5.0; d], vec![5.0; d])
    }

    #[test]
    fn sphere_5d() {
        let pso = Pso { iterations: 600, ..Default::default() };
        let rep = pso.minimize(&Sphere(5), &box5(5), None, &mut NoObserver);
        assert!(rep.cost < 1e-6, "{rep:?}");
    }

    #[test]
    fn rosenbrock_2d() {
        let pso = Pso { iterations: 600, ..Default::default() };
        let rep = pso.minimize(&Rosenbrock, &box5(2), None, &mut NoObserver);
        assert!(rep.cost < 1e-2, "{rep:?}");
        assert!(rep.x.iter().all(|v| (-5.0..=5.0).contains(v)));
    }

    #[test]
    fn deterministic_and_init() {
        let pso = Pso { iterations: 100, seed: 7, ..Default::default() };
        let a = pso.minimize(&Rosenbrock, &box5(2), Some(&[0.5, 0.5]), &mut NoObserver);
        let b = pso.minimize(&Rosenbrock, &box5(2), Some(&[0.5, 0.5]), &mut NoObserver);
        assert_eq!(a.x, b.x);
        assert_eq!(a.cost.to_bits(), b.cost.to_bits());
        // Seeding at the optimum: the best can only be the optimum.
        let c = pso.minimize(&Rosenbrock, &box5(2), Some(&[1.0, 1.0]), &mut NoObserver);
        assert_eq!(c.cost, 0.0);
        // Results do not depend on the rayon thread count.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let e = pool.install(|| pso.minimize(&Rosenbrock, &box5(2), Some(&[0.5, 0.5]), &mut NoObserver));
        assert_eq!(a.x, e.x);
    }

    #[test]
    fn nan_costs_do_not_panic() {
        let rep = Pso { iterations: 200, ..Default::default() }.minimize(&NanHole, &box5(2), None, &mut NoObserver);
        assert!(rep.cost.is_finite() && rep.cost < 1e-6, "{rep:?}");
    }
}
