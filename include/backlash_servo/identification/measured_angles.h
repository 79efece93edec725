/**
 * @file measured_angles.h
 * @brief How a recording's angles were measured, recognised from the data: each angle's count grid and noise level,
 *        and the smoothing and contact band the identification then uses. No ROS dependency.
 *
 * **Count grid.** An angle whose every sample is a whole number of counts 2π/N [rad] (N the stated resolution, or
 * the one the samples' smallest step gives) is quantised by an N-count encoder.
 *
 * **Noise.** What is not smooth motion: the third difference Δ³θ of a smooth angle is smooth (it follows the jerk),
 * that of white noise of standard deviation σ has standard deviation √20 σ and a lag-one correlation of −3/4. An
 * angle is *measured* when it lies on a count grid or its third differences alternate like noise (lag-one correlation
 * below −0.3); its σ [rad] is 1.4826 × the median |Δ³θ| / √20 over the samples where the angle moves (quantisation
 * while moving counts as noise: a uniform error of one count has σ = 2π/(N√12)). Otherwise the angle is exact (σ 0).
 *
 * **Smoothing** r [samples] (identification.h: the centred mean over 2r + 1 samples, twice) of measured angles: 2 —
 * it classifies the phases and signs the velocity, while the bodies' equations are integrated rather than
 * differentiated (identification.h), so it need not average the noise out of an acceleration; at r = 2 the moving
 * gap's filtered noise falls below a still count's half-width.
 *
 * **Contact band** [rad]: a gap on a flank reads within √3 σ_g of it still (a count's half-width) and within
 * 4σ_g√(2/(3(2r+1))) of it moving (the filter's noise), σ_g = √(σ_c² + ρ²σ_m²) the gap's raw noise.
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
 * settings leave to the data when an angle is measured: the smoothing (2) when neither it nor the band is given, the
 * contact band when it is not given; exact angles keep the settings as given.
 */
MeasuredAngles recogniseMeasurement(const Recording& data, const IdentificationSettings& settings);

}  // namespace backlash_servo
