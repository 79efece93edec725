#!/usr/bin/python3
"""command_trajectory and the start-up `profile`: the node follows the YAML's profile, refuses bad
trajectories without a change, and a good one (linear interpolation between the load joint's points, sampled by the
100 Hz drive) gives exactly backlash_sim's run with the same profile (1e-9 rad at every joint_states sample)."""
import csv
import io
import math
import os
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from backlash_servo.msg import BacklashState  # noqa: E402
from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"
# (time_from_start [s], load position [rad]); received at sim time 0 with a zero stamp, so times are sim times.
POINTS = [(10.0, 0.9), (12.0, 0.5), (13.0, 0.5), (15.0, -0.2)]
END = 40.0


def trajectory(points, joints=("motor_joint", "load_joint"), column=1):
    msg = JointTrajectory()
    msg.joint_names = list(joints)
    for t, q in points:
        p = JointTrajectoryPoint()
        p.positions = [0.0] * len(joints)
        p.positions[column] = q
        p.time_from_start = rospy.Duration.from_sec(t)
        msg.points.append(p)
    return msg


def reference_run():
    """backlash_sim with the same profile: the start-up step, then the trajectory's ramps (the first from 0.9)."""
    lines = ["- step: {time: 0, target: 0.9}"]
    previous = 0.0
    for t, q in POINTS:
        lines.append("- ramp: {time: %r, target: %r, duration: %r}" % (previous, q, t - previous))
        previous = t
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
        f.write("\n".join(lines) + "\n")
        path = f.name
    out = tempfile.mktemp(suffix=".csv")
    subprocess.run(["rosrun", "backlash_servo", "backlash_sim", "--profile", path, "--controller-rate", "100",
                    "--duration", str(END), "--csv", out, "--sample-rate", "20"], check=True, capture_output=True)
    with open(out) as f:
        rows = [r for r in csv.DictReader(f) if not r["event"]]
    return {round(float(r["time"]), 6): float(r["load_position"]) for r in rows}


class Trajectory(unittest.TestCase):
    def test_profile_and_trajectory_equal_backlash_sim(self):
        rospy.init_node("test_trajectory")
        states = Collector("/backlash_state", BacklashState)
        joints = Collector("/joint_states", JointState)
        pub = rospy.Publisher("/command_trajectory", JointTrajectory, queue_size=10)
        self.assertTrue(states.wait_connected())
        self.assertTrue(wait_for(lambda: pub.get_num_connections() > 0, 10.0))
        # Refused, changing nothing: no load joint, times going back, NaN, an empty trajectory.
        pub.publish(trajectory(POINTS, joints=("motor_joint",), column=0))
        pub.publish(trajectory([(2.0, 0.3), (1.0, 0.4)]))
        pub.publish(trajectory([(2.0, float("nan"))]))
        pub.publish(trajectory([]))
        pub.publish(trajectory(POINTS))
        time.sleep(1.0)  # the node serves callbacks while paused
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: states.msgs and states.msgs[-1].sim_time >= END, 60.0), "did not reach end")
        self.assertTrue(call_trigger(NODE + "/pause").success)
        # The set-point the node reports is the profile's value at each sample.
        for m in states.msgs:
            t = m.sim_time
            expected = 0.9
            previous, value = 0.0, 0.9
            for tp, q in POINTS:
                if t >= previous:
                    expected = value + (q - value) * min(1.0, (t - previous) / (tp - previous))
                previous, value = tp, q
            self.assertAlmostEqual(m.command, expected, delta=1e-12, msg="t = %g" % t)
        # The joint moves as backlash_sim's with the same profile.
        ref = reference_run()
        compared = 0
        origin = states.msgs[0].header.stamp - rospy.Duration.from_sec(states.msgs[0].sim_time)
        for js in joints.msgs:
            t = round((js.header.stamp - origin).to_sec(), 6)
            if t in ref and t <= END:
                self.assertAlmostEqual(js.position[1], ref[t], delta=1e-9, msg="t = %g" % t)
                compared += 1
        self.assertGreater(compared, 700)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "trajectory", Trajectory)
