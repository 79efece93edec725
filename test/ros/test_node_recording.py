#!/usr/bin/python3
"""record_bag: the node's own bag holds exactly what a subscriber received, and the inputs as they arrived."""
import io
import math
import os
import sys
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rosbag  # noqa: E402
import rospy  # noqa: E402
import rostest  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from backlash_servo.msg import BacklashState, ImpactEvent  # noqa: E402
from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"


def wire(msg):
    """A message's serialised bytes: equal bytes, equal content (whatever class deserialised it)."""
    buf = io.BytesIO()
    msg.serialize(buf)
    return buf.getvalue()


class NodeRecording(unittest.TestCase):
    def test_bag_equals_the_topics_and_holds_the_inputs(self):
        rospy.init_node("test_node_recording")
        path = rospy.get_param("~bag")
        joints = Collector("/joint_states", JointState)
        states = Collector("/backlash_state", BacklashState)
        impacts = Collector("/impact", ImpactEvent)
        command = rospy.Publisher("/command", Float64, queue_size=10)
        load_torque = rospy.Publisher("/load_torque", Float64, queue_size=10)
        self.assertTrue(joints.wait_connected() and states.wait_connected() and impacts.wait_connected())
        self.assertTrue(wait_for(lambda: command.get_num_connections() > 0 and load_torque.get_num_connections() > 0,
                                 10.0))
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: len(joints.msgs) >= 100, 30.0))
        command.publish(Float64(1.0))  # a step: impacts follow
        command.publish(Float64(float("nan")))  # rejected by the node, recorded as received
        load_torque.publish(Float64(0.0))
        # The node stops at 20 s of sim time and closes the bag (PATH.active renamed to PATH).
        self.assertTrue(wait_for(lambda: os.path.exists(path) and not os.path.exists(path + ".active"), 60.0), path)
        time.sleep(0.5)  # the last messages in flight to this client
        with rosbag.Bag(path) as bag:
            recorded = {}
            for topic, msg, _ in bag.read_messages():
                recorded.setdefault(topic, []).append(msg)
        self.assertEqual(len(recorded["/joint_states"]), 20 * 100 + 1)  # 100 Hz over 20 s, none dropped
        # What a subscriber received, message for message: it subscribed before the node resumed, so it has every
        # message but possibly the sample at t = 0 (published when the node came up, paused).
        for topic, got in (("/joint_states", joints.msgs), ("/backlash_state", states.msgs),
                           ("/impact", impacts.msgs)):
            rec = recorded[topic]
            self.assertIn(len(rec) - len(got), (0, 1) if topic != "/impact" else (0,), topic)
            if len(rec) > len(got):
                self.assertEqual(rec[0].header.stamp, rec[1].header.stamp - rospy.Duration(0.01), topic)
                rec = rec[1:]  # the sample at t = 0
            for a, b in zip(rec, got):
                b.header.seq = a.header.seq  # roscpp numbers messages on the wire only (a deprecated field)
                self.assertEqual(wire(a), wire(b), topic)  # (the bag's classes are generated from its definitions)
        self.assertGreater(len(recorded["/impact"]), 0)
        self.assertEqual(len(recorded["/clock"]), 20 * 100 + 1)
        self.assertEqual(recorded["/clock"][0]._type, Clock._type)
        self.assertEqual([c.clock for c in recorded["/clock"]], [j.header.stamp for j in recorded["/joint_states"]])
        self.assertIn("/limit_cycle", recorded)
        # Inputs as they arrived, the rejected one too; the accepted ones acted (the command is the step's).
        values = [m.data for m in recorded["/command"]]
        self.assertEqual(len(values), 2)
        self.assertEqual(values[0], 1.0)
        self.assertTrue(math.isnan(values[1]))
        self.assertEqual([m.data for m in recorded["/load_torque"]], [0.0])
        self.assertEqual(recorded["/backlash_state"][-1].command, 1.0)
        os.remove(path)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "node_recording", NodeRecording)
