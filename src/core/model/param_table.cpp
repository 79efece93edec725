#include "backlash_servo/model/param_table.h"

#include <cmath>
#include <cstdlib>
#include <map>
#include <stdexcept>
#include <string_view>
#include <unordered_map>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/run_config.h"

namespace backlash_servo
{
namespace
{
const ParamRange NON_NEGATIVE{0.0, INF, false, false};
const ParamRange UNIT{0.0, 1.0, false, false};
const ParamRange FINITE{};
// The validated envelope (docs/validation.md, "Validated envelope"): measured with backlash_fuzz, refused beyond.
const ParamRange INERTIA{1e-9, 1e9, false, false};
const ParamRange FRICTION{0.0, 1e9, false, false};
const ParamRange GAIN{0.0, 1e12, true, false};
const ParamRange RATIO{1e-3, 1e3, false, false};
const ParamRange BACKLASH{0.0, 1e3, false, false};
const ParamRange POSITION{-1e6, 1e6, false, false};
const ParamRange VELOCITY{-1e9, 1e9, false, false};

using S = ParamSection;
using T = ParamType;

/// The servo, physical form (defaults: the thesis' limit-cycle case, App. D1).
std::vector<ParamSpec> servoKeys()
{
  // clang-format off
  return {
    {"motor_inertia", "J_m", "kg·m²", T::Real, S::Servo, INERTIA, "0.1", "motor inertia on the motor shaft", true, {},
     &ServoParams::motor_inertia},
    {"load_inertia", "J_L", "kg·m²", T::Real, S::Servo, INERTIA, "0.9", "load inertia on the load shaft", true, {},
     &ServoParams::load_inertia},
    {"motor_friction", "f_m", "N·m·s/rad", T::Real, S::Servo, FRICTION, "0.48", "viscous friction of the motor",
     true, {}, &ServoParams::motor_friction},
    {"load_friction", "f_L", "N·m·s/rad", T::Real, S::Servo, FRICTION, "0.32", "viscous friction of the load",
     true, {}, &ServoParams::load_friction},
    {"gain", "K", "N·m/rad", T::Real, S::Servo, GAIN, "1", "servo gain: motor torque = K (command − load position)",
     true, {}, &ServoParams::gain},
    {"gear_ratio", "ρ", "-", T::Real, S::Servo, RATIO, "1",
     "teeth(gear 1)/teeth(gear 2); rigid mesh θ_c = ρ θ_m (both forms)", true, {}, &ServoParams::gear_ratio},
    {"backlash", "Δ", "rad", T::Real, S::Servo, BACKLASH, "0.3",
     "free play at the load shaft, 0 = rigid mesh (both forms)", true, {}, &ServoParams::backlash},
    {"restitution", "e", "-", T::Real, S::Servo, UNIT, "1",
     "coefficient of restitution of tooth impacts, 0 plastic … 1 elastic (both forms)", true, {},
     &ServoParams::restitution},
    {"load_torque", "T_ext", "N·m", T::Real, S::Servo, ParamRange{-1e9, 1e9, false, false}, "0",
     "external torque on the load: gravity preload, process load, disturbance (both forms)", true, {},
     &ServoParams::load_torque},
    {"motor_coulomb_friction", "T_cm", "N·m", T::Real, S::Servo, FRICTION, "0",
     "dry (Coulomb) friction of the sliding motor (both forms)", true, {}, &ServoParams::motor_coulomb_friction},
    {"motor_static_friction", "T_sm", "N·m", T::Real, S::Servo, FRICTION, "",
     "breakaway torque of the motor at rest, >= motor_coulomb_friction (default: that value; both forms)", true, {},
     &ServoParams::motor_static_friction, "motor_coulomb_friction"},
    {"load_coulomb_friction", "T_cL", "N·m", T::Real, S::Servo, FRICTION, "0",
     "dry (Coulomb) friction of the sliding load (both forms)", true, {}, &ServoParams::load_coulomb_friction},
    {"load_static_friction", "T_sL", "N·m", T::Real, S::Servo, FRICTION, "",
     "breakaway torque of the load at rest, >= load_coulomb_friction (default: that value; both forms)", true, {},
     &ServoParams::load_static_friction, "load_coulomb_friction"},
    {"mesh_law", "", "-", T::Choice, S::Servo, FINITE, "spring_damper",
     "compliant mesh torque: spring_damper (never pulls) or msl_elastobacklash (Modelica's ElastoBacklash; both forms)",
     true, {"spring_damper", "msl_elastobacklash"}, &ServoParams::mesh_law},
    {"mesh_stiffness", "c", "N·m/rad", T::Real, S::Servo, ParamRange{0.0, 1e12, false, false}, "0",
     "tooth stiffness at the load shaft; 0 = rigid teeth with impacts (both forms)", true, {},
     &ServoParams::mesh_stiffness},
    {"mesh_damping", "d", "N·m·s/rad", T::Real, S::Servo, FRICTION, "0",
     "tooth damping at the load shaft, compliant mesh only (both forms)", true, {}, &ServoParams::mesh_damping},
    {"gear_inertia", "J_g", "kg·m²", T::Real, S::Servo, ParamRange{0.0, 1e9, false, false}, "0",
     "output gear inertia on the load shaft, compliant mesh only (both forms)", true, {}, &ServoParams::gear_inertia},
    {"shaft_stiffness", "k_s", "N·m/rad", T::Real, S::Servo, ParamRange{0.0, 1e12, false, false}, "0",
     "torsional stiffness of the shaft from the output gear to the load; 0 = rigid shaft (both forms)", true, {},
     &ServoParams::shaft_stiffness},
    {"shaft_damping", "d_s", "N·m·s/rad", T::Real, S::Servo, FRICTION, "0",
     "torsional damping of the shaft, with shaft_stiffness only (both forms)", true, {}, &ServoParams::shaft_damping}
  };
  // clang-format on
}

/// The servo, chart form (instead of J_m … K).
std::vector<ParamSpec> chartKeys()
{
  // clang-format off
  return {
    {"zeta", "ζ", "-", T::Real, S::Chart, ParamRange{0.0, 100.0, false, false}, "", "damping ratio (required in the chart form)", false, {},
     &ChartParams::zeta},
    {"natural_frequency", "ω_n", "rad/s", T::Real, S::Chart, ParamRange{1e-3, 1e4, false, false}, "1", "natural frequency √(ρK/J)", false, {},
     &ChartParams::natural_frequency},
    {"total_inertia", "J", "kg·m²", T::Real, S::Chart, INERTIA, "1", "J = J_m + ρ²J_L", false, {},
     &ChartParams::total_inertia},
    {"inertia_ratio", "ρ²J_L/J_m", "-", T::Real, S::Chart, RATIO, "", "inertia split (required in the chart form)",
     false, {}, &ChartParams::inertia_ratio},
    {"friction_ratio", "ρ²f_L/F_T", "-", T::Real, S::Chart, UNIT, "",
     "friction split, F_T = f_m + ρ²f_L (required in the chart form)", false, {}, &ChartParams::friction_ratio}
  };
  // clang-format on
}

/// Command and initial state.
std::vector<ParamSpec> initialKeys()
{
  // clang-format off
  return {
    {"command", "θ_R", "rad", T::Real, S::Initial, POSITION, "1", "load set-point, applied at t = 0", false, {},
     &RunConfig::command},
    {"profile", "θ_R(t)", "file", T::Text, S::Initial, FINITE, "",
     "command profile instead of `command`: a YAML file of segments (step, ramp, sine, move, points) or a CSV of "
     "time [s], value [rad] rows; in a YAML config also inline as a `profile:` list (see docs/cli.md, Command profiles)",
     false, {}, {}},
    {"load_position", "θ_c", "rad", T::Real, S::Initial, POSITION, "0", "initial load position", false, {},
     &State::load_position},
    {"load_velocity", "ω_c", "rad/s", T::Real, S::Initial, VELOCITY, "0", "initial load velocity", false, {},
     &State::load_velocity},
    {"motor_position", "θ_m", "rad", T::Real, S::Initial, ParamRange{-1e9, 1e9, false, false}, "", "initial motor position (default: on the wall of `contact`)",
     false, {}, &State::motor_position},
    {"motor_velocity", "ω_m", "rad/s", T::Real, S::Initial, ParamRange{-1e12, 1e12, false, false}, "", "initial motor velocity (default: ω_c/ρ)", false,
     {}, &State::motor_velocity},
    {"contact", "", "-", T::Choice, S::Initial, FINITE, "forward", "teeth at the start: gap 0, gap Δ, or floating",
     false, {"forward", "backward", "none"}, {}}
  };
  // clang-format on
}

/// The drive (docs/model.md Part 2, "Digital drive"); the P gain is `gain`.
std::vector<ParamSpec> driveKeys()
{
  // clang-format off
  return {
    {"control_law", "", "-", T::Choice, S::Drive, FINITE, "proportional",
     "proportional (continuous or sampled), pid or cascade (sampled laws)", true, {"proportional", "pid", "cascade"},
     {}},
    {"controller_rate", "f_s", "Hz", T::Real, S::Drive, ParamRange{0.0, 1e6, false, false}, "0",
     "sample rate of the digital drive (zero-order hold), at least 0.001 Hz; 0 = continuous, the thesis' servo", true,
     {},
     &DriveParams::controller_rate},
    {"controller_delay", "", "samples", T::Real, S::Drive, UNIT, "0", "computation delay: 0 or 1 sample", true, {},
     &DriveParams::controller_delay},
    {"motor_encoder_resolution", "N_m", "counts/rev", T::Real, S::Drive, ParamRange{0.0, 1e9, false, false}, "0",
     "motor encoder resolution, 0 = ideal", true, {}, &DriveParams::motor_encoder_resolution},
    {"load_encoder_resolution", "N_L", "counts/rev", T::Real, S::Drive, ParamRange{0.0, 1e9, false, false}, "0",
     "load encoder resolution, 0 = ideal", true, {}, &DriveParams::load_encoder_resolution},
    {"feedback", "", "-", T::Choice, S::Drive, FINITE, "load",
     "position the controller reads: load encoder, or motor encoder referred through ρ (semi-closed loop)", true,
     {"load", "motor"}, {}},
    {"integral_gain", "K_i", "N·m/(rad·s)", T::Real, S::Drive, ParamRange{0.0, 1e12, false, false}, "0",
     "pid: integral gain", true, {}, &DriveParams::integral_gain},
    {"derivative_gain", "K_d", "N·m·s/rad", T::Real, S::Drive, ParamRange{0.0, 1e12, false, false}, "0",
     "pid: derivative gain, on the measurement", true, {}, &DriveParams::derivative_gain},
    {"position_loop_gain", "K_p", "1/s", T::Real, S::Drive, ParamRange{0.0, 1e9, false, false}, "0",
     "cascade: outer position loop gain", true, {}, &DriveParams::position_loop_gain},
    {"velocity_loop_gain", "K_v", "N·m·s/rad", T::Real, S::Drive, ParamRange{0.0, 1e12, false, false}, "0",
     "cascade: inner velocity loop gain", true, {}, &DriveParams::velocity_loop_gain},
    {"velocity_loop_integral_gain", "K_vi", "N·m/rad", T::Real, S::Drive, ParamRange{0.0, 1e12, false, false}, "0",
     "cascade: inner velocity loop integral gain", true, {}, &DriveParams::velocity_loop_integral_gain},
    {"torque_limit", "T_max", "N·m", T::Real, S::Drive, ParamRange{0.0, 1e12, false, false}, "0",
     "saturation of the motor torque, 0 = none (every law)", true, {}, &DriveParams::torque_limit}
  };
  // clang-format on
}

/// Backlash compensation (compensator.h for digital drives; drive.h ProportionalDrive for the continuous law).
std::vector<ParamSpec> compensationKeys()
{
  // clang-format off
  return {
    {"compensation", "", "-", T::Choice, S::Drive, FINITE, "none",
     "backlash compensator (docs/workbench.md; the continuous law takes friction_feedforward with "
     "compensation_width > 0 and a square dither)",
     true,
     {"none", "inverse", "dual_loop", "friction_feedforward", "dither"}, {}},
    {"compensation_backlash", "Δ̂", "rad", T::Real, S::Drive, BACKLASH, "0",
     "inverse: the compensator's estimate of the backlash (at the load shaft)", true, {},
     &DriveParams::compensation_backlash},
    {"compensation_width", "w", "rad", T::Real, S::Drive, ParamRange{0.0, 1e3, false, false}, "0",
     "inverse: command travel the jump is spread over; friction_feedforward: error deadband", true, {},
     &DriveParams::compensation_width},
    {"outer_loop_gain", "K_o", "1/s", T::Real, S::Drive, ParamRange{0.0, 1e9, false, false}, "0",
     "dual_loop: gain of the outer load loop trimming the motor loop's reference", true, {},
     &DriveParams::outer_loop_gain},
    {"compensation_friction", "F", "N·m", T::Real, S::Drive, FRICTION, "0",
     "friction_feedforward: torque added in the direction of the wanted motion", true, {},
     &DriveParams::compensation_friction},
    {"dither_amplitude", "A", "N·m", T::Real, S::Drive, ParamRange{0.0, 1e12, false, false}, "0",
     "dither: torque amplitude", true, {}, &DriveParams::dither_amplitude},
    {"dither_frequency", "f_d", "Hz", T::Real, S::Drive, ParamRange{0.0, 1e6, false, false}, "0",
     "dither: frequency (at most controller_rate / 2 on a digital drive)", true, {}, &DriveParams::dither_frequency},
    {"dither_shape", "", "-", T::Choice, S::Drive, FINITE, "square", "dither: square or sine wave", true,
     {"square", "sine"}, {}}
  };
  // clang-format on
}

/// Length of a command-line run.
std::vector<ParamSpec> runKeys()
{
  // clang-format off
  return {
    {"duration", "", "s", T::Real, S::Run, NON_NEGATIVE, "0",
     "simulate exactly this long (0 = until the verdict is settled)", false, {}, &RunConfig::duration},
    {"max_duration", "", "s", T::Real, S::Run, NON_NEGATIVE, "0", "cap when running until settled (0 = max(2000/ω_n, 100 × the drive's or the plant's slowest time constant, "
     "100 × the longest interval between maxima))",
     false, {}, &RunConfig::max_duration},
    {"settling_band", "", "rad", T::Real, S::Run, ParamRange{0.0, 1e3, false, false}, "0",
     "settling time and steady-state figures: the load error band |θ_R − θ_c| ≤ band (0 = the joint's own: the "
     "larger of Δ and one count of the encoder the loop reads; 2 % of the command's excursion without either)",
     false, {}, &RunConfig::settling_band},
    {"max_events", "", "-", T::Real, S::Run, ParamRange{1.0, 1e12, false, false}, "1e7",
     "event budget of a run: impacts, and apart rests and law switches; beyond it the run stops, unsettled (an "
     "impact storm or a sliding mode is not a hang)",
     false, {}, &RunConfig::max_events}
  };
  // clang-format on
}

/// ROS node.
std::vector<ParamSpec> nodeKeys()
{
  // clang-format off
  return {
    {"control_mode", "", "-", T::Choice, S::Node, FINITE, "position",
     "position: internal P law on `command`; effort: torque from `motor_effort`", true, {"position", "effort"}, {}},
    {"motor_effort", "", "N·m", T::Real, S::Node, ParamRange{-1e12, 1e12, false, false}, "0", "initial motor torque in effort mode", false, {}, {}},
    {"publish_rate", "", "Hz", T::Real, S::Node, ParamRange{0.01, 1e4, false, false}, "100",
     "joint_states and backlash_state rate (sim time); from 0.01 Hz (a state every 100 s) to 10 kHz, what the node "
     "can publish",
     true, {}, {}},
    {"real_time_factor", "", "-", T::Real, S::Node, NON_NEGATIVE, "1",
     "sim seconds per wall second; 0 = as fast as possible (publish_clock only)", true, {}, {}},
    {"publish_clock", "", "-", T::Boolean, S::Node, FINITE, "false", "the node publishes /clock (with use_sim_time)",
     false, {}, {}},
    {"clock_publish_rate", "", "Hz", T::Real, S::Node, ParamRange{0.0, 1e6, false, false}, "1000",
     "most /clock messages per second of wall time when the node is the clock and its samples come faster (as fast "
     "as possible): every node on sim time reads each one; every sample still gets one in lockstep (0 = every sample)",
     false, {}, {}},
    {"motor_joint_name", "", "-", T::Text, S::Node, FINITE, "motor_joint", "JointState name of the motor shaft", false,
     {}, {}},
    {"load_joint_name", "", "-", T::Text, S::Node, FINITE, "load_joint", "JointState name of the load shaft", false, {},
     {}},
    {"gear_joint_name", "", "-", T::Text, S::Node, FINITE, "gear_joint",
     "JointState name of the output gear θ_o (published with a compliant mesh)", false, {}, {}},
    {"shaft_twist_joint_name", "", "-", T::Text, S::Node, FINITE, "shaft_twist_joint",
     "JointState name of the shaft twist θ_o − θ_c (published with a compliant mesh)", false, {}, {}},
    {"min_impact_speed", "", "rad/s", T::Real, S::Node, NON_NEGATIVE, "0",
     "publish only impacts at least this fast (0 = all)", true, {}, {}},
    {"paused", "", "-", T::Boolean, S::Node, FINITE, "false", "start paused (call ~resume)", false, {}, {}},
    {"stop_after", "", "s", T::Real, S::Node, NON_NEGATIVE, "0", "shut down after this much sim time (0 = never)",
     false, {}, {}},
    {"stop_launch", "", "-", T::Boolean, S::Node, FINITE, "false",
     "at stop_after, end the roslaunch that started the node as Ctrl-C would (every node stops, no REQUIRED banner); "
     "set by the package's launch files", false, {}, {}},
    {"start_time", "", "s", T::Real, S::Node, ParamRange{0.0, 4e9, false, false}, "0",
     "ROS time of sim time 0 when the node publishes /clock: sim time starts at 0, as in Gazebo, so that a "
     "controller's float time arithmetic is exact and reproducible (another epoch if a stack needs one)",
     false, {}, {}},
    {"start_delay", "", "s", T::Real, S::Node, NON_NEGATIVE, "0",
     "wall time to wait before sim time starts (e.g. for rosbag)", false, {}, {}},
    {"record_bag", "", "file", T::Text, S::Node, FINITE, "",
     "bag the node writes itself: every topic it publishes and every input it receives, absolute names (written as "
     "FILE.active, renamed at exit; '' = off). Cheaper than a recorder process: no socket write per message",
     false, {}, {}},
    {"sync", "", "-", T::Boolean, S::Node, FINITE, "false",
     "lockstep with an external controller: after publishing the state at t_k the node waits for one motor_effort "
     "(effort mode) or command (position mode) before advancing to t_k+1 (needs publish_clock)", false, {}, {}},
    {"sync_timeout", "", "s", T::Real, S::Node, NON_NEGATIVE, "5",
     "lockstep: wall time to wait for an answer before advancing on the last input with a warning (0 = for ever)",
     true, {}, {}},
    {"effort_timeout", "", "s", T::Real, S::Node, NON_NEGATIVE, "0",
     "effort mode: sim time without a motor_effort message after which the torque drops to 0 with a warning "
     "(0 = never)", true, {}, {}}
  };
  // clang-format on
}

/// Every parameter, in the order of --help, the .cfg and the docs.
std::vector<ParamSpec> makeTable()
{
  std::vector<ParamSpec> table;
  for (auto section : {servoKeys, chartKeys, initialKeys, driveKeys, compensationKeys, runKeys, nodeKeys})
  {
    std::vector<ParamSpec> keys = section();
    table.insert(table.end(), std::make_move_iterator(keys.begin()), std::make_move_iterator(keys.end()));
  }
  return table;
}
}  // namespace

bool ParamRange::contains(double v) const
{
  if (!std::isfinite(v))
  {
    return false;
  }
  const bool above = lower_open ? v > lower : v >= lower;
  const bool below = upper_open ? v < upper : v <= upper;
  return above && below;
}

std::string ParamRange::describe() const
{
  const bool has_lower = std::isfinite(lower);
  const bool has_upper = std::isfinite(upper);
  if (has_lower && has_upper)
  {
    return std::string("in ") + (lower_open ? "(" : "[") + formatNumber(lower) + ", " + formatNumber(upper) +
           (upper_open ? ")" : "]");
  }
  if (has_lower)
  {
    return std::string(lower_open ? "> " : ">= ") + formatNumber(lower);
  }
  if (has_upper)
  {
    return std::string(upper_open ? "< " : "<= ") + formatNumber(upper);
  }
  return "finite";
}

std::string ParamSpec::flag() const
{
  std::string f = std::string("--") + key;
  for (char& c : f)
  {
    c = c == '_' ? '-' : c;
  }
  return f;
}

void ParamSpec::check(double v) const
{
  if (!std::isfinite(v))
  {
    throw InvalidParameterError(key, "must be a finite number (got " + formatNumber(v) + ")");
  }
  if (!range.contains(v))
  {
    throw InvalidParameterError(key, "must be " + range.describe() + " (got " + formatNumber(v) + ")");
  }
}

double ParamSpec::fallbackNumber() const
{
  return std::strtod(fallback, nullptr);
}

bool ParamSpec::isChoice(const std::string& value) const
{
  for (const char* c : choices)
  {
    if (value == c)
    {
      return true;
    }
  }
  return false;
}

bool inChartForm(const ParamSpec& spec)
{
  const std::string_view key = spec.key;  // no copy: asked for every key of every run's configuration
  return spec.section == ParamSection::Chart || key == "gear_ratio" || key == "backlash" || key == "restitution" ||
         key == "load_torque" || key == "motor_coulomb_friction" || key == "motor_static_friction" ||
         key == "load_coulomb_friction" || key == "load_static_friction" || key == "mesh_law" ||
         key == "mesh_stiffness" || key == "mesh_damping" || key == "gear_inertia" || key == "shaft_stiffness" ||
         key == "shaft_damping";
}

const std::vector<ParamSpec>& parameterTable()
{
  static const std::vector<ParamSpec> table = makeTable();
  return table;
}

const ParamSpec* findParam(const std::string& key)
{
  // An index over the table, built once: every run's configuration looks its keys up (a sweep, for each point).
  static const std::unordered_map<std::string_view, const ParamSpec*> index = [] {
    std::unordered_map<std::string_view, const ParamSpec*> out;
    for (const ParamSpec& p : parameterTable())
    {
      out.emplace(p.key, &p);
    }
    return out;
  }();
  const auto it = index.find(key);
  return it == index.end() ? nullptr : it->second;
}

const ParamSpec& param(const std::string& key)
{
  const ParamSpec* p = findParam(key);
  if (p == nullptr)
  {
    throw std::logic_error("backlash_servo: '" + key + "' is not in the parameter table");
  }
  return *p;
}

const std::vector<const ParamSpec*>& paramsIn(ParamSection section)
{
  // Built once: every parameter change validates through it (an arm sets its joints' loads thousands of times a
  // simulated second).
  static const std::map<ParamSection, std::vector<const ParamSpec*>> by_section = [] {
    std::map<ParamSection, std::vector<const ParamSpec*>> m;
    for (const ParamSpec& p : parameterTable())
    {
      m[p.section].push_back(&p);
    }
    return m;
  }();
  static const std::vector<const ParamSpec*> none;
  const auto it = by_section.find(section);
  return it == by_section.end() ? none : it->second;
}

const char* toString(ParamSection s)
{
  switch (s)
  {
    case ParamSection::Servo:
      return "servo";
    case ParamSection::Chart:
      return "chart";
    case ParamSection::Initial:
      return "initial";
    case ParamSection::Drive:
      return "drive";
    case ParamSection::Run:
      return "run";
    default:
      return "node";
  }
}

const char* toString(ParamType t)
{
  switch (t)
  {
    case ParamType::Real:
      return "real";
    case ParamType::Boolean:
      return "bool";
    case ParamType::Choice:
      return "choice";
    default:
      return "text";
  }
}

}  // namespace backlash_servo
