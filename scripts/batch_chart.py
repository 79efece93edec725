#!/usr/bin/python3
"""Chart of a tolerance study (backlash_sweep --monte-carlo N --png FILE): the share of joints per verdict with its
95 % interval, the hunting joints' peak-to-peak amplitude and period, and the batch over the two drawn keys that
separate hunting from settling best (the best split of the first drawn as a line). Called with the directory of
batch.csv (the sweep's CSV), verdicts.csv and influences.csv (the summary's figures).
usage: batch_chart.py DIR OUT.png     (also writes OUT.svg)"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HUNTING = ("limit_cycle", "irregular_oscillation")


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def number(cell):
    return float(cell) if cell not in ("", None) else math.nan


def main(directory, out):
    rows = read(os.path.join(directory, "batch.csv"))
    verdicts = read(os.path.join(directory, "verdicts.csv"))
    influences = read(os.path.join(directory, "influences.csv"))
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    fig.suptitle("tolerance study: %d joints" % len(rows))

    ax = axes[0][0]
    names = [v["verdict"] for v in verdicts]
    share = [100.0 * number(v["fraction"]) for v in verdicts]
    low = [s - 100.0 * number(v["low"]) for s, v in zip(share, verdicts)]
    high = [100.0 * number(v["high"]) - s for s, v in zip(share, verdicts)]
    colors = ["tab:red" if n in HUNTING else "tab:green" if n == "converged" else "tab:gray" for n in names]
    ax.bar(range(len(names)), share, yerr=[low, high], color=colors, capsize=6)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(names, fontsize=8)
    ax.set_ylabel("joints [%] (95 % interval)")
    ax.set_title("verdicts")
    ax.grid(axis="y", alpha=0.3)

    hunting = [r for r in rows if r["verdict"] in HUNTING]
    for ax, key, label in ((axes[0][1], "peak_to_peak", "peak to peak of the load [rad]"),
                           (axes[1][0], "period", "period [s]")):
        values = [number(r[key]) for r in hunting if not math.isnan(number(r[key]))]
        if values:
            ax.hist(values, bins=min(40, max(5, len(values) // 5)), color="tab:red", alpha=0.8)
        ax.set_title("hunting joints (%d): %s" % (len(hunting), label), fontsize=10)
        ax.set_xlabel(label)
        ax.set_ylabel("joints")
        ax.grid(alpha=0.3)

    ax = axes[1][1]
    keys = [i["key"] for i in influences]
    if keys:
        x_key = keys[0]
        y_key = keys[1] if len(keys) > 1 else None
        for group, color, label in ((HUNTING, "tab:red", "hunts"), (("converged",), "tab:green", "converges"),
                                    (("undecided", "diverged"), "tab:gray", "other")):
            pick = [r for r in rows if r["verdict"] in group]
            xs = [number(r[x_key]) for r in pick]
            ys = [number(r[y_key]) if y_key else 0.0 for r in pick]
            if pick:
                ax.scatter(xs, ys, s=10, color=color, label=label, alpha=0.7)
        threshold = number(influences[0]["threshold"])
        if not math.isnan(threshold):
            ax.axvline(threshold, color="k", lw=1.0, ls="--",
                       label="best split: %s %s %.4g %s" % (x_key, ">" if influences[0]["above"] == "1" else "<",
                                                            threshold, influences[0]["unit"]))
        ax.set_xlabel("%s [%s]" % (x_key, influences[0]["unit"]))
        ax.set_ylabel("%s [%s]" % (y_key, influences[1]["unit"]) if y_key else "")
        ax.set_title("the drawn keys that separate best (rank correlation %s)" %
                     ", ".join("%s %+.2f" % (i["key"], number(i["rank_correlation"])) for i in influences[:2]),
                     fontsize=9)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    base = out[:-4] if out.endswith(".png") else out
    fig.savefig(base + ".png", dpi=100)
    fig.savefig(base + ".svg")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
