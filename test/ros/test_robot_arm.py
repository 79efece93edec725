#!/usr/bin/python3
"""An arm in one node: every joint on joint_states, gravity carried through each gear, commands per joint."""
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dynamic_reconfigure.client  # noqa: E402
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from backlash_servo.msg import BacklashState, ImpactEvent, LimitCycleStatus  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from helpers import Collector, bag_contents, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"
THESIS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "config", "thesis_limit_cycle.yaml")
REPORT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "bin", "backlash_bag_report")
JOINTS = ["shoulder", "elbow", "wrist"]
RHO = {"shoulder": 0.01, "elbow": 0.01, "wrist": 0.02}  # 1 / the URDF's mechanicalReduction
G = 9.80665


def gravity(q):
    """Gravity's torque on each load of the example arm by hand: link masses at their centres, +q turning down."""
    c1, c12, c123 = math.cos(q[0]), math.cos(q[0] + q[1]), math.cos(q[0] + q[1] + q[2])
    wrist = G * 0.9 * 0.08 * c123
    elbow = G * (2.1 * 0.175 + 0.9 * 0.35) * c12 + wrist
    shoulder = G * (3.2 * 0.2 + 3.0 * 0.4) * c1 + elbow
    return [shoulder, elbow, wrist]


class RobotArm(unittest.TestCase):
    def test_an_arm_in_one_node(self):
        rospy.init_node("test_robot_arm")
        joints = Collector("/joint_states", JointState)
        impacts = Collector("/impact", ImpactEvent)
        cycles = {j: Collector("/%s/limit_cycle" % j, LimitCycleStatus) for j in JOINTS}
        states = Collector("/shoulder/backlash_state", BacklashState)
        diagnostics = Collector("/diagnostics", DiagnosticArray)
        trajectory = rospy.Publisher("/command_trajectory", JointTrajectory, queue_size=10)
        elbow_command = rospy.Publisher("/elbow/command", Float64, queue_size=10)
        self.assertTrue(joints.wait_connected() and impacts.wait_connected())
        self.assertTrue(all(c.wait_connected() for c in cycles.values()))
        self.assertTrue(wait_for(lambda: trajectory.get_num_connections() > 0
                                 and elbow_command.get_num_connections() > 0, 10.0))
        self.assertTrue(call_trigger(NODE + "/resume").success)

        def now():
            return joints.msgs[-1].header.stamp.to_sec() if joints.msgs else 0.0

        def pose():
            js = joints.msgs[-1]
            return [js.position[js.name.index(j)] for j in JOINTS]

        # Held at the commands (0.3, -0.6, 0.4 rad); each motor carries its load's gravity through its gear.
        self.assertTrue(wait_for(lambda: now() >= 4.0, 60.0))
        js = joints.msgs[-1]
        self.assertEqual(list(js.name), JOINTS + [j + "_motor" for j in JOINTS])
        q = pose()
        for got, want in zip(q, [0.3, -0.6, 0.4]):
            self.assertAlmostEqual(got, want, delta=1e-3)
        # (A PID on a quantised encoder hunts a fraction of a count: one count's step in its derivative is 0.05 N·m at
        # the shoulder, so the torque balances gravity on average over the hunt, here over 2.5 s.)
        held = gravity(q)
        recent = [m for m in joints.msgs if m.header.stamp.to_sec() >= 1.5]
        for i, j in enumerate(JOINTS):
            k = js.name.index(j + "_motor")
            motor = sum(m.effort[k] for m in recent) / len(recent)
            print("%s: mean motor torque %.6g N·m, -rho * gravity %.6g N·m" % (j, motor, -RHO[j] * held[i]))
            self.assertAlmostEqual(motor, -RHO[j] * held[i], delta=0.03 * RHO[j] * abs(held[i]), msg=j)
        for j in JOINTS:
            self.assertTrue(cycles[j].msgs, j)
            self.assertEqual(cycles[j].msgs[-1].joint, j)
            self.assertGreater(cycles[j].msgs[-1].settling_band, 0.0, j)  # the tracking figures, as a joint's
        # Each joint's backlash_state (the shoulder's: its set-point, the teeth on a flank or apart) and its own status
        # on /diagnostics with the load it carries now: gravity at the pose.
        self.assertTrue(states.msgs)
        self.assertEqual(states.msgs[-1].command, 0.3)
        self.assertTrue(wait_for(lambda: any(s.name.endswith(": shoulder") for a in diagnostics.msgs
                                             for s in a.status), 30.0))
        status = [s for a in diagnostics.msgs for s in a.status if s.name.endswith(": shoulder")][-1]
        values = {kv.key: kv.value for kv in status.values}
        self.assertAlmostEqual(float(values["load_torque [N·m]"]), held[0], delta=0.01 * abs(held[0]))
        self.assertIn(values["verdict"], ("limit_cycle", "converged", "undecided", "irregular_oscillation"))

        # A trajectory for the wrist alone: it goes to 0 rad in 0.5 s; the others hold their set-points.
        msg = JointTrajectory()
        msg.joint_names = ["wrist"]
        msg.points = [JointTrajectoryPoint(positions=[0.0], time_from_start=rospy.Duration(0.5))]
        sent = now()
        trajectory.publish(msg)
        self.assertTrue(wait_for(lambda: now() >= sent + 3.0, 60.0))
        q = pose()
        self.assertAlmostEqual(q[2], 0.0, delta=1e-3)
        self.assertAlmostEqual(q[0], 0.3, delta=2e-3)
        self.assertAlmostEqual(q[1], -0.6, delta=2e-3)
        wrist_status = cycles["wrist"].msgs[-1]
        self.assertEqual(wrist_status.command, 0.0)

        # A joint the arm does not have: refused whole, nothing moves.
        bad = JointTrajectory()
        bad.joint_names = ["wrist", "gripper"]
        bad.points = [JointTrajectoryPoint(positions=[0.5, 0.0], time_from_start=rospy.Duration(0.1))]
        trajectory.publish(bad)

        # The forearm upright: gravity on the elbow's load nearly vanishes, its teeth float and rattle in the play.
        sent = now()
        elbow_command.publish(Float64(math.pi / 2 - 0.3))
        self.assertTrue(wait_for(lambda: any(m.joint == "elbow" and m.sim_time > sent + 1.0 for m in impacts.msgs),
                                 60.0))
        self.assertTrue(wait_for(lambda: now() >= sent + 2.0, 60.0))
        self.assertAlmostEqual(pose()[2], 0.0, delta=1e-3)  # the refused trajectory did not move the wrist
        self.assertTrue(all(m.joint in JOINTS for m in impacts.msgs))

        # Live tuning per joint (rqt: one group per joint): the wrist's restitution changes, its judgement restarts;
        # the shoulder's load torque is the arm's gravity and is refused (the reply holds the value in force).
        wrist = dynamic_reconfigure.client.Client(NODE + "/wrist", timeout=10)
        self.assertEqual(wrist.update_configuration({"restitution": 0.5})["restitution"], 0.5)
        self.assertTrue(wait_for(lambda: "live change of restitution" in cycles["wrist"].msgs[-1].reason, 30.0),
                        cycles["wrist"].msgs[-1].reason)
        self.assertNotIn("live change", cycles["elbow"].msgs[-1].reason)
        shoulder = dynamic_reconfigure.client.Client(NODE + "/shoulder", timeout=10)
        kept = shoulder.update_configuration({"load_torque": 0.0})["load_torque"]
        self.assertNotEqual(kept, 0.0)

        # The node's bag, reported joint by joint: each joint's last verdict as its topic said it.
        path = rospy.get_param("~bag")
        self.assertTrue(wait_for(lambda: os.path.exists(path) and not os.path.exists(path + ".active"), 60.0), path)
        time.sleep(0.5)  # the last messages in flight to this client
        got = subprocess.run(["/usr/bin/python3", REPORT, path, "--json"], capture_output=True, text=True)
        self.assertEqual(got.returncode, 0, got.stderr)
        report = json.loads(got.stdout)
        self.assertEqual([r["joint"] for r in report["joints"]], JOINTS)
        for r in report["joints"]:
            last = cycles[r["joint"]].msgs[-1]
            self.assertEqual(r["node"]["verdict"], last.verdict, r["joint"])
            self.assertEqual(r["command"], last.command, r["joint"])
        self.assertAlmostEqual(report["simulated_time"], 16.0, delta=1e-9)
        elbow = report["joints"][1]
        self.assertGreater(elbow["impacts_per_second"], 10.0)  # the upright forearm rattled
        os.remove(path)

    def test_joints_without_an_arm_equal_single_joint_nodes(self):
        # Two joints in one node (a robot file without a URDF: no coupling) move exactly as two single-joint nodes
        # running their configurations: every sample and every impact bit for bit.
        with open(THESIS) as f:
            thesis = f.read()
        with tempfile.TemporaryDirectory() as d:
            files = {"two": thesis + "\njoints:\n  a: {command: 1.0}\n  b: {command: 0.5, restitution: 0.6}\n",
                     "a": thesis, "b": thesis.replace("command: 1.0", "command: 0.5")
                     .replace("restitution: 1.0", "restitution: 0.6")}
            bags = {}
            for port, (name, text) in enumerate(sorted(files.items()), start=11471):
                config = os.path.join(d, name + ".yaml")
                with open(config, "w") as f:
                    f.write(text)
                env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % port)
                subprocess.run(["roslaunch", "-p", str(port), "backlash_servo", "backlash_servo.launch",
                                "config:=" + config, "record:=true", "bag_dir:=" + d, "bag_name:=" + name,
                                "stop_after:=20", "real_time_factor:=0", "publish_clock:=true"],
                               env=env, check=False, capture_output=True, timeout=120)
                bags[name] = bag_contents(os.path.join(d, name + ".bag"))
        two = bags["two"]["/joint_states"]
        self.assertEqual(list(two[0].name), ["a", "b", "a_motor", "b_motor"])
        for joint in ("a", "b"):
            single = bags[joint]["/joint_states"]
            self.assertEqual(len(single), 2001)
            self.assertEqual(len(two), len(single))
            load, motor = two[0].name.index(joint), two[0].name.index(joint + "_motor")
            for t, s in zip(two, single):  # the single joint's order: motor_joint, load_joint
                self.assertEqual(t.header.stamp, s.header.stamp)
                self.assertEqual((t.position[load], t.velocity[load], t.effort[load]),
                                 (s.position[1], s.velocity[1], s.effort[1]))
                self.assertEqual((t.position[motor], t.velocity[motor], t.effort[motor]),
                                 (s.position[0], s.velocity[0], s.effort[0]))
            impacts = [m for m in bags["two"]["/impact"] if m.joint == joint]
            self.assertGreater(len(impacts), 10)
            self.assertEqual([(m.sim_time, m.impulse, m.energy_loss) for m in impacts],
                             [(m.sim_time, m.impulse, m.energy_loss) for m in bags[joint]["/impact"]])


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "robot_arm", RobotArm)
