/**
 * @file launch_end.h
 * @brief The end of a run with `stop_after` in a launch file: the node asks the roslaunch that started it to stop
 *        (SIGINT, as Ctrl-C would), so that every node of the launch ends and roslaunch exits without the red
 *        "REQUIRED process has died" banner a required node's own exit causes. Only a parent whose program is
 *        roslaunch is signalled (never rostest, a shell or a process manager).
 */
#pragma once

namespace backlash_servo
{
/// Sends SIGINT to the parent process if it is roslaunch; true when it did.
bool endParentLaunch();
/// endParentLaunch(), then waits (at most 20 s) for roslaunch's SIGINT to end this node.
void endParentLaunchAndWait();
}  // namespace backlash_servo
