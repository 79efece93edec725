// backlash_fuzz: runs N property-fuzz cases (fuzz_cases.h) and prints counts per outcome class, examples and the
// slowest cases (a search that crawls shows up there before it becomes a hang).
// usage: backlash_fuzz [--cases N] [--seed S] [--first K] [--budget IMPACTS] [--compliant | --damped] [--verbose]
// (--compliant: the cases' joints with a compliant mesh, fuzz::makeCompliantCase; --damped: the same with contact and
// shaft damping across the whole envelope, fuzz::makeDampedCompliantCase)
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>

#include "fuzz_cases.h"

int main(int argc, char** argv)
{
  std::uint64_t cases = 2000, seed = 1, first = 0, budget = 100000;
  bool verbose = false, compliant = false, damped = false;
  for (int i = 1; i < argc; ++i)
  {
    auto next = [&]() { return i + 1 < argc ? std::strtoull(argv[++i], nullptr, 10) : 0ull; };
    if (!std::strcmp(argv[i], "--cases"))
      cases = next();
    else if (!std::strcmp(argv[i], "--seed"))
      seed = next();
    else if (!std::strcmp(argv[i], "--first"))
      first = next();
    else if (!std::strcmp(argv[i], "--budget"))
      budget = next();
    else if (!std::strcmp(argv[i], "--verbose"))
      verbose = true;
    else if (!std::strcmp(argv[i], "--compliant"))
      compliant = true;
    else if (!std::strcmp(argv[i], "--damped"))
      damped = true;
    else
    {
      std::fprintf(
          stderr,
          "usage: backlash_fuzz [--cases N] [--seed S] [--first K] [--budget IMPACTS] [--compliant | --damped] "
          "[--verbose]\n");
      return 2;
    }
  }
  std::map<std::string, std::uint64_t> counts;
  std::map<std::string, std::string> example;
  std::uint64_t compensated = 0, profiled = 0;  // cases drawn with a compensator, with a command profile
  const bool trace = std::getenv("BACKLASH_FUZZ_TRACE") != nullptr;  // print each case's number before running it
  std::multimap<double, std::uint64_t> slowest;                      // wall time [s] → case: the SLOWEST cases
  constexpr std::size_t SLOWEST = 3;
  const auto start = std::chrono::steady_clock::now();
  for (std::uint64_t i = first; i < first + cases; ++i)
  {
    const fuzz::Case c = damped      ? fuzz::makeDampedCompliantCase(seed, i)
                         : compliant ? fuzz::makeCompliantCase(seed, i)
                                     : fuzz::makeCase(seed, i);
    if (trace)
    {
      std::fprintf(stderr, "case %llu\n", static_cast<unsigned long long>(i));  // a hang shows its case
    }
    const auto began = std::chrono::steady_clock::now();
    const fuzz::Outcome o = fuzz::check(c, budget);
    slowest.emplace(std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count(), i);
    if (slowest.size() > SLOWEST)
    {
      slowest.erase(slowest.begin());
    }
    ++counts[o.klass];
    compensated += c.drive.compensation != "none";
    profiled += c.profile != nullptr;
    if (o.klass != "ok" && o.klass != "budget" && o.klass != "diverged" && (verbose || !example.count(o.klass)))
    {
      example[o.klass] = "case " + std::to_string(i) + ": " + o.detail + "\n    backlash_sim " + c.describe();
      if (verbose)
        std::printf("%s %s\n", o.klass.c_str(), example[o.klass].c_str());
    }
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("backlash_fuzz: seed %llu, cases %llu..%llu in %.1f s\n", static_cast<unsigned long long>(seed),
              static_cast<unsigned long long>(first), static_cast<unsigned long long>(first + cases - 1), wall);
  std::printf("  (drawn with a compensator: %llu, with a command profile: %llu)\n",
              static_cast<unsigned long long>(compensated), static_cast<unsigned long long>(profiled));
  std::uint64_t failures = 0;
  for (const auto& kv : counts)
  {
    std::printf("  %-12s %llu\n", kv.first.c_str(), static_cast<unsigned long long>(kv.second));
    failures += kv.first == "ok" || kv.first == "budget" || kv.first == "diverged" ? 0 : kv.second;
  }
  std::printf("  slowest:");
  for (auto it = slowest.rbegin(); it != slowest.rend(); ++it)
  {
    std::printf(" case %llu %.2f s;", static_cast<unsigned long long>(it->second), it->first);
  }
  std::printf("\n");
  for (const auto& kv : example)
  {
    std::printf("example %s %s\n", kv.first.c_str(), kv.second.c_str());
  }
  return failures == 0 ? 0 : 1;
}
