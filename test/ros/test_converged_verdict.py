#!/usr/bin/python3
"""The node's limit_cycle topic reaches the verdict backlash_sim reaches, also where the rest/quiet rules decide."""
import json
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


class ConvergedVerdict(unittest.TestCase):
    def test_same_verdict_as_the_cli(self):
        rospy.init_node("test_converged_verdict")
        cli = json.loads(run_cli(*(rospy.get_param("~cli_args").split() + ["--json"])))
        self.assertEqual(cli["verdict"], "converged")
        self.assertTrue(cli["settled"])
        # The case is one the maxima alone cannot settle: too few maxima for the Poincaré-map test.
        self.assertLess(len(cli["maxima"]), 3)

        cycles = Collector("/limit_cycle", LimitCycleStatus)
        diags = Collector("/diagnostics", DiagnosticArray)
        self.assertTrue(cycles.wait_connected())
        self.assertTrue(diags.wait_connected())
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: cycles.msgs and cycles.msgs[-1].verdict != "undecided", 60.0),
                        "no verdict on /limit_cycle: %s" % [m.verdict for m in cycles.msgs])
        last = cycles.msgs[-1]
        self.assertEqual(last.verdict, cli["verdict"])
        self.assertFalse(last.detected)
        self.assertEqual(last.maxima_observed, len(cli["maxima"]))
        # Checked at every 50 ms sample instead of every natural period: reached no later than the CLI's check.
        self.assertLessEqual(last.sim_time, cli["simulated_time"] + 1e-9)
        # The steady error is where the load comes to rest, not the offset when the verdict was decided — here a
        # quiet convergence (the motor creeping across the backlash under a vanishing torque): the loop's one rest
        # position, the same figure on /limit_cycle, /diagnostics and in the CLI.
        self.assertEqual(cli["steady_basis"], "equilibrium")
        self.assertEqual(cli["steady_error"], cli["equilibrium"] - 1.0)
        self.assertEqual(last.steady_basis, "equilibrium")
        self.assertEqual(last.steady_error, cli["steady_error"])

        def figures():
            for a in reversed(diags.msgs):
                for s in a.status:
                    values = {kv.key: kv.value for kv in s.values}
                    if values.get("verdict") == "converged" and "steady_error [rad]" in values:
                        return values
            return None
        self.assertTrue(wait_for(lambda: figures() is not None, 20.0))
        values = figures()
        self.assertEqual(float(values["equilibrium [rad]"]), cli["equilibrium"])
        self.assertEqual(float(values["steady_error [rad]"]), cli["steady_error"])
        self.assertEqual(values["steady_basis"], "equilibrium")
        # The tracking figures under the CLI's names: the same band (Δ), a settling time and a steady RMS error inside
        # it (the node samples every 50 ms, the CLI's replay at 100 per natural period).
        self.assertEqual(float(values["settling_band [rad]"]), cli["settling_band"])
        self.assertAlmostEqual(float(values["settling_time [s]"]), cli["settling_time"], delta=0.1)
        self.assertLessEqual(float(values["steady_rms_error [rad]"]), cli["settling_band"])
        self.assertEqual(last.settling_band, cli["settling_band"])


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "converged_verdict", ConvergedVerdict)
