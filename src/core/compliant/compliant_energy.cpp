// The compliant joint's energy ledger (compliant_joint.h): kinetic and stored energy, and the work and losses
// integrated over each segment by 8-point Gauss–Legendre pieces.
#include "compliant/compliant_joint.h"

#include <cmath>

#include "compliant/compliant_joint_detail.h"
#include "numerics/gauss_legendre.h"

namespace backlash_servo
{
using compliant_detail::isForward;
using compliant_detail::isK2;

double CompliantJoint::kineticEnergy() const
{
  const int o = out(), l = loadIndex();
  const double jo = torsional_ ? s_.gear_inertia : s_.gear_inertia + s_.load_inertia;
  double k = 0.5 * s_.motor_inertia * x_(1) * x_(1) + 0.5 * jo * x_(o + 1) * x_(o + 1);
  if (torsional_)
  {
    k += 0.5 * s_.load_inertia * x_(l + 1) * x_(l + 1);
  }
  return k;
}

double CompliantJoint::potentialEnergy() const
{
  double v = 0.0;
  if (mode_ != MeshMode::Free)
  {
    ModeVector w;
    double w0;
    penetration(isForward(mode_) ? 1 : -1, &w, &w0);
    const double y = w.dot(x_) + w0;
    v = (isK2(mode_) ? 1.0 : 0.5) * s_.mesh_stiffness * y * y;
  }
  if (torsional_)
  {
    const double twist = x_(out()) - x_(loadIndex());
    v += 0.5 * s_.shaft_stiffness * twist * twist;
  }
  return v;
}

double CompliantJoint::energyBalanceError() const
{
  const CompliantEnergy& e = energy_;
  return e.input + e.load_work - e.motor_friction - e.load_friction - e.mesh_loss - e.shaft_loss -
         e.motor_dry_friction - e.load_dry_friction - e.impact_loss -
         (kineticEnergy() + potentialEnergy() - initial_kinetic_ - initial_potential_);
}

void CompliantJoint::integrate(const Segment& seg, double a, double b, CompliantEnergy* e) const
{
  // (8-point Gauss–Legendre, gauss_legendre.h.)
  if (!(b > a))
  {
    return;
  }
  const int o = out(), l = loadIndex();
  const double mid = 0.5 * (a + b), half = 0.5 * (b - a);
  const bool damped_flank = mode_ != MeshMode::Free && !isK2(mode_);
  ModeVector wv;
  double wv0 = 0.0;
  if (damped_flank)
  {
    flankTorque(isForward(mode_) ? 1 : -1, 0.0, 1.0, &wv, &wv0);  // ẏ
  }
  CompliantEnergy sum;
  for (int i = 0; i < 8; ++i)
  {
    const double s = mid + half * GAUSS_NODE[i];
    const double w = half * GAUSS_WEIGHT[i];
    const ModeVector x = seg.motion.state(s);
    const double wm = x(1), wc = x(l + 1);
    sum.input += w * (law_.offset - law_.stiffness * x(l) + waveAt(law_.wave, size(), x)) * wm;
    sum.motor_friction += w * s_.motor_friction * wm * wm;
    sum.load_friction += w * s_.load_friction * wc * wc;
    sum.load_work += w * (s_.load_torque + waveAt(load_wave_, loadWaveIndex(), x)) * wc;
    sum.motor_dry_friction += w * s_.motor_coulomb_friction * seg.slide[0] * wm;
    sum.load_dry_friction += w * s_.load_coulomb_friction * seg.slide[1] * wc;
    if (damped_flank)
    {
      const double ydot = wv.dot(x) + wv0;
      sum.mesh_loss += w * s_.mesh_damping * ydot * ydot;
    }
    if (torsional_)
    {
      const double rate = x(o + 1) - wc;
      sum.shaft_loss += w * s_.shaft_damping * rate * rate;
    }
  }
  sum.input_magnitude = std::fabs(sum.input);
  *e += sum;
}

void CompliantJoint::nextPiece(Segment* segment, double* from, double* to)
{
  // (Checked every STRETCH_CHECK pieces: a heavily damped contact's fast part is gone after a few of them, and the
  // check costs as much as a piece.)
  constexpr long STRETCH_CHECK = 16;
  constexpr double STRETCH_MIN = 2.0;
  Segment& seg = *segment;
  if (!seg.stretched && seg.pieces_done > 0 && seg.pieces_done % STRETCH_CHECK == 0)
  {
    const double at = static_cast<double>(seg.pieces_done) * seg.piece;
    if (seg.motion.decayedSpeedup(at) >= STRETCH_MIN)
    {
      seg.stretched = true;
      seg.pieces_end = at;
    }
  }
  if (!seg.stretched)
  {
    *from = static_cast<double>(seg.pieces_done) * seg.piece;
    *to = static_cast<double>(seg.pieces_done + 1) * seg.piece;
    return;
  }
  *from = seg.pieces_end;
  *to = seg.pieces_end + seg.piece * seg.motion.decayedSpeedup(seg.pieces_end);
}

void CompliantJoint::placeEnergy(double tau)
{
  Segment& seg = *segment_;
  double from = 0.0, to = 0.0;
  for (nextPiece(&seg, &from, &to); to <= tau; nextPiece(&seg, &from, &to))
  {
    integrate(seg, from, to, &seg.pieces);
    ++seg.pieces_done;
    seg.pieces_end = to;
  }
  CompliantEnergy e = seg.pieces;
  integrate(seg, from, tau, &e);
  energy_ = seg.at_start;
  energy_ += e;
}

}  // namespace backlash_servo
