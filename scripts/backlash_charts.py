#!/usr/bin/python3
"""Charts of the backlash servo study (the thesis' figures, computed). Headless (Agg); writes PNG and SVG.

usage: backlash_charts.py existence SWEEP.csv OUTDIR [THESIS.csv]   per e, the damping each design needs to be
                                                         free of a limit cycle (Figs. 1-2); THESIS.csv marks the
                                                         thesis' lattice points
       backlash_charts.py error SWEEP.csv OUTDIR        limit-cycle error vs rho^2 J_L/J_m (Figs. 3-26)
       backlash_charts.py delta SWEEP.csv OUTDIR        limit-cycle error vs backlash (Figs. 28-29)
       backlash_charts.py phase SIM.csv OUTDIR [NAME]   phase portrait from backlash_sim --csv (Figs. 30-31)
       backlash_charts.py surface SWEEP.csv OUTDIR      3-D existence surface over (friction, inertia, zeta) (Fig. 27)
       backlash_charts.py digital RATE.csv ENCODER.csv OUTDIR   limit-cycle error vs controller rate and vs
                                                         encoder resolution (sweeps over controller_rate and
                                                         load_encoder_resolution)
       backlash_charts.py compliant DIR OUTDIR          the compliant joint: D1's limit cycle against the mesh
                                                         stiffness (DIR/d1_*.json, the rigid run d1_rigid.json),
                                                         its contact phases (DIR/d1_c1e4.csv) and a robot joint's
                                                         load loop exciting the two-mass resonance
                                                         (DIR/robot_rigid.csv, DIR/robot_compliant.csv)
SWEEP.csv is backlash_sweep output; SIM.csv is backlash_sim --csv output; *.json is backlash_sim --json output.
"""
import glob
import json
import csv
import math
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_sweep(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            rows.append({
                "zeta": float(r["zeta"]), "ir": float(r["inertia_ratio"]), "fr": float(r["friction_ratio"]),
                "e": float(r["restitution"]), "delta": float(r["backlash"]), "lc": r["limit_cycle"] == "1",
                "error": float(r["limit_cycle_error"]), "verdict": r["verdict"],
            })
    if not rows:
        sys.exit(f"backlash_charts: {path} has no rows")
    return rows


def save(fig, outdir, name):
    os.makedirs(outdir, exist_ok=True)
    for ext in ("png", "svg"):
        fig.savefig(os.path.join(outdir, f"{name}.{ext}"), dpi=110, bbox_inches="tight")
    plt.close(fig)
    print(os.path.join(outdir, name + ".png"))


def grid(rows, e, zeta):
    """LC indicator on the (friction ratio, inertia ratio) grid for one e and zeta."""
    frs = sorted({r["fr"] for r in rows})
    irs = sorted({r["ir"] for r in rows})
    z = np.full((len(irs), len(frs)), np.nan)
    for r in rows:
        if r["e"] == e and r["zeta"] == zeta:
            z[irs.index(r["ir"]), frs.index(r["fr"])] = 1.0 if r["lc"] else 0.0
    return np.array(frs), np.array(irs), z


def edges(centers, log=False):
    """Cell edges around grid centres (midpoints; in log10 for a log axis)."""
    c = np.log10(centers) if log else np.asarray(centers, dtype=float)
    if len(c) == 1:
        e = np.array([c[0] - 0.5, c[0] + 0.5])
    else:
        mid = 0.5 * (c[1:] + c[:-1])
        e = np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])
    return 10.0 ** e if log else e


def classical_df_critical_zeta():
    """The largest ζ at which the classical describing function of backlash (hysteresis, d = Δ/2, r = d/A in (0, 1))
    predicts a limit cycle of the thesis' loop G = ω_n²/(s² + 2ζω_n s): the balance N(A) = −1/G(jω) = ω² − 2jζω (ω in units
    of ω_n) needs N_R = ω², N_I = −2ζω, i.e. ζ = −N_I/(2√N_R); a cycle exists iff ζ is below that ratio's maximum
    over the amplitude. The same for every inertia split, friction split, restitution and backlash."""
    r = np.linspace(1e-7, 1.0 - 1e-7, 400001)
    n_r = 0.5 + (np.arcsin(1.0 - 2.0 * r) + 2.0 * (1.0 - 2.0 * r) * np.sqrt(r * (1.0 - r))) / math.pi
    n_i = -(4.0 / math.pi) * r * (1.0 - r)
    return float(np.max(-n_i / (2.0 * np.sqrt(n_r))))


def existence(rows, outdir, lattice=None):
    """Per e, a map of the boundary damping: each cell coloured by the smallest ζ of the sweep from which every
    larger ζ converges (no limit cycle); dark red where even the largest ζ limit-cycles. Conservative: a run that
    did not converge (limit cycle, irregular, undecided) counts as a cycle. White × marks cells where the verdict is
    not monotone in ζ (a cycle at some larger ζ after convergence at a smaller one: islands). Black dots: the
    thesis' lattice points (lattice = rows of the thesis preset sweep). The classical describing function's boundary
    is ζ* on the whole map: each panel counts the cells where the exact joint cycles above it, and a dashed white
    line marks where the exact boundary crosses it (if it does on the map)."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    es = sorted({r["e"] for r in rows})
    zetas = sorted({r["zeta"] for r in rows})
    frs = sorted({r["fr"] for r in rows})
    irs = sorted({r["ir"] for r in rows})
    cycle = {(r["e"], r["zeta"], r["ir"], r["fr"]): r["verdict"] != "converged" for r in rows}
    n = len(zetas)
    zstar = classical_df_critical_zeta()
    colors = list(plt.get_cmap("viridis")(np.linspace(0.95, 0.15, n))) + [(0.55, 0.05, 0.05, 1.0)]
    cmap = ListedColormap(colors)
    norm = BoundaryNorm(np.arange(-0.5, n + 1.0), cmap.N)
    cols = min(len(es), 2)
    nrows = math.ceil(len(es) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(6.4 * cols, 5.0 * nrows), squeeze=False)
    fe, ie = edges(frs), edges(irs, log=True)
    mesh = None
    for ax, e in zip(axes.flat, es):
        z = np.full((len(irs), len(frs)), np.nan)
        islands = []
        for a, ir in enumerate(irs):
            for b, fr in enumerate(frs):
                flags = [cycle.get((e, zeta, ir, fr)) for zeta in zetas]
                if any(f is None for f in flags):
                    continue
                k = n
                while k > 0 and not flags[k - 1]:
                    k -= 1  # flags[k:] all converge
                z[a, b] = k
                if any(not f for f in flags[:k]):
                    islands.append((fr, ir))
        mesh = ax.pcolormesh(fe, ie, z, cmap=cmap, norm=norm, shading="flat", rasterized=True)
        # The classical DF's boundary is ζ* on every cell: where a cycle was seen at a ζ above it, the DF misses it.
        below = sum(1 for zeta in zetas if zeta < zstar)
        known = np.isfinite(z)
        missed = int(np.sum(z[known] > below))
        ax.text(0.98, 0.02, f"classical DF: no cycle above ζ* = {zstar:.4f};\nexact cycles above it in {missed} of "
                f"{int(known.sum())} cells", transform=ax.transAxes, ha="right", va="bottom", fontsize=7,
                color="white", bbox={"facecolor": "black", "alpha": 0.45, "pad": 2, "edgecolor": "none"})
        if np.nanmin(z) < below - 0.5 < np.nanmax(z):
            # Where the exact boundary crosses ζ* (only where the map has cells on both sides of it).
            ax.contour(frs, irs, np.ma.masked_invalid(z), levels=[below - 0.5], colors="white", linestyles="--",
                       linewidths=1.2)
            ax.plot([], [], "--", color="white", label=f"exact boundary = classical DF's ζ* = {zstar:.4f}")
        if islands:
            size = 10 if len(frs) <= 40 else 3  # fine grids: small marks
            ax.scatter(*zip(*islands), marker="x", s=size, c="white", linewidths=0.6, label="not monotone in ζ",
                       rasterized=True)
        if lattice:
            pts = sorted({(r["fr"], r["ir"]) for r in lattice})
            ax.scatter(*zip(*pts), s=9, c="black", label="thesis lattice")
        ax.set_yscale("log")
        ax.set_xlim(fe[0], fe[-1])
        ax.set_ylim(ie[0], ie[-1])
        ax.set_xlabel("friction split ρ²f_L/F_T")
        ax.set_ylabel("inertia split ρ²J_L/J_m")
        ax.set_title(f"e = {e:g}  ({len(frs)} × {len(irs)} designs × {n} ζ)")
    for ax in axes.flat[len(es):]:
        ax.axis("off")
    handles, labels = [], []
    for ax in axes.flat:
        for h, l in zip(*ax.get_legend_handles_labels()):
            if l not in labels:
                handles.append(h)
                labels.append(l)
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=len(handles), fontsize=9, facecolor="#9a9a9a")
    bar = fig.colorbar(mesh, ax=axes.ravel().tolist(), ticks=range(n + 1), shrink=0.85)
    bar.ax.set_yticklabels([f"ζ ≥ {zeta:g}" for zeta in zetas] + [f"cycle at ζ ≤ {zetas[-1]:g}"])
    bar.set_label("no limit cycle for every damping ratio at or above")
    fig.suptitle("Where a limit cycle exists: the damping a design needs to be free of it (read your design's cell)")
    save(fig, outdir, "existence_maps")


def error(rows, outdir):
    es = sorted({r["e"] for r in rows})
    frs = sorted({r["fr"] for r in rows})
    zetas = sorted({r["zeta"] for r in rows})
    fig, axes = plt.subplots(len(es), len(frs), figsize=(3.0 * len(frs), 2.6 * len(es)), squeeze=False,
                             sharex=True, sharey=True)
    cmap = plt.get_cmap("plasma")
    for i, e in enumerate(es):
        for j, fr in enumerate(frs):
            ax = axes[i][j]
            for k, zeta in enumerate(zetas):
                pts = sorted((r["ir"], r["error"]) for r in rows
                             if r["e"] == e and r["fr"] == fr and r["zeta"] == zeta and r["lc"] and r["error"] > 0)
                if pts:
                    ax.plot(*zip(*pts), "o-", ms=3, lw=1.2, color=cmap(k / max(1, len(zetas) - 1)),
                            label=f"ζ={zeta:g}")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            if i == 0:
                ax.set_title(f"ρ²f_L/F_T = {fr:g}", fontsize=9)
            if j == 0:
                ax.set_ylabel(f"e = {e:g}\nerror [rad]", fontsize=9)
            if i == len(es) - 1:
                ax.set_xlabel("ρ²J_L/J_m", fontsize=9)
    handles, labels = axes[0][0].get_legend_handles_labels()
    for row in axes:
        for ax in row:
            h, lab = ax.get_legend_handles_labels()
            if len(h) > len(handles):
                handles, labels = h, lab
    fig.legend(handles, labels, loc="upper right", fontsize=8)
    fig.suptitle("Limit-cycle error (max positive error, Δ = 0.3 rad) vs inertia split")
    save(fig, outdir, "limit_cycle_error")


def delta(rows, outdir):
    cases = defaultdict(list)
    for r in rows:
        if r["lc"]:
            cases[(r["zeta"], r["ir"], r["fr"], r["e"])].append((r["delta"], r["error"]))
    fig, ax = plt.subplots(figsize=(6.5, 4.6))
    for (zeta, ir, fr, e), pts in sorted(cases.items()):
        pts.sort()
        ax.plot(*zip(*pts), "o-", label=f"ζ={zeta:g}, ρ²J_L/J_m={ir:g}, ρ²f_L/F_T={fr:g}, e={e:g}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("backlash Δ [rad]")
    ax.set_ylabel("limit-cycle error [rad]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title("Limit-cycle error is proportional to the backlash")
    save(fig, outdir, "error_vs_backlash")


def phase(path, outdir, name="phase_portrait"):
    t, x, v, contact, event = [], [], [], [], []
    with open(path) as f:
        for r in csv.DictReader(f):
            t.append(float(r["time"]))
            x.append(float(r["load_position"]))
            v.append(float(r["load_velocity"]))
            contact.append(r["contact"])
            event.append(r["event"])
    x, v = np.array(x), np.array(v)
    apart = np.array([c == "apart" for c in contact])
    fig, ax = plt.subplots(figsize=(6.5, 5.0))
    # Draw segments coloured by contact state.
    for k in range(1, len(x)):
        ax.plot(x[k - 1:k + 1], v[k - 1:k + 1], color="#d62728" if apart[k] else "#1f77b4", lw=0.9)
    imp = [k for k, ev in enumerate(event) if ev == "impact"]
    ax.plot(x[imp], v[imp], "k.", ms=4, label="impact (velocity after)")
    ax.plot([], [], color="#1f77b4", label="teeth in contact")
    ax.plot([], [], color="#d62728", label="teeth apart")
    ax.set_xlabel("load position θ_c [rad]")
    ax.set_ylabel("load velocity θ̇_c [rad/s]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Phase portrait (exact trajectory, events at their exact times)")
    save(fig, outdir, name)


def surface(rows, outdir):
    from mpl_toolkits.mplot3d import Axes3D  # noqa: F401

    es = sorted({r["e"] for r in rows})
    zetas = sorted({r["zeta"] for r in rows})
    frs = sorted({r["fr"] for r in rows})
    irs = sorted({r["ir"] for r in rows})
    lc = {(r["e"], r["zeta"], r["ir"], r["fr"]): r["lc"] for r in rows}
    fig = plt.figure(figsize=(6.0 * min(2, len(es)), 5.0 * math.ceil(len(es) / 2)))
    for n, e in enumerate(es):
        ax = fig.add_subplot(math.ceil(len(es) / 2), min(2, len(es)), n + 1, projection="3d")
        z = np.zeros((len(irs), len(frs)))
        for i, ir in enumerate(irs):
            for j, fr in enumerate(frs):
                # Boundary damping: above the largest zeta that still limit-cycles (midway to the next grid value).
                cyc = [k for k, zeta in enumerate(zetas) if lc.get((e, zeta, ir, fr))]
                if not cyc:
                    z[i, j] = zetas[0]
                elif cyc[-1] == len(zetas) - 1:
                    z[i, j] = zetas[-1]
                else:
                    z[i, j] = 0.5 * (zetas[cyc[-1]] + zetas[cyc[-1] + 1])
        fx, iy = np.meshgrid(frs, np.log10(irs))
        fine = len(frs) > 40  # no cell edges on fine grids (they would blacken the surface)
        ax.plot_surface(fx, iy, z, cmap="viridis", edgecolor="none" if fine else "k", linewidth=0.0 if fine else 0.2,
                        alpha=0.9, rasterized=True)
        # The classical describing function's boundary: a plane at ζ* whatever the design.
        ax.plot_surface(fx, iy, np.full_like(z, classical_df_critical_zeta()), color="white", alpha=0.35,
                        edgecolor="none", rasterized=True)
        ax.set_xlabel("ρ²f_L/F_T")
        ax.set_ylabel("log10 ρ²J_L/J_m")
        ax.set_zlabel("ζ boundary (white plane: classical DF)")
        ax.set_title(f"e = {e:g}: limit cycle below the surface")
    fig.suptitle("Limit-cycle existence surface (the thesis' unfinished Fig. 27)")
    save(fig, outdir, "existence_surface")


def read_rows(path, key):
    """(value of axis key, limit-cycle error, verdict) per row of a sweep over any axis."""
    with open(path) as f:
        rows = [(float(r[key]), float(r["limit_cycle_error"]), r["verdict"]) for r in csv.DictReader(f)]
    if not rows:
        sys.exit(f"backlash_charts: {path} has no rows")
    return rows


def digital(rate_csv, encoder_csv, outdir, continuous=0.0514732):
    rate = read_rows(rate_csv, "controller_rate")
    enc = read_rows(encoder_csv, "load_encoder_resolution")
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    f = np.array([r[0] for r in rate])
    err = np.array([r[1] for r in rate])
    a.loglog(f, err - continuous, "o-", label="sampled P law (zero-order hold)")
    a.loglog(f, (err[-1] - continuous) * f[-1] / f, "k--", lw=0.8, label="first order: ∝ 1/f_s")
    a.set_xlabel("controller_rate f_s [Hz]")
    a.set_ylabel("limit-cycle error − continuous 0.0514732 [rad]")
    a.set_title("Thesis D1, P law sampled at f_s:\nthe cycle tends to the continuous one", fontsize=10)
    a.grid(True, which="both", alpha=0.3)
    a.legend()
    ideal = [r[1] for r in enc if r[0] == 0]
    quantised = [r for r in enc if r[0] > 0]
    n = np.array([r[0] for r in quantised])
    b.semilogx(n, [r[1] for r in quantised], "o-", label="load encoder, 1 kHz P law")
    if ideal:
        b.axhline(ideal[0], color="k", ls="--", lw=0.8, label="ideal encoder")
    b.semilogx(n, 2 * math.pi / n, ":", color="gray", label="one count 2π/N")
    b.set_xlabel("load_encoder_resolution N [counts/rev]")
    b.set_ylabel("limit-cycle error [rad]")
    b.set_title("Δ = 0.05 rad, e = 0.5, 1 kHz P law:\nencoder quantisation widens the cycle", fontsize=10)
    b.grid(True, which="both", alpha=0.3)
    b.legend()
    save(fig, outdir, "digital_drive")


def read_samples(path):
    """Sample rows (not event rows) of backlash_sim --csv as arrays by column."""
    cols = defaultdict(list)
    with open(path) as f:
        for r in csv.DictReader(f):
            if r["event"]:
                continue
            for k in ("time", "load_position", "mesh_torque", "motor_torque"):
                cols[k].append(float(r[k]))
            cols["contact"].append(r["contact"])
    return {k: (v if k == "contact" else np.array(v)) for k, v in cols.items()}


def compliant(src, outdir):
    runs = []
    for path in glob.glob(os.path.join(src, "d1_c*.json")):
        with open(path) as f:
            d = json.load(f)
        runs.append((d["params"]["mesh_stiffness"], d["limit_cycle_error"], d["period"], d["contact_phases"]))
    runs.sort()
    with open(os.path.join(src, "d1_rigid.json")) as f:
        rigid = json.load(f)
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5))
    a, b, c, d = axes.flat
    cs = [r[0] for r in runs]
    a.semilogx(cs, [1e3 * r[1] for r in runs], "o-", color="#1f77b4", label="compliant mesh, ζ_c = 0.0744")
    a.axhline(1e3 * rigid["limit_cycle_error"], color="k", ls="--", lw=1,
              label="rigid teeth, e = 0.8 (the contact's restitution)")
    a.set_xlabel("mesh stiffness c [N·m/rad]")
    a.set_ylabel("limit-cycle error [mrad]")
    a.set_title("Thesis D1: the limit cycle tends to the rigid one as the teeth stiffen", fontsize=10)
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)
    s = read_samples(os.path.join(src, "d1_c1e4.csv"))
    t = s["time"]
    keep = t >= t[-1] - 13.0
    b.plot(t[keep], s["load_position"][keep], color="#1f77b4", lw=1)
    b.set_xlabel("time [s]")
    b.set_ylabel("load position θ_c [rad]", color="#1f77b4")
    b2 = b.twinx()
    b2.plot(t[keep], s["mesh_torque"][keep], color="#d62728", lw=0.8)
    b2.set_ylabel("mesh torque Q [N·m] (0 in the free play)", color="#d62728")
    b.set_title("D1 at c = 1e4 N·m/rad: one cycle — each reversal a train of short contact phases", fontsize=10)
    b.grid(True, alpha=0.3)
    r = read_samples(os.path.join(src, "robot_rigid.csv"))
    m = read_samples(os.path.join(src, "robot_compliant.csv"))
    c.plot(r["time"], r["load_position"], color="k", lw=1, label="rigid teeth")
    c.plot(m["time"], m["load_position"], color="#d62728", lw=0.7, label="compliant mesh, c = 8.6e4 N·m/rad")
    c.set_xlabel("time [s]")
    c.set_ylabel("load position θ_c [rad]")
    c.set_title("Robot joint, 1 kHz PID on the load (more derivative action):\nsettles on rigid teeth, "
                "excites the two-mass resonance on the compliant joint", fontsize=10)
    c.grid(True, alpha=0.3)
    c.legend(fontsize=8)
    w0, w1 = 8.0, 8.1
    for run, color, label in ((r, "k", "rigid teeth"), (m, "#d62728", "compliant mesh")):
        k = (run["time"] >= w0) & (run["time"] <= w1)
        d.plot(run["time"][k], run["motor_torque"][k], color=color, lw=1, label=label)
    d.set_xlabel("time [s]")
    d.set_ylabel("motor torque T_m [N·m]")
    d.set_title("The same, 0.1 s of the motor torque: the resonance (~74 Hz) in the loop", fontsize=10)
    d.grid(True, alpha=0.3)
    d.legend(fontsize=8)
    fig.tight_layout()
    save(fig, outdir, "compliant_joint")


def main(argv):
    if len(argv) >= 3 and argv[0] == "compliant":
        compliant(argv[1], argv[2])
        return 0
    if len(argv) >= 4 and argv[0] == "digital":
        digital(argv[1], argv[2], argv[3])
        return 0
    if len(argv) < 3 or argv[0] not in ("existence", "error", "delta", "phase", "surface"):
        print(__doc__)
        return 2
    kind, src, outdir = argv[0], argv[1], argv[2]
    if kind == "phase":
        phase(src, outdir, *(argv[3:4]))
        return 0
    rows = read_sweep(src)
    if kind == "existence" and len(argv) >= 4:
        existence(rows, outdir, read_sweep(argv[3]))
        return 0
    {"existence": existence, "error": error, "delta": delta, "surface": surface}[kind](rows, outdir)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
