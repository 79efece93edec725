#include "backlash_servo/compliant_joint.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "backlash_servo/linear_mode.h"

namespace backlash_servo
{
namespace
{
constexpr double INF = std::numeric_limits<double>::infinity();

void requireKey(bool ok, const char* key, double value, const char* why)
{
  if (!ok)
  {
    char text[64];
    std::snprintf(text, sizeof text, "%.17g", value);
    throw InvalidParameterError(key, std::string(text) + " " + why);
  }
}

bool isForward(MeshMode m)
{
  return m == MeshMode::Forward || m == MeshMode::ForwardK2;
}
bool isK2(MeshMode m)
{
  return m == MeshMode::ForwardK2 || m == MeshMode::BackwardK2;
}

/// What ends a segment.
enum class Kind
{
  Engage,            // y of a flank rises through 0 (free play → contact)
  Reengage,          // P of a released, still penetrating flank rises through 0
  LeavePenetration,  // y of a released flank falls through 0 (back into the free play, still free)
  Release,           // P falls through 0: the torque would pull
  ToKD,              // msl: c y − d ẏ rises through 0 (K2 → KD)
  ToK2,              // msl: d ẏ − c y rises through 0 (KD → K2)
  Maximum            // ω_c falls through 0
};

struct Watch
{
  Eigen::VectorXd w;
  double w0;
  int direction;
  Kind kind;
  int sigma;  // the flank (+1 forward, −1 backward), 0 for a maximum
};
}  // namespace

void CompliantParams::validate() const
{
  if (mesh_law != "spring_damper" && mesh_law != "msl_elastobacklash")
  {
    throw InvalidParameterError("mesh_law", "'" + mesh_law + "' must be spring_damper or msl_elastobacklash");
  }
  requireKey(std::isfinite(mesh_stiffness) && mesh_stiffness > 0.0, "mesh_stiffness", mesh_stiffness,
             "must be > 0 and finite [N·m/rad]");
  requireKey(std::isfinite(mesh_damping) && mesh_damping >= 0.0, "mesh_damping", mesh_damping,
             "must be >= 0 and finite [N·m·s/rad]");
  requireKey(std::isfinite(gear_inertia) && gear_inertia >= 0.0, "gear_inertia", gear_inertia,
             "must be >= 0 and finite [kg·m²]");
  requireKey(std::isfinite(shaft_stiffness) && shaft_stiffness >= 0.0, "shaft_stiffness", shaft_stiffness,
             "must be >= 0 and finite [N·m/rad]");
  requireKey(std::isfinite(shaft_damping) && shaft_damping >= 0.0, "shaft_damping", shaft_damping,
             "must be >= 0 and finite [N·m·s/rad]");
  requireKey(!(shaft_damping > 0.0 && shaft_stiffness == 0.0), "shaft_damping", shaft_damping,
             "needs shaft_stiffness > 0 (a rigid shaft has no twist to damp)");
  requireKey(!(shaft_stiffness > 0.0 && gear_inertia == 0.0), "shaft_stiffness", shaft_stiffness,
             "needs gear_inertia > 0 (the output gear between mesh and shaft)");
}

CompliantJoint::CompliantJoint(const ServoParams& servo, const CompliantParams& mesh, double command)
    : s_(servo),
      c_(mesh),
      command_(command),
      torsional_(mesh.shaft_stiffness > 0.0),
      msl_(mesh.mesh_law == "msl_elastobacklash")
{
  s_.validate();
  c_.validate();
  setState(Eigen::VectorXd::Zero(n()));
}

void CompliantJoint::setState(const Eigen::VectorXd& x)
{
  if (x.size() != n() || !x.allFinite())
  {
    throw std::invalid_argument("CompliantJoint::setState: expected " + std::to_string(n()) + " finite entries");
  }
  x_ = x;
  mode_ = chooseMode(false, false);
  contacts_ = mode_ == MeshMode::Free ? 0 : 1;
  last_kind_ = -1;
}

void CompliantJoint::penetration(int sigma, Eigen::VectorXd* w, double* w0) const
{
  // y = σ(ρθ_m − θ_o) − δ, δ = 0 forward, Δ backward.
  *w = Eigen::VectorXd::Zero(n());
  (*w)(0) = sigma * s_.gear_ratio;
  (*w)(out()) = -sigma;
  *w0 = sigma > 0 ? 0.0 : -s_.backlash;
}

void CompliantJoint::flankTorque(int sigma, double ky, double kv, Eigen::VectorXd* w, double* w0) const
{
  // ky y + kv ẏ with ẏ = σ(ρω_m − ω_o).
  *w = Eigen::VectorXd::Zero(n());
  (*w)(0) = sigma * ky * s_.gear_ratio;
  (*w)(out()) = -sigma * ky;
  (*w)(1) = sigma * kv * s_.gear_ratio;
  (*w)(out() + 1) = -sigma * kv;
  *w0 = sigma > 0 ? 0.0 : -ky * s_.backlash;
}

void CompliantJoint::modeMatrices(MeshMode m, Eigen::MatrixXd* a, Eigen::VectorXd* u) const
{
  const int k = n(), o = out(), l = load();
  *a = Eigen::MatrixXd::Zero(k, k);
  *u = Eigen::VectorXd::Zero(k);
  const double rho = s_.gear_ratio, jm = s_.motor_inertia;
  const double j_out = torsional_ ? c_.gear_inertia : s_.load_inertia + c_.gear_inertia;
  Eigen::MatrixXd& A = *a;
  Eigen::VectorXd& U = *u;
  A(0, 1) = 1.0;
  A(o, o + 1) = 1.0;
  // Motor: J_m ω̇_m = K(θ_R − θ_c) − f_m ω_m − ρQ.
  A(1, 1) = -s_.motor_friction / jm;
  A(1, l) = -s_.gain / jm;
  U(1) = s_.gain * command_ / jm;
  if (m != MeshMode::Free)
  {
    // Q = k(ρθ_m − θ_o) + k_d(ρω_m − ω_o) − σ k δ_σ (δ = 0 forward, Δ backward).
    const int sigma = isForward(m) ? 1 : -1;
    const double kq = isK2(m) ? 2.0 * c_.mesh_stiffness : c_.mesh_stiffness;
    const double kd = isK2(m) ? 0.0 : c_.mesh_damping;
    const double q0 = sigma > 0 ? 0.0 : kq * s_.backlash;
    const double qx[4] = {kq * rho, kd * rho, -kq, -kd};  // coefficients of θ_m, ω_m, θ_o, ω_o
    const int qi[4] = {0, 1, o, o + 1};
    for (int i = 0; i < 4; ++i)
    {
      A(1, qi[i]) += -rho * qx[i] / jm;  // motor receives −ρQ
      A(o + 1, qi[i]) += qx[i] / j_out;  // the output side receives Q
    }
    U(1) += -rho * q0 / jm;
    U(o + 1) += q0 / j_out;
  }
  if (torsional_)
  {
    // S = k_s(θ_o − θ_c) + d_s(ω_o − ω_c): −S on the gear, +S on the load.
    const double ks = c_.shaft_stiffness, ds = c_.shaft_damping, jl = s_.load_inertia;
    A(o + 1, o) += -ks / j_out;
    A(o + 1, l) += ks / j_out;
    A(o + 1, o + 1) += -ds / j_out;
    A(o + 1, l + 1) += ds / j_out;
    A(l, l + 1) = 1.0;
    A(l + 1, o) += ks / jl;
    A(l + 1, l) += -ks / jl;
    A(l + 1, o + 1) += ds / jl;
    A(l + 1, l + 1) += -(ds + s_.load_friction) / jl;
    U(l + 1) += s_.load_torque / jl;
  }
  else
  {
    A(o + 1, o + 1) += -s_.load_friction / j_out;
    U(o + 1) += s_.load_torque / j_out;
  }
}

MeshMode CompliantJoint::chooseMode(bool released_forward, bool released_backward) const
{
  for (int sigma : {1, -1})
  {
    if ((sigma > 0 && released_forward) || (sigma < 0 && released_backward))
    {
      continue;
    }
    Eigen::VectorXd w;
    double w0;
    penetration(sigma, &w, &w0);
    double y = w.dot(x_) + w0;
    // A penetration within the rounding of the angles it is the difference of counts as touching.
    const double rounding =
        64.0 * std::numeric_limits<double>::epsilon() * (w.cwiseAbs().dot(x_.cwiseAbs()) + std::fabs(w0));
    if (std::fabs(y) <= rounding)
    {
      y = 0.0;
    }
    flankTorque(sigma, 0.0, 1.0, &w, &w0);
    const double ydot = w.dot(x_) + w0;
    const double tc = c_.mesh_stiffness * y, td = c_.mesh_damping * ydot;
    if (y == 0.0 && ydot == 0.0)
    {
      // Touching at relative rest (the start): engaged when the free motion would push the teeth together.
      Eigen::MatrixXd a;
      Eigen::VectorXd u;
      modeMatrices(MeshMode::Free, &a, &u);
      flankTorque(sigma, 0.0, 1.0, &w, &w0);
      if (w.dot(a * x_ + u) > 0.0)
      {
        return sigma > 0 ? MeshMode::Forward : MeshMode::Backward;
      }
      continue;
    }
    if (y < 0.0 || (y == 0.0 && !(ydot > 0.0)))
    {
      continue;
    }
    if (tc + td > 0.0 || (y == 0.0 && ydot > 0.0))
    {
      if (msl_ && td > tc)
      {
        return sigma > 0 ? MeshMode::ForwardK2 : MeshMode::BackwardK2;
      }
      return sigma > 0 ? MeshMode::Forward : MeshMode::Backward;
    }
  }
  return MeshMode::Free;
}

void CompliantJoint::advanceTo(double t_end)
{
  const double c = c_.mesh_stiffness, d = c_.mesh_damping;
  const int l = load();
  int guard = 0;
  while (time_ < t_end)
  {
    Eigen::MatrixXd a;
    Eigen::VectorXd u;
    modeMatrices(mode_, &a, &u);
    const LinearMode m(a, u, x_);
    std::vector<Watch> watches;
    Eigen::VectorXd w;
    double w0;
    if (mode_ == MeshMode::Free)
    {
      for (int sigma : {1, -1})
      {
        penetration(sigma, &w, &w0);
        const double y = w.dot(x_) + w0;
        if (y > 0.0)
        {
          watches.push_back({w, w0, -1, Kind::LeavePenetration, sigma});
          flankTorque(sigma, c, d, &w, &w0);  // P = cy + dẏ (msl: τc + τd, KD on re-engaging)
          watches.push_back({w, w0, +1, Kind::Reengage, sigma});
        }
        else
        {
          watches.push_back({w, w0, +1, Kind::Engage, sigma});
        }
      }
    }
    else
    {
      const int sigma = isForward(mode_) ? 1 : -1;
      if (isK2(mode_))
      {
        flankTorque(sigma, c, -d, &w, &w0);  // c y − d ẏ ↑ 0
        watches.push_back({w, w0, +1, Kind::ToKD, sigma});
        penetration(sigma, &w, &w0);
        watches.push_back({w, w0, -1, Kind::Release, sigma});
      }
      else
      {
        flankTorque(sigma, c, d, &w, &w0);
        watches.push_back({w, w0, -1, Kind::Release, sigma});
        if (msl_)
        {
          flankTorque(sigma, -c, d, &w, &w0);  // d ẏ − c y ↑ 0
          watches.push_back({w, w0, +1, Kind::ToK2, sigma});
        }
      }
    }
    w = Eigen::VectorXd::Zero(n());
    w(l + 1) = 1.0;
    watches.push_back({w, 0.0, -1, Kind::Maximum, 0});

    const double horizon = t_end - time_;
    // The event that began this segment lies at its start: its own crossing is not searched for again within the
    // search floor (1e-9 of the fastest time scale).
    const double skip = LinearMode::FLOOR_FRACTION / std::max(m.norm(), 1e-300);
    double first = INF;
    const Watch* hit = nullptr;
    for (const Watch& watch : watches)
    {
      const bool again = static_cast<int>(watch.kind) == last_kind_ && watch.sigma == last_sigma_;
      const double tau =
          m.firstCrossing(watch.w, watch.w0, watch.direction, std::min(horizon, first), again ? skip : 0.0);
      if (tau < first)
      {
        first = tau;
        hit = &watch;
      }
    }
    if (hit == nullptr)
    {
      x_ = m.state(horizon);
      time_ = t_end;
      last_kind_ = -1;
      return;
    }
    x_ = m.state(first);
    time_ += first;
    last_kind_ = static_cast<int>(hit->kind);
    last_sigma_ = hit->sigma;
    if (++guard > 100000000)
    {
      throw std::logic_error("CompliantJoint: no progress (internal error; please report with the parameters)");
    }
    switch (hit->kind)
    {
      case Kind::Maximum:
        // A turning point only where the load was moving up just before (not a load at rest being pushed down).
        if (x_(l) > command_ && m.state(first * (1.0 - 1e-6))(l + 1) > 0.0)
        {
          maxima_.push_back({time_, x_(l), x_(l + 1)});
        }
        break;
      case Kind::Engage:
        ++contacts_;
        // msl_elastobacklash enters in K2 (dẏ > cy = 0) unless the teeth are undamped.
        mode_ = msl_ && d > 0.0 ? (hit->sigma > 0 ? MeshMode::ForwardK2 : MeshMode::BackwardK2)
                                : (hit->sigma > 0 ? MeshMode::Forward : MeshMode::Backward);
        break;
      case Kind::Reengage:
        ++contacts_;
        ++reengagements_;
        mode_ = hit->sigma > 0 ? MeshMode::Forward : MeshMode::Backward;
        break;
      case Kind::LeavePenetration:
        // Now in the free play — or, with Δ = 0, on the other flank at once.
        mode_ = chooseMode(hit->sigma > 0, hit->sigma < 0);
        if (mode_ != MeshMode::Free)
        {
          ++contacts_;
          last_kind_ = static_cast<int>(Kind::Engage);
          last_sigma_ = -hit->sigma;
        }
        break;
      case Kind::Release:
        mode_ = MeshMode::Free;
        break;
      case Kind::ToKD:
        mode_ = hit->sigma > 0 ? MeshMode::Forward : MeshMode::Backward;
        break;
      case Kind::ToK2:
        mode_ = hit->sigma > 0 ? MeshMode::ForwardK2 : MeshMode::BackwardK2;
        break;
    }
  }
}

}  // namespace backlash_servo
