#!/usr/bin/python3
"""A core error (the event budget, 20 impacts) pauses the simulation and is reported on /diagnostics; topics and
services keep working; ~reset clears it and the simulation runs again. The node never dies."""
import os
import sys
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402

from backlash_servo.msg import BacklashState  # noqa: E402
from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"


class NodeFault(unittest.TestCase):
    def test_error_pauses_reports_and_reset_resumes(self):
        rospy.init_node("test_node_fault")
        states = Collector("/backlash_state", BacklashState)
        diags = Collector("/diagnostics", DiagnosticArray)
        self.assertTrue(states.wait_connected())
        self.assertTrue(call_trigger(NODE + "/resume").success)

        def level():
            return diags.msgs[-1].status[0].level if diags.msgs else None

        self.assertTrue(wait_for(lambda: level() == DiagnosticStatus.ERROR, 60.0), "no error on /diagnostics")
        status = diags.msgs[-1].status[0]
        self.assertIn("event budget", status.message)
        # Published through diagnostic_updater: "<node>: <task>" names, the hardware id, the task's key values.
        self.assertEqual(status.name, NODE[1:] + ": simulation")
        self.assertEqual(status.hardware_id, "backlash_servo")
        self.assertIn("verdict", [kv.key for kv in status.values])
        frozen = len(states.msgs)
        self.assertLessEqual(states.msgs[-1].impacts, 20)
        time.sleep(1.0)  # wall time: the node is paused, so is its clock
        self.assertEqual(len(states.msgs), frozen, "the simulation went on after the error")
        # Services still answer; a reset clears the error and the joint moves again.
        self.assertTrue(call_trigger(NODE + "/reset").success)
        self.assertTrue(wait_for(lambda: len(states.msgs) > frozen + 20, 20.0), "no samples after the reset")
        self.assertTrue(wait_for(lambda: level() == DiagnosticStatus.OK, 10.0))


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "node_fault", NodeFault)
