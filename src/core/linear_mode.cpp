#include "backlash_servo/linear_mode.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace backlash_servo
{
namespace
{
constexpr double INF = std::numeric_limits<double>::infinity();

/// a·x, plus u where given (plain loops: at these orders Eigen's general product costs more in dispatch than in
/// arithmetic). The product is summed before u is added, as Eigen does: near an equilibrium the two cancel, and the
/// event search's windows depend on how the rounding of that difference falls (adding u first made a stiff case halve
/// ten times as often).
ModeVector product(const ModeMatrix& a, const ModeVector& x, const ModeVector* u = nullptr)
{
  const Eigen::Index n = x.size();
  ModeVector y(n);
  for (Eigen::Index i = 0; i < n; ++i)
  {
    double sum = 0.0;
    for (Eigen::Index j = 0; j < n; ++j)
    {
      sum += a(i, j) * x(j);
    }
    y(i) = u != nullptr ? sum + (*u)(i) : sum;
  }
  return y;
}

/// a·x + u.
ModeVector affine(const ModeMatrix& a, const ModeVector& x, const ModeVector& u)
{
  return product(a, x, &u);
}

/**
 * a·x + u, as affine() where its terms do not cancel, else as if in twice the working precision, rounded once (Ogita,
 * Rump & Oishi's Dot2: each product's error by fma, each sum's by TwoSum, the errors summed apart). A mesh's torque
 * c(ρθ_m − θ_o) is a small difference of large terms when the angles are large against the penetration (a joint that
 * has turned 9e4 rad), and the motion's start rate ẋ₀ = Ax₀ + u carries that error through the whole segment — as a
 * force the stored state does not explain, whose work the energy ledger then misses. (Compensating every row cost
 * the compliant robot joint 2 % more instructions; a row is compensated where more than half its digits cancel.)
 */
ModeVector affineCompensated(const ModeMatrix& a, const ModeVector& x, const ModeVector& u)
{
  const Eigen::Index n = x.size();
  ModeVector y = affine(a, x, u);
  const auto twoSum = [](double p, double q, double* err) {
    const double s = p + q, z = s - p;
    *err += (p - (s - z)) + (q - z);
    return s;
  };
  for (Eigen::Index i = 0; i < n; ++i)
  {
    double size = 0.0;
    for (Eigen::Index j = 0; j < n; ++j)
    {
      size += std::fabs(a(i, j) * x(j));
    }
    if (!(std::fabs(y(i)) < 0x1p-26 * (size + std::fabs(u(i)))))
    {
      continue;
    }
    double sum = 0.0, err = 0.0;
    for (Eigen::Index j = 0; j < n; ++j)
    {
      const double p = a(i, j) * x(j);
      err += std::fma(a(i, j), x(j), -p);
      sum = twoSum(sum, p, &err);
    }
    sum = twoSum(sum, u(i), &err);
    y(i) = sum + err;
  }
  return y;
}
}  // namespace

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
    // Exact zeros of a structurally singular Â (the case this is for) stay within a few ulps of its largest
    // singular value's; anything larger is an eigenvalue that is merely small and is left to the check below.
    Eigen::Index rank = 0;
    while (rank < n && sv(rank) > 1e-12 * sv(0))
    {
      ++rank;
    }
    if (n - rank == kernel.cols())
    {
      break;  // ker Â^k no longer grows: the index is k − 1
    }
    // Grown by a chain only: Â maps each new direction into ker Â^{k−1} (to CHAIN_TOLERANCE of ‖Â‖, which lets in a
    // mode the slow block's series can follow). A mode merely slow (Âv = λv, 4e-5 of ‖Â‖, say) also falls below the
    // rank threshold by Â³, but is no chain: it stays with the modes diagonalised.
    const Eigen::MatrixXd grown = svd.matrixV().rightCols(n - rank);
    Eigen::MatrixXd image = b * grown;
    if (kernel.cols() > 0)
    {
      image -= kernel * (kernel.transpose() * image);
    }
    if (image.norm() > CHAIN_TOLERANCE * norm_a_)
    {
      break;
    }
    kernel = grown;
    range = svd.matrixU().leftCols(rank);
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
  const double span = LinearMode::SERIES_SPAN / norm_a_;
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

Eigen::VectorXcd ModeBasis::eigenvalues() const
{
  return Eigen::EigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(a_)).eigenvalues();
}

LinearMode::LinearMode(const Eigen::MatrixXd& a, const ModeVector& u, const ModeVector& x0)
    : LinearMode(std::make_shared<const ModeBasis>(a), u, x0)
{}

LinearMode::LinearMode(std::shared_ptr<const ModeBasis> basis, const ModeVector& u, const ModeVector& x0)
    : basis_(std::move(basis)), u_(u), x0_(x0)
{
  const Eigen::Index n = x0.size();
  if (n < 1 || basis_->order() != n || u.size() != n)
  {
    throw std::invalid_argument("LinearMode: A must be n × n and u, x0 of size n");
  }
  if (!u.allFinite() || !x0.allFinite())
  {
    throw std::invalid_argument("LinearMode: A, u and x0 must be finite");
  }
  // The motion is solved as the deviation δ = x − x₀ (δ̇ = Aδ + v₀, v₀ = Ax₀ + u, δ(0) = 0), so that its rounding is
  // relative to how far the state has moved, not to the angles it started at (which grow without bound).
  v0_ = affineCompensated(basis_->a_, x0_, u_);
  if (basis_->modal_)
  {
    // (Plain loops: Eigen's general products carry a dispatch overhead that dominates at these orders.)
    g_.resize(n);
    for (Eigen::Index k = 0; k < n; ++k)
    {
      std::complex<double> sum = 0.0;
      for (Eigen::Index j = 0; j < n; ++j)
      {
        sum += basis_->v_inv_(k, j) * (v0_(j) / basis_->bal_(j));
      }
      g_(k) = sum;
    }
    for (Eigen::Index k = 0; k + 1 < n; ++k)
    {
      if (basis_->weight_.size() > k && basis_->weight_(k) == 2.0)
      {
        // A pair's two terms sum to 2 Re(v_k f(λ_k) ḡ) with ḡ the mean of g_k and conj g_{k+1} — exactly, whatever
        // the rounding of V⁻¹ left between them.
        g_(k) = 0.5 * (g_(k) + std::conj(g_(k + 1)));
        g_(k + 1) = std::conj(g_(k));
      }
    }
    g_abs_.resize(n);
    for (Eigen::Index k = 0; k < n; ++k)
    {
      g_abs_(k) = std::abs(g_(k));
    }
    g_over_lambda_.resize(n);  // used only where |λτ| ≥ 0.1
    for (Eigen::Index k = 0; k < n; ++k)
    {
      const std::complex<double> l = basis_->lambda_(k);
      g_over_lambda_(k) = l == 0.0 ? 0.0 : g_(k) / l;
    }
    // The slow block's coordinates y (ẏ = N y + g_N, y(0) = 0): y(τ) = Σ_j Nʲ g_N τ^{j+1}/(j + 1)!, a polynomial
    // (N nilpotent: m terms; a merely slow block: the terms its basis counted).
    const int m = basis_->nil_;
    if (m > 0)
    {
      // The split's bases mix the coordinates, so a coordinate that does not move (δ_i = Σ_k (A^k v₀)_i τ^{k+1}/(k+1)!
      // with every (A^k v₀)_i = 0, k < n: a body at rest that nothing acts on) would show rounding crumbs; those
      // stay exactly where they are.
      ModeVector krylov = v0_;
      for (Eigen::Index k = 0; k < n; ++k)
      {
        for (Eigen::Index i = 0; i < n; ++i)
        {
          moving_ |= krylov(i) != 0.0 ? 1u << i : 0u;
        }
        krylov = affine(basis_->a_, krylov, ModeVector::Zero(n));
      }
    }
    else
    {
      moving_ = ~0u;
    }
    const int terms = basis_->poly_terms_;
    poly_.resize(n, terms);
    ModeVector c(m);
    for (int i = 0; i < m; ++i)
    {
      c(i) = g_(n - m + i).real();
    }
    for (int j = 0; j < terms; ++j)
    {
      if (j > 0)
      {
        c = (basis_->nilpotent_ * c / static_cast<double>(j + 1)).eval();
      }
      for (Eigen::Index i = 0; i < n; ++i)
      {
        double sum = 0.0;
        for (int l = 0; l < m; ++l)
        {
          sum += basis_->v_(i, n - m + l).real() * c(l);
        }
        poly_(i, j) = sum;
      }
    }
  }
  else
  {
    step_ = basis_->norm_a_ > 0.0 ? TAYLOR_STEP / basis_->norm_a_ : INF;
    checkpoints_.push_back(ModeVector::Zero(n));
  }
}

ModeVector LinearMode::taylorState(double tau) const
{
  // Anchors δ̂ at multiples of the step from the start, each from the one before: a pure function of τ, whatever order
  // the states are asked in.
  const double index = std::isfinite(step_) ? std::floor(tau / step_) : 0.0;
  if (!(index < 1e15))
  {
    throw std::length_error("LinearMode: a motion of more than 1e15 of its fastest time scales without an event");
  }
  const std::size_t i = static_cast<std::size_t>(index);
  // The Taylor coefficients of the last few anchors used (a search goes back and forth between neighbours).
  KrylovEntry* entry = nullptr;
  for (KrylovEntry& e : krylov_)
  {
    if (e.anchor == i)
    {
      entry = &e;
    }
  }
  if (entry == nullptr)
  {
    entry = &krylov_[krylov_next_];
    krylov_next_ = (krylov_next_ + 1) % krylov_.size();
    setKrylov(anchor(i), &entry->k);
    entry->anchor = i;
  }
  return x0_ + taylor(entry->k, tau - index * step_).cwiseProduct(basis_->bal_);
}

const ModeVector& LinearMode::anchor(std::size_t i) const
{
  // All of the first DENSE_ANCHORS; beyond, every CHECKPOINT-th and the farthest reached (memory stays bounded over a
  // long motion without events; a query behind the frontier repeats at most CHECKPOINT steps from a checkpoint).
  while (i >= checkpoints_.size() && checkpoints_.size() < DENSE_ANCHORS)
  {
    checkpoints_.push_back(taylor(checkpoints_.back(), step_));
  }
  if (i < DENSE_ANCHORS)
  {
    return checkpoints_[i];
  }
  // Kept anchor c (c ≥ DENSE_ANCHORS − 1) is anchor number DENSE_ANCHORS − 1 + (c − DENSE_ANCHORS + 1)·CHECKPOINT.
  constexpr std::size_t base = DENSE_ANCHORS - 1;
  const auto checkpoint = [](std::size_t k) { return base + (k - base) / CHECKPOINT; };
  if (frontier_index_ < DENSE_ANCHORS || i < frontier_index_)
  {
    const std::size_t c = std::min(checkpoint(i), checkpoints_.size() - 1);
    frontier_index_ = base + (c - base) * CHECKPOINT;
    frontier_ = checkpoints_[c];
  }
  while (frontier_index_ < i)
  {
    frontier_ = taylor(frontier_, step_);
    ++frontier_index_;
    if ((frontier_index_ - base) % CHECKPOINT == 0 && checkpoint(frontier_index_) == checkpoints_.size())
    {
      checkpoints_.push_back(frontier_);
    }
  }
  return frontier_;
}

void LinearMode::setKrylov(const ModeVector& xa, KrylovMatrix* k) const
{
  // δ̂(a + r) = Σ_j k_j r^j with k_0 = δ̂_a, k_1 = Âδ̂_a + v̂₀, k_j = Â k_{j−1} / j: ‖Â r‖ ≤ ½, so the terms fall below
  // 2⁻ʲ/j! of the first ones — TAYLOR_TERMS of them reach rounding.
  k->resize(xa.size(), TAYLOR_TERMS + 1);
  k->col(0) = xa;
  k->col(1).noalias() = basis_->balanced_ * xa;
  k->col(1) += v0_.cwiseQuotient(basis_->bal_);
  for (int j = 2; j <= TAYLOR_TERMS; ++j)
  {
    k->col(j).noalias() = basis_->balanced_ * k->col(j - 1);
    k->col(j) /= static_cast<double>(j);
  }
}

ModeVector LinearMode::taylor(const KrylovMatrix& k, double r)
{
  ModeVector x = k.col(k.cols() - 1);
  for (Eigen::Index j = k.cols() - 2; j >= 0; --j)
  {
    x = x * r + k.col(j);
  }
  return x;
}

ModeVector LinearMode::taylor(const ModeVector& xa, double r) const
{
  setKrylov(xa, &step_krylov_);
  return taylor(step_krylov_, r);
}

ModeVector LinearMode::state(double tau) const
{
  if (tau == 0.0)
  {
    return x0_;
  }
  // The searches of a segment's outputs ask for the same instants (a window's ends, the event, the end of a step):
  // the last few are kept.
  for (const Memo& m : memo_)
  {
    if (m.tau == tau)
    {
      return m.x;
    }
  }
  Memo& slot = memo_[memo_next_];
  memo_next_ = (memo_next_ + 1) % memo_.size();
  slot.x = evaluate(tau);
  slot.tau = tau;
  return slot.x;
}

ModeVector LinearMode::evaluate(double tau) const
{
  const Eigen::Index n = x0_.size();
  if (basis_->modal_)
  {
    // δ = D Σ_k v_k τ φ₁(λ_k τ) g_k: τφ₁(λτ) g = (e^{λτ} − 1) g/λ, by φ₁'s series where that would cancel.
    // (In real arithmetic, the products written out as (a + jb)(c + jd) = (ac − bd) + j(ad + bc) — the same
    // operations as std::complex's, without its checks for infinities, which cost two thirds of the evaluation.)
    const ModeVectorC& lambda = basis_->lambda_;
    const Eigen::Index r = n - basis_->nil_;
    const ModeVector& weight = basis_->weight_;
    std::array<double, MAX_MODE_ORDER> e_re{}, e_im{};
    for (Eigen::Index k = 0; k < r; ++k)
    {
      if (weight(k) == 0.0)
      {
        continue;  // (a pair's conjugate: counted in its partner's doubled term)
      }
      const double re = lambda(k).real() * tau, im = lambda(k).imag() * tau;
      double a, b;  // e^{λτ} − 1 over λ, or τφ₁(λτ)
      double c, d;  // g/λ, or g
      const bool series = re * re + im * im < 0.01;
      if (series)
      {
        // The terms to the tenth, but for those that can no longer change a bit of the sum: each later term is
        // smaller than this one times |z| < 0.1, and one below a quarter of a component's ulp (> 2⁻⁵⁵ of it) leaves
        // that component as it is.
        double p_re = 1.0, p_im = 0.0, t_re = 1.0, t_im = 0.0;  // φ₁ and its series' term
        const double z_abs = std::fabs(re) + std::fabs(im), quarter_ulp = 0x1p-55;
        for (int j = 2; j <= 10; ++j)
        {
          const double inv = 1.0 / j, z_re = re * inv, z_im = im * inv;
          const double next_re = t_re * z_re - t_im * z_im;
          t_im = t_re * z_im + t_im * z_re;
          t_re = next_re;
          p_re += t_re;
          p_im += t_im;
          if (j % 3 == 0)  // (at every third term: a check at each cost the compliant D1 servo more than it saved)
          {
            const double tail = (std::fabs(t_re) + std::fabs(t_im)) * z_abs;
            if (tail < quarter_ulp * std::fabs(p_re) && (im == 0.0 || tail < quarter_ulp * std::fabs(p_im)))
            {
              break;
            }
          }
        }
        const double wt = weight(k) * tau;
        a = wt * p_re;
        b = wt * p_im;
        c = g_(k).real();
        d = g_(k).imag();
      }
      else
      {
        // e^{λτ} − 1 = e^{Re}(cos Im + j sin Im) − 1 (one real exp, one sincos: cheaper than the complex exp).
        const double mag = std::exp(re);
        a = im == 0.0 ? mag - 1.0 : mag * std::cos(im) - 1.0;
        b = im == 0.0 ? 0.0 : mag * std::sin(im);
        c = g_over_lambda_(k).real();
        d = g_over_lambda_(k).imag();
      }
      const double prod_re = a * c - b * d, prod_im = a * d + b * c;
      e_re[static_cast<std::size_t>(k)] = series ? prod_re : weight(k) * prod_re;
      e_im[static_cast<std::size_t>(k)] = series ? prod_im : weight(k) * prod_im;
    }
    ModeVector x = x0_;
    const Eigen::Index terms = poly_.cols();
    for (Eigen::Index i = 0; i < n; ++i)
    {
      double sum = 0.0;
      for (Eigen::Index k = 0; k < r; ++k)
      {
        const std::size_t kk = static_cast<std::size_t>(k);
        sum += basis_->v_(i, k).real() * e_re[kk] - basis_->v_(i, k).imag() * e_im[kk];
      }
      double p = 0.0;  // Σ_j P_j τ^{j+1} (Horner)
      for (Eigen::Index j = terms - 1; j >= 0; --j)
      {
        p = (p + poly_(i, j)) * tau;
      }
      if (moving_ & (1u << i))
      {
        x(i) += (sum + p) * basis_->bal_(i);
      }
    }
    return x;
  }
  return taylorState(tau);
}

ModeVector LinearMode::rate(double tau) const
{
  return affine(basis_->a_, state(tau), u_);
}

double LinearMode::output(const ModeVector& w, double w0, double tau) const
{
  return w.dot(state(tau)) + w0;
}

double LinearMode::noise(const ModeVector& w, double w0, const ModeVector& x) const
{
  // The motion is solved as its deviation δ = x − x₀: each balanced coordinate of δ carries an error of about
  // rounding·‖D⁻¹δ‖ (the output sums them with weights |w_i| D_i), and adding x₀ a few ulps of each |x_i|. (Relative
  // to the whole state instead, a joint spinning at 3e4 rad/s had a penetration "within rounding" over its whole
  // 2 mrad excursion, and the search passed two crossings as one grazing.)
  constexpr double EPS = std::numeric_limits<double>::epsilon();
  double size = std::fabs(w0);
  for (Eigen::Index j = 0; j < x.size(); ++j)
  {
    size += std::fabs(w(j) * x(j));
  }
  return rateNoise(w, x - x0_) + 8.0 * EPS * size;
}

double LinearMode::rateNoise(const ModeVector& w, const ModeVector& v) const
{
  // (Plain loops: Eigen's expressions carry a dispatch overhead that dominates at these orders.)
  double weight = 0.0, size = 0.0;
  for (Eigen::Index j = 0; j < v.size(); ++j)
  {
    const double d = v(j) / basis_->bal_(j);
    weight += std::fabs(w(j)) * basis_->bal_(j);
    size += d * d;
  }
  return basis_->rounding_ * weight * std::sqrt(size);
}

LinearMode::Curvature LinearMode::curvature(const ModeVector& w) const
{
  Curvature k;
  if (basis_->modal_)
  {
    // s''(τ) = Σ_k (wᵀD v_k) λ_k g_k e^{λ_k τ}, s''' the same with λ_k² — the drift of a zero eigenvalue has neither.
    const Eigen::Index n = x0_.size(), m = basis_->nil_, r = n - m;
    k.beta.resize(r);
    k.rate.resize(r);
    for (Eigen::Index i = 0; i < r; ++i)
    {
      k.rate(i) = basis_->lambda_(i).real();
      if (basis_->weight_(i) == 0.0)
      {
        k.beta(i) = 0.0;  // (a pair's conjugate: counted in its partner)
        continue;
      }
      double c_re = 0.0, c_im = 0.0;  // wᵀD v_i λ_i
      for (Eigen::Index j = 0; j < n; ++j)
      {
        c_re += basis_->dvl_re_(j, i) * w(j);
        c_im += basis_->dvl_im_(j, i) * w(j);
      }
      // |wᵀD v_i λ_i| |g_i| (a pair's: both terms in the first), by hypot only where the squares could overflow or
      // underflow.
      // (An output the mode does not reach — a body's speed in a mode of the other body — has none.)
      const double squares = c_re * c_re + c_im * c_im;
      const double size = c_re == 0.0 && c_im == 0.0            ? 0.0
                          : squares > 1e-290 && squares < 1e290 ? std::sqrt(squares)
                                                                : std::hypot(c_re, c_im);
      k.beta(i) = basis_->weight_(i) * g_abs_(i) * size;
      k.steady = k.steady && (k.beta(i) == 0.0 || k.rate(i) <= 0.0);
    }
    // The polynomial part: s'' = Σ_{j ≥ 1} (Dw)·P_j (j + 1) j τ^{j−1}, s''' = Σ_{j ≥ 2} (Dw)·P_j (j + 1) j (j − 1)
    // τ^{j−2}.
    k.poly = ModeVector::Zero(poly_.cols());
    for (Eigen::Index j = 1; j < poly_.cols(); ++j)
    {
      k.poly(j) = std::fabs(w.cwiseProduct(basis_->bal_).dot(poly_.col(j))) * static_cast<double>((j + 1) * j);
      k.steady = k.steady && (j < 2 || k.poly(j) == 0.0);
    }
  }
  else
  {
    k.wa = (w.cwiseProduct(basis_->bal_).transpose() * basis_->balanced_).norm();
    k.steady = false;
  }
  return k;
}

void LinearMode::curvatureBounds(const Curvature& k, const ModeVector& x, double lo, double h, double* m2,
                                 double* m3) const
{
  constexpr double SAFE = 1.0 + 64.0 * std::numeric_limits<double>::epsilon();
  if (basis_->modal_)
  {
    // Each mode's term is largest at one end of the window.
    double b2 = 0.0, b3 = 0.0;
    for (Eigen::Index i = 0; i < k.beta.size(); ++i)
    {
      if (k.beta(i) != 0.0)
      {
        const double term = k.beta(i) * std::exp(k.rate(i) * lo + std::max(0.0, k.rate(i) * h));
        b2 += term;
        b3 += term * basis_->speed_(i);
      }
    }
    // The polynomial part's terms are largest at the window's end (τ ≥ 0).
    double p2 = 0.0, p3 = 0.0;
    for (Eigen::Index j = k.poly.size() - 1; j >= 1; --j)
    {
      p2 = p2 * (lo + h) + k.poly(j);
    }
    for (Eigen::Index j = k.poly.size() - 1; j >= 2; --j)
    {
      p3 = p3 * (lo + h) + k.poly(j) * static_cast<double>(j - 1);
    }
    *m2 = (b2 + p2) * SAFE;
    *m3 = (b3 + p3) * SAFE;
    return;
  }
  // ‖(Dw)ᵀÂ‖₂ ‖D⁻¹ẋ(lo)‖₂ e^{‖Â‖₂ h}.
  const ModeVector xd = affine(basis_->a_, x, u_);
  *m2 = k.wa * xd.cwiseQuotient(basis_->bal_).norm() * std::exp(basis_->norm_a_ * h);
  *m3 = INF;
}

LinearMode::Local LinearMode::local(const ModeVector& w, double w0, double lo, double h, const Curvature& curv) const
{
  Local l;
  const ModeVector x = state(lo);
  const ModeVector xd = affine(basis_->a_, x, u_);
  l.s = w.dot(x) + w0;
  l.s1 = w.dot(xd);
  l.noise0 = noise(w, w0, x);
  l.noise1 = rateNoise(w, xd);
  curvatureBounds(curv, x, lo, h, &l.m2, &l.m3);
  l.xd = xd;
  return l;
}

void LinearMode::completeSecond(const ModeVector& w, Local* local) const
{
  if (!local->second)
  {
    const ModeVector xdd = product(basis_->a_, local->xd);  // ẍ = A ẋ
    local->s2 = w.dot(xdd);
    local->noise2 = rateNoise(w, xdd);
    local->second = true;
  }
}

LinearMode::Verdict LinearMode::judge(const ModeVector& w, Local* local, double h) const
{
  const Local& l = *local;
  // Degree 1: s(lo + t) = s + s' t + R, |R| ≤ ½ m2 t² — beyond the remainder and the rounding of s and of s' t
  // (the window may be as long as this test allows, so neither rounding may be left out).
  const double margin = 0.5 * l.m2 * h * h + l.noise0 + l.noise1 * h;
  const double end = l.s + l.s1 * h;
  if ((l.s > margin && end > margin) || (l.s < -margin && end < -margin))
  {
    return Verdict::Clear;  // the linear part keeps one sign beyond the remainder: no zero here
  }
  // Degree 2: s(lo + t) = s + s' t + ½ s'' t² + R, |R| ≤ m3 t³/6 — the quadratic's least value on the window (at an
  // end, or at its vertex) beyond the remainder and the rounding of its coefficients.
  const bool second = std::isfinite(l.m3);
  if (second)
  {
    completeSecond(w, local);  // (only where degree 1 did not settle it)
  }
  if (second && l.s != 0.0)
  {
    const double sign = l.s > 0.0 ? 1.0 : -1.0;
    double least = std::min(sign * l.s, sign * (l.s + l.s1 * h + 0.5 * l.s2 * h * h));
    if (sign * l.s2 > 0.0)
    {
      const double vertex = -l.s1 / l.s2;
      if (vertex > 0.0 && vertex < h)
      {
        least = std::min(least, sign * (l.s + 0.5 * l.s1 * vertex));
      }
    }
    if (least > l.m3 * h * h * h / 6.0 + l.noise0 + l.noise1 * h + 0.5 * l.noise2 * h * h)
    {
      return Verdict::Clear;
    }
  }
  // s' keeps its sign on the window: by degree 1 (|s'(τ) − s'(lo)| ≤ m2 h, s'(lo) beyond its own rounding) or 2
  // (s'(lo + t) = s' + s'' t + R', |R'| ≤ ½ m3 t²).
  if (std::fabs(l.s1) > l.m2 * h + l.noise1)
  {
    return Verdict::Monotone;
  }
  if (second && l.s1 != 0.0)
  {
    const double sign = l.s1 > 0.0 ? 1.0 : -1.0;
    const double least = std::min(sign * l.s1, sign * (l.s1 + l.s2 * h));
    if (least > 0.5 * l.m3 * h * h + l.noise1 + l.noise2 * h)
    {
      return Verdict::Monotone;
    }
  }
  return Verdict::Unknown;
}

double LinearMode::reach(const ModeVector& w, Local* local, double rest) const
{
  const Local& l = *local;
  // The longest h with a h² + b h < c (c > 0): the positive root 2c / (b + √(b² + 4ac)), +inf where none.
  const auto below = [](double c, double b, double a) {
    if (!(c > 0.0))
    {
      return 0.0;
    }
    const double den = b + std::sqrt(b * b + 4.0 * a * c);
    return den > 0.0 ? 2.0 * c / den : INF;
  };
  // Degree 1 (as judge): |s| beyond ½m2h² + noise0 + noise1·h at both ends; |s'| beyond m2·h + noise1.
  const double a = std::fabs(l.s), b = l.s >= 0.0 ? l.s1 : -l.s1;
  double best =
      std::max(std::min(below(a - l.noise0, l.noise1, 0.5 * l.m2), below(a - l.noise0, l.noise1 - b, 0.5 * l.m2)),
               below(std::fabs(l.s1) - l.noise1, l.m2, 0.0));
  if (best >= rest || !std::isfinite(l.m3))
  {
    return std::min(best, rest);
  }
  completeSecond(w, local);
  // Degree 2, monotone: s' + s''t keeps its sign beyond ½m3t² + noise1 + noise2·t at both ends.
  const double a1 = std::fabs(l.s1), b1 = l.s1 >= 0.0 ? l.s2 : -l.s2;
  if (l.s1 != 0.0)
  {
    best = std::max(
        best, std::min(below(a1 - l.noise1, l.noise2, 0.5 * l.m3), below(a1 - l.noise1, l.noise2 - b1, 0.5 * l.m3)));
  }
  // Degree 2, exclusion: the quadratic's least value on [0, h] beyond m3h³/6 + noise0 + noise1·h + ½noise2·h² —
  // falling with h against a rising bound, so it holds below one length, found by bisection (in ratio).
  if (l.s != 0.0 && best < rest)
  {
    const double c = l.s >= 0.0 ? l.s2 : -l.s2;
    const auto holds = [&](double h) {
      double least = std::min(a, a + b * h + 0.5 * c * h * h);
      if (c > 0.0 && -b / c > 0.0 && -b / c < h)
      {
        least = std::min(least, a + 0.5 * b * (-b / c));
      }
      return least > l.m3 * h * h * h / 6.0 + l.noise0 + l.noise1 * h + 0.5 * l.noise2 * h * h;
    };
    if (holds(rest))
    {
      return rest;
    }
    double ok = best, no = rest;
    if (holds(ok > 0.0 ? ok * 1.0625 : rest * 1e-3))
    {
      ok = ok > 0.0 ? ok * 1.0625 : rest * 1e-3;
      for (int k = 0; k < 8; ++k)
      {
        const double mid = std::sqrt(ok * no);
        (holds(mid) ? ok : no) = mid;
      }
      best = ok;
    }
  }
  return std::min(best, rest);
}

double LinearMode::firstCrossing(const ModeVector& w, double w0, int direction, double horizon, double from,
                                 bool began_here) const
{
  if (!(horizon > 0.0) || (direction != 1 && direction != 0 && direction != -1))
  {
    return INF;
  }
  // In the balanced basis x = D x̂: s = (Dw)·x̂ + w₀, s'' = (Dw)ᵀ Â exp(Ât) (D⁻¹ẋ).
  const Curvature curv = curvature(w);
  const double scale = basis_->norm_a_ > 0.0 ? 1.0 / basis_->norm_a_ : horizon;  // the fastest time scale [s]
  const double floor = FLOOR_FRACTION * scale;
  const Local start = local(w, w0, from, horizon - from, curv);  // (the first window's, where the bounds are steady)
  {
    // An output that is zero with all its derivatives at the start (wᵀAᵏẋ = 0, k < n: the output does not see the
    // motion at all, e.g. the velocity of a body at rest on which nothing acts) stays zero: it never crosses.
    bool flat = std::fabs(start.s) <= start.noise0;
    ModeVector v = start.xd;
    for (int k = 0; flat && k < order(); ++k)
    {
      flat = std::fabs(w.dot(v)) <= rateNoise(w, v);
      v = product(basis_->a_, v);
    }
    if (flat)
    {
      return INF;
    }
  }
  const double origin = began_here ? from : std::numeric_limits<double>::quiet_NaN();
  double t = from;
  while (t < horizon)
  {
    const double rest = horizon - t;
    if (basis_->modal_ && curv.steady && std::isfinite(rest))
    {
      // The bounds do not grow with the window: the longest window the tests settle at once (reach(), arithmetic
      // only) — but at least where the remainder bound reaches about |s|, a window the search will halve if need be.
      // (A hair short of a root: there the tests' rounding may go either way.)
      Local l = t == from ? start : local(w, w0, t, rest, curv);
      const double least = l.m2 > 0.0 ? std::max(std::sqrt(std::fabs(l.s) / l.m2), 1e-3 * scale) : rest;
      const double longest = rest > least ? reach(w, &l, rest) : rest;
      const double h = std::min(std::max(longest < rest ? longest * (1.0 - 0x1p-20) : rest, least), rest);
      const double hit = searchWindow(w, w0, direction, t, t + h, curv, floor, origin, &l);
      if (hit < INF)
      {
        return hit;
      }
      t += h;
      continue;
    }
    // A window the exclusion test is likely to pass: where the remainder bound reaches about |s|.
    const ModeVector x = state(t);
    const double s = w.dot(x) + w0;
    double m = 0.0, m3 = 0.0;
    curvatureBounds(curv, x, t, scale, &m, &m3);
    double h = m > 0.0 ? std::sqrt(std::fabs(s) / m) : horizon;
    // (At least a thousandth of the fastest time scale: an output hovering near zero is searched by halving the
    // window, not by crawling. At most that time scale for the norm bound, which grows as e^{‖Â‖h}, and four of
    // them for a modal bound with a growing mode.)
    h = std::min({std::max(h, 1e-3 * scale), basis_->modal_ ? 4.0 * scale : scale, rest});
    const double hit = searchWindow(w, w0, direction, t, t + h, curv, floor, origin);
    if (hit < INF)
    {
      return hit;
    }
    t += h;
  }
  return INF;
}

double LinearMode::searchWindow(const ModeVector& w, double w0, int direction, double lo, double hi,
                                const Curvature& curv, double floor, double origin, Local* at_lo) const
{
  const double h = hi - lo;
  Local computed;
  Local& l = at_lo != nullptr ? *at_lo : (computed = local(w, w0, lo, h, curv));  // m2, m3 bound its s'', s'''
  const Verdict verdict = judge(w, &l, h);
  if (verdict == Verdict::Clear)
  {
    return INF;
  }
  const double s = l.s, s1 = l.s1, m = l.m2, rounding = l.noise0;
  const double s_hi = output(w, w0, hi);
  // (Either direction: the one the window's end tells — a crossing can only end on the side the output ends on.)
  const int dir = direction != 0 ? direction : s_hi > 0.0 ? 1 : -1;
  // The start of a motion begun by this output's own crossing, where the output is within rounding of zero and
  // moving in the asked direction: that crossing, evaluated again — its sign there means nothing. (Only there: any
  // other output found within rounding of zero at a start, moving across, is searched by its signs like anywhere.)
  const bool behind = lo == origin && std::fabs(s) <= rounding && dir * s1 > 0.0;
  const bool changes = !behind && dir * s <= 0.0 && dir * s_hi > 0.0;
  // Within rounding of zero at both ends and in its slope, on a window much shorter than any of the mode's
  // oscillations (or by the bound all along): the output's turning points there cannot be resolved, only a sign
  // change between the ends counts. (Where an output leaves zero to high order — a load set moving from rest — the
  // curvature bound, a sum over the modes, stays far above the output itself: without this the search would halve
  // down to the floor across the whole band.)
  const bool short_window = h * basis_->norm_a_ <= 1e-3;
  if (std::fabs(s) + std::fabs(s1) * h + 0.5 * m * h * h <= rounding ||
      (short_window && std::fabs(s) <= rounding && std::fabs(s_hi) <= rounding && std::fabs(s1) * h <= rounding))
  {
    return changes ? refine(w, w0, dir, lo, hi, l) : INF;
  }
  if (verdict == Verdict::Monotone)
  {
    return changes ? refine(w, w0, dir, lo, hi, l) : INF;  // one zero at most
  }
  if (h <= floor)
  {
    // Within the floor of a turning point: a sign change is the crossing; none is a grazing (see the file comment).
    return changes ? refine(w, w0, dir, lo, hi, l) : INF;
  }
  const double mid = lo + 0.5 * h;
  const double first = searchWindow(w, w0, direction, lo, mid, curv, floor, origin);
  return first < INF ? first : searchWindow(w, w0, direction, mid, hi, curv, floor, origin);
}

double LinearMode::refine(const ModeVector& w, double w0, int direction, double lo, double hi, const Local& at_lo) const
{
  // The ITP method (Oliveira & Takahashi, ACM TOMS 2020): regula falsi, truncated a little past the root so that the
  // bracket closes from both sides, projected to within a shrinking distance of the midpoint so that it never takes
  // more steps than bisection plus one — superlinear in practice. Run down to adjacent doubles, or until the end past
  // the crossing is within a few ulps of the output's terms (the doubles the state is held in cannot place s closer
  // to zero; bisecting that band to the last bit cost two thirds of all evaluations), and that end is returned. (Not
  // the closed form's whole rounding, noise(): a bound for the exclusion test, loose where the motion is fast —
  // stopping there placed a fast joint's crossing 1e-9 s off.)
  const ModeVector x_hi = state(hi);
  double f_lo = direction * at_lo.s, f_hi = direction * (w.dot(x_hi) + w0);
  const double band =
      4.0 * std::numeric_limits<double>::epsilon() * (w.cwiseAbs().dot(x_hi.cwiseAbs()) + std::fabs(w0));
  // Newton's method on the bracket first (s' = w·(Ax + u) costs a product beside the evaluation): from the root of
  // the window's Taylor model at lo (s + s't + ½s''t² where s'' is known, else the line; the secant where neither
  // lies in the bracket), each step kept inside the bracket and aimed half a band past the crossing, so that it ends
  // within the band on that side. Quadratic near a simple crossing — a few evaluations where the bracketing method
  // took about fifteen; where it stalls (a crossing at a turning point, s' ≈ 0) the bracketing method below takes
  // over from the bracket reached.
  {
    double t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    const double rise = direction * at_lo.s1;
    if (rise > 0.0)
    {
      double step = -f_lo / rise;
      if (at_lo.second)
      {
        // The smaller root of ½ s'' t² + s' t + s = 0 in the cancellation-free form 2|s| / (s' + √(s'² − 2 s s'')).
        const double disc = rise * rise - 2.0 * f_lo * direction * at_lo.s2;
        if (disc >= 0.0)
        {
          step = -2.0 * f_lo / (rise + std::sqrt(disc));
        }
      }
      if (lo + step > lo && lo + step < hi)
      {
        t = lo + step;
      }
    }
    for (int j = 0; j < NEWTON_STEPS && f_hi > band; ++j)
    {
      if (!(t > lo && t < hi))
      {
        t = lo + 0.5 * (hi - lo);
        if (!(t > lo && t < hi))
        {
          break;
        }
      }
      const ModeVector x = state(t);
      const double f = direction * (w.dot(x) + w0);
      (f > 0.0 ? hi : lo) = t;
      (f > 0.0 ? f_hi : f_lo) = f;
      const double slope = direction * w.dot(affine(basis_->a_, x, u_));
      if (!(slope > 0.0))
      {
        break;  // not rising towards the crossing here: leave it to the bracketing method
      }
      t = t - (f - 0.5 * band) / slope;  // (aimed half a band past the crossing)
    }
  }
  const double eps = 0.5 * std::max(std::nextafter(hi, INF) - hi, std::numeric_limits<double>::denorm_min());
  const double kappa1 = 0.2 / (hi - lo);
  const int n_half = static_cast<int>(std::ceil(std::log2(std::max((hi - lo) / (2.0 * eps), 1.0))));
  const int n_max = n_half + 1;
  for (int j = 0; j < 400 && f_hi > band; ++j)
  {
    const double half = lo + 0.5 * (hi - lo);
    if (!(half > lo && half < hi))
    {
      break;
    }
    double x = half;
    if (f_hi > 0.0 && f_lo <= 0.0 && std::isfinite(f_hi - f_lo))
    {
      const double width = hi - lo;
      const double r = std::max(eps * std::ldexp(1.0, std::max(n_max - j, 0)) - 0.5 * width, 0.0);
      const double delta = kappa1 * width * width;
      const double falsi = (hi * f_lo - lo * f_hi) / (f_lo - f_hi);
      const double sigma = half >= falsi ? 1.0 : -1.0;
      const double truncated = delta <= std::fabs(half - falsi) ? falsi + sigma * delta : half;
      x = std::fabs(truncated - half) <= r ? truncated : half - sigma * r;
      if (!(x > lo && x < hi))
      {
        x = half;
      }
    }
    const double f = direction * output(w, w0, x);
    if (f > 0.0)
    {
      hi = x;
      f_hi = f;
    }
    else
    {
      lo = x;
      f_lo = f;
    }
  }
  return hi;
}

}  // namespace backlash_servo
