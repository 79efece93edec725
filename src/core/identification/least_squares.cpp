#include "identification/least_squares.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace backlash_servo
{
LeastSquaresFit plainLeastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y)
{
  LeastSquaresFit f;
  // Columns scaled to unit norm for the conditioning of the normal equations' inverse.
  const Eigen::VectorXd scale = x.colwise().norm().transpose().cwiseMax(1e-300);
  const Eigen::MatrixXd xs = x * scale.cwiseInverse().asDiagonal();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(xs);
  const Eigen::VectorXd ps = qr.solve(y);
  f.p = ps.cwiseQuotient(scale);
  const Eigen::VectorXd r = y - x * f.p;
  const double dof = static_cast<double>(x.rows() - x.cols());
  const double sigma2 = r.squaredNorm() / std::max(dof, 1.0);
  f.rms = std::sqrt(r.squaredNorm() / static_cast<double>(x.rows()));
  const Eigen::MatrixXd unscale = scale.cwiseInverse().asDiagonal();
  f.cov = unscale * (xs.transpose() * xs).inverse() * unscale * sigma2;
  f.se = f.cov.diagonal().cwiseSqrt();
  return f;
}

LeastSquaresFit leastSquares(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, std::size_t* kept)
{
  constexpr double TRIM_FACTOR = 5.0;
  Eigen::MatrixXd xs = x;
  Eigen::VectorXd ys = y;
  LeastSquaresFit f = plainLeastSquares(xs, ys);
  for (int round = 0; round < 5; ++round)
  {
    const Eigen::VectorXd r = (y - x * f.p).cwiseAbs();
    std::vector<double> sorted(r.data(), r.data() + r.size());
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
    const double limit = TRIM_FACTOR * 1.4826 * sorted[sorted.size() / 2];
    std::vector<Eigen::Index> rows;
    for (Eigen::Index i = 0; i < r.size(); ++i)
    {
      if (r(i) <= limit)
      {
        rows.push_back(i);
      }
    }
    if (static_cast<Eigen::Index>(rows.size()) == xs.rows() || rows.size() < static_cast<std::size_t>(x.cols()) + 2)
    {
      break;
    }
    xs = x(rows, Eigen::all);
    ys = y(rows);
    f = plainLeastSquares(xs, ys);
  }
  *kept = static_cast<std::size_t>(xs.rows());
  return f;
}

}  // namespace backlash_servo
