// Linear least squares for the identification's regressions (identification.cpp, identify_mesh.cpp); private to the
// core.
#pragma once

#include <Eigen/Dense>
#include <cstddef>

namespace backlash_servo
{
/// A least-squares fit y ≈ X p: the parameters, their covariance σ²(XᵀX)⁻¹ (σ² the residual variance) and standard
/// errors, and the residuals' rms [y's unit].
struct LeastSquaresFit
{
  Eigen::VectorXd p, se;
  Eigen::MatrixXd cov;
  double rms = 0.0;
};

/// Plain least squares (columns scaled to unit norm for the conditioning).
LeastSquaresFit plainLeastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y);

/// Least squares robust to the few rows a discontinuity between samples spoils (an impact inside a sample interval, a
/// friction reversal): fitted, then refitted without the residuals beyond 5 robust standard deviations (1.4826 × the
/// median absolute residual), until none is dropped (at most 5 rounds; the number of rows kept is written to *kept).
LeastSquaresFit leastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, std::size_t* kept);

}  // namespace backlash_servo
