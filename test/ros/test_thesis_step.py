#!/usr/bin/python3
"""A unit step on the node reproduces backlash_sim: same maxima (1e-9 rad), same impacts at the same exact times; a
live change of the backlash restarts the verdict, which then matches backlash_sim's for the new joint."""
import csv
import json
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402

from backlash_servo.msg import BacklashState, ImpactEvent, LimitCycleStatus  # noqa: E402
from helpers import Collector, call_trigger, run_cli, wait_for  # noqa: E402

NODE = "/backlash_servo"
HORIZON = 60.0  # s of sim time compared


class ThesisStep(unittest.TestCase):
    def test_node_matches_the_cli(self):
        rospy.init_node("test_thesis_step")
        cycles = Collector("/limit_cycle", LimitCycleStatus)
        impacts = Collector("/impact", ImpactEvent)
        states = Collector("/backlash_state", BacklashState)
        for c in (cycles, impacts, states):
            self.assertTrue(c.wait_connected())
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: states.msgs and states.msgs[-1].sim_time > HORIZON + 1.0, 60.0))

        config = rospy.get_param("~config")
        csv_path = os.path.join(tempfile.mkdtemp(), "run.csv")
        cli = json.loads(run_cli("--config", config, "--duration", str(HORIZON), "--json", "--csv", csv_path,
                                 "--sample-rate", "1"))
        with open(csv_path) as f:
            cli_impacts = [float(r["time"]) for r in csv.DictReader(f) if r["event"] == "impact"]

        node_maxima = [(m.last_maximum_time, m.last_maximum_position) for m in cycles.msgs
                       if m.last_maximum_time <= HORIZON]
        self.assertGreaterEqual(len(node_maxima), 5)
        self.assertEqual(len(node_maxima), len(cli["maxima"]))
        for (t, x), ref in zip(node_maxima, cli["maxima"]):
            self.assertAlmostEqual(t, ref["time"], delta=1e-9)
            self.assertAlmostEqual(x, ref["position"], delta=1e-9)

        node_impacts = [m for m in impacts.msgs if m.sim_time <= HORIZON]
        self.assertEqual(len(node_impacts), cli["impacts"])
        self.assertEqual(len(cli_impacts), cli["impacts"])
        first = states.msgs[0]
        origin = first.header.stamp - rospy.Duration.from_sec(first.sim_time)
        for m, t in zip(node_impacts, cli_impacts):
            self.assertAlmostEqual(m.sim_time, t, delta=1e-9)
            # The stamp is the exact impact instant (ROS time has 1 ns resolution).
            self.assertAlmostEqual((m.header.stamp - origin).to_sec(), t, delta=2e-9)
        # The verdict arrives on the topic too.
        self.assertTrue(wait_for(lambda: cycles.msgs[-1].detected, 60.0))
        self.assertEqual(cycles.msgs[-1].verdict, "limit_cycle")
        self.assertAlmostEqual(cycles.msgs[-1].error, 0.0515, delta=5e-4)
        self.assertEqual(cycles.msgs[-1].reason, "")

        # A live change of the backlash restarts the judgement: at once undecided, saying why, then the verdict of
        # the new joint — the cycle backlash_sim finds for Δ = 0.2 rad (a cycle is an attractor: the same one).
        import dynamic_reconfigure.client
        client = dynamic_reconfigure.client.Client(NODE, timeout=10)
        n = len(cycles.msgs)
        client.update_configuration({"backlash": 0.2})
        # (A maximum of the old joint may still be published between reading n and the change taking effect.)
        restarted = lambda: [m for m in cycles.msgs[n:] if "live change of backlash" in m.reason]
        self.assertTrue(wait_for(lambda: restarted(), 20.0))
        first = restarted()[0]
        self.assertEqual(first.verdict, "undecided")
        self.assertFalse(first.detected)
        self.assertTrue(wait_for(lambda: cycles.msgs[-1].detected, 120.0), cycles.msgs[-1])
        cli2 = json.loads(run_cli("--config", config, "--backlash", "0.2", "--json"))
        self.assertEqual(cycles.msgs[-1].verdict, "limit_cycle")
        self.assertAlmostEqual(cycles.msgs[-1].error, cli2["limit_cycle_error"], delta=1e-6)
        self.assertAlmostEqual(cycles.msgs[-1].period, cli2["period"], delta=1e-4)
        self.assertEqual(cycles.msgs[-1].reason, "")


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "thesis_step", ThesisStep)
