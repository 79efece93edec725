#include "backlash_servo/studies/sweep_grid.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
namespace
{

bool physicalOnly(const std::string& key)
{
  const ParamSpec* spec = findParam(key);
  return spec != nullptr && spec->section == ParamSection::Servo && !inChartForm(*spec);
}

bool chartOnly(const std::string& key)
{
  const ParamSpec* spec = findParam(key);
  return spec != nullptr && spec->section == ParamSection::Chart;
}
}  // namespace

RunConfig SweepPoint::config() const
{
  KeyValues kv = grid->fixed();
  for (std::size_t i = 0; i < values.size(); ++i)
  {
    kv.setNumber(grid->axes()[i].key, values[i]);
  }
  return runConfigFrom(kv);
}

std::string SweepPoint::columns() const
{
  std::string out;
  char buf[40];
  for (std::size_t i = 0; i < values.size(); ++i)
  {
    std::snprintf(buf, sizeof buf, "%s%.10g", i == 0 ? "" : ",", values[i]);
    out += buf;
  }
  return out;
}

const std::vector<std::string>& SweepGrid::chartAxes()
{
  static const std::vector<std::string> k = {"zeta", "inertia_ratio", "friction_ratio", "restitution", "backlash"};
  return k;
}

SweepGrid::SweepGrid()
    : axes_{{"zeta", {0.4}},
            {"inertia_ratio", {9.0}},
            {"friction_ratio", {0.4}},
            {"restitution", {1.0}},
            {"backlash", {0.3}}},
      given_(5, false)
{
  fixed_.nameKeysAsFlags(true);
}

SweepGrid SweepGrid::thesis()
{
  SweepGrid g;
  g.axes_[0].values = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0};
  g.axes_[1].values = {0.04, 0.1, 1.0 / 9.0, 0.25, 1.0, 4.0, 9.0};
  g.axes_[2].values = {0.0, 0.2, 0.4, 0.6, 0.8, 1.0};
  g.axes_[3].values = {0.0, 0.6, 0.8, 1.0};
  g.axes_[4].values = {0.3};
  return g;
}

void SweepGrid::setAxis(const std::string& key, std::vector<double> values)
{
  const ParamSpec* spec = findParam(key);
  if (spec == nullptr || spec->type != ParamType::Real ||
      !(spec->section == ParamSection::Servo || spec->section == ParamSection::Chart ||
        spec->section == ParamSection::Drive || spec->section == ParamSection::Initial))
  {
    throw ConfigError("'" + key + "' is not a numeric parameter a sweep can vary");
  }
  if (values.empty())
  {
    throw ConfigError(flagName(key) + ": no values");
  }
  for (double v : values)
  {
    spec->check(v);
  }
  bool found = false;
  for (std::size_t i = 0; i < axes_.size(); ++i)
  {
    if (axes_[i].key == key)
    {
      axes_[i].values = std::move(values);
      given_[i] = true;
      found = true;
      break;
    }
  }
  if (!found)
  {
    axes_.push_back({key, std::move(values)});
    given_.push_back(true);
  }
  requireOneForm();
}

void SweepGrid::setFixed(const KeyValues& fixed)
{
  fixed_ = fixed;
  fixed_.nameKeysAsFlags(true);
  requireOneForm();
}

void SweepGrid::requireOneForm()
{
  bool physical = false;
  for (const auto& item : fixed_.keys())
  {
    physical = physical || physicalOnly(item.first);
  }
  for (const SweepAxis& a : axes_)
  {
    physical = physical || physicalOnly(a.key);
  }
  if (!physical)
  {
    return;
  }
  bool chart = false;  // a chart-only key given explicitly (an axis or a shared setting)
  for (std::size_t i = 0; i < axes_.size(); ++i)
  {
    chart = chart || (chartOnly(axes_[i].key) && given_[i]);
  }
  for (const auto& item : fixed_.keys())
  {
    chart = chart || chartOnly(item.first);
  }
  if (chart)
  {
    throw ConfigError(
        "give either physical parameters (--motor-inertia ... --gain) or the chart form (--zeta "
        "--inertia-ratio --friction-ratio ...), not both");
  }
  // The physical form: the chart axes left at their defaults are not parameters of this grid.
  for (std::size_t i = axes_.size(); i-- > 0;)
  {
    if (chartOnly(axes_[i].key) && !given_[i])
    {
      axes_.erase(axes_.begin() + static_cast<long>(i));
      given_.erase(given_.begin() + static_cast<long>(i));
    }
  }
}

void SweepGrid::addDraw(const Distribution& d)
{
  setAxis(d.key, {d.kind == Distribution::Kind::Uniform ? d.a : drawValue(d, seed_, 0)});
  draws_.erase(std::remove_if(draws_.begin(), draws_.end(), [&](const Distribution& o) { return o.key == d.key; }),
               draws_.end());
  draws_.push_back(d);
}

void SweepGrid::setMonteCarlo(std::size_t n, std::uint64_t seed)
{
  draw_count_ = n;
  seed_ = seed;
}

std::string SweepGrid::header() const
{
  std::string h;
  for (const SweepAxis& a : axes_)
  {
    h += a.key + ",";
  }
  return h + resultColumns() + (tracking_ ? "," + trackingColumns() : "");
}

std::size_t SweepGrid::size() const
{
  if (!draws_.empty() || draw_count_ > 0)
  {
    return monteCarloSize();
  }
  double n = 1.0;
  for (const SweepAxis& a : axes_)
  {
    n *= static_cast<double>(a.values.size());
  }
  if (n > MAX_POINTS)
  {
    char buf[120];
    std::snprintf(buf, sizeof buf, "the grid has %.3g points, more than the %.0e a sweep accepts", n, MAX_POINTS);
    throw std::length_error(buf);
  }
  return static_cast<std::size_t>(n);
}

std::size_t SweepGrid::monteCarloSize() const
{
  if (draws_.empty())
  {
    throw ConfigError("--monte-carlo needs a key drawn from a distribution, e.g. --backlash 'uniform(0.002,0.006)'");
  }
  if (draw_count_ == 0)
  {
    throw ConfigError(flagName(draws_.front().key) + " is drawn from " + draws_.front().text() +
                      ": say how many joints with --monte-carlo N");
  }
  for (const SweepAxis& a : axes_)
  {
    if (a.values.size() > 1)
    {
      throw ConfigError("--monte-carlo draws every joint: give " + flagName(a.key) +
                        " one value or a distribution, not " + std::to_string(a.values.size()) + " values");
    }
  }
  if (static_cast<double>(draw_count_) > MAX_POINTS)
  {
    throw std::length_error("--monte-carlo: more than the 1e9 points a sweep accepts");
  }
  return draw_count_;
}

SweepPoint SweepGrid::point(std::size_t index) const
{
  SweepPoint p;
  p.grid = this;
  p.values.resize(axes_.size());
  if (!draws_.empty())
  {
    for (std::size_t i = 0; i < axes_.size(); ++i)
    {
      const auto d =
          std::find_if(draws_.begin(), draws_.end(), [&](const Distribution& x) { return x.key == axes_[i].key; });
      p.values[i] = d != draws_.end() ? drawValue(*d, seed_, index) : axes_[i].values[0];
    }
    return p;
  }
  for (std::size_t i = axes_.size(); i-- > 0;)
  {
    const std::vector<double>& v = axes_[i].values;
    p.values[i] = v[index % v.size()];
    index /= v.size();
  }
  return p;
}

void SweepGrid::requireValidPoints() const
{
  const std::size_t n = size();
  for (std::size_t i = 0; i < n; ++i)
  {
    point(i).config();
  }
}

std::string SweepGrid::fingerprint() const
{
  std::uint64_t h = 1469598103934665603ull;
  auto mix = [&](std::uint64_t v) {
    for (int b = 0; b < 8; ++b)
    {
      h = (h ^ ((v >> (8 * b)) & 0xffu)) * 1099511628211ull;
    }
  };
  auto mixText = [&](const std::string& s) {
    mix(s.size());
    for (char c : s)
    {
      mix(static_cast<unsigned char>(c));
    }
  };
  for (const SweepAxis& axis : axes_)
  {
    mixText(axis.key);
    mix(axis.values.size());
    for (double v : axis.values)
    {
      std::uint64_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      mix(bits);
    }
  }
  for (const auto& item : fixed_.keys())
  {
    mixText(item.first);
    mixText(item.second);
  }
  if (!signature_.empty())
  {
    mixText(signature_);
  }
  for (const Distribution& d : draws_)
  {
    mixText(d.key + "=" + d.text());
  }
  if (!draws_.empty())
  {
    mix(draw_count_);
    mix(seed_);
  }
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return draws_.empty() ? std::string(buf) : std::string(buf) + DRAWN_SUFFIX;
}

const std::string& resultColumns()
{
  static const std::string columns =
      "verdict,limit_cycle,limit_cycle_error,period,impacts,simulated_time,settled,steady_error,maxima_per_period,"
      "peak_to_peak,cycle_centre,peak_to_peak_counts,below_resolution";
  return columns;
}

const std::string& trackingColumns()
{
  static const std::string columns = "settling_band,settling_time,steady_rms_error";
  return columns;
}

bool isAxisText(const std::string& text)
{
  return text.find(',') != std::string::npos || text.find(':') != std::string::npos;
}

std::vector<double> parseAxis(const std::string& flag, const std::string& text)
{
  KeyValues kv;
  auto num = [&](const std::string& s) {
    kv.set(flag, s);
    return kv.number(flag);
  };
  std::vector<std::string> parts;
  std::stringstream ss(text);
  std::string item;
  const char sep = text.find(':') != std::string::npos ? ':' : ',';
  while (std::getline(ss, item, sep))
  {
    parts.push_back(item);
  }
  std::vector<double> values;
  const std::string name = flagName(flag);
  if (sep == ':')
  {
    const bool log = !parts.empty() && parts[0] == "log";
    if (log)
    {
      parts.erase(parts.begin());
    }
    if (parts.size() != 3)
    {
      throw ConfigError(name + ": a range is start:stop:count or log:start:stop:count");
    }
    const double a = num(parts[0]), b = num(parts[1]), n = num(parts[2]);
    if (n < 1 || n != std::floor(n) || n > 1e6)
    {
      throw ConfigError(name + ": count must be a whole number in [1, 1e6]");
    }
    if (log && !(a > 0 && b > 0))
    {
      throw ConfigError(name + ": log ranges need positive ends");
    }
    for (int i = 0; i < static_cast<int>(n); ++i)
    {
      const double f = n == 1 ? 0.0 : i / (n - 1);
      values.push_back(log ? a * std::pow(b / a, f) : a + (b - a) * f);
    }
  }
  else
  {
    for (const std::string& p : parts)
    {
      values.push_back(num(p));
    }
  }
  if (values.empty())
  {
    throw ConfigError(name + ": no values");
  }
  return values;
}

}  // namespace backlash_servo

namespace backlash_servo
{
void addSweepKeys(const KeyValues& keys, SweepGrid* grid)
{
  KeyValues fixed;
  const auto& chart_axes = SweepGrid::chartAxes();
  for (const ParamSpec& spec : parameterTable())  // table order: the order of the axis columns
  {
    const std::string key = spec.key;
    if (!keys.has(key) || key == "max_duration")
    {
      continue;
    }
    const bool chart_axis = std::find(chart_axes.begin(), chart_axes.end(), key) != chart_axes.end();
    if (spec.type == ParamType::Real && isDistributionText(keys.text(key, "")))
    {
      grid->addDraw(parseDistribution(key, keys.text(key, "")));
    }
    else if (spec.type == ParamType::Real && spec.section != ParamSection::Run &&
             (chart_axis || isAxisText(keys.text(key, ""))))
    {
      grid->setAxis(key, parseAxis(key, keys.text(key, "")));
    }
    else if (spec.type == ParamType::Real)
    {
      fixed.setNumber(key, keys.number(key));
    }
    else
    {
      fixed.set(key, keys.text(key, ""));
    }
  }
  grid->setFixed(fixed);
}
}  // namespace backlash_servo
