#include "sweep_csv.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <sstream>

#include "backlash_servo/config/key_values.h"

namespace backlash_servo
{
const char* const SWEEP_CSV_HEADER =
    "zeta,inertia_ratio,friction_ratio,restitution,backlash,verdict,limit_cycle,limit_cycle_error,period,impacts,"
    "simulated_time,settled";

namespace
{
constexpr int COLUMNS = 12;
}

std::string sweepRow(const SweepPoint& p, const RunSummary& r)
{
  const bool lc = r.status.verdict == Verdict::LimitCycle || r.status.verdict == Verdict::Irregular;
  char buf[400];
  std::snprintf(buf, sizeof buf, "%s,%s,%d,%.17g,%.17g,%llu,%.17g,%d", p.columns().c_str(), toString(r.status.verdict),
                lc ? 1 : 0, lc ? r.status.error : 0.0, lc ? r.status.period : 0.0,
                static_cast<unsigned long long>(r.impacts), r.simulated, r.settled ? 1 : 0);
  return buf;
}

std::vector<std::string> resumableRows(const std::string& path, const SweepGrid& grid)
{
  std::ifstream in(path);
  const std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::stringstream ss(content);
  std::string line;
  std::vector<std::string> kept;
  bool first = true;
  const std::size_t n = grid.size();
  while (std::getline(ss, line))
  {
    const bool complete = ss.good() || (!content.empty() && content.back() == '\n');
    if (first)
    {
      first = false;
      if (line != SWEEP_CSV_HEADER)
      {
        throw ConfigError("'" + path + "' is not a backlash_sweep CSV (header differs)");
      }
      continue;
    }
    if (!complete || std::count(line.begin(), line.end(), ',') != COLUMNS - 1)
    {
      break;  // torn last line of an interrupted run
    }
    const std::size_t index = kept.size();
    const std::string expected = index < n ? grid.point(index).columns() : "";
    if (line.compare(0, expected.size() + 1, expected + ",") != 0)
    {
      throw ConfigError("'" + path + "' row " + std::to_string(index + 1) + " (" +
                        line.substr(0, std::min<std::size_t>(line.size(), 60)) + ") is not point " +
                        std::to_string(index + 1) +
                        " of this grid: it was written for a different grid; refusing to resume");
    }
    kept.push_back(line);
  }
  return kept;
}

bool SweepCsvWriter::flush()
{
  out_.flush();
  return static_cast<bool>(out_);
}

}  // namespace backlash_servo
