#!/usr/bin/python3
"""A converged verdict the load's motion contradicts later is withdrawn on /limit_cycle, saying which and since when."""
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from backlash_servo.msg import LimitCycleStatus  # noqa: E402
from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"


class ConvergedWithdrawn(unittest.TestCase):
    def test_a_withdrawn_convergence_is_announced(self):
        rospy.init_node("test_converged_withdrawn")
        cycles = Collector("/limit_cycle", LimitCycleStatus)
        joints = Collector("/joint_states", JointState)
        effort = rospy.Publisher("/motor_effort", Float64, queue_size=10)
        self.assertTrue(cycles.wait_connected() and joints.wait_connected())
        self.assertTrue(wait_for(lambda: effort.get_num_connections() > 0, 10.0))
        self.assertTrue(call_trigger(NODE + "/resume").success)
        # At rest on its command (0 rad) under no torque: converged, nothing withdrawn.
        self.assertTrue(wait_for(lambda: cycles.msgs and cycles.msgs[-1].verdict == "converged", 30.0),
                        [(m.sim_time, m.verdict) for m in cycles.msgs])
        converged_at = cycles.msgs[-1].sim_time
        self.assertNotIn("withdrawn", cycles.msgs[-1].reason)

        def load(field):
            js = joints.msgs[-1]
            return getattr(js, field)[js.name.index("load_joint")]

        # A torque lifts the load past the command, reversed it turns the load back: a maximum above the command.
        effort.publish(Float64(1.0))
        self.assertTrue(wait_for(lambda: load("position") > 0.1, 30.0))
        effort.publish(Float64(-1.0))
        self.assertTrue(wait_for(lambda: any(m.verdict != "converged" and m.sim_time > converged_at
                                             for m in cycles.msgs), 30.0),
                        [(m.sim_time, m.verdict) for m in cycles.msgs])
        # No message after the verdict and before its withdrawal still says converged with the new maximum in it.
        after = [m for m in cycles.msgs if m.sim_time > converged_at]
        self.assertEqual(after[0].verdict, "undecided", [(m.sim_time, m.verdict, m.reason) for m in after])
        withdrawn = after[0]
        self.assertIn("the converged verdict of t = ", withdrawn.reason)
        self.assertIn("is withdrawn: the load moved again (maximum at t = ", withdrawn.reason)
        self.assertIn("judging afresh", withdrawn.reason)
        self.assertGreater(withdrawn.sim_time, converged_at)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "converged_withdrawn", ConvergedWithdrawn)
