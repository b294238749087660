//! Stage "effects": the effect blocks a calibration asks for, added to its model, and the
//! rows' inputs they read (time, temperature, torques, flanks).

use super::options::CalibOptions;
use super::split::SplitData;
use crate::calib::effects::RowInputs;
use crate::calib::model::CalibModel;
use crate::dataset::Dataset;
use crate::error::Result;

/// Stage "effects": adds the requested effect blocks to the model and gives every sample the
/// per-row inputs they need (computed over the whole file in acquisition order, then split);
/// with `inputs` the rows get their inputs (and the result its torque model) even without
/// effect blocks, for a solver that reads them ([`Solver::needs_row_inputs`](crate::calib::methods::Solver::needs_row_inputs)).
pub fn effects_stage(model: &mut CalibModel, split: &mut SplitData, data: &Dataset, opts: &CalibOptions, inputs: bool) -> Result<()> {
    if opts.effects.is_empty() && !inputs {
        return Ok(());
    }
    let (torque, all) = add_effects(model, data, opts)?;
    split.torque_model = torque;
    split.train.inputs = split.train_idx.iter().map(|&i| all[i].clone()).collect();
    split.test.inputs = split.test_idx.iter().map(|&i| all[i].clone()).collect();
    Ok(())
}

/// The effect blocks `opts` asks for added to `model`, with the torque model (from the model's
/// placement) and every row's inputs (file order) they read.
pub fn add_effects(
    model: &mut CalibModel,
    data: &Dataset,
    opts: &CalibOptions,
) -> Result<(Option<crate::calib::effects::inputs::TorqueModel>, Vec<RowInputs>)> {
    let placement = model.placement(&model.nominal);
    let robot = opts.inertial_robot();
    let torque = robot.map(|r| {
        crate::calib::effects::inputs::TorqueModel::new(r, &opts.loads.joints, placement.exit(), placement.tool, model.measurement.feature().is_some())
    });
    let all = crate::calib::effects::inputs::row_inputs(data, torque.as_ref());
    // Rows with their own payload load the joints too.
    let has_torques = torque.as_ref().is_some_and(|t| t.carries_torque() || data.rows.iter().any(|r| r.payload_kg.is_some_and(|m| m > 0.0)));
    let span = crate::calib::effects::inputs::time_span(data);
    for &(kind, joint) in &opts.effects {
        let joints: Vec<Option<usize>> = match (kind.per_joint(), joint) {
            (true, None) => (0..data.n_joints()).map(Some).collect(),
            (_, j) => vec![j],
        };
        for j in joints {
            let b = crate::calib::effects::inputs::block_for(data, kind, j, has_torques)?;
            model.add_effect(if opts.sensor_lag { b } else { b.unrefined() }, span);
        }
    }
    Ok((torque, all))
}
