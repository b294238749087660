"""Tests of the Python package on the wheel (built and installed by .ci/run).

The command line they compare against is the `twincal` executable named by TWINCAL_BIN (.ci/run
points it at target/release/twincal); without it the tests that need it are skipped, saying so.
"""

import json
import os
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import twincal

ROOT = Path(__file__).resolve().parents[2]
BIN = os.environ.get("TWINCAL_BIN")


def run_cli(*args):
    """The command line: the executable TWINCAL_BIN names (the test is skipped without it)."""
    if not BIN:
        pytest.skip("TWINCAL_BIN not set: no twincal executable to compare against")
    p = subprocess.run([BIN, "--quiet", *[str(a) for a in args]], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr


def untimed(v):
    """A result without its measured times and its data's path: what must agree bit for bit."""
    if isinstance(v, dict):
        return {k: untimed(x) for k, x in v.items() if "second" not in k and k != "data"}
    if isinstance(v, list):
        return [untimed(x) for x in v]
    return v


@pytest.fixture(scope="module")
def embedded(tmp_path_factory):
    """The embedded scenario, by the command line and by the package."""
    d = tmp_path_factory.mktemp("cli") / "data"
    run_cli("generate", "--out", d)
    data, truth = twincal.generate()
    return d, data, truth


def q_matrix(data):
    n = sum(1 for k in data if k.startswith("q"))
    return np.stack([data[f"q{j + 1}"] for j in range(n)], axis=1)


def test_generate_agrees_with_the_command_line_bit_for_bit(embedded):
    d, data, truth = embedded
    assert twincal.to_csv(data) == (d / "dataset.csv").read_text()
    assert truth == json.loads((d / "truth.json").read_text())
    assert data["L"].dtype == np.float64 and data["L"].shape == (600,)
    assert set(np.unique(data["split"])) == {"train", "test"}
    again, _ = twincal.generate(seed=truth["seed"])
    assert all(np.array_equal(again[k], data[k]) for k in data), "same scenario and seed, same data"
    other, _ = twincal.generate(seed=truth["seed"] + 1)
    assert not np.array_equal(other["L"], data["L"])


def test_calibrate_agrees_with_the_command_line_bit_for_bit(embedded, tmp_path):
    d, data, truth = embedded
    run_cli("calibrate", "--data", d, "--out", tmp_path / "cli.json")
    cli = json.loads((tmp_path / "cli.json").read_text())
    for source in (data, d):
        r = twincal.calibrate(source, truth=truth if source is data else None)
        mine = json.loads(r.to_json())
        differ = sorted(k for k in set(cli) | set(mine) if cli.get(k) != mine.get(k))
        assert differ == ["provenance"], differ
        origin = sorted(k for k in set(cli["provenance"]) | set(mine["provenance"]) if cli["provenance"].get(k) != mine["provenance"].get(k))
        expected = ["data", "wall_time_s"] if source is data else ["wall_time_s"]
        assert origin == expected, origin
        assert mine["x"] == cli["x"] and mine["parameters"] == cli["parameters"] and mine["evaluation"]["truth_comparison"] == cli["evaluation"]["truth_comparison"]
    # save() writes what calibrate --out writes for this run.
    r.save(tmp_path / "py.json")
    assert (tmp_path / "py.json").read_text() == r.to_json()


def test_results_expose_parameters_metrics_and_predict(embedded):
    _, data, truth = embedded
    r = twincal.calibrate(data, truth=truth)
    assert len(r.parameters) == len(r.values) == len(r.uncertainties)
    free = [p for p in r.parameters if not p["fixed"]]
    assert free and all(p["std_uncertainty"] > 0 for p in free)
    # Predictions reproduce the residuals calibrate scored on the test rows.
    test = data["split"] == "test"
    pred = r.predict(q_matrix(data)[test])
    assert pred.shape == (test.sum(),)
    rmse = float(np.sqrt(np.mean((data["L"][test] - pred) ** 2)))
    assert abs(rmse - r.metrics["test_after"]["rmse"]) < 1e-9, (rmse, r.metrics["test_after"])
    # The same from a mapping with the rows' columns.
    pred2 = r.predict({k: v[test] for k, v in data.items()})
    assert np.array_equal(pred, pred2)



def test_a_saved_result_reads_back_and_predicts_the_same(embedded, tmp_path):
    _, data, truth = embedded
    r = twincal.calibrate(data, truth=truth)
    r.save(tmp_path / "r.json")
    back = twincal.load_result(tmp_path / "r.json")
    q = q_matrix(data)[:20]
    assert np.array_equal(back.predict(q), r.predict(q))
    assert back.values == r.values


def test_a_dataset_given_as_one_q_matrix_or_a_dataframe_is_the_same_dataset(embedded):
    _, data, _ = embedded
    cols = {"q": q_matrix(data), **{k: v for k, v in data.items() if not k.startswith("q")}}
    assert twincal.to_csv(cols) == twincal.to_csv(data)
    pd = pytest.importorskip("pandas", reason="pandas is optional; the DataFrame path is tested where it is installed")
    frame = pd.DataFrame(data)
    assert twincal.to_csv(frame) == twincal.to_csv(data)
    df, _ = twincal.generate(as_frame=True)
    assert list(df.columns) == list(data)


def test_ik_reaches_the_twins_true_tool_points(embedded):
    _, data, truth = embedded
    r = twincal.calibrate(data, truth=truth)
    targets = np.array([p["tool_mm"] for p in truth["poses"][:10]])
    sol = r.ik(targets)
    assert sol["q_deg"].shape == (10, 6)
    assert list(sol["status"]) == ["converged"] * 10
    assert np.all(sol["residual_mm"] <= 0.01)
    all_runs = r.ik(targets[:2], jacobian="all")
    assert set(all_runs) == {"calibrated/analytic", "calibrated/neural", "calibrated/hybrid"}


def test_ik_on_pose_targets_gives_the_command_lines_solutions(tmp_path):
    """Pose targets (n, 6) get every solution of the calibrated arm, the same as ``twincal ik``
    on the same poses; a pose with a NaN is refused by name."""
    d = tmp_path / "tracker"
    run_cli("generate", "--scenario", ROOT / "scenarios" / "irb120_tracker.toml", "--out", d)
    run_cli("calibrate", "--data", d, "--out", tmp_path / "r.json")
    poses = np.array([[400.0, 0.0, 500.0, 180.0, 0.0, 0.0], [450.0, 100.0, 450.0, 170.0, 10.0, 20.0], [300.0, -200.0, 600.0, 160.0, -20.0, 40.0]])
    (tmp_path / "poses.csv").write_text("x,y,z,rx,ry,rz\n" + "\n".join(",".join(repr(float(v)) for v in p) for p in poses) + "\n")
    run_cli("ik", "--model", tmp_path / "r.json", "--targets", tmp_path / "poses.csv", "--no-twin", "--out", tmp_path / "ik.csv")
    lines = (tmp_path / "ik.csv").read_text().splitlines()
    head = lines[0].split(",")
    rows = [dict(zip(head, l.split(","))) for l in lines[1:]]
    sol = twincal.load_result(tmp_path / "r.json").ik(poses)
    assert len(rows) == len(sol["status"]) >= 3
    assert [int(r["target"]) - 1 for r in rows] == list(sol["target"])
    assert [r["status"] for r in rows] == list(sol["status"])
    cli_q = np.array([[float(r[f"q{j}"]) for j in range(1, 7)] for r in rows])
    assert np.allclose(cli_q, sol["q_deg"], atol=1e-6)
    assert np.allclose([float(r["conditioning_mm_per_rad"]) for r in rows], sol["conditioning_mm_per_rad"], atol=1e-3)
    with pytest.raises(twincal.TwincalError, match="pose target 2 is not finite"):
        twincal.load_result(tmp_path / "r.json").ik(np.array([poses[0], [400.0, 0.0, np.nan, 180.0, 0.0, 0.0]]))


def test_bad_input_raises_the_command_lines_message(embedded):
    _, data, truth = embedded
    bad = dict(data)
    bad["L"] = data["L"].copy()
    bad["L"][3] = np.nan
    with pytest.raises(twincal.TwincalError, match=r"line 5, column L: NaN is not allowed"):
        twincal.calibrate(bad)
    with pytest.raises(twincal.TwincalError, match=r"missing required column\(s\) L"):
        twincal.calibrate({k: v for k, v in data.items() if k != "L"})
    with pytest.raises(twincal.TwincalError, match="unknown method 'nope'"):
        twincal.calibrate(data, method="nope")
    with pytest.raises(twincal.TwincalError, match="unknown option 'bogus'"):
        twincal.calibrate(data, bogus=3)
    # A value of the wrong type is named with its option, as is a NaN.
    with pytest.raises(twincal.TwincalError, match="option 'test_fraction'.*invalid type"):
        twincal.calibrate(data, test_fraction="a fifth")
    with pytest.raises(twincal.TwincalError, match="option 'effort' must be a finite number"):
        twincal.calibrate(data, effort=float("nan"))
    with pytest.raises(twincal.TwincalError, match="option 'folds'.*invalid type"):
        twincal.diagnose(data, folds=2.5)
    # candidates= reads a string as the command line's list, as effects= does: an unknown one
    # is then named, not refused as "expected a sequence".
    with pytest.raises(twincal.TwincalError, match="unknown effect 'stiction'"):
        twincal.diagnose(data, candidates="backlash,stiction")
    with pytest.raises(twincal.TwincalError, match=r"--test-fraction must be in \[0, 1\)"):
        twincal.calibrate(data, test_fraction=1.5)
    with pytest.raises(twincal.TwincalError, match="does not belong to"):
        twincal.calibrate({**data, "L": data["L"] + 0.001}, truth=truth)
    with pytest.raises(twincal.TwincalError, match="expected a 1-D array"):
        twincal.calibrate({**data, "L": np.ones((600, 2))})
    with pytest.raises(twincal.TwincalError, match="column L has 5 values"):
        twincal.calibrate({**data, "L": data["L"][:5]})
    with pytest.raises(TypeError, match="Result.save"):
        twincal.calibrate(data, out="result.json")
    with pytest.raises(twincal.TwincalError, match="targets must be an"):
        twincal.calibrate(data).ik(np.zeros((2, 2)))


def test_every_front_door_applies_the_command_lines_checks(embedded, tmp_path):
    _, data, _ = embedded
    # Seeds: the command line's 0..=2**64-1, not Python's OverflowError.
    for seed in (-1, 2**70):
        with pytest.raises(twincal.TwincalError, match=f"seed must be in 0..=18446744073709551615, got {seed}"):
            twincal.generate(seed=seed)
    with pytest.raises(twincal.TwincalError, match="seed must be an integer"):
        twincal.generate(seed=1.5)
    r = twincal.calibrate(data)
    with pytest.raises(twincal.TwincalError, match="seed must be in"):
        r.ik(np.array([[400.0, 0.0, 500.0]]), seed=-1)
    # ik's tolerance: the same bound as `twincal ik --tol-mm` (10 mm), not a looser one.
    with pytest.raises(twincal.TwincalError, match=r"tol_mm must be in \(0, 10\] mm, got 500"):
        r.ik(np.array([[400.0, 0.0, 500.0]]), tol_mm=500)
    # A string where a list is expected is the command line's comma list, not its letters.
    small = {k: v[:120] for k, v in data.items() if k != "split"}
    one = twincal.compare(small, methods="lm", seeds=1, test_fraction=0.2)
    assert untimed(one) == untimed(twincal.compare(small, methods=["lm"], seeds=1, test_fraction=0.2))
    with pytest.raises(twincal.TwincalError, match=r"unknown method 'nope' \(expected one of lm, "):
        twincal.compare(small, methods="lm,nope", seeds=1, test_fraction=0.2)
    with pytest.raises(twincal.TwincalError, match="effects must be strings"):
        twincal.calibrate(small, effects=[3])
    # One path where a list of parts is expected.
    part = tmp_path / "p.jsonl"
    twincal.compare(small, methods="lm", seeds=1, test_fraction=0.2, shard="0/1", shard_out=part)
    assert untimed(twincal.reduce(str(part))) == untimed(one)


def test_long_work_releases_the_gil_and_reports_progress(embedded):
    _, data, _ = embedded
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    t0 = time.perf_counter()
    twincal.calibrate(data, method="pso")
    t1 = time.perf_counter()
    stop.set()
    t.join()
    inside = [x for x in ticks if t0 <= x <= t1]
    assert t1 - t0 > 0.2, "the calibration must take long enough to tell"
    gaps = np.diff(inside)
    assert len(inside) > 50 and gaps.max() < 0.1, f"{len(inside)} ticks in {t1 - t0:.2f} s, longest gap {gaps.max():.3f} s"

    seen = []
    twincal.generate(progress=lambda what, done, total: seen.append((what, done, total)))
    assert seen and seen[-1][1] == seen[-1][2] == 600
    assert all(a[1] <= b[1] for a, b in zip(seen, seen[1:]))

    def boom(*_):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        twincal.calibrate(data, progress=boom)


HIDDEN = "[effects.compliance]\nstiffness_nm_per_rad = [1.0e9, 1.0e5, 1.0e9, 1.0e9, 1.0e9, 1.0e9]\n\n[sensor]"


def test_diagnose_names_a_hidden_compliance_and_agrees_with_the_command_line(tmp_path):
    text = (ROOT / "scenarios/irb120_geometric.toml").read_text().replace("[sensor]", HIDDEN, 1)
    scenario = tmp_path / "hidden.toml"
    scenario.write_text(text)
    data, _ = twincal.generate(scenario, seed=1)
    lines = []
    dg = twincal.diagnose(data, progress=lambda line, *_: lines.append(line))
    assert dg.report["verdict"] == "compliance[j2]", dg.report["causes"]
    assert dg.effects == "compliance:2"
    assert lines, "progress heard the diagnosis's steps"
    # The extended model predicts; the same run by the command line writes the same report.
    assert dg.result.predict(q_matrix(data)[:2]).shape == (2,)
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "dataset.csv").write_text(twincal.to_csv(data))
    run_cli("diagnose", "--data", tmp_path / "d", "--out", tmp_path / "r.json", "--result", tmp_path / "m.json")
    cli = json.loads((tmp_path / "r.json").read_text())
    mine = json.loads(dg.to_json())
    assert untimed(mine) == untimed(cli)
    assert mine["data"] != cli["data"] and mine["seconds"] != cli["seconds"], "the comparison above has left something out"
    dg.save(tmp_path / "r2.json", tmp_path / "m2.json")
    assert (tmp_path / "r2.json").read_text() == dg.to_json()


def test_replay_of_a_twins_own_data(embedded):
    d, _, _ = embedded
    s = twincal.replay(d, ROOT / "scenarios/irb120_evo_nph.toml", test_fraction=0.2)
    rows = s["rows"]
    assert len(rows["L"]) == 600
    assert s["judged"]["residual"]["rmse"] < 1.0


def test_sharded_compare_reduces_to_the_single_run(embedded, tmp_path):
    d, data, _ = embedded
    whole = twincal.compare(data, methods=["lm", "ekf"], seeds=3)
    parts = [tmp_path / f"part{i}.jsonl" for i in range(2)]
    for i, p in enumerate(parts):
        assert twincal.compare(data, methods=["lm", "ekf"], seeds=3, shard=f"{i}/2", shard_out=p) is None
    joined = twincal.reduce(parts)
    assert untimed(joined) == untimed(whole)


def test_the_dask_example_runs_shards_on_a_local_cluster(tmp_path):
    pytest.importorskip("dask.distributed", reason="the Dask example needs dask[distributed] (.ci/run installs it)")
    import importlib.util

    spec = importlib.util.spec_from_file_location("dask_compare", ROOT / "python/examples/dask_compare.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    parts = tmp_path / "parts"
    tables = example.main(["--methods", "lm", "--seeds", "4", "--shards", "3", "--workers", "2", "--parts", str(parts)])
    assert sorted((r["method"], r["seed"]) for r in tables["runs"]) == [("lm", s) for s in range(4)]
    # The same comparison in one process gives the same tables.
    whole = twincal.compare(parts / "dataset", methods=["lm"], seeds=4)
    assert untimed(tables) == untimed(whole)
    # A shard run again finds its items done and adds none: the parts still reduce.
    example.run_shard(str(parts / "dataset"), ["lm"], 4, 0, 3, str(parts / "part-0-of-3.jsonl"))
    assert untimed(twincal.reduce(sorted(parts.glob("part-*.jsonl")))) == untimed(whole)


def test_the_calibrate_example_halves_the_held_out_error_and_recovers_the_truth(capsys):
    import importlib.util

    spec = importlib.util.spec_from_file_location("calibrate_example", ROOT / "python/examples/calibrate.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    got = example.main(7)
    assert got["after_mm"] < 0.5 * got["before_mm"]
    # The embedded scenario carries compliance, backlash and thermal drift the geometric model
    # does not: most, not all, of its identifiable parameters come out within 3 sigma.
    assert got["within_3_sigma"] >= 0.8 * got["identifiable"]
    assert "held-out RMSE" in capsys.readouterr().out


def test_the_readme_example_prints_what_the_readme_shows(tmp_path, monkeypatch, capsys):
    text = (ROOT / "README.md").read_text().split("## Python\n", 1)[1]
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    shown = text.split("```python\n", 1)[1].split("```", 1)[1].split("```\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    assert capsys.readouterr().out == shown
    assert {p.name for p in tmp_path.iterdir()} == {"result.json", "calibrated.urdf", "report.html"}


def test_cli_runs_the_executable_and_raises_its_error(tmp_path):
    """twincal.cli runs the twincal executable; its error (exit 2) is a TwincalError with the message."""
    if not BIN:
        pytest.skip("TWINCAL_BIN not set: no twincal executable for twincal.cli")
    with pytest.raises(twincal.TwincalError, match="invalid value 'newton' for '--method"):
        twincal.cli(["calibrate", "--data", tmp_path, "--method", "newton"])


def test_paths_are_guarded_by_the_files_they_name_and_odd_inputs_are_named(tmp_path, monkeypatch):
    """An input is the file it named when it was given: a later chdir cannot turn save() onto
    it. A truth.json path is read as the truth; a 3-D ik input and a masked array's masked
    entries are refused by name, never read around."""
    data, truth = twincal.generate()
    small = {k: v[:150] for k, v in data.items()}
    d = tmp_path / "out" / "d"
    d.mkdir(parents=True)
    csv = twincal.to_csv(small)
    (d / "dataset.csv").write_text(csv)
    (tmp_path / "out" / "arm.urdf").write_text((ROOT / "urdf" / "irb120.urdf").read_text())
    monkeypatch.chdir(tmp_path)
    r = twincal.calibrate("out/d", model="out/arm.urdf")
    monkeypatch.chdir(tmp_path / "out")
    with pytest.raises(twincal.TwincalError, match="dataset.csv"):
        r.save("d/dataset.csv")
    with pytest.raises(twincal.TwincalError, match="arm.urdf"):
        r.save("r.json", urdf="arm.urdf")
    assert (d / "dataset.csv").read_text() == csv and not (tmp_path / "out" / "r.json").exists()
    r.save("r.json")
    assert json.loads((tmp_path / "out" / "r.json").read_text())["schema_version"] == 2
    # The truth from a file, as from the dict generate returned.
    path = tmp_path / "truth.json"
    path.write_text(json.dumps(truth))
    got = twincal.calibrate(data, truth=path).as_dict()["evaluation"]["truth_comparison"]
    assert got == twincal.calibrate(data, truth=truth).as_dict()["evaluation"]["truth_comparison"] and got is not None
    with pytest.raises(twincal.TwincalError, match="truth: cannot read"):
        twincal.calibrate(data, truth=tmp_path / "missing.json")
    with pytest.raises(twincal.TwincalError, match=r"targets must be an \(n, 3\) array"):
        r.ik(np.zeros((2, 3, 1)))
    masked = dict(small)
    masked["L"] = np.ma.masked_array(small["L"], mask=np.arange(150) == 5)
    with pytest.raises(twincal.TwincalError, match="column L: row 6 is masked"):
        twincal.calibrate(masked)


def test_ctrl_c_stops_a_long_calibration_promptly_and_the_next_one_runs():
    """A SIGINT one second into a particle-filter calibration of ~13 s raises KeyboardInterrupt
    within a second or so (the work unwinds at its next prediction), and the library runs again.
    (PSO at effort 10 stalls in under a second on these data: no long run to interrupt.)"""
    import signal

    data, _ = twincal.generate()
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        twincal.calibrate(data, method="pf", effort=10)
    elapsed = time.perf_counter() - t0
    timer.cancel()
    assert elapsed < 3.0, f"KeyboardInterrupt after {elapsed:.1f} s"
    r = twincal.calibrate(data)
    assert r.metrics["train_after"]["rmse"] < r.metrics["train_before"]["rmse"]


def test_ctrl_c_stops_a_long_plan_and_writes_nothing(tmp_path):
    """A SIGINT one second into a plan of ~14 s (150 poses of 50 000 candidates) raises
    KeyboardInterrupt promptly and leaves no poses.csv or plan.json (plan ran to its end and wrote
    them before)."""
    import signal

    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        twincal.plan(tmp_path / "p", poses=150, candidates=50_000)
    elapsed = time.perf_counter() - t0
    timer.cancel()
    assert elapsed < 6.0, f"KeyboardInterrupt after {elapsed:.1f} s"
    assert not (tmp_path / "p" / "poses.csv").exists() and not (tmp_path / "p" / "plan.json").exists()
    assert "indices" in twincal.plan(tmp_path / "q", poses=12, candidates=500) and (tmp_path / "q" / "poses.csv").exists()


def test_export_writes_every_format_as_the_command_line_and_refuses_bad_input(embedded, tmp_path):
    _, data, truth = embedded
    r = twincal.calibrate(data, truth=truth)
    r.save(tmp_path / "r.json")
    for name, fmt in [("k.urdf", None), ("k.yaml", None), ("dh.csv", "dh"), ("mdh.json", "mdh"), ("frames.csv", "frames")]:
        s = twincal.export(tmp_path / "r.json", tmp_path / name, format=fmt, robot="irb120")
        assert s["round_trip_m"] < 1e-9 and (tmp_path / name).exists()
        run_cli("export", "--model", tmp_path / "r.json", "--out", tmp_path / ("cli_" + name), *(["--format", fmt] if fmt else []), "--robot", "irb120")
        assert (tmp_path / name).read_text() == (tmp_path / ("cli_" + name)).read_text()
    # The IRB 120's flange is not turned onto joint 6's axis: the UR file says where the tool goes.
    # The flange sits on the axis, turned only: the warning names the turn and no zero offset.
    said = twincal.export(tmp_path / "r.json", tmp_path / "k2.yaml")["warnings"]
    assert any("turned from joint 6's frame" in w and "off joint 6's axis" not in w for w in said), said
    with pytest.raises(twincal.TwincalError, match="give --format"):
        twincal.export(tmp_path / "r.json", tmp_path / "t.csv")
    with pytest.raises(twincal.TwincalError, match="unknown export format 'step'"):
        twincal.export(tmp_path / "r.json", tmp_path / "t.csv", format="step")
    with pytest.raises(twincal.TwincalError, match="refusing to overwrite"):
        twincal.export(tmp_path / "r.json", tmp_path / "r.json", format="frames")
    with pytest.raises(twincal.TwincalError, match="format must be a string"):
        twincal.export(tmp_path / "r.json", tmp_path / "t.csv", format=3)
    # The robot as a path object, as every other path argument takes.
    assert twincal.export(tmp_path / "r.json", tmp_path / "p.urdf", robot=ROOT / "urdf" / "irb120.urdf")["round_trip_m"] < 1e-9
    with pytest.raises(twincal.TwincalError, match="robot must be irb120 or a URDF path"):
        twincal.export(tmp_path / "r.json", tmp_path / "t.urdf", robot=3)


def test_compensate_agrees_with_the_command_line_and_beats_the_nominal_commands(embedded, tmp_path):
    _, data, truth = embedded
    r = twincal.calibrate(data, truth=truth)
    r.save(tmp_path / "r.json")
    targets = tmp_path / "t.csv"
    targets.write_text("x,y,z\n" + "".join(f"{p[0]},{p[1]},{p[2]}\n" for p in (q["tool_mm"] for q in truth["poses"][:20])))
    s = twincal.compensate(tmp_path / "r.json", targets, tmp_path / "c.csv")
    assert all(t["status"] == "reachable" for t in s["targets"])
    assert max(t["residual_mm"] for t in s["targets"]) <= 0.001 < min(t["nominal_error_mm"] for t in s["targets"])
    run_cli("compensate", "--model", tmp_path / "r.json", "--targets", targets, "--out", tmp_path / "cli.csv")
    assert (tmp_path / "c.csv").read_text() == (tmp_path / "cli.csv").read_text()
    with pytest.raises(twincal.TwincalError, match="--payload-kg must be in"):
        twincal.compensate(tmp_path / "r.json", targets, tmp_path / "d.csv", payload_kg=-1.0)
    with pytest.raises(twincal.TwincalError, match="refusing to overwrite"):
        twincal.compensate(tmp_path / "r.json", targets, targets)
    with pytest.raises(twincal.TwincalError, match="option 'euler'.*not three axis letters"):
        twincal.compensate(tmp_path / "r.json", targets, tmp_path / "e.csv", euler="XXY")
    with pytest.raises(twincal.TwincalError, match="euler"):
        twincal.compensate(tmp_path / "r.json", targets, tmp_path / "e.csv", euler=3)


def test_compensate_filters_a_program_as_the_command_line_does(embedded, tmp_path):
    _, data, truth = embedded
    r = twincal.calibrate(data, truth=truth)
    r.save(tmp_path / "r.json")
    poses = tmp_path / "poses.csv"
    poses.write_text("q1,q2,q3,q4,q5,q6\n" + "".join(",".join(str(v) for v in p["q_cmd_deg"]) + "\n" for p in truth["poses"][:12]))
    twincal.program(poses, tmp_path / "prog", format="rapid", name="tour")
    module = tmp_path / "prog" / "tour.mod"
    # Joint targets are left unless asked: the copy is the program's bytes.
    s = twincal.compensate(tmp_path / "r.json", program=module, robot="irb120", filtered_dir=tmp_path / "same", report=tmp_path / "same.csv")
    assert (tmp_path / "same" / "tour.mod").read_bytes() == module.read_bytes()
    assert len(s["program"]["targets"]) == 12 and all(t["outcome"] == {"left": "joint_target"} for t in s["program"]["targets"])
    s = twincal.compensate(tmp_path / "r.json", program=[module], robot="irb120", joint_targets=True, filtered_dir=tmp_path / "f", report=tmp_path / "f.csv")
    assert sum(t["outcome"] == "filtered" for t in s["program"]["targets"]) == 12
    run_cli("compensate", "--model", tmp_path / "r.json", "--program", module, "--robot", "irb120", "--joint-targets", "--filtered-dir", tmp_path / "cli", "--report", tmp_path / "cli.csv")
    assert (tmp_path / "f" / "tour.mod").read_text() == (tmp_path / "cli" / "tour.mod").read_text() != module.read_text()
    with pytest.raises(twincal.TwincalError, match="program must be a path or a list of paths"):
        twincal.compensate(tmp_path / "r.json", program=3)
    with pytest.raises(twincal.TwincalError, match="is also an input"):
        twincal.compensate(tmp_path / "r.json", program=module, filtered_dir=tmp_path / "prog")


def test_iso9283_agrees_with_the_command_line(tmp_path):
    d = tmp_path / "tw"
    run_cli("generate", "--scenario", ROOT / "scenarios/irb120_tracker.toml", "--out", d)
    run_cli("calibrate", "--data", d, "--out", tmp_path / "a.json")
    e = twincal.iso9283(d, tmp_path / "a.json")
    run_cli("iso9283", "--data", d, "--model", tmp_path / "a.json", "--out", tmp_path / "cli.json")
    cli = json.loads((tmp_path / "cli.json").read_text())
    assert e["models"][0]["ap_mm"] == cli["models"][0]["ap_mm"] and e["models"][0]["rows"] == "held out"
    assert e["models"][0]["ap_mm"]["mean"] < 0.02
    with pytest.raises(twincal.TwincalError, match="unknown option 'colour'"):
        twincal.iso9283(d, tmp_path / "a.json", colour="red")


def test_plan_agrees_with_the_command_line_and_its_poses_are_what_generate_measures(tmp_path):
    scenario = ROOT / "scenarios/irb120_tracker.toml"
    p = twincal.plan(tmp_path / "p", scenario=scenario, poses=12, candidates=1500, seed=3)
    assert len(p["poses_deg"]) == 12 and p["criterion"] == "i"
    assert p["indices"]["i_prediction_variance"] < p["random_median"]["i_prediction_variance"]
    # The certified ceiling: no 12 poses of the pool below it, the plan above it.
    assert 0 < p["ceiling"]["bound"]["lower"] <= p["indices"]["i_prediction_variance"]
    data, truth = twincal.generate(scenario, poses=tmp_path / "p" / "poses.csv")
    assert len(data["q1"]) == 12
    assert np.allclose(np.column_stack([data[f"q{j}"] for j in range(1, 7)]), np.array(p["poses_deg"]), atol=1e-6)
    run_cli("plan", "--scenario", scenario, "--poses", 12, "--candidates", 1500, "--seed", 3, "--out", tmp_path / "cli")
    assert (tmp_path / "p" / "poses.csv").read_text() == (tmp_path / "cli" / "poses.csv").read_text()
    with pytest.raises(twincal.TwincalError, match="unknown criterion 'e'"):
        twincal.plan(tmp_path / "q", criterion="e")
    with pytest.raises(twincal.TwincalError, match="--candidates must be"):
        twincal.plan(tmp_path / "q", poses=40, candidates=20)
    with pytest.raises(twincal.TwincalError, match="poses"):
        twincal.plan(tmp_path / "q", poses="many")
    # Over payloads: each pose gets its own, and generate measures them with the rows' payload.
    w = twincal.plan(tmp_path / "w", scenario=scenario, poses=12, candidates=1500, seed=3, effects="compliance", payloads=[0, 4])
    assert len(w["payload_kg"]) == 12 and set(w["payload_kg"]) <= {0.0, 4.0}
    data, _ = twincal.generate(scenario, poses=tmp_path / "w" / "poses.csv")
    assert list(data["payload_kg"]) == w["payload_kg"]
    with pytest.raises(twincal.TwincalError, match="payloads"):
        twincal.plan(tmp_path / "v", payloads=["heavy"])
    # Wrong types are named, not numpy's or Python's iteration errors.
    with pytest.raises(twincal.TwincalError, match="payloads must be a list of numbers, got int"):
        twincal.plan(tmp_path / "v", payloads=5)
    with pytest.raises(twincal.TwincalError, match="payloads: entry 2 is masked"):
        twincal.plan(tmp_path / "v", payloads=np.ma.masked_array([0.0, 2.0], mask=[False, True]))
    with pytest.raises(twincal.TwincalError, match="payloads must be a list of numbers, got a 0-d array"):
        twincal.plan(tmp_path / "v", payloads=np.ma.masked_array(3.0))
    with pytest.raises(twincal.TwincalError, match="effects must be a string or a list of strings, got int"):
        twincal.plan(tmp_path / "v", effects=5)
    with pytest.raises(twincal.TwincalError, match="payload_com_mm must be a list of numbers"):
        twincal.plan(tmp_path / "v", payload_kg=1.0, payload_com_mm=5)


def test_a_moved_tracker_is_a_station_of_its_own_and_a_new_one_is_registered(tmp_path):
    d = tmp_path / "tw"
    run_cli("generate", "--scenario", ROOT / "scenarios/irb120_tracker.toml", "--out", d)
    import csv

    rows = list(csv.DictReader(open(d / "dataset.csv")))
    half = len(rows) // 2
    for i, r in enumerate(rows):
        if i >= half:
            r["x"], r["y"] = str(float(r["y"]) + 300.0), str(-float(r["x"]))
        r["station"] = "east" if i < half else "west"
    moved = tmp_path / "moved.csv"
    with open(moved, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    r = twincal.calibrate(moved)
    setup = r.setup
    assert [s["label"] for s in setup["stations"]] == ["east", "west"]
    assert abs(setup["stations"][1]["turn_deg"] - 90.0) < 0.01
    one = twincal.calibrate(moved, stations="one")
    assert one.setup is None
    assert one.metrics["test_after"]["rmse"] > 100 * r.metrics["test_after"]["rmse"]
    east = {k: [row[k] for row in rows[:half]] for k in rows[0]}
    model = twincal.calibrate({k: np.array(v, dtype=float) if k not in ("station", "split") else np.array(v) for k, v in east.items()})
    with pytest.warns(UserWarning, match="station west: not one the model was calibrated at"):
        p = model.predict(moved)
    assert np.sqrt(np.mean((p[half + 12 :] - np.array([[float(x[c]) for c in "xyz"] for x in rows[half + 12 :]])) ** 2)) < 0.02
    with pytest.raises(twincal.TwincalError, match="register each on its first rows"):
        model.predict(moved, register_rows=0)
    with pytest.raises(twincal.TwincalError, match="unknown variant `north`|stations"):
        twincal.calibrate(moved, stations="north")


def test_a_plan_and_a_pose_list_become_measurement_programs(tmp_path):
    """plan(program_format=...) writes the tour as a RAPID module beside poses.csv; program()
    writes the same pose list as KRL; wrong types and values raise TwincalError."""
    twincal.plan(tmp_path / "p", poses=6, candidates=300, program_format="rapid", hold_s=1.0)
    module = (tmp_path / "p" / "twincal_plan.mod").read_text()
    assert module.startswith("MODULE twincal_plan") and module.count("MoveAbsJ twc_p") == 6
    assert "CONST num twc_hold := 1;" in module
    s = twincal.program(tmp_path / "p" / "poses.csv", tmp_path / "k", format="krl", hold_s=0.5)
    assert s["poses"] == 6 and s["format"] == "krl"
    assert (tmp_path / "k" / "twincal_tour.src").read_text().count("PTP TWC_P") == 6
    assert "DECL E6AXIS TWC_P6=" in (tmp_path / "k" / "twincal_tour.dat").read_text()
    with pytest.raises(twincal.TwincalError, match="unknown variant"):
        twincal.program(tmp_path / "p" / "poses.csv", tmp_path / "x", format="fanuc")
    with pytest.raises(twincal.TwincalError, match="hold-s"):
        twincal.program(tmp_path / "p" / "poses.csv", tmp_path / "x", format="rapid", hold_s=-1.0)
    with pytest.raises(twincal.TwincalError, match="robot must be"):
        twincal.program(tmp_path / "p" / "poses.csv", tmp_path / "x", format="rapid", robot=3)
    assert not (tmp_path / "x").exists()


def test_the_controller_subset_is_written_as_the_controllers_data(tmp_path):
    """calibrate(controller_subset=True) on the twin's tracker data, then controller_data() as
    KRL: the offsets of the result; a full calibration is refused."""
    data, _ = twincal.generate(scenario=ROOT / "scenarios" / "irb120_tracker.toml")
    subset = twincal.calibrate(data, controller_subset=True)
    subset.save(tmp_path / "subset.json")
    s = twincal.controller_data(tmp_path / "subset.json", tmp_path / "cal.dat", format="krl")
    assert [n for n, _ in s["joint_offsets_deg"]] == [f"joint_{j}" for j in range(1, 7)]
    assert "DECL GLOBAL FRAME TWC_TOOL={X " in (tmp_path / "cal.dat").read_text()
    twincal.calibrate(data).save(tmp_path / "full.json")
    with pytest.raises(twincal.TwincalError, match="controller-subset"):
        twincal.controller_data(tmp_path / "full.json", tmp_path / "full.dat", format="krl")
    assert not (tmp_path / "full.dat").exists()


def test_a_ball_in_sockets_calibrates_as_the_command_line_does(tmp_path):
    """Seated rows (a socket column, no reading) calibrated with their stated spacing, from a
    folder and from columns in memory, agree with the command line; without a spacing the
    command line's message is raised."""
    scenario = ROOT / "scenarios" / "irb120_sockets.toml"
    d = tmp_path / "sockets"
    run_cli("generate", "--scenario", scenario, "--out", d)
    run_cli("calibrate", "--data", d, "--spacing-mm", "A:B=50", "--out", tmp_path / "cli.json")
    r = twincal.calibrate(str(d), spacing_mm=["A:B=50"])
    cli = json.loads((tmp_path / "cli.json").read_text())
    assert untimed(json.loads(r.to_json())["evaluation"]) == untimed(cli["evaluation"])
    assert r.metrics["test_after"]["rmse"] < 0.02
    with pytest.raises(twincal.TwincalError, match="no known spacing"):
        twincal.calibrate(str(d))
    with pytest.raises(twincal.TwincalError, match="seats a ball"):
        twincal.generate(str(scenario))


def test_the_tool_routines_agree_with_the_command_line(tmp_path):
    """The N-point TCP and the 3-point user frame from Python equal the command line's on the
    same configurations (a ball seated in one socket; three sockets' rows for the frame); a
    wrong type is refused by name."""
    d = tmp_path / "sockets"
    run_cli("generate", "--scenario", ROOT / "scenarios" / "irb120_sockets.toml", "--out", d)
    lines = (d / "dataset.csv").read_text().splitlines()
    header = lines[0].split(",")
    q = [i for i, h in enumerate(header) if h.startswith("q")]
    col = {h: i for i, h in enumerate(header)}
    rows = [l.split(",") for l in lines[1:]]
    at = lambda p, s: [r for r in rows if r[col["placement"]] == p and r[col["socket"]] == s]
    write = lambda path, rs: path.write_text("\n".join([",".join(header[i] for i in q)] + [",".join(r[i] for i in q) for r in rs]) + "\n")
    f = tmp_path / "tcp.csv"
    write(f, at("p1", "A")[:8])
    run_cli("tcp", "--data", f, "--out", tmp_path / "cli_tcp.json")
    cli = json.loads((tmp_path / "cli_tcp.json").read_text())
    py = twincal.tcp(f)
    assert py == cli
    assert py["rows"] == 8 and all(s > 0 for s in py["tool_sd_mm"])
    uf = tmp_path / "frame.csv"
    write(uf, [at("p1", "A")[0], at("p1", "B")[0], at("p2", "A")[0]])
    run_cli("user-frame", "--data", uf, "--tcp", tmp_path / "cli_tcp.json", "--out", tmp_path / "cli_frame.json")
    assert twincal.user_frame(uf, tmp_path / "cli_tcp.json") == json.loads((tmp_path / "cli_frame.json").read_text())
    with pytest.raises(twincal.TwincalError, match="orientation must be True or False"):
        twincal.tcp(f, orientation="yes")
    # Eight configurations turned about the point: the last two are no elongators.
    with pytest.raises(twincal.TwincalError, match="without turning"):
        twincal.tcp(f, orientation=True)
