/**
 * @file linear_mode.h
 * @brief A linear mode of any order with constant input, ẋ = A x + u, solved in closed form, and the exact location
 *        of the zero crossings of a linear output s(τ) = w·x(τ) + w₀ along it. The home of the modes of higher
 *        order (a compliant mesh couples motor and load into order 4, a torsional shaft into order 6); the rigid
 *        thesis modes keep their hand-written closed forms (modes.h) as the fast special case. No ROS dependency.
 *
 * **Solution.** A depends only on the mode (and the drive law's stiffness), u and x₀ on the moment, so what costs is
 * done once per A in a ModeBasis (mode_basis.h: the balancing Â = D⁻¹AD, the eigenbasis, the split of a zero
 * eigenvalue), which the caller may keep and share between motions. The motion is evaluated as the deviation
 * δ = x − x₀ from the start, which obeys δ̇ = Aδ + v₀ (v₀ = Ax₀ + u, δ(0) = 0), so that rounding is relative to how
 * far the state has moved and not to the angles it started at, which grow without bound over a run. Modally
 * (A = D V Λ V⁻¹ D⁻¹):
 *   x(τ) = x₀ + D V τ φ₁(Λτ) g,  g = V⁻¹D⁻¹v₀,  φ₁(z) = (e^z − 1)/z (φ₁(0) = 1),
 * a sum of damped sinusoids and exponentials at the mode's own frequencies plus the drift of its zero eigenvalues
 * (a free body under constant torque), O(n²) per evaluation. Where the zero eigenvalue lacks eigenvectors, the
 * basis splits off a block N on ker Â^K (nilpotent, N^m = 0, or slow and decoupled), whose coordinates y obey
 * ẏ = N y + g_N, y(0) = 0, so that
 *   δ̂(τ) = Σ_{λ_k ≠ 0} V_k τ φ₁(λ_kτ) g_k + V_N Σ_{j<m} Nʲ g_N τ^{j+1}/(j + 1)!,
 * damped sinusoids plus a polynomial of degree m, as cheap to evaluate (a slow block's series summed on beyond m
 * terms, to rounding over ModeBasis::SERIES_SPAN fast time scales).
 * Otherwise (a defective eigenvalue that is not zero: a critically damped pair) δ is its Taylor series in the
 * balanced basis, δ̂(a + r) = Σ_j k_j r^j (k_0 = δ̂(a), k_1 = Âδ̂(a) + v̂₀, k_j = Âk_{j−1}/j), summed to rounding
 * (TAYLOR_TERMS terms) from anchors a at multiples of TAYLOR_STEP/‖Â‖₂ from the start, each anchor from the one
 * before — exact to rounding, and a pure function of τ. (The caller re-anchors long motions: CompliantJoint starts a
 * new one every 4096 fast time scales without events.)
 *
 * **Zero crossings, rigorously.** ẋ obeys the homogeneous equation (ẍ = A ẋ), so on a window [a, a + h]
 *   s(a + t) = s(a) + s'(a) t + R(t),  |R(t)| ≤ ½ M t²,  M ≥ max |s''| on the window:
 * modally s''(τ) = Σ_k (wᵀDv_k) λ_k g_k e^{λ_k τ}, so M = Σ_k |(wᵀDv_k) λ_k g_k| e^{Re λ_k τ*}
 * with τ* the window's end where that mode's term is largest (tight: a single mode's amplitude times ω², the rigid
 * body's drift adding nothing), plus Σ_{j≥1} |(Dw)·P_j| (j + 1) j τ_end^{j−1} for the polynomial part Σ_j P_j τ^{j+1};
 * otherwise M = ‖(Dw)ᵀÂ‖₂ ‖D⁻¹ẋ(a)‖₂ e^{‖Â‖₂ h} (s'' = wᵀ A exp(A t) ẋ(a) in the
 * balanced basis x = D x̂, Â = D⁻¹AD, D a diagonal of powers of 2 (Parlett–Reinsch) so that ‖Â‖₂ is near the mode's
 * fastest frequency; ‖exp(Â t)‖₂ ≤ e^{‖Â‖₂ t}). Modally the model is also taken one degree further,
 *   s(a + t) = s(a) + s'(a) t + ½ s''(a) t² + R₃(t),  |R₃(t)| ≤ M₃ t³/6,  M₃ = Σ_k |(wᵀDv_k) λ_k g_k| |λ_k| e^{Re λ_k
 * τ*} (plus the polynomial part's third derivative), s''(a) = w·Aẋ(a) — where s is smooth on the window (the fast modes
 * decayed, or a slow peel-off from zero) the quadratic follows it much farther than the line. A window on which
 * either model keeps one sign farther from 0 than its remainder plus the rounding of the evaluated output and its
 * derivatives holds no zero. A window where |s'(a)| > M h, or where s'(a) + s''(a) t keeps its sign beyond ½ M₃ t²,
 * has a derivative of one sign, so s is monotone there: one zero at most, bracketed by the
 * signs at its ends and refined until the end past the crossing is within a few ulps of the output's terms, where
 * the sign of s means nothing more, or the ends are adjacent doubles (Newton's method kept inside the bracket, from
 * the root of the window's quadratic model, s' = w·(Ax + u), each step aimed half that band past the crossing: about
 * four evaluations a crossing; where it stalls, the ITP method — regula falsi made two-sided and never slower than
 * bisection); that end is the event. Any other window is halved, earliest half
 * first. Where the bounds do not grow with the window (modal, no growing mode, no τ in s''), each window is the
 * longest these tests settle from one evaluation — each holds below a length, the roots of their quadratics (the
 * degree-2 exclusion's cubic by bisection), so arithmetic only — and at least h = √(|s(a)|/M); otherwise h =
 * √(|s(a)|/M), at most 1/‖Â‖₂ (four of them modally); halving stops at the floor h_min = FLOOR_FRACTION / ‖Â‖₂ — only
 * near a turning point of s that lies within h_min·|s'| of zero — where a sign change in the asked direction is the
 * crossing and none is a **grazing**, reported as no crossing. That is the documented tolerance: two crossings closer
 * together than h_min (1e-9 of the mode's fastest time scale) cancel.
 */
#pragma once

#include <array>
#include <limits>
#include <memory>
#include <vector>

#include "numerics/mode_basis.h"

namespace backlash_servo
{
class LinearMode
{
 public:
  /// The search's floor h_min as a fraction of the fastest time scale 1/‖Â‖₂ (the grazing tolerance).
  static constexpr double FLOOR_FRACTION = 1e-9;
  /// Newton steps a crossing's refinement takes before it leaves the bracket to the ITP method.
  static constexpr int NEWTON_STEPS = 8;
  /// Without a modal basis: the Taylor anchors' spacing [1/‖Â‖₂], the terms summed, how many anchors are all kept,
  /// and how many apart the kept ones are beyond those.
  static constexpr double TAYLOR_STEP = 0.5;
  static constexpr int TAYLOR_TERMS = 18;
  static constexpr std::size_t DENSE_ANCHORS = 65536;
  static constexpr std::size_t CHECKPOINT = 256;

  /**
   * @param a the mode's matrix A (n × n, finite) [SI per the state's units]
   * @param u the constant input (n) [the state's units per second]
   * @param x0 the state at local time 0 (n)
   * Throws std::invalid_argument on mismatched sizes or non-finite entries.
   */
  LinearMode(const Eigen::MatrixXd& a, const ModeVector& u, const ModeVector& x0);
  /// The same with A's basis computed beforehand (shared, not copied).
  LinearMode(std::shared_ptr<const ModeBasis> basis, const ModeVector& u, const ModeVector& x0);

  int order() const { return static_cast<int>(x0_.size()); }
  /// x(τ) at local time τ ≥ 0 [s].
  ModeVector state(double tau) const;
  /// ẋ(τ) = A x(τ) + u.
  ModeVector rate(double tau) const;
  /// s(τ) = w·x(τ) + w₀.
  double output(const ModeVector& w, double w0, double tau) const;
  /**
   * The first τ in (from, horizon] where s = w·x + w₀ crosses zero in `direction` (+1: from ≤ 0 to > 0, −1: from ≥ 0
   * to < 0, 0: either — one search where two would visit the same windows), located to the last bit; +inf if none (a
   * grazing within the floor is none, see the file comment).
   * `began_here`: this output's crossing is the event that began the motion, at `from` — there, within rounding of
   * zero and moving in `direction`, its sign means nothing and is not a crossing.
   */
  double firstCrossing(const ModeVector& w, double w0, int direction, double horizon, double from = 0.0,
                       bool began_here = false) const;

  /// Whether the closed form is the modal one (else the Taylor series).
  bool modal() const { return basis_->modal(); }
  /// The order of its polynomial part (a zero eigenvalue without a full eigenspace), 0 if none.
  int polynomialOrder() const { return basis_->polynomialOrder(); }
  /// The eigenvalues of A [1/s].
  Eigen::VectorXcd eigenvalues() const { return basis_->eigenvalues(); }
  /// ‖Â‖₂ [1/s] of the balanced matrix Â = D⁻¹AD: the mode's fastest time scale is its inverse.
  double norm() const { return basis_->norm(); }

 private:
  /// What bounds the derivatives |s''| and |s'''| of one output: per mode |wᵀDv_k λ_k g_k| and Re λ_k (modal; |λ_k|
  /// from the basis), or ‖(Dw)ᵀÂ‖₂ (Taylor: |s''| only).
  struct Curvature
  {
    ModeVector beta, rate;
    ModeVector poly;  // the polynomial part's s'' = Σ_j ± poly_j τ^{j−1} (and s''' = Σ_j ± poly_j (j − 1) τ^{j−2})
    double wa = 0.0;
    double weight = 0.0;  // Σ_j |w_j| D_j: the output's share of a balanced vector's rounding (see rateNoise)
    bool steady = true;   // (modal) the bounds on a window do not grow with its length: no growing mode, no τ in s''
  };
  Curvature curvature(const ModeVector& w) const;
  /// What every output's local picture at one instant shares: the state, its first two rates, the balanced norms
  /// their rounding scales with, and each mode's decay there. A search round asks every watched output at the same
  /// instant first: that one is kept apart from the last of the windows after it.
  struct Point
  {
    double tau = std::numeric_limits<double>::quiet_NaN();
    ModeVector x, xd;                      // x, ẋ = Ax + u
    double dev_norm = 0.0, xd_norm = 0.0;  // ‖D⁻¹(x − x₀)‖, ‖D⁻¹ẋ‖
    mutable ModeVector xdd;                // ẍ = Aẋ, once asked for
    mutable double xdd_norm = 0.0;         // ‖D⁻¹ẍ‖
    mutable bool second = false;
    mutable ModeVector decay;  // (modal) e^{Re λ_k τ}, each computed once asked for (NaN until then)
  };
  mutable std::array<Point, 2> points_;  // [0]: where the last search began; [1]: the last window's start
  /// The picture at tau (kept in the first slot where a search begins there).
  const Point& pointAt(double tau, bool begins = false) const;
  /// ‖D⁻¹v‖₂.
  double balancedNorm(const ModeVector& v) const;
  /// Bounds m2 ≥ max |s''| and m3 ≥ max |s'''| (+inf: none) over [lo, lo + h] (p the picture at lo).
  void curvatureBounds(const Curvature& k, const Point& p, double lo, double h, double* m2, double* m3) const;
  /// An output's local picture at a window's start lo: its value and first two derivatives, their rounding, and the
  /// bounds m2, m3 on its second and third derivatives over the window (the second derivative only once asked for).
  struct Local
  {
    double s = 0.0, s1 = 0.0, s2 = 0.0, noise0 = 0.0, noise1 = 0.0, noise2 = 0.0, m2 = 0.0, m3 = 0.0;
    double lo = 0.0, weight = 0.0;  // the window's start [s]; the output's Curvature::weight
    bool second = false;            // s2 and noise2 computed
  };
  Local local(const ModeVector& w, double w0, double lo, double h, const Curvature& curv, bool begins = false) const;
  /// What the Taylor models of degree 1 and 2 at a window's start prove about s = w·x + w₀ on [lo, lo + h] (the
  /// second degree's coefficients computed into *l where the first does not settle it).
  enum class Verdict
  {
    Clear,     ///< no zero
    Monotone,  ///< s' keeps its sign: one zero at most
    Unknown
  };
  Verdict judge(const ModeVector& w, Local* l, double h) const;
  /// s'' = w·Aẋ and its rounding into *l, unless already there.
  void completeSecond(const ModeVector& w, Local* l) const;
  /// The longest window (at most `rest` [s]) that judge() settles from *l: each of its tests holds on an interval
  /// [0, h) of lengths, so the longest is the largest of those — the roots of its quadratics in closed form, the
  /// degree-2 exclusion's cubic by bisection. (Only where the bounds do not grow with the window.)
  double reach(const ModeVector& w, Local* l, double rest) const;
  /// The first crossing in [lo, hi] (the window's state known at lo), +inf if none; `origin` is where the crossing
  /// that began the motion lies (NaN: none, see firstCrossing's began_here); `at_lo` the window's local picture if
  /// known (completed in place).
  double searchWindow(const ModeVector& w, double w0, int direction, double lo, double hi, const Curvature& curv,
                      double floor, double origin, Local* at_lo = nullptr) const;
  /// What rounding can do to w·v of a rate v = A x + u (or a higher derivative) computed from an evaluated state.
  double rateNoise(const ModeVector& w, const ModeVector& v) const;
  /// The bracketed crossing in (lo, hi] (direction·s(lo) ≤ 0 < direction·s(hi), `at_lo` the window's local picture at
  /// lo) refined until the end past it is within a few ulps of the output's terms or the ends are adjacent doubles
  /// (Newton from the Taylor model's root, then ITP); returns that end.
  double refine(const ModeVector& w, double w0, int direction, double lo, double hi, const Local& at_lo) const;

  std::shared_ptr<const ModeBasis> basis_;
  ModeVector u_, x0_;
  ModeVector v0_;     // ẋ(0) = Ax₀ + u: the input of the deviation δ = x − x₀ the motion is solved for
  ModeVectorC g_;     // V⁻¹D⁻¹v₀ (modal)
  ModeVector g_abs_;  // |g| (modal)
  ModeVectorC g_over_lambda_;  // g/λ (modal)
  ModeMatrix poly_;            // P_j = V_N Nʲ g_N / (j + 1)!: the polynomial part Σ_j P_j τ^{j+1} of δ̂ (modal)
  unsigned moving_ = 0;        // bit i: coordinate i moves (with a polynomial part; see the constructor)
  // Without a modal basis: the anchors x̂ at multiples of step_ (all of the first DENSE_ANCHORS, then every
  // CHECKPOINT-th, and the farthest reached), and the Taylor coefficients of the anchors last used.
  double step_ = 0.0;
  mutable std::vector<ModeVector> checkpoints_;
  mutable ModeVector frontier_;
  mutable std::size_t frontier_index_ = 0;
  using KrylovMatrix = Eigen::MatrixXd;  // (on the heap: a modal motion, the common case, stays small to copy)
  struct KrylovEntry
  {
    std::size_t anchor = static_cast<std::size_t>(-1);
    KrylovMatrix k;
  };
  mutable std::array<KrylovEntry, 4> krylov_;
  mutable std::size_t krylov_next_ = 0;
  mutable KrylovMatrix step_krylov_;
  /// The closed form at τ (state() keeps the last few).
  ModeVector evaluate(double tau) const;
  struct Memo
  {
    double tau = std::numeric_limits<double>::quiet_NaN();
    ModeVector x;
  };
  mutable std::array<Memo, 4> memo_;
  mutable std::size_t memo_next_ = 0;
  ModeVector taylorState(double tau) const;
  /// The anchor x̂ at i steps from the start.
  const ModeVector& anchor(std::size_t i) const;
  /// The Taylor coefficients k_j (columns) of the motion from the anchor state x̂_a.
  void setKrylov(const ModeVector& xa, KrylovMatrix* k) const;
  /// Σ_j k_j r^j (Horner).
  static ModeVector taylor(const KrylovMatrix& k, double r);
  /// One Taylor step of r from x̂_a.
  ModeVector taylor(const ModeVector& xa, double r) const;
};

}  // namespace backlash_servo
