// backlash_sim's robot mode: the arm's file and URDF read, the joints run together, one row (or JSON object) each.
#include "sim_robot.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>

#include "backlash_servo/config/robot_config.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/robot/robot_run.h"
#include "backlash_servo/studies/run_report.h"
#include "progress.h"

namespace backlash_servo
{
namespace
{
/// The joints' CSV: the time, then each joint's load and motor positions [rad], velocities [rad/s] and gap [rad].
class RobotCsv
{
 public:
  RobotCsv(std::ostream& out, const RobotSimulator& robot) : out_(out)
  {
    out_ << "time";
    for (std::size_t i = 0; i < robot.size(); ++i)
    {
      const std::string& n = robot.spec(i).name;
      out_ << "," << n << "_position," << n << "_velocity," << n << "_motor_position," << n << "_motor_velocity," << n
           << "_gap," << n << "_load_torque";
    }
    out_ << "\n";
  }
  void row(const RobotSimulator& robot)
  {
    char buf[256];
    std::snprintf(buf, sizeof buf, "%.15g", robot.time());
    out_ << buf;
    for (std::size_t i = 0; i < robot.size(); ++i)
    {
      const State s = robot.joint(i).state();
      std::snprintf(buf, sizeof buf, ",%.15g,%.15g,%.15g,%.15g,%.15g,%.15g", s.load_position, s.load_velocity,
                    s.motor_position, s.motor_velocity, robot.joint(i).gap(), robot.loadTorque(i));
      out_ << buf;
    }
    out_ << "\n";
  }

 private:
  std::ostream& out_;
};

std::string cycleText(const RobotJointResult& j)
{
  char buf[160];
  if (std::isnan(j.cycle.peak_to_peak))
  {
    return "-";
  }
  std::snprintf(buf, sizeof buf, "%.4g rad p-p, %.4g s", j.cycle.peak_to_peak, j.status.period);
  return buf;
}

void writeTable(std::ostream& out, const std::string& robot_name, const RobotRunResult& r, double wall)
{
  char buf[512];
  std::snprintf(buf, sizeof buf, "arm '%s': %zu joints, %.6g s simulated (%s) in %.3g s wall\n", robot_name.c_str(),
                r.joints.size(), r.simulated, r.stopped_by.c_str(), wall);
  out << buf;
  std::snprintf(buf, sizeof buf, "%-14s %-22s %-28s %8s %12s %14s %12s\n", "joint", "verdict", "cycle", "impacts",
                "position", "load torque", "inertia");
  out << buf;
  std::snprintf(buf, sizeof buf, "%-14s %-22s %-28s %8s %12s %14s %12s\n", "", "", "", "", "[rad]", "[N·m]", "[kg·m²]");
  out << buf;
  for (const RobotJointResult& j : r.joints)
  {
    std::snprintf(buf, sizeof buf, "%-14s %-22s %-28s %8llu %12.6g %14.6g %12.6g\n", j.name.c_str(),
                  toString(j.status.verdict), cycleText(j).c_str(), static_cast<unsigned long long>(j.impacts),
                  j.state.load_position, j.load_torque, j.load_inertia);
    out << buf;
  }
}

/// The flags a robot run takes: how long; every joint's keys are the file's.
void requireRunFlagsOnly(const FlagParser& options)
{
  for (const auto& [key, value] : options.flags().keys())
  {
    if (key != "duration" && key != "max_duration")
    {
      throw ConfigError(flagName(key) +
                        " with a robot file: the joints' keys are the file's (its top level for every "
                        "joint, joints/NAME/" +
                        key + " for one); only --duration and --max-duration apply");
    }
  }
}
}  // namespace

int simulateRobot(const FlagParser& options, double sample_rate)
{
  const std::string path = options.option("config");
  RobotModel model;
  std::unique_ptr<RobotSimulator> robot;
  double duration = 0.0, max_duration = 0.0, check_period = 0.0;
  try
  {
    requireRunFlagsOnly(options);
    model = loadRobot(path);
    KeyValues run = model.top;
    run.overrideWith(options.flags());
    duration = run.number("duration", 0.0);
    max_duration = run.number("max_duration", 0.0);
    param("duration").check(duration);  // a flag's text is a number only here: its range as the table has it
    param("max_duration").check(max_duration);
    // The judges check at the fastest controller's samples (1 kHz for continuous laws), as often as loads change.
    check_period = robotCheckPeriod(model.joints);
    if (options.given("csv") && sample_rate * check_period > 1.0)
    {
      throw ConfigError("--sample-rate " + formatNumber(sample_rate) +
                        " Hz: a robot file's rows come at most at its "
                        "fastest controller's rate, " +
                        formatNumber(1.0 / check_period) + " Hz");
    }
    robot = std::make_unique<RobotSimulator>(model.joints, model.arm.get(), check_period);
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_sim: error: " << e.what() << "\n";
    return 2;
  }
  const std::string name = model.arm ? model.arm->robotName() : path;
  std::unique_ptr<SafeOutput> csv_file;
  std::unique_ptr<RobotCsv> csv;
  if (options.given("csv"))
  {
    removeTemporariesOnSignals();
    csv_file = std::make_unique<SafeOutput>("--csv", options.option("csv"), std::vector<std::string>{path});
    csv = std::make_unique<RobotCsv>(csv_file->stream(), *robot);
    csv->row(*robot);
  }
  const double csv_period = 1.0 / sample_rate;
  double next_row = robot->time() + csv_period;
  Progress progress(isatty(2) != 0, 1.0);
  const auto start = std::chrono::steady_clock::now();
  RobotRunResult result;
  try
  {
    result = runRobot(
        robot.get(), duration, max_duration, check_period,
        [&](const RobotSimulator& r) {
          if (csv && r.time() >= next_row - 1e-12)
          {
            csv->row(r);
            next_row += csv_period;
          }
        },
        [&](double done) { progress.update(done); });
  }
  catch (const std::exception& e)
  {
    progress.finish();
    std::cerr << "backlash_sim: error at t = " << robot->time() << " s: " << e.what() << "\n";
    return 1;
  }
  progress.finish();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (csv_file)
  {
    csv_file->commit();
  }
  if (options.given("json"))
  {
    writeRobotRunJson(std::cout, name, result, wall);
  }
  else
  {
    writeTable(std::cout, name, result, wall);
  }
  return 0;
}

}  // namespace backlash_servo
