// backlash_params: prints the parameter table (param_table.h) in the forms that derive from it — the
// dynamic_reconfigure .cfg, the Markdown tables of docs/parameters.md, JSON. scripts/generate_params.sh writes the
// files; a test fails when a committed file differs from what this prints.
#include <algorithm>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/model/param_table.h"

using namespace backlash_servo;

namespace
{
const char* HEADER = R"(usage: backlash_params --format cfg|markdown|json [--sections servo,chart,initial,run,node]
Prints the parameter table of backlash_servo: every key with its unit, range, default and doc.
)";

std::string pyString(const std::string& s)
{
  std::string out = "\"";
  for (char c : s)
  {
    out += c == '"' ? std::string("\\\"") : std::string(1, c);
  }
  return out + "\"";
}

std::string jsonString(const std::string& s)
{
  return pyString(s);
}

std::string range(const ParamSpec& p)
{
  if (p.type == ParamType::Choice)
  {
    std::string list;
    for (const char* c : p.choices)
    {
      list += (list.empty() ? "" : " \\| ") + std::string("`") + c + "`";
    }
    return list;
  }
  if (p.type == ParamType::Boolean)
  {
    return "true \\| false";
  }
  if (p.type == ParamType::Text)
  {
    return "name";
  }
  return p.range.describe();
}

bool wanted(const ParamSpec& p, const std::string& sections)
{
  std::stringstream ss(sections);
  std::string s;
  while (std::getline(ss, s, ','))
  {
    if (s == toString(p.section))
    {
      return true;
    }
  }
  return false;
}

void printCfg(std::ostream& out)
{
  out << "#!/usr/bin/env python3\n"
         "# GENERATED from the parameter table (src/core/model/param_table.cpp) by scripts/generate_params.sh: do not "
         "edit.\n"
         "# Live-tunable parameters of backlash_servo_node (dynamic_reconfigure). SI units. No min/max: the node\n"
         "# validates every value against the table and refuses a bad one with a message naming it, instead of the\n"
         "# silent clamping dynamic_reconfigure applies to slider bounds.\n"
         "from dynamic_reconfigure.parameter_generator_catkin import ParameterGenerator, double_t, int_t\n\n"
         "PACKAGE = \"backlash_servo\"\n"
         "gen = ParameterGenerator()\n";
  for (ParamSection section : {ParamSection::Servo, ParamSection::Drive, ParamSection::Node})
  {
    const std::string group = toString(section);
    bool opened = false;
    for (const ParamSpec* p : paramsIn(section))
    {
      if (!p->live)
      {
        continue;
      }
      if (!opened)
      {
        out << group << " = gen.add_group(\"" << group << "\")\n";
        opened = true;
      }
      const std::string doc =
          std::string(*p->symbol != '\0' ? std::string(p->symbol) + ", " : "") + p->doc + " [" + p->unit + "]";
      if (p->type == ParamType::Real)
      {
        out << group << ".add(\"" << p->key << "\", double_t, 0, " << pyString(doc) << ", "
            << (*p->fallback != '\0' ? std::string(p->fallback) : formatNumber(p->fallbackNumber())) << ")\n";
      }
      else if (p->type == ParamType::Choice)
      {
        std::string consts;
        int index = 0;
        int fallback = 0;
        for (const char* c : p->choices)
        {
          consts += std::string(index ? ", " : "") + "gen.const(\"" + c + "\", int_t, " + std::to_string(index) +
                    ", \"" + c + "\")";
          fallback = std::string(c) == p->fallback ? index : fallback;
          ++index;
        }
        out << group << ".add(\"" << p->key << "\", int_t, 0, " << pyString(doc) << ", " << fallback
            << ", edit_method=gen.enum([" << consts << "], \"" << p->key << "\"))\n";
      }
    }
  }
  out << "exit(gen.generate(PACKAGE, \"backlash_servo_node\", \"BacklashServo\"))\n";
}

void printMarkdown(std::ostream& out, const std::string& sections)
{
  out << "| key (YAML, ROS param; flag `--kebab-case`) | symbol | unit | allowed | default | live | meaning |\n"
         "|---|---|---|---|---|---|---|\n";
  for (const ParamSpec& p : parameterTable())
  {
    if (!wanted(p, sections))
    {
      continue;
    }
    out << "| `" << p.key << "` | " << p.symbol << " | " << p.unit << " | " << range(p) << " | "
        << (*p.fallback != '\0'    ? std::string("`") + p.fallback + "`"
            : p.same_as != nullptr ? std::string("= `") + p.same_as + "`"
                                   : std::string("–"))
        << " | " << (p.live ? "yes" : "") << " | " << p.doc << " |\n";
  }
}

void printJson(std::ostream& out)
{
  out << "[";
  bool first = true;
  for (const ParamSpec& p : parameterTable())
  {
    out << (first ? "\n" : ",\n") << "  {\"key\": " << jsonString(p.key) << ", \"symbol\": " << jsonString(p.symbol)
        << ", \"unit\": " << jsonString(p.unit) << ", \"type\": \"" << toString(p.type) << "\", \"section\": \""
        << toString(p.section) << "\", \"range\": " << jsonString(range(p))
        << ", \"default\": " << jsonString(p.fallback) << ", \"live\": " << (p.live ? "true" : "false")
        << ", \"doc\": " << jsonString(p.doc) << "}";
    first = false;
  }
  out << "\n]\n";
}
}  // namespace

int main(int argc, char** argv)
{
  FlagParser parser("backlash_params", HEADER, {},
                    {{"format", "cfg|markdown|json", "what to print"},
                     {"sections", "LIST", "markdown: comma-separated sections (default all)"}});
  try
  {
    parser.parse(argc, argv);
    const std::string format = parser.option("format");
    if (parser.given("sections"))
    {
      if (format != "markdown")
      {
        throw ConfigError("--sections applies to --format markdown only");
      }
      // Every name must be a section of the table: a typo must not print an empty table with exit status 0.
      std::vector<std::string> known;  // the table's sections, in table order
      for (const ParamSpec& p : parameterTable())
      {
        if (std::find(known.begin(), known.end(), toString(p.section)) == known.end())
        {
          known.push_back(toString(p.section));
        }
      }
      std::stringstream ss(parser.option("sections"));
      for (std::string name; std::getline(ss, name, ',');)
      {
        if (std::find(known.begin(), known.end(), name) == known.end())
        {
          std::string list;
          for (const std::string& k : known)
          {
            list += (list.empty() ? "" : ", ") + k;
          }
          throw ConfigError("--sections: unknown section '" + name + "' (" + list + ")");
        }
      }
    }
    if (format == "cfg")
    {
      printCfg(std::cout);
    }
    else if (format == "markdown")
    {
      printMarkdown(std::cout, parser.option("sections", "servo,chart,drive,initial,run,node"));
    }
    else if (format == "json")
    {
      printJson(std::cout);
    }
    else
    {
      throw ConfigError("--format must be cfg, markdown or json (got '" + format + "')");
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_params: error: " << e.what() << "\n";
    return 2;
  }
  std::cout.flush();
  return std::cout ? 0 : 1;
}
