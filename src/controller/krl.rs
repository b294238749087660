//! KUKA KRL: the tour as a program (`.src`) moving by `PTP` to the `E6AXIS` targets of its data
//! list (`.dat`), the handshake on the data list's global variables.

use super::{deg, header, number, Dialect, ProgramFile, Tour};
use crate::error::{Error, Result};
use std::fmt::Write;

/// KRL.
pub(super) struct Krl;

impl Dialect for Krl {
    fn joints(&self) -> std::ops::RangeInclusive<usize> {
        6..=7
    }
    fn measurement_program(&self, tour: &Tour) -> Vec<ProgramFile> {
        let name = tour.name.to_ascii_uppercase();
        let handshake = "Handshake: TWC_READY is TRUE while the arm holds still at pose TWC_POSE; set TWC_MEASURED=TRUE (variable access) once it is measured.";
        let mut src = String::from("&ACCESS RVP\n&REL 1\n");
        let _ = writeln!(src, "DEF {name}( )");
        for line in header(tour, "degrees", handshake) {
            let _ = writeln!(src, "  ; {line}");
        }
        let _ = writeln!(src, "  BAS (#INITMOV, 0)");
        let _ = writeln!(src, "  BAS (#VEL_PTP, {})", (100.0 * tour.speed_fraction).round().max(1.0));
        let _ = writeln!(src, "  TWC_READY=FALSE");
        for i in 0..tour.q.len() {
            if let Some(m) = tour.payload_change(i) {
                let _ = writeln!(src, "  ; twincal: mount the {m} kg payload, set its load data, start again");
                let _ = writeln!(src, "  HALT");
            }
            let _ = writeln!(src, "  PTP TWC_P{}", i + 1);
            let _ = writeln!(src, "  TWC_MEASURE({})", i + 1);
        }
        let _ = writeln!(src, "END\n");
        let _ = writeln!(src, "DEF TWC_MEASURE(POSE:IN)");
        let _ = writeln!(src, "  INT POSE");
        let _ = writeln!(src, "  WAIT SEC {}", tour.hold_s);
        let _ = writeln!(src, "  TWC_POSE=POSE");
        let _ = writeln!(src, "  TWC_MEASURED=FALSE");
        let _ = writeln!(src, "  TWC_READY=TRUE");
        let _ = writeln!(src, "  WAIT FOR TWC_MEASURED");
        let _ = writeln!(src, "  TWC_READY=FALSE");
        let _ = writeln!(src, "END");
        let mut dat = String::from("&ACCESS RVP\n&REL 1\n");
        let _ = writeln!(dat, "DEFDAT {name} PUBLIC");
        let _ = writeln!(dat, "  DECL GLOBAL BOOL TWC_READY=FALSE");
        let _ = writeln!(dat, "  DECL GLOBAL BOOL TWC_MEASURED=FALSE");
        let _ = writeln!(dat, "  DECL GLOBAL INT TWC_POSE=0");
        let _ = writeln!(dat, "  DECL INT TWC_JOINTS={}", tour.q[0].len());
        for (i, q) in tour.q.iter().enumerate() {
            let axes: Vec<String> = (0..6).map(|j| format!("A{} {}", j + 1, q.get(j).map_or("0.0".into(), |v| deg(*v)))).collect();
            let ext: Vec<String> = (0..6).map(|j| format!("E{} {}", j + 1, q.get(6 + j).map_or("0.0".into(), |v| deg(*v)))).collect();
            let _ = writeln!(dat, "  DECL E6AXIS TWC_P{}={{{},{}}}", i + 1, axes.join(","), ext.join(","));
        }
        let _ = writeln!(dat, "ENDDAT");
        vec![ProgramFile { name: format!("{}.src", tour.name), text: src }, ProgramFile { name: format!("{}.dat", tour.name), text: dat }]
    }

    fn joint_targets(&self, files: &[ProgramFile]) -> Result<Vec<Vec<f64>>> {
        let find =
            |ext: &str| files.iter().find(|f| f.name.ends_with(ext)).map(|f| f.text.as_str()).ok_or_else(|| Error::Invalid(format!("no KRL {ext} file")));
        let (src, dat) = (find(".src")?, find(".dat")?);
        let joints: usize = dat
            .lines()
            .find_map(|l| l.trim().strip_prefix("DECL INT TWC_JOINTS="))
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| Error::Invalid("the data list declares no TWC_JOINTS".into()))?;
        let mut out = Vec::new();
        for line in src.lines() {
            let Some(name) = line.trim().strip_prefix("PTP ") else { continue };
            let decl = format!("DECL E6AXIS {}={{", name.trim());
            let at = dat.find(&decl).ok_or_else(|| Error::Invalid(format!("PTP {name}: no E6AXIS declared")))?;
            let body = &dat[at + decl.len()..];
            let body = &body[..body.find('}').ok_or_else(|| Error::Invalid(format!("{name}: unclosed E6AXIS")))?];
            // "A1 0.5,A2 -90.0,...,E6 0.0": each item its axis, then its value.
            let values: Vec<f64> = body.split(',').map(|item| number(item.split_whitespace().nth(1).unwrap_or(""), name)).collect::<Result<_>>()?;
            out.push(values.into_iter().take(joints).map(f64::to_radians).collect());
        }
        Ok(out)
    }
}
