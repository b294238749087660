//! The tool's own routines, which every controller has and every owner can run: the N-point TCP
//! (the tool's tip held at one fixed point, or several, in four or more configurations turned
//! about it: where the tip sits on the flange) and the 3-point user frame (the tip touched to a
//! work object's origin, a point along its x axis and a point on its xy plane). Each states its
//! accuracy from its own residuals: how far the tips of the configurations lie from their fixed
//! point, and the standard uncertainty of the tool point that follows, on an arm as given (the
//! nominal, or a calibration's: [`crate::calib::model::CalibModel::flange_frame`]).

use crate::error::{Error, Result};
use crate::robot::kinematics::Frame;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Least configurations for a TCP: three unknowns of the tool and three of the fixed point, and
/// one configuration more to check them.
pub const MIN_TCP_ROWS: usize = 4;

/// Least turn between the configurations (degrees, the largest angle between two flange
/// orientations of one fixed point) for the tool's tip to be told from the flange.
pub const MIN_TCP_TURN_DEG: f64 = 10.0;

/// A tool point found by the N-point routine.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TcpFit {
    /// The tool's tip on the flange (flange frame), mm.
    pub tool_mm: [f64; 3],
    /// Its standard uncertainty per coordinate, mm (from the residuals' scatter).
    pub tool_sd_mm: [f64; 3],
    /// Each fixed point (base frame, mm) by its label (one unnamed: "").
    pub points_mm: Vec<(String, [f64; 3])>,
    /// Configurations used.
    pub rows: usize,
    /// RMS distance of the configurations' tips from their fixed point, mm.
    pub rms_mm: f64,
    /// The largest such distance, mm.
    pub max_mm: f64,
    /// The smallest over the fixed points of the largest turn between two of its configurations,
    /// degrees.
    pub turn_deg: f64,
    /// The tool's orientation on the flange, when two elongator configurations give it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<ToolOrientation>,
}

/// A tool frame's orientation on the flange from the elongator configurations of the 6-point
/// routine (ABB's "TCP and Z, X"): from the last configuration at the fixed point the tool is moved
/// without turning until the fixed point lies on the tool's +z axis, then on its +x axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ToolOrientation {
    /// The tool frame's orientation in the flange frame as a unit quaternion (w, x, y, z).
    pub quaternion: [f64; 4],
    /// The same as roll, pitch, yaw about the flange's x, y, z, degrees.
    pub rpy_deg: [f64; 3],
    /// How far the tool was moved for the z elongator, and for the x one, mm (a short move turns
    /// the axis with the tip's error: by e / this).
    pub levers_mm: [f64; 2],
    /// The uncertainty of the axes' directions the tip's uncertainty gives, degrees.
    pub axes_sd_deg: f64,
}

/// Largest turn (degrees) between the reference configuration and an elongator's: the tool is
/// moved, not turned.
pub const MAX_ELONGATOR_TURN_DEG: f64 = 0.5;

/// The tool's orientation on the flange from the reference configuration `reference` (the tip at
/// the fixed point) and the elongators `z` and `x` (the tool moved without turning until the
/// fixed point lies on its +z, then its +x axis), the tip on the flange `tool` (m) known to
/// `tip_sd_mm`.
pub fn tool_orientation(reference: &Frame, z: &Frame, x: &Frame, tool: &Vector3<f64>, tip_sd_mm: f64) -> Result<ToolOrientation> {
    let angle = |a: &Frame, b: &Frame| nalgebra::Rotation3::from_matrix_unchecked(a.rot.transpose() * b.rot).angle().to_degrees();
    let at = reference.point(tool);
    let mut axes = [Vector3::zeros(); 2];
    let mut levers = [0.0; 2];
    for (k, (f, name)) in [(z, "z"), (x, "x")].into_iter().enumerate() {
        let turn = angle(reference, f);
        if turn > MAX_ELONGATOR_TURN_DEG {
            return Err(Error::Calibration(format!(
                "the {name} elongator's configuration is turned {turn:.2} deg from the last one at the fixed point: move the tool along its {name} axis without turning it (at most {MAX_ELONGATOR_TURN_DEG} deg)"
            )));
        }
        let d = at - f.point(tool);
        levers[k] = crate::units::to_mm(d.norm());
        if levers[k] < 10.0 {
            return Err(Error::Calibration(format!(
                "the {name} elongator moved the tip {:.2} mm from the fixed point: move it 10 mm or more (better 100 mm) along the tool's {name} axis",
                levers[k]
            )));
        }
        axes[k] = reference.rot.transpose() * (d / d.norm());
    }
    let [zf, xf] = axes;
    let angle_zx = zf.dot(&xf).clamp(-1.0, 1.0).acos().to_degrees();
    if (angle_zx - 90.0).abs() > 30.0 {
        return Err(Error::Calibration(format!("the z and x elongators' directions are {angle_zx:.1} deg apart: they should be about 90 deg")));
    }
    let y = zf.cross(&xf).normalize();
    let xo = y.cross(&zf);
    let rot = nalgebra::Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[xo, y, zf]));
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(&rot);
    let (roll, pitch, yaw) = rot.euler_angles();
    Ok(ToolOrientation {
        quaternion: [q.w, q.i, q.j, q.k],
        rpy_deg: [roll, pitch, yaw].map(f64::to_degrees),
        levers_mm: levers,
        axes_sd_deg: (std::f64::consts::SQRT_2 * tip_sd_mm / levers[0].min(levers[1])).to_degrees(),
    })
}

impl TcpFit {
    /// What a command prints.
    pub fn lines(&self) -> Vec<String> {
        let (t, s) = (self.tool_mm, self.tool_sd_mm);
        let mut out = vec![
            format!("tool point on the flange: ({:.4}, {:.4}, {:.4}) mm, standard uncertainty ({:.4}, {:.4}, {:.4}) mm", t[0], t[1], t[2], s[0], s[1], s[2]),
            format!(
                "{} configurations, turned by up to {:.1} deg; the tips lie {:.4} mm RMS ({:.4} mm at most) from their fixed point",
                self.rows, self.turn_deg, self.rms_mm, self.max_mm
            ),
        ];
        for (l, p) in &self.points_mm {
            let name = if l.is_empty() { String::new() } else { format!(" {l}") };
            out.push(format!("fixed point{name} (base frame): ({:.3}, {:.3}, {:.3}) mm", p[0], p[1], p[2]));
        }
        if let Some(o) = &self.orientation {
            let (q, r) = (o.quaternion, o.rpy_deg);
            out.push(format!(
                "tool orientation on the flange: quaternion ({:.7}, {:.7}, {:.7}, {:.7}), roll-pitch-yaw ({:.4}, {:.4}, {:.4}) deg; elongators {:.1} and {:.1} mm: the axes known to about {:.4} deg",
                q[0], q[1], q[2], q[3], r[0], r[1], r[2], o.levers_mm[0], o.levers_mm[1], o.axes_sd_deg
            ));
        }
        out
    }
}

/// The N-point TCP of flange frames `flanges` (base frame, m), configuration `i` holding the tip
/// at fixed point `point[i]` (labels `labels`): the tool and every fixed point by least squares
/// (`R_i·t + p_i = s_k`, linear), with the uncertainty of the tool from the residuals. An error
/// names what the configurations cannot determine.
pub fn tcp(flanges: &[Frame], point: &[usize], labels: &[String]) -> Result<TcpFit> {
    let n = flanges.len();
    let k = labels.len().max(1);
    if n < MIN_TCP_ROWS + 2 * (k - 1) {
        return Err(Error::Calibration(format!(
            "{n} configurations for {k} fixed point(s): the tool's tip needs at least {MIN_TCP_ROWS} at one point (and 2 more for each other point) to be found and checked"
        )));
    }
    let mut turn = f64::INFINITY;
    for g in 0..k {
        let rot: Vec<Matrix3<f64>> = (0..n).filter(|&i| point[i] == g).map(|i| flanges[i].rot).collect();
        let t = crate::measurement::socket::turn_spread(&rot).to_degrees();
        if rot.len() < 2 || t < MIN_TCP_TURN_DEG {
            let name = labels.get(g).map_or(String::new(), |l| format!(" {l}"));
            return Err(Error::Calibration(format!(
                "the configurations at fixed point{name} turn by {t:.1} deg ({} of them): the tip is told from the flange only by turning the tool about it; turn it by {MIN_TCP_TURN_DEG} deg or more",
                rot.len()
            )));
        }
        turn = turn.min(t);
    }
    let m = 3 + 3 * k;
    let mut a = DMatrix::zeros(3 * n, m);
    let mut b = DVector::zeros(3 * n);
    for (i, f) in flanges.iter().enumerate() {
        for r in 0..3 {
            for c in 0..3 {
                a[(3 * i + r, c)] = f.rot[(r, c)];
            }
            a[(3 * i + r, 3 + 3 * point[i] + r)] = -1.0;
            b[3 * i + r] = -f.pos[r];
        }
    }
    let ata = a.transpose() * &a;
    let inv = ata.clone().try_inverse().ok_or_else(|| Error::Calibration("the configurations do not determine the tool (a singular system)".into()))?;
    let x = &inv * a.transpose() * &b;
    let r = &a * &x - &b;
    let dist: Vec<f64> = r.as_slice().chunks(3).map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()).collect();
    let dof = (3 * n).saturating_sub(m).max(1) as f64;
    let s2 = r.norm_squared() / dof;
    let mm = crate::units::MM_PER_M;
    Ok(TcpFit {
        tool_mm: [x[0] * mm, x[1] * mm, x[2] * mm],
        tool_sd_mm: [0, 1, 2].map(|c| (s2 * inv[(c, c)]).sqrt() * mm),
        points_mm: (0..k).map(|g| (labels.get(g).cloned().unwrap_or_default(), [x[3 + 3 * g] * mm, x[4 + 3 * g] * mm, x[5 + 3 * g] * mm])).collect(),
        rows: n,
        rms_mm: (dist.iter().map(|d| d * d).sum::<f64>() / n as f64).sqrt() * mm,
        max_mm: dist.iter().fold(0.0, |a: f64, d| a.max(*d)) * mm,
        turn_deg: turn,
        orientation: None,
    })
}

/// A work object's frame from three touched points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UserFrame {
    /// Its origin in the base frame, mm.
    pub origin_mm: [f64; 3],
    /// Its orientation as a unit quaternion (w, x, y, z), base frame.
    pub quaternion: [f64; 4],
    /// Its orientation as roll, pitch, yaw about the base's x, y, z, degrees.
    pub rpy_deg: [f64; 3],
    /// How far the x point lies from the origin, mm (a short lever turns the axes with the
    /// tip's error: an error e in it turns x by e / this).
    pub x_lever_mm: f64,
    /// The angle between the x axis and the direction to the xy point, degrees (near 0 or 180 the
    /// plane is ill-defined).
    pub xy_angle_deg: f64,
    /// The uncertainty of the axes' directions that a tip uncertainty of `tip_sd_mm` gives, deg.
    pub axes_sd_deg: f64,
    /// The tip's standard uncertainty the frame was judged with, mm.
    pub tip_sd_mm: f64,
}

impl UserFrame {
    /// What a command prints.
    pub fn lines(&self) -> Vec<String> {
        let (o, q, r) = (self.origin_mm, self.quaternion, self.rpy_deg);
        vec![
            format!("origin (base frame): ({:.3}, {:.3}, {:.3}) mm", o[0], o[1], o[2]),
            format!("orientation: quaternion ({:.7}, {:.7}, {:.7}, {:.7}), roll-pitch-yaw ({:.4}, {:.4}, {:.4}) deg", q[0], q[1], q[2], q[3], r[0], r[1], r[2]),
            format!(
                "x point {:.1} mm from the origin, xy point {:.1} deg off the x axis: with the tip known to {:.4} mm the axes are known to about {:.4} deg",
                self.x_lever_mm, self.xy_angle_deg, self.tip_sd_mm, self.axes_sd_deg
            ),
        ]
    }
}

/// Least angle (degrees) between the x axis and the direction to the xy point.
pub const MIN_XY_ANGLE_DEG: f64 = 10.0;

/// The 3-point user frame from the tip's positions (base frame, m) at the origin, at a point on
/// the +x axis and at a point on the xy plane (+y side); `tip_sd_mm` is how well each tip is known.
pub fn user_frame(origin: &Vector3<f64>, x_point: &Vector3<f64>, xy_point: &Vector3<f64>, tip_sd_mm: f64) -> Result<UserFrame> {
    let ex = x_point - origin;
    let exy = xy_point - origin;
    let lever = crate::units::to_mm(ex.norm());
    if lever < 1.0 {
        return Err(Error::Calibration(format!(
            "the x point lies {lever:.3} mm from the origin: touch a point at least 1 mm (better 100 mm) along the x axis"
        )));
    }
    let xhat = ex / ex.norm();
    let angle = xhat.dot(&(exy / exy.norm().max(1e-12))).clamp(-1.0, 1.0).acos().to_degrees();
    if !(MIN_XY_ANGLE_DEG..=180.0 - MIN_XY_ANGLE_DEG).contains(&angle) {
        return Err(Error::Calibration(format!(
            "the xy point is {angle:.1} deg off the x axis: touch a point well off it (at least {MIN_XY_ANGLE_DEG} deg) to fix the plane"
        )));
    }
    let z = xhat.cross(&exy).normalize();
    let y = z.cross(&xhat);
    let rot = nalgebra::Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[xhat, y, z]));
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(&rot);
    let (roll, pitch, yaw) = rot.euler_angles();
    let lever_y = crate::units::to_mm(exy.norm()) * angle.to_radians().sin();
    Ok(UserFrame {
        origin_mm: [origin.x, origin.y, origin.z].map(crate::units::to_mm),
        quaternion: [q.w, q.i, q.j, q.k],
        rpy_deg: [roll, pitch, yaw].map(f64::to_degrees),
        x_lever_mm: lever,
        xy_angle_deg: angle,
        axes_sd_deg: (std::f64::consts::SQRT_2 * tip_sd_mm / lever.min(lever_y)).to_degrees(),
        tip_sd_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn flanges(tool: &Vector3<f64>, at: &Vector3<f64>, n: usize) -> Vec<Frame> {
        (0..n)
            .map(|i| {
                let i = i as f64;
                let rot = Rotation3::from_euler_angles(0.4 * (1.3 * i).sin(), 0.5 * (0.7 * i).cos(), 2.0 * i).into_inner();
                Frame { rot, pos: at - rot * tool }
            })
            .collect()
    }

    #[test]
    fn the_tcp_finds_the_tip_and_its_uncertainty_grows_with_the_scatter() {
        let (tool, at) = (Vector3::new(0.012, -0.004, 0.155), Vector3::new(0.45, 0.1, 0.2));
        let f = flanges(&tool, &at, 6);
        let fit = tcp(&f, &[0; 6], &[]).unwrap();
        assert!((0..3).all(|c| (fit.tool_mm[c] - tool[c] * 1e3).abs() < 1e-9), "{fit:?}");
        assert!(fit.rms_mm < 1e-9);
        // The tips scattered by 0.02 mm: the tool within a few standard uncertainties, which are
        // of the scatter's size.
        let mut noisy = f.clone();
        for (i, fr) in noisy.iter_mut().enumerate() {
            fr.pos += Vector3::new((i as f64 * 1.7).sin(), (i as f64 * 2.3).cos(), (i as f64 * 0.9).sin()) * 2e-5;
        }
        let fit = tcp(&noisy, &[0; 6], &[]).unwrap();
        assert!(fit.rms_mm > 0.005 && fit.rms_mm < 0.04, "{fit:?}");
        assert!((0..3).all(|c| (fit.tool_mm[c] - tool[c] * 1e3).abs() < 4.0 * fit.tool_sd_mm[c] + 1e-6), "{fit:?}");
        assert!(tcp(&f[..3], &[0; 3], &[]).is_err(), "three configurations cannot check the tip");
        let still = vec![f[0]; 5];
        assert!(tcp(&still, &[0; 5], &[]).unwrap_err().to_string().contains("turn"));
    }

    #[test]
    fn the_six_point_routine_finds_the_tools_orientation() {
        let (tool, at) = (Vector3::new(0.012, -0.004, 0.155), Vector3::new(0.45, 0.1, 0.2));
        let f = flanges(&tool, &at, 4);
        let tool_rot = Rotation3::from_euler_angles(0.1, -0.2, 0.7).into_inner();
        // The tool moved without turning so the fixed point lies 80 mm along its +z, then +x.
        let moved = |axis: Vector3<f64>| Frame { rot: f[3].rot, pos: f[3].pos - f[3].rot * tool_rot * axis * 0.08 };
        let o = tool_orientation(&f[3], &moved(Vector3::z()), &moved(Vector3::x()), &tool, 0.01).unwrap();
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(o.quaternion[0], o.quaternion[1], o.quaternion[2], o.quaternion[3]));
        assert!((q.to_rotation_matrix().into_inner() - tool_rot).norm() < 1e-9, "{o:?}");
        assert!((o.levers_mm[0] - 80.0).abs() < 1e-6 && o.axes_sd_deg > 0.0);
        let turned = Frame { rot: f[0].rot, ..moved(Vector3::z()) };
        assert!(tool_orientation(&f[3], &turned, &moved(Vector3::x()), &tool, 0.01).unwrap_err().to_string().contains("without turning"));
    }

    #[test]
    fn the_user_frame_is_the_touched_plane() {
        let o = Vector3::new(0.5, 0.1, 0.05);
        let rot = Rotation3::from_euler_angles(0.02, -0.01, 0.6).into_inner();
        let (x, xy) = (o + rot * Vector3::new(0.2, 0.0, 0.0), o + rot * Vector3::new(0.05, 0.15, 0.0));
        let f = user_frame(&o, &x, &xy, 0.02).unwrap();
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(f.quaternion[0], f.quaternion[1], f.quaternion[2], f.quaternion[3]));
        assert!((q.to_rotation_matrix().into_inner() - rot).norm() < 1e-12);
        assert!(user_frame(&o, &x, &(o + rot * Vector3::new(0.3, 0.001, 0.0)), 0.02).is_err(), "an xy point on the x axis fixes no plane");
    }
}
