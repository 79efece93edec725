"""Helpers shared by the rostest clients: collect messages, wait in wall time (the graph runs on sim time)."""
import subprocess
import time

import rospy


class Collector:
    """Keeps every message of a topic (unbounded queue)."""

    def __init__(self, topic, msg_type):
        self.msgs = []
        self.sub = rospy.Subscriber(topic, msg_type, self.msgs.append, queue_size=None)

    def wait_connected(self, timeout=10.0):
        return wait_for(lambda: self.sub.get_num_connections() > 0, timeout)


def wait_for(predicate, timeout=20.0, period=0.01):
    """Polls predicate in wall time; True as soon as it holds, False after timeout seconds."""
    end = time.time() + timeout
    while time.time() < end and not rospy.is_shutdown():
        if predicate():
            return True
        time.sleep(period)
    return predicate()


def call_trigger(name):
    from std_srvs.srv import Trigger
    rospy.wait_for_service(name, timeout=10.0)
    return rospy.ServiceProxy(name, Trigger)()


def run_cli(*args):
    """Runs backlash_sim (found with rosrun) and returns its stdout."""
    return subprocess.run(["rosrun", "backlash_servo", "backlash_sim"] + list(args), check=True,
                          capture_output=True, text=True).stdout


def bag_contents(path):
    """Every message of a bag by topic, as recorded."""
    import rosbag
    out = {}
    with rosbag.Bag(path) as bag:
        for topic, msg, _ in bag.read_messages():
            out.setdefault(topic, []).append(msg)
    return out
