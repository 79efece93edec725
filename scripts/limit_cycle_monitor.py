#!/usr/bin/python3
"""Prints a one-line readable summary of backlash_servo's limit_cycle topic as it changes."""
import rospy
from backlash_servo.msg import LimitCycleStatus


def on_status(msg):
    if msg.detected:
        rospy.loginfo("t = %.2f s: %s, error %.6f rad, period %.4f s (%d maxima)", msg.sim_time,
                      msg.verdict.replace("_", " ").upper(), msg.error, msg.period, msg.maxima_observed)
    else:
        rospy.loginfo("t = %.2f s: %s, latest maximum %.6f rad (%d maxima)", msg.sim_time, msg.verdict,
                      msg.last_maximum_position, msg.maxima_observed)


if __name__ == "__main__":
    rospy.init_node("limit_cycle_monitor")
    rospy.Subscriber("limit_cycle", LimitCycleStatus, on_status, queue_size=100)
    rospy.spin()
