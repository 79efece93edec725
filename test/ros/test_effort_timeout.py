#!/usr/bin/python3
"""effort_timeout drops a dead controller's torque to 0; no stale effort crosses a switch to effort mode."""
import os
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from backlash_servo.msg import BacklashState  # noqa: E402
from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"


def dynparam(*args):
    return subprocess.run(["rosrun", "dynamic_reconfigure", "dynparam", "set", NODE] + list(args),
                          capture_output=True, text=True, timeout=30)


class EffortTimeout(unittest.TestCase):
    def test_timeout_then_no_stale_effort(self):
        rospy.init_node("test_effort_timeout")
        states = Collector("/backlash_state", BacklashState)
        effort = rospy.Publisher("/motor_effort", Float64, queue_size=10)
        self.assertTrue(states.wait_connected())
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: states.msgs and states.msgs[-1].sim_time > 2.0, 30.0))
        early = [m.motor_torque for m in states.msgs if m.sim_time < 0.995]
        late = [m.motor_torque for m in states.msgs if 1.005 < m.sim_time <= 2.0]
        self.assertTrue(early and all(t == 0.5 for t in early), early[:5])
        self.assertTrue(late and all(t == 0.0 for t in late), late[:5])
        # A new message revives the torque.
        self.assertTrue(wait_for(lambda: effort.get_num_connections() > 0, 10.0))
        effort.publish(Float64(0.25))
        self.assertTrue(wait_for(lambda: states.msgs[-1].motor_torque == 0.25, 10.0))
        # Position mode: a motor_effort sent now is ignored and not stored; back in effort mode the torque is 0.
        self.assertEqual(dynparam("control_mode", "0").returncode, 0)
        self.assertTrue(wait_for(lambda: states.msgs[-1].control_mode == BacklashState.POSITION, 10.0))
        effort.publish(Float64(0.7))
        rospy.sleep(0.5)
        self.assertEqual(dynparam("control_mode", "1").returncode, 0)
        self.assertTrue(wait_for(lambda: states.msgs[-1].control_mode == BacklashState.EFFORT, 10.0))
        n = len(states.msgs)
        self.assertTrue(wait_for(lambda: len(states.msgs) > n + 5, 10.0))
        self.assertEqual(states.msgs[-1].motor_torque, 0.0)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "effort_timeout", EffortTimeout)
