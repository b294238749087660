//! The library's jobs' recordings ([`twincal::jobs::Recordings`]) written for the Rerun viewer.

use std::path::Path;
use twincal::calib::pipeline::CalibResult;
use twincal::diagnose::Diagnosis;
use twincal::error::Result;
use twincal::output::OutputSet;
use twincal::report::{CalibFigures, DiagnosisFigures, ReplayFigures};

/// Recordings for the Rerun viewer: what `--rrd` of `calibrate`, `diagnose`, `replay` and `compare`
/// writes (without the `rerun` feature each is refused with an error naming it).
pub struct Rerun;

impl twincal::jobs::Recordings for Rerun {
    fn calibration(&self, result: &CalibResult, figures: &CalibFigures, outputs: &mut OutputSet, path: &Path) -> Result<()> {
        super::results::record_calibration(result, figures, outputs, path)
    }
    fn diagnosis(&self, report: &Diagnosis, figures: &DiagnosisFigures, outputs: &mut OutputSet, path: &Path) -> Result<()> {
        super::results::record_diagnosis(report, figures, outputs, path)
    }
    fn replay(&self, figures: &ReplayFigures, outputs: &mut OutputSet, path: &Path) -> Result<()> {
        super::results::record_replay(figures, outputs, path)
    }
    fn comparison(&self, table: &str, methods: &[String], runs: &[twincal::jobs::CompareRun], outputs: &mut OutputSet, path: &Path) -> Result<()> {
        let rows: Vec<super::results::CompareRow> =
            runs.iter().map(|r| super::results::CompareRow { method: &r.method, seed: r.seed, test_rmse_mm: r.test.rmse, test_max_mm: r.test.max }).collect();
        super::results::record_comparison(table, methods, &rows, outputs, path)
    }
    fn plan(
        &self,
        plan: &twincal::plan::Plan,
        s: &twincal::sim::scenario::Scenario,
        robot: &twincal::robot::Robot,
        outputs: &mut OutputSet,
        path: &Path,
    ) -> Result<()> {
        super::plan::record_plan(plan, s, robot, outputs, path)
    }
}
