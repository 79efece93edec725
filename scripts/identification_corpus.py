#!/usr/bin/env python3
"""A corpus of joints drawn at random, recorded as encoders give them, and backlash_identify's accuracy on it.

    identification_corpus.py generate --seed S --count N --out DIR [--first K] [--jobs J]
    identification_corpus.py evaluate DIR [DIR ...] [--jobs J] [--markdown] [--json FILE] [--known KEY,...]

`generate` draws each joint from wide ranges (a fixed seed: the same corpus on every machine), simulates 60 s at
1 kHz with the exact simulator and writes, per recording, `NNN.csv` (time, motor_torque, motor_position,
load_position: the torque held over each sample, both angles as the encoders read them — quantised to their counts,
Gaussian noise added outside the simulator, zeroed at t = 0 with the teeth at a random point of the play),
`NNN.prior.yaml` (what a user knows: the gear ratio and the encoders' resolutions) and `NNN.truth.yaml`.

Two kinds of excitation, alternating:
  experiment  backlash_identify --experiment (designed from rough guesses: the truth within a factor of 1.5) followed
              by a 1 kHz P drive on the load encoder — a closed-loop recording;
  engineer    what an engineer injects into the torque (rests at both ends; square, triangle, chirp and PRBS
              segments) plus a weak PD loop on the motor encoder that keeps the axis near its start.

Ranges (SI): gear ratio 0.005–1 (log), backlash 1–40 load-encoder counts, inertia split ρ²J_L/J_m 0.05–20 (log),
J_L 1e-3–10 kg·m² (log), Coulomb levels 1–30 % of the peak torque on each body (static 1–1.3 times), viscous time
constants 0.1–10 s (log), restitution 0–0.9, a load torque 5–20 % of the peak torque on half of the joints, encoders
4096–2^20 counts/rev (log), noise 0–2 counts on half of the recordings.

`evaluate` runs `backlash_identify --json` on every recording with its prior and prints, per recording kind, how
many estimates meet the targets (backlash within 5 % with the truth within 4 standard errors; inertias within 5 %;
Coulomb levels within 10 %, or 1 % of the peak torque on their shaft; restitution within 0.1), how many were declared
not identifiable, and how many recordings are honest: no estimate outside its target, or nothing estimated (exit 2)
with the reason. Needs `source build/devel/setup.bash` (ROS Python: /usr/bin/python3).
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

DURATION = 60.0  # [s]
RATE = 1000.0  # [Hz]
TWO_PI = 2.0 * math.pi
KEYS = ["backlash", "motor_inertia", "load_inertia", "motor_friction", "load_friction", "motor_coulomb_friction",
        "load_coulomb_friction", "load_torque", "restitution"]


def tool(name):
    """A backlash_servo program: on PATH, else in this checkout's build tree."""
    import shutil

    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build", "devel", "lib", "backlash_servo")
    return shutil.which(name) or os.path.join(here, name)


def log_uniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_joint(rng, index):
    """One joint, its encoders, noise and excitation kind (the draw's order is fixed: the corpus is the seed's)."""
    rho = log_uniform(rng, 0.005, 1.0)
    load_counts = int(round(2.0 ** rng.uniform(12.0, 20.0)))
    motor_counts = int(round(2.0 ** rng.uniform(12.0, 20.0)))
    backlash = rng.uniform(1.0, 40.0) * TWO_PI / load_counts
    load_inertia = log_uniform(rng, 1e-3, 10.0)
    split = log_uniform(rng, 0.05, 20.0)
    motor_inertia = rho * rho * load_inertia / split
    total = motor_inertia + rho * rho * load_inertia  # [kg·m²] at the motor
    # The motion's scale: the load swings by 5–30 backlashes at about 1 Hz; the peak torque follows from it.
    amplitude = backlash * log_uniform(rng, 5.0, 30.0)  # [rad] at the load
    peak = total * TWO_PI ** 2 * amplitude / rho  # [N·m] at the motor
    motor_coulomb = peak * rng.uniform(0.01, 0.3)
    load_coulomb = peak * rng.uniform(0.01, 0.3) / rho
    joint = {
        "gear_ratio": rho,
        "backlash": backlash,
        "motor_inertia": motor_inertia,
        "load_inertia": load_inertia,
        "motor_friction": motor_inertia / log_uniform(rng, 0.1, 10.0),
        "load_friction": load_inertia / log_uniform(rng, 0.1, 10.0),
        "motor_coulomb_friction": motor_coulomb,
        "motor_static_friction": motor_coulomb * rng.uniform(1.0, 1.3),
        "load_coulomb_friction": load_coulomb,
        "load_static_friction": load_coulomb * rng.uniform(1.0, 1.3),
        "restitution": rng.uniform(0.0, 0.9),
        "load_torque": 0.0,
    }
    with_load = rng.uniform() < 0.5
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    load_share = rng.uniform(0.05, 0.2)
    if with_load:
        joint["load_torque"] = sign * load_share * peak / rho
    noisy = rng.uniform() < 0.5
    motor_noise = rng.uniform(0.0, 2.0) if noisy else 0.0  # [counts]
    load_noise = rng.uniform(0.0, 2.0) if noisy else 0.0
    return {
        "index": index,
        "kind": "experiment" if index % 2 == 0 else "engineer",
        "joint": joint,
        "motor_counts": motor_counts,
        "load_counts": load_counts,
        "motor_noise_counts": motor_noise,
        "load_noise_counts": load_noise,
        "peak_torque": peak,
        "amplitude": amplitude,
        "start_gap": rng.uniform(0.0, 1.0) * backlash,
        "guess": [log_uniform(rng, 1.0 / 1.5, 1.5) for _ in range(4)],
        "signal_seed": int(rng.integers(0, 2 ** 31)),
        "noise_seed": int(rng.integers(0, 2 ** 31)),
    }


def quantise(angle, counts):
    step = TWO_PI / counts
    return np.round(angle / step) * step


def base_config(draw):
    j = draw["joint"]
    total = j["motor_inertia"] + j["gear_ratio"] ** 2 * j["load_inertia"]
    cfg = dict(j)
    # The P gain of the drive (experiment) and of the simulator's checks: ω_n = 2π·2 rad/s.
    cfg["gain"] = total * (TWO_PI * 2.0) ** 2 / j["gear_ratio"]
    cfg["contact"] = "none"
    cfg["load_position"] = 0.0
    cfg["motor_position"] = -draw["start_gap"] / j["gear_ratio"]
    return cfg


def engineer_signal(draw):
    """The injected torque at each sample [N·m]: rests, square, triangle, chirp, PRBS, rest."""
    rng = np.random.default_rng(draw["signal_seed"])
    u = draw["peak_torque"]
    t = np.arange(int(DURATION * RATE)) / RATE
    s = np.zeros_like(t)
    square = (t >= 2) & (t < 14)
    s[square] = u * np.sign(np.sin(TWO_PI * 1.0 * (t[square] - 2) + 1e-9))
    tri = (t >= 14) & (t < 26)
    phase = ((t[tri] - 14) * 0.5) % 1.0
    s[tri] = u * (4.0 * np.abs(phase - 0.5) - 1.0)
    chirp = (t >= 26) & (t < 41)
    tc = t[chirp] - 26
    f0, f1, length = 0.2, 5.0, 15.0
    s[chirp] = u * np.sin(TWO_PI * (f0 * tc + 0.5 * (f1 - f0) / length * tc ** 2))
    prbs = (t >= 41) & (t < 56)
    holds = rng.choice([-1.0, 1.0], size=int(15.0 / 0.05) + 1)
    s[prbs] = u * holds[((t[prbs] - 41) / 0.05).astype(int)]
    return s


def simulate(draw):
    """The true angles and the applied torque at each sample (the torque held until the next)."""
    import backlash_servo.core as core

    j = draw["joint"]
    rho = j["gear_ratio"]
    total = j["motor_inertia"] + rho * rho * j["load_inertia"]
    n = int(DURATION * RATE)
    cfg = base_config(draw)
    if draw["kind"] == "experiment":
        cfg.update({"control_law": "proportional", "controller_rate": RATE,
                    "load_encoder_resolution": draw["load_counts"]})
        cfg["profile"] = experiment_profile(draw, cfg)
        sim = core.Simulator(cfg)
        out = sim.sample((n - 1) / RATE, RATE)
        return out["time"][:n], out["motor_torque"][:n], out["motor_position"][:n], out["load_position"][:n]
    # The engineer's signal through a weak PD on the motor encoder (0.3 Hz, damping 0.7).
    sim = core.Simulator(cfg)
    signal = engineer_signal(draw)
    wn = TWO_PI * 0.3
    kp, kd = total * wn * wn, 2.0 * 0.7 * total * wn
    noise = np.random.default_rng(draw["signal_seed"] + 1)
    time_, torque, motor, load = (np.zeros(n) for _ in range(4))
    start = None
    previous = None
    for k in range(n):
        s = sim.state
        reading = quantise(s["motor_position"], draw["motor_counts"]) + \
            noise.normal(0.0, draw["motor_noise_counts"] * TWO_PI / draw["motor_counts"])
        start = reading if start is None else start
        speed = 0.0 if previous is None else (reading - previous) * RATE
        previous = reading
        u = signal[k] - kp * (reading - start) - kd * speed
        time_[k], torque[k], motor[k], load[k] = k / RATE, u, s["motor_position"], s["load_position"]
        sim.set_motor_torque(u)
        sim.advance((k + 1) / RATE)
    return time_, torque, motor, load


def experiment_profile(draw, cfg):
    """backlash_identify --experiment, designed from rough guesses of the joint (the truth within 1.5×)."""
    import tempfile

    import yaml

    j = draw["joint"]
    g = draw["guess"]
    guess = {"gear_ratio": j["gear_ratio"], "backlash": j["backlash"] * g[0], "motor_inertia": j["motor_inertia"] * g[1],
             "load_inertia": j["load_inertia"] * g[2], "motor_friction": j["motor_friction"] * g[3],
             "load_friction": j["load_friction"] * g[3], "gain": cfg["gain"], "control_law": "proportional",
             "controller_rate": RATE, "load_encoder_resolution": draw["load_counts"]}
    with tempfile.TemporaryDirectory() as d:
        prior = os.path.join(d, "guess.yaml")
        with open(prior, "w") as f:
            yaml.safe_dump(guess, f)
        out = os.path.join(d, "profile.yaml")
        subprocess.run([tool("backlash_identify"), "--experiment", "--config", prior, "--duration", str(DURATION),
                        "--travel", repr(max(draw["amplitude"], 3.0 * guess["backlash"])), "--output", out],
                       check=True, stderr=subprocess.DEVNULL)
        with open(out) as f:
            return yaml.safe_load(f)


def write_recording(args):
    draw, out_dir = args
    t, u, motor, load = simulate(draw)
    rng = np.random.default_rng(draw["noise_seed"])
    mc, lc = draw["motor_counts"], draw["load_counts"]
    # Encoders: zeroed at t = 0, quantised to their counts, noise added outside the simulator.
    motor_read = quantise(motor - motor[0], mc) + rng.normal(0.0, draw["motor_noise_counts"] * TWO_PI / mc, len(t))
    load_read = quantise(load - load[0], lc) + rng.normal(0.0, draw["load_noise_counts"] * TWO_PI / lc, len(t))
    name = os.path.join(out_dir, "%03d" % draw["index"])
    with open(name + ".csv", "w") as f:
        f.write("time,motor_torque,motor_position,load_position\n")
        for row in zip(t, u, motor_read, load_read):
            f.write("%.6f,%.12g,%.12g,%.12g\n" % row)
    with open(name + ".prior.yaml", "w") as f:
        f.write("gear_ratio: %r\nmotor_encoder_resolution: %d\nload_encoder_resolution: %d\n"
                % (draw["joint"]["gear_ratio"], mc, lc))
    truth = dict(draw["joint"])
    truth.update({k: draw[k] for k in ("kind", "motor_counts", "load_counts", "motor_noise_counts",
                                       "load_noise_counts", "peak_torque")})
    with open(name + ".truth.json", "w") as f:
        json.dump(truth, f, indent=1)
    return name


def generate(args):
    rng = np.random.default_rng(args.seed)
    draws = [draw_joint(rng, i) for i in range(args.first + args.count)][args.first:]
    os.makedirs(args.out, exist_ok=True)
    with ProcessPoolExecutor(args.jobs) as pool:
        for name in pool.map(write_recording, [(d, args.out) for d in draws]):
            print("wrote", name + ".csv", flush=True)


def identify(job):
    """backlash_identify on one recording; `known` keys are stated in the prior with their true values and not fitted
    (what a datasheet gives)."""
    name, known = job
    prior = name + ".prior.yaml"
    command = [tool("backlash_identify"), "--data", name + ".csv", "--json"]
    if known:
        with open(name + ".truth.json") as f:
            truth = json.load(f)
        with open(prior) as f:
            text = f.read()
        prior = name + ".known.yaml"
        with open(prior, "w") as f:
            f.write(text + "".join("%s: %r\n" % (key, truth[key]) for key in known))
        command += ["--fit", ",".join(key for key in KEYS if key not in known)]
    start = time.monotonic()
    run = subprocess.run(command + ["--config", prior], capture_output=True, text=True)
    elapsed = time.monotonic() - start
    result = json.loads(run.stdout) if run.returncode == 0 and run.stdout.strip() else None
    return name, run.returncode, result, run.stderr.strip().splitlines()[-1:] if run.returncode else [], elapsed


def judge(truth, estimates):
    """Per target, one of 'ok', 'miss' (a value outside the target) or 'declared' (reported not identifiable)."""
    peak = truth["peak_torque"]
    rho = truth["gear_ratio"]
    out = {}

    def get(key):
        e = estimates.get(key)
        if e is None or e.get("identifiable") is False or e.get("value") is None:
            return None
        return e

    e = get("backlash")
    if e is None:
        out["backlash"] = "declared"
    else:
        err = abs(e["value"] - truth["backlash"])
        se = e.get("standard_error") or float("nan")
        out["backlash"] = "ok" if err <= 0.05 * truth["backlash"] and err <= 4.0 * se else "miss"
    for key in ("motor_inertia", "load_inertia"):
        e = get(key)
        out[key] = "declared" if e is None else (
            "ok" if abs(e["value"] - truth[key]) <= 0.05 * truth[key] else "miss")
    # Coulomb levels: within 10 % of the level, or of 1 % of the peak torque (a level near zero), on its own shaft.
    for key, scale in (("motor_coulomb_friction", peak), ("load_coulomb_friction", peak / rho)):
        e = get(key)
        out[key] = "declared" if e is None else (
            "ok" if abs(e["value"] - truth[key]) <= max(0.1 * truth[key], 0.01 * scale) else "miss")
    e = get("restitution")
    out["restitution"] = "declared" if e is None else (
        "ok" if abs(e["value"] - truth["restitution"]) <= 0.1 else "miss")
    return out


def evaluate(args):
    names = sorted(os.path.join(d, f[:-4]) for d in args.dir for f in os.listdir(d) if f.endswith(".csv"))
    rows = []
    with ProcessPoolExecutor(args.jobs) as pool:
        for name, code, result, err, elapsed in pool.map(identify, [(name, args.known) for name in names]):
            with open(name + ".truth.json") as f:
                truth = json.load(f)
            verdicts = judge(truth, result["estimates"]) if result else {}
            verdicts.update({key: "known" for key in args.known if key in verdicts})
            label = os.path.relpath(name, os.path.dirname(os.path.dirname(name))) if len(args.dir) > 1 else \
                os.path.basename(name)
            rows.append({"name": label, "kind": truth["kind"], "exit": code, "seconds": elapsed,
                         "verdicts": verdicts, "error": err, "truth": truth,
                         "estimates": result["estimates"] if result else None})
            line = " ".join("%s:%s" % (k.replace("_friction", "").replace("motor_", "m_").replace("load_", "L_"), v)
                            for k, v in verdicts.items())
            print("%s %-10s exit %d %5.1f s  %s %s" % (label, truth["kind"], code, elapsed, line,
                                                      " ".join(err)), flush=True)
    summarise(rows, args.markdown)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


def summarise(rows, markdown):
    targets = ["backlash", "motor_inertia", "load_inertia", "motor_coulomb_friction", "load_coulomb_friction",
               "restitution"]
    print()
    header = "| recordings | estimated | " + " | ".join(targets) + " | honest (no miss) | time max |"
    print(header if markdown else header.replace("|", " "))
    if markdown:
        print("|" + "---|" * (len(targets) + 4))
    for kind in ("experiment", "engineer", "all"):
        sub = [r for r in rows if kind == "all" or r["kind"] == kind]
        if not sub:
            continue
        cells = []
        for key in targets:
            ok = sum(1 for r in sub if r["verdicts"].get(key) == "ok")
            declared = sum(1 for r in sub if r["verdicts"].get(key) == "declared")
            missed = sum(1 for r in sub if r["verdicts"].get(key) == "miss")
            known = sum(1 for r in sub if r["verdicts"].get(key) == "known")
            cells.append("known" if known and not ok + declared + missed else
                         "%d ok, %d declared" % (ok, declared) + (", %d miss" % missed if missed else ""))
        # Honest: every estimate within its target or declared, or nothing estimated with the reason (exit 2).
        honest = sum(1 for r in sub if (r["exit"] == 2 and r["error"]) or
                     (r["verdicts"] and all(v != "miss" for v in r["verdicts"].values())))
        estimated = sum(1 for r in sub if r["exit"] == 0)
        line = "| %s (%d) | %d | %s | %d | %.1f s |" % (kind, len(sub), estimated, " | ".join(cells), honest,
                                                         max(r["seconds"] for r in sub))
        print(line if markdown else line.replace("|", " "))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    g = sub.add_parser("generate")
    g.add_argument("--seed", type=int, required=True)
    g.add_argument("--count", type=int, default=40)
    g.add_argument("--first", type=int, default=0, help="skip the first K draws (a subset of the same corpus)")
    g.add_argument("--out", required=True)
    g.add_argument("--jobs", type=int, default=2)
    e = sub.add_parser("evaluate")
    e.add_argument("dir", nargs="+", help="corpus directories (several: one table over them all)")
    e.add_argument("--jobs", type=int, default=2)
    e.add_argument("--markdown", action="store_true")
    e.add_argument("--known", type=lambda text: [key for key in text.split(",") if key], default=[],
                   help="keys stated in every prior with their true values and not fitted, e.g. motor_inertia "
                        "(a datasheet's value)")
    e.add_argument("--json")
    args = parser.parse_args()
    generate(args) if args.command == "generate" else evaluate(args)


if __name__ == "__main__":
    sys.exit(main())
