#!/usr/bin/python3
"""A plain rospy node, as users write them: prints one JSON line with /use_sim_time and, for 20 joint_states
messages, rospy.Time.now() taken in the callback beside the message's stamp [s]."""
import json

import rospy
from sensor_msgs.msg import JointState

pairs = []


def on_state(msg):
    now = rospy.Time.now()
    # Time zero: rospy has not received a /clock message yet (its subscription may connect after joint_states').
    if len(pairs) < 20 and not now.is_zero():
        pairs.append((now.to_sec(), msg.header.stamp.to_sec()))


rospy.init_node("sim_time_probe", anonymous=True)
rospy.Subscriber("/joint_states", JointState, on_state, queue_size=100)
while len(pairs) < 20 and not rospy.is_shutdown():
    rospy.rostime.wallsleep(0.01)
print(json.dumps({"use_sim_time": rospy.get_param("/use_sim_time", False), "pairs": pairs}), flush=True)
