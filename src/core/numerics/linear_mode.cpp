#include "numerics/linear_mode.h"

#include "numerics/mode_products.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "backlash_servo/model/constants.h"

namespace backlash_servo
{
using mode_detail::affine;
using mode_detail::product;

namespace
{
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
        sum += basis_->v_inv_(k, j) * (v0_(j) * basis_->inv_bal_(j));
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
    g_over_lambda_.resize(n);  // used only where |λτ| ≥ 0.1
    for (Eigen::Index k = 0; k < n; ++k)
    {
      // |g| by hypot only where the squares could overflow or underflow (a bound's factor: its last bit is no matter).
      const double re = g_(k).real(), im = g_(k).imag(), squares = re * re + im * im;
      g_abs_(k) = re == 0.0 && im == 0.0                ? 0.0
                  : squares > 1e-290 && squares < 1e290 ? std::sqrt(squares)
                                                        : std::hypot(re, im);
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

double LinearMode::decayedSpeedup(double tau) const
{
  const ModeBasis& b = *basis_;
  if (!b.modal_ || poly_.cols() > 0)
  {
    return 1.0;
  }
  std::array<double, MAX_MODE_ORDER> part{};
  double total = 0.0, fastest = 0.0;
  for (int c = 0; c < b.n_active_; ++c)
  {
    const Eigen::Index k = b.active_[static_cast<std::size_t>(c)];
    const double column = b.dv_re_.col(c).cwiseAbs().sum() + b.dv_im_.col(c).cwiseAbs().sum();
    part[static_cast<std::size_t>(c)] = column * g_abs_(k) * std::exp(b.lambda_(k).real() * tau);
    total += part[static_cast<std::size_t>(c)];
    fastest = std::max(fastest, std::abs(b.lambda_(k)));
  }
  double alive = 0.0;
  for (int c = 0; c < b.n_active_; ++c)
  {
    const Eigen::Index k = b.active_[static_cast<std::size_t>(c)];
    if (part[static_cast<std::size_t>(c)] > DEAD_FRACTION * total)
    {
      alive = std::max(alive, std::abs(b.lambda_(k)));
    }
  }
  return alive * MAX_SPEEDUP > fastest ? std::max(1.0, fastest / alive) : (fastest > 0.0 ? MAX_SPEEDUP : 1.0);
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
    const ModeVector& weight = basis_->weight_;
    const int active = basis_->n_active_;
    std::array<double, MAX_MODE_ORDER> e_re{}, e_im{};
    for (int c = 0; c < active; ++c)
    {
      const Eigen::Index k = basis_->active_[static_cast<std::size_t>(c)];  // (a pair's conjugate is not: its
                                                                            // partner's term is doubled)
      const double re = lambda(k).real() * tau, im = lambda(k).imag() * tau;
      double a, b;    // e^{λτ} − 1 over λ, or τφ₁(λτ)
      double cr, ci;  // g/λ, or g
      const bool series = re * re + im * im < 0.01;
      if (series)
      {
        // The terms to the tenth, but for those that can no longer change a bit of the sum: each later term is
        // smaller than this one times |z| < 0.1, and one below a quarter of a component's ulp (> 2⁻⁵⁵ of it) leaves
        // that component as it is.
        // (A zero eigenvalue — a body's drift — has φ₁ = 1 at once.)
        static constexpr std::array<double, 11> INVERSE = {0.0,       1.0,       1.0 / 2.0, 1.0 / 3.0,
                                                           1.0 / 4.0, 1.0 / 5.0, 1.0 / 6.0, 1.0 / 7.0,
                                                           1.0 / 8.0, 1.0 / 9.0, 1.0 / 10.0};
        double p_re = 1.0, p_im = 0.0, t_re = 1.0, t_im = 0.0;  // φ₁ and its series' term
        const double z_abs = std::fabs(re) + std::fabs(im), quarter_ulp = 0x1p-55;
        for (int j = 2; j <= 10 && z_abs != 0.0 && im == 0.0; ++j)
        {
          // (A real eigenvalue: the same terms, without their zero imaginary parts.)
          t_re = t_re * (re * INVERSE[static_cast<std::size_t>(j)]);
          p_re += t_re;
          if (j % 3 == 0 && std::fabs(t_re) * z_abs < quarter_ulp * std::fabs(p_re))
          {
            break;
          }
        }
        for (int j = 2; j <= 10 && z_abs != 0.0 && im != 0.0; ++j)
        {
          const double inv = INVERSE[static_cast<std::size_t>(j)], z_re = re * inv, z_im = im * inv;
          const double next_re = t_re * z_re - t_im * z_im;
          t_im = t_re * z_im + t_im * z_re;
          t_re = next_re;
          p_re += t_re;
          p_im += t_im;
          if (j % 3 == 0)  // (at every third term: a check at each cost the compliant D1 servo more than it saved)
          {
            const double tail = (std::fabs(t_re) + std::fabs(t_im)) * z_abs;
            if (tail < quarter_ulp * std::fabs(p_re) && tail < quarter_ulp * std::fabs(p_im))
            {
              break;
            }
          }
        }
        const double wt = weight(k) * tau;
        a = wt * p_re;
        b = wt * p_im;
        cr = g_(k).real();
        ci = g_(k).imag();
      }
      else
      {
        // e^{λτ} − 1 = e^{Re}(cos Im + j sin Im) − 1 (one real exp, one sincos: cheaper than the complex exp).
        const double mag = std::exp(re);
        a = im == 0.0 ? mag - 1.0 : mag * std::cos(im) - 1.0;
        b = im == 0.0 ? 0.0 : mag * std::sin(im);
        cr = g_over_lambda_(k).real();
        ci = g_over_lambda_(k).imag();
      }
      const double prod_re = a * cr - b * ci, prod_im = a * ci + b * cr;
      e_re[static_cast<std::size_t>(c)] = series ? prod_re : weight(k) * prod_re;
      e_im[static_cast<std::size_t>(c)] = series ? prod_im : weight(k) * prod_im;
    }
    ModeVector x = x0_;
    const Eigen::Index terms = poly_.cols();
    for (Eigen::Index i = 0; i < n; ++i)
    {
      if (!(moving_ & (1u << i)))
      {
        continue;
      }
      double sum = 0.0;  // (D folded into V: D's powers of 2 scale every term exactly)
      for (int c = 0; c < active; ++c)
      {
        const std::size_t cc = static_cast<std::size_t>(c);
        sum += basis_->dv_re_(i, c) * e_re[cc] - basis_->dv_im_(i, c) * e_im[cc];
      }
      double p = 0.0;  // Σ_j P_j τ^{j+1} (Horner)
      for (Eigen::Index j = terms - 1; j >= 0; --j)
      {
        p = (p + poly_(i, j)) * tau;
      }
      x(i) += sum + p * basis_->bal_(i);
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
}  // namespace backlash_servo
