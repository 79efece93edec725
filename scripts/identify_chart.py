#!/usr/bin/python3
"""Chart of a backlash_identify fit: the recording against the fitted model replayed over the fit's windows (each
re-anchored on the measured state at its start) — the load angle, the gap theta_c - rho*theta_m that shows the
backlash, and the residuals. Called by backlash_identify --png FILE with the directory of its replay.csv (columns
time, motor, load, gap, motor_fit, load_fit, gap_fit; rad on the load shaft, empty outside the windows).
usage: identify_chart.py DIR OUT.png"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def number(text):
    return float(text) if text not in ("", "nan") else math.nan


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    directory, out = sys.argv[1], sys.argv[2]
    with open(os.path.join(directory, "replay.csv"), newline="") as f:
        rows = [{k: number(v) for k, v in r.items()} for r in csv.DictReader(f)]
    t = [r["time"] for r in rows]
    fig, axes = plt.subplots(3, 1, figsize=(10, 8.5), sharex=True, gridspec_kw={"height_ratios": [2, 2, 1.3]})
    top, middle, bottom = axes
    top.plot(t, [r["load"] for r in rows], color="0.55", lw=0.8, label="measured θ_c")
    top.plot(t, [r["load_fit"] for r in rows], color="tab:red", lw=1.2, label="fitted model, replayed per window")
    top.set_ylabel("load angle [rad]")
    top.legend(loc="upper right", fontsize=8)
    middle.plot(t, [r["gap"] for r in rows], color="0.55", lw=0.8, label="measured gap θ_c − ρθ_m")
    middle.plot(t, [r["gap_fit"] for r in rows], color="tab:red", lw=1.2, label="fitted model")
    middle.set_ylabel("gap [rad]")
    middle.legend(loc="upper right", fontsize=8)
    bottom.plot(t, [r["load_fit"] - r["load"] for r in rows], color="tab:red", lw=0.8, label="θ_c: fitted − measured")
    bottom.plot(t, [r["motor_fit"] - r["motor"] for r in rows], color="tab:blue", lw=0.8,
                label="ρθ_m: fitted − measured")
    bottom.set_ylabel("residual [rad]")
    bottom.set_xlabel("time [s]")
    bottom.legend(loc="upper right", fontsize=8)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.suptitle("backlash_identify: the recording and the fitted joint (windows re-anchored on the measured state)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
