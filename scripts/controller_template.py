#!/usr/bin/python3
"""Your own controller for backlash_servo_node, in Python: a template to copy and change.

The node runs in effort mode (``control_mode: effort``): it applies the torque you publish on ``motor_effort``
[N·m] and publishes, at every sample t_k = k / publish_rate of sim time, what the plant's encoders read on
``encoder_states`` (sensor_msgs/JointState: position = quantised motor angle [rad, motor shaft] and load angle [rad];
the true angles are on ``joint_states``). This template is a PID on each joint's load encoder:

    e_k = θ_R − y_k,   I_k = I_{k−1} + ki Δt_k e_k,   u_k = kp e_k + I_k − kd (y_k − y_{k−1}) / Δt_k

saturated at ±torque_limit with conditional integration (no wind-up against the limit).

One joint: ``motor_effort`` is a std_msgs/Float64. An arm (the node was given ``joints:``, robot.launch): one PID
per joint, and ``motor_effort`` is one sensor_msgs/JointState with every joint's effort under its name, answering
each state in one message.

Lockstep (``sync: true``, external_controller.launch, robot.launch with controller:=python): the node publishes the
state at t_k and waits for exactly one ``motor_effort`` before it advances to t_{k+1}. To be deterministic (the same
bag on every run) a controller must
  1. answer every state exactly once, from its callback — no timer, no ``rospy.Rate``, no wall time;
  2. compute with the state's stamp, never with ``rospy.Time.now()`` (which lags behind /clock by a message);
  3. keep all its state in the callback's variables (the callback runs on one thread, in order).
Sim time starts at 0 (param ``start_time``), so the usual float idiom ``stamp.to_sec() - t_prev`` used here gives
the same Δt on every run (with a wall-clock epoch of ~1.8e9 s it would round differently run to run); the integer
form ``(stamp - previous).to_sec()`` is exact for any epoch.

Params (private, SI): ~kp [N·m/rad], ~ki [N·m/(rad·s)], ~kd [N·m·s/rad], ~torque_limit [N·m] (0 = none),
~topic [encoder_states or joint_states, default encoder_states].
One joint: ~command [rad] (initial set-point θ_R, default the servo's ``backlash_servo/command``; the ``command``
topic changes it), ~joint [load joint name, default load_joint].
An arm: each joint's gains are ~gains/<joint>/kp, ki, kd, else the servo's own PID gains of that joint (its
``gain``, ``integral_gain``, ``derivative_gain``: the same law outside the node), else ~kp, ~ki, ~kd; its set-point
is the servo's ``command`` of that joint (``<joint>/command`` changes it).
"""
import math

import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

SERVO = "backlash_servo"  # the node's name beside this one: its parameters are read from there


def finite(name, value, non_negative=False):
    """The value as a float, or ValueError naming the param."""
    value = float(value)
    if not math.isfinite(value) or (non_negative and value < 0.0):
        raise ValueError("~%s: must be finite%s (got %r)" % (name, ", >= 0" if non_negative else "", value))
    return value


class Pid:
    """The law above for one joint: its gains, its set-point θ_R [rad] and its state between samples."""

    def __init__(self, name, kp, ki, kd, limit, command):
        self.name = name
        self.kp, self.ki, self.kd = kp, ki, kd
        self.limit = limit
        self.command = command
        # The controller's state: integral [N·m], previous reading [rad] and its time [s] (None before the first).
        self.integral = 0.0
        self.y_prev = 0.0
        self.t_prev = None

    def on_command(self, msg):
        if math.isfinite(msg.data):
            self.command = msg.data

    def update(self, y, t):
        """The torque [N·m] for the reading y [rad] at sim time t [s]."""
        dt = 0.0 if self.t_prev is None else t - self.t_prev  # Δt from the stamps [s]; 0 at the first state
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
        return u


class Controller:
    def __init__(self):
        # Gains and settings, read once at start-up (private params, SI units).
        kp = finite("kp", rospy.get_param("~kp", 1.0))
        ki = finite("ki", rospy.get_param("~ki", 0.0))
        kd = finite("kd", rospy.get_param("~kd", 0.0))
        limit = finite("torque_limit", rospy.get_param("~torque_limit", 0.0), non_negative=True)
        topic = rospy.get_param("~topic", "encoder_states")
        arm = rospy.get_param(SERVO + "/joints", None)
        self.pids = {}
        if arm:
            # An arm: one PID per joint, its set-point and (unless given here) its gains the servo's for that joint.
            for name, keys in arm.items():
                def servo(key, default):
                    return keys.get(key, rospy.get_param(SERVO + "/" + key, default))
                gains = rospy.get_param("~gains/" + name, {})
                pid = Pid(name,
                          finite("gains/%s/kp" % name, gains.get("kp", servo("gain", kp))),
                          finite("gains/%s/ki" % name, gains.get("ki", servo("integral_gain", ki))),
                          finite("gains/%s/kd" % name, gains.get("kd", servo("derivative_gain", kd))),
                          limit, finite(SERVO + "/joints/%s/command" % name, servo("command", 0.0)))
                self.pids[name] = pid
            self.effort_pub = rospy.Publisher("motor_effort", JointState, queue_size=100)
            for pid in self.pids.values():
                rospy.Subscriber(pid.name + "/command", Float64, pid.on_command, queue_size=10)
        else:
            # θ_R: ~command, else the servo's own set-point, else 1 rad.
            command = finite("command", rospy.get_param("~command", rospy.get_param(SERVO + "/command", 1.0)))
            name = rospy.get_param("~joint", "load_joint")
            self.pids[name] = Pid(name, kp, ki, kd, limit, command)
            self.effort_pub = rospy.Publisher("motor_effort", Float64, queue_size=100)
            rospy.Subscriber("command", Float64, self.pids[name].on_command, queue_size=10)
        self.arm = bool(arm)
        # Publisher first, then the subscriber: in lockstep the node waits until both are connected.
        rospy.Subscriber(topic, JointState, self.on_state, queue_size=100, tcp_nodelay=True)

    def on_state(self, msg):
        t = msg.header.stamp.to_sec()
        names, efforts = [], []
        for name, y in zip(msg.name, msg.position):  # each joint's load reading [rad]; motors are skipped
            pid = self.pids.get(name)
            if pid is not None:
                names.append(name)
                efforts.append(pid.update(y, t))
        if len(names) != len(self.pids):
            rospy.logwarn_throttle(5.0, "controller_template: the state lacks joints of %s" % sorted(self.pids))
        if not names:
            return
        # Exactly one answer per state.
        if self.arm:
            self.effort_pub.publish(JointState(header=msg.header, name=names, effort=efforts))
        else:
            self.effort_pub.publish(Float64(efforts[0]))


def main():
    rospy.init_node("controller")
    try:
        Controller()
    except ValueError as e:
        rospy.logfatal("controller_template: %s" % e)
        raise SystemExit(1)
    rospy.spin()


if __name__ == "__main__":
    main()
