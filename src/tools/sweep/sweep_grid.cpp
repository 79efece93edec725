#include "sweep_grid.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "backlash_servo/config/key_values.h"

namespace backlash_servo
{
ServoParams SweepPoint::params() const
{
  ChartParams ch;
  ch.zeta = zeta;
  ch.inertia_ratio = inertia_ratio;
  ch.friction_ratio = friction_ratio;
  ch.restitution = restitution;
  ch.backlash = backlash;
  return ch.toServoParams();
}

std::string SweepPoint::columns() const
{
  char buf[160];
  std::snprintf(buf, sizeof buf, "%.10g,%.10g,%.10g,%.10g,%.10g", zeta, inertia_ratio, friction_ratio, restitution,
                backlash);
  return buf;
}

const std::array<const char*, SweepGrid::AXES>& SweepGrid::keys()
{
  static const std::array<const char*, AXES> k = {"zeta", "inertia_ratio", "friction_ratio", "restitution", "backlash"};
  return k;
}

SweepGrid::SweepGrid() : axes_{{{0.4}, {9.0}, {0.4}, {1.0}, {0.3}}} {}

SweepGrid SweepGrid::thesis()
{
  SweepGrid g;
  g.axes_[0] = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0};
  g.axes_[1] = {0.04, 0.1, 1.0 / 9.0, 0.25, 1.0, 4.0, 9.0};
  g.axes_[2] = {0.0, 0.2, 0.4, 0.6, 0.8, 1.0};
  g.axes_[3] = {0.0, 0.6, 0.8, 1.0};
  g.axes_[4] = {0.3};
  return g;
}

void SweepGrid::setAxis(const std::string& key, std::vector<double> values)
{
  for (int i = 0; i < AXES; ++i)
  {
    if (key == keys()[i])
    {
      if (values.empty())
      {
        throw std::invalid_argument(key + ": no values");
      }
      axes_[i] = std::move(values);
      return;
    }
  }
  throw std::invalid_argument("'" + key + "' is not an axis of the sweep");
}

std::size_t SweepGrid::size() const
{
  double n = 1.0;
  for (const auto& a : axes_)
  {
    n *= static_cast<double>(a.size());
  }
  if (n > MAX_POINTS)
  {
    char buf[120];
    std::snprintf(buf, sizeof buf, "the grid has %.3g points, more than the %.0e a sweep accepts", n, MAX_POINTS);
    throw std::length_error(buf);
  }
  return static_cast<std::size_t>(n);
}

SweepPoint SweepGrid::point(std::size_t index) const
{
  double v[AXES];
  for (int i = AXES - 1; i >= 0; --i)
  {
    v[i] = axes_[i][index % axes_[i].size()];
    index /= axes_[i].size();
  }
  return {v[0], v[1], v[2], v[3], v[4]};
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
  for (const auto& axis : axes_)
  {
    mix(axis.size());
    for (double v : axis)
    {
      std::uint64_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      mix(bits);
    }
  }
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
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
