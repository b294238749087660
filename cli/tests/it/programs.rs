//! `twincal compensate --program`, end to end: a RAPID module, a KRL program with its data list
//! and `$config.dat`, a URScript filtered in place; only the targets' numbers change; a program
//! with nothing to move comes back byte-identical; bad programs and bad requests refused with
//! exit code 2 and nothing written.

use std::path::Path;
use std::process::{Command, Output};
use twincal::calib::pipeline::CalibResult;
use twincal::compensate::{nominal_x, Compensator};
use twincal::controller::filter::{sample::SampleProgram, Layout, Setup};
use twincal::controller::Language;

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).output().expect("runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The embedded scenario's data calibrated, in `dir`.
fn calibrated(dir: &Path) -> std::path::PathBuf {
    let data = dir.join("d");
    assert!(twincal(&["--quiet", "generate", "--out", s(&data)]).status.success());
    let result = dir.join("r.json");
    let o = twincal(&["--quiet", "calibrate", "--data", s(&data), "--out", s(&result)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    result
}

/// A program of 8 targets in `lang` written the way an offline system writes it, for the
/// calibration at `result`.
fn program(result: &Path, lang: Language) -> (Vec<twincal::controller::ProgramFile>, Vec<twincal::controller::ProgramFile>) {
    let r = CalibResult::load(result).unwrap();
    let x_nom = nominal_x(&r);
    let c = Compensator::new(&r, &x_nom, None, 0.001, 0.001).unwrap();
    let robot = twincal::robot::Robot::irb120();
    let setup = Setup::new(&r, &x_nom, Some(&robot));
    let tool = nalgebra::Isometry3::from_parts(nalgebra::Translation3::new(0.0, 0.0, 150.0), nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.4, 0.0));
    let frame = nalgebra::Isometry3::translation(300.0, -100.0, 50.0);
    let layout = match lang {
        Language::Rapid => Layout::RapidPose,
        Language::Krl => Layout::KrlPose { config: true },
        Language::Urscript => Layout::UrPose,
    };
    let qs: [[f64; 6]; 8] = [
        [10.0, 20.0, -10.0, 30.0, 40.0, 50.0],
        [-20.0, 10.0, 5.0, -40.0, 60.0, 10.0],
        [35.0, 30.0, -20.0, 60.0, 30.0, -40.0],
        [5.0, -10.0, 20.0, 10.0, 70.0, 120.0],
        [-45.0, 25.0, -30.0, -20.0, 45.0, -100.0],
        [60.0, 15.0, 0.0, 45.0, 55.0, 30.0],
        [-10.0, 35.0, -35.0, -70.0, 35.0, 75.0],
        [25.0, 0.0, 10.0, 20.0, 80.0, -20.0],
    ];
    let targets = qs
        .iter()
        .map(|d| {
            let q: Vec<f64> = d.iter().map(|v| v.to_radians()).collect();
            let (p, rot) = c.predicted_pose(&q);
            (frame.inverse() * setup.program_pose(&p, &rot) * tool, setup.config(layout, &q))
        })
        .collect();
    SampleProgram { name: "weld".into(), tool, frame, targets, home: vec![0.0, 0.0, 0.0, 0.0, 30f64.to_radians(), 0.0] }.write(lang)
}

fn write(dir: &Path, files: &[twincal::controller::ProgramFile]) -> Vec<std::path::PathBuf> {
    files
        .iter()
        .map(|f| {
            let p = dir.join(&f.name);
            std::fs::write(&p, &f.text).unwrap();
            p
        })
        .collect()
}

#[test]
fn programs_are_filtered_in_place_in_each_language() {
    let dir = tempfile::tempdir().unwrap();
    let result = calibrated(dir.path());
    for lang in Language::ALL {
        let src = dir.path().join(format!("src_{}", lang.name()));
        std::fs::create_dir_all(&src).unwrap();
        let (files, frames) = program(&result, lang);
        let paths = write(&src, &files);
        let frame_paths = write(&src, &frames);
        let out = dir.path().join(format!("out_{}", lang.name()));
        let report = dir.path().join(format!("report_{}.csv", lang.name()));
        let mut args = vec!["compensate", "--model", s(&result), "--robot", "irb120", "--filtered-dir", s(&out), "--report", s(&report)];
        for p in &paths {
            args.extend(["--program", s(p)]);
        }
        for p in &frame_paths {
            args.extend(["--frames", s(p)]);
        }
        let o = twincal(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{lang:?}: {err}");
        assert!(err.contains("left as written:") && err.contains("run time"), "{lang:?}: the run-time motion named: {err}");
        let text = std::fs::read_to_string(&report).unwrap();
        let filtered = text.lines().filter(|l| l.contains(",filtered,")).count();
        assert_eq!(filtered, 8, "{lang:?}: every target filtered: {text}");
        // Only the targets' lines differ; the rest of each file is the program's bytes.
        for f in &files {
            let after = std::fs::read_to_string(out.join(&f.name)).unwrap();
            let changed: Vec<(&str, &str)> = f.text.split('\n').zip(after.split('\n')).filter(|(a, b)| a != b).collect();
            assert_eq!(f.text.split('\n').count(), after.split('\n').count(), "{lang:?} {}", f.name);
            let target_lines =
                f.text.split('\n').filter(|l| l.contains("twc_t") && l.contains(":=") || l.contains("DECL E6POS") || l.contains("movel(p[")).count();
            assert!(changed.len() <= target_lines && changed.len() >= if f.name.ends_with(".src") { 0 } else { 8 }, "{lang:?} {}: {changed:?}", f.name);
        }
        // The same program saved in ISO-8859-1 with a degree sign in its first line: filtered
        // to the same numbers, written back in its encoding.
        let latin_dir = dir.path().join(format!("latin_{}", lang.name()));
        std::fs::create_dir_all(&latin_dir).unwrap();
        let mark = |t: &str| t.replacen('\n', " \u{b0}\n", 1);
        let latin1 = |t: &str| t.chars().map(|c| c as u8).collect::<Vec<u8>>();
        let latin_paths: Vec<_> = files.iter().map(|f| latin_dir.join(&f.name)).collect();
        for (f, p) in files.iter().zip(&latin_paths) {
            std::fs::write(p, latin1(&mark(&f.text))).unwrap();
        }
        let out_l = dir.path().join(format!("out_latin_{}", lang.name()));
        let report_l = dir.path().join(format!("report_latin_{}.csv", lang.name()));
        let mut args = vec!["--quiet", "compensate", "--model", s(&result), "--robot", "irb120", "--filtered-dir", s(&out_l), "--report", s(&report_l)];
        for p in &latin_paths {
            args.extend(["--program", s(p)]);
        }
        for p in &frame_paths {
            args.extend(["--frames", s(p)]);
        }
        let o = twincal(&args);
        assert!(o.status.success() && String::from_utf8_lossy(&o.stderr).contains("ISO-8859-1"), "{lang:?}: {}", String::from_utf8_lossy(&o.stderr));
        for f in &files {
            let utf8 = std::fs::read_to_string(out.join(&f.name)).unwrap();
            assert_eq!(std::fs::read(out_l.join(&f.name)).unwrap(), latin1(&mark(&utf8)), "{lang:?} {}", f.name);
        }
    }
}

#[test]
fn a_program_with_nothing_to_move_comes_back_byte_identical_and_bad_programs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let result = calibrated(dir.path());
    // Joint moves and run-time targets only: nothing the filter moves.
    let module = "MODULE cell\r\n  ! taught on the pendant\r\n  CONST jointtarget home := [[0,0,0,0,30,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\r\n  PROC main()\r\n    MoveAbsJ home, v200, fine, tool0;\r\n    MoveL Offs(CRobT(), 0, 0, 10), v100, z10, tool0;\r\n  ENDPROC\r\nENDMODULE\r\n";
    let path = dir.path().join("cell.mod");
    std::fs::write(&path, module).unwrap();
    let out = dir.path().join("f");
    let o = twincal(&[
        "--quiet",
        "compensate",
        "--model",
        s(&result),
        "--program",
        s(&path),
        "--robot",
        "irb120",
        "--filtered-dir",
        s(&out),
        "--report",
        s(&dir.path().join("r.csv")),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(out.join("cell.mod")).unwrap(), module.as_bytes());
    // A module with no motion at all: written as it is, and said (even with --quiet).
    let empty = dir.path().join("empty.mod");
    std::fs::write(&empty, "MODULE empty\n  PROC main()\n  ENDPROC\nENDMODULE\n").unwrap();
    let (out2, r2) = (dir.path().join("f2"), dir.path().join("r2.csv"));
    let o = twincal(&["--quiet", "compensate", "--model", s(&result), "--program", s(&empty), "--filtered-dir", s(&out2), "--report", s(&r2)]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stderr).contains("holds no motion target"), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(out2.join("empty.mod")).unwrap(), std::fs::read(&empty).unwrap());
    // An older controller's module saved in ISO-8859-1 (a degree sign in a comment): read and
    // written back byte for byte in its encoding, and said.
    let latin = dir.path().join("latin.mod");
    let latin_bytes = module.replace("taught on the pendant", "taught at 20 \u{b0}C").chars().map(|c| c as u8).collect::<Vec<u8>>();
    assert!(String::from_utf8(latin_bytes.clone()).is_err());
    std::fs::write(&latin, &latin_bytes).unwrap();
    let (out3, r3) = (dir.path().join("f3"), dir.path().join("r3.csv"));
    let o =
        twincal(&["--quiet", "compensate", "--model", s(&result), "--program", s(&latin), "--robot", "irb120", "--filtered-dir", s(&out3), "--report", s(&r3)]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stderr).contains("ISO-8859-1"), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(out3.join("latin.mod")).unwrap(), latin_bytes);
    // Bad programs and requests: exit code 2, a message naming the problem, nothing written.
    let bad = dir.path().join("bad.mod");
    std::fs::write(&bad, "MODULE bad\n  CONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,0,0]];\nENDMODULE\n").unwrap();
    let txt = dir.path().join("prog.txt");
    std::fs::write(&txt, "MoveL p, v100, z10, tool0;").unwrap();
    let binary = dir.path().join("backup.mod");
    std::fs::write(&binary, b"MODULE\x00\x01\x02 binary").unwrap();
    let never = dir.path().join("never");
    for (args, needle) in [
        (vec!["--program", s(&bad)], "bad.mod:2:24: a robtarget is"),
        (vec!["--program", s(&txt)], "is not a program file"),
        (vec!["--program", s(&binary)], "not a program's text: control byte 0x00 at byte 6"),
        (vec!["--program", s(&path), "--targets", s(&path)], "cannot be used with"),
        (vec!["--program", s(&path), "--filtered-dir", s(dir.path())], "is also an input"),
        (vec!["--program", s(&dir.path().join("nowhere.mod"))], "nowhere.mod"),
        (vec!["--program", s(&path), "--start-joints-deg", "1,2"], "--start-joints-deg"),
    ] {
        let mut full = vec!["--quiet", "compensate", "--model", s(&result), "--report", s(&never)];
        if !args.contains(&"--filtered-dir") {
            full.extend(["--filtered-dir", s(&never)]);
        }
        full.extend(args.iter().copied());
        let o = twincal(&full);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: '{err}' lacks '{needle}'");
        assert!(!never.exists(), "{args:?}: wrote {}", never.display());
    }
    assert_eq!(std::fs::read(&path).unwrap(), module.as_bytes(), "the program is never written over");
}
