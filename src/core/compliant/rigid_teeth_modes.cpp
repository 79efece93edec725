// Rigid teeth in the compliant joint's linear modes (compliant_joint.h, "Rigid teeth"): when a sine is exact on them,
// the meshed pair's mode, the torque that releases it, and the impacts (the thesis' impact map).
#include "compliant/compliant_joint.h"

#include <cmath>
#include <string>
#include <utility>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/gear_mesh.h"
#include "backlash_servo/rigid/impact.h"

#include "compliant/compliant_joint_detail.h"

namespace backlash_servo
{

void requireExactWave(const ServoParams& p, const std::string& what)
{
  if (p.compliant())
  {
    return;
  }
  const std::pair<const char*, double> dry[] = {{"motor_static_friction", p.motor_static_friction},
                                                {"motor_coulomb_friction", p.motor_coulomb_friction},
                                                {"load_static_friction", p.load_static_friction},
                                                {"load_coulomb_friction", p.load_coulomb_friction}};
  for (const auto& [key, value] : dry)
  {
    if (value != 0.0)
    {
      throw InvalidParameterError(key, formatNumber(value) + ": " + what +
                                           " is exact on rigid teeth only without dry friction; give a "
                                           "controller_rate (the sine sampled and held) or a compliant mesh");
    }
  }
}

void CompliantJoint::rigidContact(ModeMatrix* a, ModeVector* u) const
{
  // The pair as one body on the load shaft (θ_c = θ_o, no shaft): J ω̇_c = ρ(a − kθ_c + A sin) − F_T ω_c + ρ²T_ext,
  // T_ext = load_torque + Σ B sin.
  // The motor follows it — θ̇_m = ω_c/ρ, ω̇_m = ω̇_c/ρ — so the gap stays exactly as it began, and the motor's
  // columns are zero (its eigenvalues 0 have a full eigenspace: no polynomial in the closed form).
  const int k = dim(), o = out();
  *a = ModeMatrix::Zero(k, k);
  *u = ModeVector::Zero(k);
  const double rho = s_.gear_ratio;
  const double r = 1.0 / s_.totalInertia();
  ModeMatrix& A = *a;
  ModeVector& U = *u;
  A(o, o + 1) = 1.0;
  A(o + 1, o + 1) = -s_.totalFriction() * r;
  A(o + 1, o) = -rho * law_.stiffness * r;
  U(o + 1) = (rho * law_.offset + rho * rho * s_.load_torque) * r;
  addOscillators(law_.wave, size(), rho * r, o + 1, a);                  // the sines on the pair, ρT_m
  addOscillators(load_wave_, loadWaveIndex(), rho * rho * r, o + 1, a);  // and the load's, ρ²T_ext
  A(0, o + 1) = 1.0 / rho;
  A.row(1) = A.row(o + 1) / rho;
  U(1) = U(o + 1) / rho;
}

void CompliantJoint::rigidMeshTorque(ModeVector* w, double* w0) const
{
  // Q = J_L ω̇_c + f_L ω_c − T_ext, ω̇_c the pair's.
  ModeMatrix a;
  ModeVector u;
  rigidContact(&a, &u);
  const int o = out();
  const double jl = s_.load_inertia;
  *w = jl * a.row(o + 1).transpose();
  (*w)(o + 1) += s_.load_friction;
  *w0 = jl * u(o + 1) - s_.load_torque;
  for (int i = 0; i < load_wave_.count; ++i)
  {
    (*w)(loadWaveIndex() + 2 * i + 1) -= load_wave_.tones[static_cast<std::size_t>(i)].amplitude;  // − the sines
  }
}

void CompliantJoint::impact(int sigma)
{
  const double rho = s_.gear_ratio, delta = s_.backlash;
  const int o = out();
  const GearMesh mesh(s_);
  const Contact wall = sigma > 0 ? Contact::Forward : Contact::Backward;
  x_(0) = mesh.motorPositionOnWall(x_(o), wall);  // onto the flank exactly (moves θ_m by rounding)
  const double v = x_(o + 1), w = x_(1);
  const double closing = mesh.closingSpeed(wall, v, w);  // ẏ > 0: the teeth approach
  const double speed_noise = 64.0 * EPS * (std::fabs(v) + rho * std::fabs(w));
  if (!(closing > 0.0) && -closing > speed_noise)
  {
    mode_ = MeshMode::Free;  // clearly moving away: only rounding put the gap on the flank
    return;
  }
  // The free motion's acceleration ÿ pressing the teeth together: a rebound s rises s²/(2ÿ) off the flank.
  ModeMatrix a;
  ModeVector u, wy;
  double wy0;
  modeMatrices(MeshMode::Free, slide_, &a, &u);
  flankTorque(sigma, 0.0, 1.0, &wy, &wy0);
  const double press = wy.dot(a * x_ + u);
  const double gap_noise = 64.0 * EPS * (std::fabs(x_(o)) + rho * std::fabs(x_(0)) + delta);
  const double rebound = s_.restitution * std::max(closing, 0.0);
  const bool plastic =
      rebound <= speed_noise || delta == 0.0 || (press > 0.0 && rebound * rebound <= 2.0 * gap_noise * press);
  const ImpactOutcome out = ImpactMap(s_, plastic ? 0.0 : s_.restitution)(v, w);
  x_(o + 1) = out.load_velocity;
  x_(1) = out.motor_velocity;
  if (track_energy_)
  {
    energy_.impact_loss += out.energy_loss;
  }
  mode_ = plastic ? chooseMode(false, false) : MeshMode::Free;
  if (closing > 0.0)
  {
    ++impacts_;
    last_impact_ = JointImpact{sigma, v, w, closing, out, mode_ != MeshMode::Free};
  }
}

}  // namespace backlash_servo
