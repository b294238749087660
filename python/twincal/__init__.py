"""twincal from Python: the digital twin and the calibration of serial arms, in process.

The functions here run the same library as the ``twincal`` command line (no second
implementation). Keyword options are the command line's options, with ``_`` for ``-``
(``test_fraction=0.2`` is ``--test-fraction 0.2``), checked and defaulted as there. Datasets are
mappings of column names to 1-D numpy arrays (``q1..qN`` in degrees, ``L`` or ``x, y, z``
[``rx, ry, rz``] in mm, optional ``t``, ``temp``, ``sx, sy, sz``, ``split``), read and checked
exactly as a CSV file with these columns is; a pandas DataFrame works as such a mapping, and
``q`` may be given as one (n, N) array. A path (dataset folder, .csv, .xlsx) works wherever data
do. Errors are raised as :class:`TwincalError` with the command line's message. Long work runs
with the GIL released; ``progress(what, done, total)`` is called with news while it runs.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _native
from ._native import TwincalError, __version__

__all__ = [
    "TwincalError",
    "Result",
    "Diagnosis",
    "generate",
    "read",
    "to_csv",
    "calibrate",
    "load_result",
    "diagnose",
    "replay",
    "compare",
    "reduce",
    "export",
    "tcp",
    "user_frame",
    "compensate",
    "iso9283",
    "plan",
    "program",
    "controller_data",
    "cli",
    "__version__",
]

Data = Union[str, os.PathLike, Mapping[str, Any]]
Progress = Optional[Callable[[str, int, int], Any]]

# Options that name files a command writes: from Python they go to save(), or are handled here.
_OUTPUTS = {"out", "urdf", "rrd", "report", "scenario_out", "result"}


def _plain(name: str, value: Any) -> Any:
    """An option's value as JSON holds it: paths as strings, numpy scalars as Python numbers,
    tuples as lists; a NaN or infinity is refused with the option's name."""
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        raise TwincalError(f"option '{name}' must be a finite number, got {value}")
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(name, v) for v in value]
    return value


def _options(options: Mapping[str, Any]) -> str:
    """Keyword options as the JSON object the library's requests read (``twincal::requests``:
    the command line's options by their snake-case names; None leaves an option at its
    default). The library names an unknown option or a value of the wrong type."""
    return json.dumps({k: _plain(k, v) for k, v in options.items() if v is not None})


_SEED_MAX = 2**64 - 1


def _seed(seed: Any, name: str = "seed") -> Any:
    """A seed as the command line takes it (an integer in 0..=2**64-1), else TwincalError."""
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TwincalError(f"{name} must be an integer in 0..={_SEED_MAX}, got {type(seed).__name__} {seed!r}")
    if not 0 <= int(seed) <= _SEED_MAX:
        raise TwincalError(f"{name} must be in 0..={_SEED_MAX}, got {int(seed)}")
    return int(seed)


def _numbers(value: Any, name: str, length: Optional[int] = None) -> Optional[list[float]]:
    """A list of numbers (payloads, a centre of mass): a sequence or an array of numbers, of
    ``length`` where given; a masked entry, a NaN or a non-number is refused by name."""
    if value is None:
        return None
    if isinstance(value, (str, bytes)) or np.ndim(value) != 1:
        what = "a 0-d array" if isinstance(value, np.ndarray) and value.ndim == 0 else type(value).__name__
        raise TwincalError(f"{name} must be a list of numbers{'' if length is None else f' ({length})'}, got {what}")
    if np.ma.isMaskedArray(value) and np.ma.getmaskarray(value).any():
        k = int(np.flatnonzero(np.ma.getmaskarray(value))[0])
        raise TwincalError(f"{name}: entry {k + 1} is masked; pass the value or leave it out")
    out = []
    for k, v in enumerate(np.ma.getdata(value) if np.ma.isMaskedArray(value) else value):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise TwincalError(f"{name}: entry {k + 1} must be a number, got {type(v).__name__} {v!r}")
        if not math.isfinite(float(v)):
            raise TwincalError(f"{name}: entry {k + 1} must be a finite number, got {float(v)}")
        out.append(float(v))
    if length is not None and len(out) != length:
        raise TwincalError(f"{name} must hold {length} numbers, got {len(out)}")
    return out


def _names(value: Any, name: str) -> Optional[list[str]]:
    """A list of names (methods, effects): a string is the command line's comma-separated list
    (``"lm"`` is one method, not two letters), else an iterable of strings."""
    if value is None:
        return None
    if isinstance(value, str):
        return [v.strip() for v in value.split(",")]
    try:
        items = list(value)
    except TypeError:
        raise TwincalError(f"{name} must be a string or a list of strings, got {type(value).__name__}") from None
    bad = [v for v in items if not isinstance(v, str)]
    if bad:
        raise TwincalError(f"{name} must be strings, got {type(bad[0]).__name__} {bad[0]!r}")
    return items


def _paths(value: Any, name: str) -> list[str]:
    """One path or a list of them."""
    if isinstance(value, (str, os.PathLike)):
        return [os.fspath(value)]
    try:
        return [os.fspath(v) for v in value]
    except TypeError:
        raise TwincalError(f"{name} must be a path or a list of paths, got {type(value).__name__}") from None


def _no_outputs(command: str, options: Mapping[str, Any], how: str) -> None:
    named = sorted(k for k in options if k in _OUTPUTS)
    if named:
        raise TypeError(f"{command}() writes no files itself: {', '.join(named)} go to {how}")


def _columns(data: Data) -> Any:
    """A path as it is; a mapping as (name, float64 array | list of str) pairs."""
    if isinstance(data, (str, os.PathLike)):
        return os.fspath(data)
    if not hasattr(data, "keys"):
        raise TypeError("data must be a path (dataset folder, .csv, .xlsx) or a mapping of column names to 1-D arrays")
    out: list[tuple[str, Any]] = []
    for key in data.keys():
        name = str(key)
        v = data[key]
        v = _unmasked(name, v) if np.ma.isMaskedArray(v) else np.asarray(v)
        if name.strip().lower() == "q" and v.ndim == 2:
            out.extend((f"q{j + 1}", np.ascontiguousarray(v[:, j], dtype=np.float64)) for j in range(v.shape[1]))
            continue
        if v.ndim != 1:
            raise TwincalError(f"column {name}: expected a 1-D array, got shape {v.shape}")
        if v.dtype.kind in "biuf":
            out.append((name, np.ascontiguousarray(v, dtype=np.float64)))
        else:
            out.append((name, ["" if x is None or (isinstance(x, float) and x != x) else str(x) for x in v.tolist()]))
    return out


_MAY_BE_EMPTY = ("sx", "sy", "sz")


def _unmasked(name: str, v: Any) -> np.ndarray:
    """An array of floats with a masked array's masked entries as NaN (never their hidden
    values) in the columns whose cells may be empty (``sx, sy, sz``, read as empty cells);
    elsewhere a masked entry is refused by its row, as masked."""
    if np.ma.isMaskedArray(v):
        if v.dtype.kind not in "biuf":
            raise TwincalError(f"column {name}: a masked array of {v.dtype} is not supported; pass plain values")
        mask = np.ma.getmaskarray(v)
        if mask.any() and name.strip().lower() not in _MAY_BE_EMPTY:
            row = int(np.argwhere(mask)[0][0])
            raise TwincalError(f"column {name}: row {row + 1} is masked; a value is required there (pass it, or drop the row)")
        return np.ma.filled(v.astype(np.float64), np.nan)
    try:
        return np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise TwincalError(f"{name}: expected numbers, got {np.asarray(v).dtype}") from None


def _truth_text(truth: Any) -> Optional[str]:
    """The truth as JSON text: the dict ``generate`` returns, its text, or a truth.json path."""
    if truth is None:
        return None
    if isinstance(truth, dict):
        return json.dumps(truth)
    if isinstance(truth, os.PathLike) or (isinstance(truth, str) and not truth.lstrip().startswith("{")):
        path = os.fspath(truth)
        try:
            with open(path) as f:
                return f.read()
        except OSError as e:
            raise TwincalError(f"truth: cannot read {path}: {e.strerror}") from None
    if isinstance(truth, str):
        return truth
    raise TwincalError(f"truth must be the dict generate returns, its JSON text or a truth.json path, got {type(truth).__name__}")


def _mapping(columns: Sequence[tuple[str, Any]]) -> dict[str, np.ndarray]:
    return {name: (v if isinstance(v, np.ndarray) else np.array(v, dtype=str)) for name, v in columns}


def _frame(data: dict[str, np.ndarray], as_frame: bool) -> Any:
    if not as_frame:
        return data
    import pandas as pd  # optional: only for as_frame=True

    return pd.DataFrame(data)


def generate(
    scenario: Optional[Union[str, os.PathLike]] = None,
    seed: Optional[int] = None,
    *,
    poses: Optional[Union[str, os.PathLike]] = None,
    as_frame: bool = False,
    progress: Progress = None,
) -> tuple[Any, dict]:
    """Simulate a scenario (TOML path; None: the embedded IRB 120 default), as ``twincal generate``;
    with ``poses`` (a pose list as :func:`plan` writes it, q1..qN in degrees) the twin measures
    those poses in their order, none held out, as ``generate --poses``.

    Returns ``(data, truth)``: the dataset's columns (a dict of numpy arrays, or a pandas
    DataFrame with ``as_frame=True``), equal value for value to the ``dataset.csv`` that
    ``twincal generate`` writes, and its ``truth.json`` as a dict.
    """
    columns, truth = _native.generate(None if scenario is None else os.fspath(scenario), _seed(seed), progress, None if poses is None else os.fspath(poses))
    return _frame(_mapping(columns), as_frame), json.loads(truth)


def read(data: Data, *, as_frame: bool = False, **options: Any) -> Any:
    """A dataset read and checked as ``twincal calibrate --data`` reads it (options: ``angles``,
    ``measurement``, ``euler``); its columns, angles in degrees."""
    return _frame(_mapping(_native.read(_columns(data), _options(options))), as_frame)


def to_csv(data: Data, angles: str = "auto") -> str:
    """The ``dataset.csv`` text of a dataset (what ``generate`` writes, what ``calibrate`` reads)."""
    return _native.to_csv(_columns(data), angles)


class Result:
    """A calibrated model: what ``twincal calibrate`` writes to result.json, and its use."""

    def __init__(self, native: Any) -> None:
        self._native = native
        self._dict: dict = json.loads(native.to_json())

    def to_json(self) -> str:
        """result.json's text: byte for byte what ``twincal calibrate --out`` writes."""
        return self._native.to_json()

    def as_dict(self) -> dict:
        """result.json as a dict."""
        return json.loads(self.to_json())

    @property
    def parameters(self) -> list[dict]:
        """Every parameter: name, unit, nominal, value, std_uncertainty, fixed (and the truth
        comparison on a twin)."""
        return [dict(p) for p in self._dict["parameters"]]

    @property
    def values(self) -> dict[str, float]:
        """Parameter values by name (mm for lengths, degrees for angles)."""
        return {p["name"]: p["value"] for p in self._dict["parameters"]}

    @property
    def uncertainties(self) -> dict[str, Optional[float]]:
        """Standard uncertainties by name (None for a fixed parameter)."""
        return {p["name"]: p["std_uncertainty"] for p in self._dict["parameters"]}

    @property
    def metrics(self) -> dict:
        """Residual statistics before and after, on training and test rows (mm)."""
        return dict(self._dict["evaluation"]["metrics"])

    @property
    def setup(self) -> Optional[dict]:
        """The instrument's stations and the target's mounts where there were several: each one's
        rows and its shift and turn from the first (``None`` for one of each)."""
        return self._dict.get("setup")

    @property
    def verdict(self) -> Optional[dict]:
        """The verdict against max_test_rmse_mm / max_test_max_mm, when given."""
        return self._dict.get("verdict")

    @property
    def warnings(self) -> list[str]:
        return list(self._native.warnings)

    def predict(self, data: Union[np.ndarray, Data], *, angles: str = "auto", euler: str = "XYZ", register_rows: int = 12) -> np.ndarray:
        """Readings the model predicts, in mm (as ``twincal predict``).

        ``data``: an (n, N) array of joint angles in degrees, or a dataset (mapping or path) with
        ``q1..qN`` and whatever else the model reads (``temp``, ``t``, ``station``, ``mount``).
        Returns shape (n,) for a cable length, (n, 3) for a tracker's point, (n, 6) for a pose
        (x, y, z mm; rx, ry, rz in degrees, ``euler`` convention). A station (or mount) the model
        was not calibrated at is registered on its first ``register_rows`` rows (a warning says
        which); 0 refuses it.
        """
        if isinstance(data, np.ndarray) or (isinstance(data, (list, tuple)) and not isinstance(data, str)):
            q = np.atleast_2d(_unmasked("q", data))
            if q.ndim != 2:
                raise TwincalError(f"joint angles must be an (n, N) array in degrees, got shape {q.shape}")
            data = {f"q{j + 1}": q[:, j] for j in range(q.shape[1])}
        if isinstance(register_rows, bool) or not isinstance(register_rows, (int, np.integer)) or register_rows < 0:
            raise TwincalError(f"register_rows must be a whole number of rows >= 0, got {register_rows!r}")
        values, warning = self._native.predict(_columns(data), angles, euler, int(register_rows))
        if warning:
            import warnings

            warnings.warn(warning, stacklevel=2)
        return values[:, 0] if values.shape[1] == 1 else values

    def ik(
        self,
        targets: np.ndarray,
        *,
        jacobian: Optional[str] = None,
        tol_mm: float = 0.01,
        seed: int = 0,
        tol_deg: float = 0.001,
        euler: str = "XYZ",
    ) -> dict:
        """Inverse kinematics for target points (n, 3), mm in the robot's base frame, as
        ``twincal ik --targets``: ``{"q_deg", "status", "iterations", "residual_mm"}`` for one
        Jacobian (analytic, neural, hybrid; default: the command line's, hybrid), or a dict of
        them by label for ``"all"``. Pose targets (n, 6: x, y, z in mm, rx, ry, rz in degrees
        in the convention ``euler``) get every solution of the calibrated arm, one entry each:
        ``{"target" (0-based), "q_deg", "status", "residual_mm", "residual_deg",
        "conditioning_mm_per_rad"}``."""
        t = np.ascontiguousarray(np.atleast_2d(_unmasked("targets", targets)))
        if t.ndim == 2 and t.shape[1] == 6:
            runs = {
                label: {
                    "target": np.array(target, dtype=int),
                    "q_deg": q,
                    "status": np.array(status, dtype=str),
                    "residual_mm": res_mm,
                    "residual_deg": res_deg,
                    "conditioning_mm_per_rad": cond,
                }
                for label, target, q, status, res_mm, res_deg, cond in self._native.ik_poses(t, euler, jacobian, tol_mm, tol_deg)
            }
            return runs if len(runs) > 1 else next(iter(runs.values()))
        if t.ndim != 2 or t.shape[1] != 3:
            raise TwincalError(f"targets must be an (n, 3) array of x, y, z in mm (or one point of 3), or (n, 6) poses with rx, ry, rz in degrees, got shape {t.shape}")
        runs = {
            label: {"q_deg": q, "status": np.array(status, dtype=str), "iterations": np.array(iters), "residual_mm": res}
            for label, q, status, iters, res in self._native.ik(t, jacobian, tol_mm, _seed(seed))
        }
        return runs if len(runs) > 1 else next(iter(runs.values()))

    def save(self, out: Union[str, os.PathLike], *, urdf=None, rrd=None, report=None, scenario_out=None) -> None:
        """Write what ``twincal calibrate`` writes: result.json at ``out``, and the calibrated URDF,
        Rerun recording, HTML report and identified twin (scenario + URDF) where given; all
        together or none."""
        f = lambda p: None if p is None else os.fspath(p)  # noqa: E731
        self._native.save(os.fspath(out), f(urdf), f(rrd), f(report), f(scenario_out))

    def __repr__(self) -> str:
        m = self._dict["evaluation"]["metrics"]
        test = m.get("test_after")
        return (
            f"<twincal.Result {self._dict['provenance']['method']} / {self._dict['provenance']['model_name']}: train RMSE {m['train_after']['rmse']:.4f} mm"
            + (f", test RMSE {test['rmse']:.4f} mm" if test else "")
            + ">"
        )


def calibrate(
    data: Data,
    method: str = "lm",
    *,
    model: Optional[str] = None,
    effects: Optional[Iterable[str]] = None,
    truth: Optional[Union[dict, str, os.PathLike]] = None,
    progress: Progress = None,
    **options: Any,
) -> Result:
    """Calibrate a model on measured data, as ``twincal calibrate``.

    ``method``: lm, ekf, pf, pso, rbf, dsade-gkan, pso-ekf-awnn (and their ablations); ``model``:
    irb120 (default), a .urdf path or generic (no nominal: the axes found from the data); ``effects``: e.g. ``["compliance:2", "backlash"]``.
    Any other ``calibrate`` option by name: ``test_fraction``, ``seed``, ``params``, ``effort``,
    ``outliers``, ``loss``, ``angles``, ``measurement``, ``euler``, ``payload_kg``, ... ``truth``:
    the twin's truth (the dict ``generate`` returns, its JSON text, or a truth.json path) for
    in-memory data; a dataset folder finds its own truth.json. Outputs are written by :meth:`Result.save`.
    """
    _no_outputs("calibrate", options, "Result.save()")
    opts = {"method": method, "model": model, "effects": _names(effects, "effects"), **options}
    return Result(_native.calibrate(_columns(data), _options(opts), _truth_text(truth), progress))


def load_result(path: Union[str, os.PathLike]) -> Result:
    """A result.json written by ``twincal calibrate`` (or ``diagnose --result``)."""
    return Result(_native.load_result(os.fspath(path)))


class Diagnosis:
    """What ``twincal diagnose`` found: the report (report.json) and the extended model."""

    def __init__(self, native: Any) -> None:
        self._native = native
        self.report: dict = json.loads(native.to_json())
        self.result: Result = Result(native.result())

    def to_json(self) -> str:
        """report.json's text: byte for byte what ``twincal diagnose --out`` writes."""
        return self._native.to_json()

    @property
    def effects(self) -> str:
        """The effects kept, as ``calibrate --effects`` takes them ("" for none)."""
        return self.report["effects_option"]

    def save(self, out, result, *, rrd=None, report=None, scenario_out=None) -> None:
        """Write what ``twincal diagnose`` writes: the report at ``out``, the model at ``result``,
        and the recording, HTML report and identified twin where given; all together or none."""
        f = lambda p: None if p is None else os.fspath(p)  # noqa: E731
        self._native.save(os.fspath(out), os.fspath(result), f(rrd), f(report), f(scenario_out))

    def __repr__(self) -> str:
        return f"<twincal.Diagnosis effects={self.effects!r} held-out RMSE {self.report['final_heldout_rmse_mm']:.4f} mm>"


def diagnose(data: Data, *, progress: Progress = None, **options: Any) -> Diagnosis:
    """What the geometric model gets wrong, which effect causes it, how big it is and how much
    better the extended model predicts unseen rows, as ``twincal diagnose`` (options: ``model``,
    ``candidates``, ``folds``, ``alpha``, ``seed``, ``test_fraction``, ...). ``progress`` hears
    each step as ``(line, 0, 0)``."""
    _no_outputs("diagnose", options, "Diagnosis.save()")
    # A string is the command line's comma-separated list, as for effects= and methods=.
    if "candidates" in options:
        options["candidates"] = _names(options["candidates"], "candidates")
    return Diagnosis(_native.diagnose(_columns(data), _options(options), progress))


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    out: dict[str, np.ndarray] = {}
    for k, name in enumerate(header):
        cells = [r[k] if k < len(r) else "" for r in body]
        try:
            out[name] = np.array([float(c) if c != "" else np.nan for c in cells])
        except ValueError:
            out[name] = np.array(cells, dtype=str)
    return out


def _staged(data: Data, tmp: str, angles: Optional[str]) -> str:
    """A path for the command line: the path itself, or in-memory data written as a CSV."""
    if isinstance(data, (str, os.PathLike)):
        return os.fspath(data)
    p = os.path.join(tmp, "data.csv")
    with open(p, "w") as f:
        f.write(_native.to_csv(_columns(data), angles or "auto"))
    return p


def replay(data: Data, scenario: Union[str, os.PathLike], *, progress: Progress = None, **options: Any) -> dict:
    """Drive the twin of ``scenario`` through a measured acquisition, as ``twincal replay``: the
    summary (replay.json) as a dict, with its per-row table (replay.csv) under ``"rows"`` as
    arrays. Options: ``test_fraction``, ``split_by``, ``seed``, ``angles``, ``measurement``,
    ``euler``."""
    _no_outputs("replay", options, "the command line's replay --out")
    if "seed" in options:
        options["seed"] = _seed(options["seed"])
    with tempfile.TemporaryDirectory(prefix="twincal-") as tmp:
        out = os.path.join(tmp, "replay")
        text = _native.replay(_staged(data, tmp, options.get("angles")), os.fspath(scenario), _options(options), out, progress)
        summary = json.loads(text)
        summary["rows"] = _read_csv(Path(out) / "replay.csv")
    return summary


def compare(
    data: Data,
    methods: Sequence[str] = ("lm", "ekf", "pf", "pso", "rbf"),
    seeds: int = 30,
    *,
    shard: Optional[str] = None,
    shard_out=None,
    progress: Progress = None,
    **options: Any,
) -> Optional[dict]:
    """Compare methods over seeds, as ``twincal compare``: the tables (what ``--out`` writes) as a
    dict. With ``shard="i/N"`` and
    ``shard_out=PATH`` it runs that shard's items only, appending them to the partial file, and
    returns None: join the parts with :func:`reduce`."""
    _no_outputs("compare", options, "the command line's compare --out")
    request = _options({**options, "methods": _names(methods, "methods"), "seeds": seeds})
    with tempfile.TemporaryDirectory(prefix="twincal-") as tmp:
        staged = _staged(data, tmp, options.get("angles"))
        if shard is not None or shard_out is not None:
            part = os.fspath(shard_out) if shard_out is not None else None
            _native.compare(staged, request, None, shard, part, progress)
            return None
        out = os.path.join(tmp, "compare.json")
        _native.compare(staged, request, out, None, None, progress)
        with open(out) as f:
            return json.load(f)


def reduce(parts: Sequence[Union[str, os.PathLike]], out: Optional[Union[str, os.PathLike]] = None) -> dict:
    """Join the partial files of sharded compares, as ``twincal reduce``: every item exactly once
    (duplicates dropped, missing ones named in the error), then the tables as one compare's
    (written to ``out`` too when given)."""
    with tempfile.TemporaryDirectory(prefix="twincal-") as tmp:
        target = os.fspath(out) if out is not None else os.path.join(tmp, "compare.json")
        _native.reduce(_paths(parts, "parts"), target)
        with open(target) as f:
            return json.load(f)


def export(
    model: Union[str, os.PathLike],
    out: Union[str, os.PathLike],
    *,
    format: Optional[str] = None,
    robot: Optional[Union[str, os.PathLike]] = None,
    against: Optional[Union[str, os.PathLike]] = None,
) -> dict:
    """Write the calibrated model ``model`` (a result.json path) for a controller or driver, as
    ``twincal export``: ``format`` urdf, frames, dh, mdh or ur-yaml (default: from ``out``'s
    extension), ``robot`` the nominal robot (irb120 or a URDF path) for a URDF's inertials and
    limits. The file is read back and checked before it is written. Returns the summary: the
    format, the file, what it does not carry (``warnings``) and the read-back difference
    (``round_trip_m``); with ``against`` (another file of the format: the maker's calibration),
    ``against`` joint by joint (each frame in its parent's: ``position_mm``, ``rotation_deg``)."""
    if against is not None and not isinstance(against, (str, os.PathLike)):
        raise TwincalError(f"against must be a path, got {type(against).__name__}")
    if format is not None and not isinstance(format, str):
        raise TwincalError(f"format must be a string, got {type(format).__name__}")
    if robot is not None:
        if not isinstance(robot, (str, os.PathLike)):
            raise TwincalError(f"robot must be irb120 or a URDF path (a string or os.PathLike), got {type(robot).__name__}")
        robot = os.fspath(robot)
    against = None if against is None else os.path.abspath(os.fspath(against))
    text = _native.export(os.fspath(model), os.fspath(out), _options({"format": format, "robot": robot, "against": against}))
    return json.loads(text)


def _arm(model: Any, robot: Any) -> dict:
    """The arm a tool routine reads the flange of: a calibration result or a nominal robot."""
    if model is not None and not isinstance(model, (str, os.PathLike)):
        raise TwincalError(f"model must be a result.json path, got {type(model).__name__}")
    if not isinstance(robot, (str, os.PathLike)):
        raise TwincalError(f"robot must be irb120 or a URDF path (a string or os.PathLike), got {type(robot).__name__}")
    name = os.fspath(robot)
    return {
        "model": None if model is None else os.path.abspath(os.fspath(model)),
        "robot": name if name == "irb120" else os.path.abspath(name),
    }


def tcp(
    data: Union[str, os.PathLike],
    *,
    model: Optional[Union[str, os.PathLike]] = None,
    robot: Union[str, os.PathLike] = "irb120",
    angles: Optional[str] = None,
    orientation: bool = False,
    out: Optional[Union[str, os.PathLike]] = None,
) -> dict:
    """The N-point TCP, as ``twincal tcp``: the tool's tip on the flange from four or more
    configurations (joint angles, ``data``) holding it at one fixed point (a ``socket`` column
    names several), on ``model`` (a result.json) or the nominal ``robot``. Returns the fit: the
    tool point and its standard uncertainty (mm), the fixed points, the tips' scatter; with
    ``orientation`` the last two rows are the z and x elongators and the tool's orientation on
    the flange is returned too. ``out`` writes the same as JSON."""
    if not isinstance(orientation, bool):
        raise TwincalError(f"orientation must be True or False, got {type(orientation).__name__}")
    options = {"data": os.path.abspath(os.fspath(data)), "angles": angles, "orientation": orientation, **_arm(model, robot)}
    options["out"] = None if out is None else os.path.abspath(os.fspath(out))
    return json.loads(_native.tcp(_options(options)))


def user_frame(
    data: Union[str, os.PathLike],
    tcp: Union[str, os.PathLike],
    *,
    model: Optional[Union[str, os.PathLike]] = None,
    robot: Union[str, os.PathLike] = "irb120",
    angles: Optional[str] = None,
    out: Optional[Union[str, os.PathLike]] = None,
) -> dict:
    """The 3-point user frame, as ``twincal user-frame``: the tip at the frame's origin, at a
    point on its +x axis and at a point on its xy plane (three rows of joint angles, ``data``, in
    that order), the tool from ``tcp`` (a tcp result file). Returns the frame: origin (mm),
    quaternion, roll-pitch-yaw (degrees) and how well its axes are known."""
    options = {"data": os.path.abspath(os.fspath(data)), "tcp": os.path.abspath(os.fspath(tcp)), "angles": angles, **_arm(model, robot)}
    options["out"] = None if out is None else os.path.abspath(os.fspath(out))
    return json.loads(_native.user_frame(_options(options)))


def compensate(
    model: Union[str, os.PathLike],
    targets: Optional[Union[str, os.PathLike]] = None,
    out: Union[str, os.PathLike] = "commands.csv",
    *,
    program: Optional[Union[str, os.PathLike, Sequence[Union[str, os.PathLike]]]] = None,
    frames: Optional[Union[str, os.PathLike, Sequence[Union[str, os.PathLike]]]] = None,
    robot: Optional[Union[str, os.PathLike]] = None,
    joint_targets: bool = False,
    leave: Optional[Sequence[str]] = None,
    start_joints_deg: Optional[Sequence[float]] = None,
    filtered_dir: Union[str, os.PathLike] = "filtered",
    report: Union[str, os.PathLike] = "filter_report.csv",
    payload_kg: Optional[float] = None,
    payload_com_mm: Optional[Sequence[float]] = None,
    tol_mm: float = 0.001,
    tol_deg: float = 0.001,
    euler: str = "XYZ",
) -> dict:
    """The joint commands that make the calibrated arm reach a program's targets, as ``twincal
    compensate``: ``model`` a result.json path, ``targets`` a CSV of x, y, z (mm, base frame),
    with rx, ry, rz (degrees, the tool's orientation in the Euler convention ``euler``) for
    poses, or q1..qN (degrees, taught on the nominal model), the payload the program runs with;
    writes the commands CSV to ``out`` and returns the summary (per target the command in
    radians, status, predicted residual, uncompensated error and filtered Cartesian target; for
    poses also the orientation residuals in degrees).

    With ``program`` (a RAPID .mod/.prg, a KRL .src with its .dat, a URScript .script; a path
    or a list of paths) instead of ``targets``, the program is filtered: its targets compensated
    in place, with the frames it declares or ``frames`` declare (a module with tooldata /
    wobjdata, KUKA's $config.dat, a script with set_tcp), the controller's base and tool0 from
    ``robot`` (irb120 or a URDF path); the copies go to ``filtered_dir``, a line per target to
    ``report``, and the summary's ``program`` holds each target's outcome and the run-time
    motions left as written."""

    def paths(v: Any, name: str) -> Any:
        if v is None:
            return None
        if isinstance(v, (str, os.PathLike)):
            v = [v]
        if not isinstance(v, (list, tuple)) or not all(isinstance(p, (str, os.PathLike)) for p in v):
            raise TwincalError(f"{name} must be a path or a list of paths, got {type(v).__name__}")
        return [os.path.abspath(os.fspath(p)) for p in v]

    if robot is not None and not isinstance(robot, (str, os.PathLike)):
        raise TwincalError(f"robot must be irb120 or a URDF path (a string or os.PathLike), got {type(robot).__name__}")
    robot_name = None if robot is None else os.fspath(robot)
    if robot_name not in (None, "irb120"):
        robot_name = os.path.abspath(robot_name)
    if isinstance(leave, str):
        leave = [leave]
    options = _options(
        {
            "model": os.path.abspath(os.fspath(model)),
            "targets": None if targets is None else os.path.abspath(os.fspath(targets)),
            "program": paths(program, "program"),
            "frames": paths(frames, "frames"),
            "robot": robot_name,
            "joint_targets": joint_targets,
            "leave": leave,
            "start_joints_deg": _numbers(start_joints_deg, "start_joints_deg"),
            "filtered_dir": os.fspath(filtered_dir),
            "report": os.fspath(report),
            "payload_kg": payload_kg,
            "payload_com_mm": _numbers(payload_com_mm, "payload_com_mm", 3),
            "tol_mm": tol_mm,
            "tol_deg": tol_deg,
            "euler": euler,
            "out": os.fspath(out),
        }
    )
    return json.loads(_native.compensate(options))


def plan(
    out: Union[str, os.PathLike],
    *,
    scenario: Optional[Union[str, os.PathLike]] = None,
    poses: int = 30,
    candidates: int = 10_000,
    criterion: str = "i",
    params: Optional[str] = None,
    effects: Any = None,
    payload_kg: Optional[float] = None,
    payload_com_mm: Optional[Sequence[float]] = None,
    seed: Optional[int] = None,
    rrd: Optional[Union[str, os.PathLike]] = None,
    model: Optional[Union[str, os.PathLike]] = None,
    payloads: Optional[Sequence[float]] = None,
    program_format: Optional[str] = None,
    hold_s: float = 2.0,
) -> dict:
    """Measurement poses worth measuring, as ``twincal plan``: feasible candidates of the scenario's
    arm, instrument and cell (None: the embedded one), ``poses`` of them chosen by ``criterion``
    (``i``, ``d``, ``min-sv``, ``noise``, ``a``) for the ``params`` parametrisation (None:
    hayati) and the ``effects`` the calibration will fit (``"compliance"``, under the payload
    mounted: the scenario's unless ``payload_kg`` says), or for the next calibration of the
    calibrated arm ``model`` (a result.json: its parametrisation and effect blocks, at its
    calibrated values), ordered into a short tour; with ``payloads`` (kg, e.g. ``[0, 2, 5]``) each
    pose also gets the payload to measure it with. Writes ``poses.csv`` (what :func:`generate` takes as ``poses``) and ``plan.json``
    into the folder ``out`` (and a recording at ``rrd``); with ``program_format`` (``rapid``,
    ``krl``, ``urscript``) also the tour as a measurement program the controller runs (``hold_s``
    seconds still at each pose, then a wait until it is measured); returns plan.json as a dict."""
    options = _options(
        {
            "scenario": None if scenario is None else os.fspath(scenario),
            "poses": poses,
            "candidates": candidates,
            "criterion": criterion,
            "params": params,
            "effects": _names(effects, "effects"),
            "payload_kg": payload_kg,
            "payload_com_mm": _numbers(payload_com_mm, "payload_com_mm", 3),
            "seed": _seed(seed),
            "rrd": None if rrd is None else os.fspath(rrd),
            "model": None if model is None else os.fspath(model),
            "payloads": _numbers(payloads, "payloads"),
            "program_format": program_format,
            "hold_s": hold_s,
        }
    )
    return json.loads(_native.plan(os.fspath(out), options))


def controller_data(
    model: Union[str, os.PathLike],
    out: Union[str, os.PathLike],
    *,
    format: str,
    tool_mass_kg: Optional[float] = None,
    full: Optional[Union[str, os.PathLike]] = None,
    robot: Optional[Union[str, os.PathLike]] = None,
) -> dict:
    """Write a ``calibrate(..., controller_subset=True)`` result (a result.json path) as the
    controller's own data, as ``twincal controller-data``: ``format`` ``rapid`` (a .mod of
    tooldata, wobjdata and the joint offsets), ``krl`` (a .dat of FRAMEs for TOOL_DATA and
    BASE_DATA) or ``urscript`` (a .script); ``tool_mass_kg`` where the calibration states no
    payload (RAPID's tooldata needs a mass); ``full`` a full calibration of the same rows, whose
    held-out RMSE is reported beside the subset's; ``robot`` (irb120 or a URDF path) whose
    ``tool0`` and ``base`` the data are written in. Returns the summary: the file, the joint
    offsets (degrees), the tool point (mm) and ``held_out`` (nominal, subset and full RMSE)."""
    if robot is not None and not isinstance(robot, (str, os.PathLike)):
        raise TwincalError(f"robot must be irb120 or a URDF path (a string or os.PathLike), got {type(robot).__name__}")
    robot_name = None if robot is None else os.fspath(robot)
    if robot_name not in (None, "irb120"):
        robot_name = os.path.abspath(robot_name)
    options = _options(
        {
            "model": os.path.abspath(os.fspath(model)),
            "format": format,
            "tool_mass_kg": tool_mass_kg,
            "full": None if full is None else os.path.abspath(os.fspath(full)),
            "robot": robot_name,
            "out": os.fspath(out),
        }
    )
    return json.loads(_native.controller_data(options))


def program(
    poses: Union[str, os.PathLike],
    out: Union[str, os.PathLike],
    *,
    format: str,
    robot: Union[str, os.PathLike] = "irb120",
    name: str = "twincal_tour",
    hold_s: float = 2.0,
    speed_fraction: float = 0.2,
) -> dict:
    """Write the pose list ``poses`` (a poses.csv: ``q1..qN`` in degrees, optionally
    ``payload_kg``) as a measurement program for the controller, as ``twincal program``:
    ``format`` ``rapid`` (NAME.mod), ``krl`` (NAME.src and NAME.dat) or ``urscript``
    (NAME.script), into the folder ``out``; the poses must lie within ``robot``'s joint limits
    (irb120 or a URDF path). Returns the summary: the format, the files, the number of poses."""
    if not isinstance(robot, (str, os.PathLike)):
        raise TwincalError(f"robot must be irb120 or a URDF path (a string or os.PathLike), got {type(robot).__name__}")
    robot = os.fspath(robot)
    if robot != "irb120":
        robot = os.path.abspath(robot)
    options = _options(
        {
            "poses": os.path.abspath(os.fspath(poses)),
            "format": format,
            "robot": robot,
            "name": name,
            "hold_s": hold_s,
            "speed_fraction": speed_fraction,
            "out": os.fspath(out),
        }
    )
    return json.loads(_native.program(options))


def iso9283(data: Union[str, os.PathLike], models: Any, **options: Any) -> dict:
    """ISO 9283 pose accuracy (AP), repeatability (RP), distance accuracy (AD) and orientation
    error of the measured poses ``data`` (a path) against each model of ``models`` (a result.json
    path or a list of them: before and after), as ``twincal iso9283``; options: ``angles``,
    ``measurement``, ``euler``."""
    _no_outputs("iso9283", options, "the command line's iso9283 --out")
    return json.loads(_native.iso9283(os.fspath(data), _paths(models, "models"), _options(options)))


def cli(argv: Sequence[str]) -> None:
    """Run a ``twincal`` command line (``argv`` without the program name) with the installed
    ``twincal`` executable (``$TWINCAL_BIN``, else the one on ``PATH``; ``cargo install --path
    cli`` installs it): this package is the library's Python API and holds no command line.
    Raises :class:`TwincalError` where the executable fails, with its message."""
    exe = os.environ.get("TWINCAL_BIN") or shutil.which("twincal")
    if not exe:
        raise TwincalError("twincal.cli runs the twincal executable, which was not found: set TWINCAL_BIN or put twincal on PATH (cargo install --path cli)")
    proc = subprocess.Popen([exe, *[os.fspath(a) for a in argv]], stderr=subprocess.PIPE, text=True)
    try:
        _, err = proc.communicate()
    except KeyboardInterrupt:
        # Ctrl-C: the command stops as on a terminal (its staged outputs removed), then Python.
        proc.send_signal(signal.SIGINT)
        proc.wait()
        raise
    sys.stderr.write(err)
    if proc.returncode != 0:
        errors = [line[len("error: ") :] for line in err.splitlines() if line.startswith("error: ")]
        raise TwincalError(errors[-1] if errors else f"twincal exited with code {proc.returncode}")
