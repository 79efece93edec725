/**
 * @file recording.h
 * @brief A recording of the joint as plain data: sample times [s], the motor torque held over each sample [N·m]
 *        and both shafts' angles [rad]. Read from CSV or bags by the tools; identified by identification/ with
 *        the settings below.
 */
#pragma once

#include <cmath>
#include <vector>

namespace backlash_servo
{
/// A recording of the joint (SI): equal lengths, uniform time steps.
struct Recording
{
  std::vector<double> time;            ///< t_k [s]
  std::vector<double> motor_torque;    ///< u_k [N·m], held over [t_k, t_{k+1})
  std::vector<double> motor_position;  ///< θ_m [rad] on the motor shaft
  std::vector<double> load_position;   ///< θ_c [rad] on the load shaft
};

/// How a recording is read: the known gear ratio and what tells contact, rest and a phase apart in it (SI).
struct IdentificationSettings
{
  double gear_ratio = 1.0;  ///< ρ [-] (known)
  double contact_band = 0.0;  ///< [rad]; 0 = 1e-8 Δ̂ (noise-free data: a contact keeps the gap to rounding, a chatter of
                              ///< short flights does not) — give the encoders' resolution for measured data
  double still_speed = 0.0;  ///< [rad/s]; 0 = 1e-6 of the largest motor speed
  /// r [samples]: every term filtered by the centred mean over 2r + 1 samples, twice, before the fits (quantised or
  /// noisy angles); a sample then needs its phase over 4r + 5 samples. 0: none (exact data).
  int smoothing = 0;
  /// [N·m]: used when the contact motion goes one way only (a limit cycle pushed from one side, say), where the
  /// Coulomb friction and the load torque cannot be told apart; NaN: none (such a recording is then refused).
  double load_torque_fallback = NAN;
  /// J_m, J_L [kg·m²] known (stated in the prior and not fitted): on measured angles each holds its column of the
  /// bodies' equations, so the other inertia follows from the pair's sum; NaN: estimated.
  double known_motor_inertia = NAN, known_load_inertia = NAN;
  /// Measured angles without a smoothing given: the bodies' equations integrated twice over stretches of one phase
  /// (no derivative of an angle; errors in the angles corrected for) instead of differentiated after the filter.
  bool integrated = false;
  /// The encoders' resolutions N_m, N_L [counts/rev] when stated (0: unknown): tried first when the angles' count
  /// grids are recognised (measured_angles.h).
  double motor_encoder_resolution = 0.0, load_encoder_resolution = 0.0;
};
}  // namespace backlash_servo
