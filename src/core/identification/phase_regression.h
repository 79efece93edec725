// The equations of motion integrated twice over stretches of one phase, for measured angles (quantised, noisy): no
// derivative of an angle is taken, so no smoothing biases them. Private to the core (identification.cpp).
//
// Over a stretch [t_a, t] of one phase, with τ = t − t_a, a body of inertia J, viscous F, Coulomb C (the velocity's
// sign s) and a constant torque b integrates to
//   J θ(t) + F ∫_a^t θ + C ∬ s + b τ²/2 = ∬ u + c₀ + c₁τ,
// the initial angle and speed in the nuisance line c₀ + c₁τ (one per stretch, projected out). ∬u is exact for the
// held torque; ∫θ is the trapezoid rule's (O(h²) — why exact angles keep the pointwise equations).
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "backlash_servo/identification/identification.h"

namespace backlash_servo
{
/// Stretches of one phase as half-open sample ranges [first, last).
using Stretches = std::vector<std::pair<std::size_t, std::size_t>>;

/// Rows [θ, ∫θ, ∬s, τ²/2] and ∬u, each stretch cut into pieces of at most `piece` samples, the nuisance line
/// projected out of every piece; `cluster` numbers the pieces (their rows' errors are correlated).
struct PhaseRows
{
  Eigen::MatrixXd x;
  Eigen::VectorXd y;
  std::vector<std::size_t> cluster;
  /// E[ΔᵀΔ] of the columns θ and ∫θ for white noise of unit variance in the angle (Δ: the noise as projected):
  /// what noise in the regressors adds to XᵀX, subtracted so that it does not shrink the inertia (errors in
  /// variables). Summed over the pieces [rad²·(1, s, s²)].
  Eigen::Matrix2d noise_gram = Eigen::Matrix2d::Zero();
};

PhaseRows integratedRows(const Recording& data, const std::vector<double>& sign, const Stretches& stretches,
                         std::size_t piece, std::size_t first_cluster);

/// The bodies' parameters from both phases at once: p = [J_m, f_m, T_cm, J_L, f_L, T_cL, T_ext] (SI), the first six
/// ≥ 0 (an active set: a level that would come out negative is held at 0), each phase weighted by its residual's
/// rms, the normal equations corrected for the angle's noise; standard errors by the cluster-robust (sandwich)
/// covariance with the pieces as clusters.
struct BodiesFit
{
  Eigen::VectorXd p, se;                      // [7]
  std::vector<bool> at_bound;                 // held at 0 by the constraint
  double apart_rms = 0.0, contact_rms = 0.0;  // [N·m·s²]
  std::size_t apart_rows = 0, contact_rows = 0;
  std::size_t pieces_dropped = 0;  // fitting beyond 5 × the median piece's rms (an impact unseen between samples)
  std::size_t apart_pieces = 0, contact_pieces = 0;  // kept: the clusters of the standard errors
  bool swamped = false;  // the angle's noise exceeds what the rows hold (the corrected equations not positive definite)
};

/// `known_load` (NaN: estimated) holds T_ext, `known_inertia` (J_m, J_L; NaN: estimated) the inertias — a known
/// inertia splits the pair's sum without the motor alone; a phase without rows leaves its parameters out (NaN), the
/// motor's columns then carrying the pair's sums. `noise` [rad]:
/// the motor angle's noise level (measured_angles.h), whose share of XᵀX is subtracted; not `white` (the counts of
/// a grid, correlated while the angle creeps) the correction's size joins each standard error.
BodiesFit fitBodies(const PhaseRows& apart, const PhaseRows& contact, double rho, double known_load,
                    std::pair<double, double> known_inertia, double noise, bool white);

}  // namespace backlash_servo
