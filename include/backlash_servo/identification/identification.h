/**
 * @file identification.h
 * @brief The joint identified from a recording of its own motion: the start of a fit — backlash, inertias, viscous and
 *        Coulomb friction and the load torque estimated from the data alone, by linear least squares on the phases
 *        where the equations of motion are linear in the parameters. No ROS dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "Initial estimates from a recording".
 */
#pragma once

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/model/recording.h"

namespace backlash_servo
{
/// One estimated quantity.
struct Estimate
{
  double value = 0.0;           ///< [its unit]
  double standard_error = 0.0;  ///< [its unit]; NaN when the data do not inform it
};

struct InitialEstimates
{
  Estimate backlash;                ///< Δ [rad]
  double zero_offset = 0.0;         ///< g₀: the gap the encoders read on the forward flank [rad]
  Estimate motor_inertia;           ///< J_m [kg·m²]
  Estimate load_inertia;            ///< J_L [kg·m²]
  Estimate motor_friction;          ///< f_m [N·m·s/rad]
  Estimate load_friction;           ///< f_L [N·m·s/rad]
  Estimate motor_coulomb_friction;  ///< T_cm [N·m]
  Estimate load_coulomb_friction;   ///< T_cL [N·m]
  Estimate load_torque;             ///< T_ext [N·m]
  /// T_sm [N·m] from the motor's rests with the teeth apart (NaN: none seen; standard error NaN: never seen
  /// breaking away, the value is a lower bound).
  Estimate motor_static_friction{NAN, NAN};
  /// T_sL [N·m] from the pair's rests on a flank, less the motor's share (NaN: no rest of either kind).
  Estimate load_static_friction{NAN, NAN};
  /// A compliant mesh (identify_mesh.h): c [N·m/rad] and d [N·m·s/rad] (NaN: rigid teeth, not estimated).
  Estimate mesh_stiffness{NAN, NAN};
  Estimate mesh_damping{NAN, NAN};
  bool load_torque_given = false;  ///< contact motion one way only: the load torque was the settings' (not estimated)
  /// Measured angles: the phases were read at the load's count edges (the gap did not resolve the free play).
  bool phases_from_edges = false;
  /// Keys the recording does not inform, with the reason (their estimates NaN).
  std::map<std::string, std::string> not_identifiable;
  std::size_t contact_samples = 0, apart_samples = 0;
  double contact_rms_residual = 0.0;  ///< [N·m]
  double apart_rms_residual = 0.0;    ///< [N·m]

  /// The estimates by parameter key (backlash, motor_inertia, …, load_torque; the mesh's when estimated).
  std::map<std::string, Estimate> byKey() const;
};

/// A body's motion from its recorded angle: the angle filtered by F (smoothing r), velocity and acceleration by central
/// differences [rad, rad/s, rad/s²] (0 at the ends) and F sgn ω [-].
struct BodyMotion
{
  std::vector<double> angle, velocity, acceleration, sign;
};

/// Checks the recording (at least 50 samples, equal columns, finite values, uniform increasing times, a known gear
/// ratio, a smoothing that fits) and returns its sample period h [s]; throws InvalidParameterError naming what is
/// wrong.
double samplePeriod(const Recording& data, const IdentificationSettings& settings);

/// The body's filtered angle and its differences (sample period h [s], smoothing r [samples]).
BodyMotion differentiate(const std::vector<double>& angle, double h, int smoothing);

/// ū_k = (u_{k−1} + u_k)/2 filtered by F [N·m]: the torque the second difference at sample k averages.
std::vector<double> meanTorque(const Recording& data, int smoothing);

/// The joint `joint` with the estimates in place (keys of the parameter table; NaN values skipped): levels bounded
/// below by 0 (friction, the mesh's coefficients) that came out below it are 0 within their scatter, and each body's
/// static friction is at least its Coulomb level.
ServoParams withEstimates(ServoParams joint, const std::map<std::string, Estimate>& estimates);

/// Bounds on a static friction level from rests: the largest net torque that held the body [N·m] (−1: no rest) and
/// the smallest that broke it away (∞: never seen breaking away).
struct RestBounds
{
  double low = -1.0, high = INFINITY;
  /// The level: the middle of [low, high] with the standard error of a uniform spread over it; {low, NaN} when it
  /// never broke away (a lower bound); NaN when there was no rest or the bounds cross (noise, not friction).
  Estimate level() const;
};

/// The smoothing filter F of `IdentificationSettings::smoothing` r: the centred mean over 2r + 1 samples, twice (a
/// triangle 4r + 1 samples wide); the samples within 2r of an end keep their values (they are never used).
std::vector<double> smoothedSignal(const std::vector<double>& x, int r);

/// The fewest samples a rest lasts [samples] at sample period h [s]: 10, at least the smoothing's support 4r + 5,
/// and with measured data (a contact band given) 0.2 s — a reversal at acceleration α stays within the band for
/// 2√(2 band/α), so only α ≤ 8 band/(0.2 s)² passes for a rest (its torque J α is then far below the friction levels).
std::size_t minimumRest(const IdentificationSettings& settings, double h);

/// The gap on each flank [rad].
struct Flanks
{
  double forward = 0.0, backward = 0.0;
};

/**
 * Where the gap dwells at each end of its range. Exact angles (band 0): its extremes. Measured ones (without the
 * `edge` samples at each end, the filter's): from each end of the sorted gaps, the first place where at least
 * max(20, n/1000) samples lie within twice the band [rad] (a few samples beyond a flank — noise, an impact's
 * overshoot — are passed over), refined to the median of those samples.
 */
Flanks locateFlanks(const std::vector<double>& gap, std::size_t edge, double band);

/// A gain K [N·m/rad] for replaying a joint whose loop is not known: a replay drives it by the recorded torque (the
/// gain acts nowhere), but the simulator checks the envelope with it — ω_n = max(1 rad/s, 2F/J) keeps ζ ≤ 1/4.
double replayGain(const ServoParams& joint);

/**
 * The initial estimates from the recording. Throws InvalidParameterError naming what is missing: too few samples,
 * non-uniform or non-increasing times, non-finite values, a recording that never touches both flanks (no backlash
 * to measure: reversals that cross it are needed), or too few samples in contact or apart to fit (each phase needs
 * motion in both directions).
 */
InitialEstimates estimateInitial(const Recording& data, const IdentificationSettings& settings);

/**
 * An experiment that informs the initial estimates, as a command profile for the position loop (the node and
 * backlash_sim replay it): three sines of the command about its start θ₀, one after the other, each a third of
 * `duration` [s], amplitude `travel` [rad] (the largest excursion allowed; at least 3Δ so that every reversal carries
 * the motor across the free play) at ω_n/8, ω_n/3 and (half the amplitude) ω_n/1.5, ω_n the loop's natural frequency
 * under the P gain K (params.naturalFrequency()). The slow sine moves the joint in contact both ways at low
 * acceleration (viscous and Coulomb friction, the load torque); the faster ones accelerate it (the inertias); every
 * reversal crosses the backlash (Δ, and the motor alone while the teeth are apart). A dither (`dither_amplitude`
 * a_d [rad] at `dither_frequency` f_d [Hz], 0: none) rides on every sine: a torque K a_d oscillating faster than the
 * loop follows keeps a body from sticking at the slow reversals (stick-slip hides the Coulomb level) — at the price
 * of the rests the static levels come from. Throws InvalidParameterError for a duration ≤ 0, a travel below 3Δ, or
 * a dither amplitude < 0 or without a frequency > 0.
 */
std::vector<ProfileSegment> identificationExperiment(const ServoParams& params, double duration, double travel,
                                                     double dither_amplitude = 0.0, double dither_frequency = 0.0);

}  // namespace backlash_servo
