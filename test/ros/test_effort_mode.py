#!/usr/bin/python3
"""Effort mode: the node follows an injected motor torque; the load velocity matches the closed form."""
import math
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from backlash_servo.msg import BacklashState  # noqa: E402
from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"


class EffortMode(unittest.TestCase):
    def test_follows_injected_torque(self):
        rospy.init_node("test_effort_mode")
        states = Collector("/backlash_state", BacklashState)
        joints = Collector("/joint_states", JointState)
        effort = rospy.Publisher("/motor_effort", Float64, queue_size=10)
        self.assertTrue(states.wait_connected() and joints.wait_connected())
        self.assertTrue(wait_for(lambda: effort.get_num_connections() > 0, 10.0))
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: len(states.msgs) > 10, 10.0))
        self.assertEqual(states.msgs[-1].control_mode, BacklashState.EFFORT)
        u = 0.5
        effort.publish(Float64(u))
        self.assertTrue(wait_for(lambda: any(s.motor_torque == u for s in states.msgs), 10.0))
        self.assertTrue(wait_for(lambda: states.msgs[-1].sim_time > 8.0, 30.0))
        # The torque acted from the boundary after the last sample that still showed zero torque.
        t0 = max(s.sim_time for s in states.msgs if s.motor_torque == 0.0)
        p = {k: rospy.get_param(NODE + "/" + k) for k in
             ("motor_inertia", "load_inertia", "motor_friction", "load_friction", "gear_ratio")}
        rho = p["gear_ratio"]
        j = p["motor_inertia"] + rho ** 2 * p["load_inertia"]
        f = p["motor_friction"] + rho ** 2 * p["load_friction"]
        # From rest in forward contact the pressing torque keeps the teeth together: J v' + F v = rho u.
        checked = 0
        for s, js in zip(states.msgs, joints.msgs):
            if s.sim_time <= t0 + 0.5:
                continue
            self.assertEqual(s.contact, BacklashState.FORWARD)
            expected = rho * u / f * (1.0 - math.exp(-f * (s.sim_time - t0) / j))
            self.assertAlmostEqual(js.velocity[1], expected, delta=1e-9)
            self.assertAlmostEqual(js.effort[0], u, delta=1e-12)
            checked += 1
        self.assertGreater(checked, 100)
        # Position mode commands are ignored (logged), the torque stays.
        self.assertEqual(states.msgs[-1].motor_torque, u)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "effort_mode", EffortMode)
