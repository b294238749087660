//! Pipeline stage "sensor placement": the starting model of a calibration. For an arm with a
//! nominal description, the draw-wire's exit point and length offset by multilateration from the
//! nominal tool points, then exit point, offset and tool point by a sensor-only least-squares fit;
//! for the generic 6R model, a global search for the whole structure ([`super::generic`]).

use super::model::{CalibModel, SensorGuess};
use super::problem::{ReadingFit, Samples};
use super::run::{CalibOptions, ModelSpec};
use crate::error::{Error, Result};
use crate::measurement::length::multilaterate;
use crate::optim::{LevenbergMarquardt, NoObserver};

/// The calibration model of `spec` with the sensor at `guess`.
pub fn build_model(spec: &ModelSpec, guess: &SensorGuess) -> CalibModel {
    match spec {
        ModelSpec::Nominal { robot, parametrisation } => match parametrisation.as_str() {
            "frame" => CalibModel::frame(robot, guess),
            "dh" => CalibModel::dh(robot, guess, false),
            _ => CalibModel::dh(robot, guess, true),
        },
        ModelSpec::Generic6r => CalibModel::generic(6, guess),
    }
}

/// The starting model: nominal geometry and a sensor guess (given, or multilaterated and
/// aligned), or for the generic model a global search from broad bounds.
pub fn place_sensor(opts: &CalibOptions, train: &Samples) -> Result<CalibModel> {
    let spec = &opts.model;
    let zero_guess = SensorGuess { exit_m: [0.0; 3], offset_m: 0.0, tool_m: [0.0; 3] };
    match spec {
        // The generic model's start is its search over arm topologies, which places the sensor
        // for each candidate arm; a fixed guess with no arm around it (the old all-zero D-H
        // chain) started fits far from any real robot.
        ModelSpec::Generic6r if opts.sensor_guess.is_some() => Err(Error::Invalid(
            "--sensor-guess applies to a nominal model (irb120 or a URDF); the generic model (generic6r) places its sensor in its own search".into(),
        )),
        ModelSpec::Nominal { .. } => {
            let guess = match &opts.sensor_guess {
                Some(g) => g.clone(),
                None => {
                    let m = build_model(spec, &zero_guess);
                    let mut w = m.work();
                    let pts: Vec<_> = train.q.iter().map(|q| m.tool_point(&m.nominal, q, &mut w)).collect();
                    let (e, c) = multilaterate(&pts, &train.y)
                        .ok_or_else(|| Error::Calibration("cannot locate the cable exit point: need at least 6 well-spread poses".into()))?;
                    SensorGuess { exit_m: e, offset_m: c, tool_m: [0.0; 3] }
                }
            };
            // Then align the sensor alone (exit point, offset, tool point) to the nominal robot,
            // so that every method starts from "nominal kinematics, best-fitting sensor" and the
            // identifiability analysis sees a realistic tool point.
            let mut model = build_model(spec, &guess);
            let nc = model.n_chain();
            let fixed: Vec<bool> = (0..model.n_params()).map(|k| k < nc).collect();
            let fit = ReadingFit { model: &model, data: train };
            let lm = LevenbergMarquardt::budget(200);
            let x = lm.minimize(&fit, &model.nominal, &fixed, &mut NoObserver).x;
            if x.iter().all(|v| v.is_finite()) {
                model.nominal = x;
            }
            Ok(model)
        }
        ModelSpec::Generic6r => super::generic::search(train, opts),
    }
}
