//! A calibrated model as a URDF: one revolute joint per chain joint, with the
//! calibrated frame between consecutive joint axes as its origin (joint zero offsets folded in),
//! fixed frames for the flange, the draw-wire tool point and the cable exit point. Inertial data
//! are carried over from the nominal robot when there is one, moved into the calibrated frames.

use super::joint_frames;
use crate::calib::model::CalibModel;
use crate::robot::kinematics::{rpy, FkWork, Frame};
use crate::robot::Robot;
use nalgebra::Vector3;
use std::fmt::Write;

fn origin(f: &Frame) -> String {
    let [r, p, y] = rpy(&f.rot);
    format!("<origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/>", f.pos.x, f.pos.y, f.pos.z, r, p, y)
}

/// The calibrated URDF text. `nominal` supplies inertials (moved into the calibrated frames).
pub fn urdf(model: &CalibModel, x: &[f64], nominal: Option<&Robot>, name: &str) -> String {
    let (frames, axes, flange) = joint_frames(model, x);
    let n = frames.len();
    // Where the nominal robot's link frames sit in the model's own frames (at nominal parameters).
    let (nom_frames, _, _) = joint_frames(model, &model.nominal);
    let nominal_urdf_frames: Option<Vec<Frame>> = nominal.map(|r| {
        let c = r.error_chain();
        let mut ws = FkWork::new(&c);
        c.forward(&vec![0.0; c.n_joints], &vec![0.0; c.n_params()], 1.0, &mut ws);
        (0..c.n_joints).map(|j| c.frame(&ws, j + 1)).collect()
    });
    let mut out = String::new();
    let _ = writeln!(out, "<?xml version=\"1.0\"?>");
    let _ = writeln!(out, "<!-- Calibrated by twincal ({} model). Units: m, rad, kg. -->", model.name);
    let _ = writeln!(out, "<robot name=\"{name}\">");
    let _ = writeln!(out, "  <link name=\"base_link\"/>");
    let mut parent = "base_link".to_string();
    let mut parent_frame = Frame::identity();
    for j in 0..n {
        let link = format!("link_{}", j + 1);
        let _ = writeln!(out, "  <link name=\"{link}\">");
        if let (Some(r), Some(uf)) = (nominal, &nominal_urdf_frames) {
            if let Some(inertial) = r.links.get(j) {
                // URDF link frame expressed in the model's link frame.
                let rel = uf[j].relative_to(&nom_frames[j]);
                let i = inertial.transformed(&rel);
                let t = &i.inertia;
                let _ = writeln!(
                    out,
                    "    <inertial><origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/><mass value=\"{}\"/><inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/></inertial>",
                    i.com.x, i.com.y, i.com.z, i.mass, t[(0, 0)], t[(0, 1)], t[(0, 2)], t[(1, 1)], t[(1, 2)], t[(2, 2)]
                );
            }
        }
        let _ = writeln!(out, "  </link>");
        let rel = frames[j].relative_to(&parent_frame);
        // An arm without a nominal has no known limits, and its controller may log angles past
        // ±180° (HSR's q3 reads about 215°): ±360°.
        let (lo, hi) = nominal.and_then(|r| r.joints.get(j)).map(|jt| (jt.lower, jt.upper)).unwrap_or((-std::f64::consts::TAU, std::f64::consts::TAU));
        let vel = nominal.and_then(|r| r.joints.get(j)).map(|jt| jt.max_velocity).unwrap_or(1.0);
        let a = axes[j];
        // A continuous joint stays one (its stops-free rotation is the nominal's, not a ±180° range).
        let continuous = nominal.and_then(|r| r.joints.get(j)).is_some_and(|jt| jt.continuous);
        let _ = writeln!(out, "  <joint name=\"joint_{}\" type=\"{}\">", j + 1, if continuous { "continuous" } else { "revolute" });
        let _ = writeln!(out, "    <parent link=\"{parent}\"/>\n    <child link=\"{link}\"/>");
        let _ = writeln!(out, "    {}", origin(&rel));
        let _ = writeln!(out, "    <axis xyz=\"{} {} {}\"/>", a.x, a.y, a.z);
        if continuous {
            let _ = writeln!(out, "    <limit effort=\"0\" velocity=\"{vel}\"/>");
        } else {
            let _ = writeln!(out, "    <limit lower=\"{lo}\" upper=\"{hi}\" effort=\"0\" velocity=\"{vel}\"/>");
        }
        let _ = writeln!(out, "  </joint>");
        parent = link;
        parent_frame = frames[j];
    }
    let fixed = |out: &mut String, name: &str, parent: &str, f: &Frame| {
        let _ = writeln!(out, "  <link name=\"{name}\"/>");
        let _ = writeln!(
            out,
            "  <joint name=\"{parent}-{name}\" type=\"fixed\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{name}\"/>\n    {}\n  </joint>",
            origin(f)
        );
    };
    fixed(&mut out, "flange", &parent, &flange.relative_to(&parent_frame));
    let placement = model.placement(x);
    match placement.exit() {
        Some(exit) => {
            fixed(&mut out, "cable_tool_point", "flange", &Frame { rot: nalgebra::Matrix3::identity(), pos: placement.tool });
            fixed(&mut out, "cable_exit_point", "base_link", &Frame { rot: nalgebra::Matrix3::identity(), pos: exit });
            let _ = writeln!(out, "  <!-- draw-wire length offset: {} m -->", placement.own[3]);
        }
        None => {
            // A pose's probe has its orientation on the flange.
            let rot = model.measurement.def().target_rotation(&placement.own);
            fixed(&mut out, "tracker_target", "flange", &Frame { rot, pos: placement.tool });
            let names = model.measurement.placement_names();
            let own: Vec<String> = names.iter().zip(&placement.own).map(|(n, v)| format!("{n} = {v}")).collect();
            let _ = writeln!(out, "  <!-- {} placement (m, rad): {} -->", model.measurement.def().describe(), own.join(", "));
        }
    }
    let _ = writeln!(out, "</robot>");
    out
}

/// The URDF format.
pub struct Urdf;

impl super::ExportFormat for Urdf {
    fn name(&self) -> &'static str {
        "urdf"
    }
    fn describe(&self) -> &'static str {
        "a URDF: the calibrated frames as joint origins, inertials from the nominal robot"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["urdf"]
    }
    fn write(
        &self,
        _table: &super::JointTable,
        model: &CalibModel,
        x: &[f64],
        nominal: Option<&Robot>,
        _ext: &str,
        _warnings: &mut Vec<String>,
    ) -> crate::error::Result<String> {
        Ok(urdf(model, x, nominal, "calibrated"))
    }
    /// The chain from the base link to the flange, and the tool point: the origin of the fixed
    /// frame the export hangs on the flange (`cable_tool_point` or `tracker_target`), else the
    /// flange's own origin.
    fn read(&self, text: &str, _ext: &str) -> crate::error::Result<super::ReadBack> {
        let robot = Robot::from_urdf_str(text, "the exported URDF")?;
        let doc = urdf_rs::read_from_string(text).map_err(|e| crate::error::Error::Invalid(format!("the exported URDF: {e}")))?;
        let tcp = doc
            .joints
            .iter()
            .find(|j| j.parent.link == robot.flange_name && matches!(j.child.link.as_str(), "cable_tool_point" | "tracker_target"))
            .map_or_else(Vector3::zeros, |j| Vector3::new(j.origin.xyz[0], j.origin.xyz[1], j.origin.xyz[2]));
        let chain = robot.error_chain();
        Ok(super::ReadBack { params: vec![0.0; chain.n_params()], chain, tcp })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn rpy_is_exact_at_and_near_gimbal_lock() {
        let half = std::f64::consts::FRAC_PI_2;
        for (r, p, y) in [(0.3, 0.2, -1.1), (2.498, -half + 1.5e-8, 0.588), (0.7, half, 0.0), (-0.4, -half, 1.3), (1.0, half - 1e-13, -2.0)] {
            let m = Rotation3::from_euler_angles(r, p, y).into_inner();
            let [a, b, c] = rpy(&m);
            let back = Rotation3::from_euler_angles(a, b, c).into_inner();
            assert!((back - m).norm() < 1e-12, "({r}, {p}, {y}) -> ({a}, {b}, {c}): {:.3e}", (back - m).norm());
        }
    }
    use crate::calib::model::DrawWireGuess;

    #[test]
    fn exported_urdf_reproduces_the_calibrated_model() {
        let robot = Robot::irb120();
        let g = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.062, 0.004, -0.003] };
        // The generic model: a product of exponentials around lines at a reference pose.
        use crate::calib::pipeline::generic::{frames_of, model_around, Line};
        let line = |p: [f64; 3], d: [f64; 3]| Line { point: Vector3::from(p), dir: Vector3::from(d).normalize() };
        let lines = [
            line([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            line([0.15, 0.0, 0.0], [0.0, 1.0, 0.0]),
            line([0.4, 0.0, 0.6], [0.0, 1.0, 0.0]),
            line([0.8, 0.0, 0.7], [1.0, 0.0, 0.1]),
            line([0.8, 0.0, 0.7], [0.0, 1.0, 0.0]),
            line([0.8, 0.0, 0.7], [1.0, 0.0, 0.0]),
        ];
        let cable = crate::measurement::Placement::cable(Vector3::from(g.exit_m), g.offset_m, Vector3::from(g.tool_m));
        let generic = model_around(&frames_of(&lines), &[0.2, -1.3, 3.7, -2.8, 0.7, 1.1], &cable);
        for m in [CalibModel::dh(&robot, &g, true), CalibModel::frame(&robot, &g), generic] {
            let mut x = m.nominal.clone();
            for k in 0..m.n_chain() {
                x[k] += 1e-3 * ((k as f64) * 2.1).sin();
            }
            let text = urdf(&m, &x, (m.name != "generic6r").then_some(&robot), "calibrated");
            let r = Robot::from_urdf_str(&text, "exported").unwrap();
            assert_eq!(r.flange_name, "flange");
            let c = r.error_chain();
            let p0 = vec![0.0; c.n_params()];
            let mut w = m.work();
            let tool = Vector3::new(x[m.n_chain() + 4], x[m.n_chain() + 5], x[m.n_chain() + 6]);
            for k in 0..10 {
                let q: Vec<f64> = (0..6).map(|j| ((k * 5 + j) as f64 * 0.61).sin() * 1.5).collect();
                let a = m.tool_point(&x, &q, &mut w);
                let b = c.point(&q, &p0, 1.0, c.flange(), &tool);
                assert!((a - b).norm() < 1e-9, "{}: {a} vs {b}", m.name);
            }
            if m.name != "generic6r" {
                assert!((r.links.iter().map(|l| l.mass).sum::<f64>() - robot.links.iter().map(|l| l.mass).sum::<f64>()).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn a_continuous_joint_is_exported_as_one() {
        // The IRB 120 with its joint 6 made continuous: the export keeps the type (no ±180° stops).
        let text = crate::robot::IRB120_URDF;
        let i = text.rfind("type=\"revolute\"").unwrap();
        let text = format!("{}type=\"continuous\"{}", &text[..i], &text[i + "type=\"revolute\"".len()..]);
        let robot = Robot::from_urdf_str(&text, "continuous").unwrap();
        assert!(robot.joints[5].continuous && !robot.joints[4].continuous);
        let g = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.062, 0.004, -0.003] };
        let m = CalibModel::frame(&robot, &g);
        let exported = urdf(&m, &m.nominal, Some(&robot), "calibrated");
        assert_eq!(exported.matches("type=\"continuous\"").count(), 1, "{exported}");
        let back = Robot::from_urdf_str(&exported, "exported").unwrap();
        assert!(back.joints[5].continuous && (back.joints[5].upper - std::f64::consts::PI).abs() < 1e-12);
    }
}
