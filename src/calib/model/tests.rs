//! The calibration models' tests: D-H tables against the URDF, and every derivative against
//! central differences.
use super::*;

fn guess() -> DrawWireGuess {
    DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.062, 0.004, -0.003] }
}

/// Central differences (step `h`) of a row's readings and of its tool point with respect to
/// parameter `k` of `x`.
fn central_differences(
    m: &CalibModel,
    x: &[f64],
    k: usize,
    h: f64,
    q: &[f64],
    inp: &crate::calib::effects::RowInputs,
    w: &mut ModelWork,
) -> (Vec<f64>, Vector3<f64>) {
    let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
    xp[k] += h;
    xm[k] -= h;
    let d = m.measurement.dim();
    let (mut yp, mut ym) = (vec![0.0; d], vec![0.0; d]);
    m.readings(&xp, q, inp, w, &mut yp);
    m.readings(&xm, q, inp, w, &mut ym);
    let dy = yp.iter().zip(&ym).map(|(a, b)| (a - b) / (2.0 * h)).collect();
    (dy, (m.tool_point_with(&xp, q, inp, w) - m.tool_point_with(&xm, q, inp, w)) / (2.0 * h))
}

#[test]
fn dh_tables_reproduce_the_urdf() {
    let robot = Robot::irb120();
    let t = DhTable::from_robot(&robot);
    let mm: Vec<(f64, f64, f64, f64)> = t.rows.iter().map(|r| (r.theta.to_degrees(), r.d * 1e3, r.a * 1e3, r.alpha.to_degrees())).collect();
    // d1 = 290, a2 = 270, a3 = 70, d4 = 302, d6 = 72 (IRB 120 data sheet).
    assert!((mm[0].1 - 290.0).abs() < 1e-9 && (mm[1].2 - 270.0).abs() < 1e-9 && (mm[2].2 - 70.0).abs() < 1e-9, "{mm:?}");
    assert!((mm[3].1 - 302.0).abs() < 1e-9 && (mm[5].1 - 72.0).abs() < 1e-9, "{mm:?}");
    assert!(t.rows[1].parallel && !t.rows[0].parallel && !t.rows[2].parallel);
    let frame = CalibModel::frame(&robot, &guess());
    for hayati in [false, true] {
        let m = CalibModel::dh(&robot, &guess(), hayati);
        assert_eq!(m.n_params(), 31);
        let (mut w1, mut w2) = (m.work(), frame.work());
        for k in 0..20 {
            let q: Vec<f64> = (0..6).map(|j| ((k * 7 + j * 3) as f64 * 0.37).sin() * 2.0).collect();
            let a = m.tool_point(&m.nominal, &q, &mut w1);
            let b = frame.tool_point(&frame.nominal, &q, &mut w2);
            assert!((a - b).norm() < 1e-12, "hayati={hayati}: {a} vs {b}");
        }
    }
}

#[test]
fn effect_gradients_match_finite_differences() {
    use crate::calib::effects::{EffectBlock, EffectKind, RowInputs, ThermalDrive};
    let robot = Robot::irb120();
    for thermal in
        [ThermalDrive::WarmUp, ThermalDrive::Temperature { ref_c: 21.0, sensor_lag: false }, ThermalDrive::Temperature { ref_c: 21.0, sensor_lag: true }]
    {
        let mut m = CalibModel::dh(&robot, &guess(), true);
        for j in 0..6 {
            m.add_effect(EffectBlock::joint(EffectKind::Compliance, j), 3600.0);
            m.add_effect(EffectBlock::joint(EffectKind::Backlash, j), 3600.0);
            m.add_effect(EffectBlock::joint(EffectKind::Eccentricity, j), 3600.0);
        }
        m.add_effect(EffectBlock { kind: EffectKind::Thermal, joint: None, thermal: Some(thermal), range_m: None }, 3600.0);
        m.add_effect(EffectBlock { kind: EffectKind::Thermal, joint: Some(1), thermal: Some(thermal), range_m: None }, 3600.0);
        m.add_effect(EffectBlock { kind: EffectKind::Nonlinearity, joint: None, thermal: None, range_m: Some([0.4, 1.6]) }, 3600.0);
        let mut x = m.nominal.clone();
        let first = m.first_effect();
        for (k, v) in x.iter_mut().enumerate() {
            let scale = match m.kinds[k] {
                Kind::Effect(crate::calib::effects::EffectUnit::Compliance) => 1e-5,
                Kind::Effect(crate::calib::effects::EffectUnit::Seconds | crate::calib::effects::EffectUnit::Lag) => 50.0,
                Kind::Effect(crate::calib::effects::EffectUnit::Ratio | crate::calib::effects::EffectUnit::PerKelvin) => 1e-4,
                Kind::Effect(_) => 1e-3,
                _ => 0.01,
            };
            *v += scale * ((k as f64) * 1.3).sin();
        }
        assert!(x.len() >= first + 29);
        let inp = RowInputs {
            t_s: Some(900.0),
            temp_c: Some(24.5),
            temp_rate_k_per_s: Some(2.5e-3),
            torque: vec![1.0, -30.0, 12.0, 0.8, -0.6, 0.1],
            side: vec![1.0, -1.0, 1.0, -1.0, 1.0, 1.0],
            ..Default::default()
        };
        let q = [0.3, -0.4, 0.5, 1.0, -0.7, 0.2];
        let mut w = m.work();
        let mut g = vec![0.0; m.n_params()];
        m.length_grad(&x, &q, &inp, &mut w, &mut g);
        // And the tool point's parameter Jacobian with every effect (the thermal scale's
        // terms too) on the cable's model: the cable's own parameters do not move the tool.
        let mut dx = vec![Vector3::zeros(); m.n_params()];
        m.tool_point_grad_with(&x, &q, &inp, &mut w, &mut dx);
        for k in 0..m.n_params() {
            let h = if matches!(m.kinds[k], Kind::Effect(crate::calib::effects::EffectUnit::Seconds | crate::calib::effects::EffectUnit::Lag)) {
                1e-2
            } else {
                1e-7
            };
            let (dy, fd) = central_differences(&m, &x, k, h, &q, &inp, &mut w);
            let tol = 1e-7 * (1.0 + g[k].abs());
            assert!((dy[0] - g[k]).abs() < tol, "{:?} {}: {} vs {}", thermal, m.names[k], dy[0], g[k]);
            assert!((fd - dx[k]).norm() < 1e-7 * (1.0 + fd.norm()), "{:?} tool point / {}: {fd} vs {}", thermal, m.names[k], dx[k]);
        }
        // With no effect active the prediction equals the rigid model's.
        let rigid = CalibModel::dh(&robot, &guess(), true);
        let mut wr = rigid.work();
        let l0 = m.length(&m.nominal, &q, &inp, &mut w);
        assert!((l0 - rigid.length(&rigid.nominal, &q, &RowInputs::default(), &mut wr)).abs() < 1e-15);
    }
}

#[test]
fn station_and_mount_gradients_match_finite_differences() {
    use crate::calib::effects::{EffectBlock, EffectKind, RowInputs};
    let robot = Robot::irb120();
    for measurement in Measurement::ALL {
        let own: Vec<f64> = (0..measurement.target_index()).map(|k| 0.2 * (k as f64 * 0.9).sin() + 0.05).collect();
        let p = Placement { measurement, own, tool: Vector3::new(0.01, -0.02, 0.08) };
        let base = CalibModel::dh(&robot, &guess(), true).with_placement(&p);
        let (ns, nm) = (base.setup_params(SetupKind::Station).len(), base.setup_params(SetupKind::Mount).len());
        assert_eq!(ns + nm, measurement.n_placement());
        let others: Vec<Vec<f64>> = (1..3).map(|s| (0..ns).map(|k| 0.3 * ((k + 5 * s) as f64 * 0.7).cos()).collect()).collect();
        let mount: Vec<Vec<f64>> = vec![(0..nm).map(|k| 0.05 * (k as f64 * 1.7).sin() + 0.02).collect()];
        let labels = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let mut m = base.with_setups((labels(&["a", "b", "c"]), &others), (labels(&["m1", "m2"]), &mount));
        m.add_effect(EffectBlock::joint(EffectKind::Compliance, 1), 3600.0);
        assert_eq!(m.n_params(), m.n_chain() + measurement.n_placement() + 2 * ns + nm + 1);
        assert_eq!(m.first_effect(), m.setup_block(SetupKind::Mount, 1).end);
        assert_eq!(m.station_range(2).end, m.setup_block(SetupKind::Mount, 1).start);
        let mut x = m.nominal.clone();
        x[m.first_effect()] = 1e-5;
        let q = [0.3, -0.4, 0.5, 1.0, -0.7, 0.2];
        let mut w = m.work();
        let d = measurement.dim();
        for (station, mount) in [(0, 0), (1, 0), (2, 1), (0, 1)] {
            let inp = RowInputs { torque: vec![1.0, -30.0, 12.0, 0.8, -0.6, 0.1], station, mount, ..Default::default() };
            let (mut y, mut jac) = (vec![0.0; d], vec![0.0; d * m.n_params()]);
            m.readings_grad(&x, &q, &inp, &mut w, &mut y, &mut jac);
            // Without the effect, a set-up reads as a one-set-up model placed there.
            let alone = CalibModel::dh(&robot, &guess(), true).with_placement(&m.placement_at(&x, station, mount));
            let mut x0 = x.clone();
            x0[m.first_effect()] = 0.0;
            let (mut y0, mut y1) = (vec![0.0; d], vec![0.0; d]);
            m.readings(&x0, &q, &inp, &mut w, &mut y0);
            let mut wa = alone.work();
            alone.readings(&alone.nominal, &q, &RowInputs::default(), &mut wa, &mut y1);
            assert!(y0.iter().zip(&y1).all(|(a, b)| (a - b).abs() < 1e-12), "{} ({station}, {mount}): {y0:?} vs {y1:?}", measurement.name());
            let mut dx = vec![Vector3::zeros(); m.n_params()];
            m.tool_point_grad_with(&x, &q, &inp, &mut w, &mut dx);
            for k in 0..m.n_params() {
                let (dy, fd) = central_differences(&m, &x, k, 1e-7, &q, &inp, &mut w);
                for (i, dy) in dy.iter().enumerate() {
                    let g = jac[i * m.n_params() + k];
                    assert!((dy - g).abs() < 1e-6 * (1.0 + g.abs()), "{} ({station}, {mount}) value {i} / {}: {dy} vs {g}", measurement.name(), m.names[k]);
                }
                assert!(
                    (fd - dx[k]).norm() < 1e-6 * (1.0 + fd.norm()),
                    "{} ({station}, {mount}) tool point / {}: {fd} vs {}",
                    measurement.name(),
                    m.names[k],
                    dx[k]
                );
            }
        }
    }
}

#[test]
fn length_gradient_matches_finite_differences() {
    let robot = Robot::irb120();
    for m in [CalibModel::dh(&robot, &guess(), true), CalibModel::frame(&robot, &guess()), CalibModel::generic(6, &guess())] {
        let mut x = m.nominal.clone();
        for (k, v) in x.iter_mut().enumerate() {
            *v += 0.01 * ((k as f64) * 1.3).sin();
        }
        if m.name == "generic6r" {
            for k in 0..m.n_chain() {
                x[k] += 0.3 * ((k as f64) * 0.7).cos();
            }
        }
        let q = [0.3, -0.4, 0.5, 1.0, -0.7, 0.2];
        let mut w = m.work();
        let mut g = vec![0.0; m.n_params()];
        m.length_grad(&x, &q, &RowInputs::default(), &mut w, &mut g);
        for k in 0..m.n_params() {
            let fd = central_differences(&m, &x, k, 1e-7, &q, &Default::default(), &mut w).0[0];
            assert!((fd - g[k]).abs() < 1e-7, "{} {}: {fd} vs {}", m.name, m.names[k], g[k]);
        }
    }
}

#[test]
fn tracker_readings_jacobians_match_finite_differences() {
    use crate::calib::effects::{EffectBlock, EffectKind, RowInputs};
    let robot = Robot::irb120();
    let point = Placement { measurement: Measurement::Point, own: vec![0.2, -0.1, 0.05, 0.03, -0.02, 0.6], tool: Vector3::new(0.01, 0.02, 0.08) };
    let pose = Placement { measurement: Measurement::Pose, own: vec![0.2, -0.1, 0.05, 0.03, -0.02, 0.6, 0.4, -0.3, 1.2], tool: Vector3::new(0.01, 0.02, 0.08) };
    for tracker in [point, pose] {
        let mut m = CalibModel::dh(&robot, &guess(), true).with_placement(&tracker);
        assert_eq!(m.placement(&m.nominal), tracker);
        assert_eq!(m.names[m.placement_range()].join(","), tracker.measurement.placement_names().join(","));
        m.add_effect(EffectBlock::joint(EffectKind::Compliance, 1), 3600.0);
        m.add_effect(EffectBlock::joint(EffectKind::Backlash, 2), 3600.0);
        let mut x = m.nominal.clone();
        for (k, v) in x.iter_mut().enumerate() {
            *v += if matches!(m.kinds[k], Kind::Effect(_)) { 1e-5 } else { 0.01 } * ((k as f64) * 1.3).sin();
        }
        let inp = RowInputs { torque: vec![1.0, -30.0, 12.0, 0.8, -0.6, 0.1], side: vec![1.0, -1.0, 1.0, -1.0, 1.0, 1.0], ..Default::default() };
        let q = [0.3, -0.4, 0.5, 1.0, -0.7, 0.2];
        let (n, d, mut w) = (m.n_params(), m.measurement.dim(), m.work());
        let (mut y, mut jac) = (vec![0.0; d], vec![0.0; d * n]);
        m.readings_grad(&x, &q, &inp, &mut w, &mut y, &mut jac);
        let mut plain = vec![0.0; d];
        m.readings(&x, &q, &inp, &mut w, &mut plain);
        assert_eq!(y, plain);
        let (mut yp, mut ym) = (vec![0.0; d], vec![0.0; d]);
        let h = 1e-7;
        // The readings' and the tool point's parameter Jacobians (the tool point's is what a
        // plan's accuracy is judged on).
        let mut dx = vec![Vector3::zeros(); n];
        let p0 = m.tool_point_grad_with(&x, &q, &inp, &mut w, &mut dx);
        assert_eq!(p0, m.tool_point_with(&x, &q, &inp, &mut w));
        for k in 0..n {
            let (dy, fd) = central_differences(&m, &x, k, h, &q, &inp, &mut w);
            for (i, dy) in dy.iter().enumerate() {
                assert!((dy - jac[i * n + k]).abs() < 1e-7 * (1.0 + dy.abs()), "{} y{i} / {}: {dy} vs {}", m.measurement.name(), m.names[k], jac[i * n + k]);
            }
            assert!((fd - dx[k]).norm() < 1e-7 * (1.0 + fd.norm()), "tool point / {}: {fd} vs {}", m.names[k], dx[k]);
        }
        // And with respect to the joint angles (the row's inputs held).
        let mut gq = vec![0.0; d * 6];
        m.readings_grad_q(&x, &q, &inp, &mut w, &mut y, &mut gq);
        assert_eq!(y, plain);
        for j in 0..6 {
            let (mut qp, mut qm) = (q, q);
            qp[j] += h;
            qm[j] -= h;
            m.readings(&x, &qp, &inp, &mut w, &mut yp);
            m.readings(&x, &qm, &inp, &mut w, &mut ym);
            for i in 0..d {
                let fd = (yp[i] - ym[i]) / (2.0 * h);
                assert!((fd - gq[i * 6 + j]).abs() < 1e-7 * (1.0 + fd.abs()), "{} y{i} / q{}: {fd} vs {}", m.measurement.name(), j + 1, gq[i * 6 + j]);
            }
        }
    }
}
