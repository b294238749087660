"""Benchmark: the wheel's calibrate against the command line's, on the same 500 poses.

Target (issue 22): the wheel's `calibrate` on 500 poses within 10 % of the CLI's time. The CLI is
timed end to end as a user runs it (`twincal --quiet calibrate --data DIR --out FILE`: process
start, reading, calibration, writing result.json); the wheel from the same folder (reading and
calibration in process) and from numpy arrays already in memory, and then `Result.save` of the same
result.json. Medians of --repeat runs each, interleaved, in this one process; ratios against the
CLI's median.

    python benchmarks/calibrate_vs_cli.py --bin target/release/twincal [--repeat 15] [--method lm]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import tempfile
import time

import numpy as np

import twincal


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--bin", required=True, help="the twincal executable")
    p.add_argument("--repeat", type=int, default=15)
    p.add_argument("--poses", type=int, default=500)
    p.add_argument("--method", action="append", help="methods to time (default: lm and pso)")
    a = p.parse_args()
    methods = a.method or ["lm", "pso"]

    data, _ = twincal.generate()
    rows = {k: v[: a.poses] for k, v in data.items()}
    with tempfile.TemporaryDirectory(prefix="twincal-bench-") as tmp:
        folder = os.path.join(tmp, "data")
        os.makedirs(folder)
        with open(os.path.join(folder, "dataset.csv"), "w") as f:
            f.write(twincal.to_csv(rows))
        out = os.path.join(tmp, "result.json")
        print(f"calibrate on {a.poses} poses of the embedded scenario, median of {a.repeat} runs each (interleaved)")
        print(f"{'method':<8} {'CLI (process)':>14} {'wheel (folder)':>15} {'ratio':>7} {'wheel (arrays)':>15} {'ratio':>7} {'+ save':>9}")
        for method in methods:
            cli, folder_t, arrays_t, save_t = [], [], [], []
            for _ in range(a.repeat):
                t0 = time.perf_counter()
                subprocess.run([a.bin, "--quiet", "calibrate", "--data", folder, "--method", method, "--out", out], check=True, stderr=subprocess.DEVNULL)
                cli.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                twincal.calibrate(folder, method=method)
                folder_t.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                r = twincal.calibrate(rows, method=method)
                arrays_t.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                r.save(out)
                save_t.append(time.perf_counter() - t0)
            c, f_, m, s = (statistics.median(x) for x in (cli, folder_t, arrays_t, save_t))
            print(f"{method:<8} {c * 1e3:>11.1f} ms {f_ * 1e3:>12.1f} ms {f_ / c:>7.3f} {m * 1e3:>12.1f} ms {m / c:>7.3f} {s * 1e3:>6.1f} ms")
            verdict = "within" if f_ <= 1.10 * c else "NOT within"
            print(f"         wheel from the folder / CLI = {f_ / c:.3f}: {verdict} the 10 % target")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
