#!/usr/bin/python3
"""Lockstep (sync: true): a closed loop through ROS is deterministic and equals the same law inside the drive."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rosbag  # noqa: E402
import rostest  # noqa: E402

from helpers import run_cli  # noqa: E402


def run_loop(bag_dir, name, port, stop_after, extra=()):
    """One external_controller.launch run with its own master on `port`; returns the bag path."""
    env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % port)
    subprocess.run(["roslaunch", "-p", str(port), "backlash_servo", "external_controller.launch", "sync:=true",
                    "record:=true", "bag_dir:=" + bag_dir, "bag_name:=" + name, "stop_after:=%g" % stop_after]
                   + list(extra), env=env, check=False, capture_output=True, timeout=180)
    return os.path.join(bag_dir, name + ".bag")


def contents(path):
    """Every recorded message by topic; stamps relative to the first (the clock starts at the run's wall time)."""
    out = {}
    t0 = None
    with rosbag.Bag(path) as bag:
        for topic, msg, _ in bag.read_messages():
            if hasattr(msg, "header"):
                stamp = msg.header.stamp.to_nsec()
                t0 = stamp if t0 is None else t0
                msg.header.stamp.secs, msg.header.stamp.nsecs = divmod(stamp - t0, 10**9)
            out.setdefault(topic, []).append(msg)
    return out


class Lockstep(unittest.TestCase):
    def test_two_runs_give_identical_bags(self):
        with tempfile.TemporaryDirectory() as d:
            a = contents(run_loop(d, "a", 11411, 60))
            b = contents(run_loop(d, "b", 11412, 60))
        self.assertEqual(len(a["/joint_states"]), 6001)  # every step of 10 ms over 60 s, none dropped
        self.assertEqual(len(a["/motor_effort"]), 6001)  # one answer per state
        for topic in ("/joint_states", "/motor_effort", "/backlash_state", "/limit_cycle"):
            self.assertEqual(len(a[topic]), len(b[topic]), topic)
            for m, n in zip(a[topic], b[topic]):
                self.assertEqual(m, n, topic)

    def test_external_loop_equals_the_sampled_drive(self):
        # The example PID with kp = K, ki = kd = 0 answers u_k = K (θ_R − θ_c(t_k)) for the state at t_k, applied on
        # [t_k, t_k+1): exactly the P law sampled at 100 Hz without delay inside the drive.
        cli = json.loads(run_cli("--config", os.path.join(os.path.dirname(__file__), "..", "..", "config",
                                                          "external_controller.yaml"),
                                 "--controller-rate", "100", "--json"))
        with tempfile.TemporaryDirectory() as d:
            bag = contents(run_loop(d, "p", 11413, cli["simulated_time"] + 1.0))
        last = bag["/limit_cycle"][-1]
        self.assertEqual(cli["verdict"], "limit_cycle")
        self.assertEqual(last.verdict, "limit_cycle")
        self.assertAlmostEqual(last.error, cli["limit_cycle_error"], delta=1e-9)
        maxima = [m for m in bag["/limit_cycle"] if m.maxima_observed > 0]
        first = min(maxima, key=lambda m: m.maxima_observed)
        self.assertAlmostEqual(first.last_maximum_position, cli["maxima"][0]["position"], delta=1e-9)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "lockstep", Lockstep)
