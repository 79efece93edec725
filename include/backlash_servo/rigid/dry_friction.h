/**
 * @file dry_friction.h
 * @brief Dry (Coulomb) friction and stiction of the motor and the load: the rest / stick / breakaway rule of
 *        docs/model.md Part 2, and the folding of the kinetic friction of sliding bodies into the constant
 *        inputs of the linear modes. No ROS dependency.
 *
 * A sliding body gets the constant torque \f$ -T_c\,\mathrm{sign}(\omega) \f$; between events its sign does not change
 * (the velocity reaching zero is an event), so every mode stays linear with constant input:
 * \f[ J_m\dot\omega_m = T_m - f_m\omega_m - s_m T_{cm} - \rho Q,\qquad
 *     J_L\dot\omega_c = Q - f_L\omega_c - s_L T_{cL} + T_{ext} \f]
 * i.e. the motor law's constant part a becomes \f$ a - s_m T_{cm} \f$ and the load torque \f$ T_{ext} - s_L T_{cL}
 * \f$ (foldKineticFriction()). A body at rest stays while the torque that holds it is within its static band.
 */
#pragma once

#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"

namespace backlash_servo
{
/// How a body moves from now: stuck (0) or sliding in direction +1 / −1.
using Slide = int;

/// The mode chosen at an instant where a body is at rest.
struct RestDecision
{
  Contact contact = Contact::Apart;  ///< wall the teeth press (the pair moves or sticks as one), or Apart
  Slide motor = 0;                   ///< motor: 0 stuck, ±1 sliding direction (sign of ω_m when it moves)
  Slide load = 0;                    ///< load: 0 stuck, ±1 sliding direction (sign of ω_c when it moves)
};

/// A body at rest under the applied torque `torque` [N·m] with static band `static_friction` [N·m]: stuck (0) while
/// |torque| ≤ static_friction, else it breaks away in the direction of the torque.
Slide restSlide(double torque, double static_friction);

/// Direction of a body with velocity v [rad/s]: sign(v), or `at_rest` when v = 0.
inline Slide slideOf(double v, Slide at_rest)
{
  return v > 0.0 ? 1 : v < 0.0 ? -1 : at_rest;
}

/**
 * The rest rule (docs/model.md Part 2, "Rest, stick and breakaway") at state s with motor torque T_m = motor_torque
 * [N·m]; bodies with non-zero velocity keep sliding in the direction of their velocity.
 * 1. Apart (Q = 0): each body at rest on its own (motor under T_m, load under T_ext). If the teeth do not touch a
 *    wall (s.contact == Apart) or the resulting relative acceleration does not drive them into the wall they touch,
 *    that is the answer (contact Apart).
 * 2. Else the pair presses: one body at the load shaft with applied torque \f$ A = \rho T_m + \rho^2 T_{ext} \f$ and
 *    static capacity \f$ S = \rho T_{sm} + \rho^2 T_{sL} \f$; stuck while |A| ≤ S, else sliding in the direction of A
 *    — unless its mesh torque with kinetic friction would pull off the wall, when the bodies break away separately.
 * With Δ = 0 the wall is the one the relative acceleration drives into.
 */
RestDecision decideAtRest(const ServoParams& p, double motor_torque, const State& s);

/**
 * Parameters and motor law with the kinetic friction of sliding bodies folded into the constant inputs (see the
 * file comment): a' = a − motor·T_cm, T_ext' = T_ext − load·T_cL, and no dry friction left in *folded_params (the
 * linear modes do not know it). motor/load: the slide directions (0: the body is not sliding, nothing folded).
 */
void foldKineticFriction(const ServoParams& p, const MotorInput& law, Slide motor, Slide load,
                         ServoParams* folded_params, MotorInput* folded_law);

}  // namespace backlash_servo
