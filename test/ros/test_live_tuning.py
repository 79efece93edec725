#!/usr/bin/python3
"""Live tuning through dynamic_reconfigure: the PID's integral gain changed mid-run takes effect at the next sample
with the integrator kept (checked sample by sample against the PID written out here, from encoder_states and the
torque on joint_states); a live encoder resolution quantises the next readings; a refused value leaves the reply
holding the values in force and is published on /diagnostics (WARN, naming key and value) until an accepted change;
non-ASCII characters arrive in /rosout as UTF-8."""
import math
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dynamic_reconfigure.client  # noqa: E402
import rospy  # noqa: E402
import rostest  # noqa: E402
from backlash_servo.msg import LimitCycleStatus  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from rosgraph_msgs.msg import Log  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"
T = 0.01  # controller period [s]
K, KD, KI_OLD, KI_NEW = 1.0, 0.3, 0.3, 1.5


def ns(stamp):
    return stamp.to_nsec()


class LiveTuning(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_live_tuning")
        cls.enc = Collector("/encoder_states", JointState)
        cls.js = Collector("/joint_states", JointState)
        cls.diag = Collector("/diagnostics", DiagnosticArray)
        cls.log = Collector("/rosout", Log)
        cls.verdicts = Collector("/limit_cycle", LimitCycleStatus)
        assert cls.enc.wait_connected() and cls.js.wait_connected() and cls.diag.wait_connected()
        cls.client = dynamic_reconfigure.client.Client(NODE, timeout=10)

    def test_1_integral_gain_and_encoder_live(self):
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: len(self.enc.msgs) >= 300, 60.0))
        reply = self.client.update_configuration({"integral_gain": KI_NEW})
        self.assertEqual(reply["integral_gain"], KI_NEW)
        n_changed = len(self.enc.msgs)
        self.assertTrue(wait_for(lambda: len(self.enc.msgs) >= n_changed + 300, 60.0))
        reply = self.client.update_configuration({"load_encoder_resolution": 4096.0})
        self.assertEqual(reply["load_encoder_resolution"], 4096.0)
        n_quantised = len(self.enc.msgs)
        self.assertTrue(wait_for(lambda: len(self.enc.msgs) >= n_quantised + 100, 60.0))
        self.assertTrue(call_trigger(NODE + "/pause").success)

        # u_k is the torque held on [t_k, t_k+1): joint_states at t_k+1 is published as the held interval ends,
        # before the sample there.
        torque = {ns(m.header.stamp): m.effort[0] for m in self.js.msgs}
        samples = [(ns(m.header.stamp), m.position[1], torque.get(ns(m.header.stamp) + 10000000))
                   for m in self.enc.msgs]
        # The integrator after sample k, from the law: I_k = u_k − K e_k + K_d (y_k − y_{k−1})/T, e_k = 1 − y_k.
        increments = []
        for (t0, y0, _), (t1, y1, u1), (t2, y2, u2) in zip(samples, samples[1:], samples[2:]):
            if u1 is None or u2 is None or t2 - t1 != 10000000:
                continue
            i1 = u1 - K * (1.0 - y1) + KD * (y1 - y0) / T
            i2 = u2 - K * (1.0 - y2) + KD * (y2 - y1) / T
            increments.append((t2, (i2 - i1) / (T * (1.0 - y2)) if abs(1.0 - y2) > 1e-6 else None))
        gains = [(t, g) for t, g in increments if g is not None]
        self.assertGreater(len(gains), 400)
        # Exactly one switch from K_i = 0.3 to 1.5, never a reset of the integrator (which would show as a wild
        # increment at the switch).
        switched = False
        for t, g in gains:
            if not switched and abs(g - KI_NEW) < 1e-6:
                switched = True
            self.assertAlmostEqual(g, KI_NEW if switched else KI_OLD, delta=1e-6, msg="t = %d ns" % t)
        self.assertTrue(switched)
        # Each live drive change restarted the judgement: /limit_cycle said undecided, naming the key — also a change
        # that needs a fresh controller (the feedback: the load encoder → the motor encoder).
        self.assertEqual(self.client.update_configuration({"feedback": 1})["feedback"], 1)
        self.assertTrue(wait_for(lambda: any("live change of feedback" in m.reason for m in self.verdicts.msgs), 10.0))
        self.client.update_configuration({"feedback": 0})
        for key in ("integral_gain", "load_encoder_resolution"):
            self.assertTrue(any(m.verdict == "undecided" and "live change of " + key in m.reason
                                for m in self.verdicts.msgs), [m.reason for m in self.verdicts.msgs])
        # After the encoder change every load reading is a whole number of counts of 2π/4096.
        count = 2.0 * math.pi / 4096.0
        for m in self.enc.msgs[n_quantised + 5:]:
            self.assertAlmostEqual(m.position[1] / count, round(m.position[1] / count), delta=1e-6)

    def test_2_refused_value_is_visible(self):
        before = self.client.get_configuration(timeout=10)
        reply = self.client.update_configuration({"restitution": 2.0})
        self.assertEqual(reply["restitution"], before["restitution"])  # the values in force, as rqt shows them

        def warning():
            for a in self.diag.msgs[-5:]:
                for s in a.status:
                    if s.level == DiagnosticStatus.WARN and "restitution" in s.message and "2" in s.message:
                        return True
            return False
        self.assertTrue(wait_for(warning, 10.0), [s.message for a in self.diag.msgs[-3:] for s in a.status])
        # A refused envelope value: the message names the keys behind the derived quantity, in readable UTF-8.
        self.client.update_configuration({"motor_friction": 200.0})
        self.assertTrue(wait_for(lambda: any("ζ" in m.msg and "motor_friction 200" in m.msg for m in self.log.msgs),
                                 10.0), [m.msg for m in self.log.msgs[-3:]])
        # An accepted change clears the warning.
        self.client.update_configuration({"restitution": 0.6})
        n = len(self.diag.msgs)
        self.assertTrue(wait_for(lambda: len(self.diag.msgs) > n, 10.0))
        self.assertTrue(wait_for(lambda: all(s.level == DiagnosticStatus.OK for s in self.diag.msgs[-1].status),
                                 10.0))


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "live_tuning", LiveTuning)
