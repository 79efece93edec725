#include "backlash_servo/rigid/dry_friction.h"

#include <cmath>

#include "backlash_servo/model/gear_mesh.h"

namespace backlash_servo
{
Slide restSlide(double torque, double static_friction)
{
  if (std::fabs(torque) <= static_friction)
  {
    return 0;
  }
  return torque > 0.0 ? 1 : -1;
}

RestDecision decideAtRest(const ServoParams& p, double motor_torque, const State& s)
{
  const double rho = p.gear_ratio;
  // Step 1: each body on its own (Q = 0); viscous terms vanish for a body at rest.
  RestDecision apart;
  apart.motor = slideOf(s.motor_velocity, restSlide(motor_torque, p.motor_static_friction));
  apart.load = slideOf(s.load_velocity, restSlide(p.load_torque, p.load_static_friction));
  if (s.contact == Contact::Apart)
  {
    return apart;
  }
  if (apart.motor == 0 && apart.load == 0)
  {
    // Both hold on their own: nothing moves, the teeth keep touching (the pair is stuck as well: |A| ≤ S).
    apart.contact = s.contact;
    return apart;
  }
  const double motor_accel =
      apart.motor == 0 ? 0.0
                       : (motor_torque - p.motor_friction * s.motor_velocity - apart.motor * p.motor_coulomb_friction) /
                             p.motor_inertia;
  const double load_accel =
      apart.load == 0
          ? 0.0
          : (p.load_torque - p.load_friction * s.load_velocity - apart.load * p.load_coulomb_friction) / p.load_inertia;
  const double gap_accel = load_accel - rho * motor_accel;
  Contact wall = s.contact;
  if (p.backlash == 0.0)
  {
    wall = gap_accel < 0.0 ? Contact::Forward : Contact::Backward;
  }
  const bool into_wall = wall == Contact::Forward ? gap_accel < 0.0 : gap_accel > 0.0;
  if (!into_wall && p.backlash > 0.0)
  {
    return apart;
  }
  // Step 2: the teeth press; the pair at the load shaft.
  const double applied = rho * motor_torque + rho * rho * p.load_torque;
  const double capacity = rho * p.motor_static_friction + rho * rho * p.load_static_friction;
  RestDecision pair;
  pair.contact = wall;
  if (std::fabs(applied) <= capacity)
  {
    return pair;  // stuck together
  }
  const Slide dir = applied > 0.0 ? 1 : -1;
  const double kinetic = rho * p.motor_coulomb_friction + rho * rho * p.load_coulomb_friction;
  const double accel = (applied - dir * kinetic) / p.totalInertia();
  const double mesh_torque = p.load_inertia * accel + dir * p.load_coulomb_friction - p.load_torque;
  pair.motor = dir;
  pair.load = dir;
  if (p.backlash == 0.0)
  {
    pair.contact = mesh_torque >= 0.0 ? Contact::Forward : Contact::Backward;  // a rigid mesh presses one flank
    return pair;
  }
  if (mesh_torque * GearMesh::pressingSign(wall) >= 0.0)
  {
    return pair;
  }
  return apart;  // the pair would pull its own teeth apart: they break away separately
}

void foldKineticFriction(const ServoParams& p, const MotorInput& law, Slide motor, Slide load,
                         ServoParams* folded_params, MotorInput* folded_law)
{
  *folded_params = p;
  folded_params->load_torque = p.load_torque - load * p.load_coulomb_friction;
  folded_params->motor_coulomb_friction = 0.0;
  folded_params->motor_static_friction = 0.0;
  folded_params->load_coulomb_friction = 0.0;
  folded_params->load_static_friction = 0.0;
  *folded_law = law;
  folded_law->offset = law.offset - motor * p.motor_coulomb_friction;
}

}  // namespace backlash_servo
