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
