//! Universal Robots URScript: the tour as one program of `movej` to joint lists (radians), the
//! handshake on RTDE boolean registers.

use super::{header, numbers, Dialect, ProgramFile, Tour};
use crate::error::{Error, Result};
use std::fmt::Write;

/// URScript.
pub(super) struct UrScript;

/// A UR joint's top speed, rad/s (180°/s on the UR3, UR5 and UR10's wrists; their base and
/// shoulder are slower, which the controller limits itself).
const TOP_SPEED_RAD_S: f64 = std::f64::consts::PI;

impl Dialect for UrScript {
    fn joints(&self) -> std::ops::RangeInclusive<usize> {
        6..=6
    }
    fn measurement_program(&self, tour: &Tour) -> Vec<ProgramFile> {
        let handshake = "Handshake: RTDE output boolean register 64 is True while the arm holds still at the pose in output integer register 24; set input boolean register 64 to True once it is measured, then back to False.";
        let mut t = String::new();
        let _ = writeln!(t, "def {}():", tour.name);
        for line in header(tour, "radians", handshake) {
            let _ = writeln!(t, "  # {line}");
        }
        let _ = writeln!(t, "  def twc_measure(pose):");
        let _ = writeln!(t, "    sleep({})", tour.hold_s);
        let _ = writeln!(t, "    write_output_integer_register(24, pose)");
        let _ = writeln!(t, "    write_output_boolean_register(64, True)");
        let _ = writeln!(t, "    while not read_input_boolean_register(64):");
        let _ = writeln!(t, "      sync()");
        let _ = writeln!(t, "    end");
        let _ = writeln!(t, "    write_output_boolean_register(64, False)");
        let _ = writeln!(t, "    while read_input_boolean_register(64):");
        let _ = writeln!(t, "      sync()");
        let _ = writeln!(t, "    end");
        let _ = writeln!(t, "  end");
        let _ = writeln!(t, "  write_output_boolean_register(64, False)");
        let v = TOP_SPEED_RAD_S * tour.speed_fraction;
        for (i, q) in tour.q.iter().enumerate() {
            if let Some(m) = tour.payload_change(i) {
                let _ = writeln!(t, "  popup(\"twincal: mount the {m} kg payload, set it in the installation, continue\", title=\"twincal\", blocking=True)");
            }
            let list: Vec<String> = q.iter().map(|v| format!("{v:.9}")).collect();
            let _ = writeln!(t, "  movej([{}], a=1.4, v={v:.4})", list.join(", "));
            let _ = writeln!(t, "  twc_measure({})", i + 1);
        }
        let _ = writeln!(t, "end");
        let _ = writeln!(t, "{}()", tour.name);
        vec![ProgramFile { name: format!("{}.script", tour.name), text: t }]
    }

    fn joint_targets(&self, files: &[ProgramFile]) -> Result<Vec<Vec<f64>>> {
        let text = &files.first().ok_or_else(|| Error::Invalid("no URScript file".into()))?.text;
        let mut out = Vec::new();
        for line in text.lines() {
            let Some(rest) = line.trim().strip_prefix("movej([") else { continue };
            let end = rest.find(']').ok_or_else(|| Error::Invalid(format!("unclosed joint list: {line}")))?;
            out.push(numbers(&rest[..end], "movej")?);
        }
        Ok(out)
    }
}
