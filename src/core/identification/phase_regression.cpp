#include "identification/phase_regression.h"

#include <algorithm>
#include <cmath>

#include "identification/least_squares.h"

namespace backlash_servo
{
namespace
{
constexpr std::size_t FEWEST_PIECE = 6;  // samples: the nuisance line and three columns need more rows

/// Removes from every column of x and from y their least-squares line in τ (rows [0, m), τ_i = i).
void projectLine(Eigen::Ref<Eigen::MatrixXd> x, Eigen::Ref<Eigen::VectorXd> y)
{
  const Eigen::Index m = x.rows();
  Eigen::MatrixXd basis(m, 2);
  for (Eigen::Index i = 0; i < m; ++i)
  {
    basis(i, 0) = 1.0;
    basis(i, 1) = static_cast<double>(i) - 0.5 * static_cast<double>(m - 1);  // (centred: orthogonal to the 1s)
  }
  const Eigen::VectorXd norms = basis.colwise().squaredNorm().transpose();
  for (Eigen::Index j = 0; j < 2; ++j)
  {
    const Eigen::VectorXd b = basis.col(j);
    x -= b * ((b.transpose() * x) / norms(j));
    y -= b * (b.dot(y) / norms(j));
  }
}

/// E[ΔᵀΔ] for the columns θ and ∫θ of one piece of m samples at period h, unit white noise in θ: with P the
/// projection that removes the line and T the trapezoid rule, Δ = [P e, P T e], so E = [[tr P, tr PT], [tr PT,
/// ‖PT‖²_F]].
Eigen::Matrix2d noiseGram(std::size_t m, double h)
{
  const Eigen::Index n = static_cast<Eigen::Index>(m);
  Eigen::MatrixXd t = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index k = 1; k < n; ++k)
  {
    t(k, 0) = 0.5 * h;
    for (Eigen::Index j = 1; j < k; ++j)
    {
      t(k, j) = h;
    }
    t(k, k) = 0.5 * h;
  }
  Eigen::MatrixXd pt = t;
  Eigen::VectorXd unused = Eigen::VectorXd::Zero(n);
  projectLine(pt, unused);
  Eigen::Matrix2d g;
  g(0, 0) = static_cast<double>(n - 2);
  g(0, 1) = g(1, 0) = pt.trace();
  g(1, 1) = pt.squaredNorm();
  return g;
}

/// The noise's share N of XᵀX over all seven columns, and what it adds to Xᵀy where known values were moved to the
/// right-hand side (N_fk p_k: the noise of a known column's regressor, now in y, correlates with the free ones').
struct NoiseShare
{
  Eigen::MatrixXd gram;
  Eigen::VectorXd rhs;
};

/// Solves the normal equations (XᵀX − N) p = Xᵀy + N_fk p_k of the columns `free`.
Eigen::VectorXd correctedSolve(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const NoiseShare& noise,
                               const std::vector<Eigen::Index>& free, Eigen::MatrixXd* inverse)
{
  const Eigen::MatrixXd xf = x(Eigen::all, free);
  const Eigen::VectorXd scale = xf.colwise().norm().transpose().cwiseMax(1e-300);
  const Eigen::MatrixXd normal =
      (xf.transpose() * xf - noise.gram(free, free)).cwiseQuotient(scale * scale.transpose());
  // The noise's share may not exceed what the rows hold: corrected normal equations that are not positive definite
  // say the noise swamps the motion (NaN: nothing determined).
  if (Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(normal, Eigen::EigenvaluesOnly).eigenvalues().minCoeff() <= 0.0)
  {
    if (inverse)
    {
      *inverse = Eigen::MatrixXd::Constant(xf.cols(), xf.cols(), NAN);
    }
    return Eigen::VectorXd::Constant(xf.cols(), NAN);
  }
  const Eigen::MatrixXd inv = normal.inverse().cwiseQuotient(scale * scale.transpose());
  if (inverse)
  {
    *inverse = inv;
  }
  return inv * (xf.transpose() * y + noise.rhs(free));
}

}  // namespace

PhaseRows integratedRows(const Recording& d, const std::vector<double>& sign, const Stretches& stretches,
                         std::size_t piece, std::size_t first_cluster)
{
  const double h = (d.time.back() - d.time.front()) / static_cast<double>(d.time.size() - 1);
  std::vector<std::pair<std::size_t, std::size_t>> pieces;
  std::size_t rows = 0;
  for (const auto& [first, last] : stretches)
  {
    const std::size_t length = last - first, count = (length + piece - 1) / piece;
    for (std::size_t i = 0; i < count; ++i)
    {
      const std::size_t a = first + i * length / count, b = first + (i + 1) * length / count;
      if (b - a >= FEWEST_PIECE)
      {
        pieces.emplace_back(a, b);
        rows += b - a;
      }
    }
  }
  PhaseRows out;
  out.x.resize(static_cast<Eigen::Index>(rows), 4);
  out.y.resize(static_cast<Eigen::Index>(rows));
  out.cluster.reserve(rows);
  Eigen::Index row = 0;
  for (std::size_t c = 0; c < pieces.size(); ++c)
  {
    const auto [a, b] = pieces[c];
    const Eigen::Index start = row;
    double theta_integral = 0.0, sign_integral = 0.0, sign_double = 0.0, u_integral = 0.0, u_double = 0.0;
    for (std::size_t k = a; k < b; ++k)
    {
      if (k > a)
      {
        // Over [t_{k−1}, t_k): the torque u_{k−1} held (exact), the angle and the sign by the trapezoid rule.
        const double u = d.motor_torque[k - 1], s = 0.5 * (sign[k - 1] + sign[k]);
        theta_integral += 0.5 * h * (d.motor_position[k - 1] + d.motor_position[k]);
        u_double += u_integral * h + 0.5 * u * h * h;
        u_integral += u * h;
        sign_double += sign_integral * h + 0.5 * s * h * h;
        sign_integral += s * h;
      }
      const double tau = static_cast<double>(k - a) * h;
      out.x.row(row) << d.motor_position[k], theta_integral, sign_double, 0.5 * tau * tau;
      out.y(row) = u_double;
      out.cluster.push_back(first_cluster + c);
      ++row;
    }
    projectLine(out.x.middleRows(start, row - start), out.y.segment(start, row - start));
    out.noise_gram += noiseGram(b - a, h);
  }
  return out;
}

namespace
{
/// Pieces an unseen impact spoils (a jump of the motor's speed inside a piece, between samples that read apart) fit
/// far worse than the rest: left out, as the rows beyond 5 × the median piece's rms after a first fit. Counts the
/// pieces kept in each phase (the first na rows are the motor alone's) and dropped into `out`.
void dropSpoiledPieces(const NoiseShare& gram, const std::vector<Eigen::Index>& free, Eigen::Index na,
                       Eigen::MatrixXd* x_io, Eigen::VectorXd* y_io, std::vector<std::size_t>* cluster_io,
                       BodiesFit* fit)
{
  Eigen::MatrixXd& x = *x_io;
  Eigen::VectorXd& y = *y_io;
  std::vector<std::size_t>& cluster = *cluster_io;
  BodiesFit& out = *fit;
  const Eigen::VectorXd r = y - x(Eigen::all, free) * correctedSolve(x, y, gram, free, nullptr);
  std::vector<double> piece_rms;
  std::vector<std::pair<Eigen::Index, Eigen::Index>> spans;
  for (Eigen::Index i = 0, a = 0; i < r.size(); ++i)
  {
    if (i + 1 == r.size() || cluster[static_cast<std::size_t>(i + 1)] != cluster[static_cast<std::size_t>(i)])
    {
      piece_rms.push_back(std::sqrt(r.segment(a, i + 1 - a).squaredNorm() / static_cast<double>(i + 1 - a)));
      spans.emplace_back(a, i + 1);
      a = i + 1;
    }
  }
  std::vector<double> sorted = piece_rms;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
  const double median = sorted[sorted.size() / 2];
  const double limit = std::isfinite(median) ? 5.0 * median : INFINITY;  // (nothing determined: nothing dropped)
  std::vector<Eigen::Index> keep;
  std::vector<std::size_t> kept_cluster;
  for (std::size_t c = 0; c < spans.size(); ++c)
  {
    if (piece_rms[c] <= limit)
    {
      ++(spans[c].first < na ? out.apart_pieces : out.contact_pieces);
      for (Eigen::Index i = spans[c].first; i < spans[c].second; ++i)
      {
        keep.push_back(i);
        kept_cluster.push_back(cluster[static_cast<std::size_t>(i)]);
      }
    }
    else
    {
      ++out.pieces_dropped;
    }
  }
  x = Eigen::MatrixXd(x(keep, Eigen::all));
  y = Eigen::VectorXd(y(keep));
  cluster = kept_cluster;
}

/// The corrected fit with the levels constrained ≥ 0: the most negative of the constrained levels (columns < 6) held
/// at 0 (taken out of `free`, marked in `out`), until none is. False when no column is left.
bool holdNegativeLevels(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const NoiseShare& gram,
                        std::vector<Eigen::Index>* free_io, BodiesFit* fit)
{
  std::vector<Eigen::Index>& free = *free_io;
  BodiesFit& out = *fit;
  Eigen::VectorXd p;
  while (true)
  {
    p = correctedSolve(x, y, gram, free, nullptr);
    Eigen::Index worst = -1;
    for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(free.size()); ++i)
    {
      if (free[static_cast<std::size_t>(i)] < 6 && p(i) < 0.0 && (worst < 0 || p(i) < p(worst)))
      {
        worst = i;
      }
    }
    if (worst < 0)
    {
      break;
    }
    out.at_bound[static_cast<std::size_t>(free[static_cast<std::size_t>(worst)])] = true;
    out.p(free[static_cast<std::size_t>(worst)]) = 0.0;
    free.erase(free.begin() + worst);
    if (free.empty())
    {
      return false;
    }
  }
  return true;
}

/// The parameters of the free columns with cluster-robust errors (XᵀX)⁻¹ (Σ_c X_cᵀ r_c r_cᵀ X_c) (XᵀX)⁻¹, widened by
/// the correction's own size on a count grid (`white` false: a count's error is white only while the angle crosses
/// counts quickly).
void robustEstimates(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const NoiseShare& gram,
                     const std::vector<Eigen::Index>& free, const std::vector<std::size_t>& cluster, bool white,
                     BodiesFit* fit)
{
  BodiesFit& out = *fit;
  const Eigen::MatrixXd xf = x(Eigen::all, free);
  Eigen::MatrixXd bread;
  const Eigen::VectorXd p = correctedSolve(x, y, gram, free, &bread);
  const Eigen::VectorXd r = y - xf * p;
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(xf.cols(), xf.cols());
  Eigen::VectorXd score = Eigen::VectorXd::Zero(xf.cols());
  std::size_t clusters = 0;
  for (Eigen::Index i = 0; i < xf.rows(); ++i)
  {
    score += xf.row(i).transpose() * r(i);
    const bool last =
        i + 1 == xf.rows() || cluster[static_cast<std::size_t>(i + 1)] != cluster[static_cast<std::size_t>(i)];
    if (last)
    {
      meat += score * score.transpose();
      score.setZero();
      ++clusters;
    }
  }
  const double g = static_cast<double>(clusters);
  out.swamped = !p.allFinite();
  const Eigen::MatrixXd cov = bread * meat * bread * (g > 1.0 ? g / (g - 1.0) : 1.0);
  // A count's error is white only while the angle crosses counts quickly: on a grid, the correction's own size is
  // counted as uncertain.
  const Eigen::VectorXd uncorrected =
      white ? p : correctedSolve(x, y, {Eigen::MatrixXd::Zero(7, 7), Eigen::VectorXd::Zero(7)}, free, nullptr);
  for (std::size_t i = 0; i < free.size(); ++i)
  {
    const Eigen::Index j = static_cast<Eigen::Index>(i);
    out.p(free[i]) = p(j);
    out.se(free[i]) = std::hypot(std::sqrt(cov(j, j)), p(j) - uncorrected(j));
  }
}
}  // namespace

BodiesFit fitBodies(const PhaseRows& apart, const PhaseRows& contact, double rho, double known_load,
                    std::pair<double, double> known_inertia, double noise, bool white)
{
  constexpr std::size_t FEWEST_ROWS = 20;
  const bool motor_alone = static_cast<std::size_t>(apart.x.rows()) >= FEWEST_ROWS;
  const bool pair = static_cast<std::size_t>(contact.x.rows()) >= FEWEST_ROWS;
  BodiesFit out;
  out.p = Eigen::VectorXd::Constant(7, NAN);
  out.se = Eigen::VectorXd::Constant(7, NAN);
  out.at_bound.assign(7, false);
  // Each phase's own residual level (its unconstrained fit) weights its rows.
  std::size_t kept = 0;
  if (motor_alone)
  {
    out.apart_rms = plainLeastSquares(apart.x.leftCols(3), apart.y).rms;
    out.apart_rows = static_cast<std::size_t>(apart.x.rows());
  }
  if (pair)
  {
    out.contact_rms = leastSquares(contact.x, contact.y, &kept).rms;
    out.contact_rows = static_cast<std::size_t>(contact.x.rows());
  }
  const Eigen::Index na = motor_alone ? apart.x.rows() : 0, nc = pair ? contact.x.rows() : 0;
  if (na + nc == 0)
  {
    return out;
  }
  const double wa = out.apart_rms > 0.0 ? 1.0 / out.apart_rms : 1.0;
  const double wc = out.contact_rms > 0.0 ? 1.0 / out.contact_rms : 1.0;
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(na + nc, 7);
  Eigen::VectorXd y(na + nc);
  std::vector<std::size_t> cluster;
  if (motor_alone)
  {
    x.topLeftCorner(na, 3) = wa * apart.x.leftCols(3);
    y.head(na) = wa * apart.y;
    cluster.insert(cluster.end(), apart.cluster.begin(), apart.cluster.end());
  }
  if (pair)
  {
    x.bottomLeftCorner(nc, 3) = wc * contact.x.leftCols(3);
    x.block(na, 3, nc, 2) = wc * rho * rho * contact.x.leftCols(2);
    x.block(na, 5, nc, 1) = wc * rho * contact.x.col(2);
    x.block(na, 6, nc, 1) = -wc * rho * contact.x.col(3);  // b = −ρT_ext
    y.tail(nc) = wc * contact.y;
    cluster.insert(cluster.end(), contact.cluster.begin(), contact.cluster.end());
  }
  // The angle's noise in XᵀX: the θ and ∫θ columns of each phase (the pair's also in J_L's and f_L's columns).
  NoiseShare share{Eigen::MatrixXd::Zero(7, 7), Eigen::VectorXd::Zero(7)};
  Eigen::MatrixXd& gram = share.gram;
  const double variance = noise * noise;
  if (motor_alone)
  {
    gram.topLeftCorner(2, 2) += wa * wa * variance * apart.noise_gram;
  }
  if (pair)
  {
    Eigen::MatrixXd map = Eigen::MatrixXd::Zero(2, 7);  // (θ, ∫θ) noise → the columns it enters
    map(0, 0) = 1.0;
    map(0, 3) = rho * rho;
    map(1, 1) = 1.0;
    map(1, 4) = rho * rho;
    gram += wc * wc * variance * map.transpose() * contact.noise_gram * map;
  }
  // The free columns: a phase without rows leaves its parameters out (the pair alone gives J_m + ρ²J_L, …: the
  // motor's columns then carry the pair's sums, reported by the caller as such); a known value moves its column to
  // the right-hand side (a known inertia splits the pair's inertia without the motor alone).
  const double known[7] = {known_inertia.first, NAN, NAN, known_inertia.second, NAN, NAN, known_load};
  const bool split = motor_alone || std::isfinite(known[0]) || std::isfinite(known[3]);
  std::vector<Eigen::Index> free;
  for (Eigen::Index j = 0; j < 7; ++j)
  {
    const bool present = j == 3 ? pair && split : j == 4 || j == 5 ? motor_alone && pair : j != 6 || pair;
    if (!present)
    {
      continue;
    }
    if (std::isfinite(known[j]))
    {
      y -= x.col(j) * known[j];
      share.rhs += gram.col(j) * known[j];
      continue;
    }
    free.push_back(j);
  }
  dropSpoiledPieces(share, free, na, &x, &y, &cluster, &out);
  if (!holdNegativeLevels(x, y, share, &free, &out))
  {
    return out;
  }
  robustEstimates(x, y, share, free, cluster, white, &out);
  for (Eigen::Index j : {0, 3, 6})
  {
    if (std::isfinite(known[j]) && (j == 0 || pair))
    {
      out.p(j) = known[j];
    }
  }
  return out;
}

}  // namespace backlash_servo
