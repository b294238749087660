use super::*;
use crate::measurement::Euler;

#[test]
fn prediction_csv_has_residuals_only_when_every_row_has_a_length() {
    let q: &[f64] = &[1.0, 2.0, 3.0, 4.0, 5.0, 6.5];
    let with = prediction_csv(&["L"], None, &[(q, &[300.5]), (q, &[301.0])], &[300.25, 301.0]);
    assert_eq!(with, "q1,q2,q3,q4,q5,q6,L,L_pred,residual\n1,2,3,4,5,6.5,300.5,300.25,0.25\n1,2,3,4,5,6.5,301,301,0\n");
    let without = prediction_csv(&["L"], None, &[(q, &[]), (q, &[301.0])], &[300.25, 301.0]);
    assert_eq!(without, "q1,q2,q3,q4,q5,q6,L_pred\n1,2,3,4,5,6.5,300.25\n1,2,3,4,5,6.5,301\n");
    // A tracker's point: three values per row, each with its prediction and residual.
    let point = prediction_csv(&["x", "y", "z"], None, &[(q, &[400.5, -20.0, 600.0])], &[400.25, -20.5, 600.0]);
    assert_eq!(
        point,
        "q1,q2,q3,q4,q5,q6,x,y,z,x_pred,y_pred,z_pred,x_residual,y_residual,z_residual\n1,2,3,4,5,6.5,400.5,-20,600,400.25,-20.5,600,0.25,0.5,0\n"
    );
    // A pose: the orientation's residual is a rotation vector (degrees), whatever the Euler
    // angles do: 179.5° against -179.5° about x is a 1° turn, and at gimbal lock (ry = 90°) a
    // 0.001° turn that moves rx and rz by tens of degrees each stays a 0.001° turn.
    let pose =
        prediction_csv(&["x", "y", "z", "rx", "ry", "rz"], Some(Euler::XYZ), &[(q, &[1.0, 2.0, 3.0, 179.5, 0.0, 0.0])], &[1.0, 2.0, 3.5, -179.5, 0.0, 0.0]);
    assert!(pose.starts_with("q1,q2,q3,q4,q5,q6,x,y,z,rx,ry,rz,x_pred,y_pred,z_pred,rx_pred,ry_pred,rz_pred,x_residual,y_residual,z_residual,wx_residual,wy_residual,wz_residual\n"), "{pose}");
    let cells: Vec<f64> = pose.lines().nth(1).unwrap().split(',').map(|c| c.parse().unwrap()).collect();
    assert_eq!(&cells[18..21], &[0.0, 0.0, -0.5]);
    assert!((cells[21] + 1.0).abs() < 1e-9 && cells[22].abs() < 1e-9 && cells[23].abs() < 1e-9, "{pose}");
    let m = [30.0, 89.9999, 10.0];
    let rm = Euler::XYZ.matrix(m.map(f64::to_radians));
    let rp = rm * *nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::x_axis(), 0.001f64.to_radians()).matrix();
    let p = Euler::XYZ.angles(&rp).map(f64::to_degrees);
    let w = rotation_residual_deg(&m, &p, Euler::XYZ);
    let turn = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    assert!((turn - 0.001).abs() < 1e-6, "{w:?} for Euler angles {m:?} against {p:?}");
}

#[test]
fn data_inputs_name_the_files_read() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(data_inputs(dir.path()), vec![dir.path().join("dataset.csv"), dir.path().join("truth.json")]);
    let x = dir.path().join("m.xlsx#Sheet1");
    assert_eq!(data_inputs(&x), vec![dir.path().join("m.xlsx"), dir.path().join("truth.json")]);
}
