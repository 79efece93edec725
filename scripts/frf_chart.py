#!/usr/bin/python3
"""Bode chart of a backlash_frf measurement: gain (dB) and phase (deg) against frequency, one curve per amplitude,
the response with backlash 0 dashed. Stepped sines (points.csv): points that did not settle into a periodic
response are marked with a cross. Broadband (lines.csv): the H1 estimate per DFT line and a third panel with the
coherence. Called by backlash_frf --png FILE with the directory of its points.csv or lines.csv and channel.txt.
usage: frf_chart.py DIR OUT.png"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

UNITS = {
    "command:load_position": ("θ_c / θ_R", "rad/rad"),
    "motor_torque:motor_velocity": ("ω_m / T_m", "(rad/s)/(N·m)"),
    "motor_torque:load_velocity": ("ω_c / T_m", "(rad/s)/(N·m)"),
    "torque_setpoint:motor_velocity": ("ω_m / T_m, loops closed", "(rad/s)/(N·m)"),
    "torque_setpoint:load_velocity": ("ω_c / T_m, loops closed", "(rad/s)/(N·m)"),
    "load_torque:load_position": ("θ_c / T_ext, dynamic compliance", "rad/(N·m)"),
}


def number(text):
    return float(text) if text != "" else math.nan


def unwrapped(phases, settled=None):
    """Phases [rad] → degrees, continued across ±180°: each within 180° of the last settled one before it (a point
    that did not settle follows its neighbours but does not lead them)."""
    out, ref = [], None
    for i, p in enumerate(phases):
        d = math.degrees(p)
        if ref is not None and not math.isnan(d):
            d += 360.0 * round((ref - d) / 360.0)
        out.append(d)
        if settled is None or settled[i]:
            ref = d
    return out


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    directory, out = sys.argv[1], sys.argv[2]
    broadband = os.path.exists(os.path.join(directory, "lines.csv"))
    with open(os.path.join(directory, "lines.csv" if broadband else "points.csv"), newline="") as f:
        rows = [{k: number(v) for k, v in r.items()} for r in csv.DictReader(f)]
    for r in rows:
        r.setdefault("periodic", 1.0)
    with open(os.path.join(directory, "channel.txt")) as f:
        meta = f.read().split()
    channel = meta[0]
    excitation = meta[1] if len(meta) > 1 else "stepped sines"
    ratio, unit = UNITS.get(channel, ("gain", ""))
    amplitudes = sorted({r["amplitude"] for r in rows})
    if broadband:
        fig, (mag, pha, coh) = plt.subplots(3, 1, sharex=True, figsize=(8, 9), gridspec_kw={"height_ratios": [3, 3, 1.5]})
    else:
        fig, (mag, pha) = plt.subplots(2, 1, sharex=True, figsize=(8, 7))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]

    def db(g):
        return 20.0 * math.log10(g) if g > 0 else math.nan

    for i, a in enumerate(amplitudes):
        pts = sorted((r for r in rows if r["amplitude"] == a), key=lambda r: r["frequency"])
        c = colours[i % len(colours)]
        w = [r["frequency"] for r in pts]
        mark = "-" if broadband else "o-"
        mag.semilogx(w, [db(r["gain"]) for r in pts], mark, color=c, ms=3, label=f"A = {a:.4g}")
        # Phase continued only through settled points (stepped sines) or coherent lines (broadband).
        trusted = [r["coherence"] >= 0.5 if broadband else r["periodic"] == 1 for r in pts]
        phase = unwrapped([r["phase"] for r in pts], trusted)
        pha.semilogx(w, phase, mark, color=c, ms=3)
        if broadband:
            coh.semilogx(w, [r["coherence"] for r in pts], "-", color=c)
        bad = [i for i, r in enumerate(pts) if r["periodic"] == 0]
        mag.semilogx([w[i] for i in bad], [db(pts[i]["gain"]) for i in bad], "x", color="k", ms=8)
        pha.semilogx([w[i] for i in bad], [phase[i] for i in bad], "x", color="k", ms=8)
        if i == 0 and all(not math.isnan(r["linear_gain"]) for r in pts):
            mag.semilogx(w, [db(r["linear_gain"]) for r in pts], "--", color="0.3", label="backlash 0")
            pha.semilogx(w, unwrapped([r["linear_phase"] for r in pts]), "--", color="0.3")
    if any(r["periodic"] == 0 for r in rows):
        mag.plot([], [], "x", color="k", label="not periodic")
    mag.set_ylabel(f"gain {ratio} [dB re 1 {unit}]")
    pha.set_ylabel("phase [deg]")
    if broadband:
        coh.set_ylabel("coherence γ²")
        coh.set_ylim(0.0, 1.05)
        coh.grid(True, which="both", alpha=0.3)
        coh.set_xlabel("frequency ω [rad/s]")
    else:
        pha.set_xlabel("frequency ω [rad/s]")
    mag.set_title(f"Frequency response, {channel} ({'H1 from ' + excitation if broadband else excitation})")
    mag.grid(True, which="both", alpha=0.3)
    pha.grid(True, which="both", alpha=0.3)
    mag.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=100)


if __name__ == "__main__":
    main()
