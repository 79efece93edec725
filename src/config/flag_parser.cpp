#include "backlash_servo/config/flag_parser.h"

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "backlash_servo/config/robot_config.h"
#include "backlash_servo/config/run_config_loader.h"

namespace backlash_servo
{
namespace
{
std::string keyOf(std::string flag)
{
  flag = flag.substr(2);
  std::replace(flag.begin(), flag.end(), '-', '_');
  return flag;
}

/// Width of UTF-8 text in columns (one per code point).
std::size_t columns(const std::string& s)
{
  return static_cast<std::size_t>(std::count_if(s.begin(), s.end(), [](char c) { return (c & 0xC0) != 0x80; }));
}

/// lhs padded to the help's second column.
std::string padded(const std::string& lhs)
{
  const std::size_t w = columns(lhs);
  return lhs + std::string(w < 34 ? 34 - w : 1, ' ');
}

/// "(default 0.1; > 0)" from the table entry (a derived default is explained by the doc line).
std::string defaultAndRange(const ParamSpec& p)
{
  std::string out;
  if (*p.fallback != '\0')
  {
    out += std::string("default ") + p.fallback;
  }
  if (p.type == ParamType::Real && p.range.describe() != "finite")
  {
    out += (out.empty() ? "" : "; ") + p.range.describe();
  }
  if (p.type == ParamType::Choice)
  {
    std::string list;
    for (const char* c : p.choices)
    {
      list += (list.empty() ? "" : "|") + std::string(c);
    }
    out += (out.empty() ? "" : "; ") + list;
  }
  return out.empty() ? "" : " (" + out + ")";
}
}  // namespace

std::vector<std::string> keysOfSections(const std::vector<ParamSection>& sections)
{
  std::vector<std::string> keys;
  for (const ParamSpec& p : parameterTable())
  {
    if (std::find(sections.begin(), sections.end(), p.section) != sections.end())
    {
      keys.push_back(p.key);
    }
  }
  return keys;
}

FlagParser::FlagParser(std::string tool, std::string header, std::vector<std::string> keys,
                       std::vector<ToolOption> options)
    : tool_(std::move(tool)), header_(std::move(header)), keys_accepted_(std::move(keys)), options_(std::move(options))
{
  for (const std::string& k : keys_accepted_)
  {
    param(k);  // a key not in the table is a programming error, found at once
  }
  for (const ToolOption& o : options_)
  {
    // So is a tool option named as an accepted key: one of the two would never be read.
    if (std::find(keys_accepted_.begin(), keys_accepted_.end(), o.name) != keys_accepted_.end())
    {
      throw std::logic_error(tool_ + ": the option --" + o.name + " is also a parameter key");
    }
  }
}

void FlagParser::parse(int argc, char** argv)
{
  KeyValues flags;
  for (int i = 1; i < argc; ++i)
  {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h")
    {
      std::cout << usage();
      std::exit(0);
    }
    if (arg.rfind("--", 0) != 0 || arg.size() == 2)
    {
      throw ConfigError("unexpected argument '" + arg + "' (options start with --; see --help)");
    }
    std::string value;
    bool has_value = false;
    const auto eq = arg.find('=');
    if (eq != std::string::npos)
    {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
      has_value = true;
    }
    const std::string key = keyOf(arg);
    const auto option =
        std::find_if(options_.begin(), options_.end(), [&](const ToolOption& o) { return o.name == key; });
    const bool is_key = std::find(keys_accepted_.begin(), keys_accepted_.end(), key) != keys_accepted_.end();
    if (option == options_.end() && !is_key)
    {
      std::vector<std::string> names = keys_accepted_;
      for (const ToolOption& o : options_)
      {
        names.push_back(o.name);
      }
      const std::string near = nearestName(key, names);
      throw ConfigError("unknown option " + arg + (near.empty() ? "" : " (did you mean " + flagName(near) + "?)") +
                        " (see --help)");
    }
    const bool is_switch = option != options_.end() && option->value_name.empty();
    if (is_switch)
    {
      if (has_value)
      {
        throw ConfigError(arg + " takes no value");
      }
      options_given_.set(key, "true");
      continue;
    }
    if (!has_value)
    {
      if (i + 1 >= argc)
      {
        throw ConfigError(arg + " needs a value");
      }
      value = argv[++i];
    }
    (is_key ? flags : options_given_).set(key, value);
  }
  if (options_given_.has("config"))
  {
    const std::string path = options_given_.text("config", "");
    robot_config_ = accept_robot_files_ && isRobotFile(path);
    if (!robot_config_)
    {
      keys_.loadYaml(path);
      requireKnownKeys(keys_, "config file '" + path + "'");
    }
  }
  keys_.overrideWith(flags);
  flags_ = flags;
}

std::string FlagParser::option(const std::string& name, const std::string& fallback) const
{
  return options_given_.text(name, fallback);
}

double FlagParser::optionNumber(const std::string& name, double fallback) const
{
  return options_given_.number(name, fallback);
}

std::string FlagParser::usage() const
{
  std::ostringstream out;
  out << header_;
  if (!keys_accepted_.empty())
  {
    out << "\nparameters (SI units; the same keys in snake_case in a YAML file):\n";
    ParamSection section = param(keys_accepted_.front()).section;
    bool first = true;
    for (const std::string& k : keys_accepted_)
    {
      const ParamSpec& p = param(k);
      if (first || p.section != section)
      {
        out << " " << toString(p.section) << (p.section == ParamSection::Chart ? " form (instead of J_m … K)" : "")
            << ":\n";
        section = p.section;
        first = false;
      }
      const std::string metavar = p.type == ParamType::Text ? "FILE" : (*p.symbol != '\0' ? p.symbol : "VALUE");
      out << padded("  " + p.flag() + " " + metavar) << "[" << p.unit << "] " << p.doc << defaultAndRange(p) << "\n";
    }
  }
  if (!options_.empty())
  {
    out << "\noptions:\n";
    for (const ToolOption& o : options_)
    {
      out << padded("  " + flagName(o.name) + (o.value_name.empty() ? "" : " " + o.value_name)) << o.help << "\n";
    }
  }
  out << padded("  --help") << "this text\n";
  return out.str();
}

}  // namespace backlash_servo
