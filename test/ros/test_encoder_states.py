#!/usr/bin/python3
"""encoder_states: one message per controller sample (stamped t_k = k/f_s in sim time) with the quantised readings
q(θ) = 2π/N floor(Nθ/2π) of the true angles at that instant, and dry friction parameters reaching the node."""
import math
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"
RATE = 100.0
N_LOAD, N_MOTOR = 4096, 1000


def quantise(angle, counts):
    return 2.0 * math.pi / counts * math.floor(counts * angle / (2.0 * math.pi))


class EncoderStates(unittest.TestCase):
    def test_readings_at_the_controller_rate(self):
        rospy.init_node("test_encoder_states")
        self.assertEqual(rospy.get_param(NODE + "/load_static_friction"), 0.05)
        enc = Collector("/encoder_states", JointState)
        truth = Collector("/joint_states", JointState)
        self.assertTrue(enc.wait_connected())
        self.assertTrue(truth.wait_connected())
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: len(enc.msgs) >= 500, 60.0), "only %d encoder messages" % len(enc.msgs))
        self.assertTrue(call_trigger(NODE + "/pause").success)
        stamps = [m.header.stamp.to_sec() for m in enc.msgs]
        t0 = stamps[0]
        for k, t in enumerate(stamps[:500]):
            self.assertAlmostEqual(t - t0, k / RATE, delta=2e-6)  # one per sample, none missing (stamps in ns)
        for m in enc.msgs[:500]:
            self.assertEqual(list(m.name), ["motor_joint", "load_joint"])
            motor, load = m.position
            # Readings are whole counts.
            self.assertAlmostEqual(load / (2 * math.pi / N_LOAD), round(load / (2 * math.pi / N_LOAD)), delta=1e-6)
            self.assertAlmostEqual(motor / (2 * math.pi / N_MOTOR), round(motor / (2 * math.pi / N_MOTOR)),
                                   delta=1e-6)
        # Where a joint_states sample falls on a controller sample (every 50 ms = 5 samples), the readings are the
        # quantised true angles.
        by_time = {round(m.header.stamp.to_sec(), 6): m for m in enc.msgs}
        matched = 0
        for js in truth.msgs:
            m = by_time.get(round(js.header.stamp.to_sec(), 6))
            if m is None:
                continue
            matched += 1
            self.assertAlmostEqual(m.position[0], quantise(js.position[0], N_MOTOR), delta=1e-9)
            self.assertAlmostEqual(m.position[1], quantise(js.position[1], N_LOAD), delta=1e-9)
        self.assertGreater(matched, 50)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "encoder_states", EncoderStates)
