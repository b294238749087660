//! What a controller that takes no new kinematic model can be given of a calibration: the
//! joints' zero offsets, the tool (TCP) and, for an instrument with a frame of its own (a
//! tracker), that frame as a user frame / base, written as RAPID data (`tooldata`, `wobjdata`
//! and a table of offsets) or KRL data (`FRAME`s for `TOOL_DATA` / `BASE_DATA`, and the table).
//!
//! The values are those of a calibration that fitted only them (`calibrate
//! --controller-subset`): a full calibration's offsets absorb errors the controller cannot take
//! and are refused.

use super::Language;
use crate::calib::pipeline::CalibResult;
use crate::error::{Error, Result};
use crate::robot::kinematics::rpy;
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use std::fmt::Write;

/// The controller-writable values of a calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerData {
    /// Per joint its name and zero offset, degrees: the arm's joint stands this much beyond
    /// the angle the controller reads (true angle = reading + offset).
    pub joint_offsets_deg: Vec<(String, f64)>,
    /// The tool point (TCP) in the flange frame, mm.
    pub tool_mm: Vector3<f64>,
    /// The tool's orientation in the flange frame (a 6-D probe's; identity for a point).
    pub tool_rot: Matrix3<f64>,
    /// Whether the instrument measured the tool's orientation (a 6-D probe): else the tool has
    /// none of its own, and its axes are the controller flange's.
    pub tool_oriented: bool,
    /// The instrument's frame in the robot's base frame (origin mm, axes as columns), where the
    /// instrument reads coordinates of its own: a user frame in which points measured by it are
    /// the robot's targets.
    pub user_frame: Option<(Vector3<f64>, Matrix3<f64>)>,
    /// The payload the calibration was made with (kg, centre of mass in the flange frame, mm).
    pub payload: Option<(f64, [f64; 3])>,
    /// The joints whose offset the data cannot tell from the base frame or the tool (held at
    /// zero, their share in those).
    pub held: Vec<String>,
    /// What the subset leaves on the calibration's held-out rows, beside the nominal model and a
    /// full calibration of the same rows, in words (a line of the file's header).
    pub accuracy: Option<String>,
}

impl ControllerData {
    /// The values of `r`, a calibration of the controller subset (every other fitted parameter
    /// refused by name).
    pub fn of(r: &CalibResult) -> Result<ControllerData> {
        let m = &r.model;
        let zero_offsets = m.chain.zero_offset_params();
        let chain = 0..m.n_chain();
        let fitted = |k: usize| r.parameters.iter().any(|p| p.name == m.names[k] && !p.fixed);
        if let Some(k) = chain.clone().find(|k| !zero_offsets.contains(k) && fitted(*k)) {
            return Err(Error::Invalid(format!(
                "the calibration fitted {}, which no controller without a kinematic model takes: calibrate with --controller-subset to fit what it takes",
                m.names[k]
            )));
        }
        if !m.effects.is_empty() || r.corrector.is_some() {
            return Err(Error::Invalid("the calibration carries effects or a learned corrector, which no controller without a kinematic model takes: calibrate with --controller-subset".into()));
        }
        let joint_offsets_deg = zero_offsets.iter().enumerate().map(|(j, &k)| (format!("joint_{}", j + 1), (r.x[k] - m.nominal[k]).to_degrees())).collect();
        let held = zero_offsets.iter().enumerate().filter(|(_, k)| !fitted(**k)).map(|(j, _)| format!("joint_{}", j + 1)).collect();
        let placement = m.placement(&r.x);
        let frame = m.measurement.def().frame(&placement.own);
        Ok(ControllerData {
            joint_offsets_deg,
            held,
            tool_mm: crate::units::to_mm(placement.tool),
            tool_rot: m.measurement.def().target_rotation(&placement.own),
            tool_oriented: m.measurement == crate::measurement::Measurement::Pose,
            user_frame: frame.axes.map(|a| (crate::units::to_mm(frame.origin), a)),
            payload: r.torque_model.as_ref().and_then(|t| t.payload).filter(|(mass, _)| *mass > 0.0).map(|(mass, c)| (mass, c.map(crate::units::to_mm))),
            accuracy: None,
        })
    }

    /// The data in the controller's own frames ([`crate::robot::Robot::controller_frames`]): the
    /// tool in the controller's flange frame (tool0; a tool without an orientation of its own
    /// keeps tool0's axes), the instrument's frame in the controller's base frame.
    pub fn in_controller_frames(mut self, base: &crate::robot::kinematics::Frame, tool0: &crate::robot::kinematics::Frame) -> ControllerData {
        // tool0⁻¹ · (tool point, tool axes): both given in the model's flange frame.
        let rt = tool0.rot.transpose();
        self.tool_mm = rt * (self.tool_mm - crate::units::to_mm(tool0.pos));
        if self.tool_oriented {
            self.tool_rot = rt * self.tool_rot;
        }
        self.payload = self.payload.map(|(m, c)| (m, (rt * (nalgebra::Vector3::from(c) - crate::units::to_mm(tool0.pos))).into()));
        let rb = base.rot.transpose();
        self.user_frame = self.user_frame.map(|(o, a)| (rb * (o - crate::units::to_mm(base.pos)), rb * a));
        self
    }

    /// The data as a file of `lang` (its name, its text); `tool_mass_kg` stands in for a
    /// payload the calibration did not state (RAPID's `tooldata` needs a mass).
    pub fn write(&self, lang: Language, name: &str, tool_mass_kg: Option<f64>, source: &str) -> Result<super::ProgramFile> {
        match lang {
            Language::Rapid => self.rapid(name, tool_mass_kg, source),
            Language::Krl => Ok(self.krl(name, source)),
            Language::Urscript => Ok(self.urscript(name, source)),
        }
    }

    /// The header's lines: where the values come from and the offsets' table.
    fn header(&self, source: &str) -> Vec<String> {
        let mut lines = vec![
            format!("twincal controller data of {source} (calibrate --controller-subset)."),
            "Joint zero offsets, degrees (the arm's joint stands this much beyond the angle the controller reads;".into(),
            "enter them in the controller's joint calibration with its own sign convention):".into(),
        ];
        lines.extend(self.joint_offsets_deg.iter().map(|(n, v)| format!("  {n} {:+.6}", clean(*v))));
        lines.extend(self.accuracy.clone());
        if !self.held.is_empty() {
            lines.push(format!("Held at zero, the data cannot tell them from the base frame and the tool: {}.", self.held.join(", ")));
        }
        lines
    }

    fn rapid(&self, name: &str, tool_mass_kg: Option<f64>, source: &str) -> Result<super::ProgramFile> {
        let (mass, cog) = match (self.payload, tool_mass_kg) {
            (_, Some(m)) if m > 0.0 && m.is_finite() => (m, self.payload.map_or([0.0; 3], |p| p.1)),
            (Some((m, c)), None) => (m, c),
            _ => return Err(Error::Invalid("a RAPID tooldata needs the tool's mass: the calibration states no payload, give --tool-mass-kg (> 0)".into())),
        };
        let mut t = String::new();
        let _ = writeln!(t, "MODULE {name}");
        for line in self.header(source) {
            let _ = writeln!(t, "    ! {line}");
        }
        let q = quaternion(&self.tool_rot);
        let p = self.tool_mm;
        let _ = writeln!(
            t,
            "    PERS tooldata twc_tool := [TRUE,[[{:.4},{:.4},{:.4}],[{}]],[{mass},[{:.4},{:.4},{:.4}],[1,0,0,0],0,0,0]];",
            p.x, p.y, p.z, q, cog[0], cog[1], cog[2]
        );
        if let Some((o, a)) = &self.user_frame {
            let _ = writeln!(t, "    ! The instrument's frame as a work object: targets in its coordinates are reached as measured.");
            let _ = writeln!(
                t,
                "    PERS wobjdata twc_instrument := [FALSE,TRUE,\"\",[[{:.4},{:.4},{:.4}],[{}]],[[0,0,0],[1,0,0,0]]];",
                o.x,
                o.y,
                o.z,
                quaternion(a)
            );
        }
        let _ = writeln!(t, "ENDMODULE");
        Ok(super::ProgramFile { name: format!("{name}.mod"), text: t })
    }

    fn krl(&self, name: &str, source: &str) -> super::ProgramFile {
        let name_uc = name.to_ascii_uppercase();
        let mut t = String::from("&ACCESS RVP\n&REL 1\n");
        let _ = writeln!(t, "DEFDAT {name_uc} PUBLIC");
        for line in self.header(source) {
            let _ = writeln!(t, "  ; {line}");
        }
        let _ = writeln!(t, "  ; Copy TWC_TOOL into a TOOL_DATA[n] and TWC_BASE into a BASE_DATA[n] of $config.dat (A, B, C: Z-Y-X, degrees).");
        let _ = writeln!(t, "  DECL GLOBAL FRAME TWC_TOOL={}", frame_krl(&self.tool_mm, &self.tool_rot));
        if let Some((o, a)) = &self.user_frame {
            let _ = writeln!(t, "  DECL GLOBAL FRAME TWC_BASE={}", frame_krl(o, a));
        }
        let _ = writeln!(t, "ENDDAT");
        super::ProgramFile { name: format!("{name}.dat"), text: t }
    }

    fn urscript(&self, name: &str, source: &str) -> super::ProgramFile {
        let mut t = String::new();
        for line in self.header(source) {
            let _ = writeln!(t, "# {line}");
        }
        let _ = writeln!(t, "# The joint offsets go to the robot's kinematics (twincal export --format ur-yaml of the same result).");
        let _ = writeln!(t, "def {name}():");
        let _ = writeln!(t, "  set_tcp({})", pose_ur(&self.tool_mm, &self.tool_rot));
        if let Some((o, a)) = &self.user_frame {
            let _ = writeln!(t, "  # The instrument's frame in the base frame: pose_trans(twc_instrument, p) is a point p it measured.");
            let _ = writeln!(t, "  global twc_instrument = {}", pose_ur(o, a));
        }
        let _ = writeln!(t, "end");
        super::ProgramFile { name: format!("{name}.script"), text: t }
    }
}

/// RAPID's quaternion `q1,q2,q3,q4` (w first, w ≥ 0) of a rotation.
fn quaternion(r: &Matrix3<f64>) -> String {
    let q = UnitQuaternion::from_matrix(r);
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    format!("{:.9},{:.9},{:.9},{:.9}", s * q.w, s * q.i, s * q.j, s * q.k)
}

/// A KRL `FRAME` (mm; A, B, C the Z-Y-X angles in degrees: R = Rz(A)·Ry(B)·Rx(C)).
fn frame_krl(p: &Vector3<f64>, r: &Matrix3<f64>) -> String {
    let [roll, pitch, yaw] = rpy(r).map(f64::to_degrees);
    format!("{{X {:.4},Y {:.4},Z {:.4},A {:.6},B {:.6},C {:.6}}}", clean(p.x), clean(p.y), clean(p.z), clean(yaw), clean(pitch), clean(roll))
}

/// `v` with a value that prints as zero printed without a sign (no `-0.000000`).
fn clean(v: f64) -> f64 {
    if v.abs() < 5e-7 {
        0.0
    } else {
        v
    }
}

/// A URScript pose `p[x, y, z, rx, ry, rz]` (m, rotation vector in rad).
fn pose_ur(p_mm: &Vector3<f64>, r: &Matrix3<f64>) -> String {
    let v = nalgebra::Rotation3::from_matrix(r).scaled_axis();
    let p = p_mm / 1000.0;
    format!("p[{:.7}, {:.7}, {:.7}, {:.9}, {:.9}, {:.9}]", p.x, p.y, p.z, v.x, v.y, v.z)
}
