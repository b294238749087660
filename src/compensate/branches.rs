//! Every solution of the calibrated arm for a pose target: the inverse kinematics `ik` answers
//! pose targets with.
//!
//! A calibrated arm has no closed form (its axes are a few hundredths of a degree off the
//! structure that has one), but each of its solutions lies next to one of the nominal arm's:
//! from every solution of the nominal arm (all of them in closed form where its geometry allows,
//! [`crate::ik::closed_form`]; else the one a numerical search finds) a local descent on the
//! calibrated model reaches the calibrated arm's solution on that branch. Where none converges
//! (a target the nominal arm cannot reach but the calibrated one can), a search with random
//! restarts answers with one solution.

use super::{nearest_turns, Compensator};
use crate::ik::closed_form::wrap;
use crate::ik::solver::PoseSolution;
use crate::ik::{IkOptions, IkStatus, IkWork, JacobianKind};
use nalgebra::{Matrix3, Vector3};

/// Two converged solutions closer than this in every joint (rad, modulo a turn) are one: descents
/// from two starts of one branch end a tolerance's worth apart (1e-5 rad at 0.001 mm), distinct
/// branches tenths of a radian or more.
pub const SAME_SOLUTION_RAD: f64 = 1e-3;

impl Compensator<'_> {
    /// Every solution (rad) of the calibrated model for the tool at `p` (mm) turned `r` (base
    /// frame), stepped with the Jacobian `kind`: one per branch of the nominal arm that a local
    /// descent from it reaches, each angle at its turn nearest zero within its limits (a joint
    /// whose range spans more than a turn reaches the same pose a turn away too), in the nominal
    /// solutions' order; where none is reached, the answer of a search with restarts (its status
    /// says why when it did not converge either).
    pub fn pose_solutions(&self, p: &Vector3<f64>, r: &Matrix3<f64>, kind: JacobianKind, wc: &mut IkWork, wn: &mut IkWork) -> Vec<PoseSolution> {
        let local = IkOptions { local: true, ..self.options.clone() };
        let mut found: Vec<PoseSolution> = Vec::new();
        for start in self.nominal_starts(p, r, wn) {
            let mut s = self.calibrated.solve_pose_from(p, r, Some(&start), kind, &local, wc);
            nearest_turns(&mut s.q, &start, &self.calibrated.limits);
            if s.status == IkStatus::Converged && !found.iter().any(|f| within_turns(&f.q, &s.q, SAME_SOLUTION_RAD)) {
                found.push(s);
            }
        }
        if found.is_empty() {
            // Where the nominal arm has no solution near (a pose beyond its reach that the
            // calibrated arm reaches), a search with restarts.
            found.push(self.calibrated.solve_pose_from(p, r, None, kind, &self.options, wc));
        }
        found
    }

    /// [`Self::pose_solutions`] of every pose (`p` mm, `r`, base frame), in parallel (each
    /// thread with its own workspaces), each solution with its conditioning
    /// ([`Self::pose_conditioning`]), and each target's time.
    pub fn solve_poses(&self, poses: &[(Vector3<f64>, Matrix3<f64>)], kind: JacobianKind) -> PoseAnswers {
        use rayon::prelude::*;
        let each: Vec<(Vec<PoseSolution>, Vec<f64>, f64)> = poses
            .par_iter()
            .map_init(
                || self.works(),
                |(wc, wn), (p, r)| {
                    let t0 = std::time::Instant::now();
                    let s = self.pose_solutions(p, r, kind, wc, wn);
                    let seconds = t0.elapsed().as_secs_f64();
                    let conditioning = s.iter().map(|s| self.pose_conditioning(&s.q, wc)).collect();
                    (s, conditioning, seconds)
                },
            )
            .collect();
        let mut out = PoseAnswers { solutions: Vec::new(), conditioning: Vec::new(), seconds: Vec::new() };
        for (s, k, t) in each {
            out.solutions.push(s);
            out.conditioning.push(k);
            out.seconds.push(t);
        }
        out
    }

    /// How well the calibrated arm's pose at `q` (rad) pins its joints down
    /// ([`crate::ik::IkModel::pose_conditioning`], mm/rad).
    pub fn pose_conditioning(&self, q: &[f64], wc: &mut IkWork) -> f64 {
        self.calibrated.pose_conditioning(q, wc)
    }

    /// The nominal arm's solutions for the pose, then those for the pose pulled towards the base
    /// by each of [`PULL_MM`], one per branch: each angle at its turn nearest zero within its
    /// limits, a start kept where it lies farther than [`NEW_START_RAD`] (modulo a turn) from
    /// every start so far. A calibrated arm reaches some poses (the elbow near stretched, a wrist
    /// or shoulder near its singularity) on branches the nominal arm just misses there.
    fn nominal_starts(&self, p: &Vector3<f64>, r: &Matrix3<f64>, wn: &mut IkWork) -> Vec<Vec<f64>> {
        let limits = &self.calibrated.limits;
        let zero = vec![0.0; limits.len()];
        let mut starts: Vec<Vec<f64>> = Vec::new();
        let mut add = |mut q: Vec<f64>| {
            nearest_turns(&mut q, &zero, limits);
            if !starts.iter().any(|s| within_turns(s, &q, NEW_START_RAD)) {
                starts.push(q);
            }
        };
        self.nominal_pose_solutions(p, r, wn).into_iter().for_each(&mut add);
        let norm = p.norm();
        if self.closed_form() {
            for pull in PULL_MM.into_iter().filter(|pull| *pull < norm) {
                self.nominal_pose_solutions(&(p * (1.0 - pull / norm)), r, wn).into_iter().for_each(&mut add);
            }
        }
        starts
    }
}

/// Every pose target's answers ([`Compensator::solve_poses`]), in target order.
pub struct PoseAnswers {
    /// Each target's solutions ([`Compensator::pose_solutions`]).
    pub solutions: Vec<Vec<PoseSolution>>,
    /// Each solution's conditioning, mm/rad ([`crate::ik::IkModel::pose_conditioning`]).
    pub conditioning: Vec<Vec<f64>>,
    /// Each target's solve time, s.
    pub seconds: Vec<f64>,
}

/// How far (mm) [`Compensator::pose_solutions`] also pulls a pose towards the base for the
/// nominal arm's solutions: beyond what calibrations change of an arm's reach (tenths of a mm).
pub const PULL_MM: [f64; 2] = [0.5, 3.0];

/// A start of the nominal arm farther than this from every other (rad, in some joint) is a
/// branch of its own.
pub const NEW_START_RAD: f64 = 0.05;

/// Whether every joint of `a` lies within `tol` (rad) of `b`'s, modulo a turn.
fn within_turns(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| wrap(x - y).abs() < tol)
}
