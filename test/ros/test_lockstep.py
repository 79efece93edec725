#!/usr/bin/python3
"""Lockstep (sync: true): a closed loop through ROS is deterministic and equals the same law inside the drive."""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rostest  # noqa: E402

from helpers import bag_contents, run_cli  # noqa: E402


def run_loop(bag_dir, name, port, stop_after, extra=()):
    """One external_controller.launch run with its own master on `port`; returns the bag path."""
    env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % port)
    subprocess.run(["roslaunch", "-p", str(port), "backlash_servo", "external_controller.launch", "sync:=true",
                    "record:=true", "bag_dir:=" + bag_dir, "bag_name:=" + name, "stop_after:=%g" % stop_after]
                   + list(extra), env=env, check=False, capture_output=True, timeout=180)
    return os.path.join(bag_dir, name + ".bag")


def run_arm(bag_dir, name, port, stop_after):
    """The example arm driven by the rospy template (robot.launch controller:=python) at 1 kHz; the bag's path."""
    env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % port)
    subprocess.run(["roslaunch", "-p", str(port), "backlash_servo", "robot.launch", "controller:=python",
                    "record:=true", "bag_dir:=" + bag_dir, "bag_name:=" + name, "stop_after:=%g" % stop_after,
                    "publish_rate:=1000", "real_time_factor:=0"], env=env, check=False, capture_output=True, timeout=180)
    return os.path.join(bag_dir, name + ".bag")


def serialized(msg):
    import io
    buf = io.BytesIO()
    msg.serialize(buf)
    return buf.getvalue()


def quantise(angle, counts):
    return 2.0 * math.pi / counts * math.floor(counts * angle / (2.0 * math.pi))


class Lockstep(unittest.TestCase):
    def test_two_runs_give_identical_bags(self):
        with tempfile.TemporaryDirectory() as d:
            a = bag_contents(run_loop(d, "a", 11411, 60))
            b = bag_contents(run_loop(d, "b", 11412, 60))
        self.assertEqual(a["/joint_states"][0].header.stamp.to_nsec(), 0)  # sim time starts at 0
        self.assertEqual(len(a["/joint_states"]), 6001)  # every step of 10 ms over 60 s, none dropped
        self.assertEqual(len(a["/motor_effort"]), 6001)  # one answer per state
        for topic in ("/joint_states", "/motor_effort", "/backlash_state", "/limit_cycle"):
            self.assertEqual(len(a[topic]), len(b[topic]), topic)
            for m, n in zip(a[topic], b[topic]):
                self.assertEqual(serialized(m), serialized(n), topic)  # bit for bit (NaN fields included)

    def test_python_template_on_quantised_encoders_is_deterministic(self):
        # The rospy template (float time arithmetic: stamp.to_sec() differences) reads encoder_states, which effort mode publishes
        # at every sample with the plant's encoders; two runs give bit-identical bags.
        with tempfile.TemporaryDirectory() as d:
            config = os.path.join(d, "joint.yaml")
            with open(os.path.join(os.path.dirname(__file__), "..", "..", "config", "external_controller.yaml")) as f:
                text = f.read()
            with open(config, "w") as f:
                f.write(text + "\nbacklash: 0.05\nload_encoder_resolution: 4096\nmotor_encoder_resolution: 1000\n")
            extra = ("controller:=python", "config:=" + config, "kp:=2.0", "kd:=0.5", "ki:=0.1")
            a = bag_contents(run_loop(d, "a", 11414, 20, extra))
            b = bag_contents(run_loop(d, "b", 11415, 20, extra))
        self.assertEqual(len(a["/joint_states"]), 2001)
        self.assertEqual(len(a["/encoder_states"]), 2001)  # one reading per state, in effort mode too
        self.assertEqual(len(a["/motor_effort"]), 2001)  # one answer per state
        for topic in ("/joint_states", "/encoder_states", "/motor_effort", "/backlash_state"):
            self.assertEqual(a[topic], b[topic], topic)
        n_load, n_motor = 4096, 1000
        for js, enc in zip(a["/joint_states"], a["/encoder_states"]):
            self.assertEqual(js.header.stamp, enc.header.stamp)
            self.assertEqual(enc.position[0], quantise(js.position[0], n_motor))
            self.assertEqual(enc.position[1], quantise(js.position[1], n_load))
        # The template's law on the readings: u_0 = kp e_0 at the first state (no Δt yet), then the PID.
        e0 = 1.0 - a["/encoder_states"][0].position[1]
        self.assertAlmostEqual(a["/motor_effort"][0].data, 2.0 * e0, delta=1e-12)
        y0, y1 = a["/encoder_states"][0].position[1], a["/encoder_states"][1].position[1]
        e1 = 1.0 - y1
        self.assertAlmostEqual(a["/motor_effort"][1].data, 2.0 * e1 + 0.1 * 0.01 * e1 - 0.5 * (y1 - y0) / 0.01,
                               delta=1e-9)

    def test_external_loop_equals_the_sampled_drive(self):
        # The example PID with kp = K, ki = kd = 0 answers u_k = K (θ_R − θ_c(t_k)) for the state at t_k, applied on
        # [t_k, t_k+1): exactly the P law sampled at 100 Hz without delay inside the drive.
        cli = json.loads(run_cli("--config", os.path.join(os.path.dirname(__file__), "..", "..", "config",
                                                          "external_controller.yaml"),
                                 "--controller-rate", "100", "--json"))
        with tempfile.TemporaryDirectory() as d:
            bag = bag_contents(run_loop(d, "p", 11413, cli["simulated_time"] + 1.0))
        last = bag["/limit_cycle"][-1]
        self.assertEqual(cli["verdict"], "limit_cycle")
        self.assertEqual(last.verdict, "limit_cycle")
        self.assertAlmostEqual(last.error, cli["limit_cycle_error"], delta=1e-9)
        maxima = [m for m in bag["/limit_cycle"] if m.maxima_observed > 0]
        first = min(maxima, key=lambda m: m.maxima_observed)
        self.assertAlmostEqual(first.last_maximum_position, cli["maxima"][0]["position"], delta=1e-9)

    def test_an_arm_driven_from_outside_is_deterministic_and_exact(self):
        # Every joint of the example arm answered by one motor_effort (a JointState of efforts by name) per state:
        # two runs give identical bags; the torque each motor carries over [t_k, t_k+1) is the answer to the state at
        # t_k; the template's first answers follow its law on the encoder readings; the held arm's gravity is carried
        # through each gear.
        joints = ["shoulder", "elbow", "wrist"]
        with tempfile.TemporaryDirectory() as d:
            a = bag_contents(run_arm(d, "arm_a", 11416, 2.0))
            b = bag_contents(run_arm(d, "arm_b", 11417, 2.0))
        states, answers, readings = a["/joint_states"], a["/motor_effort"], a["/encoder_states"]
        self.assertEqual(len(states), 2001)  # every step of 1 ms over 2 s
        self.assertEqual(len(answers), 2001)  # one answer per state
        self.assertEqual(len(readings), 2001)
        topics = ["/joint_states", "/encoder_states", "/motor_effort"]
        topics += ["/%s/%s" % (j, t) for j in joints for t in ("backlash_state", "limit_cycle")]
        for topic in topics:
            self.assertEqual(len(a[topic]), len(b[topic]), topic)
            for m, n in zip(a[topic], b[topic]):
                self.assertEqual(serialized(m), serialized(n), topic)
        names = list(states[0].name)
        self.assertEqual(names[:3], joints)
        motor = {j: names[3 + i] for i, j in enumerate(joints)}
        for k in range(len(states) - 1):
            self.assertEqual(answers[k].header.stamp, states[k].header.stamp)
            self.assertEqual(sorted(answers[k].name), sorted(joints))
            nxt = states[k + 1]
            for j, u in zip(answers[k].name, answers[k].effort):
                self.assertEqual(nxt.effort[nxt.name.index(motor[j])], u, (k, j))
        # Encoder readings: the true load angles on the YAML's 17-bit load encoder.
        for js, enc in zip(states, readings):
            self.assertEqual(list(enc.name), names)
            for j in joints:
                self.assertEqual(enc.position[names.index(j)], quantise(js.position[names.index(j)], 131072))
        # The template's first two answers: kp e_0, then kp e_1 + ki Δt e_1 − kd (y_1 − y_0)/Δt, with each joint's
        # own PID gains from the YAML (shoulder: 22.5, 45, 1.05).
        y0 = readings[0].position[0]
        y1 = readings[1].position[0]
        e0, e1 = 0.3 - y0, 0.3 - y1
        u = dict(zip(answers[0].name, answers[0].effort))
        self.assertAlmostEqual(u["shoulder"], 22.5 * e0, delta=1e-12)
        u = dict(zip(answers[1].name, answers[1].effort))
        self.assertAlmostEqual(u["shoulder"], 22.5 * e1 + 45.0 * 0.001 * e1 - 1.05 * (y1 - y0) / 0.001, delta=1e-9)
        # Held at its commands, each motor carries its load's gravity through its gear (the mean over the last
        # 0.5 s; the mesh torque on each load is gravity's, so the motor's is −ρ times it on average).
        last = [js for js in states if js.header.stamp.to_sec() >= 1.5]
        for i, j in enumerate(joints):
            mesh = sum(js.effort[i] for js in last) / len(last)
            torque = sum(js.effort[3 + i] for js in last) / len(last)
            rho = 0.02 if j == "wrist" else 0.01
            self.assertAlmostEqual(torque, rho * mesh, delta=0.05 * abs(rho * mesh), msg=j)
            self.assertGreater(abs(mesh), 0.01, j)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "lockstep", Lockstep)
