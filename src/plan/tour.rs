//! The order the planned poses are measured in: a short tour from home through every pose, timed
//! by the twin's motion model (synchronised trapezoidal joint moves at the scenario's speed, then
//! the hold and the reading window at each pose; [`crate::sim::twin::acquisition::Schedule`]).
//!
//! Nearest neighbour from home, then 2-opt reversals of stretches of the open path until none
//! shortens it. A move's duration is not symmetric in general (it is here: the profile depends
//! on |Δq| only), so the reversal's cost is the sum of the two moves it changes.

use crate::robot::Robot;
use crate::sim::twin::motion::Move;
use serde::Serialize;

/// The timing of a tour.
#[derive(Clone, Debug, Serialize)]
pub struct TourTime {
    /// Moving, s.
    pub moving_s: f64,
    /// Holding and reading at the poses, s.
    pub reading_s: f64,
    /// The whole acquisition, from home to the last reading, s (with the payload changes).
    pub total_s: f64,
    /// Changing the payload between runs, s (included in `total_s`).
    #[serde(skip_serializing_if = "is_zero")]
    pub payload_changes_s: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// How the tour is timed: joint speeds (rad/s), the ramp (s), and the time spent at each pose (s).
pub struct Motion {
    speed: Vec<f64>,
    ramp_s: f64,
    at_pose_s: f64,
}

impl Motion {
    /// Moves at `speed_fraction` of `robot`'s speed limits with ramps of `ramp_s`, `at_pose_s` at
    /// each pose (hold + reading window).
    pub fn new(robot: &Robot, speed_fraction: f64, ramp_s: f64, at_pose_s: f64) -> Motion {
        Motion { speed: robot.joints.iter().map(|j| speed_fraction * j.speed_limit()).collect(), ramp_s, at_pose_s }
    }
    fn duration(&self, a: &[f64], b: &[f64]) -> f64 {
        Move::plan(a, b, &self.speed, self.ramp_s).duration
    }

    /// The timing of visiting `poses` in order from `home`.
    pub fn time(&self, home: &[f64], poses: &[Vec<f64>]) -> TourTime {
        let mut moving = 0.0;
        let mut prev = home;
        for q in poses {
            moving += self.duration(prev, q);
            prev = q;
        }
        let reading = self.at_pose_s * poses.len() as f64;
        TourTime { moving_s: moving, reading_s: reading, total_s: moving + reading, payload_changes_s: 0.0 }
    }

    /// A short visiting order of `poses` from `home` (indices into `poses`).
    pub fn order(&self, home: &[f64], poses: &[Vec<f64>]) -> Vec<usize> {
        let n = poses.len();
        // Node 0 is home, node i + 1 pose i.
        let node = |i: usize| if i == 0 { home } else { &poses[i - 1][..] };
        let cost: Vec<Vec<f64>> = (0..=n).map(|i| (0..=n).map(|j| self.duration(node(i), node(j))).collect()).collect();
        let mut path = vec![0];
        let mut left: Vec<usize> = (1..=n).collect();
        while !left.is_empty() {
            let last = *path.last().expect("starts at home");
            let (k, _) = left.iter().enumerate().min_by(|a, b| cost[last][*a.1].total_cmp(&cost[last][*b.1])).expect("not empty");
            path.push(left.swap_remove(k));
        }
        // 2-opt on the open path: reverse path[i..=j] when it shortens the tour.
        let mut improved = true;
        while improved {
            improved = false;
            for i in 1..n {
                for j in i + 1..=n {
                    let (a, b, c) = (path[i - 1], path[i], path[j]);
                    let before = cost[a][b] + if j < n { cost[c][path[j + 1]] } else { 0.0 };
                    let after = cost[a][c] + if j < n { cost[b][path[j + 1]] } else { 0.0 };
                    if after < before - 1e-12 {
                        path[i..=j].reverse();
                        improved = true;
                    }
                }
            }
        }
        path[1..].iter().map(|i| i - 1).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_tour_is_no_longer_than_the_given_order_and_visits_every_pose_once() {
        let robot = Robot::irb120();
        let m = Motion::new(&robot, 0.2, 0.2, 1.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let poses: Vec<Vec<f64>> = (0..40).map(|_| (0..6).map(|_| rng.random::<f64>() * 3.0 - 1.5).collect()).collect();
        let home = vec![0.0; 6];
        let order = m.order(&home, &poses);
        let mut seen = order.clone();
        seen.sort();
        assert_eq!(seen, (0..40).collect::<Vec<_>>());
        let toured: Vec<Vec<f64>> = order.iter().map(|&i| poses[i].clone()).collect();
        let (given, short) = (m.time(&home, &poses), m.time(&home, &toured));
        assert!(short.total_s < 0.8 * given.total_s, "tour {:.1} s vs given order {:.1} s", short.total_s, given.total_s);
        assert_eq!(short.reading_s, 40.0);
    }
}
