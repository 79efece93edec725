#!/usr/bin/python3
"""Node from the default YAML: publishing rate in sim time, reset, NaN commands, live tuning as rqt does it."""
import math
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dynamic_reconfigure.client  # noqa: E402
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from backlash_servo.msg import BacklashState  # noqa: E402
from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"


class NodeBasics(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_node_basics")
        cls.joints = Collector("/joint_states", JointState)
        cls.states = Collector("/backlash_state", BacklashState)
        cls.command = rospy.Publisher("/command", Float64, queue_size=10, latch=False)
        assert cls.joints.wait_connected() and cls.states.wait_connected()
        assert wait_for(lambda: cls.command.get_num_connections() > 0, 10.0)
        assert call_trigger(NODE + "/resume").success

    def latest_state(self):
        return self.states.msgs[-1]

    def test_1_publishes_at_the_configured_rate_in_sim_time(self):
        self.assertTrue(wait_for(lambda: len(self.joints.msgs) >= 300, 30.0))
        msgs = list(self.joints.msgs[:300])
        rate = rospy.get_param(NODE + "/publish_rate")
        for a, b in zip(msgs, msgs[1:]):
            self.assertAlmostEqual((b.header.stamp - a.header.stamp).to_sec(), 1.0 / rate, delta=2e-9)
        m = msgs[-1]
        self.assertEqual(m.name, ["motor_joint", "load_joint"])
        self.assertEqual(len(m.position), 2)
        self.assertEqual(len(m.velocity), 2)
        self.assertEqual(len(m.effort), 2)
        s = self.latest_state()
        self.assertEqual(s.contact, BacklashState.FORWARD)  # at rest on its (zero) command
        self.assertAlmostEqual(s.sim_time * rate, round(s.sim_time * rate), delta=1e-6)

    def test_2_step_moves_the_load_and_reset_restores_the_initial_state(self):
        self.command.publish(Float64(1.0))
        self.assertTrue(wait_for(lambda: self.latest_state().command == 1.0 and
                                 self.joints.msgs[-1].position[1] > 0.5, 30.0))
        reply = call_trigger(NODE + "/reset")
        self.assertTrue(reply.success, reply.message)
        t_reset = float(reply.message.split("t = ")[1].split(" s")[0])
        first = self.states.msgs[0]
        origin = first.header.stamp.to_sec() - first.sim_time
        # Messages already in flight were published before the reset: look at samples stamped after it.
        later = lambda: [m for m in self.joints.msgs if m.header.stamp.to_sec() - origin > t_reset + 1e-3]
        self.assertTrue(wait_for(lambda: len(later()) > 2, 10.0))
        after = later()[0]
        self.assertEqual(list(after.position), [0.0, 0.0])
        self.assertEqual(list(after.velocity), [0.0, 0.0])
        # (backlash_state arrives on its own connection, possibly after joint_states of the same instant: wait for it)
        states_after = lambda: [m for m in self.states.msgs if m.sim_time > t_reset + 1e-3]
        self.assertTrue(wait_for(lambda: len(states_after()) > 0, 10.0))
        states = states_after()
        self.assertEqual(states[0].command, 0.0)
        self.assertEqual(states[0].impacts, 0)

    def test_3_non_finite_commands_are_dropped(self):
        self.command.publish(Float64(0.25))
        self.assertTrue(wait_for(lambda: self.latest_state().command == 0.25, 10.0))
        self.command.publish(Float64(float("nan")))
        self.command.publish(Float64(float("inf")))
        n = len(self.states.msgs)
        self.assertTrue(wait_for(lambda: len(self.states.msgs) > n + 20, 10.0))
        self.assertEqual(self.latest_state().command, 0.25)
        self.assertTrue(math.isfinite(self.joints.msgs[-1].position[1]))

    def test_4_live_tuning_applies_and_invalid_values_are_refused(self):
        client = dynamic_reconfigure.client.Client(NODE, timeout=10)
        cfg = client.update_configuration({"backlash": 0.1, "restitution": 0.5})
        self.assertAlmostEqual(cfg["backlash"], 0.1)
        self.assertAlmostEqual(cfg["restitution"], 0.5)
        self.command.publish(Float64(-1.0))  # drive the teeth across the new, smaller gap
        n = len(self.states.msgs)
        self.assertTrue(wait_for(lambda: len(self.states.msgs) > n + 500, 30.0))
        gaps = [s.gap for s in self.states.msgs[n:]]
        self.assertLessEqual(max(gaps), 0.1 + 1e-12)
        self.assertGreater(max(gaps), 0.05)
        # Zero inertia is physically invalid: refused, previous value reported back, node keeps running.
        refused = client.update_configuration({"motor_inertia": 0.0})
        self.assertAlmostEqual(refused["motor_inertia"], 0.1)
        self.assertAlmostEqual(client.get_configuration(timeout=5)["motor_inertia"], 0.1)
        n = len(self.joints.msgs)
        self.assertTrue(wait_for(lambda: len(self.joints.msgs) > n + 50, 10.0))

    def test_5_values_are_never_clamped_behind_the_users_back(self):
        # The .cfg is generated from the parameter table without slider bounds: dynamic_reconfigure passes every
        # value through and the node either takes it as given or refuses it, keeping every value as it was.
        client = dynamic_reconfigure.client.Client(NODE, timeout=10)
        before = client.get_configuration(timeout=5)
        taken = client.update_configuration({"gain": 5000.0})
        self.assertEqual(taken["gain"], 5000.0)
        for bad in ({"restitution": 2.0}, {"control_mode": 5}, {"gear_ratio": float("inf")},
                    {"load_inertia": -1.0}):
            after = client.update_configuration(bad)
            for key in ("restitution", "control_mode", "gear_ratio", "load_inertia", "publish_rate"):
                self.assertEqual(after[key], before[key], "%s after refusing %s" % (key, bad))
        self.assertEqual(client.update_configuration({"gain": before["gain"]})["gain"], before["gain"])

    def test_6_load_torque_topic_is_a_live_disturbance(self):
        # A preload on the load_torque topic shifts where the P law comes to rest by ρ T_ext / K (here −0.2 rad),
        # shows in dynamic_reconfigure, and a non-finite value is dropped.
        client = dynamic_reconfigure.client.Client(NODE, timeout=10)
        pub = rospy.Publisher("/load_torque", Float64, queue_size=10)
        self.assertTrue(wait_for(lambda: pub.get_num_connections() > 0, 10.0))
        cfg = client.get_configuration(timeout=5)
        shift = cfg["gear_ratio"] * -0.1 / cfg["gain"]
        pub.publish(Float64(-0.1))
        self.assertTrue(wait_for(lambda: client.get_configuration(timeout=5)["load_torque"] == -0.1, 10.0))
        pub.publish(Float64(float("nan")))
        rospy.sleep(rospy.Duration(0.5))
        self.assertEqual(client.get_configuration(timeout=5)["load_torque"], -0.1)
        command = self.latest_state().command
        # Settled position: the command shifted by ρ T_ext / K.
        self.assertTrue(wait_for(lambda: abs(self.joints.msgs[-1].position[1] - (command + shift)) < 2e-3, 60.0),
                        "load at %g, expected %g" % (self.joints.msgs[-1].position[1], command + shift))
        pub.publish(Float64(0.0))


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "node_basics", NodeBasics)
