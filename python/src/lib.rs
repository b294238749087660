//! `twincal._native`: the twincal library's commands for Python, in memory.
//!
//! The Python package (`twincal/__init__.py`) wraps this module, which is over the library only
//! (and its recordings, `twincal-viz`): keyword arguments become the library's typed requests
//! (`twincal::requests`, `twincal::jobs`: the command line's options, with the same defaults,
//! checks and messages), mappings of numpy arrays become datasets (read by the same reader as a
//! CSV file), and results come back as objects and arrays. Long work runs with the GIL
//! released; an optional progress callback is called from the calling thread.

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use twincal::calib::pipeline::{CalibResult, TruthFile};
use twincal::dataset::AngleUnit;
use twincal::dataset::{ColumnValues, Dataset};
use twincal::jobs::{self, CalibrateJob, Calibration, CompareJob, CompareRequest, Compared, DiagnoseJob, Diagnosed, ReplayJob, ReplayRequest};
use twincal::requests::{from_json, CalibrateRequest, DiagnoseRequest, Reading};
use twincal::sim::generate::Progress;
use twincal_viz::Rerun;

create_exception!(
    _native,
    TwincalError,
    PyValueError,
    "An error twincal reports: bad input or options, a calibration that cannot run. Its message is what the command line prints after 'error:'."
);

fn err(e: twincal::Error) -> PyErr {
    TwincalError::new_err(e.to_string())
}

/// A request from its options as JSON (Python's keyword arguments, `twincal/__init__.py`).
fn request<T: serde::de::DeserializeOwned + serde::Serialize + Default>(command: &str, options: &str) -> PyResult<T> {
    from_json(command, options).map_err(err)
}

/// Progress as the library reports it, read by the calling thread for the Python callback.
#[derive(Default)]
struct Ticker {
    total: AtomicU64,
    done: AtomicU64,
    what: Mutex<String>,
    /// Changes with every report, so that the caller calls back only on news.
    stamp: AtomicU64,
}

impl Ticker {
    fn say(&self, line: &str) {
        *self.what.lock().unwrap_or_else(|e| e.into_inner()) = line.to_string();
        self.stamp.fetch_add(1, Ordering::SeqCst);
    }
    fn state(&self) -> (String, u64, u64) {
        (self.what.lock().unwrap_or_else(|e| e.into_inner()).clone(), self.done.load(Ordering::SeqCst), self.total.load(Ordering::SeqCst))
    }
}

impl Progress for Ticker {
    fn start(&self, total: u64, what: &str) {
        self.total.store(total, Ordering::SeqCst);
        self.done.store(0, Ordering::SeqCst);
        self.say(what);
    }
    fn inc(&self, n: u64) {
        self.done.fetch_add(n, Ordering::SeqCst);
        self.stamp.fetch_add(1, Ordering::SeqCst);
        twincal::progress::check_stop();
    }
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_else(|| "unknown panic".into())
}

/// Runs of the library in flight in this process: the last one to end after a Ctrl-C lets
/// computations run again.
static IN_FLIGHT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Runs `work` with the GIL released, on a scoped thread, while this thread checks for signals
/// every 50 ms: a Ctrl-C (KeyboardInterrupt) asks the work to stop (it unwinds at its next
/// check, dropping whatever it staged, see [`twincal::progress::request_stop`]) and is raised
/// once it has. With a `progress` callable this thread also calls `progress(what, done, total)`
/// whenever the work reports news (at most every 0.1 s); an exception in the callback is raised
/// once the work is done.
fn released<T: Send>(py: Python<'_>, progress: Option<&Bound<'_, PyAny>>, work: impl FnOnce(&Ticker) -> twincal::Result<T> + Send) -> PyResult<T> {
    let ticker = Ticker::default();
    let mut cb_err: Option<PyErr> = None;
    let mut interrupted: Option<PyErr> = None;
    IN_FLIGHT.fetch_add(1, Ordering::SeqCst);
    let joined = std::thread::scope(|s| {
        let h = s.spawn(|| work(&ticker));
        let mut seen = u64::MAX;
        let mut last_call = Instant::now() - Duration::from_secs(1);
        loop {
            let finished = py.detach(|| {
                let t0 = Instant::now();
                while !h.is_finished() && t0.elapsed() < Duration::from_millis(50) {
                    std::thread::sleep(Duration::from_millis(2));
                }
                h.is_finished()
            });
            if interrupted.is_none() {
                if let Err(e) = py.check_signals() {
                    twincal::progress::request_stop();
                    interrupted = Some(e);
                }
            }
            let stamp = ticker.stamp.load(Ordering::SeqCst);
            if let Some(cb) = progress.filter(|_| stamp != seen && cb_err.is_none() && (finished || last_call.elapsed() >= Duration::from_millis(100))) {
                (seen, last_call) = (stamp, Instant::now());
                if let Err(e) = cb.call1(ticker.state()) {
                    cb_err = Some(e);
                }
            }
            if finished {
                break;
            }
        }
        h.join()
    });
    if IN_FLIGHT.fetch_sub(1, Ordering::SeqCst) == 1 {
        twincal::progress::clear_stop();
    }
    if let Some(e) = interrupted {
        return Err(e);
    }
    let out = joined.map_err(|p| {
        if p.is::<twincal::progress::Stopped>() {
            // Another thread's Ctrl-C stopped this work too.
            pyo3::exceptions::PyKeyboardInterrupt::new_err("stopped by a Ctrl-C (KeyboardInterrupt) in another thread")
        } else {
            PyRuntimeError::new_err(format!("twincal failed unexpectedly: {}", panic_text(p.as_ref())))
        }
    })?;
    if let Some(e) = cb_err {
        return Err(e);
    }
    out.map_err(err)
}

/// Where a dataset comes from: a path (folder, CSV, xlsx) or columns in memory.
enum Source {
    Path(PathBuf),
    Columns(Vec<(String, ColumnValues)>),
}

/// The label of in-memory data in messages and results.
/// In-memory data as errors name them (the header is line 1, so row k is line k + 2), and as
/// results record them.
const MEMORY: &str = "(arrays; line k + 2 is row k)";
const MEMORY_SOURCE: &str = "arrays (in memory)";

fn source(data: &Bound<'_, PyAny>) -> PyResult<Source> {
    if let Ok(p) = data.extract::<PathBuf>() {
        return Ok(Source::Path(p));
    }
    let Ok(items) = data.extract::<Vec<(String, Bound<'_, PyAny>)>>() else {
        return Err(PyTypeError::new_err("data must be a path (dataset folder, .csv, .xlsx) or a mapping of column names to 1-D arrays"));
    };
    items
        .into_iter()
        .map(|(name, v)| {
            let values = if let Ok(a) = v.extract::<PyReadonlyArray1<'_, f64>>() {
                ColumnValues::Numbers(a.as_array().to_vec())
            } else if let Ok(t) = v.extract::<Vec<String>>() {
                ColumnValues::Texts(t)
            } else {
                return Err(PyTypeError::new_err(format!("column {name}: expected a 1-D float64 array or a list of strings")));
            };
            Ok((name, values))
        })
        .collect::<PyResult<Vec<_>>>()
        .map(Source::Columns)
}

/// Loaded data, the fingerprint of their bytes, the truth that belongs to them (a twin's), and
/// whether they came from a file (which the outputs must not overwrite).
struct Loaded {
    data: Dataset,
    sha256: String,
    truth: Option<TruthFile>,
    path: Option<PathBuf>,
}

/// What to do about a truth that belongs to other data.
const TRUTH_FIX: &str = "pass the truth twincal.generate returned with exactly the data it returned";

/// The dataset a source holds, read and checked as `--data` reads a file. In-memory data keep
/// their label for messages only.
fn dataset(src: Source, opts: &twincal::dataset::ReadOptions) -> twincal::Result<Dataset> {
    match src {
        Source::Path(p) => Dataset::load_with(&p, opts),
        Source::Columns(c) => Dataset::from_columns(c, MEMORY, opts),
    }
}

fn load(src: Source, opts: &twincal::dataset::ReadOptions, truth: Option<&str>) -> twincal::Result<Loaded> {
    use twincal::dataset::truth::sha256_hex;
    match src {
        Source::Path(p) => {
            let data = Dataset::load_with(&p, opts)?;
            let file = jobs::data_inputs(&p).swap_remove(0);
            let bytes = std::fs::read(&file).map_err(|e| twincal::Error::io(&file, e))?;
            let sha256 = sha256_hex(&bytes);
            let truth = match truth {
                Some(text) => {
                    let t = TruthFile::parse(text, "truth")?;
                    t.check_belongs(&bytes, &file.display().to_string(), "truth", TRUTH_FIX)?;
                    Some(t)
                }
                None => TruthFile::find(&p)?,
            };
            // Resolved now, so that a later change of working directory cannot point the
            // outputs' check (no output over an input) at another file.
            let p = std::path::absolute(&p).unwrap_or(p);
            Ok(Loaded { data, sha256, truth, path: Some(p) })
        }
        Source::Columns(cols) => {
            let mut data = dataset(Source::Columns(cols), opts)?;
            data.source = MEMORY_SOURCE.into();
            let csv = data.to_csv_string();
            let truth = match truth {
                Some(text) => {
                    let t = TruthFile::parse(text, "truth")?;
                    t.check_belongs(csv.as_bytes(), "the data given", "truth", TRUTH_FIX)?;
                    Some(t)
                }
                None => None,
            };
            Ok(Loaded { data, sha256: sha256_hex(csv.as_bytes()), truth, path: None })
        }
    }
}

/// A dataset's columns as Python gets them: (name, float64 array or list of strings).
type Columns = Vec<(String, Py<PyAny>)>;
/// One IK run for Python: label, q (n, N) degrees, status, iterations, residual (mm).
type IkRunPy = (String, Py<PyAny>, Vec<String>, Vec<usize>, Py<PyAny>);
/// One Jacobian's pose answers: label, target index per solution, joint angles, status, residual
/// (mm), residual (degrees), conditioning (mm/rad).
type IkPosesPy = (String, Vec<usize>, Py<PyAny>, Vec<String>, Py<PyAny>, Py<PyAny>, Py<PyAny>);

/// A dataset's columns for Python: (name, float64 array or list of strings), in file order.
fn columns_py(py: Python<'_>, ds: &Dataset) -> PyResult<Columns> {
    ds.columns()
        .into_iter()
        .map(|(name, c)| {
            let v: Py<PyAny> = match c {
                ColumnValues::Numbers(v) => PyArray1::from_vec(py, v).into_any().unbind(),
                ColumnValues::Texts(v) => v.into_pyobject(py)?.into_any().unbind(),
            };
            Ok((name, v))
        })
        .collect()
}

/// Simulates a scenario (a TOML path; the embedded default when None), as `twincal generate`.
/// Returns the dataset's columns and truth.json's text, the bytes `generate` writes.
#[pyfunction]
#[pyo3(signature = (scenario=None, seed=None, progress=None, poses=None))]
fn generate(
    py: Python<'_>,
    scenario: Option<PathBuf>,
    seed: Option<u64>,
    progress: Option<Bound<'_, PyAny>>,
    poses: Option<PathBuf>,
) -> PyResult<(Columns, String)> {
    let (ds, truth) = released(py, progress.as_ref(), |t| {
        let (mut s, robot) = jobs::load_scenario(scenario.as_deref())?;
        if let Some(seed) = seed {
            s.seed = seed;
        }
        let g = match &poses {
            None => twincal::sim::generate::generate(&s, &robot, t)?,
            Some(p) => {
                let list = twincal::sim::pose_list::read_pose_list(p, &robot)?;
                twincal::sim::pose_list::generate_pose_list(&s, &robot, list, t)?
            }
        };
        let (_, truth) = twincal::sim::generate::output_texts(&g)?;
        Ok((g.dataset, truth))
    })?;
    Ok((columns_py(py, &ds)?, truth))
}

/// The dataset.csv text of columns, as `generate` and `calibrate` would write and read them.
#[pyfunction]
#[pyo3(signature = (data, angles="auto"))]
fn to_csv(data: &Bound<'_, PyAny>, angles: &str) -> PyResult<String> {
    let opts = Reading { angles: angle_unit(angles)?, ..Reading::default() }.load_options(false);
    let ds = dataset(source(data)?, &opts).map_err(err)?;
    Ok(ds.to_csv_string())
}

/// Reads a dataset (path or columns) the way `calibrate --data` reads it; returns its columns.
/// `options`: a JSON object of `angles`, `measurement`, `euler`.
#[pyfunction]
#[pyo3(signature = (data, options))]
fn read(py: Python<'_>, data: &Bound<'_, PyAny>, options: &str) -> PyResult<Columns> {
    let a: Reading = request("read", options)?;
    let opts = a.load_options(false);
    let src = source(data)?;
    let ds = py.detach(|| dataset(src, &opts)).map_err(err)?;
    columns_py(py, &ds)
}

fn angle_unit(s: &str) -> PyResult<AngleUnit> {
    s.parse::<AngleUnit>().map_err(|_| TwincalError::new_err(format!("angles must be auto, deg or rad, got '{s}'")))
}

/// What a Result holds: a calibration run here (which can still write every output `calibrate`
/// writes), or a result read from a file (which predicts and solves IK).
enum Held {
    Run { c: Box<Calibration>, args: Box<CalibrateJob>, data_path: Option<PathBuf> },
    Read { result: Box<CalibResult> },
}

/// A calibrated model: what `twincal calibrate` writes to result.json, and its use.
#[pyclass(name = "Result", module = "twincal._native", frozen)]
struct PyCalibration {
    held: Held,
}

impl PyCalibration {
    fn result(&self) -> &CalibResult {
        match &self.held {
            Held::Run { c, .. } => &c.result,
            Held::Read { result } => result,
        }
    }
}

#[pymethods]
impl PyCalibration {
    /// result.json's text, byte for byte what `calibrate --out` writes for this run.
    fn to_json(&self) -> PyResult<String> {
        let verdict = match &self.held {
            Held::Run { c, .. } => c.verdict.as_ref(),
            Held::Read { .. } => None,
        };
        let v = twincal::report::verdict::with_verdict(self.result(), verdict).map_err(err)?;
        serde_json::to_string_pretty(&v).map_err(|e| TwincalError::new_err(format!("cannot serialise the result: {e}")))
    }

    /// Readings the model predicts for the rows of `data` (columns q1..qN, and whatever else
    /// the model reads), in the file's reading columns: an (n, d) array.
    #[pyo3(signature = (data, angles="auto", euler="XYZ", register_rows=twincal::calib::pipeline::DEFAULT_REGISTER_ROWS))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        data: &Bound<'py, PyAny>,
        angles: &str,
        euler: &str,
        register_rows: usize,
    ) -> PyResult<(Bound<'py, PyArray2<f64>>, Option<String>)> {
        let reading = Reading {
            angles: angle_unit(angles)?,
            measurement: None,
            euler: euler.parse().map_err(|e: String| err(twincal::Error::Invalid(format!("--euler: {e}"))))?,
        };
        let opts = reading.load_options(false);
        let src = source(data)?;
        let r = self.result();
        let p = py
            .detach(|| {
                let ds = dataset(src, &opts)?;
                jobs::predicted_readings(r, &ds, opts.euler, "the model", register_rows)
            })
            .map_err(err)?;
        let (values, warning) = (p.values, (!p.warnings.is_empty()).then(|| p.warnings.join("; ")));
        let d = r.model.measurement.file_dim();
        let n = values.len() / d;
        Ok((PyArray1::from_vec(py, values).reshape([n, d])?, warning))
    }

    /// Inverse kinematics on this model (geometry and corrector) for target points (n, 3), mm in
    /// the robot's base frame, as `twincal ik --targets`: per Jacobian, the joint angles
    /// (degrees), status, iterations and model residual of each target.
    #[pyo3(signature = (targets, jacobian=None, tol_mm=0.01, seed=0))]
    fn ik<'py>(&self, py: Python<'py>, targets: PyReadonlyArray2<'py, f64>, jacobian: Option<&str>, tol_mm: f64, seed: u64) -> PyResult<Vec<IkRunPy>> {
        use twincal::ik::solver::{IkOptions, JacobianChoice, JacobianKind};
        if targets.shape().len() != 2 || targets.shape()[1] != 3 {
            return Err(TwincalError::new_err(format!("targets must be an (n, 3) array of x, y, z in mm, got shape {:?}", targets.shape())));
        }
        twincal::ik::solver::check_tol_mm(tol_mm, "tol_mm").map_err(err)?;
        let choice: JacobianChoice = jacobian.map(str::parse).transpose().map_err(err)?.unwrap_or_default();
        let kinds: Vec<JacobianKind> = choice.kinds();
        let a = targets.as_array();
        let pts: Vec<nalgebra::Vector3<f64>> = a.rows().into_iter().map(|r| nalgebra::Vector3::new(r[0], r[1], r[2])).collect();
        let r = self.result();
        let o = IkOptions { tol_mm, seed, ..Default::default() };
        let runs = py.detach(|| twincal::ik::validation::ik_runs(r, &pts, &kinds, &o, None));
        let joints = r.model.chain.n_joints;
        runs.into_iter()
            .map(|run| {
                let q: Vec<f64> = run.solutions.iter().flat_map(|s| s.q.iter().map(|v| v.to_degrees())).collect();
                let q = PyArray1::from_vec(py, q).reshape([run.solutions.len(), joints])?.into_any().unbind();
                let status = run.solutions.iter().map(|s| s.status.name().to_string()).collect();
                let iterations = run.solutions.iter().map(|s| s.iterations).collect();
                let residual = PyArray1::from_vec(py, run.solutions.iter().map(|s| s.residual_mm).collect()).into_any().unbind();
                Ok((run.label, q, status, iterations, residual))
            })
            .collect()
    }

    /// Every solution of the calibrated arm for pose targets (n, 6): x, y, z (mm, base frame) and
    /// rx, ry, rz (degrees, `euler`), as `twincal ik --targets` with orientation columns: per
    /// Jacobian, one entry per solution (its target's index, 0-based), the joint angles
    /// (degrees), status, model residuals (mm, degrees) and conditioning (mm/rad).
    #[pyo3(signature = (targets, euler="XYZ", jacobian=None, tol_mm=0.01, tol_deg=0.001))]
    fn ik_poses<'py>(
        &self,
        py: Python<'py>,
        targets: PyReadonlyArray2<'py, f64>,
        euler: &str,
        jacobian: Option<&str>,
        tol_mm: f64,
        tol_deg: f64,
    ) -> PyResult<Vec<IkPosesPy>> {
        use twincal::ik::solver::JacobianChoice;
        if targets.shape().len() != 2 || targets.shape()[1] != 6 {
            return Err(TwincalError::new_err(format!(
                "pose targets must be an (n, 6) array of x, y, z (mm) and rx, ry, rz (degrees), got shape {:?}",
                targets.shape()
            )));
        }
        let euler: twincal::measurement::Euler = euler.parse().map_err(|e: String| err(twincal::Error::Invalid(format!("euler: {e}"))))?;
        let choice: JacobianChoice = jacobian.map(str::parse).transpose().map_err(err)?.unwrap_or_default();
        let a = targets.as_array();
        if let Some((i, row)) = a.rows().into_iter().enumerate().find(|(_, r)| r.iter().any(|v| !v.is_finite())) {
            return Err(TwincalError::new_err(format!("pose target {} is not finite: {:?}", i + 1, row.to_vec())));
        }
        let poses: Vec<(nalgebra::Vector3<f64>, nalgebra::Matrix3<f64>)> =
            a.rows().into_iter().map(|r| (nalgebra::Vector3::new(r[0], r[1], r[2]), euler.matrix([r[3], r[4], r[5]].map(f64::to_radians)))).collect();
        let r = self.result();
        let x_nom = twincal::compensate::nominal_x(r);
        let c = twincal::compensate::Compensator::new(r, &x_nom, None, tol_mm, tol_deg).map_err(err)?;
        let joints = r.model.chain.n_joints;
        choice
            .kinds()
            .into_iter()
            .map(|kind| {
                let answers = py.detach(|| c.solve_poses(&poses, kind));
                let rows: Vec<(usize, &twincal::ik::solver::PoseSolution, f64)> = answers
                    .solutions
                    .iter()
                    .zip(&answers.conditioning)
                    .enumerate()
                    .flat_map(|(i, (ss, ks))| ss.iter().zip(ks).map(move |(s, k)| (i, s, *k)))
                    .collect();
                let q: Vec<f64> = rows.iter().flat_map(|(_, s, _)| s.q.iter().map(|v| v.to_degrees())).collect();
                let q = PyArray1::from_vec(py, q).reshape([rows.len(), joints])?.into_any().unbind();
                let column = |f: &dyn Fn(&(usize, &twincal::ik::solver::PoseSolution, f64)) -> f64| {
                    PyArray1::from_vec(py, rows.iter().map(f).collect()).into_any().unbind()
                };
                Ok((
                    format!("calibrated/{}", kind.name()),
                    rows.iter().map(|(i, _, _)| *i).collect(),
                    q,
                    rows.iter().map(|(_, s, _)| s.status.name().to_string()).collect(),
                    column(&|r| r.1.residual_mm),
                    column(&|r| r.1.residual_deg),
                    column(&|r| r.2),
                ))
            })
            .collect()
    }

    /// Writes what `calibrate` writes for this run: result.json at `out`, and the URDF, Rerun
    /// recording, HTML report and identified twin where given; all together or none.
    #[pyo3(signature = (out, urdf=None, rrd=None, report=None, scenario_out=None))]
    fn save(
        &self,
        py: Python<'_>,
        out: PathBuf,
        urdf: Option<PathBuf>,
        rrd: Option<PathBuf>,
        report: Option<PathBuf>,
        scenario_out: Option<PathBuf>,
    ) -> PyResult<()> {
        match &self.held {
            Held::Run { c, args, data_path } => {
                let mut a = (**args).clone();
                (a.out, a.urdf, a.figures.rrd, a.figures.report, a.scenario_out) = (out, urdf, rrd, report, scenario_out);
                if let Some(p) = data_path {
                    a.data = p.clone();
                }
                py.detach(|| a.check_files(data_path.is_some()).and_then(|_| jobs::write_calibration(&a, c, &Rerun))).map_err(err)
            }
            Held::Read { result } => {
                if urdf.is_some() || rrd.is_some() || report.is_some() || scenario_out.is_some() {
                    return Err(TwincalError::new_err(
                        "a result read from a file saves only its JSON (out); the URDF, recording, report and twin need the calibration run",
                    ));
                }
                result.check_writable().and_then(|_| twincal::output::write_json(&out, &**result)).map_err(err)
            }
        }
    }

    /// The warnings `calibrate` prints (an optimiser that stopped on its budget, ...).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.result().warnings.clone()
    }
}

/// Calibrates as `twincal calibrate` on `data`; `options`: a JSON object of its options but
/// `--data` and the files it writes ([`CalibrateRequest`]).
#[pyfunction]
#[pyo3(signature = (data, options, truth=None, progress=None))]
fn calibrate(py: Python<'_>, data: &Bound<'_, PyAny>, options: &str, truth: Option<String>, progress: Option<Bound<'_, PyAny>>) -> PyResult<PyCalibration> {
    let src = source(data)?;
    let mut req: CalibrateRequest = request("calibrate", options)?;
    req.model.resolve_paths();
    let planned = req.options().map_err(err)?;
    let opts = req.load_options();
    let args = CalibrateJob::new(MEMORY.into(), req);
    let c = released(py, progress.as_ref(), |t| {
        t.start(1, "calibrate");
        let l = load(src, &opts, truth.as_deref())?;
        let path = l.path.clone();
        let c = jobs::calibrate_loaded(planned, l.data, l.truth.as_ref(), Some(l.sha256))?;
        t.inc(1);
        Ok((c, path))
    })?;
    Ok(PyCalibration { held: Held::Run { c: Box::new(c.0), args: Box::new(args), data_path: c.1 } })
}

/// Reads a result.json (`twincal calibrate --out`).
#[pyfunction]
fn load_result(path: PathBuf) -> PyResult<PyCalibration> {
    Ok(PyCalibration { held: Held::Read { result: Box::new(CalibResult::load(&path).map_err(err)?) } })
}

/// A diagnosis: what `twincal diagnose` writes to report.json, and the extended model.
#[pyclass(name = "Diagnosis", module = "twincal._native", frozen)]
struct PyDiagnosis {
    d: Box<Diagnosed>,
    args: Box<DiagnoseJob>,
    data_path: Option<PathBuf>,
}

#[pymethods]
impl PyDiagnosis {
    /// report.json's text, byte for byte what `diagnose --out` writes for this run.
    fn to_json(&self) -> PyResult<String> {
        let v = twincal::report::verdict::with_verdict(&self.d.report, self.d.verdict.as_ref()).map_err(err)?;
        serde_json::to_string_pretty(&v).map_err(|e| TwincalError::new_err(format!("cannot serialise the report: {e}")))
    }

    /// The extended model (what `diagnose --result` writes), as a Result.
    fn result(&self) -> PyCalibration {
        PyCalibration { held: Held::Read { result: Box::new(self.d.result.clone()) } }
    }

    /// Writes what `diagnose` writes: report.json at `out`, the model at `result`, and the
    /// recording, HTML report and identified twin where given; all together or none.
    #[pyo3(signature = (out, result, rrd=None, report=None, scenario_out=None))]
    fn save(
        &self,
        py: Python<'_>,
        out: PathBuf,
        result: PathBuf,
        rrd: Option<PathBuf>,
        report: Option<PathBuf>,
        scenario_out: Option<PathBuf>,
    ) -> PyResult<()> {
        let mut a = (*self.args).clone();
        (a.out, a.result, a.figures.rrd, a.figures.report, a.scenario_out) = (out, result, rrd, report, scenario_out);
        if let Some(p) = &self.data_path {
            a.data = p.clone();
        }
        py.detach(|| a.check_files(self.data_path.is_some()).and_then(|_| jobs::write_diagnosis(&a, &self.d, &Rerun))).map_err(err)
    }
}

/// Diagnoses as `twincal diagnose` on `data`; `options`: a JSON object of its options but
/// `--data` and the files it writes ([`DiagnoseRequest`]); `progress` hears each step's line.
#[pyfunction]
#[pyo3(signature = (data, options, progress=None))]
fn diagnose(py: Python<'_>, data: &Bound<'_, PyAny>, options: &str, progress: Option<Bound<'_, PyAny>>) -> PyResult<PyDiagnosis> {
    let src = source(data)?;
    let mut req: DiagnoseRequest = request("diagnose", options)?;
    req.model.resolve_paths();
    req.loads.robot = req.loads.robot.map(|p| std::path::absolute(&p).unwrap_or(p));
    let planned = req.options().map_err(err)?;
    let opts = req.load_options();
    let args = DiagnoseJob::new(MEMORY.into(), req);
    let (d, path) = released(py, progress.as_ref(), |t| {
        let l = load(src, &opts, None)?;
        let path = l.path.clone();
        let d = jobs::diagnose_loaded(&args.request, planned, l.data, &|line: &str| t.say(line))?;
        Ok((d, path))
    })?;
    Ok(PyDiagnosis { d: Box::new(d), args: Box::new(args), data_path: path })
}

/// Replays the measured acquisition `data` (a path) through the twin of `scenario`, as
/// `twincal replay`, writing its files into the folder `out`; `options`: a JSON object of its
/// options ([`ReplayRequest`]). Returns replay.json's text.
#[pyfunction]
#[pyo3(signature = (data, scenario, options, out, progress=None))]
fn replay(py: Python<'_>, data: PathBuf, scenario: PathBuf, options: &str, out: PathBuf, progress: Option<Bound<'_, PyAny>>) -> PyResult<String> {
    let request: ReplayRequest = request("replay", options)?;
    let job = ReplayJob { data, scenario, request, out, rrd: None, report: None };
    let summary = released(py, progress.as_ref(), |t| jobs::replay(&job, t, &Rerun))?;
    serde_json::to_string(&summary).map_err(|e| TwincalError::new_err(format!("cannot serialise the summary: {e}")))
}

/// Compares methods over seeds on `data` (a path), as `twincal compare`; `options`: a JSON
/// object of its options ([`CompareRequest`]: methods, seeds, model, ...). Writes the tables'
/// JSON to `out`, or with `shard` ("i/N") appends that shard's items to `shard_out`. Returns the
/// tables (Markdown), or the shard's line.
#[pyfunction]
#[pyo3(signature = (data, options, out=None, shard=None, shard_out=None, progress=None))]
fn compare(
    py: Python<'_>,
    data: PathBuf,
    options: &str,
    out: Option<PathBuf>,
    shard: Option<String>,
    shard_out: Option<PathBuf>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    let request: CompareRequest = request("compare", options)?;
    let job = CompareJob { data, request, out, rrd: None, shard, shard_out };
    let done = released(py, progress.as_ref(), |t| jobs::compare(&job, t, &Rerun))?;
    match done {
        Compared::Done(c) => {
            c.outputs.commit().map_err(err)?;
            Ok(c.table)
        }
        Compared::Shard(line) => Ok(line),
    }
}

/// Joins the partial files of sharded compares, as `twincal reduce`, writing the tables' JSON
/// to `out`; returns the tables (Markdown).
#[pyfunction]
fn reduce(py: Python<'_>, parts: Vec<PathBuf>, out: PathBuf) -> PyResult<String> {
    py.detach(|| {
        if parts.is_empty() {
            return Err(twincal::Error::Invalid("reduce needs the shards' partial files".into()));
        }
        twincal::output::check_outputs(&parts.iter().map(|p| ("part", p.as_path())).collect::<Vec<_>>(), &[("out", out.as_path())])?;
        let read = jobs::shard::Parts::read(&parts)?;
        if read.kind() != "compare" {
            return Err(twincal::Error::Invalid(format!(
                "twincal.reduce joins the parts of sharded compares; these are of a '{}' study (join them with the command line's `twincal reduce`)",
                read.kind()
            )));
        }
        let (c, ..) = jobs::reduce_compare(read, Some(&out), None, &Rerun)?;
        c.outputs.commit()?;
        Ok(c.table)
    })
    .map_err(err)
}

/// Writes the calibrated model `model` (a result.json path) as `twincal export` does; `options`:
/// a JSON object of its `format` and `robot`. Returns the summary's JSON (format, file, warnings,
/// read-back difference).
#[pyfunction]
fn export(py: Python<'_>, model: PathBuf, out: PathBuf, options: &str) -> PyResult<String> {
    #[derive(serde::Deserialize, serde::Serialize, Default)]
    #[serde(deny_unknown_fields, default)]
    struct Options {
        format: Option<String>,
        robot: Option<twincal::robot::RobotChoice>,
        against: Option<PathBuf>,
    }
    let o: Options = request("export", options)?;
    let robot = o.robot.map(twincal::robot::RobotChoice::absolute);
    let job = jobs::ExportJob { model, out, format: o.format, robot, against: o.against };
    let summary = released(py, None, |_| job.run())?;
    serde_json::to_string(&summary).map_err(|e| TwincalError::new_err(format!("cannot serialise the summary: {e}")))
}

/// Compensates a program's targets (a CSV) or filters a robot program with a calibrated model,
/// as `twincal compensate`; `options`: a JSON object of the job's fields (`model`, `targets` or
/// `program`, `frames`, `robot`, `joint_targets`, `leave`, `start_joints_deg`, `filtered_dir`,
/// `report`, `payload_kg`, `payload_com_mm`, `tol_mm`, `tol_deg`, `euler`, `out`). Returns the
/// summary's JSON (per target the command, status, residuals and filtered target; for a program
/// also each target's outcome and the run-time motions left).
#[pyfunction]
fn compensate(py: Python<'_>, options: &str) -> PyResult<String> {
    let job: jobs::CompensateJob = request("compensate", options)?;
    let summary = released(py, None, |_| job.run())?;
    serde_json::to_string(&summary).map_err(|e| TwincalError::new_err(format!("cannot serialise the summary: {e}")))
}

/// The N-point TCP, as `twincal tcp`; `options`: a JSON object of the job's fields (`data`,
/// `angles`, `model` or `robot`, `orientation`, `out`). Returns the fit's JSON (the tool point,
/// its uncertainty, the fixed points, the tips' scatter; with `orientation` the tool's
/// orientation on the flange).
#[pyfunction]
fn tcp(py: Python<'_>, options: &str) -> PyResult<String> {
    let job: jobs::TcpJob = request("tcp", options)?;
    let fit = released(py, None, |_| job.run())?;
    serde_json::to_string(&fit).map_err(|e| TwincalError::new_err(format!("cannot serialise the fit: {e}")))
}

/// The 3-point user frame, as `twincal user-frame`; `options`: a JSON object of the job's fields
/// (`data`, `angles`, `tcp`, `model` or `robot`, `out`). Returns the frame's JSON.
#[pyfunction]
fn user_frame(py: Python<'_>, options: &str) -> PyResult<String> {
    let job: jobs::UserFrameJob = request("user_frame", options)?;
    let frame = released(py, None, |_| job.run())?;
    serde_json::to_string(&frame).map_err(|e| TwincalError::new_err(format!("cannot serialise the frame: {e}")))
}

/// Writes a pose list as a measurement program, as `twincal program`; `options`: a JSON object
/// of the job's fields (`poses`, `format`, `robot`, `name`, `hold_s`, `speed_fraction`, `out`).
/// Returns the summary's JSON.
#[pyfunction]
fn program(py: Python<'_>, options: &str) -> PyResult<String> {
    let job: jobs::ProgramJob = serde_json::from_str(options).map_err(|e| TwincalError::new_err(format!("program: {e}")))?;
    let summary = released(py, None, |_| job.run())?;
    serde_json::to_string(&summary).map_err(|e| TwincalError::new_err(format!("cannot serialise the summary: {e}")))
}

/// Writes a controller-subset calibration as the controller's data, as `twincal
/// controller-data`; `options`: a JSON object of the job's fields (`model`, `format`,
/// `tool_mass_kg`, `out`). Returns the summary's JSON.
#[pyfunction]
fn controller_data(py: Python<'_>, options: &str) -> PyResult<String> {
    let job: jobs::ControllerDataJob = serde_json::from_str(options).map_err(|e| TwincalError::new_err(format!("controller_data: {e}")))?;
    let summary = released(py, None, |_| job.run())?;
    serde_json::to_string(&summary).map_err(|e| TwincalError::new_err(format!("cannot serialise the summary: {e}")))
}

/// Plans measurement poses as `twincal plan`, writing poses.csv and plan.json into `out`;
/// `options`: a JSON object of its `scenario`, `poses`, `candidates`, `criterion`, `params`,
/// `seed` and `rrd`. Returns plan.json's text.
#[pyfunction]
fn plan(py: Python<'_>, out: PathBuf, options: &str) -> PyResult<String> {
    let mut job: jobs::PlanJob = request("plan", options)?;
    job.out = out;
    let p = released(py, None, |_| job.run(&Rerun))?;
    serde_json::to_string(&p).map_err(|e| TwincalError::new_err(format!("cannot serialise the plan: {e}")))
}

/// ISO 9283 figures of the measured poses `data` (a path) against each of `models` (result.json
/// paths), as `twincal iso9283`; returns the evaluation's JSON.
#[pyfunction]
fn iso9283(py: Python<'_>, data: PathBuf, models: Vec<PathBuf>, options: &str) -> PyResult<String> {
    let reading: twincal::requests::Reading = request("iso9283", options)?;
    let job = jobs::Iso9283Job { data, model: models, reading, out: None, report: None, register_rows: twincal::calib::pipeline::DEFAULT_REGISTER_ROWS };
    let e = released(py, None, |_| job.run())?;
    serde_json::to_string(&e).map_err(|e| TwincalError::new_err(format!("cannot serialise the evaluation: {e}")))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("TwincalError", m.py().get_type::<TwincalError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(generate, m)?)?;
    m.add_function(wrap_pyfunction!(to_csv, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(load_result, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(replay, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(reduce, m)?)?;
    m.add_function(wrap_pyfunction!(export, m)?)?;
    m.add_function(wrap_pyfunction!(tcp, m)?)?;
    m.add_function(wrap_pyfunction!(user_frame, m)?)?;
    m.add_function(wrap_pyfunction!(compensate, m)?)?;
    m.add_function(wrap_pyfunction!(iso9283, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(program, m)?)?;
    m.add_function(wrap_pyfunction!(controller_data, m)?)?;
    m.add_class::<PyCalibration>()?;
    m.add_class::<PyDiagnosis>()?;
    Ok(())
}
