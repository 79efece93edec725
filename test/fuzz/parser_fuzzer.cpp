// Coverage-guided fuzz target (clang/libFuzzer): the YAML and flag parsers every tool and the node share,
// and a short run of whatever they accept. Built by `cmake -DBACKLASH_LIBFUZZER=ON` with clang in build/libfuzzer by
// scripts/fuzz_parsers.sh SECONDS (the test command runs it for 60 s).
//
// The first byte picks the parser, the rest is its input:
//   0: a run's YAML (KeyValues::loadYaml + runConfigFrom, with an inline `profile:` list),
//   1: the workbench's experiment file (loadCompareConfig),
//   2: a profile file (YAML list, loadProfileFile),
//   3: command-line flags (FlagParser, whitespace-separated, then runConfigFrom),
//   4: a profile CSV of time,value rows (loadProfileFile of a .csv),
//   5: a sweep part file (mergeParts of one part).
// Properties: only ConfigError / InvalidParameterError escape a parser (a yaml-cpp exception or a logic_error
// escaping is a finding: libFuzzer reports the uncaught exception as a crash), nothing crashes or hangs;
// an accepted run config simulates (0.2 s, at most 1e4 impacts and 1e4 controller samples) to a finite state whose
// gap lies in [0, Δ] to rounding (rigid teeth; a compliant mesh's penetration takes it outside); an accepted profile
// CSV holds finite points in time order whose value at every point time (and between) equals a linear scan written
// here; an accepted part merges into its header and exactly its rows.
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
#include "backlash_servo/model/gear_mesh.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/simulation/step_response.h"
#include "backlash_servo/studies/sweep_csv.h"

using namespace backlash_servo;

namespace
{
/// The input as a file (the parsers read files, as the tools do); one per process, rewritten each time. Its path
/// does not depend on the process (a pid's digits formatted would vary the coverage from one run to the next), and
/// scripts/fuzz_parsers.sh --ci also fixes the directory and disables address randomisation (yaml-cpp orders its
/// nodes by address): with a fixed seed a run then repeats exactly.
std::string asFile(const std::string& text, const char* suffix)
{
  static const std::string base = [] {
    // BACKLASH_FUZZ_DIR: a directory of this run's own (scripts/fuzz_parsers.sh --ci), the same path every time.
    const char* fixed = std::getenv("BACKLASH_FUZZ_DIR");
    if (fixed != nullptr && *fixed != '\0')
    {
      return std::string(fixed) + "/input";
    }
    static char tmpl[] = "/tmp/backlash_parser_fuzz.XXXXXX";
    if (mkdtemp(tmpl) == nullptr)
    {
      std::abort();
    }
    std::atexit([] {
      for (const char* suffix : {".yaml", ".csv"})
      {
        std::remove((std::string(tmpl) + "/input" + suffix).c_str());
      }
      ::rmdir(tmpl);
    });
    return std::string(tmpl) + "/input";
  }();
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
  if (c.params.compliant())
  {
    return;  // a compliant mesh penetrates by design: its gap leaves [0, Δ]
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
/// An accepted CSV profile: points finite and in order, and at() equal to a linear scan (the reference).
void runProfileCsv(const std::string& text)
{
  const auto profile = loadProfileFile(asFile(text, ".csv"), 0.0);
  const std::vector<ProfileSegment>& segments = profile->segments();
  if (segments.size() != 1 || segments[0].points.empty())
  {
    fail("a CSV profile is one non-empty points segment");
  }
  const auto& points = segments[0].points;
  auto linear = [&](double t) {
    double v = 0.0;  // the start value passed above
    for (const auto& p : points)
    {
      if (p.first > t)
      {
        break;
      }
      v = p.second;
    }
    return v;
  };
  for (std::size_t k = 0; k < points.size() && k < 64; ++k)
  {
    if (!std::isfinite(points[k].first) || !std::isfinite(points[k].second) ||
        (k > 0 && points[k].first < points[k - 1].first))
    {
      fail("a CSV profile accepted a non-finite or unordered point");
    }
    for (double t : {points[k].first, std::nextafter(points[k].first, -INFINITY), points[k].first + 0.5})
    {
      if (t >= 0.0 && profile->at(t) != linear(t))
      {
        fail("profile value differs from the linear scan");
      }
    }
  }
}

/// An accepted part: the merge is its header line and exactly its rows.
void runSweepPart(const std::string& text)
{
  const std::string merged = mergeParts({asFile(text, ".csv")});
  const auto lines = std::count(merged.begin(), merged.end(), '\n');
  const auto first = text.find('\n');
  unsigned long long k = 0, n = 0, a = 0, b = 0, total = 0;
  if (first == std::string::npos ||
      std::sscanf(text.c_str(), "# backlash_sweep part %llu/%llu: points [%llu, %llu) of %llu", &k, &n, &a, &b,
                  &total) != 5)
  {
    fail("a part without a part line was merged");
  }
  if (static_cast<unsigned long long>(lines) != total + 1 || n != 1)
  {
    fail("a merge is not the header and every row of the grid");
  }
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
    switch (data[0] % 6)
    {
      case 4:
        runProfileCsv(text);
        break;
      case 5:
        runSweepPart(text);
        break;
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
        break;
      case 3:
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
