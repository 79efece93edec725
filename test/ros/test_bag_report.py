#!/usr/bin/python3
"""backlash_bag_report on the main job's bag agrees with the node's own limit_cycle topic and with backlash_sim."""
import csv
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
            recording = os.path.join(d, "recording.csv")
            out = subprocess.run(["/usr/bin/python3", REPORT, bag, "--json", "--png", os.path.join(d, "r.png"),
                                  "--recording", recording], check=True, capture_output=True, text=True).stdout
            # The node's own recording identifies its joint (App. D1, e = 1): backlash_identify on --recording.
            identified = json.loads(subprocess.run(["rosrun", "backlash_servo", "backlash_identify", "--data", recording,
                                                    "--gear-ratio", "1", "--json"], check=True, capture_output=True,
                                                   text=True).stdout)
            # The bag itself as --data: converted by the same converter, identified the same.
            direct = json.loads(subprocess.run(["rosrun", "backlash_servo", "backlash_identify", "--data", bag,
                                                "--gear-ratio", "1", "--json"], check=True, capture_output=True,
                                               text=True).stdout)
            self.assertTrue(os.path.getsize(os.path.join(d, "r.png")) > 10000)
            torn = subprocess.run(["/usr/bin/python3", REPORT, bag + ".active"], capture_output=True, text=True)
        report = json.loads(out)
        est = {k: v["value"] for k, v in identified["estimates"].items()}
        self.assertAlmostEqual(est["backlash"], 0.3, delta=1e-5)
        self.assertAlmostEqual(est["motor_inertia"], 0.1, delta=1e-3)
        self.assertAlmostEqual(est["load_inertia"], 0.9, delta=9e-3)
        self.assertAlmostEqual(est["motor_friction"], 0.48, delta=5e-3)
        self.assertAlmostEqual(est["load_friction"], 0.32, delta=1e-2)  # (100 Hz samples of a continuous torque)
        self.assertAlmostEqual(est["restitution"], 1.0, delta=1e-2)
        self.assertTrue(identified["load_torque_given"])  # the limit cycle's contact pushes one way only
        self.assertEqual({k: v["value"] for k, v in direct["estimates"].items()}, est)
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
        # The cycle's shape: the node's (exact turning points) is the CLI's; the samples' agrees to the sampling.
        self.assertEqual(node["peak_to_peak"], last.peak_to_peak)
        self.assertEqual(node["maxima_per_period"], 1)
        self.assertAlmostEqual(node["peak_to_peak"], cli["peak_to_peak"], delta=1e-6)
        self.assertAlmostEqual(node["cycle_centre"], cli["cycle_centre"], delta=1e-6)
        self.assertEqual(report["from_samples"]["maxima_per_period"], 1)
        self.assertAlmostEqual(report["from_samples"]["peak_to_peak"], cli["peak_to_peak"], delta=1e-3)
        self.assertAlmostEqual(report["from_samples"]["cycle_centre"], cli["cycle_centre"], delta=1e-3)
        # Tracking: the band is Δ; the cycle (±0.05 rad) settles inside it after the first overshoot. The node (100 Hz
        # samples), the report (the same samples) and backlash_sim (its replay at 100 per natural period, 15.9 Hz)
        # agree to their sampling.
        self.assertEqual(node["settling_band"], 0.3)
        self.assertEqual(report["from_samples"]["settling_band"], 0.3)
        self.assertAlmostEqual(report["from_samples"]["settling_time"], node["settling_time"], delta=0.011)
        self.assertAlmostEqual(node["settling_time"], cli["settling_time"], delta=1.0 / 15.9 + 0.011)
        self.assertAlmostEqual(report["from_samples"]["steady_rms_error"], node["steady_rms_error"], delta=1e-3)
        self.assertNotEqual(torn.returncode, 0)


def write_bag(path, servo_ns="", arm=False, joints=("motor_joint", "load_joint"), state_type="servo", nan=False,
              samples=50):
    """A small bag as the node records it (optionally with an arm's joint_states beside a namespaced servo)."""
    import rospy
    from backlash_servo.msg import BacklashState
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String
    with rosbag.Bag(path, "w") as bag:
        for i in range(samples):
            t = rospy.Time(1000 + i * 0.01)
            js = JointState(name=list(joints), position=[0.1 * i] * len(joints), velocity=[0.0] * len(joints))
            js.header.stamp = t
            bag.write(servo_ns + "/joint_states", js, t)
            if state_type == "servo":
                st = BacklashState(sim_time=i * 0.01, command=1.0, gap=0.1, impacts=i)
                st.energy_impact_loss = float("nan") if nan else 0.01 * i
                bag.write(servo_ns + "/backlash_state", st, t)
            else:
                bag.write(servo_ns + "/backlash_state", String(data="not a servo"), t)
            if arm:
                a = JointState(name=["shoulder", "elbow", "wrist"], position=[0.5, 0.5, 0.5], velocity=[0, 0, 0])
                a.header.stamp = t
                bag.write("/joint_states", a, t)


class NodeRecordingTargets(unittest.TestCase):
    """record_bag checked like every output: a device is refused at start; a full disk is reported, the node exits
    cleanly with status 1 and the partial bag is kept as FILE.active."""

    def test_device_target_and_full_disk(self):
        with tempfile.TemporaryDirectory() as d:
            env = dict(os.environ, ROS_MASTER_URI="http://localhost:11427", ROS_HOME=d)
            master = subprocess.Popen(["roscore", "-p", "11427"], env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL)
            try:
                node = ["rosrun", "backlash_servo", "backlash_servo_node", "_publish_clock:=true",
                        "_real_time_factor:=0", "_start_delay:=0", "_stop_after:=200"]
                dev = subprocess.run(node + ["_record_bag:=/dev/null"], env=env, capture_output=True, text=True,
                                     timeout=60)
                self.assertEqual(dev.returncode, 1, dev.stderr)
                self.assertIn("record_bag: '/dev/null' is a device", dev.stderr + dev.stdout)
                bag = os.path.join(d, "x.bag")
                # A 64 KiB file-size limit: writes fail as on a full disk (EFBIG instead of ENOSPC).
                full = subprocess.run(["bash", "-c", "trap '' XFSZ; ulimit -f 64; exec \"$@\"", "bash"] + node +
                                      ["_record_bag:=" + bag], env=env, capture_output=True, text=True, timeout=60)
                out = full.stdout + full.stderr
                self.assertEqual(full.returncode, 1, out[-2000:])  # not 134 (an exception out of a destructor)
                self.assertIn("record_bag: could not write", out)
                self.assertIn("closing %s.active failed" % bag, out)
                self.assertTrue(os.path.exists(bag + ".active"))
                self.assertFalse(os.path.exists(bag))
            finally:
                master.terminate()
                master.wait(timeout=30)


class BagReportInputs(unittest.TestCase):
    """Damaged, foreign and ambiguous bags: one line and exit 2, never a traceback; JSON is valid; PNG writes checked."""

    def report(self, *args):
        r = subprocess.run(["/usr/bin/python3", REPORT] + list(args), capture_output=True, text=True, timeout=60)
        return r.returncode, r.stdout, r.stderr

    def assert_one_line_refusal(self, args, says):
        code, out, err = self.report(*args)
        self.assertEqual(code, 2, err)
        self.assertNotIn("Traceback", err)
        self.assertEqual(err.count("\n"), 1, err)
        self.assertIn(says, err)

    def test_any_joint_states_topic_becomes_a_recording(self):
        # A robot's bag without backlash_servo topics: --joint-states TOPIC with the motor's and load's joint names
        # writes backlash_identify's recording (time from the first sample, the motor's effort, both positions).
        import rospy
        from sensor_msgs.msg import JointState
        with tempfile.TemporaryDirectory() as d:
            bag_path, csv_path = os.path.join(d, "robot.bag"), os.path.join(d, "recording.csv")
            with rosbag.Bag(bag_path, "w") as bag:
                for i in range(20):
                    t = rospy.Time(500 + i * 0.001)
                    js = JointState(name=["shoulder", "m1", "l1"], position=[9.0, 0.01 * i, 0.02 * i],
                                    velocity=[0.0, 0.0, 0.0], effort=[5.0, 0.5 + i, -1.0])
                    js.header.stamp = t
                    bag.write("/arm/joint_states", js, t)
            code, out, err = self.report(bag_path, "--joint-states", "/arm/joint_states", "--motor-joint", "m1",
                                         "--load-joint", "l1", "--recording", csv_path)
            self.assertEqual(code, 0, err)
            self.assertIn("20 samples", out)
            with open(csv_path) as f:
                rows = list(csv.DictReader(f))
            self.assertEqual(len(rows), 20)
            self.assertAlmostEqual(float(rows[3]["time"]), 0.003, delta=2e-9)  # (ROS time: whole nanoseconds)
            self.assertEqual(float(rows[3]["motor_torque"]), 3.5)
            self.assertAlmostEqual(float(rows[3]["motor_position"]), 0.03, delta=1e-15)
            self.assertAlmostEqual(float(rows[3]["load_position"]), 0.06, delta=1e-15)
            self.assert_one_line_refusal([bag_path, "--joint-states", "/arm/joint_states", "--recording", csv_path],
                                         "has no joint 'load_joint'")
            self.assert_one_line_refusal([bag_path, "--joint-states", "/nowhere", "--recording", csv_path],
                                         "no topic /nowhere")

    def test_damaged_foreign_and_ambiguous_bags(self):
        with tempfile.TemporaryDirectory() as d:
            good = os.path.join(d, "good.bag")
            write_bag(good)
            code, out, err = self.report(good, "--json")
            self.assertEqual(code, 0, err)
            self.assertEqual(json.loads(out)["samples"], 50)
            # Damaged: the middle of the file overwritten, and the file cut short.
            data = open(good, "rb").read()
            damaged = os.path.join(d, "damaged.bag")
            with open(damaged, "wb") as f:
                f.write(data[:len(data) // 3] + b"\xff" * 2000 + data[len(data) // 3 + 2000:])
            code, _, err = self.report(damaged)
            self.assertEqual(code, 2, err)
            self.assertNotIn("Traceback", err)
            garbage = os.path.join(d, "garbage.bag")
            with open(garbage, "wb") as f:
                f.write(b"#ROSBAG V2.0\n" + os.urandom(5000))
            code, _, err = self.report(garbage)
            self.assertEqual(code, 2, err)
            self.assertNotIn("Traceback", err)
            one = os.path.join(d, "one_joint.bag")
            write_bag(one, joints=("motor_joint",))
            self.assert_one_line_refusal([one], "no joint 'load_joint'")
            foreign = os.path.join(d, "foreign.bag")
            write_bag(foreign, state_type="string")
            self.assert_one_line_refusal([foreign], "not a backlash_servo recording")
            # A whole robot: the arm's /joint_states beside /servo/*: the servo's own topics are read.
            robot = os.path.join(d, "robot.bag")
            write_bag(robot, servo_ns="/servo", arm=True, samples=80)
            code, out, err = self.report(robot, "--json")
            self.assertEqual(code, 0, err)
            self.assertEqual(json.loads(out)["samples"], 80)
            two = os.path.join(d, "two.bag")
            with rosbag.Bag(two, "w") as b:
                for src in (robot, good):
                    with rosbag.Bag(src) as r:
                        for topic, msg, t in r.read_messages():
                            b.write(topic, msg, t)
            self.assert_one_line_refusal([two], "choose one with --namespace")
            code, out, err = self.report(two, "--namespace", "/servo", "--json")
            self.assertEqual(code, 0, err)
            self.assertEqual(json.loads(out)["samples"], 80)

    def test_json_is_valid_and_png_writes_are_checked(self):
        with tempfile.TemporaryDirectory() as d:
            bag = os.path.join(d, "nan.bag")
            write_bag(bag, nan=True)
            code, out, err = self.report(bag, "--json")
            self.assertEqual(code, 0, err)
            self.assertNotIn("NaN", out)
            report = json.loads(out)
            self.assertIsNone(report["impact_energy_per_second"])
            self.assert_one_line_refusal([bag, "--png", "/dev/full"], "not a regular file")
            self.assert_one_line_refusal([bag, "--png", os.path.join(d, "missing", "r.png")], "does not exist")
            os.symlink("elsewhere.png", os.path.join(d, "link.png"))
            self.assert_one_line_refusal([bag, "--png", os.path.join(d, "link.png")], "symbolic link")
            code, _, err = self.report(bag, "--png", os.path.join(d, "r.png"))
            self.assertEqual(code, 0, err)
            self.assertEqual(open(os.path.join(d, "r.png"), "rb").read(4), b"\x89PNG")
            self.assertEqual(sorted(os.listdir(d)), ["link.png", "nan.bag", "r.png"])  # no temporary left


class BagReportStretches(unittest.TestCase):
    """Each stretch between changes is reported on its own: a bag whose load oscillates about 1 rad with amplitude
    0.05 rad and period 2 s until a live change at 10 s restarts the node's judgement, then about 0.5 rad with 0.02 rad
    and 1 s. The report's stretches carry the node's verdict of each and estimates from each one's samples only."""

    def test_two_stretches(self):
        import math
        import rospy
        from backlash_servo.msg import BacklashState, LimitCycleStatus
        from sensor_msgs.msg import JointState
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "stretches.bag")
            with rosbag.Bag(path, "w") as bag:
                def lc(t, verdict, error, period, maxima, command, reason=""):
                    m = LimitCycleStatus(sim_time=t, verdict=verdict, detected=verdict == "limit_cycle", error=error,
                                         period=period, maxima_observed=maxima, command=command, reason=reason)
                    m.header.stamp = rospy.Time(t + 1.0)
                    bag.write("/limit_cycle", m, rospy.Time(t + 1.0))
                for i in range(2001):
                    t = i * 0.01
                    command, amp, period = (1.0, 0.05, 2.0) if t < 10.0 else (0.5, 0.02, 1.0)
                    x = command + amp * math.sin(2.0 * math.pi * t / period)
                    stamp = rospy.Time(t + 1.0)
                    js = JointState(name=["motor_joint", "load_joint"], position=[x, x], velocity=[0.0, 0.0])
                    js.header.stamp = stamp
                    bag.write("/joint_states", js, stamp)
                    bag.write("/backlash_state", BacklashState(sim_time=t, command=command, gap=0.0), stamp)
                    if i == 900:
                        lc(t, "limit_cycle", 0.05, 2.0, 4, 1.0)
                    if i == 1000:
                        lc(t, "undecided", 0.0, 0.0, 0, 0.5, "live change of backlash at t = 10 s: judging afresh")
                    if i == 1900:
                        lc(t, "limit_cycle", 0.02, 1.0, 8, 0.5)
            out = subprocess.run(["/usr/bin/python3", REPORT, path, "--json"], check=True, capture_output=True,
                                 text=True).stdout
            text = subprocess.run(["/usr/bin/python3", REPORT, path], check=True, capture_output=True,
                                  text=True).stdout
        report = json.loads(out)
        s = report["stretches"]
        self.assertEqual(len(s), 2, s)
        self.assertEqual((s[0]["from"], s[0]["reason"], s[0]["command"]), (0.0, "start", 1.0))
        self.assertAlmostEqual(s[1]["from"], 10.0, delta=1e-9)
        self.assertIn("live change of backlash", s[1]["reason"])
        self.assertEqual(s[1]["command"], 0.5)
        self.assertEqual(s[0]["node"]["limit_cycle_error"], 0.05)
        self.assertEqual(s[1]["node"]["limit_cycle_error"], 0.02)
        for stretch, (amp, period) in zip(s, ((0.05, 2.0), (0.02, 1.0))):
            self.assertAlmostEqual(stretch["from_samples"]["error"], amp, delta=1e-5)  # parabola through samples
            self.assertAlmostEqual(stretch["from_samples"]["period"], period, delta=1e-3)
            self.assertAlmostEqual(stretch["rms_error"], amp / math.sqrt(2.0), delta=1e-3)
        self.assertIn("2 stretches between changes", text)

    def test_nan_figures_inside_stretches_and_a_converged_verdicts_text(self):
        # The node publishes NaN for figures that do not exist yet (a settling time while outside the band): inside
        # the stretches' list too they are null in the JSON, and a converged verdict's text gives its steady error,
        # never "error 0 rad, period 0 s".
        import rospy
        from backlash_servo.msg import BacklashState, LimitCycleStatus
        from sensor_msgs.msg import JointState
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "converged.bag")
            with rosbag.Bag(path, "w") as bag:
                for i in range(400):
                    t = i * 0.01
                    stamp = rospy.Time(t + 1.0)
                    command = 1.0 if t < 2.0 else 0.5
                    js = JointState(name=["motor_joint", "load_joint"], position=[command, command], velocity=[0, 0])
                    js.header.stamp = stamp
                    bag.write("/joint_states", js, stamp)
                    bag.write("/backlash_state", BacklashState(sim_time=t, command=command, gap=0.0), stamp)
                    if i in (100, 200, 300):
                        m = LimitCycleStatus(sim_time=t, verdict="undecided" if i == 200 else "converged",
                                             command=command, settling_time=float("nan"),
                                             steady_rms_error=float("nan"),
                                             steady_error=-0.3 if i == 100 else float("nan"),
                                             steady_basis={100: "equilibrium", 200: "", 300: "unsettled"}[i],
                                             reason="a new command at t = 2 s: judging afresh" if i == 200 else "")
                        m.header.stamp = stamp
                        bag.write("/limit_cycle", m, stamp)
            code, out, err = self.report_of(path, "--json")
            self.assertEqual(code, 0, err)
            report = json.loads(out, parse_constant=lambda c: self.fail("non-JSON constant %s" % c))
            text = self.report_of(path)[1]
        self.assertEqual(len(report["stretches"]), 2)
        self.assertIsNone(report["stretches"][0]["node"]["steady_rms_error"])
        self.assertEqual(report["stretches"][0]["node"]["steady_error"], -0.3)
        self.assertIsNone(report["node"]["steady_error"])
        self.assertIsNone(report["node"]["limit_cycle_error"])
        self.assertIn("node's verdict: converged, steady error n/a", text)
        self.assertIn("node converged, steady error -0.3 rad (equilibrium)", text)
        self.assertNotIn("period 0 s", text)

    @staticmethod
    def report_of(path, *args):
        p = subprocess.run(["/usr/bin/python3", REPORT, path] + list(args), capture_output=True, text=True)
        return p.returncode, p.stdout, p.stderr

    def test_a_pattern_of_two_maxima(self):
        """x = 0.04 cos(2πt/P) + 0.03 cos(4πt/P + 1): two unequal maxima per period P = 1.6 s. The report finds the
        pattern (2 maxima per period, its period P, not the spacing of maxima) and its peak to peak, checked against
        the curve's own extremes over a period evaluated on a fine grid here."""
        import math
        import rospy
        from backlash_servo.msg import BacklashState
        from sensor_msgs.msg import JointState
        P = 1.6
        x = lambda t: 0.04 * math.cos(2 * math.pi * t / P) + 0.03 * math.cos(4 * math.pi * t / P + 1.0)
        fine = [x(i * P / 100000) for i in range(100000)]
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "pattern.bag")
            with rosbag.Bag(path, "w") as bag:
                for i in range(1601):
                    t = i * 0.01
                    stamp = rospy.Time(t + 1.0)
                    js = JointState(name=["motor_joint", "load_joint"], position=[x(t), x(t)], velocity=[0.0, 0.0])
                    js.header.stamp = stamp
                    bag.write("/joint_states", js, stamp)
                    bag.write("/backlash_state", BacklashState(sim_time=t, command=-0.2, gap=0.0), stamp)
            out = subprocess.run(["/usr/bin/python3", REPORT, path, "--json"], check=True, capture_output=True,
                                 text=True).stdout
        est = json.loads(out)["from_samples"]
        self.assertEqual(est["maxima_per_period"], 2)
        self.assertAlmostEqual(est["period"], P, delta=2e-3)
        self.assertAlmostEqual(est["peak_to_peak"], max(fine) - min(fine), delta=1e-4)
        self.assertAlmostEqual(est["cycle_centre"], 0.5 * (max(fine) + min(fine)), delta=1e-4)
        self.assertAlmostEqual(est["error"], max(fine) + 0.2, delta=1e-5)


if __name__ == "__main__":
    ALL = unittest.TestSuite([unittest.TestLoader().loadTestsFromTestCase(c)
                              for c in (BagReport, BagReportInputs, NodeRecordingTargets, BagReportStretches)])
    rostest.rosrun("backlash_servo", "bag_report", "__main__.ALL")
