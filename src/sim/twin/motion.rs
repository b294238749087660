//! Joint-space moves of the controller: synchronised trapezoidal velocity profiles.
//!
//! Every joint starts and stops together. A joint's speed limit is `speed_fraction` × its URDF
//! velocity limit and its acceleration limit that speed over `ramp_s` (URDF files carry no
//! acceleration limits). The slowest joint sets the duration; the others follow the same
//! normalised profile s(t) ∈ [0, 1], so none exceeds its limits.

/// One move from `from` to `to` (commanded angles, rad).
#[derive(Clone, Debug, PartialEq)]
pub struct Move {
    /// Start angles, rad.
    pub from: Vec<f64>,
    /// End angles, rad.
    pub to: Vec<f64>,
    /// Total duration, s (0 when no joint moves).
    pub duration: f64,
    /// Duration of the acceleration ramp and of the deceleration ramp, s.
    pub ramp: f64,
}

impl Move {
    /// Plans the move with per-joint speed limits `speed` (rad/s) and ramp time `ramp_s`.
    pub fn plan(from: &[f64], to: &[f64], speed: &[f64], ramp_s: f64) -> Move {
        let mut duration: f64 = 0.0;
        for j in 0..from.len() {
            let d = (to[j] - from[j]).abs();
            if d == 0.0 {
                continue;
            }
            let v = speed[j];
            // Cruise reached when the distance exceeds what the two ramps cover (v·ramp).
            let t = if d >= v * ramp_s { d / v + ramp_s } else { 2.0 * (d * ramp_s / v).sqrt() };
            duration = duration.max(t);
        }
        let ramp = ramp_s.min(0.5 * duration);
        Move { from: from.to_vec(), to: to.to_vec(), duration, ramp }
    }

    /// Normalised position s, speed ds/dt and acceleration at time `t` from the move's start.
    pub fn profile(&self, t: f64) -> (f64, f64, f64) {
        let (tt, tr) = (self.duration, self.ramp);
        if tt <= 0.0 || t >= tt {
            return (1.0, 0.0, 0.0);
        }
        if t <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        // Peak normalised speed: area under the trapezoid is 1.
        let vs = 1.0 / (tt - tr);
        let a = vs / tr;
        if t < tr {
            (0.5 * a * t * t, a * t, a)
        } else if t <= tt - tr {
            (0.5 * a * tr * tr + vs * (t - tr), vs, 0.0)
        } else {
            let r = tt - t;
            (1.0 - 0.5 * a * r * r, a * r, -a)
        }
    }

    /// Commanded angle and speed of joint `j` at time `t` from the move's start.
    pub fn joint(&self, j: usize, t: f64) -> (f64, f64) {
        let (s, ds, _) = self.profile(t);
        let d = self.to[j] - self.from[j];
        (self.from[j] + d * s, d * ds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_respect_limits_and_end_on_target() {
        let speed = [1.0, 0.5, 2.0];
        for (from, to) in [([0.0, 0.0, 0.0], [1.0, -0.2, 0.05]), ([0.3, 1.0, -1.0], [0.3, 1.0001, 2.0])] {
            let m = Move::plan(&from, &to, &speed, 0.2);
            let n = 4000;
            let mut prev = from.to_vec();
            for k in 1..=n {
                let t = m.duration * k as f64 / n as f64;
                for j in 0..3 {
                    let (q, v) = m.joint(j, t);
                    assert!(v.abs() <= speed[j] * (1.0 + 1e-9), "joint {j} speed {v}");
                    let a = (to[j] - from[j]) * m.profile(t).2;
                    assert!(a.abs() <= speed[j] / 0.2 * (1.0 + 1e-9), "joint {j} acceleration {a}");
                    // Monotonic: never overshoots.
                    assert!((q - prev[j]) * (to[j] - from[j]) >= -1e-15);
                    prev[j] = q;
                }
            }
            for j in 0..3 {
                assert!((m.joint(j, m.duration).0 - to[j]).abs() < 1e-15);
            }
            // The limiting joint reaches its speed limit (or its acceleration limit on a short move).
            let peak: f64 = (0..3).map(|j| m.joint(j, 0.5 * m.duration).1.abs() / speed[j]).fold(0.0, f64::max);
            assert!(peak > 0.999 || m.ramp == 0.5 * m.duration, "peak {peak}");
        }
        let still = Move::plan(&[1.0, 2.0], &[1.0, 2.0], &[1.0, 1.0], 0.1);
        assert_eq!(still.duration, 0.0);
        assert_eq!(still.joint(1, 0.0), (2.0, 0.0));
    }
}
