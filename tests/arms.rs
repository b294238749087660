//! Universal Robots UR5 and UR10 (`urdf/ur5.urdf`, `urdf/ur10.urdf`, typed from UR's published
//! D-H tables, link masses and centres of mass): their forward kinematics against
//! `ur_description`'s URDFs and the UR5 tracker grid's targets (read from ../shared at run time,
//! skipped when absent).

use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};
use twincal::robot::Robot;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn shared(rel: &str) -> Option<PathBuf> {
    let p = root().join("../shared").join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIP: {} is absent (reference files are read from ../shared at run time)", p.display());
        None
    }
}

/// Nominal pose of `robot`'s flange frame at `q` (rad): rotation and position (mm).
fn flange(robot: &Robot, q: &[f64]) -> (Matrix3<f64>, Vector3<f64>) {
    let chain = robot.error_chain();
    let mut ws = twincal::robot::kinematics::FkWork::new(&chain);
    chain.forward(q, &vec![0.0; chain.n_params()], 1.0, &mut ws);
    let f = chain.frame(&ws, chain.flange());
    (f.rot, f.pos * 1e3)
}

/// The flange point of our URDF equals `ur_description`'s tool flange point (the origin of
/// `ee_link`, 82.3 / 92.2 mm along wrist_3_link's y; twincal's loader ends that chain at
/// wrist_3_link) once turned 180° about the base z (UR's D-H base frame against ROS's base_link).
#[test]
fn ur_urdfs_match_ur_description_at_random_poses() {
    for (ours, theirs, d6) in [("urdf/ur5.urdf", "reference/ur_description/ur5_robot.urdf", 82.3), ("urdf/ur10.urdf", "reference/ur_description/ur10_robot.urdf", 92.2)] {
        let Some(reference) = shared(theirs) else { continue };
        let a = Robot::from_urdf_file(&root().join(ours)).unwrap();
        let b = Robot::from_urdf_file(&reference).unwrap();
        assert_eq!((a.dof(), b.dof()), (6, 6));
        let turn = Matrix3::new(-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20);
        let mut worst: f64 = 0.0;
        for _ in 0..1000 {
            let q: Vec<f64> = (0..6).map(|_| rng.random_range(-std::f64::consts::PI..std::f64::consts::PI)).collect();
            let (_, pa) = flange(&a, &q);
            let (rb, pb) = flange(&b, &q);
            let pb = turn * (pb + rb * Vector3::new(0.0, d6, 0.0));
            worst = worst.max((pa - pb).norm());
        }
        eprintln!("{ours}: largest flange-point difference to {theirs} over 1000 random poses {worst:.3e} mm");
        assert!(worst < 1e-6, "{ours}: {worst} mm");
    }
}
