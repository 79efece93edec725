/**
 * @file measured_angles.h
 * @brief How a recording's angles were measured, recognised from the data: each angle's count grid 2π/N [rad] and
 *        noise σ [rad] (0: exact), and the smoothing r [samples] and contact band [rad] the identification then
 *        uses when they are not given. Exact angles keep the settings as given. The tests (third differences, the
 *        band's half count plus four filtered σ, r the least of 2, 4, … 32 that resolves the flanks):
 *        docs/identification.md, "Measured data: counts and noise". No ROS dependency.
 */
#pragma once

#include <string>

#include "backlash_servo/identification/identification.h"

namespace backlash_servo
{
/// One angle as recognised.
struct AngleMeasurement
{
  double resolution = 0.0;  ///< N [counts/rev] whose grid every sample lies on; 0: none found
  double noise = 0.0;       ///< σ [rad] (quantisation while moving included); 0: exact
  bool measured() const { return resolution > 0.0 || noise > 0.0; }
};

/// The recording's angles as recognised, and the settings they give.
struct MeasuredAngles
{
  AngleMeasurement motor, load;
  int smoothing = 0;          ///< r [samples] chosen (or given)
  double contact_band = 0.0;  ///< [rad] chosen (or given); 0: exact angles (identification.h's default)
  bool from_data = false;     ///< the band (and the smoothing unless given) chosen here
  bool integrated = false;    ///< measured angles, no smoothing given: the equations integrated (identification.h)
  /// One line for a person: each angle's grid and noise, the smoothing and the band.
  std::string summary() const;
};

/// The angle's grid and noise; `stated` [counts/rev] is the encoder's resolution when known (0: unknown).
AngleMeasurement recogniseAngle(const std::vector<double>& angle, double stated);

/**
 * Recognises both angles (the settings' encoder resolutions, when stated, are tried first) and fills what the
 * settings leave to the data when an angle is measured: the contact band when it is not given, and with it the
 * smoothing (the least of 2, 4, … 32 samples at which the band puts the flanks four bands apart) when that is not
 * given either; exact angles keep the settings as given.
 */
MeasuredAngles recogniseMeasurement(const Recording& data, const IdentificationSettings& settings);

}  // namespace backlash_servo
