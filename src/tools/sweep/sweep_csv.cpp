#include "sweep_csv.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <sstream>

#include "backlash_servo/config/key_values.h"

namespace backlash_servo
{

std::string sweepRow(const SweepPoint& p, const RunSummary& r, double command)
{
  const bool lc = r.status.verdict == Verdict::LimitCycle || r.status.verdict == Verdict::Irregular;
  char buf[400];
  std::snprintf(buf, sizeof buf, "%s,%d,%.17g,%.17g,%llu,%.17g,%d,", toString(r.status.verdict), lc ? 1 : 0,
                lc ? r.status.error : 0.0, lc ? r.status.period : 0.0, static_cast<unsigned long long>(r.impacts),
                r.simulated, r.settled ? 1 : 0);
  std::string row = p.columns();
  row += (row.empty() ? "" : ",") + std::string(buf);
  if (r.status.verdict == Verdict::Converged)
  {
    std::snprintf(buf, sizeof buf, "%.17g", r.final_state.load_position - command);
    row += buf;
  }
  return row;
}

SweepShard shardOf(std::size_t k, std::size_t n, std::size_t total)
{
  SweepShard s;
  s.k = k;
  s.n = n;
  s.first = (k - 1) * total / n;
  s.last = k * total / n;
  return s;
}

std::string SweepShard::headerLine(const SweepGrid& grid) const
{
  return "# backlash_sweep part " + std::to_string(k) + "/" + std::to_string(n) + ": points [" + std::to_string(first) +
         ", " + std::to_string(last) + ") of " + std::to_string(grid.size()) + ", grid " + grid.fingerprint();
}

std::string mergeParts(const std::vector<std::string>& paths)
{
  struct Part
  {
    std::size_t k, n, first, last, total;
    std::string grid, path;
    std::vector<std::string> rows;
  };
  std::vector<Part> parts;
  std::string header;
  for (const std::string& path : paths)
  {
    std::ifstream in(path);
    if (!in)
    {
      throw ConfigError("--merge: cannot read '" + path + "'");
    }
    const std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::stringstream ss(content);
    std::string line;
    std::getline(ss, line);
    Part p;
    p.path = path;
    char grid[64] = {0};
    unsigned long long k, n, first, last, total;
    if (std::sscanf(line.c_str(), "# backlash_sweep part %llu/%llu: points [%llu, %llu) of %llu, grid %63s", &k, &n,
                    &first, &last, &total, grid) != 6 ||
        k < 1 || k > n || last < first)
    {
      throw ConfigError("--merge: '" + path + "' is not a part of a sharded sweep (no part line)");
    }
    p.k = k, p.n = n, p.first = first, p.last = last, p.total = total, p.grid = grid;
    std::getline(ss, line);
    if (line.find("verdict,limit_cycle,") == std::string::npos || (!header.empty() && line != header))
    {
      throw ConfigError("--merge: '" + path + "' has no sweep CSV header, or another grid's");
    }
    header = line;
    while (std::getline(ss, line))
    {
      const bool complete = ss.good() || (!content.empty() && content.back() == '\n');
      if (complete)
      {
        p.rows.push_back(line);
      }
    }
    if (p.rows.size() != p.last - p.first)
    {
      throw ConfigError("--merge: part " + std::to_string(p.k) + "/" + std::to_string(p.n) + " ('" + path + "') has " +
                        std::to_string(p.rows.size()) + " of " + std::to_string(p.last - p.first) +
                        " rows: finish it with --resume first");
    }
    parts.push_back(std::move(p));
  }
  if (parts.empty())
  {
    throw ConfigError("--merge: no part files given");
  }
  const Part& ref = parts.front();
  std::vector<const Part*> by_k(ref.n + 1, nullptr);
  for (const Part& p : parts)
  {
    if (p.n != ref.n || p.total != ref.total || p.grid != ref.grid)
    {
      throw ConfigError("--merge: '" + p.path + "' belongs to another sweep (part of " + std::to_string(p.n) +
                        ", grid " + p.grid + ") than '" + ref.path + "'");
    }
    if (by_k[p.k] != nullptr)
    {
      throw ConfigError("--merge: part " + std::to_string(p.k) + "/" + std::to_string(p.n) + " given twice ('" +
                        by_k[p.k]->path + "', '" + p.path + "')");
    }
    by_k[p.k] = &p;
  }
  std::string missing;
  for (std::size_t k = 1; k <= ref.n; ++k)
  {
    if (by_k[k] == nullptr)
    {
      missing += (missing.empty() ? "" : ", ") + std::to_string(k);
    }
  }
  if (!missing.empty())
  {
    throw ConfigError("--merge: missing part(s) " + missing + " of " + std::to_string(ref.n));
  }
  std::string out = header + "\n";
  for (std::size_t k = 1; k <= ref.n; ++k)
  {
    for (const std::string& row : by_k[k]->rows)
    {
      out += row + "\n";
    }
  }
  return out;
}

std::vector<std::string> resumableRows(const std::string& path, const SweepGrid& grid, const SweepShard& shard)
{
  std::ifstream in(path);
  const std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::stringstream ss(content);
  std::string line;
  std::vector<std::string> kept;
  bool first = true;
  bool part_line = !shard.whole();
  const std::size_t n = grid.size();
  while (std::getline(ss, line))
  {
    const bool complete = ss.good() || (!content.empty() && content.back() == '\n');
    if (part_line)
    {
      part_line = false;
      if (line != shard.headerLine(grid))
      {
        throw ConfigError("'" + path + "' is not part " + std::to_string(shard.k) + "/" + std::to_string(shard.n) +
                          " of this grid; refusing to resume");
      }
      continue;
    }
    if (first)
    {
      first = false;
      if (line != grid.header())
      {
        throw ConfigError("'" + path + "' is not a backlash_sweep CSV (header differs)");
      }
      continue;
    }
    const std::string header = grid.header();
    if (!complete || std::count(line.begin(), line.end(), ',') != std::count(header.begin(), header.end(), ','))
    {
      break;  // torn last line of an interrupted run
    }
    const std::size_t index = shard.first + kept.size();
    const std::string expected = index < (shard.whole() ? n : shard.last) ? grid.point(index).columns() + "," : "";
    if (line.compare(0, expected.size(), expected) != 0)
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
