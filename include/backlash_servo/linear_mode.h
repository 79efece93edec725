/**
 * @file linear_mode.h
 * @brief A linear mode of any order with constant input, ẋ = A x + u, solved in closed form, and the exact location
 *        of the zero crossings of a linear output s(τ) = w·x(τ) + w₀ along it. The home of the modes of higher
 *        order (a compliant mesh couples motor and load into order 4, a torsional shaft into order 6); the rigid
 *        thesis modes keep their hand-written closed forms (modes.h) as the fast special case. No ROS dependency.
 *
 * **Solution.** With z = (x, 1): ż = Ã z, Ã = [[A, u], [0, 0]], so x(τ) = the first n entries of exp(Ã τ) z₀. When
 * Ã has a complete, well-conditioned eigenbasis (cond(V) ≤ MAX_EIGENBASIS_CONDITION) the exponential is evaluated
 * modally, exp(Ã τ) z₀ = V e^{Λτ} V⁻¹ z₀ — a sum of damped sinusoids and exponentials at the mode's own frequencies,
 * at O(n²) per evaluation. Otherwise (a body whose position feeds back nowhere makes A singular and Ã defective:
 * polynomial terms) it is evaluated by Padé scaling and squaring (Eigen's MatrixFunctions), to rounding.
 *
 * **Zero crossings, rigorously.** ẋ obeys the homogeneous equation (ẍ = A ẋ), so on a window [a, a + h]
 *   s(a + t) = s(a) + s'(a) t + R(t),  |R(t)| ≤ ½ M t²,  M = ‖(Dw)ᵀÂ‖₂ ‖D⁻¹ẋ(a)‖₂ e^{‖Â‖₂ h}
 * (s'' = wᵀ A exp(A t) ẋ(a), written in the balanced basis x = D x̂, Â = D⁻¹AD with D a diagonal of powers of 2
 * (Parlett–Reinsch) so that ‖Â‖₂ is near the mode's fastest frequency; ‖exp(Â t)‖₂ ≤ e^{‖Â‖₂ t}). A window on which the
 * linear part keeps one sign farther from 0 than ½ M h² plus the rounding of an evaluated output holds no zero. A
 * window where |s'(a)| > M h has a derivative of one sign, so s is monotone there: one zero at most, bracketed by the
 * signs at its ends and refined by bisection to the last representable bit. Any other window is halved, earliest half
 * first. Windows start as long as the exclusion is likely to pass (h = √(|s(a)|/M), at most 1/‖Â‖₂); halving stops at
 * the floor h_min = FLOOR_FRACTION / ‖Â‖₂ — only near a turning point of s that lies within h_min·|s'| of zero — where
 * a sign change in the asked direction is the crossing and none is a **grazing**, reported as no crossing. That is the
 * documented tolerance: two crossings closer together than h_min (1e-9 of the mode's fastest time scale) cancel.
 */
#pragma once

#include <Eigen/Dense>
#include <complex>

namespace backlash_servo
{
class LinearMode
{
 public:
  /// Eigenbases worse conditioned than this are not used: the Padé exponential instead.
  static constexpr double MAX_EIGENBASIS_CONDITION = 1e8;
  /// The search's floor h_min as a fraction of the fastest time scale 1/‖Â‖₂ (the grazing tolerance).
  static constexpr double FLOOR_FRACTION = 1e-9;

  /**
   * @param a the mode's matrix A (n × n, finite) [SI per the state's units]
   * @param u the constant input (n) [the state's units per second]
   * @param x0 the state at local time 0 (n)
   * Throws std::invalid_argument on mismatched sizes or non-finite entries.
   */
  LinearMode(const Eigen::MatrixXd& a, const Eigen::VectorXd& u, const Eigen::VectorXd& x0);

  int order() const { return static_cast<int>(x0_.size()); }
  /// x(τ) at local time τ ≥ 0 [s].
  Eigen::VectorXd state(double tau) const;
  /// ẋ(τ) = A x(τ) + u.
  Eigen::VectorXd rate(double tau) const;
  /// s(τ) = w·x(τ) + w₀.
  double output(const Eigen::VectorXd& w, double w0, double tau) const;
  /**
   * The first τ in (from, horizon] where s = w·x + w₀ crosses zero in `direction` (+1: from ≤ 0 to > 0, −1: from ≥ 0
   * to < 0), located to the last bit; +inf if none (a grazing within the floor is none, see the file comment).
   */
  double firstCrossing(const Eigen::VectorXd& w, double w0, int direction, double horizon, double from = 0.0) const;

  /// Whether the closed form is the modal one (else the Padé exponential).
  bool modal() const { return modal_; }
  /// The eigenvalues of A [1/s] (those of Ã less the input's zero).
  Eigen::VectorXcd eigenvalues() const;
  /// ‖Â‖₂ [1/s] of the balanced matrix Â = D⁻¹AD: the mode's fastest time scale is its inverse.
  double norm() const { return norm_a_; }

 private:
  /// The first crossing in [lo, hi] (the window's state known at lo), +inf if none.
  double searchWindow(const Eigen::VectorXd& w, double w0, int direction, double lo, double hi, double wa,
                      double floor) const;
  /// The bracketed crossing in (lo, hi] refined by bisection: direction·s(lo) ≤ 0 < direction·s(hi).
  double bisect(const Eigen::VectorXd& w, double w0, int direction, double lo, double hi) const;

  Eigen::MatrixXd a_;
  Eigen::VectorXd u_, x0_;
  Eigen::MatrixXd aug_;  // Ã
  bool modal_ = false;
  Eigen::MatrixXcd v_;        // eigenvectors of Ã (modal)
  Eigen::VectorXcd lambda_;   // eigenvalues of Ã (modal)
  Eigen::VectorXcd c_;        // V⁻¹ z₀ (modal)
  Eigen::VectorXd bal_;       // the balancing D (diagonal)
  Eigen::MatrixXd balanced_;  // Â = D⁻¹AD
  double norm_a_ = 0.0;       // ‖Â‖₂
};

}  // namespace backlash_servo
