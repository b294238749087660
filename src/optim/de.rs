//! Differential evolution (DE) family over a box, sharing one engine.
//!
//! # Variants
//!
//! * [`DeVariant::Classic`] — DE/rand/1/bin (Storn & Price 1997) with fixed `F` and `CR`:
//!   `v = x_r1 + F·(x_r2 − x_r3)`.
//! * [`DeVariant::Jade`] — JADE (Zhang & Sanderson 2009): DE/current-to-pbest/1 with an external
//!   archive of replaced parents, `v = x_i + F·(x_pbest − x_i) + F·(x_r1 − x̃_r2)` where `x_pbest`
//!   is drawn from the best `⌈p·N⌉` individuals and `x̃_r2` from population ∪ archive.
//!   Per individual `CR ~ N(μCR, 0.1)` clipped to `[0, 1]`, `F ~ Cauchy(μF, 0.1)` (redrawn while
//!   `≤ 0`, truncated at 1). After each generation `μCR ← (1−c)·μCR + c·mean(S_CR)` and
//!   `μF ← (1−c)·μF + c·mean_Lehmer(S_F)` over the successful parameters.
//! * [`DeVariant::Shade`] — SHADE (Tanabe & Fukunaga 2013): like JADE but `F`/`CR` are drawn
//!   around a randomly chosen slot of `memory`-long success-history memories `M_F`, `M_CR`;
//!   each generation with successes overwrites one slot (round robin) with the improvement-
//!   weighted Lehmer mean of `S_F` and weighted arithmetic mean of `S_CR`. The pbest fraction
//!   is the fixed `p`.
//! * [`DeVariant::LShade`] — L-SHADE (Tanabe & Fukunaga 2014): SHADE plus linear population size
//!   reduction from `pop` to `min_pop` over the evaluation budget (`max_evals`, or
//!   `pop·(generations + 1)` when unset), the weighted Lehmer mean for `M_CR`, a "terminal" `CR`
//!   memory value (once all successful `CR` are 0, that slot always gives `CR = 0`) and an
//!   archive of 2.6·N.
//! * [`DeVariant::DsAde`] — dual-strategy adaptive DE (DS-ADE, after the Evo-NPH calibration
//!   paper): each trial uses DE/current-to-pbest/1 with probability `p1`, else
//!   DE/rand-to-pbest/1 `v = x_r1 + F·(x_pbest − x_r1) + F·(x_r2 − x̃_r3)`, both with the
//!   archive. `p1` is the share of the generation's cumulative fitness gain that
//!   current-to-pbest/1's successes earned (kept in `[p_min, 1 − p_min]`). `F`/`CR` come from
//!   SHADE-style memories updated by gain-weighted Lehmer means (for both `F` and `CR`).
//! * [`DeVariant::RandToPBest`] — the same adaptation with rand-to-pbest/1 only (the DS-ADE
//!   ablation "single-strategy DE").
//!
//! # Engine
//!
//! Every generation is synchronous: all trial vectors are built from the current population
//! (mutation → binomial crossover with one forced coordinate → bound repair), evaluated together
//! in parallel with rayon, then selected one-to-one (`trial ≤ parent` replaces it; a *strict*
//! improvement is a success that feeds adaptation and the archive). All random numbers are drawn
//! on the calling thread in a fixed order and all ties are broken by index, so results depend
//! only on the seed, never on the thread count. NaN costs count as +∞.
//!
//! Costs may refine what they evaluate ([`super::Cost::cost_refine`], Lamarckian: e.g. solving
//! the coordinates the cost is linear in); the refined vector is what enters the population.
//!
//! Bound repair: a trial coordinate outside `[lower, upper]` is set to the midpoint between the
//! parent's coordinate and the violated bound, `(lower + x_i)/2` or `(upper + x_i)/2`.
//!
//! # Extension point: adding a variant
//!
//! The engine knows only two things about a variant, both behind the private `Controller`
//! trait built by `controller_for`:
//!
//! 1. **per trial**, `Controller::plan` returns a `TrialPlan`: the `F`, `CR` *and mutation
//!    operator* (`Mutation`) to use, plus a free `tag` for the controller's bookkeeping;
//! 2. **per generation**, `Controller::end_generation` receives every `Outcome` (the plan that
//!    was used, parent and trial cost, success flag), and `Controller::next_pop_size` /
//!    `Controller::archive_rate` steer population size and archive.
//!
//! A dual-strategy variant (e.g. choosing between DE/rand/1 and DE/current-to-pbest/1 with a
//! probability learned from each operator's success history) is therefore one new
//! `DeVariant` arm, one `Controller` implementation whose `plan` picks the operator (recording
//! it in the plan, so `end_generation` can credit successes to it), and one line in
//! `controller_for`. A genuinely new mutation formula is one new `Mutation` arm plus its
//! branch in `Engine::mutate`; nothing else in the engine changes.
//!
//! # Stopping
//!
//! After `generations`, when the next generation would exceed `max_evals`, or early when the
//! best cost has not improved by more than `tol·|best|` for `patience` consecutive generations
//! (`patience = 0` disables early stopping; this is reported as `converged`).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::util::{argmin, eval_rows_refine, Stall};
use super::{Bounds, Cost, Event, Observer, Report, Termination};

/// Which DE algorithm to run. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub enum DeVariant {
    /// DE/rand/1/bin with fixed scale factor `f` and crossover rate `cr`.
    Classic {
        /// Scale factor `F` of the difference vector.
        f: f64,
        /// Binomial crossover rate `CR`, in `[0, 1]`.
        cr: f64,
    },
    /// JADE: current-to-pbest/1 with archive; `c` is the adaptation rate of μF/μCR, `p` the
    /// pbest fraction.
    Jade {
        /// Adaptation rate of μF and μCR, in `[0, 1]`.
        c: f64,
        /// Pbest fraction: `x_pbest` is drawn from the best `p·N` individuals (at least 2).
        p: f64,
    },
    /// SHADE: success-history memories of length `memory`; `p` the pbest fraction.
    Shade {
        /// Length of the `M_F` and `M_CR` memories (at least 1 is used).
        memory: usize,
        /// Pbest fraction: `x_pbest` is drawn from the best `p·N` individuals (at least 2).
        p: f64,
    },
    /// L-SHADE: SHADE with linear population size reduction down to `min_pop`.
    LShade {
        /// Length of the `M_F` and `M_CR` memories (at least 1 is used).
        memory: usize,
        /// Pbest fraction: `x_pbest` is drawn from the best `p·N` individuals (at least 2).
        p: f64,
        /// Population size at the end of the evaluation budget (at least 4 is used).
        min_pop: usize,
    },
    /// DS-ADE: SHADE-style memories (weighted Lehmer means for both `F` and `CR`) with two
    /// operators, current-to-pbest/1 and rand-to-pbest/1, chosen per trial with a probability
    /// learned from each operator's cumulative fitness gains (kept within `[p_min, 1 − p_min]`).
    DsAde {
        /// Length of the `M_F` and `M_CR` memories (at least 1 is used).
        memory: usize,
        /// Pbest fraction: `x_pbest` is drawn from the best `p·N` individuals (at least 2).
        p: f64,
        /// Least probability of either operator (clamped to `[0, 0.5]`).
        p_min: f64,
    },
    /// Single-strategy DE with success-history adaptation: rand-to-pbest/1 only (the DS-ADE
    /// ablation without the strategy scheduler).
    RandToPBest {
        /// Length of the `M_F` and `M_CR` memories (at least 1 is used).
        memory: usize,
        /// Pbest fraction: `x_pbest` is drawn from the best `p·N` individuals (at least 2).
        p: f64,
    },
}

impl Default for DeVariant {
    fn default() -> Self {
        DeVariant::LShade { memory: 6, p: 0.11, min_pop: 4 }
    }
}

impl DeVariant {
    fn name(&self) -> &'static str {
        match self {
            DeVariant::Classic { .. } => "de",
            DeVariant::Jade { .. } => "jade",
            DeVariant::Shade { .. } => "shade",
            DeVariant::LShade { .. } => "lshade",
            DeVariant::DsAde { .. } => "ds-ade",
            DeVariant::RandToPBest { .. } => "de-rand-to-pbest",
        }
    }
}

/// Differential evolution settings. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct De {
    /// Which DE algorithm to run, with its own parameters.
    pub variant: DeVariant,
    /// (Initial) population size; at least 4 is used.
    pub pop: usize,
    /// Maximum number of generations.
    pub generations: usize,
    /// Optional cap on cost evaluations (never exceeded); also the L-SHADE reduction horizon.
    pub max_evals: Option<usize>,
    /// RNG seed (ChaCha8).
    pub seed: u64,
    /// Relative improvement below which a generation counts as stalled.
    pub tol: f64,
    /// Stalled generations before stopping (0 = never stop early).
    pub patience: usize,
}

impl Default for De {
    fn default() -> Self {
        De { variant: DeVariant::default(), pop: 50, generations: 1000, max_evals: None, seed: 0, tol: 1e-12, patience: 100 }
    }
}

// ---------------------------------------------------------------------------------------------
// Engine ↔ variant interface
// ---------------------------------------------------------------------------------------------

/// Mutation operators the engine implements.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mutation {
    /// `v = x_r1 + F·(x_r2 − x_r3)`, r1, r2, r3 distinct and ≠ i.
    Rand1,
    /// `v = x_i + F·(x_pbest − x_i) + F·(x_r1 − x̃_r2)`, pbest among the best `max(2, round(p·N))`,
    /// r1 from the population, r2 from population ∪ archive, all distinct from i and each other.
    CurrentToPBest1 { p: f64 },
    /// `v = x_r1 + F·(x_pbest − x_r1) + F·(x_r2 − x̃_r3)`: a random base vector pulled towards a
    /// pbest individual; r1, r2 from the population, r3 from population ∪ archive, all distinct.
    RandToPBest1 { p: f64 },
}

/// What a controller decides for one trial vector.
#[derive(Clone, Copy, Debug)]
struct TrialPlan {
    f: f64,
    cr: f64,
    op: Mutation,
    /// Controller-private bookkeeping (memory slot, strategy id, ...).
    #[allow(dead_code)]
    tag: usize,
}

/// Result of one parent/trial comparison, handed back to the controller.
#[derive(Clone, Copy, Debug)]
struct Outcome {
    plan: TrialPlan,
    parent_cost: f64,
    #[allow(dead_code)]
    trial_cost: f64,
    /// Strictly better than the parent.
    success: bool,
}

impl Outcome {
    /// Improvement used as a weight; +∞ when a finite trial replaced an infinite (NaN) parent.
    fn gain(&self) -> f64 {
        self.parent_cost - self.trial_cost
    }
}

/// The per-variant policy. See "Extension point" in the module documentation.
trait Controller {
    /// Parameters and operator for the next trial vector.
    fn plan(&mut self, rng: &mut ChaCha8Rng) -> TrialPlan;
    /// Learn from the generation's outcomes (all of them, successful or not, in index order).
    fn end_generation(&mut self, outcomes: &[Outcome]);
    /// Archive capacity as a multiple of the current population size (0 = no archive).
    fn archive_rate(&self) -> f64 {
        0.0
    }
    /// Population size for the next generation, given evaluations so far and the budget.
    fn next_pop_size(&self, current: usize, _evals: usize, _budget: usize) -> usize {
        current
    }
}

fn controller_for(v: &DeVariant, pop: usize) -> Box<dyn Controller> {
    match *v {
        DeVariant::Classic { f, cr } => Box::new(Classic { f, cr }),
        DeVariant::Jade { c, p } => Box::new(Jade { c, p, mu_f: 0.5, mu_cr: 0.5, s_f: Vec::new(), s_cr: Vec::new() }),
        DeVariant::Shade { memory, p } => Box::new(Shade::new(memory, p, None, pop)),
        DeVariant::LShade { memory, p, min_pop } => Box::new(Shade::new(memory, p, Some(min_pop.max(4)), pop)),
        DeVariant::DsAde { memory, p, p_min } => Box::new(DualStrategy::new(memory, p, p_min.clamp(0.0, 0.5), true)),
        DeVariant::RandToPBest { memory, p } => Box::new(DualStrategy::new(memory, p, 0.0, false)),
    }
}

/// `N(mean, sd)` clipped to `[0, 1]`.
fn sample_cr(rng: &mut ChaCha8Rng, mean: f64) -> f64 {
    let e: f64 = rng.sample(StandardNormal);
    (mean + 0.1 * e).clamp(0.0, 1.0)
}

/// `Cauchy(loc, 0.1)` redrawn while ≤ 0, truncated at 1.
fn sample_f(rng: &mut ChaCha8Rng, loc: f64) -> f64 {
    for _ in 0..64 {
        let u: f64 = rng.random();
        let f = loc + 0.1 * (std::f64::consts::PI * (u - 0.5)).tan();
        if f > 0.0 {
            return f.min(1.0);
        }
    }
    loc.clamp(0.1, 1.0)
}

/// Sum of the successes' weights (fitness gains); when they are not a positive finite sum,
/// every success gets weight 1 instead.
fn success_weight_sum(succ: &mut [(f64, f64, f64)]) -> f64 {
    let wsum: f64 = succ.iter().map(|s| s.0).sum();
    if wsum > 0.0 && wsum.is_finite() {
        return wsum;
    }
    succ.iter_mut().for_each(|s| s.0 = 1.0);
    succ.len() as f64
}

/// `Σ wᵢ·vᵢ² / Σ wᵢ·vᵢ`.
fn lehmer(v: impl Iterator<Item = (f64, f64)>) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (w, x) in v {
        num += w * x * x;
        den += w * x;
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// DE/rand/1/bin.
struct Classic {
    f: f64,
    cr: f64,
}
impl Controller for Classic {
    fn plan(&mut self, _rng: &mut ChaCha8Rng) -> TrialPlan {
        TrialPlan { f: self.f, cr: self.cr, op: Mutation::Rand1, tag: 0 }
    }
    fn end_generation(&mut self, _outcomes: &[Outcome]) {}
}

/// JADE adaptation.
struct Jade {
    c: f64,
    p: f64,
    mu_f: f64,
    mu_cr: f64,
    s_f: Vec<f64>,
    s_cr: Vec<f64>,
}
impl Controller for Jade {
    fn plan(&mut self, rng: &mut ChaCha8Rng) -> TrialPlan {
        let cr = sample_cr(rng, self.mu_cr);
        let f = sample_f(rng, self.mu_f);
        TrialPlan { f, cr, op: Mutation::CurrentToPBest1 { p: self.p }, tag: 0 }
    }
    fn end_generation(&mut self, outcomes: &[Outcome]) {
        self.s_f.clear();
        self.s_cr.clear();
        for o in outcomes.iter().filter(|o| o.success) {
            self.s_f.push(o.plan.f);
            self.s_cr.push(o.plan.cr);
        }
        if self.s_f.is_empty() {
            return;
        }
        let mean_cr = self.s_cr.iter().sum::<f64>() / self.s_cr.len() as f64;
        self.mu_cr = (1.0 - self.c) * self.mu_cr + self.c * mean_cr;
        self.mu_f = (1.0 - self.c) * self.mu_f + self.c * lehmer(self.s_f.iter().map(|&f| (1.0, f)));
    }
    fn archive_rate(&self) -> f64 {
        1.0
    }
}

/// SHADE, or L-SHADE when `lshade` holds `(min_pop, initial_pop)`.
struct Shade {
    p: f64,
    m_f: Vec<f64>,
    /// NaN marks L-SHADE's terminal value ⊥ (CR = 0 from that slot).
    m_cr: Vec<f64>,
    next: usize,
    lshade: Option<(usize, usize)>,
    /// Scratch: (weight, F, CR) of the generation's successes.
    succ: Vec<(f64, f64, f64)>,
}
impl Shade {
    fn new(memory: usize, p: f64, min_pop: Option<usize>, pop: usize) -> Self {
        let h = memory.max(1);
        Shade { p, m_f: vec![0.5; h], m_cr: vec![0.5; h], next: 0, lshade: min_pop.map(|m| (m, pop)), succ: Vec::new() }
    }
}
impl Controller for Shade {
    fn plan(&mut self, rng: &mut ChaCha8Rng) -> TrialPlan {
        let slot = rng.random_range(0..self.m_f.len());
        let mcr = self.m_cr[slot];
        let cr = if mcr.is_nan() { 0.0 } else { sample_cr(rng, mcr) };
        let f = sample_f(rng, self.m_f[slot]);
        TrialPlan { f, cr, op: Mutation::CurrentToPBest1 { p: self.p }, tag: slot }
    }
    fn end_generation(&mut self, outcomes: &[Outcome]) {
        self.succ.clear();
        let any_inf = outcomes.iter().any(|o| o.success && !o.gain().is_finite());
        for o in outcomes.iter().filter(|o| o.success) {
            let g = o.gain();
            // Improvements from +∞ parents dominate: weight them equally, the rest zero.
            let w = if any_inf { f64::from(u8::from(!g.is_finite())) } else { g };
            self.succ.push((w, o.plan.f, o.plan.cr));
        }
        if self.succ.is_empty() {
            return;
        }
        let wsum = success_weight_sum(&mut self.succ);
        let k = self.next;
        self.m_f[k] = lehmer(self.succ.iter().map(|s| (s.0 / wsum, s.1)));
        if self.lshade.is_some() {
            let max_cr = self.succ.iter().map(|s| s.2).fold(0.0, f64::max);
            self.m_cr[k] = if self.m_cr[k].is_nan() || max_cr == 0.0 { f64::NAN } else { lehmer(self.succ.iter().map(|s| (s.0 / wsum, s.2))) };
        } else {
            self.m_cr[k] = self.succ.iter().map(|s| s.0 / wsum * s.2).sum();
        }
        self.next = (k + 1) % self.m_f.len();
    }
    fn archive_rate(&self) -> f64 {
        if self.lshade.is_some() {
            2.6
        } else {
            1.0
        }
    }
    fn next_pop_size(&self, current: usize, evals: usize, budget: usize) -> usize {
        match self.lshade {
            Some((min_pop, init)) if budget > 0 => {
                let frac = (evals as f64 / budget as f64).min(1.0);
                let target = (init as f64 + (min_pop as f64 - init as f64) * frac).round() as usize;
                target.clamp(min_pop.min(current), current)
            }
            _ => current,
        }
    }
}

/// DS-ADE (and its single-strategy ablation). Per trial: a memory slot `k` at random,
/// `F ~ Cauchy(M_F[k], 0.1)`, `CR ~ N(M_CR[k], 0.1)`, and operator 1 (current-to-pbest/1) with
/// probability `p1`, else operator 2 (rand-to-pbest/1). After a generation with successes, slot
/// `next` of both memories takes the gain-weighted Lehmer mean of the successful values, and
/// `p1 ← Σ_{S1} Δf / (Σ_{S1} Δf + Σ_{S2} Δf)` over the operators' successful trials (unchanged
/// without successes), clamped to `[p_min, 1 − p_min]` so neither operator dies out.
struct DualStrategy {
    p: f64,
    p_min: f64,
    dual: bool,
    p1: f64,
    m_f: Vec<f64>,
    m_cr: Vec<f64>,
    next: usize,
    succ: Vec<(f64, f64, f64)>,
}
impl DualStrategy {
    fn new(memory: usize, p: f64, p_min: f64, dual: bool) -> Self {
        let h = memory.max(1);
        DualStrategy { p, p_min, dual, p1: if dual { 0.5 } else { 0.0 }, m_f: vec![0.5; h], m_cr: vec![0.5; h], next: 0, succ: Vec::new() }
    }
}
impl Controller for DualStrategy {
    fn plan(&mut self, rng: &mut ChaCha8Rng) -> TrialPlan {
        let slot = rng.random_range(0..self.m_f.len());
        let cr = sample_cr(rng, self.m_cr[slot]);
        let f = sample_f(rng, self.m_f[slot]);
        let first = self.dual && rng.random::<f64>() < self.p1;
        let op = if first { Mutation::CurrentToPBest1 { p: self.p } } else { Mutation::RandToPBest1 { p: self.p } };
        TrialPlan { f, cr, op, tag: slot }
    }
    fn end_generation(&mut self, outcomes: &[Outcome]) {
        self.succ.clear();
        let (mut g1, mut g2) = (0.0, 0.0);
        for o in outcomes.iter().filter(|o| o.success) {
            // A finite trial replacing an infinite parent counts as one unit of gain.
            let g = if o.gain().is_finite() { o.gain() } else { 1.0 };
            self.succ.push((g, o.plan.f, o.plan.cr));
            match o.plan.op {
                Mutation::CurrentToPBest1 { .. } => g1 += g,
                _ => g2 += g,
            }
        }
        if self.succ.is_empty() {
            return;
        }
        if self.dual && g1 + g2 > 0.0 {
            self.p1 = (g1 / (g1 + g2)).clamp(self.p_min, 1.0 - self.p_min);
        }
        let wsum = success_weight_sum(&mut self.succ);
        let k = self.next;
        self.m_f[k] = lehmer(self.succ.iter().map(|s| (s.0 / wsum, s.1)));
        let cr = lehmer(self.succ.iter().map(|s| (s.0 / wsum, s.2)));
        // All-zero successful CR: keep the slot's value rather than locking CR at 0.
        if cr > 0.0 {
            self.m_cr[k] = cr;
        }
        self.next = (k + 1) % self.m_f.len();
    }
    fn archive_rate(&self) -> f64 {
        1.0
    }
}

// ---------------------------------------------------------------------------------------------
// Engine
// ---------------------------------------------------------------------------------------------

/// Population state and work buffers (row-major `n × d` matrices).
struct Engine<'b> {
    d: usize,
    b: &'b Bounds,
    x: Vec<f64>,
    fx: Vec<f64>,
    trials: Vec<f64>,
    tcost: Vec<f64>,
    plans: Vec<TrialPlan>,
    /// Population indices sorted by cost (for pbest), refreshed each generation.
    rank: Vec<usize>,
    archive: Vec<f64>,
    archive_len: usize,
}

impl<'b> Engine<'b> {
    fn n(&self) -> usize {
        self.fx.len()
    }

    fn row(&self, i: usize) -> &[f64] {
        &self.x[i * self.d..(i + 1) * self.d]
    }

    /// Row `j` of population ∪ archive.
    fn pool_row(&self, j: usize) -> &[f64] {
        let n = self.n();
        if j < n {
            self.row(j)
        } else {
            &self.archive[(j - n) * self.d..(j - n + 1) * self.d]
        }
    }

    /// Build trial `i` (mutation, crossover, bound repair) into `self.trials`.
    fn mutate(&mut self, i: usize, plan: &TrialPlan, rng: &mut ChaCha8Rng) {
        let (n, d) = (self.n(), self.d);
        let pick = |rng: &mut ChaCha8Rng, upto: usize, avoid: &[usize]| loop {
            let r = rng.random_range(0..upto);
            if !avoid.contains(&r) {
                break r;
            }
        };
        let jrand = rng.random_range(0..d);
        let mut t = std::mem::take(&mut self.trials);
        {
            let out = &mut t[i * d..(i + 1) * d];
            let xi = self.row(i);
            let f = plan.f;
            match plan.op {
                Mutation::Rand1 => {
                    let r1 = pick(rng, n, &[i]);
                    let r2 = pick(rng, n, &[i, r1]);
                    let r3 = pick(rng, n, &[i, r1, r2]);
                    let (a, bb, c) = (self.row(r1), self.row(r2), self.row(r3));
                    for k in 0..d {
                        out[k] = a[k] + f * (bb[k] - c[k]);
                    }
                }
                Mutation::CurrentToPBest1 { p } => {
                    let top = ((p * n as f64).round() as usize).clamp(2, n);
                    let pb = self.rank[rng.random_range(0..top)];
                    let r1 = pick(rng, n, &[i]);
                    let r2 = pick(rng, n + self.archive_len, &[i, r1]);
                    let (xp, a, c) = (self.row(pb), self.row(r1), self.pool_row(r2));
                    for k in 0..d {
                        out[k] = xi[k] + f * (xp[k] - xi[k]) + f * (a[k] - c[k]);
                    }
                }
                Mutation::RandToPBest1 { p } => {
                    let top = ((p * n as f64).round() as usize).clamp(2, n);
                    let pb = self.rank[rng.random_range(0..top)];
                    let r1 = pick(rng, n, &[i]);
                    let r2 = pick(rng, n, &[i, r1]);
                    let r3 = pick(rng, n + self.archive_len, &[i, r1, r2]);
                    let (xp, a, bb, c) = (self.row(pb), self.row(r1), self.row(r2), self.pool_row(r3));
                    for k in 0..d {
                        out[k] = a[k] + f * (xp[k] - a[k]) + f * (bb[k] - c[k]);
                    }
                }
            }
            // Binomial crossover (coordinate jrand always from the mutant), then bound repair.
            for k in 0..d {
                if k != jrand && rng.random::<f64>() >= plan.cr {
                    out[k] = xi[k];
                }
                let (lo, hi) = (self.b.lower[k], self.b.upper[k]);
                if out[k] < lo {
                    out[k] = 0.5 * (lo + xi[k]);
                } else if out[k] > hi {
                    out[k] = 0.5 * (hi + xi[k]);
                } else if out[k].is_nan() {
                    out[k] = xi[k];
                }
            }
        }
        self.trials = t;
    }

    fn sort_rank(&mut self) {
        let n = self.n();
        self.rank.clear();
        self.rank.extend(0..n);
        let fx = &self.fx;
        self.rank.sort_unstable_by(|&a, &b| fx[a].total_cmp(&fx[b]).then(a.cmp(&b)));
    }

    /// Put parent `i` into the archive (random replacement when full).
    fn archive_push(&mut self, i: usize, cap: usize, rng: &mut ChaCha8Rng) {
        if cap == 0 {
            return;
        }
        let d = self.d;
        let slot = if self.archive_len < cap {
            self.archive_len += 1;
            if self.archive.len() < self.archive_len * d {
                self.archive.resize(self.archive_len * d, 0.0);
            }
            self.archive_len - 1
        } else {
            rng.random_range(0..cap)
        };
        let (src, dst) = (i * d, slot * d);
        let (x, a) = (&self.x, &mut self.archive);
        a[dst..dst + d].copy_from_slice(&x[src..src + d]);
    }

    /// Shrink the archive to `cap` by deleting random members.
    fn archive_trim(&mut self, cap: usize, rng: &mut ChaCha8Rng) {
        let d = self.d;
        while self.archive_len > cap {
            let j = rng.random_range(0..self.archive_len);
            let last = self.archive_len - 1;
            if j != last {
                self.archive.copy_within(last * d..(last + 1) * d, j * d);
            }
            self.archive_len -= 1;
        }
    }

    /// Keep the best `keep` individuals (ties by index), preserving their relative order.
    fn shrink(&mut self, keep: usize) {
        let (n, d) = (self.n(), self.d);
        if keep >= n {
            return;
        }
        self.sort_rank();
        let mut alive = vec![false; n];
        for &i in &self.rank[..keep] {
            alive[i] = true;
        }
        let mut w = 0;
        for i in 0..n {
            if alive[i] {
                if w != i {
                    self.x.copy_within(i * d..(i + 1) * d, w * d);
                    self.fx[w] = self.fx[i];
                }
                w += 1;
            }
        }
        self.x.truncate(keep * d);
        self.fx.truncate(keep);
        self.trials.truncate(keep * d);
        self.tcost.truncate(keep);
    }

    /// A population of `n0` uniform in the box `b`, individual 0 at `init` (clamped into the box)
    /// when given.
    fn start(b: &'b Bounds, n0: usize, init: Option<&[f64]>, rng: &mut ChaCha8Rng) -> Self {
        let d = b.dim();
        let mut x = vec![0.0; n0 * d];
        for row in x.chunks_exact_mut(d) {
            for k in 0..d {
                row[k] = b.lower[k] + (b.upper[k] - b.lower[k]) * rng.random::<f64>();
            }
        }
        if let Some(x0) = init {
            assert_eq!(x0.len(), d, "init has {} entries, cost has {d} dimensions", x0.len());
            x[..d].copy_from_slice(x0);
            b.clamp(&mut x[..d]);
        }
        let dummy = TrialPlan { f: 0.0, cr: 0.0, op: Mutation::Rand1, tag: 0 };
        Engine {
            d,
            b,
            trials: x.clone(),
            x,
            fx: vec![0.0; n0],
            tcost: vec![0.0; n0],
            plans: vec![dummy; n0],
            rank: Vec::with_capacity(n0),
            archive: Vec::new(),
            archive_len: 0,
        }
    }

    /// One-to-one selection, in index order: a trial at least as good as its parent replaces it
    /// (a strictly better one's parent goes to the archive, capped at `cap`); `outcomes` records
    /// each pair.
    fn select(&mut self, cap: usize, outcomes: &mut Vec<Outcome>, rng: &mut ChaCha8Rng) {
        let d = self.d;
        outcomes.clear();
        for i in 0..self.n() {
            let (pc, tc) = (self.fx[i], self.tcost[i]);
            let success = tc < pc;
            outcomes.push(Outcome { plan: self.plans[i], parent_cost: pc, trial_cost: tc, success });
            if tc <= pc {
                if success {
                    self.archive_push(i, cap, rng);
                }
                let (src, t) = (i * d..(i + 1) * d, &self.trials);
                self.x[src.clone()].copy_from_slice(&t[src]);
                self.fx[i] = tc;
            }
        }
    }
}

impl De {
    /// Minimise `c` over `b`. With `init`, individual 0 starts at `init` (clamped into the box);
    /// the rest are uniform in the box.
    ///
    /// One [`Event`] per generation with the best individual. `Report::evaluations` counts
    /// cost evaluations; `converged` is true when the run stopped on the stall criterion.
    ///
    /// # Panics
    /// If `b.dim() != c.dim()` or `init` has the wrong length.
    pub fn minimize<C: Cost>(&self, c: &C, b: &Bounds, init: Option<&[f64]>, obs: &mut dyn Observer) -> Report {
        let d = c.dim();
        assert_eq!(b.dim(), d, "bounds have {} dimensions, cost has {d}", b.dim());
        assert_eq!(b.upper.len(), d, "bounds lower/upper lengths differ");
        let method = self.variant.name();
        let n0 = self.pop.max(4);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut ctl = controller_for(&self.variant, n0);

        let mut e = Engine::start(b, n0, init, &mut rng);
        eval_rows_refine(c, &mut e.x, d, &mut e.fx);
        let mut evaluations = n0;
        let budget = self.max_evals.unwrap_or(n0.saturating_mul(self.generations.saturating_add(1)));
        let mut outcomes: Vec<Outcome> = Vec::with_capacity(n0);

        let mut bi = argmin(&e.fx);
        let mut best = e.row(bi).to_vec();
        let mut best_cost = e.fx[bi];
        let mut stall = Stall::new(self.tol, self.patience, best_cost);
        let mut generations = 0;
        let mut termination = Termination::Budget;
        let mut reason = "maximum number of generations reached";

        while generations < self.generations {
            let n = e.n();
            if let Some(me) = self.max_evals {
                if evaluations + n > me {
                    termination = Termination::EvaluationBudget;
                    reason = "evaluation budget (max_evals) exhausted";
                    break;
                }
            }
            generations += 1;
            e.sort_rank();
            for i in 0..n {
                let plan = ctl.plan(&mut rng);
                e.plans[i] = plan;
                e.mutate(i, &plan, &mut rng);
            }
            eval_rows_refine(c, &mut e.trials, d, &mut e.tcost);
            evaluations += n;

            let cap = (ctl.archive_rate() * n as f64).round() as usize;
            e.select(cap, &mut outcomes, &mut rng);
            ctl.end_generation(&outcomes);

            // Population size reduction (L-SHADE); archive follows the population size.
            let next = ctl.next_pop_size(n, evaluations, budget).max(4).min(n);
            if next < n {
                e.shrink(next);
            }
            let cap = (ctl.archive_rate() * e.n() as f64).round() as usize;
            e.archive_trim(cap, &mut rng);

            bi = argmin(&e.fx);
            if e.fx[bi] < best_cost {
                best_cost = e.fx[bi];
                best.copy_from_slice(e.row(bi));
            }
            obs.observe(&Event { method, iteration: generations, cost: best_cost, x: &best });
            if stall.update(best_cost) {
                termination = Termination::Stalled;
                reason = "no relative improvement above tol within patience";
                break;
            }
        }

        Report { x: best, cost: best_cost, iterations: generations, evaluations, termination, reason: reason.to_owned(), covariance: None }
    }
}

#[cfg(test)]
mod tests {
    use super::super::util::testfns::{NanHole, Rosenbrock, Sphere};
    use super::super::{History, NoObserver};
    use super::*;

    fn box5(d: usize) -> Bounds {
        Bounds::new(vec![-5.0; d], vec![5.0; d])
    }

    fn variants() -> Vec<DeVariant> {
        vec![
            DeVariant::Classic { f: 0.5, cr: 0.9 },
            DeVariant::Jade { c: 0.1, p: 0.05 },
            DeVariant::Shade { memory: 6, p: 0.11 },
            DeVariant::LShade { memory: 6, p: 0.11, min_pop: 4 },
            DeVariant::DsAde { memory: 6, p: 0.11, p_min: 0.1 },
            DeVariant::RandToPBest { memory: 6, p: 0.11 },
        ]
    }

    fn solver(v: DeVariant) -> De {
        De { variant: v, pop: 40, generations: 600, max_evals: None, seed: 1, tol: 1e-12, patience: 100 }
    }

    #[test]
    fn sphere_5d_all_variants() {
        for v in variants() {
            let rep = solver(v.clone()).minimize(&Sphere(5), &box5(5), None, &mut NoObserver);
            assert!(rep.cost < 1e-6, "{v:?}: {rep:?}");
        }
    }

    #[test]
    fn rosenbrock_2d_all_variants() {
        for v in variants() {
            let rep = solver(v.clone()).minimize(&Rosenbrock, &box5(2), None, &mut NoObserver);
            assert!(rep.cost < 1e-2, "{v:?}: {rep:?}");
            assert!(rep.x.iter().all(|x| (-5.0..=5.0).contains(x)));
        }
    }

    #[test]
    fn deterministic_all_variants() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        for v in variants() {
            let s = De { generations: 60, ..solver(v.clone()) };
            let a = s.minimize(&Rosenbrock, &box5(2), Some(&[0.0, 0.0]), &mut NoObserver);
            let b = s.minimize(&Rosenbrock, &box5(2), Some(&[0.0, 0.0]), &mut NoObserver);
            let c = pool.install(|| s.minimize(&Rosenbrock, &box5(2), Some(&[0.0, 0.0]), &mut NoObserver));
            assert_eq!(a.x, b.x, "{v:?}");
            assert_eq!(a.x, c.x, "{v:?} depends on thread count");
        }
    }

    #[test]
    fn max_evals_and_lshade_reduction() {
        let s = De { variant: DeVariant::LShade { memory: 6, p: 0.11, min_pop: 4 }, max_evals: Some(3000), patience: 0, ..solver(DeVariant::default()) };
        let mut h = History::default();
        let rep = s.minimize(&Sphere(5), &box5(5), None, &mut h);
        assert!(rep.evaluations <= 3000, "{rep:?}");
        // With shrinking population, far more generations fit into the budget than 3000/40.
        assert!(rep.iterations > 3000 / 40, "{rep:?}");
        assert!(h.cost.windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn ds_ade_credits_the_operator_that_gains() {
        let plan = |op| TrialPlan { f: 0.5, cr: 0.5, op, tag: 0 };
        let o = |op, gain: f64| Outcome { plan: plan(op), parent_cost: 1.0 + gain, trial_cost: 1.0, success: gain > 0.0 };
        let (cur, rnd) = (Mutation::CurrentToPBest1 { p: 0.1 }, Mutation::RandToPBest1 { p: 0.1 });
        let mut c = DualStrategy::new(4, 0.1, 0.1, true);
        c.end_generation(&[o(cur, 3.0), o(rnd, 1.0)]);
        assert!((c.p1 - 0.75).abs() < 1e-12, "{}", c.p1);
        c.end_generation(&[o(rnd, 1.0)]);
        assert!((c.p1 - 0.1).abs() < 1e-12, "clamped to p_min: {}", c.p1);
        c.end_generation(&[o(cur, 0.0)]);
        assert!((c.p1 - 0.1).abs() < 1e-12, "no success, no change: {}", c.p1);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let picks = (0..1000).filter(|_| matches!(c.plan(&mut rng).op, Mutation::CurrentToPBest1 { .. })).count();
        assert!((60..140).contains(&picks), "{picks} of 1000 at p1 = 0.1");
        let mut single = DualStrategy::new(4, 0.1, 0.0, false);
        assert!((0..200).all(|_| matches!(single.plan(&mut rng).op, Mutation::RandToPBest1 { .. })));
    }

    #[test]
    fn nan_costs_do_not_panic() {
        for v in variants() {
            let rep = De { generations: 200, ..solver(v.clone()) }.minimize(&NanHole, &box5(2), None, &mut NoObserver);
            assert!(rep.cost.is_finite() && rep.cost < 1e-6, "{v:?}: {rep:?}");
        }
    }
}
