use super::sample::{pose_layout, SampleProgram};
use super::*;
use crate::calib::pipeline::{calibrate, CalibOptions, CalibResult, Method, ModelSpec, Parametrisation};
use crate::compensate::{nominal_x, Target};
use crate::sim::generate::{generate, Silent};
use crate::sim::scenario::Scenario;
use rand::{Rng, SeedableRng};
use std::sync::OnceLock;

/// The IRB 120's tracker twin calibrated (geometry), and its robot.
fn fixture() -> &'static (CalibResult, crate::robot::Robot) {
    static F: OnceLock<(CalibResult, crate::robot::Robot)> = OnceLock::new();
    F.get_or_init(|| {
        let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/irb120_tracker.toml"));
        let s = Scenario::from_toml(&std::fs::read_to_string(path).unwrap(), "irb120_tracker").unwrap();
        let robot = s.load_robot(path.parent()).unwrap();
        let g = generate(&s, &robot, &Silent).unwrap();
        let r = calibrate(&g.dataset, None, &CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM)).unwrap();
        (r, robot)
    })
}

/// `n` targets of `lang` at seeded configurations inside the IRB 120's usual ranges (clear of
/// the quadrant and wrist boundaries), as the calibrated model puts the tool there, in `frame`.
fn sample(c: &Compensator, setup: &Setup, lang: Language, tool: Isometry3<f64>, frame: Isometry3<f64>, n: usize, seed: u64) -> SampleProgram {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let ranges = [(-80.0, 80.0), (-30.0, 60.0), (-60.0, 30.0), (-120.0, 120.0), (20.0, 100.0), (-150.0, 150.0)];
    let mut targets = Vec::new();
    // A walk, as a program's neighbouring targets: each joint steps up to 10° (kept in range).
    let mut walk: Vec<f64> = ranges.iter().map(|(a, b): &(f64, f64)| a + (b - a) * rng.random::<f64>()).collect();
    let mut home = None;
    while targets.len() < n {
        for (v, (a, b)) in walk.iter_mut().zip(&ranges) {
            *v = (*v + 10.0 * (2.0 * rng.random::<f64>() - 1.0)).clamp(*a, *b);
        }
        let q: Vec<f64> = walk.iter().map(|d| d.to_radians()).collect();
        if [0usize, 3, 5].iter().any(|&j| (q[j].to_degrees() / 90.0 - (q[j].to_degrees() / 90.0).round()).abs() < 0.05) {
            continue;
        }
        let (p, r) = c.predicted_pose(&q);
        let tcp = setup.program_pose(&p, &r) * tool;
        targets.push((frame.inverse() * tcp, setup.config(pose_layout(lang), &q)));
        home.get_or_insert(q);
    }
    SampleProgram { name: "twc_test".into(), tool, frame, targets, home: home.unwrap_or_default() }
}

fn frame() -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(300.0, -150.0, 120.0), UnitQuaternion::from_euler_angles(0.1, -0.05, 0.5))
}

fn compensator(r: &CalibResult, x_nom: &[f64], tol_mm: f64, tol_deg: f64) -> Compensator<'static> {
    // The test's result outlives the compensator (a leaked copy keeps the borrow simple).
    let r: &'static CalibResult = Box::leak(Box::new(r.clone()));
    let x: &'static [f64] = Box::leak(x_nom.to_vec().into_boxed_slice());
    Compensator::new(r, x, None, tol_mm, tol_deg).unwrap()
}

#[test]
fn programs_with_nothing_to_move_come_back_byte_identical() {
    let (r, robot) = fixture();
    let mut nominal = r.clone();
    nominal.x = nominal_x(r);
    let x_nom = nominal.x.clone();
    let c = compensator(&nominal, &x_nom, 0.001, 0.001);
    let setup = Setup::new(&nominal, &x_nom, Some(robot));
    for lang in Language::ALL {
        let tool = Isometry3::from_parts(Translation3::new(10.0, 5.0, 120.0), UnitQuaternion::from_euler_angles(0.0, 0.3, 0.0));
        let prog = sample(&c, &setup, lang, tool, frame(), 12, 1);
        let (files, frames) = prog.write(lang);
        let f = filter_program(&c, &setup, lang, &files, &frames, &FilterOptions { joint_targets: true, ..Default::default() }).unwrap();
        assert_eq!(f.files, files, "{lang:?}: {}", report_csv(&f));
        let nothing = f.targets.iter().filter(|t| t.outcome == Outcome::NothingToMove).count();
        assert_eq!(nothing, 13, "{lang:?}: 12 targets and the home, each nothing to move: {}", report_csv(&f));
        assert_eq!(f.run_time.len(), 1, "{lang:?}: the run-time motion listed: {:?}", f.run_time);
    }
}

#[test]
fn filtered_targets_equal_compensate_on_the_same_targets() {
    let (r, robot) = fixture();
    let x_nom = nominal_x(r);
    let c = compensator(r, &x_nom, 1e-7, 1e-9);
    let setup = Setup::new(r, &x_nom, Some(robot));
    for lang in Language::ALL {
        // The calibrated tool point as the program's tool, in the base frame: the targets are
        // those `compensate --targets` takes.
        let prog = sample(&c, &setup, lang, setup.probe_tool(), Isometry3::identity(), 20, 2);
        let (files, frames) = prog.write(lang);
        let f = filter_program(&c, &setup, lang, &files, &frames, &FilterOptions::default()).unwrap();
        let reread = read_program(&c, &setup, lang, &f.files, &frames, &FilterOptions::default()).unwrap();
        // The tool as the program writes it (rounded), for both.
        let tool = reader(lang)
            .parse(&files, &frames)
            .unwrap()
            .tools
            .values()
            .flatten()
            .copied()
            .find(|t| (t.translation.vector - setup.probe_tool().translation.vector).norm() < 0.01)
            .unwrap();
        let mut compared = 0;
        for (k, (t, after)) in f.targets.iter().zip(&reread).enumerate() {
            if t.outcome != Outcome::Filtered {
                continue;
            }
            let k_prog = t.compensated.as_ref().unwrap();
            // The written target as `compensate` reads it, and its compensation there.
            let (pose, _) = pose_of(pose_layout(lang), &parse_values(&files, &t.name, lang, k));
            let (p, rr) = setup.model_target(&(pose * tool.inverse()));
            let csv = c.compensate(&[Target::Pose(p, rr)]).remove(0);
            if csv.command_q.iter().zip(&k_prog.command_q).any(|(a, b)| (a - b).abs() > 1e-3) {
                // compensate's own nominal solve (no configuration data) chose another of the
                // arm's solutions: another branch, nothing else.
                let layout = Layout::RapidPose;
                assert_ne!(setup.config(layout, &csv.nominal_q), setup.config(layout, &k_prog.nominal_q), "{lang:?} {}", t.name);
                continue;
            }
            compared += 1;
            let (fp, _) = pose_of(pose_layout(lang), &parse_values(&f.files, &t.name, lang, k));
            let (mp, _) = setup.model_target(&(fp * tool.inverse()));
            let d = (mp - Vector3::from(csv.filtered_mm)).norm();
            assert!(
                d < 1e-6,
                "{lang:?} {}: {d} mm apart: {:?} vs {:?}; status {:?} {:?} res {} {} {:?} {:?} dq {:?}",
                t.name,
                mp.as_slice(),
                csv.filtered_mm,
                csv.status,
                k_prog.status,
                csv.residual_mm,
                k_prog.residual_mm,
                csv.pose.as_ref().map(|p| p.residual_deg),
                k_prog.pose.as_ref().map(|p| p.residual_deg),
                csv.command_q.iter().zip(&k_prog.command_q).map(|(a, b)| a - b).collect::<Vec<_>>()
            );
            // The controller reading the filtered target with its configuration data commands
            // the compensated joints.
            let q_read = after.as_ref().unwrap();
            assert!(q_read.iter().zip(&k_prog.command_q).all(|(a, b)| (a - b).abs() < 1e-6), "{lang:?} {}: {q_read:?} vs {:?}", t.name, k_prog.command_q);
        }
        assert!(compared >= 5, "{lang:?}: only {compared} of 20 compared: {}", report_csv(&f));
    }
}

/// The values of target `k` of the files as the reader reads them.
fn parse_values(files: &[ProgramFile], name: &str, lang: Language, k: usize) -> Vec<f64> {
    let frames = if lang == Language::Krl {
        SampleProgram { name: "x".into(), tool: Isometry3::identity(), frame: Isometry3::identity(), targets: vec![], home: vec![0.0; 6] }.write(lang).1
    } else {
        vec![]
    };
    let p = reader(lang).parse(files, &frames).unwrap();
    let s = &p.sites[k];
    assert_eq!(s.name, name);
    s.values()
}

#[test]
fn run_time_targets_taught_ones_and_joint_targets_are_left_and_listed() {
    let (r, robot) = fixture();
    let x_nom = nominal_x(r);
    let c = compensator(r, &x_nom, 0.001, 0.001);
    let setup = Setup::new(r, &x_nom, Some(robot));
    let prog = sample(&c, &setup, Language::Rapid, setup.probe_tool(), frame(), 4, 3);
    let (files, _) = prog.write(Language::Rapid);
    // twc_t2 is computed in code; twc_t3 is taught.
    let text = files[0].text.replace("    PROC main()\r\n", "    PROC main()\r\n        twc_t2 := RelTool(twc_t1, 0, 0, 5);\r\n");
    let files = vec![ProgramFile { name: files[0].name.clone(), text }];
    let f = filter_program(&c, &setup, Language::Rapid, &files, &[], &FilterOptions { leave: vec!["TWC_T3".into()], ..Default::default() }).unwrap();
    let outcome = |n: &str| f.targets.iter().find(|t| t.name == n).unwrap().outcome.clone();
    assert_eq!(outcome("twc_home"), Outcome::Left(Left::JointTarget));
    assert!(matches!(outcome("twc_t2"), Outcome::Left(Left::RunTime(_))), "{:?}", outcome("twc_t2"));
    assert_eq!(outcome("twc_t3"), Outcome::Left(Left::Taught));
    assert_eq!(outcome("twc_t1"), Outcome::Filtered);
    assert_eq!(f.run_time.len(), 1);
    assert!(f.run_time[0].target.starts_with("Offs(") && f.run_time[0].reason.contains("run time"), "{:?}", f.run_time);
    // Every line but twc_t1's and twc_t4's declarations is the program's own.
    let (a, b) = (&files[0].text, &f.files[0].text);
    let changed: Vec<&str> = a.split('\n').zip(b.split('\n')).filter(|(x, y)| x != y).map(|(x, _)| x).collect();
    assert_eq!(changed.len(), 2, "{changed:?}");
    assert!(changed.iter().all(|l| l.contains("twc_t1 :=") || l.contains("twc_t4 :=")), "{changed:?}");
    assert!(b.ends_with("ENDMODULE\r\n") && b.matches("\r\n").count() == a.matches("\r\n").count());
}

#[test]
fn malformed_programs_are_refused_by_line_and_column() {
    let (r, robot) = fixture();
    let x_nom = nominal_x(r);
    let c = compensator(r, &x_nom, 0.001, 0.001);
    let setup = Setup::new(r, &x_nom, Some(robot));
    let cases: [(Language, &str, &str, &str); 8] = [
        (
            Language::Rapid,
            "a.mod",
            "MODULE a\n  CONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9]];\nENDMODULE\n",
            "a.mod:2:24: a robtarget",
        ),
        (Language::Rapid, "a.mod", "MODULE a\n  CONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9];\nENDMODULE\n", "a.mod:2:"),
        (
            Language::Rapid,
            "a.mod",
            "MODULE a\n  CONST robtarget p := [[1,2.5.1,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n",
            "a.mod:2:28: '2.5.1' is not a number",
        ),
        (Language::Rapid, "a.mod", "MODULE a\n  CONST robtarget p := [[1,2,3],[0.5,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n", "not a unit quaternion"),
        (Language::Krl, "a.dat", "DEFDAT A\n  DECL E6POS XP1={X 1.0,Y 2.0,Z 3.0,A 0,B 0,C 0,S 2,T oops}\nENDDAT\n", "a.dat:2:"),
        (
            Language::Urscript,
            "a.script",
            "def a():\n  movel(p[0.1, 0.2, 0.3, 0, 0], a=1.2)\nend\n",
            "a.script:2:9: a pose p[x, y, z, rx, ry, rz] holds six numbers, found 5",
        ),
        (Language::Urscript, "a.script", "def a():\n  movel(p[0.1, 0.2, 0.3, 0, 0, 0, a=1.2)\nend\n", "a.script:2:"),
        (Language::Krl, "a.dat", "DEFDAT A\n  DECL E6POS XP1={X 1e999,Y 2.0,Z 3.0,A 0,B 0,C 0,S 2,T 0}\nENDDAT\n", "a.dat:2:21: '1e999' is beyond"),
    ];
    for (lang, name, text, want) in cases {
        let files = [ProgramFile { name: name.into(), text: text.into() }];
        let e = filter_program(&c, &setup, lang, &files, &[], &FilterOptions::default()).unwrap_err().to_string();
        assert!(e.contains(want), "{name}: '{e}' does not contain '{want}'");
    }
}

#[test]
fn line_and_column_by_index_agree_with_the_scan() {
    let t = "ab\nçd\r\n\nxyz";
    let lines = text::Lines::new(t);
    for at in 0..=t.len() {
        assert_eq!(lines.at(at), text::line_col(t, at), "byte {at}");
    }
}

/// Modules as the controllers' own tools save them: a RAPID module with the `%%%` header keeps
/// its first declaration (the tool); one written offline with `[0,0,0,0]` everywhere and run
/// under `ConfJ\Off` / `ConfL\Off` is filtered, the configuration data left as written; a
/// KRL data list with every field of its FDAT and PDAT lines, `FDAT_ACT` and `BAS(#PTP_PARAMS)`
/// selecting the frames and a `$config.dat` with loads and `XHOME` reads as the plain one; S and
/// T in a LIN are the arm's branch, not the target's; why a target is left is said.
#[test]
fn modules_in_the_forms_controllers_save_them() {
    let (r, robot) = fixture();
    let x_nom = nominal_x(r);
    let c = compensator(r, &x_nom, 0.001, 0.001);
    assert!(c.closed_form(), "the IRB 120's nominal controller is read in closed form");
    let setup = Setup::new(r, &x_nom, Some(robot));
    let prog = sample(&c, &setup, Language::Rapid, setup.probe_tool(), frame(), 6, 5);
    let (files, _) = prog.write(Language::Rapid);
    let plain = filter_program(&c, &setup, Language::Rapid, &files, &[], &FilterOptions::default()).unwrap();
    let header = format!("%%%\r\n  VERSION:1\r\n  LANGUAGE:ENGLISH\r\n%%%\r\n\r\n{}", files[0].text);
    let saved = vec![ProgramFile { name: files[0].name.clone(), text: header.clone() }];
    let f = filter_program(&c, &setup, Language::Rapid, &saved, &[], &FilterOptions::default()).unwrap();
    let outcomes = |f: &Filtered| f.targets.iter().map(|t| (t.name.clone(), t.outcome.name())).collect::<Vec<_>>();
    assert_eq!(outcomes(&f), outcomes(&plain), "{}", report_csv(&f));
    assert!(f.targets.iter().filter(|t| t.outcome == Outcome::Filtered).count() >= 5, "{}", report_csv(&f));
    assert!(f.files[0].text.starts_with("%%%\r\n  VERSION:1\r\n"));

    // Offline: every configuration [0,0,0,0], run with the monitoring off.
    let mut text = files[0].text.clone();
    for t in &prog.targets {
        let cfg: Vec<String> = t.1.iter().map(|v| v.to_string()).collect();
        text = text.replacen(&format!("[{}],[9E+09", cfg.join(",")), "[0,0,0,0],[9E+09", 1);
    }
    let off = text.replace("    PROC main()\r\n", "    PROC main()\r\n        ConfJ \\Off;\r\n        ConfL\\Off;\r\n");
    let on = filter_program(&c, &setup, Language::Rapid, &[ProgramFile { name: "m.mod".into(), text }], &[], &FilterOptions::default()).unwrap();
    let with_off = filter_program(&c, &setup, Language::Rapid, &[ProgramFile { name: "m.mod".into(), text: off }], &[], &FilterOptions::default()).unwrap();
    let count = |f: &Filtered, o: &str| f.targets.iter().filter(|t| t.outcome.name() == o).count();
    assert!(count(&on, "no_nominal_solution") > 0, "the monitoring on holds the arm to [0,0,0,0]: {}", report_csv(&on));
    assert!(count(&with_off, "no_nominal_solution") == 0 && count(&with_off, "filtered") >= 5, "{}", report_csv(&with_off));
    assert!(with_off.targets.iter().filter(|t| t.kind == "pose").all(|t| t.config_after == t.config_before), "{}", report_csv(&with_off));
    let csv = report_csv(&on);
    assert!(csv.lines().next().unwrap().contains(",outcome,reason,") && csv.contains("no solution with its configuration data"), "{csv}");
    // Which quadrant disagrees: the data the nominal arm reaches the target with instead.
    let t1 = on.targets.iter().find(|t| t.name == "twc_t1").unwrap();
    let cfg: Vec<String> = prog.targets[0].1.iter().zip(["cf1", "cf4", "cf6", "cfx"]).map(|(v, n)| format!("{n} {v}")).collect();
    let why = t1.outcome.reason();
    assert!(why.contains("it reaches the target with ") && why.contains(&cfg.join(", ")), "{why}");

    // KRL as KSS writes it.
    let prog = sample(&c, &setup, Language::Krl, setup.probe_tool(), frame(), 6, 6);
    let (files, frames) = prog.write(Language::Krl);
    let plain = filter_program(&c, &setup, Language::Krl, &files, &frames, &FilterOptions::default()).unwrap();
    let src = files[0].text.replace("  BAS(#TOOL,1)\n  BAS(#BASE,2)\n", "  FDAT_ACT=FP1\n  PDAT_ACT=PPDAT1\n  BAS(#PTP_PARAMS,100)\n");
    let dat = files[1].text.replace(
        "ENDDAT",
        "  DECL FDAT FP1={TOOL_NO 1,BASE_NO 2,IPO_FRAME #BASE,POINT2[] \" \",TQ_STATE FALSE}\n  DECL PDAT PPDAT1={VEL 100.000,ACC 100.000,APO_DIST 100.000,APO_MODE #CDIS,GEAR_JERK 100.000,EXAX_IGN 0}\n  DECL LDAT LCPDAT1={VEL 2.0,ACC 100.0,APO_DIST 100.0,APO_FAC 50.0,AXIS_VEL 100.0,AXIS_ACC 100.0,ORI_TYP #VAR,CIRC_TYP #BASE,JERK_FAC 50.0,GEAR_JERK 100.0,EXAX_IGN 0,CB {AUX_PT {ORI #CONSIDER,E1 #INTERPOLATE,E2 #INTERPOLATE,E3 #IGNORE,E4 #IGNORE,E5 #IGNORE,E6 #IGNORE},TARGET_PT {ORI #INTERPOLATE,E1 #INTERPOLATE,E2 #INTERPOLATE,E3 #INTERPOLATE,E4 #INTERPOLATE,E5 #INTERPOLATE,E6 #INTERPOLATE}}}\nENDDAT",
    );
    let config = frames[0].text.replace(
        "ENDDAT",
        "  DECL E6AXIS XHOME={A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 0.0,A6 0.0,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}\n  LOAD_DATA[1]={M -1.0,CM {X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}\nENDDAT",
    );
    let kss = [
        ProgramFile { name: files[0].name.clone(), text: src.replace("  PTP XTWC_T1", "  PTP XHOME\n  PTP XTWC_T1") },
        ProgramFile { name: files[1].name.clone(), text: dat },
    ];
    let f = filter_program(&c, &setup, Language::Krl, &kss, &[ProgramFile { name: "$config.dat".into(), text: config }], &FilterOptions::default()).unwrap();
    assert_eq!(outcomes(&f), outcomes(&plain), "{}", report_csv(&f));
    assert!(f.run_time.iter().any(|n| n.target == "XHOME" && n.reason.contains("$config.dat")), "{:?}", f.run_time);
    // IPO_FRAME #TCP: the tool stands in the cell; the targets moved with it are left, and why.
    let ext = [kss[0].clone(), ProgramFile { name: kss[1].name.clone(), text: kss[1].text.replace("IPO_FRAME #BASE", "IPO_FRAME #TCP") }];
    let f = filter_program(&c, &setup, Language::Krl, &ext, &frames, &FilterOptions::default()).unwrap();
    assert!(
        f.targets.iter().filter(|t| t.kind == "pose").all(|t| t.outcome.name() == "left_frames" && t.outcome.reason().contains("surroundings")),
        "{}",
        report_csv(&f)
    );
    // S and T in a LIN: the controller keeps the arm's branch, and so does the filter.
    let lin = [ProgramFile { name: files[0].name.clone(), text: files[0].text.replace("  PTP XTWC_T", "  LIN XTWC_T") }, files[1].clone()];
    let f = filter_program(&c, &setup, Language::Krl, &lin, &frames, &FilterOptions::default()).unwrap();
    assert!(f.targets.iter().filter(|t| t.kind == "pose").all(|t| t.config_after == t.config_before), "{}", report_csv(&f));
    assert!(f.targets.iter().filter(|t| t.outcome == Outcome::Filtered).count() >= 5, "{}", report_csv(&f));
}

mod readers_property {
    //! The three readers on programs assembled from the pieces controllers and their tools
    //! write (headers, data lists with every field, configuration switches, comments, mixed
    //! case, CRLF, Latin-1 characters), cut and spliced: each answers (read, or an error naming
    //! a line), never panics; what it reads it writes back byte for byte when nothing moves.
    use super::super::*;
    use proptest::prelude::*;

    const RAPID: [&str; 14] = [
        "%%%\r\n  VERSION:1\r\n  LANGUAGE:ENGLISH\r\n%%%\r\n",
        "MODULE m\r\n",
        "  PERS tooldata tg := [TRUE,[[10,0,120],[1,0,0,0]],[1.5,[0,0,40],[1,0,0,0],0,0,0]];\r\n",
        "  TASK PERS wobjdata wo := [FALSE,TRUE,\"\",[[300,0,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\r\n",
        "  CONST robtarget p1 := [[400,50,300],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];\r\n",
        "  const ROBTARGET P2:=[[410,-20,280],[0.7071068,0,0.7071068,0],[-1,0,-1,1],[9E9,9E9,9E9,9E9,9E9,9E9]];\r\n",
        "  PROC main()\r\n",
        "    ConfJ \\Off;\r\n",
        "    confl\\on;\r\n",
        "    MoveJ p1, v200, fine, tg\\WObj:=wo; ! a comment ; with a semicolon\r\n",
        "    MOVEL P2, v100, z10, tg;\r\n",
        "    MoveL Offs(p1,0,0,10), v100, z10, tg\\WObj:=wo;\r\n",
        "  ENDPROC\r\n",
        "ENDMODULE\r\n",
    ];
    const KRL: [&str; 12] = [
        "&ACCESS RVP\n&REL 1\n",
        "DEFDAT prog PUBLIC\n",
        "  DECL E6POS XP1={X 400.0,Y 50.0,Z 300.0,A 0.0,B 90.0,C 0.0,S 2,T 35,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}\n",
        "  DECL FDAT FP1={TOOL_NO 1,BASE_NO 2,IPO_FRAME #BASE,POINT2[] \" \",TQ_STATE FALSE}\n",
        "  DECL PDAT PPDAT1={VEL 100.000,ACC 100.000,APO_DIST 100.000,APO_MODE #CDIS,GEAR_JERK 100.000,EXAX_IGN 0}\n",
        "  decl e6axis xhome={a1 0.0,a2 -90.0,a3 90.0,a4 0.0,a5 0.0,a6 0.0}\n",
        "ENDDAT\n",
        "DEF prog( )\n",
        "  FDAT_ACT=FP1\n  BAS(#PTP_PARAMS,100)\n",
        "  PTP XP1 C_PTP ; to the first point\n",
        "  LIN {X 410,Y -20,Z 280,A 0,B 90,C 0} C_DIS\n",
        "END\n",
    ];
    const UR: [&str; 6] = [
        "def prog():\n",
        "  set_tcp(p[0.0, 0.0, 0.12, 0.0, 0.0, 0.0])\n",
        "  p1 = p[0.4, 0.05, 0.3, 0.0, 3.1416, 0.0]\n",
        "  movel(p1, a=1.2, v=0.25)  # a comment\n",
        "  movej([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], a=1.4, v=1.05)\n",
        "end\n",
    ];
    /// Latin-1 characters as controllers' files carry them (the file read as ISO-8859-1).
    const LATIN: [&str; 3] = ["° ", "é", "µ"];

    fn program(pieces: &'static [&'static str]) -> impl Strategy<Value = String> {
        let piece = prop_oneof![
            8 => proptest::sample::select(pieces.to_vec()).prop_map(str::to_string),
            1 => proptest::sample::select(LATIN.to_vec()).prop_map(str::to_string),
            1 => "[ -~]{0,12}".prop_map(|s| s),
        ];
        (proptest::collection::vec(piece, 0..18), any::<bool>(), any::<proptest::sample::Index>()).prop_map(|(parts, upper, cut)| {
            let text = parts.concat();
            let text = if upper { text.to_uppercase() } else { text };
            // Cut at a character boundary: a file truncated anywhere.
            let at = cut.index(text.len() + 1);
            let at = (0..=at).rev().find(|i| text.is_char_boundary(*i)).unwrap_or(0);
            text[..at].to_string()
        })
    }

    fn answers(lang: Language, name: &str, text: String) {
        let files = vec![ProgramFile { name: name.into(), text }];
        let _ = parse(lang, &files, &[]);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 128, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn the_rapid_reader_answers_any_module(text in program(&RAPID)) {
            answers(Language::Rapid, "m.mod", text);
        }

        #[test]
        fn the_krl_reader_answers_any_data_list_and_program(text in program(&KRL)) {
            answers(Language::Krl, "prog.src", text.clone());
            answers(Language::Krl, "prog.dat", text);
        }

        #[test]
        fn the_urscript_reader_answers_any_script(text in program(&UR)) {
            answers(Language::Urscript, "prog.script", text);
        }
    }

    /// The saved forms read whole: each language's full program parses.
    #[test]
    fn the_saved_forms_parse_whole() {
        for (lang, name, pieces) in [(Language::Rapid, "m.mod", &RAPID[..]), (Language::Urscript, "p.script", &UR[..])] {
            let files = vec![ProgramFile { name: name.into(), text: pieces.concat() }];
            let p = parse(lang, &files, &[]).unwrap_or_else(|e| panic!("{lang:?}: {e}"));
            assert!(!p.sites.is_empty(), "{lang:?}");
        }
        let src = KRL[7..].concat();
        let dat = KRL[..7].concat();
        let files = vec![ProgramFile { name: "prog.src".into(), text: src }, ProgramFile { name: "prog.dat".into(), text: dat }];
        let p = parse(Language::Krl, &files, &[]).unwrap();
        assert_eq!(p.sites.len(), 3, "XP1, XHOME and the inline LIN target");
        let xp1 = p.sites.iter().find(|s| s.name == "XP1").unwrap();
        assert_eq!((xp1.uses.len(), xp1.config_ignored), (1, 0), "a PTP reads S and T");
        let inline = p.sites.iter().find(|s| s.name == "inline").unwrap();
        assert_eq!(inline.uses[0].0, "TOOL_DATA[1]", "FDAT_ACT's tool");
    }
}
