#include "backlash_servo/studies/monte_carlo.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <sstream>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/model/params.h"

namespace backlash_servo
{
namespace
{
/// SplitMix64's finaliser: a well-mixed 64-bit value of x.
std::uint64_t mix64(std::uint64_t x)
{
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// A uniform in (0, 1) from a 64-bit value (53 bits, never 0 or 1).
double unitOpen(std::uint64_t bits)
{
  return (static_cast<double>(bits >> 11) + 0.5) * 0x1p-53;
}

/// The key's name as a number (FNV-1a): what makes two keys' draws of one point independent.
std::uint64_t keyHash(const std::string& key)
{
  std::uint64_t h = 1469598103934665603ull;
  for (char c : key)
  {
    h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  }
  return h;
}

const char* kindName(Distribution::Kind k)
{
  switch (k)
  {
    case Distribution::Kind::Uniform:
      return "uniform";
    case Distribution::Kind::Normal:
      return "normal";
    case Distribution::Kind::LogNormal:
      return "lognormal";
  }
  return "";
}

/// Wilson's 95 % interval of k successes in n trials.
void wilson(std::size_t k, std::size_t n, double* low, double* high)
{
  const double z = 1.959963984540054, p = static_cast<double>(k) / static_cast<double>(n), nn = static_cast<double>(n);
  const double centre = (p + z * z / (2.0 * nn)) / (1.0 + z * z / nn);
  const double half = z * std::sqrt(p * (1.0 - p) / nn + z * z / (4.0 * nn * nn)) / (1.0 + z * z / nn);
  *low = std::max(0.0, centre - half);
  *high = std::min(1.0, centre + half);
}

/// The q-quantile of sorted values (linear between order statistics); NaN when empty.
double quantile(const std::vector<double>& sorted, double q)
{
  if (sorted.empty())
  {
    return NAN;
  }
  const double at = q * static_cast<double>(sorted.size() - 1);
  const std::size_t i = static_cast<std::size_t>(std::floor(at));
  const double f = at - static_cast<double>(i);
  return i + 1 < sorted.size() ? sorted[i] * (1.0 - f) + sorted[i + 1] * f : sorted[i];
}

/// Mid-ranks of v (ties share their mean rank), 1-based.
std::vector<double> ranks(const std::vector<double>& v)
{
  std::vector<std::size_t> order(v.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return v[a] < v[b]; });
  std::vector<double> r(v.size());
  for (std::size_t i = 0; i < order.size();)
  {
    std::size_t j = i;
    while (j + 1 < order.size() && v[order[j + 1]] == v[order[i]])
    {
      ++j;
    }
    for (std::size_t k = i; k <= j; ++k)
    {
      r[order[k]] = 0.5 * static_cast<double>(i + j) + 1.0;
    }
    i = j + 1;
  }
  return r;
}

/// Pearson's correlation of x and y; NaN when either is constant.
double correlation(const std::vector<double>& x, const std::vector<double>& y)
{
  const double n = static_cast<double>(x.size());
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n, my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i)
  {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxx > 0.0 && syy > 0.0 ? sxy / std::sqrt(sxx * syy) : NAN;
}

/// The best one-split rule of `hunts` by x: every threshold between distinct sorted values, both directions.
void bestSplit(const std::vector<double>& x, const std::vector<double>& hunts, KeyInfluence* out)
{
  std::vector<std::size_t> order(x.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return x[a] < x[b]; });
  const double total = std::accumulate(hunts.begin(), hunts.end(), 0.0), n = static_cast<double>(x.size());
  // Rule "hunts above": right = hunters at or below the split counted as settling, plus hunters above.
  double hunters_below = 0.0;
  out->accuracy = std::max(total, n - total) / n;  // no split: call every joint the commoner verdict
  out->threshold = NAN;
  for (std::size_t i = 0; i + 1 < order.size(); ++i)
  {
    hunters_below += hunts[order[i]];
    if (x[order[i]] == x[order[i + 1]])
    {
      continue;
    }
    const double below = static_cast<double>(i + 1);
    const double above_right = (below - hunters_below) + (total - hunters_below);  // settle below, hunt above
    const double below_right = hunters_below + ((n - below) - (total - hunters_below));
    const double best = std::max(above_right, below_right) / n;
    if (best > out->accuracy)
    {
      out->accuracy = best;
      out->threshold = 0.5 * (x[order[i]] + x[order[i + 1]]);
      out->above = above_right >= below_right;
    }
  }
}

std::string shortNumber(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string percent(double f)
{
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f %%", 100.0 * f);
  return buf;
}
}  // namespace

std::string Distribution::text() const
{
  return std::string(kindName(kind)) + "(" + formatNumber(a) + "," + formatNumber(b) + ")";
}

bool isDistributionText(const std::string& text)
{
  for (const char* name : {"uniform(", "normal(", "lognormal("})
  {
    if (text.rfind(name, 0) == 0)
    {
      return true;
    }
  }
  return false;
}

Distribution parseDistribution(const std::string& key, const std::string& text)
{
  const ParamSpec* spec = findParam(key);
  const std::string where = flagName(key) + " '" + text + "'";
  if (spec == nullptr || spec->type != ParamType::Real)
  {
    throw ConfigError(where + ": only a numeric parameter can be drawn from a distribution");
  }
  Distribution d;
  d.key = key;
  const std::size_t open = text.find('(');
  const std::string name = text.substr(0, open);
  if (name == "uniform")
  {
    d.kind = Distribution::Kind::Uniform;
  }
  else if (name == "normal")
  {
    d.kind = Distribution::Kind::Normal;
  }
  else if (name == "lognormal")
  {
    d.kind = Distribution::Kind::LogNormal;
  }
  else
  {
    throw ConfigError(where + ": expected uniform(a,b), normal(mean,sigma) or lognormal(mu,sigma)");
  }
  if (open == std::string::npos || text.back() != ')')
  {
    throw ConfigError(where + ": expected " + name + "(a,b)");
  }
  std::vector<std::string> args = splitCsvCells(text.substr(open + 1, text.size() - open - 2));
  for (std::string& arg : args)  // (spaces after the comma, as YAML writers put them)
  {
    arg.erase(0, arg.find_first_not_of(' '));
    arg.erase(arg.find_last_not_of(' ') + 1);
  }
  KeyValues kv;
  auto number = [&](const std::string& s) {
    kv.set(key, s);
    return kv.number(key);
  };
  if (args.size() != 2)
  {
    throw ConfigError(where + ": expected two numbers in the parentheses");
  }
  try
  {
    d.a = number(args[0]);
    d.b = number(args[1]);
  }
  catch (const std::exception&)
  {
    throw ConfigError(where + ": its parameters must be finite numbers");
  }
  if (d.kind == Distribution::Kind::Uniform)
  {
    if (!(d.b >= d.a))
    {
      throw ConfigError(where + ": uniform(a,b) needs b >= a");
    }
    try
    {
      spec->check(d.a);
      spec->check(d.b);
    }
    catch (const std::exception& e)
    {
      throw ConfigError(where + ": reaches outside the key's range (" + e.what() + ")");
    }
  }
  else if (!(d.b > 0.0))
  {
    throw ConfigError(where + ": sigma must be > 0");
  }
  return d;
}

double drawValue(const Distribution& d, std::uint64_t seed, std::size_t index)
{
  const ParamSpec& spec = param(d.key);
  const std::uint64_t base = mix64(mix64(seed ^ keyHash(d.key)) ^ static_cast<std::uint64_t>(index));
  for (std::uint64_t attempt = 0; attempt < 1000; ++attempt)
  {
    const std::uint64_t r1 = mix64(base + 2 * attempt), r2 = mix64(base + 2 * attempt + 1);
    double v = 0.0;
    if (d.kind == Distribution::Kind::Uniform)
    {
      v = d.a + (d.b - d.a) * unitOpen(r1);
    }
    else
    {
      // Box–Muller: a standard normal from two uniforms.
      const double z = std::sqrt(-2.0 * std::log(unitOpen(r1))) * std::cos(2.0 * PI * unitOpen(r2));
      v = d.kind == Distribution::Kind::Normal ? d.a + d.b * z : std::exp(d.a + d.b * z);
    }
    try
    {
      spec.check(v);
      return v;
    }
    catch (const std::exception&)
    {
      // outside the key's range: truncated, drawn again
    }
  }
  throw ConfigError(flagName(d.key) + " '" + d.text() + "': 1000 draws in a row fell outside the key's range");
}

MonteCarloSummary summarizeBatch(const std::string& csv, const std::vector<std::string>& drawn)
{
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = splitCsvCells(line);
  const auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end())
    {
      throw ConfigError("the sweep CSV has no column '" + name + "'");
    }
    return static_cast<std::size_t>(it - header.begin());
  };
  const std::size_t verdict = column("verdict"), p2p = column("peak_to_peak"), period = column("period");
  const auto below = std::find(header.begin(), header.end(), "below_resolution");
  std::vector<std::size_t> keys;
  for (const std::string& k : drawn)
  {
    keys.push_back(column(k));
  }
  MonteCarloSummary s;
  std::map<std::string, std::size_t> counts;
  std::vector<double> hunts, sizes, periods;
  std::vector<std::vector<double>> values(keys.size());
  while (std::getline(in, line))
  {
    const std::vector<std::string> cells = splitCsvCells(line);
    if (cells.size() != header.size())
    {
      continue;
    }
    ++s.joints;
    ++counts[cells[verdict]];
    const bool hunting = cells[verdict] == "limit_cycle" || cells[verdict] == "irregular_oscillation";
    hunts.push_back(hunting ? 1.0 : 0.0);
    if (hunting)
    {
      s.below_resolution += below != header.end() && cells[static_cast<std::size_t>(below - header.begin())] == "1";
      sizes.push_back(std::stod(cells[p2p]));
      periods.push_back(std::stod(cells[period]));
    }
    for (std::size_t k = 0; k < keys.size(); ++k)
    {
      values[k].push_back(std::stod(cells[keys[k]]));
    }
  }
  if (s.joints == 0)
  {
    return s;
  }
  for (const auto& c : counts)
  {
    MonteCarloSummary::Share share;
    share.verdict = c.first;
    share.count = c.second;
    share.fraction = static_cast<double>(c.second) / static_cast<double>(s.joints);
    wilson(c.second, s.joints, &share.low, &share.high);
    s.verdicts.push_back(share);
  }
  s.hunting = sizes.size();
  std::sort(sizes.begin(), sizes.end());
  std::sort(periods.begin(), periods.end());
  s.quantile_levels = {0.05, 0.25, 0.5, 0.75, 0.95};
  for (double q : s.quantile_levels)
  {
    s.peak_to_peak_quantiles.push_back(quantile(sizes, q));
    s.period_quantiles.push_back(quantile(periods, q));
  }
  for (std::size_t k = 0; k < keys.size(); ++k)
  {
    KeyInfluence in_k;
    in_k.key = drawn[k];
    in_k.rank_correlation = correlation(ranks(values[k]), ranks(hunts));
    bestSplit(values[k], hunts, &in_k);
    s.influences.push_back(in_k);
  }
  std::stable_sort(s.influences.begin(), s.influences.end(), [](const KeyInfluence& a, const KeyInfluence& b) {
    const double x = std::isnan(a.rank_correlation) ? -1.0 : std::fabs(a.rank_correlation);
    const double y = std::isnan(b.rank_correlation) ? -1.0 : std::fabs(b.rank_correlation);
    return x > y;
  });
  return s;
}

std::string summaryText(const MonteCarloSummary& s)
{
  std::ostringstream out;
  out << "batch of " << s.joints << " joints (95 % intervals: Wilson)\n";
  for (const MonteCarloSummary::Share& v : s.verdicts)
  {
    char buf[160];
    std::snprintf(buf, sizeof buf, "  %-22s %6zu  %7s  [%s, %s]\n", v.verdict.c_str(), v.count,
                  percent(v.fraction).c_str(), percent(v.low).c_str(), percent(v.high).c_str());
    out << buf;
  }
  if (s.hunting > 0)
  {
    out << "hunting joints (" << s.hunting
        << (s.below_resolution > 0
                ? ", " + std::to_string(s.below_resolution) + " of them below one count of the loop's encoder"
                : std::string())
        << "), quantiles 5 / 25 / 50 / 75 / 95 %:\n  peak to peak [rad]:";
    for (double q : s.peak_to_peak_quantiles)
    {
      out << " " << shortNumber(q);
    }
    out << "\n  period [s]:";
    for (double q : s.period_quantiles)
    {
      out << " " << shortNumber(q);
    }
    out << "\n";
  }
  if (s.hunting == 0 || s.hunting == s.joints)
  {
    out << (s.hunting == 0 ? "no joint hunts" : "every joint hunts")
        << ": no drawn key separates hunting from settling\n";
    return out.str();
  }
  out << "what separates hunting from settling (Spearman's rank correlation with hunting; the best one split):\n";
  for (const KeyInfluence& k : s.influences)
  {
    char buf[240];
    if (std::isnan(k.threshold))
    {
      std::snprintf(buf, sizeof buf, "  %-24s rho %+.3f  no split does better than calling every joint alike\n",
                    k.key.c_str(), k.rank_correlation);
    }
    else
    {
      std::snprintf(buf, sizeof buf, "  %-24s rho %+.3f  hunts when %s %s %.6g: right for %s of the batch\n",
                    k.key.c_str(), k.rank_correlation, k.key.c_str(), k.above ? ">" : "<", k.threshold,
                    percent(k.accuracy).c_str());
    }
    out << buf;
  }
  return out.str();
}

}  // namespace backlash_servo
