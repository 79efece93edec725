// The compliant joint's dry friction (compliant_joint.h): the bodies' holding torques and the rest rule, a joint held
// by stiction, and a stuck load over a motor settling on the mesh spring (settlesForever).
#include "compliant/compliant_joint.h"

#include <cmath>
#include <complex>

#include <Eigen/Dense>

#include "compliant/compliant_joint_detail.h"

namespace backlash_servo
{
using compliant_detail::isForward;
using compliant_detail::isK2;
using compliant_detail::roundingOf;

void CompliantJoint::holdingTorque(int body, MeshMode m, ModeVector* w, double* w0) const
{
  // J ω̇ = H − f ω − T_c·slide: H is J times the body's velocity row while it moves, its fold taken back (ω = 0).
  ModeMatrix a;
  ModeVector u;
  modeMatrices(m, {1, 1}, &a, &u);
  const int v = angleIndex(body) + 1;
  const double j = inertiaOf(body);
  *w = j * a.row(v).transpose();
  (*w)(v) = 0.0;  // (the viscous term vanishes at rest)
  *w0 = j * u(v) + coulombOf(body);
}

int CompliantJoint::restSlide(int body) const
{
  ModeVector w;
  double w0;
  holdingTorque(body, mode_, &w, &w0);
  const double h = w.dot(x_) + w0;
  return std::fabs(h) <= staticOf(body) ? 0 : h > 0.0 ? 1 : -1;
}

bool CompliantJoint::held() const
{
  if (torsional_ || forced() || !dry_[0] || !dry_[1] || slide_[0] != 0 || slide_[1] != 0)
  {
    return false;
  }
  return restSlide(0) == 0 && restSlide(1) == 0;
}

bool CompliantJoint::settlesForever() const
{
  // (msl's 2c·y sub-mode holds only while d·ẏ > c·y > 0: a motor coming to rest leaves it first.)
  if (rigid_ || torsional_ || forced() || dry_[0] || !dry_[1] || slide_[1] != 0 || mode_ == MeshMode::Free ||
      isK2(mode_))
  {
    return false;
  }
  ModeMatrix a;
  ModeVector u;
  modeMatrices(mode_, slide_, &a, &u);  // (the load's rows frozen)
  const Eigen::Matrix2d m = a.topLeftCorner(2, 2);
  const Eigen::Vector2d f = u.head(2) + a.block(0, 2, 2, size() - 2) * x_.segment(2, size() - 2);
  if (!(std::fabs(m.determinant()) > 0.0))
  {
    return false;
  }
  const Eigen::Vector2d eq = -m.partialPivLu().solve(f), dev = x_.head(2) - eq;
  Eigen::EigenSolver<Eigen::Matrix2d> solver(m);
  const Eigen::Vector2cd lambda = solver.eigenvalues();
  const Eigen::Matrix2cd v = solver.eigenvectors();
  if (!(lambda.real().maxCoeff() < 0.0) || !(std::abs(lambda(0) - lambda(1)) > 1e-9 * lambda.cwiseAbs().maxCoeff()) ||
      !(std::fabs(v.determinant()) > 0.0))
  {
    return false;  // not decaying, or a repeated eigenvalue (a polynomial factor: no simple bound)
  }
  const Eigen::Vector2cd modal = v.partialPivLu().solve(dev.cast<std::complex<double>>());
  // o(t) − o_eq = w_m·V e^{Λt} V⁻¹ δ: within Σ|c_i| for all t ≥ 0; o_eq and the bound from the motor's part w_m.
  const auto side = [&](const ModeVector& w, double w0, double* at_eq, double* bound) {
    ModeVector x = x_;
    x.head(2) = eq;
    *at_eq = w.dot(x) + w0;
    const Eigen::RowVector2cd wm = w.head(2).transpose().cast<std::complex<double>>() * v;
    *bound = std::abs(wm(0) * modal(0)) + std::abs(wm(1) * modal(1)) + roundingOf(w, w0, x) +
             1e-12 * (std::fabs(*at_eq) + w.head(2).cwiseAbs().dot(dev.cwiseAbs()));
  };
  const int sigma = isForward(mode_) ? 1 : -1;
  double eq_value, bound;
  ModeVector w;
  double w0;
  flankTorque(sigma, s_.mesh_stiffness, s_.mesh_damping, &w, &w0);
  side(w, w0, &eq_value, &bound);
  if (!(eq_value - bound > 0.0))
  {
    return false;  // the contact might be released
  }
  if (msl_)
  {
    // c·y + d·ẏ while d·ẏ − c·y < 0: the switch to 2c·y must not come.
    flankTorque(sigma, -s_.mesh_stiffness, s_.mesh_damping, &w, &w0);
    side(w, w0, &eq_value, &bound);
    if (!(eq_value + bound < 0.0))
    {
      return false;
    }
  }
  holdingTorque(1, mode_, &w, &w0);
  side(w, w0, &eq_value, &bound);
  return std::fabs(eq_value) + bound < staticOf(1);
}

void CompliantJoint::heldMotorTorque(double* lo, double* hi) const
{
  const double pressed = s_.gear_ratio * meshTorque(), now = law_.torque(x_(loadIndex()), time_);
  const auto inside = [now](double end) { return end - 1e-9 * (end - now); };  // pulled towards the torque now
  *lo = inside(pressed - s_.motor_static_friction);
  *hi = inside(pressed + s_.motor_static_friction);
}

void CompliantJoint::holdTo(double t)
{
  if (t > time_)
  {
    time_ = t;
    segment_.reset();
  }
}

}  // namespace backlash_servo
