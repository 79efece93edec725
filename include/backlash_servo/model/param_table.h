/**
 * @file param_table.h
 * @brief The one parameter table: every parameter of the servo, its run and the node is declared here once (key,
 *        symbol, unit, allowed range, default, one-line doc, live-tunable or not). Validation, CLI flags and
 *        `--help`, YAML keys, ROS params, the dynamic_reconfigure .cfg, the JSON echo and docs/parameters.md all
 *        derive from it (see `backlash_params`). No ROS dependency.
 *
 * Adding a parameter: one entry in param_table.cpp (with the struct field it binds to, if any) + the physics that
 * uses it; then `bash scripts/generate_params.sh` rewrites the .cfg and docs/parameters.md (a test fails until then).
 */
#pragma once

#include <limits>
#include <string>
#include <variant>
#include <vector>

#include "backlash_servo/model/drive_params.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"

namespace backlash_servo
{
struct RunConfig;

enum class ParamType
{
  Real,     ///< a finite double in the range
  Boolean,  ///< true | false
  Choice,   ///< one of `choices`
  Text      ///< a non-empty string
};

/// Which block a parameter belongs to; tools accept the blocks they use.
enum class ParamSection
{
  Servo,    ///< physical form of the servo (ServoParams)
  Chart,    ///< the thesis' chart form (ChartParams), instead of the physical form
  Initial,  ///< command and initial state
  Drive,    ///< the control law and the digital drive (DriveParams)
  Run,      ///< length of a command-line run
  Node      ///< ROS node only
};

/// Allowed interval of a Real parameter.
struct ParamRange
{
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  bool lower_open = false;  ///< lower bound excluded
  bool upper_open = false;  ///< upper bound excluded

  bool contains(double v) const;
  /// "> 0", ">= 0", "in [0, 1]", "finite".
  std::string describe() const;
};

/// Struct field a parameter is stored in (the node's own settings are bound in the node's adapter).
using ParamField = std::variant<std::monostate, double ServoParams::*, double ChartParams::*, double State::*,
                                double RunConfig::*, double DriveParams::*, std::string ServoParams::*>;

struct ParamSpec
{
  const char* key;     ///< snake_case: YAML key, ROS param, dynamic_reconfigure name; flag = --kebab-case
  const char* symbol;  ///< maths symbol ("J_m"), "" if none
  const char* unit;    ///< SI unit ("kg·m²"), "-" for pure numbers
  ParamType type;
  ParamSection section;
  ParamRange range;                  ///< Real only
  const char* fallback;              ///< default as text; "" = derived from other values (see doc)
  const char* doc;                   ///< one line
  bool live;                         ///< tunable while the node runs (dynamic_reconfigure)
  std::vector<const char*> choices;  ///< Choice only
  ParamField field;                  ///< where the value goes
  const char* same_as = nullptr;     ///< fallback "": the default is the value of this (earlier) key

  /// "--motor-inertia".
  std::string flag() const;
  /// Throws InvalidParameterError(key, "must be > 0 (got -1)") when v is not finite or out of range.
  void check(double v) const;
  double fallbackNumber() const;
  /// The default of a Real key given the values read so far (value_of(key) for same_as).
  template <class ValueOf>
  double defaultValue(const ValueOf& value_of) const
  {
    return same_as != nullptr ? value_of(same_as) : fallbackNumber();
  }
  bool isChoice(const std::string& value) const;
};

/// Part of the chart form: the Chart section and the keys both forms share (gear_ratio, backlash, restitution, load
/// torque, dry friction).
bool inChartForm(const ParamSpec& spec);

/// Every parameter, in the order of the docs (Servo, Chart, Initial, Run, Node).
const std::vector<ParamSpec>& parameterTable();
/// The entry for key, or nullptr.
const ParamSpec* findParam(const std::string& key);
/// The entry for key; throws std::logic_error for a key not in the table (a programming error).
const ParamSpec& param(const std::string& key);
/// Entries of one section, in table order (built once).
const std::vector<const ParamSpec*>& paramsIn(ParamSection section);
const char* toString(ParamSection s);
const char* toString(ParamType t);

}  // namespace backlash_servo
