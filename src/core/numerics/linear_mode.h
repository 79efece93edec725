/**
 * @file linear_mode.h
 * @brief A linear mode of any order with constant input, ẋ = A x + u, solved in closed form, and the exact location
 *        of the zero crossings of a linear output s(τ) = w·x(τ) + w₀ along it. The home of the modes of higher
 *        order (a compliant mesh couples motor and load into order 4, a torsional shaft into order 6); the rigid
 *        thesis modes keep their hand-written closed forms (modes.h) as the fast special case. No ROS dependency.
 *
 * Guaranteed: the motion exact to rounding (relative to how far the state moved); every zero crossing of s found and
 * located to a few ulps, except two closer together than FLOOR_FRACTION of the mode's fastest time scale (a grazing),
 * which cancel.
 * How it is computed and what it guarantees: docs/model.md, Part 4, "Linear modes of any order and their zero
 * crossings".
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
   * grazing within the floor is none, docs/model.md, Part 4).
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
  /// How much slower than its fastest the motion still varies at τ ≥ 0: max |λ_k| over max |λ_k| of the modes whose
  /// part of ẋ, ‖Dv_k‖₁|g_k|e^{Re λ_k τ}, is above DEAD_FRACTION of all of them together (a decaying mode below that
  /// changes no sum it enters), at most MAX_SPEEDUP; 1 without a modal basis or with a polynomial part. A quadrature
  /// over pieces sized for the fastest time scale may lengthen them by this much from τ on (it only grows with τ).
  double decayedSpeedup(double tau) const;
  static constexpr double DEAD_FRACTION = 1e-18;
  static constexpr double MAX_SPEEDUP = 1e6;

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
  /// The rounding of the output w·x + w0 at the point p [the output's unit] (`weight`: Curvature::weight).
  double valueNoise(const ModeVector& w, double w0, const Point& p, double weight) const;
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
