"""The Python API (backlash_servo.core) against the command-line tools: every result bit for bit the CLI's.

Run with Debian's /usr/bin/python3 after `source build/devel/setup.bash` (scripts/run_tests.sh does):
    /usr/bin/python3 -m pytest test/python
"""
import cmath
import csv
import io
import json
import math
import os
import re
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import backlash_servo.core as core

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TOOLS = os.path.join(ROOT, "build", "devel", "lib", "backlash_servo")
THESIS = os.path.join(ROOT, "config", "thesis_limit_cycle.yaml")
WORKBENCH = os.path.join(ROOT, "config", "compare_example.yaml")

# A 100:1 robot joint with dry friction, gravity and a 1 kHz PID on a quantised encoder (the README's quick start).
ROBOT = {
    "motor_inertia": 2.0e-5, "load_inertia": 0.05, "motor_friction": 1.0e-4, "load_friction": 0.1,
    "gear_ratio": 0.01, "backlash": 0.00349, "restitution": 0.3, "load_torque": -2.0,
    "motor_coulomb_friction": 0.01, "control_law": "pid", "controller_rate": 1000.0,
    "load_encoder_resolution": 4096, "gain": 20.0, "derivative_gain": 0.05, "command": 0.5,
}


def tool(name, *args):
    p = subprocess.run([os.path.join(TOOLS, name)] + [str(a) for a in args], capture_output=True, text=True)
    return p.returncode, p.stdout, p.stderr


def write_yaml(path, config):
    with open(path, "w") as f:
        for key, value in config.items():
            f.write("%s: %s\n" % (key, json.dumps(value) if isinstance(value, str) else repr(value)))


def without_wall_time(result):
    return {k: v for k, v in result.items() if k != "wall_time"}


@pytest.mark.parametrize("config", [
    THESIS,
    ROBOT,
    {"zeta": 0.2, "inertia_ratio": 1.0, "friction_ratio": 0.4, "restitution": 0.6},
    {"load_coulomb_friction": 0.05, "compensation": "friction_feedforward", "compensation_friction": 0.05,
     "compensation_width": 0.01, "duration": 60.0},
])
def test_run_equals_backlash_sim_json(tmp_path, config):
    path = config
    if isinstance(config, dict):
        path = str(tmp_path / "joint.yaml")
        write_yaml(path, config)
    code, out, err = tool("backlash_sim", "--config", path, "--json")
    assert code == 0, err
    cli = json.loads(out)
    assert without_wall_time(core.run(config)) == without_wall_time(cli)
    assert without_wall_time(core.run(path)) == without_wall_time(cli)


def test_robot_equals_backlash_sim_json():
    arm = os.path.join(ROOT, "config", "three_joint_arm.yaml")
    code, out, err = tool("backlash_sim", "--config", arm, "--duration", 2, "--json")
    assert code == 0, err
    cli = json.loads(out)
    got = core.robot(arm, duration=2.0)
    assert without_wall_time(got) == without_wall_time(cli)
    assert [j["name"] for j in got["joints"]] == ["shoulder", "elbow", "wrist"]
    with pytest.raises(ValueError) as e:
        core.run(arm)  # a single joint's run never takes an arm's file as the default joint
    assert "describes an arm (joints:)" in str(e.value)


def test_errors_are_value_errors_with_the_tools_message(tmp_path):
    for bad, message in (({"restitution": 2.0}, "restitution: must be in [0, 1] (got 2)"),
                         ({"motor_inertai": 1.0}, "unknown key 'motor_inertai'")):
        path = str(tmp_path / "bad.yaml")
        write_yaml(path, bad)
        code, _, err = tool("backlash_sim", "--config", path)
        assert code == 2 and message in err
        for config in (bad, path):  # the same one-line message as the CLI, from a dict or the file
            with pytest.raises(ValueError) as e:
                core.run(config)
            assert message in str(e.value)
            assert "\n" not in str(e.value)


def test_settings_are_checked_as_the_tools_check_their_flags():
    # A value the CLI refuses is refused here too, naming the key (never taken, never pybind's cast error).
    n = 100
    t = [0.001 * k for k in range(n)]
    zeros = [0.0] * n
    for kwargs, words in (({"contact_band": float("nan")}, "contact_band"), ({"contact_band": -1.0}, "contact_band"),
                          ({"still_speed": float("nan")}, "still_speed"), ({"load_torque": float("inf")},
                                                                           "load_torque")):
        with pytest.raises(ValueError, match=words):
            core.identify(t, zeros, zeros, zeros, gear_ratio=1.0, **kwargs)
    with pytest.raises(ValueError, match="motor_effort"):
        core.Simulator({}).set_motor_torque(1e300)
    with pytest.raises(ValueError, match=r"harmonics: must be in \[1, 1000\] \(got 0\)"):
        core.frequency_response({"controller_rate": 100.0}, amplitude=0.1, frequency=1.0, harmonics=0)


def test_simulator_samples_equal_the_cli_csv(tmp_path):
    path = str(tmp_path / "robot.yaml")
    config = dict(ROBOT, duration=2.0)
    write_yaml(path, config)
    code, _, err = tool("backlash_sim", "--config", path, "--csv", str(tmp_path / "run.csv"), "--sample-rate", 200)
    assert code == 0, err
    with open(tmp_path / "run.csv") as f:
        rows = [r for r in csv.DictReader(f) if not r["event"]]
    sim = core.Simulator(config)
    got = sim.sample(2.0, 200.0)
    assert len(got["time"]) == len(rows) == 401
    for key in ("time", "load_position", "load_velocity", "motor_position", "motor_velocity", "gap", "mesh_torque",
                "motor_torque"):
        assert ["%.15g" % v for v in got[key]] == ["%.15g" % float(r[key]) for r in rows], key
    # Advancing to the end gives the run's final state exactly.
    fresh = core.Simulator(config)
    fresh.advance(2.0)
    final = core.run(config)["final_state"]
    assert fresh.state == final


def test_simulator_live_changes_and_refusals():
    sim = core.Simulator(ROBOT)
    sim.advance(0.5)
    before = sim.state
    with pytest.raises(ValueError, match="restitution"):
        sim.set({"restitution": 1.5})
    with pytest.raises(ValueError, match="publish_rate"):
        sim.set({"publish_rate": 10.0})
    assert sim.state == before  # a refused change changes nothing
    sim.set({"integral_gain": 50.0, "backlash": 0.002})
    sim.set_command(0.2)
    sim.advance(3.0)
    assert sim.time == 3.0
    assert abs(sim.state["load_position"] - 0.2) < 0.01


def test_sweep_equals_backlash_sweep(tmp_path):
    settings = {"zeta": [0.2, 0.5], "restitution": [0.0, 0.8], "controller_rate": 100.0}
    code, out, err = tool("backlash_sweep", "--zeta", "0.2,0.5", "--restitution", "0,0.8", "--controller-rate", 100)
    assert code == 0, err
    assert core.sweep_csv(settings) == out
    columns = core.sweep(settings)
    rows = list(csv.DictReader(io.StringIO(out)))
    assert columns["verdict"] == [r["verdict"] for r in rows]
    for key in ("zeta", "restitution", "limit_cycle_error", "period", "simulated_time"):
        expected = np.array([float(r[key]) if r[key] else np.nan for r in rows])
        np.testing.assert_array_equal(columns[key], expected)
    # The robot joint's restitution and backlash as axes, from a dict (what backlash_sweep --config does).
    path = str(tmp_path / "robot.yaml")
    write_yaml(path, ROBOT)
    code, out, err = tool("backlash_sweep", "--config", path, "--restitution", "0,0.6", "--backlash", "0.001,0.004")
    assert code == 0, err
    assert core.sweep_csv(dict(ROBOT, restitution=[0.0, 0.6], backlash=[0.001, 0.004])) == out
    # With the tracking figures (--tracking).
    code, out, err = tool("backlash_sweep", "--zeta", "0.2,0.5", "--restitution", "0,0.8", "--controller-rate", 100,
                          "--tracking")
    assert code == 0, err
    assert core.sweep_csv(settings, tracking=True) == out
    assert "steady_rms_error" in core.sweep(settings, tracking=True)


def test_monte_carlo_equals_backlash_sweep():
    """A tolerance study from Python: the CSV's columns of `backlash_sweep --monte-carlo`, draws given as text or
    tuples, and the summary's fractions counted from the verdicts."""
    code, out, err = tool("backlash_sweep", "--monte-carlo", 16, "--seed", 4, "--backlash", "uniform(0.05,0.5)",
                          "--zeta", "normal(0.35,0.1)")
    assert code == 0, err
    got = core.monte_carlo({}, {"backlash": ("uniform", 0.05, 0.5), "zeta": "normal(0.35,0.1)"}, 16, seed=4)
    rows = list(csv.DictReader(io.StringIO(out)))
    assert got["verdict"] == [r["verdict"] for r in rows]
    for key in ("zeta", "backlash", "limit_cycle_error", "period"):
        expected = np.array([float(r[key]) if r[key] else np.nan for r in rows])
        np.testing.assert_array_equal(got[key], expected)
    summary = got["summary"]
    for verdict, (fraction, low, high) in summary["verdicts"].items():
        assert fraction == got["verdict"].count(verdict) / 16
        assert low <= fraction <= high
    assert summary["text"] in err
    assert {k["key"] for k in summary["influences"]} == {"zeta", "backlash"}
    with pytest.raises(core.ConfigError, match="backlash"):
        core.monte_carlo({}, {"backlash": "uniform(-1,1)"}, 4)
    with pytest.raises(core.ConfigError, match="draws"):
        core.monte_carlo({"zeta": 0.3}, {}, 4)


def test_numpy_values_and_paths_are_taken_as_the_numbers_and_files_they_are(tmp_path):
    # numpy scalars and 1-D arrays and a pathlib.Path are what Python users pass: the same results as plain values.
    import pathlib
    plain = core.run({"restitution": 0.5, "gain": 2, "duration": 20.0})
    for value in (np.float64(0.5), np.float32(0.5)):  # (0.5: exact in single precision too)
        assert core.run({"restitution": value, "gain": np.int64(2), "duration": 20.0})["maxima"] == plain["maxima"]
    axes = core.sweep({"restitution": np.linspace(0.0, 0.8, 3), "zeta": np.array([0.2])})
    assert list(axes["restitution"]) == [0.0, 0.4, 0.8]
    assert core.sweep({"restitution": range(0, 1)})["restitution"][0] == 0.0
    path = tmp_path / "joint.yaml"
    path.write_text("restitution: 0.5\ngain: 2\nduration: 20.0\n")
    assert core.run(pathlib.Path(path))["maxima"] == plain["maxima"]
    # Values that are no number, or too big for one, are refused naming the key.
    for bad, words in (({"gain": 10 ** 400}, "gain"), ({"restitution": [[0.1, 0.2]]}, "restitution"),
                       ({"restitution": np.zeros((2, 2))}, "restitution"), ({"gain": object()}, "gain"),
                       ({"restitution": ["a"]}, "restitution")):
        with pytest.raises(ValueError, match=words):
            core.run(bad) if "restitution" not in bad or not isinstance(bad["restitution"], (list, np.ndarray)) \
                else core.sweep(bad)


def test_steady_error_is_where_the_joint_comes_to_rest():
    # The D1 servo (e = 0.8) under −0.3 N·m stops by the state rule 2.6e-6 rad short of its rest: the steady error
    # is the rest's, ρT_ext/K = −0.3 (K = ρ = 1), in run() and in every sweep row of the same joint.
    r = core.run({"restitution": 0.8, "load_torque": -0.3})
    assert r["verdict"] == "converged" and r["steady_basis"] == "equilibrium"
    assert abs(r["steady_error"] + 0.3) <= 1e-12 * 0.3
    assert abs(r["final_state"]["load_position"] - 1.0 + 0.3) > 1e-7
    columns = core.sweep({"restitution": [0.8], "load_torque": [-0.3]})
    assert columns["steady_error"][0] == r["steady_error"]
    held = core.run({"restitution": 0.5, "load_coulomb_friction": 0.2, "load_static_friction": 0.2})
    assert held["steady_basis"] == "held"
    assert held["steady_error"] == held["final_state"]["load_position"] - 1.0


def test_compare_equals_backlash_compare():
    code, out, err = tool("backlash_compare", "--config", WORKBENCH, "--json")
    assert code == 0, err
    cli = json.loads(out)
    strategies = cli["strategies"] if isinstance(cli, dict) else cli
    got = core.compare(WORKBENCH)
    assert [s["name"] for s in got] == [s["name"] for s in strategies]
    for mine, theirs in zip(got, strategies):
        for key, value in mine.items():
            assert theirs[key] == value, (mine["name"], key)


FIRST_CALLS = """
import sys, threading
import backlash_servo.core as core
calls = [lambda: core.Simulator({"restitution": 0.6}).sample(1.0, 100.0),
         lambda: core.sweep({"zeta": [0.2, 0.5], "restitution": [0.0]}),
         lambda: core.run({"restitution": 0.6, "duration": 5.0}),
         lambda: core.broadband_response({"controller_rate": 20.0, "restitution": 0.8}, amplitude=0.05,
                                         prbs_order=6),
         lambda: core.Simulator({"restitution": 0.6}).sample(1.0, 100.0)]
errors = []
def call(f):
    try:
        f()
    except Exception as e:
        errors.append(repr(e))
threads = [threading.Thread(target=call, args=(f,)) for f in calls]
for t in threads:
    t.start()
for t in threads:
    t.join()
print("answered", len(calls), errors)
"""


def test_first_calls_from_several_threads_at_once_do_not_deadlock():
    # Each try is a fresh interpreter, where the module's first numpy array is still to be made.
    for attempt in range(3):
        p = subprocess.run(["/usr/bin/python3", "-c", FIRST_CALLS], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr
        assert p.stdout.strip() == "answered 5 []", p.stdout + p.stderr


CTRL_C = """
import os, signal, sys, threading, time
import backlash_servo.core as core
threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
start = time.time()
try:
    core.run({"duration": 1e8}) if sys.argv[1] == "run" else core.Simulator({}).advance(1e8)
    print("finished")
except KeyboardInterrupt:
    print("interrupted after %.3f s" % (time.time() - start))
"""


@pytest.mark.parametrize("call", ["run", "advance"])
def test_ctrl_c_interrupts_a_long_computation(call):
    # 1e8 s of the D1 servo take minutes; Ctrl-C at 1 s raises KeyboardInterrupt within a fraction of a second.
    # (SIGINT as a terminal delivers it: a test runner started in the background passes it on ignored)
    p = subprocess.run(["/usr/bin/python3", "-c", CTRL_C, call], capture_output=True, text=True, timeout=120,
                       preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert p.stdout.startswith("interrupted after"), p.stdout + p.stderr
    assert float(p.stdout.split()[2]) < 10.0, p.stdout


def test_a_sample_request_beyond_memory_is_refused_naming_its_size():
    with pytest.raises(ValueError, match=r"1e\+12 samples \(1.44e\+05 GB\) exceed the limit"):
        core.Simulator({}).sample(1e12, 1.0)
    assert len(core.Simulator({}).sample(10.0, 100.0)["time"]) == 1001


def test_the_gil_is_released_while_the_core_computes():
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    start = time.time()
    # The grid's costliest point (elastic chatter of a light load, ~10^6 impacts).
    core.run({"zeta": 0.8, "inertia_ratio": 0.04, "friction_ratio": 1.0, "restitution": 1.0})
    elapsed = time.time() - start
    stop.set()
    t.join()
    # The counter ran alongside (about a tick per ms): it could not, had the run held the GIL (then ~0 ticks).
    assert elapsed > 0.05
    assert len(ticks) >= 10


def test_an_inline_profile_equals_the_yaml_file(tmp_path):
    # A dict holding `profile:` as a list of segments means what the same keys mean in a YAML file.
    path = tmp_path / "profile.yaml"
    path.write_text("controller_rate: 100.0\nprofile:\n  - ramp: {time: 0.0, target: 1.0, duration: 2.0}\n"
                    "  - step: {time: 30.0, target: 0.5}\n")
    config = {"controller_rate": 100.0, "profile": [{"ramp": {"time": 0.0, "target": 1.0, "duration": 2.0}},
                                                    {"step": {"time": 30.0, "target": 0.5}}]}
    code, out, err = tool("backlash_sim", "--config", str(path), "--json")
    assert code == 0, err
    assert without_wall_time(core.run(config)) == without_wall_time(json.loads(out))
    code, out, err = tool("backlash_sweep", "--config", str(path), "--zeta", "0.2,0.4")
    assert code == 0, err
    assert core.sweep_csv(dict(config, zeta=[0.2, 0.4])) == out


def test_describing_functions_and_harmonic_balance():
    # A = 2d: N = 1/2 - j/pi; within the free play nothing passes.
    n = core.backlash_df(0.3, 0.3)
    assert abs(n - (0.5 - 1j / np.pi)) < 1e-15
    assert core.backlash_df(0.1, 0.3) == 0
    assert abs(core.dead_zone_df(0.3, 0.15) - (1 - 2 / np.pi * (np.arcsin(0.5) + 0.5 * np.sqrt(0.75)))) < 1e-15
    # The type-1 loop rho*K / (J s^2 + f s) (J 0.1, f 0.48, K 20): every solution satisfies the balance, an unstable
    # cycle beside the free play and a stable one (the C++ test checks them against the closed form).
    g = lambda w: 20.0 / complex(-0.1 * w * w, 0.48 * w)  # noqa: E731
    found = core.harmonic_balance(g, 0.3, 1e-3, 1e3)
    assert [h["stable"] for h in found] == [False, True]
    for h in found:
        assert abs(g(h["frequency"]) * core.backlash_df(h["amplitude"], 0.3) + 1) < 1e-6
    assert 0.15 < found[0]["amplitude"] < found[1]["amplitude"]
    with pytest.raises(ValueError, match="backlash"):
        core.harmonic_balance(g, 0.0, 1e-3, 1e3)
    # G(jω) from a callable that returns no finite complex number: ConfigError naming g, what it returned and where.
    for bad, shown in [(lambda w: "x" * 500, "'xxx"), (lambda w: float("nan"), "nan"), (lambda w: [1.0], "[1.0]")]:
        with pytest.raises(core.ConfigError, match=r"g: must return a finite complex .*\(got " + re.escape(shown)):
            core.harmonic_balance(bad, 0.3, 1e-3, 1e3)
    assert core.harmonic_balance(lambda w: np.complex128(g(w)), 0.3, 1e-3, 1e3) == found  # numpy scalars are numbers


def test_limit_cycle_prediction_is_backlash_dfs_analysis(tmp_path):
    # The D1 loop at zeta = 0.1: the same predictions and exact cycle as `backlash_df --json`, the stable prediction's
    # balance holding (G N = -1) and its error measured against the exact cycle.
    config = {"zeta": 0.1, "inertia_ratio": 9.0, "friction_ratio": 0.4, "restitution": 1.0, "backlash": 0.3}
    a = core.limit_cycle_prediction(config)
    path = str(tmp_path / "loop.yaml")
    write_yaml(path, config)
    code, out, err = tool("backlash_df", "--config", path, "--json")
    assert code == 0, err
    cli = json.loads(out)

    def nulls(d):  # (the JSON writes NaN as null)
        return {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in d.items()}

    assert cli["predictions"] == [nulls(p) for p in a["predictions"]]
    assert cli["simulated"] == nulls(a["simulated"])
    assert a["simulated"]["verdict"] == "limit_cycle"
    stable = [h for h in a["predictions"] if h["stable"] and h["method"] == "classical"]
    assert len(stable) == 1
    assert cli["numerical_note"] == a["numerical_note"]
    h = stable[0]
    wn, zeta = a["natural_frequency"], a["zeta"]
    g = wn * wn / complex(-h["frequency"] ** 2, 2 * zeta * wn * h["frequency"])
    assert abs(g * core.backlash_df(h["amplitude"], 0.3) + 1) < 1e-6
    assert h["amplitude_error"] == h["amplitude"] / a["simulated"]["amplitude"] - 1
    with pytest.raises(ValueError, match="motor_encoder_resolution"):
        core.limit_cycle_prediction(dict(config, controller_rate=100.0, control_law="cascade", position_loop_gain=1.0,
                                         velocity_loop_gain=1.0, motor_encoder_resolution=4096))


def test_frequency_response_of_the_locked_joint_is_the_held_transfer_function():
    # Backlash 0: torque to motor speed is 1/(F + jwJ) times the hold's (1 - e^{-jwT})/(jwT) (J = 1, F = 0.8).
    p = core.frequency_response({"backlash": 0.0}, amplitude=0.3, frequency=3.0, channel="motor_torque:motor_velocity",
                                injection_rate=200.0, tolerance=1e-12)
    w, t = p["frequency"], 1.0 / 200.0
    expected = 1.0 / complex(0.8, w) * (1.0 - cmath.exp(-1j * w * t)) / (1j * w * t)
    assert p["periodic"]
    assert abs(p["response"] - expected) < 1e-9 * abs(expected)
    assert p["gain"] == pytest.approx(abs(expected), rel=1e-9)
    # The continuous P law takes the sine itself, on rigid teeth too: D1 without backlash is rho K/(rho K - J w^2 + j w F)
    # (rho = K = 1, J = 1, F = 0.8) to 1e-9; with dry friction the exact sine is refused naming the key.
    d = core.frequency_response({"backlash": 0.0}, amplitude=0.1, frequency=1.3)
    expected = 1.0 / complex(1.0 - 1.3 ** 2, 0.8 * 1.3)
    assert d["frequency"] == 1.3
    assert d["release_amplitude"] == 0.0  # nothing holds the teeth on a flank
    assert abs(d["response"] - expected) < 1e-9 * abs(expected)
    # The mechanics measured with the loops of a digital P drive closed: 1/(F + jwJ), the controller out of the ratio.
    c = core.frequency_response({"backlash": 0.0, "controller_rate": 500.0}, amplitude=0.2, frequency=2.0,
                                channel="torque_setpoint:motor_velocity", tolerance=1e-12)
    assert abs(c["response"] - 1.0 / complex(0.8, c["frequency"])) < 1e-9
    with pytest.raises(ValueError, match="load_static_friction"):
        core.frequency_response({"load_coulomb_friction": 0.01, "load_static_friction": 0.01}, amplitude=0.1,
                                frequency=1.0)


def test_broadband_response_of_the_locked_joint_is_coherent():
    r = core.broadband_response({"backlash": 0.0}, amplitude=0.5, channel="motor_torque:motor_velocity",
                                injection_rate=50.0, prbs_order=7, settle_periods=12, periods=2)
    t = 1.0 / 50.0
    e = math.exp(-0.8 * t)
    b = (1.0 - e) / 0.8
    z = np.exp(1j * r["frequency"] * t)
    assert len(r["frequency"]) == 63
    assert np.max(np.abs(r["h1"] - b / (z - e)) / np.abs(b / (z - e))) < 1e-9
    assert np.max(np.abs(r["coherence"] - 1.0)) < 1e-9
    # Injected into a 50 Hz P drive's torque set-point (loop closed, automatic settling): the same mechanics.
    q = core.broadband_response({"backlash": 0.0, "controller_rate": 50.0}, amplitude=0.5,
                                channel="torque_setpoint:motor_velocity", prbs_order=7, periods=2)
    assert np.max(np.abs(q["h1"] - b / (z - e)) / np.abs(b / (z - e))) < 1e-9
    with pytest.raises(ValueError, match="excitation"):
        core.broadband_response({}, amplitude=1.0, excitation="noise", channel="motor_torque:motor_velocity")


def test_dynamic_compliance_of_the_locked_joint_is_its_transfer_function():
    # A sine torque on the load, the continuous P law holding: theta_c/T_ext = 1/(K - J w^2 + j w F) (D1, rho = 1).
    p = core.frequency_response({"backlash": 0.0}, amplitude=0.3, frequency=0.7, channel="load_torque:load_position",
                                tolerance=1e-12)
    expected = 1.0 / complex(1.0 - 0.49, 0.8 * 0.7)
    assert p["periodic"]
    assert abs(p["response"] - expected) < 1e-9 * abs(expected)
    # The same disturbance stepped from Python, started on that forced response: it stays on it.
    z = expected * 0.3
    sim = core.Simulator({"backlash": 0.0, "load_position": z.imag, "motor_position": z.imag,
                          "load_velocity": (0.7j * z).imag, "motor_velocity": (0.7j * z).imag, "command": 0.0})
    sim.set_load_torque_wave(0.3, 0.7)
    sim.advance(10.0)
    assert abs(sim.state["load_position"] - (z * cmath.exp(7j)).imag) < 1e-9
    with pytest.raises(ValueError, match="load_wave"):
        sim.set_load_torque_wave(math.nan, 0.7)


def test_frequency_response_of_a_pressed_compliant_joint_under_an_exact_sine():
    # The sine itself on a compliant mesh pressed by a torque offset: the two-mass drive's w_m/T_m, no hold.
    cfg = {"backlash": 0.1, "gear_ratio": 0.5, "mesh_stiffness": 100.0, "mesh_damping": 1.0}
    p = core.frequency_response(cfg, amplitude=0.02, frequency=19.0, channel="motor_torque:motor_velocity",
                                offset=1.0, continuous=True, tolerance=1e-12)
    s = 19.0j
    m, l, k = 0.1 * s + 0.48, 0.9 * s + 0.32, 100.0 + 1.0 * s
    expected = 1.0 / (m + 0.25 * k * l / (s * l + k))
    assert p["periodic"] and p["frequency"] == 19.0
    assert abs(p["response"] - expected) < 1e-9 * abs(expected)


def test_simulator_in_effort_mode_follows_the_motor_torque():
    # Teeth pressed (a load torque), one body on the motor shaft: w(t) = (T/F)(1 - exp(-F t/J)), J = 1, F = 0.8,
    # with T the motor torque less the load torque reflected (rho = 1).
    sim = core.Simulator({"load_torque": -0.5})
    sim.set_motor_torque(2.0)
    sim.advance(3.0)
    t, torque = 3.0, 2.0 - 0.5
    assert sim.state["motor_velocity"] == pytest.approx(torque / 0.8 * (1.0 - math.exp(-0.8 * t)), rel=1e-12)
    assert sim.motor_torque == 2.0


def record_joint(config, samples):
    """The simulator in effort mode as the joint: a torque excitation held over 1 kHz samples, both angles recorded
    (time, motor_torque, motor_position, load_position)."""
    sim = core.Simulator(config)
    t, u, m, l = [], [], [], []
    for k in range(samples):
        tk = k / 1000.0
        sim.advance(tk)
        uk = 1.5 * math.sin(1.3 * tk) + 0.8 * math.sin(4.1 * tk + 0.5)
        sim.set_motor_torque(uk)
        s = sim.state
        t.append(tk)
        u.append(uk)
        m.append(s["motor_position"])
        l.append(s["load_position"])
    return t, u, m, l


def test_identify_recovers_a_joint_from_its_recording():
    # The simulator in effort mode records a joint under a torque excitation; identify() gets it back.
    t, u, m, l = record_joint({"restitution": 0.5, "load_coulomb_friction": 0.1, "load_torque": 0.2}, 30001)
    e = core.identify(t, u, m, l, gear_ratio=1.0)
    assert e["backlash"] == pytest.approx(0.3, abs=1e-9)
    assert e["load_inertia"] == pytest.approx(0.9, rel=1e-3)
    assert e["load_coulomb_friction"] == pytest.approx(0.1, rel=1e-3)
    assert e["restitution"] == pytest.approx(0.5, abs=1e-3)
    # The joint fit ran on these exact angles: every fitted key informed, a symmetric correlation matrix.
    assert e["joint_fit"] and "load_inertia" in e["fitted"] and all(e["informed"])
    c = e["correlation"]
    assert c.shape == (len(e["fitted"]), len(e["fitted"]))
    assert abs(c - c.T).max() < 1e-12 and abs(c.diagonal() - 1.0).max() < 1e-12
    assert e["rms_residual"] < 1e-6
    off = core.identify(t, u, m, l, gear_ratio=1.0, joint_fit="off", keys=["backlash", "load_inertia"])
    assert not off["joint_fit"] and "fitted" not in off and "motor_inertia" not in off
    assert off["load_inertia"] == off["load_inertia_initial"]
    with pytest.raises(ValueError, match="gear_ratio"):
        core.identify(t, u, m, l, gear_ratio=0.0)
    with pytest.raises(ValueError, match="gear_ratio"):
        core.identify(t, u, m, l)


def test_identify_measured_angles_from_a_prior_of_what_is_known():
    # The recording read through 2^16-count encoders; the prior states only the gear ratio and the resolutions (no
    # drive, no inertias): accepted, the count grids recognised, each estimate a number or a reason.
    t, u, m, l = record_joint({"restitution": 0.5, "load_coulomb_friction": 0.1, "load_torque": 0.2}, 30001)
    q = 2.0 * math.pi / 65536
    mq, lq = (np.round(np.asarray(x) / q) * q for x in (m, l))
    prior = {"gear_ratio": 1.0, "motor_encoder_resolution": 65536, "load_encoder_resolution": 65536}
    e = core.identify(t, u, mq, lq, prior=prior)
    assert e["measurement"]["motor_encoder_resolution"] == 65536
    assert e["measurement"]["load_encoder_resolution"] == 65536
    assert e["measurement"]["contact_band"] > 0.0
    assert e["backlash"] == pytest.approx(0.3, rel=0.05)
    for key in ("motor_inertia", "load_inertia", "motor_coulomb_friction", "load_coulomb_friction", "restitution"):
        assert math.isfinite(e[key]) or e["not_identifiable"][key], key
    # A motor inertia the prior states and `keys` leaves out is known: it holds its column, the load's follows.
    keys = ["backlash", "load_inertia", "motor_friction", "load_friction", "motor_coulomb_friction",
            "load_coulomb_friction", "load_torque"]
    known = core.identify(t, u, mq, lq, prior=dict(prior, motor_inertia=0.1), keys=keys, joint_fit="off")
    assert "motor_inertia" not in known
    assert known["load_inertia"] == pytest.approx(0.9, rel=0.05)
    unknown = core.identify(t, u, mq, lq, prior=prior, keys=keys + ["motor_inertia"], joint_fit="off")
    assert math.isnan(unknown["load_inertia"]) and "motor alone" in unknown["not_identifiable"]["load_inertia"]
    exact = core.identify(t, u, m, l, gear_ratio=1.0, joint_fit="off")
    assert exact["measurement"]["motor_noise"] == 0.0
    assert set(exact["not_identifiable"]) <= {"motor_static_friction", "load_static_friction"}  # (no rests here)


def test_identify_a_compliant_mesh_when_the_prior_says_so():
    # A prior with mesh_stiffness > 0 selects the compliant joint: its stiffness and damping are estimated (from a
    # guess 5x off), the restitution is not.
    t, u, m, l = record_joint({"mesh_stiffness": 1000.0, "mesh_damping": 2.0, "load_torque": 0.2}, 15001)
    prior = {"gear_ratio": 1.0, "mesh_stiffness": 5000.0}
    e = core.identify(t, u, m, l, prior=prior, joint_fit="off")
    assert e["mesh_stiffness"] == pytest.approx(1000.0, rel=1e-2)
    assert e["mesh_damping"] == pytest.approx(2.0, rel=1e-2)
    assert e["load_inertia"] == pytest.approx(0.9, rel=1e-4)
    assert e["backlash"] == pytest.approx(0.3, rel=1e-4)
    assert "restitution" not in e
    with pytest.raises(ValueError, match="restitution"):
        core.identify(t, u, m, l, prior=prior, keys=["restitution"])
