#!/usr/bin/python3
"""Chart of a backlash_compare run: load trajectories against the reference, tracking errors, and one bar chart per
metric. Called by backlash_compare --png FILE with the directory of its trajectories.csv and metrics.csv. With
--vary (no trajectories.csv; metrics.csv's second column is the varied key): each metric against the varied value,
one line per strategy, verdicts marked (o converged, x limit cycle / irregular, . undecided).
usage: compare_chart.py DIR OUT.png     (also writes OUT.svg)"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

BARS = [("rms_error", "RMS tracking error [rad]"), ("steady_rms_error", "steady-state RMS error [rad]"),
        ("limit_cycle_error", "limit-cycle error [rad]"), ("settling_time", "settling time into the band [s]"),
        ("overshoot", "overshoot [rad]"), ("impacts_per_second", "impacts (compliant: contacts) per second [1/s]"),
        ("impact_energy_per_second", "impact (compliant: mesh) losses [W]"), ("rms_torque", "RMS motor torque [N·m]")]


def save(fig, out):
    base = out[:-4] if out.endswith(".png") else out
    fig.savefig(base + ".png", dpi=100)
    fig.savefig(base + ".svg")


def vary_chart(metrics, key, out):
    """Robustness: each metric against the varied parameter, one line per strategy."""
    names = list(dict.fromkeys(m["name"] for m in metrics))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    panels = [("limit_cycle_error", "limit-cycle error [rad]"), ("steady_error", "|steady error| [rad]")] + \
        [b for b in BARS if b[0] not in ("limit_cycle_error", "overshoot")]
    fig, axes = plt.subplots(2, 4, figsize=(16, 8))
    marker = {"converged": "o", "limit_cycle": "x", "irregular_oscillation": "x"}
    for ax, (metric, label) in zip(axes.flat, panels):
        for i, name in enumerate(names):
            rows = [m for m in metrics if m["name"] == name]
            x = [float(m[key]) for m in rows]
            y = [abs(float(m[metric])) if m[metric] != "" else math.nan for m in rows]
            c = colors[i % len(colors)]
            ax.plot(x, y, "-", color=c, lw=1.0, label=name if ax is axes.flat[0] else None)
            for xi, yi, m in zip(x, y, rows):
                if not math.isnan(yi):
                    ax.plot([xi], [yi], marker.get(m["verdict"], "."), color=c, ms=5)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel(key, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    fig.legend(fontsize=7, ncol=5, loc="lower center")
    fig.suptitle("Robustness of each strategy against %s (o converged, x limit cycle, . undecided)" % key,
                 fontsize=11)
    fig.tight_layout(rect=(0, 0.07, 1, 0.97))
    save(fig, out)


def main(argv):
    if len(argv) != 2:
        print(__doc__)
        return 2
    src, out = argv
    with open(os.path.join(src, "metrics.csv")) as f:
        reader = csv.DictReader(f)
        metrics = list(reader)
        columns = reader.fieldnames
    if not os.path.exists(os.path.join(src, "trajectories.csv")):
        vary_chart(metrics, columns[1], out)
        return 0
    traj = {}
    with open(os.path.join(src, "trajectories.csv")) as f:
        for r in csv.DictReader(f):
            traj.setdefault(int(r["strategy"]), []).append(
                (float(r["time"]), float(r["reference"]), float(r["load_position"])))
    names = [m["name"] for m in metrics]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig = plt.figure(figsize=(15, 11))
    gs = fig.add_gridspec(4, 4, height_ratios=[1.3, 1.3, 1, 1])
    ax_pos = fig.add_subplot(gs[0, :])
    ax_err = fig.add_subplot(gs[1, :], sharex=ax_pos)
    for i, name in enumerate(names):
        pts = traj.get(i, [])
        if not pts:
            continue
        t = [p[0] for p in pts]
        c = colors[i % len(colors)]
        if i == 0:
            ax_pos.plot(t, [p[1] for p in pts], "k--", lw=1.0, label="reference θ_R")
        ax_pos.plot(t, [p[2] for p in pts], color=c, lw=0.9, label=name)
        ax_err.plot(t, [p[1] - p[2] for p in pts], color=c, lw=0.8)
    ax_pos.set_ylabel("load position θ_c [rad]")
    ax_pos.legend(fontsize=7, ncol=3, loc="best")
    ax_pos.grid(alpha=0.3)
    ax_err.set_ylabel("tracking error θ_R − θ_c [rad]")
    ax_err.set_xlabel("time [s]")
    ax_err.grid(alpha=0.3)
    for k, (key, label) in enumerate(BARS):
        ax = fig.add_subplot(gs[2 + k // 4, k % 4])
        values = [float(m[key]) if m[key] != "" else math.nan for m in metrics]
        ax.bar(range(len(names)), [0 if math.isnan(v) else v for v in values],
               color=[colors[i % len(colors)] for i in range(len(names))])
        for i, v in enumerate(values):
            if math.isnan(v):
                ax.text(i, 0, "n/a", ha="center", va="bottom", fontsize=6)
        ax.set_title(label, fontsize=8)
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels([str(i + 1) for i in range(len(names))], fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle("Compensation workbench: strategies (bars numbered as in the legend order)", fontsize=11)
    fig.tight_layout()
    save(fig, out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
