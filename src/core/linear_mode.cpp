#include "backlash_servo/linear_mode.h"

#include <unsupported/Eigen/MatrixFunctions>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace backlash_servo
{
namespace
{
constexpr double INF = std::numeric_limits<double>::infinity();
}  // namespace

LinearMode::LinearMode(const Eigen::MatrixXd& a, const Eigen::VectorXd& u, const Eigen::VectorXd& x0)
    : a_(a), u_(u), x0_(x0)
{
  const Eigen::Index n = x0.size();
  if (n < 1 || a.rows() != n || a.cols() != n || u.size() != n)
  {
    throw std::invalid_argument("LinearMode: A must be n × n and u, x0 of size n");
  }
  if (!a.allFinite() || !u.allFinite() || !x0.allFinite())
  {
    throw std::invalid_argument("LinearMode: A, u and x0 must be finite");
  }
  aug_ = Eigen::MatrixXd::Zero(n + 1, n + 1);
  aug_.topLeftCorner(n, n) = a;
  aug_.topRightCorner(n, 1) = u;
  // Diagonal balancing D (Parlett–Reinsch, powers of 2): Â = D⁻¹AD has the mode's frequencies without the spread of
  // units between positions and speeds (c/J against 1), so the search's windows are as long as the motion allows.
  bal_ = Eigen::VectorXd::Ones(n);
  Eigen::MatrixXd b = a;
  for (bool changed = true; changed;)
  {
    changed = false;
    for (Eigen::Index i = 0; i < n; ++i)
    {
      double c = 0.0, r = 0.0;
      for (Eigen::Index j = 0; j < n; ++j)
      {
        if (j != i)
        {
          c += std::fabs(b(j, i));
          r += std::fabs(b(i, j));
        }
      }
      if (c == 0.0 || r == 0.0)
      {
        continue;
      }
      const double sum = c + r;
      double f = 1.0;
      while (c < 0.5 * r)
      {
        c *= 2.0;
        r *= 0.5;
        f *= 2.0;
      }
      while (c >= 2.0 * r)
      {
        c *= 0.5;
        r *= 2.0;
        f *= 0.5;
      }
      if (c + r < 0.95 * sum)
      {
        bal_(i) *= f;
        b.row(i) /= f;
        b.col(i) *= f;
        changed = true;
      }
    }
  }
  balanced_ = b;
  norm_a_ = b.operatorNorm();
  Eigen::ComplexEigenSolver<Eigen::MatrixXcd> solver(aug_.cast<std::complex<double>>());
  if (solver.info() == Eigen::Success)
  {
    const Eigen::JacobiSVD<Eigen::MatrixXcd> svd(solver.eigenvectors());
    const auto& sv = svd.singularValues();
    if (sv(sv.size() - 1) > 0.0 && sv(0) / sv(sv.size() - 1) <= MAX_EIGENBASIS_CONDITION)
    {
      v_ = solver.eigenvectors();
      lambda_ = solver.eigenvalues();
      Eigen::VectorXcd z0(n + 1);
      z0.head(n) = x0.cast<std::complex<double>>();
      z0(n) = 1.0;
      c_ = v_.partialPivLu().solve(z0);
      modal_ = true;
    }
  }
}

Eigen::VectorXd LinearMode::state(double tau) const
{
  const Eigen::Index n = x0_.size();
  if (tau == 0.0)
  {
    return x0_;
  }
  if (modal_)
  {
    Eigen::VectorXcd e(lambda_.size());
    for (Eigen::Index k = 0; k < lambda_.size(); ++k)
    {
      e(k) = std::exp(lambda_(k) * tau) * c_(k);
    }
    return (v_ * e).head(n).real();
  }
  Eigen::VectorXd z0(n + 1);
  z0.head(n) = x0_;
  z0(n) = 1.0;
  const Eigen::MatrixXd e = (aug_ * tau).exp();
  return (e * z0).head(n);
}

Eigen::VectorXd LinearMode::rate(double tau) const
{
  return a_ * state(tau) + u_;
}

double LinearMode::output(const Eigen::VectorXd& w, double w0, double tau) const
{
  return w.dot(state(tau)) + w0;
}

Eigen::VectorXcd LinearMode::eigenvalues() const
{
  return Eigen::EigenSolver<Eigen::MatrixXd>(a_).eigenvalues();
}

double LinearMode::firstCrossing(const Eigen::VectorXd& w, double w0, int direction, double horizon, double from) const
{
  if (!(horizon > 0.0) || (direction != 1 && direction != -1))
  {
    return INF;
  }
  // In the balanced basis x = D x̂: s = (Dw)·x̂ + w₀, s'' = (Dw)ᵀ Â exp(Ât) (D⁻¹ẋ).
  const double wa = (w.cwiseProduct(bal_).transpose() * balanced_).norm();
  const double scale = norm_a_ > 0.0 ? 1.0 / norm_a_ : horizon;  // the fastest time scale [s]
  const double floor = FLOOR_FRACTION * scale;
  {
    // An output that is zero with all its derivatives at the start (wᵀAᵏẋ = 0, k < n: the output does not see the
    // motion at all, e.g. the velocity of a body at rest on which nothing acts) stays zero: it never crosses.
    const Eigen::VectorXd x = state(from);
    Eigen::VectorXd v = a_ * x + u_;
    const double eps = 64.0 * std::numeric_limits<double>::epsilon();
    bool flat = std::fabs(w.dot(x) + w0) <= eps * (w.cwiseAbs().dot(x.cwiseAbs()) + std::fabs(w0));
    for (int k = 0; flat && k < order(); ++k)
    {
      flat = std::fabs(w.dot(v)) <= eps * w.cwiseAbs().dot(v.cwiseAbs());
      v = a_ * v;
    }
    if (flat)
    {
      return INF;
    }
  }
  double t = from;
  while (t < horizon)
  {
    // A window the exclusion test is likely to pass: where the remainder bound reaches about |s|.
    const Eigen::VectorXd x = state(t);
    const double s = w.dot(x) + w0;
    const double m = wa * (a_ * x + u_).cwiseQuotient(bal_).norm() * std::exp(1.0);
    double h = m > 0.0 ? std::sqrt(std::fabs(s) / m) : horizon;
    // (At least a thousandth of the fastest time scale: an output hovering near zero is searched by halving the
    // window, not by crawling.)
    h = std::min({std::max(h, 1e-3 * scale), scale, horizon - t});
    const double hit = searchWindow(w, w0, direction, t, t + h, wa, floor);
    if (hit < INF)
    {
      return hit;
    }
    t += h;
  }
  return INF;
}

double LinearMode::searchWindow(const Eigen::VectorXd& w, double w0, int direction, double lo, double hi, double wa,
                                double floor) const
{
  const Eigen::VectorXd x = state(lo);
  const Eigen::VectorXd xd = a_ * x + u_;
  const double s = w.dot(x) + w0;
  const double s1 = w.dot(xd);
  const double h = hi - lo;
  const double m = wa * xd.cwiseQuotient(bal_).norm() * std::exp(norm_a_ * h);  // ≥ max |s''| on the window
  // What rounding can do to an evaluated output (the closed form's error, relative to the terms it sums).
  const double noise = (modal_ ? 64.0 : 4096.0) * std::numeric_limits<double>::epsilon() *
                       (w.cwiseAbs().dot(x.cwiseAbs()) + std::fabs(w0));
  const double margin = 0.5 * m * h * h + noise;
  const double end = s + s1 * h;
  if ((s > margin && end > margin) || (s < -margin && end < -margin))
  {
    return INF;  // the linear part keeps one sign beyond the remainder: no zero here
  }
  const double s_hi = output(w, w0, hi);
  const bool changes = direction * s <= 0.0 && direction * s_hi > 0.0;
  if (std::fabs(s1) > m * h)
  {
    // s' keeps its sign on the window (|s'(τ) − s'(lo)| ≤ M h): s is monotone, one zero at most.
    return changes ? bisect(w, w0, direction, lo, hi) : INF;
  }
  if (h <= floor)
  {
    // Within the floor of a turning point: a sign change is the crossing; none is a grazing (see the file comment).
    return changes ? bisect(w, w0, direction, lo, hi) : INF;
  }
  const double mid = lo + 0.5 * h;
  const double first = searchWindow(w, w0, direction, lo, mid, wa, floor);
  return first < INF ? first : searchWindow(w, w0, direction, mid, hi, wa, floor);
}

double LinearMode::bisect(const Eigen::VectorXd& w, double w0, int direction, double lo, double hi) const
{
  for (int i = 0; i < 200; ++i)
  {
    const double mid = lo + 0.5 * (hi - lo);
    if (!(mid > lo && mid < hi))
    {
      break;
    }
    (direction * output(w, w0, mid) > 0.0 ? hi : lo) = mid;
  }
  return hi;
}

}  // namespace backlash_servo
