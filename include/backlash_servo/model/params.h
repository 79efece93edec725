/**
 * @file params.h
 * @brief Physical parameters of the backlash servo (SI units) and their validation.
 *
 * No ROS dependency. See docs/model.md for the model.
 */
#pragma once

#include <stdexcept>
#include <string>

namespace backlash_servo
{
/// Thrown when a parameter is outside its allowed range; the message names the field and the range.
class InvalidParameterError : public std::invalid_argument
{
 public:
  InvalidParameterError(const std::string& field, const std::string& message)
      : std::invalid_argument(field + ": " + message), field_(field)
  {}
  /// Name of the offending field (snake_case, as in YAML and on the command line).
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

/// The validated envelope's derived limits (docs/validation.md, "Validated envelope"); the plain ranges are in
/// param_table.cpp.
constexpr double INERTIA_SPLIT_MIN = 1e-3;      ///< ρ²J_L/J_m [-]
constexpr double INERTIA_SPLIT_MAX = 1e3;       ///< ρ²J_L/J_m [-]
constexpr double NATURAL_FREQUENCY_MIN = 1e-3;  ///< ω_n [rad/s]
constexpr double NATURAL_FREQUENCY_MAX = 1e4;   ///< ω_n [rad/s]
constexpr double DAMPING_RATIO_MAX = 100.0;     ///< ζ [-]
/// A compliant mesh's contact frequency √(c/μ), and a torsional shaft's, at most this many times ω_n [-].
constexpr double COMPLIANT_FREQUENCY_RATIO_MAX = 1e4;
/// A compliant mesh's damping rate d/μ, and a torsional shaft's, at most this many times ω_n [-] (a contact damping
/// ratio far beyond any gear's: a mistyped exponent, whose stiff decay the closed forms follow only slowly).
constexpr double COMPLIANT_DAMPING_RATE_RATIO_MAX = 1e5;

/**
 * @brief Physical parameters of the geared position servo with backlash.
 *
 * Motor torque in position mode: \f$ T_m = K(\theta_R - \theta_c) \f$ (feedback from the load).
 * Rigid mesh: \f$ \theta_c = \rho\,\theta_m + g \f$ with gap \f$ g \in [0, \Delta] \f$.
 */
struct ServoParams
{
  double motor_inertia = 0.1;           ///< J_m, motor inertia on the motor shaft [kg·m²], > 0
  double load_inertia = 0.9;            ///< J_L, load inertia on the load shaft [kg·m²], > 0
  double motor_friction = 0.48;         ///< f_m, viscous friction of the motor [N·m·s/rad], >= 0
  double load_friction = 0.32;          ///< f_L, viscous friction of the load [N·m·s/rad], >= 0
  double gain = 1.0;                    ///< K, servo gain [N·m/rad], > 0
  double gear_ratio = 1.0;              ///< ρ = teeth(gear 1)/teeth(gear 2) [-], > 0; rigid mesh gives θ_c = ρ θ_m
  double backlash = 0.3;                ///< Δ, free play measured at the load shaft [rad], >= 0 (0 = rigid mesh)
  double restitution = 1.0;             ///< e, coefficient of restitution of the tooth impact [-], in [0, 1]
  double load_torque = 0.0;             ///< T_ext, external torque on the load (gravity preload, process load) [N·m]
  double motor_coulomb_friction = 0.0;  ///< T_cm, kinetic dry friction of the sliding motor [N·m], >= 0
  double motor_static_friction = 0.0;   ///< T_sm, breakaway torque of the motor at rest [N·m], >= T_cm
  double load_coulomb_friction = 0.0;   ///< T_cL, kinetic dry friction of the sliding load [N·m], >= 0
  double load_static_friction = 0.0;    ///< T_sL, breakaway torque of the load at rest [N·m], >= T_cL
  // The compliant joint (docs/model.md, "The compliant joint"): mesh_stiffness > 0 replaces the rigid teeth and their
  // impacts by a spring–damper mesh; shaft_stiffness > 0 adds a torsional shaft between the output gear and the load.
  std::string mesh_law = "spring_damper";  ///< spring_damper | msl_elastobacklash: how the mesh torque is formed
  double mesh_stiffness = 0.0;             ///< c, mesh stiffness at the load shaft [N·m/rad], >= 0 (0 = rigid teeth)
  double mesh_damping = 0.0;               ///< d, mesh damping at the load shaft [N·m·s/rad], >= 0
  double gear_inertia = 0.0;               ///< J_g, output gear inertia on the load shaft [kg·m²], >= 0
  double shaft_stiffness = 0.0;            ///< k_s, torsional shaft stiffness [N·m/rad], >= 0 (0 = rigid shaft)
  double shaft_damping = 0.0;              ///< d_s, torsional shaft damping [N·m·s/rad], >= 0

  /// Throws InvalidParameterError naming the first bad field, its value and its allowed range (param_table.h): the
  /// values (validateValues) and the validated envelope (validateEnvelope).
  void validate() const;
  /// Each value in its range, static friction at least the Coulomb level, the compliant joint's keys together.
  void validateValues() const;
  /// The derived quantities inside the validated envelope (docs/validation.md); without `with_gain` only those that
  /// do not involve the gain K (the inertia splits): a joint whose loop is not known, as identification gives it.
  void validateEnvelope(bool with_gain) const;

  /// A compliant mesh (mesh_stiffness > 0) instead of rigid teeth with impacts.
  bool compliant() const { return mesh_stiffness > 0.0; }
  /// A torsional shaft between the output gear and the load (shaft_stiffness > 0).
  bool torsionalShaft() const { return shaft_stiffness > 0.0; }
  /// J = J_m + ρ² (J_L + J_g), inertia of the meshed pair referred to the load shaft [kg·m²].
  double totalInertia() const { return motor_inertia + gear_ratio * gear_ratio * (load_inertia + gear_inertia); }
  /// F_T = f_m + ρ² f_L, total friction referred to the load shaft [N·m·s/rad].
  double totalFriction() const { return motor_friction + gear_ratio * gear_ratio * load_friction; }
  /// ω_n = sqrt(ρK/J), natural frequency of the meshed servo [rad/s].
  double naturalFrequency() const;
  /// ζ = F_T / (2 ω_n J), damping ratio of the meshed servo [-].
  double dampingRatio() const;
  /// Whether any dry friction acts (then bodies can stick; see dry_friction.h).
  bool hasDryFriction() const
  {
    return motor_static_friction > 0.0 || load_static_friction > 0.0 || motor_coulomb_friction > 0.0 ||
           load_coulomb_friction > 0.0;
  }
  /// ρ² J_L / J_m, the thesis' inertia split [-].
  double inertiaRatio() const { return gear_ratio * gear_ratio * load_inertia / motor_inertia; }
  /// ρ² f_L / F_T, the thesis' friction split [-] (0 when F_T = 0).
  double frictionRatio() const;
};

/**
 * @brief The thesis' chart form of the parameters (non-dimensional study of Anderson & Lockett).
 *
 * \f[ J = J_m + \rho^2 J_L,\quad \omega_n^2 = \rho K / J,\quad F_T = 2\zeta\omega_n J,\quad
 *     \rho^2 J_L / J_m = \text{inertia\_ratio},\quad \rho^2 f_L / F_T = \text{friction\_ratio} \f]
 */
struct ChartParams
{
  double zeta = 0.4;                    ///< ζ, damping ratio [-], >= 0
  double natural_frequency = 1.0;       ///< ω_n [rad/s], > 0
  double total_inertia = 1.0;           ///< J = J_m + ρ² J_L [kg·m²], > 0
  double inertia_ratio = 9.0;           ///< ρ² J_L / J_m [-], > 0
  double friction_ratio = 0.4;          ///< ρ² f_L / F_T [-], in [0, 1]
  double gear_ratio = 1.0;              ///< ρ [-], > 0
  double backlash = 0.3;                ///< Δ [rad], >= 0
  double restitution = 1.0;             ///< e [-], in [0, 1]
  double load_torque = 0.0;             ///< T_ext [N·m]
  double motor_coulomb_friction = 0.0;  ///< T_cm [N·m]
  double motor_static_friction = 0.0;   ///< T_sm [N·m]
  double load_coulomb_friction = 0.0;   ///< T_cL [N·m]
  double load_static_friction = 0.0;    ///< T_sL [N·m]

  /// Converts to physical SI parameters; throws InvalidParameterError on bad input.
  ServoParams toServoParams() const;
};

/// Checks that value is finite; throws InvalidParameterError(field, "must be a finite number (got …)") otherwise.
void requireFinite(const std::string& field, double value);

/// Throws InvalidParameterError(field, what) unless ok.
void requireThat(bool ok, const std::string& field, const std::string& what);

/// The shortest decimal text that reads back as the same double ("0.1", "1e-07", "inf", "nan").
std::string formatNumber(double value);

}  // namespace backlash_servo
