//! ABB RAPID: the tour as a module of `jointtarget`s moved to by `MoveAbsJ`, the handshake on
//! `PERS bool` variables.

use super::{deg, header, numbers, Dialect, ProgramFile, Tour};
use crate::error::{Error, Result};
use std::fmt::Write;

/// RAPID.
pub(super) struct Rapid;

/// An unused external axis in a `jointtarget`.
const NO_AXIS: &str = "9E+09";

impl Dialect for Rapid {
    fn joints(&self) -> std::ops::RangeInclusive<usize> {
        6..=7
    }
    fn measurement_program(&self, tour: &Tour) -> Vec<ProgramFile> {
        let mut t = String::new();
        let _ = writeln!(t, "MODULE {}", tour.name);
        let handshake = "Handshake: twc_ready is TRUE while the arm holds still at pose twc_pose; set twc_measured := TRUE (Robot Web Services, PC SDK) once it is measured.";
        for line in header(tour, "degrees", handshake) {
            let _ = writeln!(t, "    ! {line}");
        }
        let _ = writeln!(t, "    PERS bool twc_ready := FALSE;");
        let _ = writeln!(t, "    PERS bool twc_measured := FALSE;");
        let _ = writeln!(t, "    PERS num twc_pose := 0;");
        let _ = writeln!(t, "    CONST num twc_hold := {};", tour.hold_s);
        for (i, q) in tour.q.iter().enumerate() {
            let arm: Vec<String> = q.iter().take(6).map(|v| deg(*v)).collect();
            let mut ext: Vec<String> = q.iter().skip(6).map(|v| deg(*v)).collect();
            ext.resize(6, NO_AXIS.to_string());
            let _ = writeln!(t, "    CONST jointtarget twc_p{} := [[{}],[{}]];", i + 1, arm.join(","), ext.join(","));
        }
        let _ = writeln!(t);
        let _ = writeln!(t, "    PROC main()");
        let _ = writeln!(t, "        twc_ready := FALSE;");
        let _ = writeln!(t, "        VelSet {}, 5000;", (100.0 * tour.speed_fraction).round().max(1.0));
        for i in 0..tour.q.len() {
            if let Some(m) = tour.payload_change(i) {
                let _ = writeln!(t, "        TPWrite \"twincal: mount the {m} kg payload, set its load data, start again\";");
                let _ = writeln!(t, "        Stop;");
            }
            let _ = writeln!(t, "        MoveAbsJ twc_p{}\\NoEOffs, v1000, fine, tool0;", i + 1);
            let _ = writeln!(t, "        twc_measure {};", i + 1);
        }
        let _ = writeln!(t, "    ENDPROC");
        let _ = writeln!(t);
        let _ = writeln!(t, "    PROC twc_measure(num pose)");
        let _ = writeln!(t, "        WaitTime twc_hold;");
        let _ = writeln!(t, "        twc_pose := pose;");
        let _ = writeln!(t, "        twc_measured := FALSE;");
        let _ = writeln!(t, "        twc_ready := TRUE;");
        let _ = writeln!(t, "        WaitUntil twc_measured;");
        let _ = writeln!(t, "        twc_ready := FALSE;");
        let _ = writeln!(t, "    ENDPROC");
        let _ = writeln!(t, "ENDMODULE");
        vec![ProgramFile { name: format!("{}.mod", tour.name), text: t }]
    }

    fn joint_targets(&self, files: &[ProgramFile]) -> Result<Vec<Vec<f64>>> {
        let text = &files.first().ok_or_else(|| Error::Invalid("no RAPID module".into()))?.text;
        let mut out = Vec::new();
        for line in text.lines() {
            let Some(rest) = line.trim().strip_prefix("MoveAbsJ ") else { continue };
            let name = rest.split(['\\', ',']).next().unwrap_or("").trim();
            let decl = format!("CONST jointtarget {name} := [[");
            let at = text.find(&decl).ok_or_else(|| Error::Invalid(format!("MoveAbsJ {name}: no jointtarget declared")))?;
            let body = &text[at + decl.len()..];
            let arm_end = body.find(']').ok_or_else(|| Error::Invalid(format!("{name}: unclosed robax")))?;
            let mut q = numbers(&body[..arm_end], name)?;
            let ext_start = body[arm_end..].find('[').map(|k| arm_end + k + 1).ok_or_else(|| Error::Invalid(format!("{name}: no extax")))?;
            let ext_end = ext_start + body[ext_start..].find(']').ok_or_else(|| Error::Invalid(format!("{name}: unclosed extax")))?;
            q.extend(numbers(&body[ext_start..ext_end], name)?.into_iter().filter(|v| *v < 8.9e9));
            out.push(q.into_iter().map(f64::to_radians).collect());
        }
        Ok(out)
    }
}
