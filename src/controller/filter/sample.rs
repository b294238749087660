//! Programs written the way an offline programming system writes them, for checking the
//! filter and the executed-program verification: Cartesian targets with their configuration
//! data in a work object (base) with a tool, each moved to once, plus a run-time target and a
//! joint target that the filter must leave.

use super::Layout;
use crate::controller::{Language, ProgramFile};
use crate::measurement::Euler;
use nalgebra::{Isometry3, Matrix3, Rotation3};
use std::fmt::Write;

/// A program's content.
#[derive(Clone, Debug)]
pub struct SampleProgram {
    /// The program's name.
    pub name: String,
    /// The tool: the TCP in the controller's flange frame (tool0), mm.
    pub tool: Isometry3<f64>,
    /// The work object (base) in the controller's base frame, mm (URScript has none: its
    /// targets are in the base frame).
    pub frame: Isometry3<f64>,
    /// The Cartesian targets: the TCP's pose in the frame (mm) and the configuration data the
    /// language writes (empty for URScript).
    pub targets: Vec<(Isometry3<f64>, Vec<i64>)>,
    /// A joint target (rad) the program moves to first.
    pub home: Vec<f64>,
}

/// The layout of a language's Cartesian targets.
pub fn pose_layout(lang: Language) -> Layout {
    match lang {
        Language::Rapid => Layout::RapidPose,
        Language::Krl => Layout::KrlPose { config: true },
        Language::Urscript => Layout::UrPose,
    }
}

fn quat(p: &Isometry3<f64>) -> String {
    let q = p.rotation.quaternion();
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    format!("{:.6},{:.6},{:.6},{:.6}", s * q.w, s * q.i, s * q.j, s * q.k)
}

fn xyz(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector;
    format!("{:.3},{:.3},{:.3}", t.x, t.y, t.z)
}

fn rot(p: &Isometry3<f64>) -> Matrix3<f64> {
    p.rotation.to_rotation_matrix().into_inner()
}

fn krl_frame(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector;
    let [a, b, c] = Euler::ZYX.angles(&rot(p)).map(f64::to_degrees);
    format!("X {:.3},Y {:.3},Z {:.3},A {a:.4},B {b:.4},C {c:.4}", t.x, t.y, t.z)
}

fn ur_pose(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector / 1000.0;
    let v = Rotation3::from_matrix(&rot(p)).scaled_axis();
    format!("p[{:.6}, {:.6}, {:.6}, {:.6}, {:.6}, {:.6}]", t.x, t.y, t.z, v.x, v.y, v.z)
}

impl SampleProgram {
    /// The program's files and the frames file beside it (KRL's `$config.dat`; none for the
    /// others, which declare their frames in the program).
    pub fn write(&self, lang: Language) -> (Vec<ProgramFile>, Vec<ProgramFile>) {
        match lang {
            Language::Rapid => (vec![self.rapid()], Vec::new()),
            Language::Krl => self.krl(),
            Language::Urscript => (vec![self.urscript()], Vec::new()),
        }
    }

    fn rapid(&self) -> ProgramFile {
        let mut t = String::new();
        let _ = writeln!(t, "MODULE {}\r", self.name);
        let _ = writeln!(t, "    ! Written offline: {} targets in twc_wobj with twc_tool.\r", self.targets.len());
        let _ = writeln!(t, "    PERS tooldata twc_tool := [TRUE,[[{}],[{}]],[1.5,[0,0,40],[1,0,0,0],0,0,0]];\r", xyz(&self.tool), quat(&self.tool));
        let _ = writeln!(t, "    TASK PERS wobjdata twc_wobj := [FALSE,TRUE,\"\",[[{}],[{}]],[[0,0,0],[1,0,0,0]]];\r", xyz(&self.frame), quat(&self.frame));
        let home: Vec<String> = self.home.iter().map(|v| format!("{:.4}", v.to_degrees())).collect();
        let _ = writeln!(t, "    CONST jointtarget twc_home := [[{}],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\r", home.join(","));
        for (i, (p, cfg)) in self.targets.iter().enumerate() {
            let c: Vec<String> = cfg.iter().map(|v| v.to_string()).collect();
            let _ =
                writeln!(t, "    CONST robtarget twc_t{} := [[{}],[{}],[{}],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\r", i + 1, xyz(p), quat(p), c.join(","));
        }
        let _ = writeln!(t, "\r\n    PROC main()\r");
        let _ = writeln!(t, "        MoveAbsJ twc_home, v200, fine, tool0;\r");
        for i in 0..self.targets.len() {
            let _ = writeln!(t, "        MoveJ twc_t{}, v200, fine, twc_tool\\WObj:=twc_wobj;  ! target {}\r", i + 1, i + 1);
        }
        let _ = writeln!(t, "        MoveL Offs(twc_t1, 0, 0, 20), v100, z10, twc_tool\\WObj:=twc_wobj;\r");
        let _ = writeln!(t, "    ENDPROC\r\nENDMODULE\r");
        ProgramFile { name: format!("{}.mod", self.name), text: t }
    }

    fn krl(&self) -> (Vec<ProgramFile>, Vec<ProgramFile>) {
        let name = self.name.to_ascii_uppercase();
        let mut src = format!("&ACCESS RVP\n&REL 1\nDEF {name}( )\n  ; written offline: {} targets in BASE_DATA[2] with TOOL_DATA[1]\n", self.targets.len());
        let _ = writeln!(src, "  BAS(#TOOL,0)\n  BAS(#BASE,0)\n  PTP XTWC_HOME");
        let _ = writeln!(src, "  BAS(#TOOL,1)\n  BAS(#BASE,2)");
        for i in 0..self.targets.len() {
            let _ = writeln!(src, "  PTP XTWC_T{}   ; target {}", i + 1, i + 1);
        }
        let _ = writeln!(src, "  LIN_REL {{Z 20.0}} C_DIS\nEND");
        let mut dat = format!("&ACCESS RVP\n&REL 1\nDEFDAT {name} PUBLIC\n");
        let home: Vec<String> = self.home.iter().enumerate().map(|(j, v)| format!("A{} {:.4}", j + 1, v.to_degrees())).collect();
        let _ = writeln!(dat, "  DECL E6AXIS XTWC_HOME={{{},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}", home.join(","));
        for (i, (p, cfg)) in self.targets.iter().enumerate() {
            let _ = writeln!(dat, "  DECL E6POS XTWC_T{}={{{},S {},T {},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}", i + 1, krl_frame(p), cfg[0], cfg[1]);
        }
        let _ = writeln!(dat, "ENDDAT");
        let config = format!("DEFDAT $CONFIG\n  TOOL_DATA[1]={{{}}}\n  BASE_DATA[2]={{{}}}\nENDDAT\n", krl_frame(&self.tool), krl_frame(&self.frame));
        (
            vec![ProgramFile { name: format!("{}.src", self.name), text: src }, ProgramFile { name: format!("{}.dat", self.name), text: dat }],
            vec![ProgramFile { name: "$config.dat".into(), text: config }],
        )
    }

    fn urscript(&self) -> ProgramFile {
        let mut t = format!("def {}():\n  # written offline: {} targets in the base frame\n", self.name, self.targets.len());
        let _ = writeln!(t, "  set_tcp({})", ur_pose(&self.tool));
        let home: Vec<String> = self.home.iter().map(|v| format!("{v:.6}")).collect();
        let _ = writeln!(t, "  movej([{}], a=1.4, v=1.05)", home.join(", "));
        for (i, (p, _)) in self.targets.iter().enumerate() {
            let _ = writeln!(t, "  movel({}, a=1.2, v=0.25)  # target {}", ur_pose(&(self.frame * p)), i + 1);
        }
        let _ = writeln!(t, "  movel(pose_trans(get_actual_tcp_pose(), p[0, 0, -0.02, 0, 0, 0]), a=1.2, v=0.25)\nend");
        ProgramFile { name: format!("{}.script", self.name), text: t }
    }
}
