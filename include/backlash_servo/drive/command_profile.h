/**
 * @file command_profile.h
 * @brief Command profiles beyond a step: the load set-point θ_R(t) [rad] as a sequence of segments.
 *        A digital drive samples θ_R at its instants, so any profile stays exact. No ROS dependency.
 *
 * Segments start at their `time` [s] from the value the profile has there (v₀) and hold their end value until the
 * next segment starts (a later segment cuts an unfinished one):
 * - step:  θ_R = target;
 * - ramp:  θ_R = v₀ + (target − v₀) min(1, (t − time)/D), D = duration, or |target − v₀|/rate;
 * - sine:  θ_R = v₀ + A sin(2π f (t − time)) + a_d sin(2π f_d (t − time)) for t − time < duration, then v₀ (a_d
 *          the optional dither: a small fast sine on top, which keeps a stuck body breaking away);
 * - move:  trapezoidal point-to-point move by `distance` with |velocity| ≤ max_velocity, |acceleration| ≤
 *          max_acceleration (triangular when the distance is too short to cruise);
 * - points: set-points (time, value) held from their time on (e.g. read from a CSV).
 */
#pragma once

#include <string>

#include <utility>
#include <vector>
#include "backlash_servo/model/state.h"

namespace backlash_servo
{
struct ProfileSegment
{
  enum class Kind
  {
    Step,
    Ramp,
    Sine,
    Move,
    Points
  } kind = Kind::Step;
  double time = 0.0;                              ///< start [s]
  double target = 0.0;                            ///< step, ramp: end value [rad]
  double duration = 0.0;                          ///< ramp (or rate), sine [s]
  double rate = 0.0;                              ///< ramp: |dθ_R/dt| [rad/s] when no duration
  double amplitude = 0.0;                         ///< sine [rad]
  double frequency = 0.0;                         ///< sine [Hz]
  double dither_amplitude = 0.0;                  ///< sine: a_d, the dither's amplitude [rad] (0: none)
  double dither_frequency = 0.0;                  ///< sine: f_d, the dither's frequency [Hz]
  double distance = 0.0;                          ///< move [rad]
  double max_velocity = 0.0;                      ///< move [rad/s]
  double max_acceleration = 0.0;                  ///< move [rad/s²]
  std::vector<std::pair<double, double>> points;  ///< points: (time [s], value [rad]), times ascending
};

class CommandProfile
{
 public:
  /// start: θ_R before the first segment [rad]. Throws InvalidParameterError naming the segment and field.
  CommandProfile(double start, std::vector<ProfileSegment> segments);
  /// θ_R(t) [rad].
  double at(double t) const;
  /// The value the profile ends at (after every segment) [rad].
  double finalValue() const;
  /// The time the last segment ends [s] (a sine or move: its end; a step: its time).
  double endTime() const;
  /// Only steps and points: θ_R is piecewise constant.
  bool piecewiseConstant() const;
  /// Steps, points and ramps: θ_R is piecewise linear, which the continuous law takes exactly (module doc).
  bool piecewiseLinear() const;
  /// For a piecewise-linear profile: the piece in force at t [s]: θ_R(t) = at(t) [rad], its slope [rad/s] and the
  /// first instant after t [s] where value or slope may change (+inf: none). Within a sine segment (taken exactly
  /// by the continuous law), `wave` (if given) gets the sine A sin(2πf(t − time)) and its dither a_d sin(2πf_d(t −
  /// time)) [rad], `base` its centre v₀ [rad], and `until` the segment's end; elsewhere wave is empty.
  void pieceAt(double t, double* slope, double* until, Waveform* wave = nullptr, double* base = nullptr) const;
  /// For a piecewise-constant profile: the first instant after t [s] at which θ_R may change (+inf: none).
  double nextChange(double t) const;
  /// Throws InvalidParameterError("profile", …) unless a drive of this kind can take the profile: a digital drive
  /// (sampled) takes any; the continuous law steps, points, — without dry friction (`dry`) — ramps, and sines (exact:
  /// the joint's modes carry the sine and its dither; on rigid teeth (`compliant` false) without dry friction; a
  /// dither only where the modes carry `max_tones` ≥ 2 sines).
  void requireTakenBy(bool sampled, bool dry, bool compliant = false, int max_tones = MAX_TONES) const;
  /// The same profile started dt [s] later (every segment and point time + dt).
  CommandProfile delayed(double dt) const;
  const std::vector<ProfileSegment>& segments() const { return segments_; }

 private:
  /// Segment i evaluated tau [s] after its start, from v0.
  double evaluate(const ProfileSegment& s, double v0, double tau) const;
  double start_;
  std::vector<ProfileSegment> segments_;
};

}  // namespace backlash_servo
