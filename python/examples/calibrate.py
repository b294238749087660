"""Generate the embedded IRB 120 scenario in memory, calibrate it, and judge the fit by the truth.

The same steps as ``twincal generate`` then ``twincal calibrate``, with no files: ``generate``
returns the dataset's columns and its truth, ``calibrate`` fits the default model (LM on the
Hayati parameters) on the training rows, and the result says how well it predicts the held-out
rows and how many identifiable parameters it recovered within three standard uncertainties.

    python calibrate.py [SEED]
"""

from __future__ import annotations

import sys

import twincal


def main(seed: int = 7) -> dict:
    data, truth = twincal.generate(seed=seed)
    result = twincal.calibrate(data, truth=truth)
    before, after = result.metrics["test_before"]["rmse"], result.metrics["test_after"]["rmse"]
    t = result.as_dict()["evaluation"]["truth_comparison"]
    print(f"seed {seed}: {len(data['L'])} rows, held-out RMSE {before:.4f} mm before, {after:.4f} mm after")
    print(f"truth: {t['within_3_sigma']}/{t['identifiable']} identifiable parameters within 3 sigma (max |z| {t['max_abs_z']:.2f})")
    if not after < 0.5 * before:
        raise SystemExit(f"calibration did not halve the held-out error: {before:.4f} -> {after:.4f} mm")
    return {"before_mm": before, "after_mm": after, "within_3_sigma": t["within_3_sigma"], "identifiable": t["identifiable"]}


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 7)
