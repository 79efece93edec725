// Property fuzzing of the tools' input files, deterministic (fixed seeds): valid profiles (YAML and CSV), sweep parts
// and workbench files, mutated (bytes flipped, NUL/CR/commas/extreme numbers inserted, lines dropped, repeated or
// swapped), then read by the same loaders the tools use. Properties: a loader either accepts or throws ConfigError /
// InvalidParameterError (never anything else, never a crash); what it accepts is sound — a profile's points are
// finite and ordered and its value at every point time equals a linear scan written here, a part merges into exactly
// its header and rows, a workbench file's strategies hold valid parameters. Every case is reproducible from its
// seed (printed on failure).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/config/compare_config.h"
#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/profile_loader.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/studies/sweep_csv.h"

namespace
{
using namespace backlash_servo;

const char* const PROFILE_CSV = "time,value\n0,0\n0.5,1\n1,-0.25\n2.5,0.1\n4,0.1\n";
const char* const PROFILE_YAML =
    "- step: {time: 0, target: 1}\n- ramp: {time: 2, target: 0.5, duration: 1}\n- move: {time: 4, distance: -0.5, "
    "max_velocity: 0.5, max_acceleration: 2}\n";
const char* const PART =
    "# backlash_sweep part 1/1: points [0, 4) of 4, grid 0123456789abcdef\n"
    "zeta,restitution,verdict,limit_cycle,limit_cycle_error,period,impacts,simulated_time,settled,steady_error,"
    "maxima_per_period,peak_to_peak,cycle_centre,peak_to_peak_counts,below_resolution\n"
    "0.3,0,converged,0,0,0,4,80,1,1.5e-17,0,,,,\n0.3,1,limit_cycle,1,0.05,12.2,23,160.5,1,,1,0.1,1,,\n"
    "0.5,0,converged,0,0,0,3,60,1,0,0,,,,\n0.5,1,undecided,0,0,0,100,2000,0,,0,,,,\n";
const char* const COMPARE =
    "motor_inertia: 1.0e-4\nload_inertia: 0.5\nmotor_friction: 1.0e-4\nload_friction: 0.5\ngear_ratio: 0.01\n"
    "backlash: 0.005\nrestitution: 0.5\ncontroller_rate: 1000\ngain: 6\nduration: 2\nsample_rate: 100\n"
    "profile:\n  - step: {time: 0, target: 0.5}\nstrategies:\n  - name: P\n    control_law: proportional\n"
    "  - name: PID\n    control_law: pid\n    integral_gain: 30\n    derivative_gain: 0.4\n";

/// Small random edits of `text`, reproducible from the generator's state.
std::string mutate(std::string text, std::mt19937_64& rng)
{
  static const std::vector<std::string> tokens = {",",
                                                  std::string(1, '\0'),
                                                  "\r",
                                                  "\n",
                                                  "nan",
                                                  "inf",
                                                  "1e300",
                                                  "-1e12",
                                                  "-",
                                                  "#",
                                                  ":",
                                                  "[",
                                                  "{",
                                                  "'",
                                                  "\"",
                                                  "  ",
                                                  "0",
                                                  ".5",
                                                  "18446744073709551615",
                                                  "1e-320",
                                                  "converged",
                                                  ",,"};
  std::uniform_int_distribution<int> ops(1, 4);
  const int n = ops(rng);
  for (int k = 0; k < n && !text.empty(); ++k)
  {
    std::uniform_int_distribution<std::size_t> at(0, text.size() - 1);
    switch (rng() % 6)
    {
      case 0:  // flip a byte
        text[at(rng)] ^= static_cast<char>(1u << (rng() % 8));
        break;
      case 1:  // insert a token
        text.insert(at(rng), tokens[rng() % tokens.size()]);
        break;
      case 2:  // delete a range
      {
        const std::size_t from = at(rng);
        text.erase(from, std::min<std::size_t>(text.size() - from, 1 + rng() % 12));
        break;
      }
      default:  // drop, repeat or swap whole lines
      {
        std::vector<std::string> lines;
        std::stringstream ss(text);
        for (std::string l; std::getline(ss, l);)
        {
          lines.push_back(l);
        }
        if (lines.size() < 2)
        {
          break;
        }
        const std::size_t a = rng() % lines.size(), b = rng() % lines.size();
        const int how = static_cast<int>(rng() % 3);
        if (how == 0)
        {
          lines.erase(lines.begin() + static_cast<long>(a));
        }
        else if (how == 1)
        {
          lines.insert(lines.begin() + static_cast<long>(a), lines[b]);
        }
        else
        {
          std::swap(lines[a], lines[b]);
        }
        text.clear();
        for (const std::string& l : lines)
        {
          text += l + "\n";
        }
      }
    }
  }
  return text;
}

class InputFuzz : public ::testing::Test
{
 protected:
  void SetUp() override
  {
    char tmpl[] = "/tmp/backlash_input_fuzz.XXXXXX";
    ASSERT_NE(mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override
  {
    for (const char* name : {"/p.csv", "/p.yaml", "/part.csv", "/c.yaml"})
    {
      std::remove((dir_ + name).c_str());
    }
    ::rmdir(dir_.c_str());
  }
  std::string file(const char* name, const std::string& text)
  {
    const std::string path = dir_ + name;
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    return path;
  }
  /// Runs `load` on `cases` mutations of `base`; counts accepted and refused inputs.
  template <class Load>
  void fuzz(const char* base, int cases, std::uint64_t seed, Load load)
  {
    int accepted = 0, refused = 0;
    for (int i = 0; i < cases; ++i)
    {
      std::mt19937_64 rng(seed * 1000003u + static_cast<std::uint64_t>(i));
      const std::string input = i == 0 ? std::string(base) : mutate(base, rng);
      SCOPED_TRACE("case " + std::to_string(i) + " (seed " + std::to_string(seed) + ")");
      try
      {
        load(input);
        ++accepted;
      }
      catch (const ConfigError&)
      {
        ++refused;
      }
      catch (const InvalidParameterError&)
      {
        ++refused;
      }
      catch (const std::exception& e)
      {
        ADD_FAILURE() << "escaped: " << e.what() << "\ninput:\n" << input;
      }
    }
    std::printf("input fuzz: %d accepted, %d refused\n", accepted, refused);
    EXPECT_GT(accepted, 0);  // the unmutated base is always accepted
    EXPECT_GT(refused, cases / 10);
  }
  std::string dir_;
};

TEST_F(InputFuzz, ProfileCsvsAreRefusedOrSound)
{
  fuzz(PROFILE_CSV, 1500, 1, [&](const std::string& text) {
    const auto profile = loadProfileFile(file("/p.csv", text), 0.0);
    const auto& points = profile->segments().at(0).points;
    ASSERT_FALSE(points.empty());
    for (std::size_t k = 0; k < points.size(); ++k)
    {
      ASSERT_TRUE(std::isfinite(points[k].first) && std::isfinite(points[k].second)) << text;
      ASSERT_LE(std::fabs(points[k].second), 1e6) << text;
      ASSERT_TRUE(k == 0 || points[k].first >= points[k - 1].first) << text;
      for (double t : {points[k].first, points[k].first + 0.25})
      {
        double expected = 0.0;
        for (const auto& p : points)
        {
          if (p.first > t)
          {
            break;
          }
          expected = p.second;
        }
        ASSERT_EQ(profile->at(t), expected) << "t = " << t << "\n" << text;
      }
    }
  });
}

TEST_F(InputFuzz, ProfileYamlsAreRefusedOrSound)
{
  fuzz(PROFILE_YAML, 1500, 2, [&](const std::string& text) {
    const auto profile = loadProfileFile(file("/p.yaml", text), 0.0);
    ASSERT_FALSE(profile->segments().empty());
    for (double t = 0.0; t < 8.0; t += 0.37)
    {
      ASSERT_TRUE(std::isfinite(profile->at(t))) << text;
      ASSERT_LE(std::fabs(profile->at(t)), 2e6) << text;
    }
  });
}

TEST_F(InputFuzz, SweepPartsAreRefusedOrMergeIntoTheirRows)
{
  fuzz(PART, 1500, 3, [&](const std::string& text) {
    const std::string merged = mergeParts({file("/part.csv", text)});
    unsigned long long k = 0, n = 0, a = 0, b = 0, total = 0;
    ASSERT_EQ(std::sscanf(text.c_str(), "# backlash_sweep part %llu/%llu: points [%llu, %llu) of %llu", &k, &n, &a, &b,
                          &total),
              5)
        << text;
    ASSERT_EQ(static_cast<unsigned long long>(std::count(merged.begin(), merged.end(), '\n')), total + 1) << text;
    // Every merged row is one of the input's lines, in the input's order.
    std::size_t from = 0;
    std::stringstream rows(merged.substr(merged.find('\n') + 1));
    for (std::string row; std::getline(rows, row);)
    {
      const std::size_t at = text.find(row + "\n", from);
      ASSERT_NE(at, std::string::npos) << row << "\n" << text;
      from = at + row.size();
    }
  });
}

TEST_F(InputFuzz, WorkbenchFilesAreRefusedOrHoldValidStrategies)
{
  fuzz(COMPARE, 800, 4, [&](const std::string& text) {
    const CompareConfig c = loadCompareConfig(file("/c.yaml", text));
    ASSERT_FALSE(c.strategies.empty());
    for (const CompareStrategy& s : c.strategies)
    {
      EXPECT_NO_THROW(s.config.params.validate()) << s.name << "\n" << text;
      ASSERT_TRUE(s.config.profile != nullptr);
    }
  });
}

}  // namespace
