#!/usr/bin/python3
"""Writes sim_cases.txt: the backlash_sim argument lines whose outputs test_golden.cpp pins. Deterministic (seeded);
run once, the file is committed."""
import random

rng = random.Random(20261123)
cases = [
    "",  # thesis App. D1 until settled
    "--zeta 0.5 --inertia-ratio 1 --friction-ratio 0.4",  # Fig. 31
    "--backlash 0",  # rigid mesh
    "--backlash 0 --duration 30",
    "--zeta 0.1 --inertia-ratio 1 --friction-ratio 0.4 --restitution 0.6 --max-duration 400",  # irregular
    "--zeta 0.8 --inertia-ratio 0.25 --friction-ratio 0.2 --restitution 0.8",
    "--zeta 0.3 --inertia-ratio 4 --friction-ratio 1 --restitution 0",
    "--contact none --load-position 0.1 --motor-position 0 --duration 20",
    "--contact backward --duration 20",
    "--command -0.5 --duration 25",
    "--gear-ratio 3 --duration 40",
    "--duration 7.3",
]
for i in range(56):
    zeta = rng.choice([0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0, 1.5])
    ir = rng.choice([0.04, 0.1, 0.25, 1, 4, 9, 30])
    fr = rng.choice([0, 0.2, 0.4, 0.6, 0.8, 1])
    e = rng.choice([0, 0.3, 0.6, 0.8, 1])
    delta = rng.choice([0, 0.05, 0.3, 1.0])
    wn = rng.choice([0.5, 1, 3])
    rho = rng.choice([0.5, 1, 2])
    cmd = rng.choice([1, -1, 0.3, 2.5])
    args = (f"--zeta {zeta} --inertia-ratio {ir} --friction-ratio {fr} --restitution {e} --backlash {delta} "
            f"--natural-frequency {wn} --gear-ratio {rho} --command {cmd}")
    start = rng.random()
    if start < 0.3 and delta > 0:
        g = round(rng.uniform(0.1, 0.9) * delta, 6)
        args += f" --contact none --load-position {g} --motor-position 0"
        args += f" --load-velocity {round(rng.uniform(-1, 1), 4)} --motor-velocity {round(rng.uniform(-1, 1), 4)}"
    elif start < 0.5:
        v = round(rng.uniform(-1, 1), 4)
        args += f" --load-velocity {v} --motor-velocity {v / rho!r}"
    if rng.random() < 0.5:
        args += f" --duration {round(rng.uniform(1, 60), 3)}"
    else:
        args += " --max-duration 300"
    cases.append(args)
with open("sim_cases.txt", "w") as f:
    f.write("\n".join(cases) + "\n")
