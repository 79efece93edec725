// Coverage-guided fuzz target (clang/libFuzzer, issue 14): the YAML and flag parsers every tool and the node share,
// and a short run of whatever they accept. Built by `cmake -DBACKLASH_LIBFUZZER=ON` with clang in build/libfuzzer by
// scripts/fuzz_parsers.sh SECONDS (the test command runs it for 60 s).
//
// The first byte picks the parser, the rest is its input:
//   0: a run's YAML (KeyValues::loadYaml + runConfigFrom, with an inline `profile:` list),
//   1: the workbench's experiment file (loadCompareConfig),
//   2: a profile file (YAML list, loadProfileFile),
//   3: command-line flags (FlagParser, whitespace-separated, then runConfigFrom).
// Properties: only ConfigError / InvalidParameterError escape a parser (a yaml-cpp exception or a logic_error
// escaping is a finding: libFuzzer reports the uncaught exception as a crash), nothing crashes or hangs;
// an accepted run config simulates (0.2 s, at most 1e4 impacts and 1e4 controller samples) to a finite state whose
// gap lies in [0, Δ] to rounding.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/config/compare_config.h"
#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/profile_loader.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/gear_mesh.h"
#include "backlash_servo/param_table.h"
#include "backlash_servo/step_response.h"

using namespace backlash_servo;

namespace
{
/// The input as a file (the parsers read files, as the tools do); one per process, rewritten each time.
std::string asFile(const std::string& text, const char* suffix)
{
  static const std::string base = "/tmp/backlash_parser_fuzz_" + std::to_string(getpid());
  const std::string path = base + suffix;
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
  return path;
}

void fail(const char* what)
{
  std::fprintf(stderr, "parser_fuzzer: property violated: %s\n", what);
  std::abort();
}

/// A short, bounded run of an accepted config: finite state, gap within [0, Δ] to rounding.
void simulate(RunConfig c)
{
  c.duration = 0.2;
  c.max_events = 1e4;
  RunSummary r;
  try
  {
    r = runResponse(c);
  }
  catch (const InvalidParameterError&)
  {
    return;  // refused at run time (e.g. a profile the law cannot take): a clear error, allowed
  }
  catch (const std::domain_error&)
  {
    if (c.drive.sampled())
    {
      return;  // an unstable digital loop runs off to infinity (backlash_design calls it "diverged"): allowed
    }
    throw;
  }
  if (r.status.verdict == Verdict::Diverged && c.drive.sampled())
  {
    return;  // an unstable digital loop, stopped with a clear verdict: allowed
  }
  const State& s = r.final_state;
  for (double v : {s.load_position, s.load_velocity, s.motor_position, s.motor_velocity})
  {
    if (!std::isfinite(v))
    {
      if (c.drive.sampled())
      {
        return;  // diverged, as above
      }
      fail("non-finite final state");
    }
  }
  const double g = GearMesh(c.params).gap(s.load_position, s.motor_position);
  const double tol = 1e-9 * (std::fabs(s.load_position) + c.params.backlash + 1.0);
  if (g < -tol || g > c.params.backlash + tol)
  {
    fail("gap outside [0, backlash]");
  }
}

void runYaml(const std::string& text)
{
  KeyValues kv;
  kv.loadYaml(asFile(text, ".yaml"));
  requireKnownKeys(kv, "fuzz");
  simulate(runConfigFrom(kv));
}

void runFlags(const std::string& text)
{
  std::vector<std::string> words{"fuzz"};
  std::string line = text;
  std::replace(line.begin(), line.end(), '\0', ' ');  // argv words end at a NUL
  std::istringstream in(line);
  for (std::string w; in >> w;)
  {
    if (w == "--help" || w == "-h" || w.rfind("--config", 0) == 0)
    {
      return;  // --help exits the process by design; --config reads files named by the input
    }
    words.push_back(w);
  }
  std::vector<char*> argv;
  for (std::string& w : words)
  {
    argv.push_back(&w[0]);
  }
  FlagParser parser("fuzz", "",
                    keysOfSections({ParamSection::Servo, ParamSection::Chart, ParamSection::Drive,
                                    ParamSection::Initial, ParamSection::Run}),
                    {{"json", "", "switch"}, {"csv", "FILE", "option"}});
  parser.parse(static_cast<int>(argv.size()), argv.data());
  KeyValues keys = parser.keys();
  if (keys.has("profile"))
  {
    return;  // a file name from the input: not read
  }
  simulate(runConfigFrom(keys));
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
  if (size < 1 || size > 4096)
  {
    return 0;
  }
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  try
  {
    switch (data[0] % 4)
    {
      case 0:
        runYaml(text);
        break;
      case 1:
        for (const CompareStrategy& s : loadCompareConfig(asFile(text, ".yaml")).strategies)
        {
          RunConfig c = s.config;
          simulate(c);
        }
        break;
      case 2:
        loadProfileFile(asFile(text, ".yaml"), 0.0)->finalValue();
        break;
      default:
        runFlags(text);
        break;
    }
  }
  catch (const ConfigError&)
  {
    // a clear refusal naming the key or the file; anything else escaping is a finding
  }
  catch (const InvalidParameterError&)
  {}
  return 0;
}
