/**
 * @file mode_basis.h
 * @brief What a linear mode's matrix A determines, computed once and shared by every motion of that mode (the
 *        closed forms built on it are in linear_mode.h): the balancing, the eigenbasis, and the split of a zero
 *        eigenvalue that lacks eigenvectors. No ROS dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "A mode's basis: balancing, eigenbasis, the zero
 * eigenvalue".
 */
#pragma once

#include <Eigen/Dense>
#include <array>
#include <complex>

namespace backlash_servo
{
class LinearMode;

/// The largest order of a linear mode (the compliant joint's are 4 and 6).
constexpr int MAX_MODE_ORDER = 8;
/// Vectors and matrices of a mode's order, stored in place (no heap allocation on the event searches' hot paths).
using ModeVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MAX_MODE_ORDER, 1>;
using ModeVectorC = Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 1, 0, MAX_MODE_ORDER, 1>;
using ModeMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MAX_MODE_ORDER, MAX_MODE_ORDER>;
using ModeMatrixC =
    Eigen::Matrix<std::complex<double>, Eigen::Dynamic, Eigen::Dynamic, 0, MAX_MODE_ORDER, MAX_MODE_ORDER>;

/// What one mode's matrix A determines, computed once: the balancing D, Â = D⁻¹AD and ‖Â‖₂, and the eigenbasis of Â
/// when it is complete and well-conditioned. Fixed once built (but for a cache of its outputs' reach); shared between
/// the motions of that mode.
class ModeBasis
{
 public:
  /// A slow (not nilpotent) block's series is summed to rounding over τ ≤ SERIES_SPAN/‖Â‖₂ (CompliantJoint
  /// re-anchors every 4096/‖Â‖₂); beyond, its truncation grows.
  static constexpr double SERIES_SPAN = 65536.0;
  /// Eigenbases worse conditioned than this are not used: the Taylor series instead. (A defective eigenvalue's
  /// computed eigenvectors are parallel to about √ε, a condition near 1e8: the threshold stays well below that.)
  static constexpr double MAX_EIGENBASIS_CONDITION = 1e6;
  /// How far from ker Â^{k−1} (relative to ‖Â‖₂) Â may map a direction that grows ker Â^k: a chain of the zero
  /// eigenvalue, or a mode slow enough for the slow block's series; a faster one stays with the diagonalised modes.
  /// Also the threshold, relative to the largest, of the singular values of Â^k that are candidates for the kernel.
  static constexpr double CHAIN_TOLERANCE = 1e-7;
  /// The zero eigenvalue's split (docs/model.md, Part 4), relative to ‖Â‖₂ (to its m-th power for Nᵐ): couplings
  /// between the subspaces and a remainder Nᵐ up to EXACT_SPLIT are rounding; up to NEAR_SPLIT — as far as
  /// CHAIN_TOLERANCE admits a chain — they are removed (the blocks decoupled, the decoupling checked down to
  /// EXACT_SPLIT, the slow block's series summed beyond m terms); beyond, the Taylor series, whose bounds on an output
  /// are loose (the event search then crawls along an output that hovers near zero).
  static constexpr double EXACT_SPLIT = 1e-14;
  static constexpr double NEAR_SPLIT = CHAIN_TOLERANCE;

  /// @param a the mode's matrix A (n × n, n ≤ MAX_MODE_ORDER, finite) [SI per the state's units]. Throws
  /// std::invalid_argument.
  explicit ModeBasis(const Eigen::MatrixXd& a);

  int order() const { return static_cast<int>(a_.rows()); }
  const ModeMatrix& matrix() const { return a_; }
  /// Whether motions are evaluated modally (else by their Taylor series).
  bool modal() const { return modal_; }
  /// The order of the modal form's polynomial part (0: none; docs/model.md, Part 4).
  int polynomialOrder() const { return nil_; }
  /// ‖Â‖₂ [1/s] of the balanced matrix: the mode's fastest time scale is its inverse.
  double norm() const { return norm_a_; }
  /// The eigenvalues of A [1/s].
  Eigen::VectorXcd eigenvalues() const;
  /// The relative rounding error of an evaluated state, in the balanced basis (grows with cond(V)).
  double rounding() const { return rounding_; }

  /// What an output s = w·x + w₀ of this mode's motions owes to the mode alone: how strongly each mode reaches it
  /// and how the rounding of a balanced vector reaches it.
  struct OutputReach
  {
    ModeVector w;
    ModeVector size;      // (modal) |wᵀD v_k λ_k| per eigenvalue (0 for a pair's conjugate: counted in its partner)
    double weight = 0.0;  // Σ_j |w_j| D_j
  };
  /// The reach of output w, kept for the last few outputs asked (a joint watches the same few in each mode). Not
  /// thread-safe: a basis belongs to the one joint whose modes it decomposes.
  const OutputReach& reach(const ModeVector& w) const;

 private:
  friend class LinearMode;
  ModeMatrix a_;
  ModeVector bal_;       // the balancing D (diagonal)
  ModeVector inv_bal_;   // D⁻¹ (exact: powers of 2)
  ModeMatrix balanced_;  // Â = D⁻¹AD
  double norm_a_ = 0.0;  // ‖Â‖₂
  bool modal_ = false;
  double rounding_ = 0.0;
  ModeMatrixC v_;               // eigenvectors of Â (modal), then a real basis of the nilpotent block's subspace
  ModeVectorC lambda_;          // eigenvalues (modal; 0 for the nilpotent block's coordinates)
  ModeVector speed_;            // |λ| of each (modal, the nilpotent block's excepted)
  ModeMatrix dvl_re_, dvl_im_;  // D V Λ (modal, those columns): an output w's modal curvatures are wᵀDVΛ
  ModeMatrixC v_inv_;           // V⁻¹ (modal)
  ModeVector weight_;           // per eigenvalue: 1, or 2 and 0 for a complex pair (only the first evaluated, doubled)
  std::array<int, MAX_MODE_ORDER> active_{};  // the eigenvalues evaluated (weight ≠ 0), in order
  int n_active_ = 0;
  ModeMatrix dv_re_, dv_im_;  // D V of those columns (modal): a motion's deviation is D V (τ φ₁(Λτ) g)
  int nil_ = 0;               // the order of the nilpotent block (the last nil_ columns of V)
  int poly_terms_ = 0;        // the terms of its series: nil_, or more for a block that is slow but not nilpotent
  ModeMatrix nilpotent_;      // N: Â restricted to ker Â^K in those coordinates (N^nil_ = 0, or merely small)
  /// Takes V, Λ (and a nilpotent block of that order in V's last columns) if V is well-conditioned.
  bool useBasis(const Eigen::MatrixXcd& v, const Eigen::VectorXcd& lambda, int nilpotent_order);
  /// The modal form with a polynomial part where Â's zero eigenvalue lacks eigenvectors (docs/model.md, Part 4).
  void splitNilpotent(const Eigen::MatrixXd& b);
  /// Block-diagonalises T⁻¹ÂT = [F C; D S] (F r × r) by T ← T [I X; Y I] (Sylvester equations for X, Y) and
  /// recomputes *blocks; false if the blocks could not be separated.
  bool decouple(Eigen::Index r, Eigen::Index m, Eigen::MatrixXd* t, Eigen::MatrixXd* blocks);
  /// The terms of the slow block S's series that reach rounding on τ ≤ SERIES_SPAN/‖Â‖₂.
  int slowTerms(const Eigen::MatrixXd& s) const;
  mutable std::array<OutputReach, 8> reaches_;
  mutable std::size_t reaches_next_ = 0, reaches_kept_ = 0;
};

}  // namespace backlash_servo
