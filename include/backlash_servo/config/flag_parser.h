/**
 * @file flag_parser.h
 * @brief The one command-line parser of every tool: parameter flags come from the parameter table
 *        (`--motor-inertia` ⇔ key `motor_inertia`), tool options are declared by the tool, `--help` is generated
 *        from both. No ROS dependency.
 */
#pragma once

#include <string>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
/// An option of one tool that is not a model parameter (output files, formats, worker counts).
struct ToolOption
{
  std::string name;        ///< snake_case; the flag is its kebab-case ("sample_rate" → --sample-rate)
  std::string value_name;  ///< shown in --help ("FILE"); empty = a switch without value
  std::string help;        ///< one line
};

class FlagParser
{
 public:
  /**
   * @param tool program name for messages
   * @param header usage text printed first by --help (synopsis and what the tool does)
   * @param keys parameter-table keys this tool takes as flags
   * @param options the tool's own options; one named "config" loads a YAML file under the flags
   */
  FlagParser(std::string tool, std::string header, std::vector<std::string> keys, std::vector<ToolOption> options);

  /**
   * Parses argv (`--flag value` or `--flag=value`). `--help`/`-h` prints usage() and exits 0. Throws ConfigError
   * for unknown flags, missing values, or (with --config) unknown YAML keys. Parameter values are kept as text in
   * keys() (YAML values under the flags); they are checked when read.
   */
  void parse(int argc, char** argv);

  const KeyValues& keys() const { return keys_; }
  /// The parameter flags given on the command line alone (without the config file's keys).
  const KeyValues& flags() const { return flags_; }
  /// A tool that runs arms calls this before parse(): a robot file (robot_config.h) given to --config is then left to
  /// the tool (robotConfig()); elsewhere it is refused as a config file, naming the tool that runs it.
  void acceptRobotFiles() { accept_robot_files_ = true; }
  /// Whether --config names a robot file the tool accepts: its keys are then not in keys(), the tool reads the file.
  bool robotConfig() const { return robot_config_; }
  bool given(const std::string& option) const { return options_given_.has(option); }
  /// The text of a tool option, or fallback.
  std::string option(const std::string& name, const std::string& fallback = "") const;
  /// A tool option as a finite number (error names the flag), or fallback.
  double optionNumber(const std::string& name, double fallback) const;
  /// The generated --help text.
  std::string usage() const;

 private:
  std::string tool_;
  std::string header_;
  std::vector<std::string> keys_accepted_;
  std::vector<ToolOption> options_;
  KeyValues keys_;
  KeyValues flags_;
  KeyValues options_given_;
  bool accept_robot_files_ = false;
  bool robot_config_ = false;
};

/// Every table key of the given sections (param_table.h), in table order.
std::vector<std::string> keysOfSections(const std::vector<ParamSection>& sections);

}  // namespace backlash_servo
