/**
 * @file state.h
 * @brief State of the servo and of its input (no ROS dependency).
 */
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace backlash_servo
{
/// Which side of the backlash the teeth touch. Gap g = θ_c − ρ θ_m: Forward ⇔ g = 0, Backward ⇔ g = Δ.
enum class Contact
{
  Forward,   ///< g = 0: the motor tooth can push the load in +
  Backward,  ///< g = Δ: the motor tooth can push the load in −
  Apart      ///< 0 < g < Δ: teeth floating
};

/// "forward" | "backward" | "apart".
const char* toString(Contact c);
/// Parses "forward", "backward", "apart" or "none"; throws std::invalid_argument otherwise.
Contact contactFromString(const std::string& s);

/// Full mechanical state. Angles on their own shafts.
struct State
{
  double time = 0.0;            ///< simulated time [s]
  double load_position = 0.0;   ///< θ_c [rad]
  double load_velocity = 0.0;   ///< ω_c [rad/s]
  double motor_position = 0.0;  ///< θ_m [rad]
  double motor_velocity = 0.0;  ///< ω_m [rad/s]
  /// Teeth side: for rigid teeth as the gap says; for a compliant mesh (mesh_stiffness > 0) the flank that presses
  /// (Forward: the penetration θ_o − ρθ_m ≤ 0 transmits torque, Backward: θ_o − ρθ_m ≥ Δ), Apart when none does.
  Contact contact = Contact::Forward;
  double shaft_twist = 0.0;       ///< θ_o − θ_c: output gear angle less load angle, torsional shaft only [rad]
  double shaft_twist_rate = 0.0;  ///< ω_o − ω_c, torsional shaft only [rad/s]
};

/// How the motor torque is produced.
enum class ControlMode
{
  Position,  ///< T_m = K (θ_R − θ_c), the servo's own P loop
  Effort     ///< T_m supplied directly by the caller (external controller)
};

/// A sinusoidal torque A sin(ω(t − t₀) + φ) [N·m] (amplitude 0: none).
struct Sinusoid
{
  double amplitude = 0.0;  ///< A [N·m]
  double frequency = 0.0;  ///< ω [rad/s]
  double phase = 0.0;      ///< φ [rad]
  double origin = 0.0;     ///< t₀ [s]
  bool active() const { return amplitude != 0.0; }
  /// The argument ω(t − t₀) + φ [rad] at time t [s].
  double angle(double t) const { return frequency * (t - origin) + phase; }
  double at(double t) const { return amplitude * std::sin(angle(t)); }
};

/// Most sines a Waveform sums (each adds two states to a mode, whose order is at most MAX_MODE_ORDER).
constexpr int MAX_TONES = 2;

/// A sum of sines Σ A_i sin(ω_i(t − t₀,i) + φ_i) [N·m] — a sine and its dither, two test tones; empty: none.
struct Waveform
{
  Waveform() = default;
  /// The single sine s (none if its amplitude is 0).
  Waveform(const Sinusoid& s) { add(s); }  // NOLINT(google-explicit-constructor): a sine is a waveform
  /// Adds the sine s (ignored if its amplitude is 0); throws std::length_error beyond MAX_TONES.
  void add(const Sinusoid& s)
  {
    if (!s.active())
    {
      return;
    }
    if (count >= MAX_TONES)
    {
      throw std::length_error("a waveform sums at most " + std::to_string(MAX_TONES) + " sines");
    }
    tones[static_cast<std::size_t>(count++)] = s;
  }
  bool active() const { return count > 0; }
  double at(double t) const
  {
    double sum = 0.0;
    for (int i = 0; i < count; ++i)
    {
      sum += tones[static_cast<std::size_t>(i)].at(t);
    }
    return sum;
  }
  /// Every amplitude times k.
  Waveform scaled(double k) const
  {
    Waveform w = *this;
    for (int i = 0; i < count; ++i)
    {
      w.tones[static_cast<std::size_t>(i)].amplitude *= k;
    }
    return w;
  }
  std::array<Sinusoid, MAX_TONES> tones{};
  int count = 0;
};

/**
 * The motor torque as an affine function of the load position: \f$ T_m = a - k\,\theta_c \f$, plus an optional
 * sinusoid of time (`wave`: a sine on the command through the continuous law, or a sine torque in effort mode; a
 * compliant mesh only).
 * Position mode: a = K θ_R, k = K. Effort mode: a = u, k = 0.
 */
struct MotorInput
{
  MotorInput() = default;
  MotorInput(double a, double k, const Waveform& w = Waveform()) : offset(a), stiffness(k), wave(w) {}
  double offset = 0.0;     ///< a [N·m]
  double stiffness = 0.0;  ///< k [N·m/rad]
  Waveform wave;           ///< + Σ A_i sin(ω_i(t − t₀,i) + φ_i) [N·m]
  /// a − kθ_c [N·m], the law without its wave.
  double torque(double load_position) const { return offset - stiffness * load_position; }
  /// a − kθ_c + wave(t) [N·m] at time t [s].
  double torque(double load_position, double t) const { return torque(load_position) + wave.at(t); }
};

}  // namespace backlash_servo
