#!/usr/bin/python3
"""joint_states of a compliant joint: the output gear θ_o and the shaft twist θ_o − θ_c beside the motor and the
load, consistent with each other at every sample, at rest on the static torque balance, and naming exactly the joints
of urdf/backlash_servo_compliant.urdf."""
import math
import os
import subprocess
import sys
import unittest
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rospy  # noqa: E402
import rostest  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from helpers import Collector, call_trigger, wait_for  # noqa: E402

NODE = "/backlash_servo"
URDF = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "urdf", "backlash_servo_compliant.urdf")


class CompliantJoint(unittest.TestCase):
    def test_gear_and_shaft_twist(self):
        rospy.init_node("test_compliant_joint")
        p = {k: rospy.get_param(NODE + "/" + k) for k in
             ("gain", "gear_ratio", "load_torque", "mesh_stiffness", "shaft_stiffness", "shaft_damping", "command")}
        js = Collector("/joint_states", JointState)
        self.assertTrue(js.wait_connected())
        self.assertTrue(call_trigger(NODE + "/resume").success)
        self.assertTrue(wait_for(lambda: js.msgs and js.msgs[-1].header.stamp.to_sec() > 30.0, 60.0),
                        "joint_states did not reach 30 s of sim time")
        self.assertTrue(call_trigger(NODE + "/pause").success)
        names = ["motor_joint", "load_joint", "gear_joint", "shaft_twist_joint"]
        moved = 0.0
        for m in js.msgs:
            self.assertEqual(list(m.name), names)
            motor, load, gear, twist = m.position
            # The gear is the load turned by the twist, in position and in velocity; the twist's effort is the shaft
            # torque S = k_s·twist + d_s·rate, the gear's the mesh torque (also the load's, as for rigid teeth).
            self.assertAlmostEqual(gear, load + twist, delta=1e-12)
            self.assertAlmostEqual(m.velocity[2], m.velocity[1] + m.velocity[3], delta=1e-12)
            self.assertAlmostEqual(m.effort[3], p["shaft_stiffness"] * twist + p["shaft_damping"] * m.velocity[3],
                                   delta=1e-9)
            self.assertEqual(m.effort[2], m.effort[1])
            moved = max(moved, abs(twist))
        self.assertGreater(moved, 1e-3)
        # At rest: the load torque T_ext is held by the shaft (S = −T_ext), the shaft by the mesh (Q = S, forward flank
        # pressed by y = Q/c), the mesh by the motor (T_m = ρQ = K(θ_R − θ_c)).
        last = js.msgs[-1]
        t_ext, rho = p["load_torque"], p["gear_ratio"]
        s = -t_ext
        load = p["command"] - rho * s / p["gain"]
        twist = s / p["shaft_stiffness"]
        motor = (load + twist + s / p["mesh_stiffness"]) / rho
        self.assertAlmostEqual(last.position[1], load, delta=1e-5)
        self.assertAlmostEqual(last.position[3], twist, delta=1e-6)
        self.assertAlmostEqual(last.position[0], motor, delta=1e-5)
        self.assertAlmostEqual(last.effort[3], s, delta=1e-4)
        self.assertAlmostEqual(last.effort[2], s, delta=1e-4)
        self.assertAlmostEqual(last.effort[0], rho * s, delta=1e-4)
        for v in last.velocity:
            self.assertLess(abs(v), 1e-4)
        # The compliant URDF's moving joints are all published (load_joint is published too; that tree reaches the
        # load through the shaft twist).
        joints = [j.get("name") for j in ET.parse(URDF).getroot().iter("joint") if j.get("type") != "fixed"]
        self.assertEqual(sorted(joints), sorted(n for n in names if n != "load_joint"))
        self.assertTrue(math.isfinite(sum(last.position)))

    def test_joint_names_must_differ(self):
        # A node given two joints of one name refuses to start, naming both keys.
        p = subprocess.run(["rosrun", "backlash_servo", "backlash_servo_node", "__name:=duplicate_names",
                            "_gear_joint_name:=load_joint"], capture_output=True, text=True, timeout=60)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("load_joint_name, gear_joint_name: must be different joint names (both 'load_joint')",
                      p.stdout + p.stderr)


if __name__ == "__main__":
    rostest.rosrun("backlash_servo", "compliant_joint", CompliantJoint)
