//! Plausible arm shapes at the reference pose: the generic search's starts. Each shape is a
//! family of industrial arms drawn with seeded link lengths, signs and joint angles, written as
//! axis lines in a frame of its own (joint 1 vertical through the origin) with a tool point;
//! the search places each in the data's frame by fitting the instrument to it.
//!
//! * [`Shape::SphericalWrist`]: the classic 6R industrial arm (ABB, KUKA, Fanuc, HSR) — joint
//!   2 horizontal at a shoulder offset, joint 3 parallel to it, a spherical wrist (4, 5, 6 meet).
//! * [`Shape::ParallelWrist`]: the Universal Robots' shape — joints 2, 3 and 4 parallel, joint 5
//!   across them at a wrist offset, joint 6 across joint 5.
//! * [`Shape::Seven`]: a 7R arm with shoulder, elbow and wrist (Barrett WAM, KUKA iiwa) — joints
//!   1 and 2 meet, joint 3 along the upper arm, an elbow (4) across it at a small offset, joint 5
//!   along the forearm, a wrist (6, 7) meeting it.

use super::Line;
use nalgebra::Vector3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;

/// A family of arm shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// 6R with a spherical wrist.
    SphericalWrist,
    /// 6R with three parallel axes (2, 3, 4) and an offset wrist.
    ParallelWrist,
    /// 7R shoulder–elbow–wrist.
    Seven,
}

impl Shape {
    /// The shapes of arms with `n` joints.
    pub fn of_joints(n: usize) -> &'static [Shape] {
        match n {
            6 => &[Shape::SphericalWrist, Shape::ParallelWrist],
            7 => &[Shape::Seven],
            _ => &[],
        }
    }

    /// One arm of this shape: its axis lines and a tool point (m).
    pub fn draw(self, rng: &mut ChaCha8Rng) -> (Vec<Line>, Vector3<f64>) {
        match self {
            Shape::SphericalWrist => spherical_wrist(rng),
            Shape::ParallelWrist => parallel_wrist(rng),
            Shape::Seven => seven(rng),
        }
    }
}

/// A random sign.
fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random_bool(0.5) {
        1.0
    } else {
        -1.0
    }
}

/// A unit vector in the plane spanned by `a` and `b` (orthonormal) at a random angle.
fn in_plane(rng: &mut ChaCha8Rng, a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
    let phi: f64 = rng.random_range(0.0..TAU);
    a * phi.cos() + b * phi.sin()
}

/// 6R with a spherical wrist (the draw order is the draw-wire search's since its first
/// version: its results depend on it).
pub fn spherical_wrist(rng: &mut ChaCha8Rng) -> (Vec<Line>, Vector3<f64>) {
    let mut sign = || if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let (s2, s3, s4, s5, s6) = (sign(), sign(), sign(), sign(), sign());
    let up = Line { point: Vector3::zeros(), dir: Vector3::z() };
    let shoulder = Vector3::new(rng.random_range(0.0..0.3), 0.0, 0.0);
    let j2 = Line { point: shoulder, dir: Vector3::y() * s2 };
    let phi: f64 = rng.random_range(0.0..TAU);
    let elbow = shoulder + Vector3::new(phi.cos(), 0.0, phi.sin()) * rng.random_range(0.3..1.1);
    let j3 = Line { point: elbow, dir: Vector3::y() * s3 };
    let psi: f64 = rng.random_range(0.0..TAU);
    let forearm = Vector3::new(psi.cos(), 0.0, psi.sin());
    let normal = Vector3::y().cross(&forearm);
    let wrist = elbow + normal * rng.random_range(-0.25..0.25) + forearm * rng.random_range(0.3..1.3);
    let j4 = Line { point: wrist, dir: forearm * s4 };
    let chi: f64 = rng.random_range(0.0..TAU);
    let w5 = Vector3::y() * chi.cos() + normal * chi.sin();
    let j5 = Line { point: wrist, dir: w5 * s5 };
    let omega: f64 = rng.random_range(0.0..TAU);
    let across = w5.cross(&forearm);
    let w6 = forearm * omega.cos() + across * omega.sin();
    let j6 = Line { point: wrist, dir: w6 * s6 };
    let tool = wrist + w6 * rng.random_range(0.05..0.35);
    (vec![up, j2, j3, j4, j5, j6], tool)
}

/// 6R with joints 2, 3, 4 parallel (horizontal) and an offset wrist.
fn parallel_wrist(rng: &mut ChaCha8Rng) -> (Vec<Line>, Vector3<f64>) {
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let up = Line { point: Vector3::zeros(), dir: z };
    let shoulder = x * rng.random_range(0.0..0.2);
    let j2 = Line { point: shoulder, dir: y * sign(rng) };
    let elbow = shoulder + in_plane(rng, &x, &z) * rng.random_range(0.3..1.1);
    let j3 = Line { point: elbow, dir: y * sign(rng) };
    let wrist1 = elbow + in_plane(rng, &x, &z) * rng.random_range(0.3..1.3);
    let j4 = Line { point: wrist1, dir: y * sign(rng) };
    let w5 = in_plane(rng, &x, &z);
    let p5 = wrist1 + y * (sign(rng) * rng.random_range(0.05..0.25));
    let j5 = Line { point: p5, dir: w5 * sign(rng) };
    let w6 = in_plane(rng, &y, &w5.cross(&y));
    let p6 = p5 + w5 * rng.random_range(0.05..0.15);
    let j6 = Line { point: p6, dir: w6 * sign(rng) };
    let tool = p6 + w6 * rng.random_range(0.05..0.35);
    (vec![up, j2, j3, j4, j5, j6], tool)
}

/// 7R: shoulder (1, 2 meeting), upper-arm roll (3), elbow (4), forearm roll (5), wrist (6, 7).
fn seven(rng: &mut ChaCha8Rng) -> (Vec<Line>, Vector3<f64>) {
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let up = Line { point: Vector3::zeros(), dir: z };
    let shoulder = x * rng.random_range(0.0..0.1);
    let j2 = Line { point: shoulder, dir: y * sign(rng) };
    let upper = in_plane(rng, &x, &z);
    let j3 = Line { point: shoulder, dir: upper * sign(rng) };
    let d4 = in_plane(rng, &y, &upper.cross(&y));
    let side = upper.cross(&d4);
    let elbow = shoulder + upper * rng.random_range(0.3..0.8) + side * rng.random_range(-0.1..0.1);
    let j4 = Line { point: elbow, dir: d4 * sign(rng) };
    let fore = in_plane(rng, &upper, &d4.cross(&upper));
    let offset = d4.cross(&fore) * rng.random_range(-0.1..0.1);
    let j5 = Line { point: elbow + offset, dir: fore * sign(rng) };
    let wrist = elbow + offset + fore * rng.random_range(0.25..0.8);
    let d6 = in_plane(rng, &d4, &fore.cross(&d4));
    let j6 = Line { point: wrist, dir: d6 * sign(rng) };
    let d7 = in_plane(rng, &fore, &d6.cross(&fore));
    let j7 = Line { point: wrist, dir: d7 * sign(rng) };
    let tool = wrist + d7 * rng.random_range(0.05..0.35);
    (vec![up, j2, j3, j4, j5, j6, j7], tool)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn every_shape_draws_unit_axes_with_its_parallels_and_meetings() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for shape in [Shape::SphericalWrist, Shape::ParallelWrist, Shape::Seven] {
            for _ in 0..50 {
                let (lines, _) = shape.draw(&mut rng);
                assert!(lines.iter().all(|l| (l.dir.norm() - 1.0).abs() < 1e-12), "{shape:?}");
                let parallel = |a: usize, b: usize| lines[a].dir.cross(&lines[b].dir).norm() < 1e-12;
                let perpendicular = |a: usize, b: usize| lines[a].dir.dot(&lines[b].dir).abs() < 1e-12;
                match shape {
                    Shape::SphericalWrist => assert!(parallel(1, 2) && lines[3].point == lines[5].point),
                    Shape::ParallelWrist => assert!(parallel(1, 2) && parallel(2, 3) && perpendicular(3, 4) && perpendicular(4, 5)),
                    Shape::Seven => assert!(lines.len() == 7 && perpendicular(2, 3) && perpendicular(3, 4) && perpendicular(5, 6)),
                }
            }
        }
    }
}
