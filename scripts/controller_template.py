#!/usr/bin/python3
"""Your own controller for backlash_servo_node, in Python: a template to copy and change.

The node runs in effort mode (``control_mode: effort``): it applies the torque you publish on ``motor_effort``
[N·m] and publishes, at every sample t_k = k / publish_rate of sim time, what the plant's encoders read on
``encoder_states`` (sensor_msgs/JointState: position = quantised motor angle [rad, motor shaft] and load angle [rad];
the true angles are on ``joint_states``). This template is a PID on the load encoder:

    e_k = θ_R − y_k,   I_k = I_{k−1} + ki Δt_k e_k,   u_k = kp e_k + I_k − kd (y_k − y_{k−1}) / Δt_k

saturated at ±torque_limit with conditional integration (no wind-up against the limit).

Lockstep (``sync: true``, external_controller.launch): the node publishes the state at t_k and waits for exactly one
``motor_effort`` before it advances to t_{k+1}. To be deterministic (the same bag on every run) a controller must
  1. answer every state exactly once, from its callback — no timer, no ``rospy.Rate``, no wall time;
  2. compute with the state's stamp, never with ``rospy.Time.now()`` (which lags behind /clock by a message);
  3. keep all its state in the callback's variables (the callback runs on one thread, in order).
Sim time starts at 0 (param ``start_time``), so the usual float idiom ``stamp.to_sec() - t_prev`` used here gives
the same Δt on every run (with a wall-clock epoch of ~1.8e9 s it would round differently run to run); the integer
form ``(stamp - previous).to_sec()`` is exact for any epoch.

Params (private, SI): ~kp [N·m/rad], ~ki [N·m/(rad·s)], ~kd [N·m·s/rad], ~torque_limit [N·m] (0 = none),
~command [rad] (initial set-point θ_R, default the servo's ``backlash_servo/command``; the ``command`` topic
changes it), ~joint [load joint name, default
load_joint], ~topic [encoder_states or joint_states, default encoder_states].
"""
import math

import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64


class PidController:
    def __init__(self):
        # Gains and settings, read once at start-up (private params, SI units).
        self.kp = float(rospy.get_param("~kp", 1.0))
        self.ki = float(rospy.get_param("~ki", 0.0))
        self.kd = float(rospy.get_param("~kd", 0.0))
        self.limit = float(rospy.get_param("~torque_limit", 0.0))
        # θ_R: ~command, else the servo's own set-point (backlash_servo/command beside this node), else 1 rad.
        self.command = float(rospy.get_param("~command", rospy.get_param("backlash_servo/command", 1.0)))
        self.joint = rospy.get_param("~joint", "load_joint")
        topic = rospy.get_param("~topic", "encoder_states")
        for name, value in (("kp", self.kp), ("ki", self.ki), ("kd", self.kd), ("torque_limit", self.limit),
                            ("command", self.command)):
            if not math.isfinite(value) or (name == "torque_limit" and value < 0.0):
                raise ValueError("~%s: must be finite%s (got %r)" % (name, ", >= 0" if name == "torque_limit" else "",
                                                                     value))
        # The controller's state: integral [N·m], previous reading [rad] and its time [s] (None before the first).
        self.integral = 0.0
        self.y_prev = 0.0
        self.t_prev = None
        # Publisher first, then the subscriber: in lockstep the node waits until both are connected.
        self.effort_pub = rospy.Publisher("motor_effort", Float64, queue_size=100)
        rospy.Subscriber("command", Float64, self.on_command, queue_size=10)
        rospy.Subscriber(topic, JointState, self.on_state, queue_size=100, tcp_nodelay=True)

    def on_command(self, msg):
        if math.isfinite(msg.data):
            self.command = msg.data

    def on_state(self, msg):
        try:
            y = msg.position[list(msg.name).index(self.joint)]  # the load reading [rad]
        except (ValueError, IndexError):
            rospy.logwarn_throttle(5.0, "controller_template: no joint '%s' in the state" % self.joint)
            return
        # Δt from the stamps [s]; 0 at the first state.
        t = msg.header.stamp.to_sec()
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        e = self.command - y
        derivative = self.kd * (y - self.y_prev) / dt if dt > 0.0 else 0.0
        integral = self.integral + self.ki * dt * e
        u = self.kp * e + integral - derivative
        if self.limit > 0.0 and abs(u) > self.limit:
            if u * e > 0.0:
                integral = self.integral  # conditional integration: hold the integral while saturated
                u = self.kp * e + integral - derivative
            u = max(-self.limit, min(self.limit, u))
        self.integral, self.y_prev, self.t_prev = integral, y, t
        self.effort_pub.publish(Float64(u))  # exactly one answer per state


def main():
    rospy.init_node("controller")
    try:
        PidController()
    except ValueError as e:
        rospy.logfatal("controller_template: %s" % e)
        raise SystemExit(1)
    rospy.spin()


if __name__ == "__main__":
    main()
