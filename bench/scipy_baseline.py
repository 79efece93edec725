#!/usr/bin/python3
"""The event-driven adaptive integrator a Python user would write: scipy.integrate.solve_ivp with events, the same
hybrid model as backlash_servo, tight tolerances. Reads the cases and reference maxima written by
`bench_core --reference-out FILE` and prints rows in the same table format, with the speed ratio to ours.

usage: scipy_baseline.py REFERENCE_FILE [--max-sim SECONDS]
       scipy_baseline.py --d1 SECONDS    one solution of App. D1 over SECONDS [s] (bench/thesis_vs_scipy.sh times it)
"""
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

STICK = 1e-7  # rad/s, relative speed below which a bounce is treated as sticking (as the C++ baselines do)


def simulate(p, duration, rtol=1e-10, atol=1e-12):
    jm, jl, fm, fl, k, rho, delta, e = p
    jt, ft = jm + rho * rho * jl, fm + rho * rho * fl
    cmd = 1.0
    state = {"mode": 0}  # 0 forward, 1 backward, 2 apart

    def acc_contact(x):
        return (rho * k * (cmd - x[0]) - ft * x[1]) / jt

    def mesh(x):
        return jl * acc_contact(x) + fl * x[1]

    def rhs(t, x):
        if state["mode"] != 2:
            a = acc_contact(x)
            return [x[1], a, x[1] / rho, a / rho]
        return [x[1], -fl * x[1] / jl, x[3], (k * (cmd - x[0]) - fm * x[3]) / jm]

    def separation(t, x):
        return mesh(x) if state["mode"] == 0 else -mesh(x)
    separation.terminal, separation.direction = True, -1

    def wall0(t, x):
        return x[0] - rho * x[2] if state["mode"] == 2 else 1.0
    wall0.terminal, wall0.direction = True, -1

    def wall1(t, x):
        return delta - (x[0] - rho * x[2]) if state["mode"] == 2 else 1.0
    wall1.terminal, wall1.direction = True, -1

    def vmax(t, x):
        return x[1]
    vmax.terminal, vmax.direction = False, -1

    x = np.zeros(4)
    t = 0.0
    maxima, events = [], 0
    while t < duration:
        evs = [separation, vmax] if state["mode"] != 2 else [wall0, wall1, vmax]
        sol = solve_ivp(rhs, (t, duration), x, method="DOP853", rtol=rtol, atol=atol, events=evs)
        ve = sol.t_events[-1]
        ye = sol.y_events[-1]
        for tv, yv in zip(ve, ye):
            if yv[0] > cmd:
                maxima.append((tv, yv[0]))
            events += 1
        if sol.status != 1:  # reached the end
            break
        # The terminal event that stopped the integration.
        t_stop, kind = None, None
        for j, te in enumerate(sol.t_events[:-1]):
            if len(te):
                t_stop, kind = te[-1], j
        t = t_stop
        x = sol.y_events[kind][-1].copy()
        events += 1
        if state["mode"] != 2:
            state["mode"] = 2
            continue
        w = kind  # 0: gap 0 wall, 1: gap delta wall
        x[2] = (x[0] - (delta if w == 1 else 0.0)) / rho
        v, u = x[1], rho * x[3] - x[1]
        ee = 0.0 if e * abs(u) < STICK else e
        x[1] = v + jm * (1 + ee) * u / jt
        x[3] = (x[1] - ee * u) / rho
        if v > 0 >= x[1] and x[0] > cmd:
            maxima.append((t, x[0]))
        if ee == 0.0:
            pressing = mesh(x) >= 0 if w == 0 else mesh(x) <= 0
            if pressing:
                state["mode"] = w
                x[3] = x[1] / rho
    return maxima, events


D1 = [0.1, 0.9, 0.48, 0.32, 1.0, 1.0, 0.3, 1.0]  # J_m, J_L, f_m, f_L, K, rho, Delta, e: the thesis' App. D1


def main(argv):
    if not argv:
        print(__doc__)
        return 2
    if argv[0] == "--d1":
        if len(argv) != 2:
            print("scipy_baseline.py: --d1 takes one duration [s]\n" + __doc__, file=sys.stderr)
            return 2
        maxima, events = simulate(D1, float(argv[1]))
        print("scipy D1: %d maxima, %d events" % (len(maxima), events))
        return 0
    max_sim = float(argv[argv.index("--max-sim") + 1]) if "--max-sim" in argv else 200.0
    for line in open(argv[0]):
        parts = line.split()
        name, duration, ours_wall = parts[0], float(parts[1]), float(parts[2])
        p = [float(v) for v in parts[3:11]]
        ref = [float(v) for v in parts[11:]]
        sim = min(duration, max_sim)
        start = time.perf_counter()
        maxima, events = simulate(p, sim)
        wall = time.perf_counter() - start
        n = min(len(maxima), len(ref))
        err = max((abs(maxima[i][1] - ref[i]) for i in range(n)), default=float("inf"))
        ratio = (wall / sim) / (ours_wall / duration)  # compare wall time per simulated second
        print("%-15s %-22s %11.1f %12.4g %10.0f %8d %7d %11.2e %9s" % (
            name, "scipy DOP853 1e-10", wall * 1e3, sim / wall, wall * 1e9 / max(events, 1), events, len(maxima),
            err, "%.0fx faster" % ratio))
        if n == 0:
            print("%-15s (scipy found no maxima: events were missed, the gap left the backlash)" % name)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
