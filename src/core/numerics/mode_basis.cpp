#include "numerics/mode_basis.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace backlash_servo
{
ModeBasis::ModeBasis(const Eigen::MatrixXd& a) : a_(a)
{
  const Eigen::Index n = a.rows();
  if (n < 1 || a.cols() != n || n > MAX_MODE_ORDER)
  {
    throw std::invalid_argument("LinearMode: A must be n × n, n ≤ " + std::to_string(MAX_MODE_ORDER));
  }
  if (!a.allFinite())
  {
    throw std::invalid_argument("LinearMode: A, u and x0 must be finite");
  }
  // Diagonal balancing D (Parlett–Reinsch, powers of 2): Â = D⁻¹AD has the mode's frequencies without the spread of
  // units between positions and speeds (c/J against 1), so the search's windows are as long as the motion allows.
  bal_ = ModeVector::Ones(n);
  Eigen::MatrixXd b = a;  // (the decompositions below on heap storage: they run once per mode)
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
  inv_bal_ = bal_.cwiseInverse();
  norm_a_ = b.operatorNorm();
  const double eps = std::numeric_limits<double>::epsilon();
  rounding_ = 256.0 * eps;  // the Taylor steps' (a few ulps per step, over the steps of a long motion)
  const Eigen::EigenSolver<Eigen::MatrixXd> solver(b);
  if (solver.info() == Eigen::Success && useBasis(solver.eigenvectors(), solver.eigenvalues(), 0))
  {
    return;
  }
  splitNilpotent(b);
}

bool ModeBasis::useBasis(const Eigen::MatrixXcd& v, const Eigen::VectorXcd& lambda, int nilpotent_order)
{
  const Eigen::JacobiSVD<Eigen::MatrixXcd> svd(v);
  const auto& sv = svd.singularValues();
  if (!(sv(sv.size() - 1) > 0.0) || !(sv(0) / sv(sv.size() - 1) <= MAX_EIGENBASIS_CONDITION))
  {
    return false;
  }
  v_ = v;
  lambda_ = lambda;
  v_inv_ = v.inverse();
  nil_ = nilpotent_order;
  // A complex pair's two terms are conjugates: the first, doubled, is their sum's real part (half the work).
  const Eigen::Index r = v.cols() - nil_;
  weight_.setOnes(r);
  for (Eigen::Index k = 0; k + 1 < r; ++k)
  {
    if (lambda(k).imag() != 0.0 && lambda(k + 1) == std::conj(lambda(k)) && v.col(k + 1) == v.col(k).conjugate())
    {
      weight_(k) = 2.0;
      weight_(k + 1) = 0.0;
      ++k;
    }
  }
  speed_.resize(r);
  dvl_re_.resize(v.rows(), r);
  dvl_im_.resize(v.rows(), r);
  for (Eigen::Index k = 0; k < r; ++k)
  {
    speed_(k) = std::abs(lambda(k));
    for (Eigen::Index j = 0; j < v.rows(); ++j)
    {
      const std::complex<double> e = bal_(j) * v(j, k) * lambda(k);
      dvl_re_(j, k) = e.real();
      dvl_im_(j, k) = e.imag();
    }
  }
  n_active_ = 0;
  for (Eigen::Index k = 0; k < r; ++k)
  {
    if (weight_(k) != 0.0)
    {
      active_[static_cast<std::size_t>(n_active_++)] = static_cast<int>(k);
    }
  }
  dv_re_.resize(v.rows(), n_active_);
  dv_im_.resize(v.rows(), n_active_);
  for (int c = 0; c < n_active_; ++c)
  {
    for (Eigen::Index j = 0; j < v.rows(); ++j)
    {
      dv_re_(j, c) = bal_(j) * v(j, active_[static_cast<std::size_t>(c)]).real();
      dv_im_(j, c) = bal_(j) * v(j, active_[static_cast<std::size_t>(c)]).imag();
    }
  }
  modal_ = true;
  rounding_ = 64.0 * std::numeric_limits<double>::epsilon() * sv(0) / sv(sv.size() - 1);
  return true;
}

void ModeBasis::splitNilpotent(const Eigen::MatrixXd& b)
{
  // Â's zero eigenvalue without a full eigenspace (a body's position, on which nothing depends or which only the
  // drive law reads): ℝⁿ = ker Â^K ⊕ range Â^K for the index K of that eigenvalue, both invariant. On the range Â is
  // invertible and diagonalised as usual; on the kernel it is nilpotent, so there the motion is a polynomial.
  const Eigen::Index n = b.rows();
  if (!(norm_a_ > 0.0))
  {
    return;
  }
  Eigen::MatrixXd power = Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd kernel, range;
  for (Eigen::Index k = 1; k <= n; ++k)
  {
    power = (b * power).eval();
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(power, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const auto& sv = svd.singularValues();
    // The candidates: singular values to CHAIN_TOLERANCE of the largest — exact zeros of a structurally singular Â
    // (the case this is for) stay within a few ulps of it; a chain whose end is not quite zero (the common drift of
    // bodies with viscous friction, λ a small fraction of ‖Â‖) gives about |λ|/‖Â‖.
    Eigen::Index rank = 0;
    while (rank < n && sv(rank) > CHAIN_TOLERANCE * sv(0))
    {
      ++rank;
    }
    // Grown by a chain only: Â maps each new direction into ker Â^{k−1} (to CHAIN_TOLERANCE of ‖Â‖, which lets in a
    // mode the slow block's series can follow). A mode merely slow (Âv = λv, 4e-5 of ‖Â‖, say) also falls below the
    // threshold by Â³, but is no chain: it stays with the modes diagonalised — the largest set of the smallest
    // singular directions that is a chain grows the kernel (the slow mode's, with a larger singular value, left out).
    Eigen::Index grows = 0;
    for (Eigen::Index d = n - rank; d > kernel.cols() && grows == 0; --d)
    {
      const Eigen::MatrixXd grown = svd.matrixV().rightCols(d);
      Eigen::MatrixXd image = b * grown;
      if (kernel.cols() > 0)
      {
        image -= kernel * (kernel.transpose() * image);
      }
      if (image.norm() <= CHAIN_TOLERANCE * norm_a_)
      {
        grows = d;
      }
    }
    if (grows == 0)
    {
      break;  // ker Â^k no longer grows by a chain: the index is k − 1
    }
    kernel = svd.matrixV().rightCols(grows);
    range = svd.matrixU().leftCols(n - grows);
  }
  const Eigen::Index m = kernel.cols(), r = n - m;
  if (m == 0)
  {
    return;  // no zero eigenvalue: defective elsewhere (a critically damped pair), the Taylor series
  }
  Eigen::MatrixXd t(n, n);
  t << range, kernel;
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(t);
  if (!lu.isInvertible())
  {
    return;
  }
  Eigen::MatrixXd blocks = lu.solve(b * t);
  // Both subspaces invariant and the kernel's block nilpotent to within NEAR_SPLIT; else the Taylor series.
  const double norm_m = std::pow(norm_a_, static_cast<double>(m));
  const auto coupling = [&] {
    return std::max(blocks.topRightCorner(r, m).norm(), blocks.bottomLeftCorner(m, r).norm()) / norm_a_;
  };
  const auto nilpotency = [&] {
    Eigen::MatrixXd power_m = Eigen::MatrixXd::Identity(m, m);
    for (Eigen::Index k = 0; k < m; ++k)
    {
      power_m = (blocks.bottomRightCorner(m, m) * power_m).eval();
    }
    return power_m.norm() / norm_m;
  };
  const double split_coupling = coupling(), split_remainder = nilpotency();
  if (split_coupling > NEAR_SPLIT || split_remainder > NEAR_SPLIT)
  {
    return;
  }
  poly_terms_ = static_cast<int>(m);
  if (split_coupling > EXACT_SPLIT || split_remainder > EXACT_SPLIT)
  {
    // A zero eigenvalue's neighbour that is merely small (a body's viscous friction f/J ~ 1e-9 of the mesh's
    // frequency): the split is exact only once decoupled, and the slow block is not nilpotent — its series runs on.
    if (!decouple(r, m, &t, &blocks) || !(coupling() <= EXACT_SPLIT))
    {
      return;
    }
    poly_terms_ = slowTerms(blocks.bottomRightCorner(m, m));
    if (poly_terms_ > MAX_MODE_ORDER)
    {
      return;
    }
  }
  Eigen::MatrixXcd v(n, n);
  Eigen::VectorXcd lambda = Eigen::VectorXcd::Zero(n);
  if (r > 0)
  {
    const Eigen::EigenSolver<Eigen::MatrixXd> solver(blocks.topLeftCorner(r, r));
    if (solver.info() != Eigen::Success)
    {
      return;
    }
    v << t.leftCols(r) * solver.eigenvectors(), t.rightCols(m).cast<std::complex<double>>();
    lambda.head(r) = solver.eigenvalues();
  }
  else
  {
    v = t.cast<std::complex<double>>();
  }
  if (useBasis(v, lambda, static_cast<int>(m)))
  {
    nilpotent_ = blocks.bottomRightCorner(m, m);
  }
}

namespace
{
/// X (r × m) with F X − X S = R, by the Kronecker form (I ⊗ F − Sᵀ ⊗ I) vec X = vec R; false if singular.
bool solveSylvester(const Eigen::MatrixXd& f, const Eigen::MatrixXd& s, const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x)
{
  const Eigen::Index r = f.rows(), m = s.rows();
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(r * m, r * m);
  for (Eigen::Index j = 0; j < m; ++j)
  {
    k.block(j * r, j * r, r, r) += f;
    for (Eigen::Index i = 0; i < m; ++i)
    {
      k.block(j * r, i * r, r, r) -= s(i, j) * Eigen::MatrixXd::Identity(r, r);
    }
  }
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(k);
  if (!lu.isInvertible())
  {
    return false;
  }
  const Eigen::VectorXd vec = lu.solve(Eigen::Map<const Eigen::VectorXd>(rhs.data(), r * m));
  *x = Eigen::Map<const Eigen::MatrixXd>(vec.data(), r, m);
  return x->allFinite();
}
}  // namespace

bool ModeBasis::decouple(Eigen::Index r, Eigen::Index m, Eigen::MatrixXd* t, Eigen::MatrixXd* blocks)
{
  // With T⁻¹ÂT = [F C; D S], L = [I X; Y I] block-diagonalises it: T⁻¹ÂT L = L diag(F + CY, S + DX) when
  // F X − X S = X D X − C and Y F − S Y = D − Y C Y (the first from X = 0, Y = 0; the quadratic terms are of the
  // couplings' order squared, a second pass takes them).
  const Eigen::MatrixXd f = blocks->topLeftCorner(r, r), c = blocks->topRightCorner(r, m);
  const Eigen::MatrixXd d = blocks->bottomLeftCorner(m, r), s = blocks->bottomRightCorner(m, m);
  Eigen::MatrixXd x = Eigen::MatrixXd::Zero(r, m), y = Eigen::MatrixXd::Zero(m, r), yt;
  for (int pass = 0; pass < 2; ++pass)
  {
    // (Y F − S Y = R as Fᵀ Yᵀ − Yᵀ Sᵀ = Rᵀ.)
    if (!solveSylvester(f, s, x * d * x - c, &x) ||
        !solveSylvester(f.transpose(), s.transpose(), (d - y * c * y).transpose(), &yt))
    {
      return false;
    }
    y = yt.transpose();
  }
  // The couplings are small, so X and Y are: L stays near the identity (else the subspaces were not split).
  if (!(x.norm() < 1e-3 && y.norm() < 1e-3))
  {
    return false;
  }
  const Eigen::Index n = r + m;
  Eigen::MatrixXd l = Eigen::MatrixXd::Identity(n, n);
  l.topRightCorner(r, m) = x;
  l.bottomLeftCorner(m, r) = y;
  *t = (*t * l).eval();
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(*t);
  if (!lu.isInvertible())
  {
    return false;
  }
  *blocks = lu.solve(balanced_ * *t);
  return true;
}

int ModeBasis::slowTerms(const Eigen::MatrixXd& s) const
{
  // The slow block's series Σ_j Sʲ g τ^{j+1}/(j + 1)! summed to the term that no longer changes a bit of the largest
  // (2⁻⁵⁵ of it, and every later one smaller still) anywhere on τ ≤ SERIES_SPAN/‖Â‖₂.
  const double span = SERIES_SPAN / norm_a_;
  Eigen::MatrixXd power = Eigen::MatrixXd::Identity(s.rows(), s.cols());
  double largest = 0.0, term = 0.0, scale = 1.0;  // scale = span^{j+1}/(j + 1)!
  for (int j = 0; j <= MAX_MODE_ORDER; ++j)
  {
    scale *= span / static_cast<double>(j + 1);
    term = power.norm() * scale;
    largest = std::max(largest, term);
    if (j >= s.rows() && term <= 0x1p-55 * largest)
    {
      return j;
    }
    power = (s * power).eval();
  }
  return MAX_MODE_ORDER + 1;
}

const ModeBasis::OutputReach& ModeBasis::reach(const ModeVector& w) const
{
  for (std::size_t i = 0; i < reaches_kept_; ++i)
  {
    if (reaches_[i].w.size() == w.size() && reaches_[i].w == w)
    {
      return reaches_[i];
    }
  }
  OutputReach& o = reaches_[reaches_next_];
  reaches_next_ = (reaches_next_ + 1) % reaches_.size();
  reaches_kept_ = std::max(reaches_kept_, reaches_next_ == 0 ? reaches_.size() : reaches_next_);
  o.w = w;
  o.weight = 0.0;
  for (Eigen::Index j = 0; j < w.size(); ++j)
  {
    o.weight += std::fabs(w(j)) * bal_(j);
  }
  if (modal_)
  {
    const Eigen::Index n = w.size(), r = n - nil_;
    o.size.resize(r);
    for (Eigen::Index i = 0; i < r; ++i)
    {
      if (weight_(i) == 0.0)
      {
        o.size(i) = 0.0;
        continue;
      }
      double c_re = 0.0, c_im = 0.0;  // wᵀD v_i λ_i
      for (Eigen::Index j = 0; j < n; ++j)
      {
        c_re += dvl_re_(j, i) * w(j);
        c_im += dvl_im_(j, i) * w(j);
      }
      // By hypot only where the squares could overflow or underflow. (An output the mode does not reach — a body's
      // speed in a mode of the other body — has none.)
      const double squares = c_re * c_re + c_im * c_im;
      o.size(i) = c_re == 0.0 && c_im == 0.0            ? 0.0
                  : squares > 1e-290 && squares < 1e290 ? std::sqrt(squares)
                                                        : std::hypot(c_re, c_im);
    }
  }
  return o;
}

Eigen::VectorXcd ModeBasis::eigenvalues() const
{
  return Eigen::EigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(a_)).eigenvalues();
}
}  // namespace backlash_servo
