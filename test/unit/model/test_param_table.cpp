// The one parameter table (param_table.h) and what derives from it: validation, the flag parser and --help, the
// YAML loader, the generated .cfg and the tables of docs/parameters.md (a committed file that differs from the table
// fails here).
#include <gtest/gtest.h>

#include <dirent.h>

#include <cmath>

#include <fstream>
#include <set>
#include <sstream>

#include "backlash_servo/config/compare_config.h"
#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/robot_config.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/model/param_table.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;
using test_helpers::readFile;
using test_helpers::runCapture;

std::string params(const std::string& args)
{
  int code = 0;
  const std::string out = runCapture(std::string(BACKLASH_PARAMS_EXE) + " " + args, &code);
  EXPECT_EQ(code, 0) << args;
  return out;
}

TEST(ParamTable, EntriesAreWellFormed)
{
  std::set<std::string> keys;
  for (const ParamSpec& p : parameterTable())
  {
    EXPECT_TRUE(keys.insert(p.key).second) << "duplicate key " << p.key;
    EXPECT_NE(std::string(p.unit), "") << p.key << ": every parameter states its unit ('-' for none)";
    EXPECT_NE(std::string(p.doc), "") << p.key;
    EXPECT_EQ(p.flag().find('_'), std::string::npos) << p.flag();
    if (p.type == ParamType::Real && *p.fallback != '\0')
    {
      EXPECT_NO_THROW(p.check(p.fallbackNumber())) << p.key << " default " << p.fallback;
    }
    if (p.type == ParamType::Choice)
    {
      EXPECT_TRUE(p.isChoice(p.fallback)) << p.key;
    }
    if (p.section == ParamSection::Servo)
    {
      EXPECT_TRUE(p.type == ParamType::Choice ? std::holds_alternative<std::string ServoParams::*>(p.field)
                                              : std::holds_alternative<double ServoParams::*>(p.field))
          << p.key;
    }
    if (p.section == ParamSection::Chart)
    {
      EXPECT_TRUE(std::holds_alternative<double ChartParams::*>(p.field)) << p.key;
    }
    if (p.live)
    {
      // What the node can change mid-run: the plant, the drive and its own settings (not the initial state).
      EXPECT_TRUE(p.section == ParamSection::Servo || p.section == ParamSection::Drive ||
                  p.section == ParamSection::Node)
          << p.key;
    }
  }
  // The table's defaults are the defaults of the structs the physics uses (the thesis' App. D1 case).
  const ServoParams defaults;
  for (const ParamSpec* p : paramsIn(ParamSection::Servo))
  {
    if (const auto* text = std::get_if<std::string ServoParams::*>(&p->field))
    {
      EXPECT_EQ(defaults.*(*text), p->fallback) << p->key;
      continue;
    }
    EXPECT_EQ(defaults.*std::get<double ServoParams::*>(p->field), p->fallbackNumber()) << p->key;
  }
}

TEST(ParamTable, RangesAcceptTheirBoundsAndRefuseBeyond)
{
  // Independent expectations for each kind of range, written out here.
  EXPECT_THROW(param("motor_inertia").check(0.0), InvalidParameterError);
  EXPECT_NO_THROW(param("motor_inertia").check(1e-9));  // the envelope's edge is inside
  EXPECT_THROW(param("motor_inertia").check(0.99e-9), InvalidParameterError);
  EXPECT_NO_THROW(param("motor_friction").check(0.0));
  EXPECT_THROW(param("motor_friction").check(-1e-300), InvalidParameterError);
  EXPECT_NO_THROW(param("restitution").check(1.0));
  EXPECT_THROW(param("restitution").check(std::nextafter(1.0, 2.0)), InvalidParameterError);
  EXPECT_THROW(param("command").check(INFINITY), InvalidParameterError);
  try
  {
    param("restitution").check(1.5);
    FAIL();
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_EQ(std::string(e.what()), "restitution: must be in [0, 1] (got 1.5)");
    EXPECT_EQ(e.field(), "restitution");
  }
}

TEST(ParamTable, DerivedQuantitiesOutsideTheEnvelopeAreRefusedNamingThem)
{
  ServoParams p;
  p.motor_inertia = 1e-7;  // ρ²J_L/J_m = 9e6
  try
  {
    p.validate();
    FAIL();
  }
  catch (const InvalidParameterError& e)
  {
    const std::string what = e.what();
    EXPECT_NE(what.find("inertia split"), std::string::npos) << what;
    EXPECT_NE(what.find("9000000"), std::string::npos) << what;
    EXPECT_NE(what.find("motor_inertia 1e-07"), std::string::npos) << what;
  }
  ServoParams fast;
  fast.gain = 1e9;  // ω_n = 3.2e4 rad/s
  EXPECT_THROW(fast.validate(), InvalidParameterError);
  ServoParams edge;
  edge.motor_inertia = 0.9e-3;  // ρ²J_L/J_m = 1000: inside
  EXPECT_NO_THROW(edge.validate());
}

TEST(ParamTable, FlagParserTakesTableKeysAndToolOptions)
{
  const std::string yaml = ::testing::TempDir() + "param_table.yaml";
  std::ofstream(yaml) << "gain: 2\nbacklash: 0.2\npublish_rate: 50\n";  // a node-only key is known, not refused
  FlagParser parser("t", "header\n", {"gain", "backlash", "restitution"},
                    {{"config", "FILE", "yaml"}, {"json", "", "switch"}, {"out", "FILE", "value"}});
  const char* argv[] = {"t", "--config", yaml.c_str(), "--gain=3", "--json", "--out", "x.csv"};
  parser.parse(7, const_cast<char**>(argv));
  EXPECT_EQ(parser.keys().number("gain"), 3.0);      // the flag overrides the file
  EXPECT_EQ(parser.keys().number("backlash"), 0.2);  // the file's value
  EXPECT_FALSE(parser.keys().has("restitution"));
  EXPECT_TRUE(parser.given("json"));
  EXPECT_EQ(parser.option("out"), "x.csv");
  const std::string usage = parser.usage();
  for (const char* k : {"--gain", "--backlash", "--restitution", "--config FILE", "--json", "N·m/rad", "in [0, 1]"})
  {
    EXPECT_NE(usage.find(k), std::string::npos) << k;
  }
  auto refuse = [](std::vector<const char*> args, const std::string& mentions) {
    FlagParser p("t", "", {"gain"}, {{"json", "", ""}});
    args.insert(args.begin(), "t");
    try
    {
      p.parse(static_cast<int>(args.size()), const_cast<char**>(args.data()));
      ADD_FAILURE() << mentions;
    }
    catch (const ConfigError& e)
    {
      EXPECT_NE(std::string(e.what()).find(mentions), std::string::npos) << e.what();
    }
  };
  refuse({"--backlash", "1"}, "--backlash");  // a table key this tool does not take
  refuse({"--gain"}, "needs a value");
  refuse({"--json=1"}, "takes no value");
  refuse({"gain"}, "unexpected argument");
  const std::string bad_yaml = ::testing::TempDir() + "param_table_bad.yaml";
  std::ofstream(bad_yaml) << "gain: 2\ngian: 3\n";
  FlagParser p("t", "", {"gain"}, {{"config", "FILE", ""}});
  const char* argv2[] = {"t", "--config", bad_yaml.c_str()};
  EXPECT_THROW(p.parse(3, const_cast<char**>(argv2)), ConfigError);
}

TEST(ParamTable, TypedValuesAreNotRoundTrippedThroughText)
{
  KeyValues kv;
  const double v = 0.1 + 0.2;  // 0.30000000000000004: any text form shorter than 17 digits would change it
  kv.setNumber("gain", v);
  kv.setNumber("backlash", std::nextafter(0.3, 1.0));
  const RunConfig c = runConfigFrom(kv);
  EXPECT_EQ(c.params.gain, v);
  EXPECT_EQ(c.params.backlash, std::nextafter(0.3, 1.0));
  kv.setNumber("gain", NAN);
  EXPECT_THROW(runConfigFrom(kv), ConfigError);
  KeyValues mixed;
  mixed.setNumber("zeta", 0.4);
  mixed.setNumber("gain", 2.0);
  EXPECT_THROW(runConfigFrom(mixed), ConfigError);
}

// The chart form shares the compliant mesh's and shaft's keys with the physical form: they reach the joint as given
// (the same joint as the physical form of that chart), and are validated together there too.
TEST(ParamTable, TheChartFormCarriesTheCompliantKeys)
{
  KeyValues kv;
  kv.setNumber("zeta", 0.4);
  kv.setNumber("inertia_ratio", 9.0);
  kv.setNumber("friction_ratio", 0.4);
  kv.set("mesh_law", "msl_elastobacklash");
  kv.setNumber("mesh_stiffness", 1e4);
  kv.setNumber("mesh_damping", 4.5);
  kv.setNumber("gear_inertia", 0.05);
  kv.setNumber("shaft_stiffness", 300.0);
  kv.setNumber("shaft_damping", 0.2);
  const ServoParams p = runConfigFrom(kv).params;
  EXPECT_EQ(p.mesh_law, "msl_elastobacklash");
  EXPECT_EQ(p.mesh_stiffness, 1e4);
  EXPECT_EQ(p.mesh_damping, 4.5);
  EXPECT_EQ(p.gear_inertia, 0.05);
  EXPECT_EQ(p.shaft_stiffness, 300.0);
  EXPECT_EQ(p.shaft_damping, 0.2);
  EXPECT_NEAR(p.motor_inertia, 0.1, 1e-15);  // D1 in physical units: the chart's J = 1 kg·m², ρ²J_L/J_m = 9
  kv.setNumber("shaft_stiffness", 0.0);      // shaft damping without a shaft: refused, naming the key
  try
  {
    runConfigFrom(kv);
    ADD_FAILURE() << "accepted shaft_damping without shaft_stiffness";
  }
  catch (const std::exception& e)
  {
    EXPECT_NE(std::string(e.what()).find("shaft_damping"), std::string::npos) << e.what();
  }
}

TEST(ParamTable, GeneratedFilesMatchTheTable)
{
  const std::string src = SOURCE_DIR;
  EXPECT_EQ(readFile(src + "/cfg/BacklashServo.cfg"), params("--format cfg"))
      << "cfg/BacklashServo.cfg differs from the parameter table: run bash scripts/generate_params.sh";
  const std::string readme = readFile(src + "/docs/parameters.md");
  const std::string begin = "<!-- BEGIN GENERATED params: ";
  std::size_t pos = 0;
  int blocks = 0;
  while ((pos = readme.find(begin, pos)) != std::string::npos)
  {
    const std::size_t sections_end = readme.find(" -->\n", pos);
    const std::string sections = readme.substr(pos + begin.size(), sections_end - pos - begin.size());
    const std::size_t body = sections_end + 5;
    const std::size_t end = readme.find("<!-- END GENERATED params -->", body);
    ASSERT_NE(end, std::string::npos);
    EXPECT_EQ(readme.substr(body, end - body), params("--format markdown --sections " + sections))
        << "docs/parameters.md table " << sections
        << " differs from the parameter table: run bash scripts/generate_params.sh";
    pos = end;
    ++blocks;
  }
  EXPECT_GE(blocks, 1);
}

TEST(ParamTable, ShippedYamlFilesUseOnlyTableKeys)
{
  const std::string dir = std::string(SOURCE_DIR) + "/config/";
  DIR* d = opendir(dir.c_str());
  ASSERT_NE(d, nullptr);
  int files = 0;
  while (dirent* e = readdir(d))
  {
    const std::string name = e->d_name;
    if (name.rfind("compare_", 0) == 0)
    {
      EXPECT_NO_THROW(loadCompareConfig(dir + name)) << name;  // workbench experiment files (lists inside)
      ++files;
      continue;
    }
    if (name.size() > 5 && name.substr(name.size() - 5) == ".yaml" && isRobotFile(dir + name))
    {
      // An arm: the top level and every joint's keys are table keys, and every joint is a valid one.
      const RobotFile file = loadRobotFile(dir + name);
      const auto arm = file.urdf.empty() ? nullptr : std::make_unique<ArmModel>(readFile(file.urdf));
      EXPECT_NO_THROW(robotJointsFrom(file.top, file.joints, arm.get())) << name;
      ++files;
      continue;
    }
    if (name.size() > 5 && name.substr(name.size() - 5) == ".yaml")
    {
      KeyValues kv;
      kv.loadYaml(dir + name);
      EXPECT_NO_THROW(requireKnownKeys(kv, name)) << name;
      EXPECT_NO_THROW(runConfigFrom(kv)) << name;
      ++files;
    }
  }
  closedir(d);
  EXPECT_GE(files, 2);
}

}  // namespace
