#include "backlash_servo/studies/sweep_csv.h"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/safe_input.h"

namespace backlash_servo
{

std::string sweepRow(const SweepPoint& p, const RunSummary& r, const TrackingFigures* tracking)
{
  const bool lc = r.status.verdict == Verdict::LimitCycle || r.status.verdict == Verdict::Irregular;
  // A compliant mesh has contact phases where rigid teeth have impacts: the column counts those.
  const std::uint64_t impacts = r.contact_phases > 0 ? r.contact_phases : r.impacts;
  char buf[400];
  std::snprintf(buf, sizeof buf, "%s,%d,%.17g,%.17g,%llu,%.17g,%d,", toString(r.status.verdict), lc ? 1 : 0,
                lc ? r.status.error : 0.0, lc ? r.status.period : 0.0, static_cast<unsigned long long>(impacts),
                r.simulated, r.settled ? 1 : 0);
  std::string row = p.columns();
  row += (row.empty() ? "" : ",") + std::string(buf);
  if (std::isfinite(r.steady.error))  // (a converged joint that had not come to rest within rounding: empty)
  {
    std::snprintf(buf, sizeof buf, "%.17g", r.steady.error);
    row += buf;
  }
  row += "," + std::to_string(lc ? r.status.multiplicity : 0);  // maxima per period of the pattern
  if (lc)
  {
    std::snprintf(buf, sizeof buf, ",%.17g,%.17g", r.cycle.peak_to_peak, r.cycle.centre);
    row += buf;
  }
  else
  {
    row += ",,";
  }
  // The cycle in counts of the encoder the loop reads and whether it is under one (empty: no cycle or an ideal
  // sensor).
  if (lc && std::isfinite(r.resolution.counts))
  {
    std::snprintf(buf, sizeof buf, ",%.17g,%d", r.resolution.counts, r.resolution.below_count ? 1 : 0);
    row += buf;
  }
  else
  {
    row += ",,";
  }
  if (tracking != nullptr)
  {
    std::snprintf(buf, sizeof buf, ",%.17g,", tracking->band);
    row += buf;
    if (!std::isnan(tracking->settling_time))
    {
      std::snprintf(buf, sizeof buf, "%.17g", tracking->settling_time);
      row += buf;
    }
    row += ",";
    if (!std::isnan(tracking->steady_rms_error))
    {
      std::snprintf(buf, sizeof buf, "%.17g", tracking->steady_rms_error);
      row += buf;
    }
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

namespace
{
/// Largest part or sweep file read back (a 1344-point sweep is ~150 kB).
constexpr std::size_t kMaxSweepFileBytes = std::size_t(1) << 30;
bool endsWith(const std::string& line, const std::string& tail)
{
  return line == tail ||
         (line.size() > tail.size() && line.compare(line.size() - tail.size() - 1, tail.size() + 1, "," + tail) == 0);
}

/// Whether a sweep CSV header carries the tracking columns.
bool hasTracking(const std::string& header)
{
  return endsWith(header, resultColumns() + "," + trackingColumns());
}

/// How many result columns (tracking ones included) follow the axis columns under `header`.
std::size_t resultColumnCount(const std::string& header)
{
  static const std::size_t n = splitCsvCells(resultColumns()).size();
  static const std::size_t t = splitCsvCells(trackingColumns()).size();
  return n + (hasTracking(header) ? t : 0);
}

/// A sweep CSV header: axis names, then exactly the result columns (and the tracking columns).
bool isSweepHeader(const std::string& line)
{
  return endsWith(line, resultColumns()) || hasTracking(line);
}

bool isNumber(const std::string& cell)
{
  if (cell.empty() || cell.size() > 40)
  {
    return false;
  }
  char* end = nullptr;
  const double v = std::strtod(cell.c_str(), &end);
  return *end == '\0' && std::isfinite(v) && !std::isspace(static_cast<unsigned char>(cell[0]));
}

/// Throws ConfigError unless `line` is a well-formed result row under `header` (column count and every cell's
/// type: parameter values, a verdict name, 0/1 flags, numbers; steady_error empty unless converged, the cycle's
/// peak_to_peak and cycle_centre empty unless oscillating).
void checkRow(const std::string& line, const std::vector<std::string>& header, const std::string& where)
{
  const std::vector<std::string> cells = splitCsvCells(line);
  auto bad = [&](const std::string& why) {
    throw ConfigError(where + ": " + why + " (" + line.substr(0, std::min<std::size_t>(line.size(), 80)) + ")");
  };
  if (cells.size() != header.size())
  {
    bad(std::to_string(cells.size()) + " columns, the header has " + std::to_string(header.size()));
  }
  std::string joined;
  for (const std::string& h : header)
  {
    joined += (joined.empty() ? "" : ",") + h;
  }
  const bool tracking = hasTracking(joined);
  const std::size_t v = header.size() - resultColumnCount(joined);  // the verdict column
  for (std::size_t c = 0; c < v; ++c)
  {
    if (!isNumber(cells[c]))
    {
      bad("'" + header[c] + "' is not a number");
    }
  }
  static const char* const verdicts[] = {"limit_cycle", "converged", "irregular_oscillation", "diverged", "undecided"};
  if (std::find(std::begin(verdicts), std::end(verdicts), cells[v]) == std::end(verdicts))
  {
    bad("unknown verdict '" + cells[v] + "'");
  }
  for (std::size_t c : {v + 1, v + 6})
  {
    if (cells[c] != "0" && cells[c] != "1")
    {
      bad("'" + header[c] + "' is not 0 or 1");
    }
  }
  for (std::size_t c : {v + 2, v + 3, v + 4, v + 5})
  {
    if (!isNumber(cells[c]))
    {
      bad("'" + header[c] + "' is not a number");
    }
  }
  if (cells[v + 4].find_first_not_of("0123456789") != std::string::npos)
  {
    bad("'impacts' is not a whole number");
  }
  const bool converged = cells[v] == "converged";
  if (converged ? !cells[v + 7].empty() && !isNumber(cells[v + 7]) : !cells[v + 7].empty())
  {
    bad("'steady_error' must be a number or empty for a converged point and empty otherwise");
  }
  if (cells[v + 8].empty() || cells[v + 8].find_first_not_of("0123456789") != std::string::npos)
  {
    bad("'maxima_per_period' is not a whole number");
  }
  const bool oscillating = cells[v + 1] == "1";
  for (std::size_t c : {v + 9, v + 10})
  {
    if (oscillating ? !isNumber(cells[c]) : !cells[c].empty())
    {
      bad("'" + header[c] + "' must be a number for an oscillating point and empty otherwise");
    }
  }
  const bool counted = !cells[v + 11].empty();
  if (counted ? !oscillating || !isNumber(cells[v + 11]) || (cells[v + 12] != "0" && cells[v + 12] != "1")
              : !cells[v + 12].empty())
  {
    bad("'peak_to_peak_counts' and 'below_resolution' must be a number and 0/1 for an oscillating point read "
        "through an encoder, and empty otherwise");
  }
  if (tracking)
  {
    if (!isNumber(cells[v + 13]))
    {
      bad("'settling_band' is not a number");
    }
    for (std::size_t c : {v + 14, v + 15})
    {
      if (!cells[c].empty() && !isNumber(cells[c]))
      {
        bad("'" + header[c] + "' is neither a number nor empty");
      }
    }
  }
}

/**
 * The merged rows must enumerate the grid in its order (last axis fastest): each axis' values are those of its
 * column in order of first appearance, their product must be the grid's size, and row i must hold point i. Catches
 * swapped, repeated or altered parameter values.
 */
void checkGridOrder(const std::vector<const std::string*>& rows, std::size_t axes, std::size_t total)
{
  std::vector<std::vector<std::string>> values(axes);
  std::vector<std::vector<std::string>> cells;
  cells.reserve(rows.size());
  for (const std::string* row : rows)
  {
    cells.push_back(splitCsvCells(*row));
    for (std::size_t a = 0; a < axes; ++a)
    {
      if (std::find(values[a].begin(), values[a].end(), cells.back()[a]) == values[a].end())
      {
        values[a].push_back(cells.back()[a]);
      }
    }
  }
  double product = 1.0;
  for (const auto& v : values)
  {
    product *= static_cast<double>(v.size());
  }
  if (product != static_cast<double>(total))
  {
    throw ConfigError("--merge: the parts' parameter columns do not form a grid of " + std::to_string(total) +
                      " points (altered or foreign rows)");
  }
  for (std::size_t i = 0; i < cells.size(); ++i)
  {
    std::size_t index = i;
    for (std::size_t a = axes; a-- > 0;)
    {
      if (cells[i][a] != values[a][index % values[a].size()])
      {
        throw ConfigError("--merge: row " + std::to_string(i + 1) + " is not point " + std::to_string(i + 1) +
                          " of the grid (rows swapped or altered)");
      }
      index /= values[a].size();
    }
  }
}
}  // namespace

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
    const std::string content = readRegularFile("--merge", path, kMaxSweepFileBytes);
    std::stringstream ss(content);
    std::string line;
    std::getline(ss, line);
    Part p;
    p.path = path;
    char grid[64] = {0};
    unsigned long long k, n, first, last, total;
    char tail = 0;
    if (std::sscanf(line.c_str(), "# backlash_sweep part %llu/%llu: points [%llu, %llu) of %llu, grid %63s%c", &k, &n,
                    &first, &last, &total, grid, &tail) != 6 ||
        k < 1 || k > n || n > 100000 || total > 1000000000000ull)
    {
      throw ConfigError("--merge: '" + path + "' is not a part of a sharded sweep (no valid part line)");
    }
    const SweepShard expected = shardOf(k, n, total);
    if (first != expected.first || last != expected.last)
    {
      throw ConfigError("--merge: '" + path + "': part " + std::to_string(k) + "/" + std::to_string(n) + " of " +
                        std::to_string(total) + " points holds points [" + std::to_string(expected.first) + ", " +
                        std::to_string(expected.last) + "), not [" + std::to_string(first) + ", " +
                        std::to_string(last) + ") (a damaged part line)");
    }
    p.k = k, p.n = n, p.first = first, p.last = last, p.total = total, p.grid = grid;
    std::getline(ss, line);
    if (!isSweepHeader(line) || (!header.empty() && line != header))
    {
      throw ConfigError("--merge: '" + path + "' has no sweep CSV header, or another grid's");
    }
    header = line;
    const std::vector<std::string> columns = splitCsvCells(header);
    while (std::getline(ss, line))
    {
      const bool complete = ss.good() || (!content.empty() && content.back() == '\n');
      if (!complete)
      {
        break;  // torn last line: the part is then short, reported below
      }
      if (p.rows.size() == p.last - p.first)
      {
        throw ConfigError("--merge: part " + std::to_string(p.k) + "/" + std::to_string(p.n) + " ('" + path +
                          "') has more than its " + std::to_string(p.last - p.first) + " rows");
      }
      checkRow(line, columns, "--merge: '" + path + "' row " + std::to_string(p.rows.size() + 1));
      p.rows.push_back(line);
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
  std::vector<const std::string*> rows;
  std::string out = header + "\n";
  for (std::size_t k = 1; k <= ref.n; ++k)
  {
    for (const std::string& row : by_k[k]->rows)
    {
      rows.push_back(&row);
      out += row + "\n";
    }
  }
  const std::string drawn = DRAWN_SUFFIX;
  const bool draws =
      ref.grid.size() > drawn.size() && ref.grid.compare(ref.grid.size() - drawn.size(), drawn.size(), drawn) == 0;
  if (!draws)  // (a tolerance study's points are draws, not a grid's enumeration)
  {
    checkGridOrder(rows, splitCsvCells(header).size() - resultColumnCount(header), ref.total);
  }
  return out;
}

std::vector<std::string> resumableRows(const std::string& path, const SweepGrid& grid, const SweepShard& shard)
{
  struct stat st;
  if (::stat(path.c_str(), &st) != 0 && errno == ENOENT)
  {
    return {};  // nothing to resume: a fresh start
  }
  const std::string content = readRegularFile("--resume", path, kMaxSweepFileBytes);
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
    checkRow(line, splitCsvCells(header), "--resume: '" + path + "' row " + std::to_string(index + 1));
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
