#!/usr/bin/python3
"""The package's launch files as users run them, each with its own master: sim time that every rospy node follows,
sim time starting at 0, a clean end at stop_after (roslaunch exits by itself, no REQUIRED banner), and no parameter
of an earlier launch carried over."""
import json
import os
import subprocess
import sys
import time
import unittest

import rostest

HERE = os.path.dirname(os.path.abspath(__file__))
PROBE = os.path.join(HERE, "sim_time_probe.py")


def env_for(port):
    return dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % port)


def roslaunch(port, launch, *args, timeout=90):
    """Runs roslaunch to its end; returns (exit code, output). A launch that does not end by itself fails."""
    p = subprocess.run(["roslaunch", "-p", str(port), "backlash_servo", launch] + list(args), env=env_for(port),
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=timeout)
    return p.returncode, p.stdout


class Master:
    """A roscore of its own on `port` for the test's duration."""

    def __init__(self, port):
        self.port = port

    def __enter__(self):
        self.proc = subprocess.Popen(["roscore", "-p", str(self.port)], env=env_for(self.port),
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        end = time.time() + 30
        while time.time() < end:
            if subprocess.run(["rosparam", "list"], env=env_for(self.port), capture_output=True).returncode == 0:
                return self
            time.sleep(0.2)
        raise RuntimeError("roscore on port %d did not come up" % self.port)

    def __exit__(self, *exc):
        self.proc.terminate()
        self.proc.wait(timeout=30)


CLOCK = """
import rospy
from rosgraph_msgs.msg import Clock
rospy.init_node("external_clock")
pub = rospy.Publisher("/clock", Clock, queue_size=10)
t = 1000.0
while not rospy.is_shutdown():
    pub.publish(Clock(rospy.Time.from_sec(t)))
    t += 0.01
    rospy.rostime.wallsleep(0.01)
"""


def probe_with(port, launch, *args, external_clock=False):
    """Starts the launch (and an external /clock from 1000 s), then the probe; returns the probe's JSON and the
    launch's output."""
    with Master(port):
        clock = subprocess.Popen(["/usr/bin/python3", "-c", CLOCK], env=env_for(port)) if external_clock else None
        launch_proc = subprocess.Popen(["roslaunch", "backlash_servo", launch] + list(args), env=env_for(port),
                                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            # As in a launch file, the probe starts after roslaunch has set the parameters (rospy reads
            # /use_sim_time once, in init_node).
            end = time.time() + 30
            while time.time() < end and subprocess.run(["rosparam", "get", "/backlash_servo/stop_launch"],
                                                        env=env_for(port), capture_output=True).returncode != 0:
                time.sleep(0.2)
            probe = subprocess.run(["/usr/bin/python3", PROBE], env=env_for(port), capture_output=True, text=True,
                                   timeout=60)
        finally:
            launch_proc.terminate()
            out, _ = launch_proc.communicate(timeout=60)
            if clock:
                clock.terminate()
                clock.wait(timeout=30)
    return json.loads(probe.stdout.strip().splitlines()[-1]), out


class LaunchFiles(unittest.TestCase):
    def check_clean_end(self, code, out, stop_after):
        self.assertEqual(code, 0, out)
        self.assertIn("stop_after %g s reached" % stop_after, out)
        self.assertNotIn("REQUIRED process", out)
        self.assertNotIn("has died", out)

    def test_stop_after_ends_every_launch_file_cleanly(self):
        code, out = roslaunch(11421, "backlash_servo.launch", "publish_clock:=true", "real_time_factor:=0",
                              "stop_after:=5")
        self.check_clean_end(code, out, 5)
        code, out = roslaunch(11422, "thesis_limit_cycle.launch", "real_time_factor:=0", "stop_after:=5",
                              "record:=false")
        self.check_clean_end(code, out, 5)
        # The controller node ends with the launch too.
        code, out = roslaunch(11423, "external_controller.launch", "controller:=python", "stop_after:=2")
        self.check_clean_end(code, out, 2)

    def test_parameters_of_an_earlier_launch_do_not_carry_over(self):
        with Master(11424) as m:
            # What an earlier lockstep launch and dynamic_reconfigure leave on the master.
            for key, value in (("sync", "true"), ("control_mode", "1"), ("publish_rate", "7.0"), ("bogus", "1")):
                subprocess.run(["rosparam", "set", "/backlash_servo/" + key, value], env=env_for(m.port), check=True)
            code, out = roslaunch(m.port, "backlash_servo.launch", "publish_clock:=true", "real_time_factor:=0",
                                  "stop_after:=3")
        self.check_clean_end(code, out, 3)
        self.assertNotIn("waiting for a controller", out)
        self.assertNotIn("bogus", out)
        self.assertIn("publishing /clock, real_time_factor 0, 100 Hz", out)  # the YAML's rate, not the stale 7

    def test_a_typo_in_a_parameter_stops_the_node_naming_the_nearest_key(self):
        # Running with the key's default instead (a derivative gain of 0: a limit cycle) would be a silent override.
        with Master(11429) as m:
            p = subprocess.run(["rosrun", "backlash_servo", "backlash_servo_node", "_derivitive_gain:=0.3",
                                "_publish_clock:=true", "_real_time_factor:=0", "_stop_after:=1"],
                               env=env_for(m.port), capture_output=True, text=True, timeout=60)
        self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
        self.assertIn("~derivitive_gain: unknown parameter (did you mean 'derivative_gain'?)", p.stdout + p.stderr)

    def test_rospy_time_follows_the_simulator_clock(self):
        # The node is the clock: /use_sim_time is set by the launch file's publish_clock arg, rospy.Time.now()
        # follows the node's /clock, and sim time starts at 0.
        for port, launch, args in ((11425, "backlash_servo.launch", ("publish_clock:=true", "real_time_factor:=5")),
                                   (11426, "thesis_limit_cycle.launch", ("record:=false", "real_time_factor:=5"))):
            got, out = probe_with(port, launch, *args)
            self.assertTrue(got["use_sim_time"], out)
            for now, stamp in got["pairs"]:
                self.assertLess(stamp, 100.0)  # sim time from 0, not the wall clock's epoch
                # rospy's clock is the node's, up to the callback's latency (5 s of sim time = 1 s of wall time at
                # real_time_factor 5: generous for a loaded machine, tiny against a wall-clock epoch of 1.8e9 s).
                self.assertLessEqual(abs(now - stamp), 5.0, (launch, got))
        # An external clock (rosbag play --clock, another simulator): the node and rospy both follow it.
        got, out = probe_with(11428, "backlash_servo.launch", "use_sim_time:=true", external_clock=True)
        self.assertTrue(got["use_sim_time"], out)
        for now, stamp in got["pairs"]:
            self.assertGreaterEqual(stamp, 1000.0, got)
            self.assertLessEqual(abs(now - stamp), 5.0, got)
        # Real time (no clock published, use_sim_time false): stamps and rospy time are the wall clock.
        got, out = probe_with(11427, "backlash_servo.launch")
        self.assertFalse(got["use_sim_time"], out)
        for now, stamp in got["pairs"]:
            self.assertLess(abs(now - time.time()), 60.0)
            self.assertLess(abs(now - stamp), 5.0)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "launch_files", LaunchFiles)
