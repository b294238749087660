//! The plan on the IRB 120 tracker scenario with a cell: every pose feasible, better indices
//! than random sets, a shorter tour than the design's order; and on the twin, planned poses
//! calibrate to a smaller true error than random ones.

use super::verify::{study, StudyOptions};
use super::*;

const CELL: &str = "\n[workspace]\nlink_radius_mm = 45.0\nfloor_z_mm = 0.0\nkeep_out = [{ name = \"fixture\", min_mm = [250.0, -400.0, 0.0], max_mm = [450.0, -200.0, 300.0] }]\n";

fn scenario() -> (Scenario, Robot) {
    let text = format!("{}{CELL}", include_str!("../../scenarios/irb120_tracker.toml"));
    let s = Scenario::from_toml(&text, "irb120_tracker + cell").unwrap();
    s.validate(&Robot::irb120(), "test").unwrap();
    (s, Robot::irb120())
}

#[test]
fn a_plan_keeps_every_pose_feasible_and_beats_random_sets_of_its_size() {
    let (s, robot) = scenario();
    let p = plan(&s, &robot, &PlanOptions { n: 20, candidates: 2000, ..PlanOptions::default() }).unwrap();
    assert_eq!(p.poses.len(), 20);
    let cell = s.cell(&robot);
    let mut fk = cell.work();
    let ranges = s.ranges_rad(&robot);
    for q in &p.poses {
        assert_eq!(cell.check(q, &mut fk), Ok(()), "planned pose {q:?} refused");
        assert!(q.iter().zip(&ranges).all(|(v, (lo, hi))| *v >= lo - 1e-9 && *v <= hi + 1e-9), "{q:?} outside the ranges");
    }
    // The cell refused poses for its box and its floor, and the pool kept none of them.
    assert!(p.candidates.refused.contains_key(crate::sim::workspace::Refusal::KeepOut.name()), "{:?}", p.candidates.refused);
    assert!(p.indices.i_prediction_variance < 0.8 * p.random_median.i_prediction_variance, "{:?} vs {:?}", p.indices, p.random_median);
    assert!(p.indices.o1_d > p.random_median.o1_d);
    assert!(p.tour.total_s <= p.unordered.total_s + 1e-9);
    // Every criterion plans; each wins on its own index against the random sets.
    for c in CRITERIA {
        let q = plan(&s, &robot, &PlanOptions { n: 20, candidates: 2000, criterion: c.name().into(), ..PlanOptions::default() }).unwrap();
        let (a, b) = (&q.indices, &q.random_median);
        let better = match c.name() {
            "i" => a.i_prediction_variance < b.i_prediction_variance,
            "d" => a.o1_d > b.o1_d,
            "min-sv" => a.o3_min_sv > b.o3_min_sv,
            "noise" => a.o4_noise > b.o4_noise,
            _ => a.o5_a > b.o5_a,
        };
        assert!(better, "{}: {a:?} vs {b:?}", c.name());
    }
}

#[test]
fn planned_poses_calibrate_to_a_smaller_true_error_than_random_ones_on_the_twin() {
    let (s, robot) = scenario();
    let o = StudyOptions {
        ns: vec![15],
        multiples: vec![1.0],
        seeds: vec![1, 2, 3, 4],
        test_poses: 100,
        plan: PlanOptions { candidates: 2000, ..PlanOptions::default() },
    };
    let c = &study(&s, &robot, &o).unwrap()[0];
    let wins = c.seeds.iter().filter(|r| r.planned_mm < r.random_mm[0]).count();
    eprintln!("planned {:.4} mm, random {:.4} mm (medians), planned better on {wins}/4 seeds", c.planned_median_mm, c.random_median_mm[0]);
    assert!(c.planned_median_mm < 0.9 * c.random_median_mm[0], "{c:?}");
    assert!(wins >= 3, "{c:?}");
}

#[test]
fn a_plan_for_compliance_designs_for_its_parameters_under_the_payload() {
    let (s, robot) = scenario();
    let loads = JointLoads { payload: Some(crate::robot::statics::Payload { mass_kg: 3.0, com_mm: [40.0, 0.0, 60.0] }), ..JointLoads::default() };
    let o = PlanOptions { n: 30, candidates: 2000, effects: vec![(EffectKind::Compliance, None)], loads, ..PlanOptions::default() };
    let p = plan(&s, &robot, &o).unwrap();
    let compliance: Vec<&String> = p.identifiable.iter().filter(|n| n.contains("compliance")).collect();
    // Joints 2 and 3 carry the arm's weight on every pose: their compliance is seen.
    assert!(compliance.len() >= 2, "{:?}", p.identifiable);
    assert!(p.indices.i_prediction_variance < p.random_median.i_prediction_variance, "{:?} vs {:?}", p.indices, p.random_median);
    // The same plan without the effect is another design: the compliance moves the choice.
    let geometric = plan(&s, &robot, &PlanOptions { effects: Vec::new(), ..o.clone() }).unwrap();
    assert!(geometric.identifiable.len() + compliance.len() == p.identifiable.len(), "{:?} vs {:?}", geometric.identifiable, p.identifiable);
    assert_ne!(geometric.poses, p.poses);
    // An effect the candidates cannot configure is refused by name.
    let e = plan(&s, &robot, &PlanOptions { effects: vec![(EffectKind::Thermal, None)], ..o.clone() }).unwrap_err().to_string();
    assert!(e.contains("thermal") || e.contains("temp"), "{e}");
}

#[test]
fn the_tool_point_information_is_the_mean_error_left_after_a_rigid_registration() {
    // For any parameter change δ, δᵀWδ is the mean over the pool of |Gδ − Bξ|² with ξ the
    // small rigid motion of the base that best absorbs Gδ.
    let (s, robot) = scenario();
    let q = candidates(&s, &robot, 300, 3).unwrap().q;
    let model = Model::new(&s, &robot, Parametrisation::Hayati, &[], &JointLoads::default()).unwrap();
    let n = model.model.n_params();
    let keep: Vec<usize> = (0..n).collect();
    let scale = vec![1.0; n];
    let w = tool_point_information(&model, &q, None, &keep, &scale);
    let mut wk = model.model.work();
    let mut dx = vec![Vector3::zeros(); n];
    let mut rows = Vec::new();
    for qi in &q {
        let pt = crate::units::to_mm(model.model.tool_point_grad_with(&model.x, qi, &RowInputs::default(), &mut wk, &mut dx));
        rows.push((pt, DMatrix::from_fn(3, n, |r, c| crate::units::to_mm(dx[c][r]))));
    }
    for k in 0..3 {
        let delta = nalgebra::DVector::from_fn(n, |i, _| (((i + 7 * k) as f64) * 0.91).sin() * 1e-4);
        // Least squares over ξ = (t, ω): e_i ≈ t + ω × p_i.
        let e: Vec<Vector3<f64>> = rows.iter().map(|(_, g)| Vector3::from_iterator((g * &delta).iter().copied())).collect();
        let b = DMatrix::from_fn(3 * q.len(), 6, |r, c| {
            let p = rows[r / 3].0 / 1000.0;
            let skew = -p.cross_matrix();
            if c < 3 {
                if r % 3 == c {
                    1.0
                } else {
                    0.0
                }
            } else {
                skew[(r % 3, c - 3)]
            }
        });
        let y = nalgebra::DVector::from_iterator(3 * q.len(), e.iter().flat_map(|v| v.iter().copied()));
        let xi = b.clone().svd(true, true).solve(&y, 1e-14).unwrap();
        let left = (&y - &b * xi).norm_squared() / q.len() as f64;
        let quad = (delta.transpose() * &w * &delta)[(0, 0)];
        assert!((quad - left).abs() < 1e-6 * left.max(1e-30), "δ {k}: δᵀWδ {quad} vs mean error left {left}");
        assert!(left > 0.0 && left < (y.norm_squared() / q.len() as f64), "the registration absorbs part of the error");
    }
    // A turn of the whole arm about the base's z axis is absorbed whole: joint 1's zero.
    let j1 = model.model.index("joint_1.theta").expect("the Hayati model names joint 1's zero");
    assert!(w[(j1, j1)] < 1e-12 * w.diagonal().max(), "joint 1's zero: {:.3e} of {:.3e}", w[(j1, j1)], w.diagonal().max());
}
