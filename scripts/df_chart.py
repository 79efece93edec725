#!/usr/bin/python3
"""Chart of a backlash_df analysis: the Nyquist plot of the loop's linear part G(jw) and the describing function's
critical locus -1/N(A); harmonic-balance predictions where they meet (filled: stable, hollow: unstable), and the
exact simulated cycle's point on each curve (-1/N at its amplitude, G at its frequency). Called by
backlash_df --png FILE with the directory of its nyquist.csv, locus.csv and points.csv.
usage: df_chart.py DIR OUT.png"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(path):
    with open(path, newline="") as f:
        return [{k: float(v) if k != "kind" else v for k, v in r.items()} for r in csv.DictReader(f)]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    directory, out = sys.argv[1], sys.argv[2]
    nyquist = rows(os.path.join(directory, "nyquist.csv"))
    locus = rows(os.path.join(directory, "locus.csv"))
    points = rows(os.path.join(directory, "points.csv"))
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    ax.plot([r["re"] for r in nyquist], [r["im"] for r in nyquist], color="tab:blue", label="G(jω), the linear loop")
    element_path = os.path.join(directory, "element.txt")
    element = open(element_path).read().strip() if os.path.exists(element_path) else "classical DF of backlash"
    ax.plot([r["re"] for r in locus], [r["im"] for r in locus], color="tab:red", label=f"−1/N(A), {element}")
    for p in points:
        if p["kind"] in ("stable", "unstable"):
            ax.plot(p["re"], p["im"], "o", color="k", mfc="k" if p["kind"] == "stable" else "w", ms=8,
                    label=f"predicted {p['kind']}: A = {p['amplitude']:.4g} rad, ω = {p['frequency']:.4g} rad/s")
        elif p["kind"] == "simulated_locus":
            ax.plot(p["re"], p["im"], "s", color="tab:green", ms=8,
                    label=f"exact cycle: −1/N at A = {p['amplitude']:.4g} rad")
        elif p["kind"] == "simulated_nyquist":
            ax.plot(p["re"], p["im"], "D", color="tab:green", mfc="w", ms=8,
                    label=f"exact cycle: G at ω = {p['frequency']:.4g} rad/s")
    # A view around the critical region: the locus starts at −1; the stable predictions and the exact cycle's points
    # set the reach (an unstable solution far out along the locus is listed in the legend, not zoomed to).
    near = [p for p in points if p["kind"] != "unstable"]
    span = max(2.0, 1.6 * max([1.0] + [abs(p["re"]) for p in near] + [abs(p["im"]) for p in near]))
    ax.set_xlim(-span, 0.5 * span)
    ax.set_ylim(-span, 0.5 * span)
    ax.axhline(0.0, color="0.7", lw=0.8)
    ax.axvline(0.0, color="0.7", lw=0.8)
    ax.set_xlabel("real")
    ax.set_ylabel("imaginary")
    ax.set_title("Harmonic balance G(jω)·N(A) = −1")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(out, dpi=100)


if __name__ == "__main__":
    main()
