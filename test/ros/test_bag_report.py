#!/usr/bin/python3
"""backlash_bag_report on the main job's bag agrees with the node's own limit_cycle topic and with backlash_sim."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rosbag  # noqa: E402
import rostest  # noqa: E402

from helpers import run_cli  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REPORT = os.path.join(HERE, "..", "..", "bin", "backlash_bag_report")


class BagReport(unittest.TestCase):
    def test_report_agrees_with_the_node_and_the_cli(self):
        with tempfile.TemporaryDirectory() as d:
            env = dict(os.environ, ROS_MASTER_URI="http://localhost:11421", ROS_HOME=d)
            subprocess.run(["roslaunch", "-p", "11421", "backlash_servo", "thesis_limit_cycle.launch",
                            "real_time_factor:=0", "stop_after:=250"], env=env, check=False, capture_output=True,
                           timeout=180)
            bag = os.path.join(d, "thesis_limit_cycle.bag")  # bag_dir defaults to $ROS_HOME
            self.assertTrue(os.path.exists(bag), os.listdir(d))
            with rosbag.Bag(bag) as b:
                topics = b.get_type_and_topic_info().topics
                self.assertIn("/joint_states", topics)  # absolute names
                last = [m for _, m, _ in b.read_messages(topics=["/limit_cycle"])][-1]
                samples = b.get_message_count("/joint_states")
            out = subprocess.run(["/usr/bin/python3", REPORT, bag, "--json", "--png", os.path.join(d, "r.png")],
                                 check=True, capture_output=True, text=True).stdout
            self.assertTrue(os.path.getsize(os.path.join(d, "r.png")) > 10000)
            torn = subprocess.run(["/usr/bin/python3", REPORT, bag + ".active"], capture_output=True, text=True)
        report = json.loads(out)
        self.assertEqual(samples, 250 * 100 + 1)  # every 100 Hz sample, none dropped
        node = report["node"]
        self.assertEqual(node["verdict"], last.verdict)
        self.assertEqual(node["limit_cycle_error"], last.error)
        self.assertEqual(node["verdict"], "limit_cycle")
        cli = json.loads(run_cli("--json"))  # App. D1, the main job's case
        self.assertAlmostEqual(node["limit_cycle_error"], cli["limit_cycle_error"], delta=1e-6)
        # Estimated from the 100 Hz samples alone (parabola through the samples around each maximum).
        self.assertAlmostEqual(report["from_samples"]["error"], cli["limit_cycle_error"], delta=2e-4)
        self.assertAlmostEqual(report["from_samples"]["period"], cli["period"], delta=0.05)
        self.assertNotEqual(torn.returncode, 0)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "bag_report", BagReport)
