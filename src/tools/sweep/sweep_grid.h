// The sweep's grid: five chart-form axes, a point identified by its index (last axis fastest), its parameters.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "backlash_servo/params.h"

namespace backlash_servo
{
/// One point of the chart-form study (ω_n = 1 rad/s, J = 1 kg·m², ρ = 1).
struct SweepPoint
{
  double zeta;            ///< ζ [-]
  double inertia_ratio;   ///< ρ²J_L/J_m [-]
  double friction_ratio;  ///< ρ²f_L/F_T [-]
  double restitution;     ///< e [-]
  double backlash;        ///< Δ [rad]

  /// Physical parameters; throws InvalidParameterError naming the bad one.
  ServoParams params() const;
  /// The CSV's parameter columns ("%.10g" each), as written and read back by --resume.
  std::string columns() const;
};

class SweepGrid
{
 public:
  static constexpr int AXES = 5;
  /// Parameter-table keys of the axes, in column order.
  static const std::array<const char*, AXES>& keys();
  /// Largest grid accepted (points); a bigger one is refused before anything is allocated.
  static constexpr double MAX_POINTS = 1e9;

  /// One value per axis: the thesis' App. D1 case.
  SweepGrid();
  /// The 1961 grid (1344 points).
  static SweepGrid thesis();

  /// Replaces the values of axis `key`; throws std::invalid_argument for an unknown key or no values.
  void setAxis(const std::string& key, std::vector<double> values);
  const std::vector<double>& axis(int i) const { return axes_[i]; }
  /// Number of points; throws std::length_error when above MAX_POINTS.
  std::size_t size() const;
  /// Point `index` in [0, size()): nested loops over the axes in column order, the last axis fastest.
  SweepPoint point(std::size_t index) const;
  /// A fingerprint of the axes' values (FNV-1a over their bits, hex): parts of one grid carry the same.
  std::string fingerprint() const;

 private:
  std::array<std::vector<double>, AXES> axes_;
};

/// Values of an axis flag: a list "0.1,0.2", a range "start:stop:count" or "log:start:stop:count". Throws
/// ConfigError naming the flag.
std::vector<double> parseAxis(const std::string& flag, const std::string& text);

}  // namespace backlash_servo
