#!/usr/bin/python3
"""A hunt below one count of the encoder the loop reads: the node's /limit_cycle and /diagnostics give its size in
counts and arcmin and flag it, with backlash_sim's figures for the same joint."""
import json
import math
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402

from backlash_servo.msg import LimitCycleStatus  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from helpers import Collector, call_trigger, run_cli, wait_for  # noqa: E402

NODE = "/backlash_servo"
COUNT = 2.0 * math.pi / 131072  # one count of the 17-bit load encoder [rad]


class CycleResolution(unittest.TestCase):
    def test_a_hunt_below_one_count_is_flagged(self):
        rospy.init_node("test_cycle_resolution")
        cli = json.loads(run_cli(*(rospy.get_param("~cli_args").split() + ["--json"])))
        self.assertIn(cli["verdict"], ("limit_cycle", "irregular_oscillation"))
        self.assertTrue(cli["below_encoder_resolution"])

        cycles = Collector("/limit_cycle", LimitCycleStatus)
        diags = Collector("/diagnostics", DiagnosticArray)
        self.assertTrue(cycles.wait_connected())
        self.assertTrue(diags.wait_connected())
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: cycles.msgs and cycles.msgs[-1].detected, 120.0),
                        "no cycle on /limit_cycle: %s" % [m.verdict for m in cycles.msgs[-5:]])
        last = cycles.msgs[-1]
        self.assertEqual(last.verdict, cli["verdict"])
        # The figures follow from the cycle's peak to peak: counts of 2π/2^17 rad and arcmin at the load.
        self.assertAlmostEqual(last.peak_to_peak_counts, last.peak_to_peak / COUNT, delta=1e-9)
        self.assertAlmostEqual(last.peak_to_peak_arcmin, math.degrees(last.peak_to_peak) * 60.0, delta=1e-9)
        self.assertLess(last.peak_to_peak_counts, 1.0)
        self.assertTrue(last.below_encoder_resolution)
        # The same cycle backlash_sim found (the node judges at its 50 ms samples, the CLI at the drive's).
        self.assertAlmostEqual(last.peak_to_peak_counts, cli["peak_to_peak_counts"],
                               delta=0.05 * cli["peak_to_peak_counts"])

        def figures():
            for a in reversed(diags.msgs):
                for s in a.status:
                    values = {kv.key: kv.value for kv in s.values}
                    if "peak_to_peak_counts" in values:
                        return values
            return None
        self.assertTrue(wait_for(lambda: figures() is not None, 20.0))
        values = figures()
        self.assertEqual(values["below_encoder_resolution"], "true")
        self.assertLess(float(values["peak_to_peak_counts"]), 1.0)
        self.assertAlmostEqual(float(values["peak_to_peak_counts"]), float(values["peak_to_peak [rad]"]) / COUNT,
                               delta=1e-6)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "cycle_resolution", CycleResolution)
