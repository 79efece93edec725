// Property fuzzing of the core: a deterministic random-case generator over the validated envelope and its
// edges, and the properties every case must keep. Used by test/fuzz/test_fuzz.cpp (a bounded sample in CI) and by
// backlash_fuzz (long runs, `bash scripts/fuzz_long.sh`). No ROS.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/simulation/simulator.h"

namespace fuzz
{
using namespace backlash_servo;
const double INERTIA_RATIO_MIN = INERTIA_SPLIT_MIN;
const double INERTIA_RATIO_MAX = INERTIA_SPLIT_MAX;

struct Case
{
  ServoParams params;
  DriveParams drive;  ///< continuous P law, or a sampled drive
  State start;
  double command = 1.0;
  double duration = 1.0;  ///< [s]
  /// A command profile instead of the constant command, or null; profile_yaml says it as a YAML list.
  std::shared_ptr<const CommandProfile> profile;
  std::string profile_yaml;
  std::string describe() const
  {
    std::ostringstream o;
    o.precision(17);
    o << "--motor-inertia " << params.motor_inertia << " --load-inertia " << params.load_inertia << " --motor-friction "
      << params.motor_friction << " --load-friction " << params.load_friction << " --gain " << params.gain
      << " --gear-ratio " << params.gear_ratio << " --backlash " << params.backlash << " --restitution "
      << params.restitution << " --load-torque " << params.load_torque << " --motor-coulomb-friction "
      << params.motor_coulomb_friction << " --motor-static-friction " << params.motor_static_friction
      << " --load-coulomb-friction " << params.load_coulomb_friction << " --load-static-friction "
      << params.load_static_friction << " --command " << command << " --contact "
      << (start.contact == Contact::Apart ? "none" : toString(start.contact)) << " --load-position "
      << start.load_position << " --load-velocity " << start.load_velocity << " --motor-position "
      << start.motor_position << " --motor-velocity " << start.motor_velocity << " --duration " << duration;
    if (params.compliant())
    {
      o << " --mesh-law " << params.mesh_law << " --mesh-stiffness " << params.mesh_stiffness << " --mesh-damping "
        << params.mesh_damping << " --gear-inertia " << params.gear_inertia << " --shaft-stiffness "
        << params.shaft_stiffness << " --shaft-damping " << params.shaft_damping;
    }
    if (!drive.sampled() && drive.torque_limit > 0.0)
    {
      o << " --torque-limit " << drive.torque_limit;
    }
    if (drive.sampled())
    {
      o << " --control-law " << drive.control_law << " --controller-rate " << drive.controller_rate
        << " --controller-delay " << drive.controller_delay << " --feedback " << drive.feedback
        << " --motor-encoder-resolution " << drive.motor_encoder_resolution << " --load-encoder-resolution "
        << drive.load_encoder_resolution << " --integral-gain " << drive.integral_gain << " --derivative-gain "
        << drive.derivative_gain << " --position-loop-gain " << drive.position_loop_gain << " --velocity-loop-gain "
        << drive.velocity_loop_gain << " --velocity-loop-integral-gain " << drive.velocity_loop_integral_gain
        << " --torque-limit " << drive.torque_limit;
    }
    if (drive.compensation != "none")
    {
      o << " --compensation " << drive.compensation << " --compensation-backlash " << drive.compensation_backlash
        << " --compensation-width " << drive.compensation_width << " --outer-loop-gain " << drive.outer_loop_gain
        << " --compensation-friction " << drive.compensation_friction << " --dither-amplitude "
        << drive.dither_amplitude << " --dither-frequency " << drive.dither_frequency << " --dither-shape "
        << drive.dither_shape;
    }
    if (profile)
    {
      o << " --profile FILE  # FILE: a YAML list " << profile_yaml;
    }
    return o.str();
  }
};

/// The drive's additions drawn on top of a case — a compensator on sampled drives, a command profile — from a stream
/// of their own, so that every case of a seed keeps the parameters it had before they were drawn.
inline void drawWorkbench(Case* c, std::uint64_t seed, std::uint64_t index)
{
  std::mt19937_64 rng(seed * 0xD1B54A32D192ED03ull + index + 1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto logu = [&](double lo, double hi) { return lo * std::pow(hi / lo, u(rng)); };
  const double delta = c->params.backlash;
  const double scale = delta > 0.0 ? delta : 1.0;
  const double omega_n = c->params.naturalFrequency();
  const double torque = c->params.gain * std::max(std::fabs(c->command), scale);
  DriveParams& d = c->drive;
  const DriveParams plain = d;  // kept when a drawn compensator is refused
  if (d.sampled() && u(rng) < 0.4)
  {
    const double k = u(rng);
    if (k < 0.5)
    {
      d.compensation = k < 0.25 ? "inverse" : "dual_loop";
      d.feedback = "motor";
      d.compensation_backlash = delta * logu(0.5, 1.5);
      d.compensation_width = u(rng) < 0.5 ? 0.0 : scale * logu(0.1, 10.0);
      d.outer_loop_gain = omega_n * logu(0.01, 0.5);
    }
    else if (k < 0.75)
    {
      d.compensation = "friction_feedforward";
      d.compensation_friction = torque * logu(1e-3, 0.5);
      d.compensation_width = u(rng) < 0.5 ? 0.0 : scale * logu(1e-3, 0.1);
    }
    else
    {
      d.compensation = "dither";
      d.dither_amplitude = torque * logu(1e-3, 0.5);
      d.dither_frequency = d.controller_rate * logu(0.01, 0.5);
      d.dither_shape = u(rng) < 0.5 ? "square" : "sine";
    }
  }
  else if (!d.sampled() && u(rng) < 0.2)
  {
    // The continuous law's compensators: friction feed-forward with a dead band, square dither.
    if (u(rng) < 0.5)
    {
      d.compensation = "friction_feedforward";
      d.compensation_friction = torque * logu(1e-3, 0.5);
      d.compensation_width = scale * logu(1e-3, 0.1);
    }
    else
    {
      d.compensation = "dither";
      d.dither_amplitude = torque * logu(1e-3, 0.5);
      d.dither_frequency = omega_n / (2.0 * 3.14159265358979) * logu(0.1, 10.0);
    }
  }
  try
  {
    d.validate();
  }
  catch (const InvalidParameterError&)
  {
    d = plain;
  }
  if (u(rng) < 0.2)
  {
    // Ramp to a point of the way, a step to the command, and (digital drives) a sine and a trapezoidal move.
    const double t0 = c->start.time, span = c->duration;
    const bool ramps = d.sampled() || !c->params.hasDryFriction();
    std::vector<ProfileSegment> segments;
    std::ostringstream y;
    y.precision(17);
    ProfileSegment first;
    first.kind = ramps ? ProfileSegment::Kind::Ramp : ProfileSegment::Kind::Step;
    first.time = t0 + span * 0.2 * u(rng);
    first.target = c->command * (u(rng) * 2.0 - 0.5);
    first.duration = span * logu(0.02, 0.3);
    segments.push_back(first);
    y << "[{" << (ramps ? "ramp" : "step") << ": {time: " << first.time << ", target: " << first.target
      << (ramps ? ", duration: " : "");
    if (ramps)
    {
      y << first.duration;
    }
    y << "}}";
    ProfileSegment step;
    step.time = t0 + span * (0.3 + 0.2 * u(rng));
    step.target = c->command;
    segments.push_back(step);
    y << ", {step: {time: " << step.time << ", target: " << step.target << "}}";
    if (d.sampled())
    {
      ProfileSegment sine;
      sine.kind = ProfileSegment::Kind::Sine;
      sine.time = t0 + span * 0.6;
      sine.amplitude = scale * logu(0.1, 10.0);
      sine.frequency = omega_n / (2.0 * 3.14159265358979) * logu(0.1, 2.0);
      sine.duration = span * 0.15;
      ProfileSegment move;
      move.kind = ProfileSegment::Kind::Move;
      move.time = t0 + span * 0.8;
      move.distance = -c->command * u(rng);
      move.max_velocity = std::fabs(c->command) * omega_n * logu(0.1, 1.0) + 1e-300;
      move.max_acceleration = move.max_velocity * omega_n * logu(0.1, 2.0);
      segments.push_back(sine);
      segments.push_back(move);
      y << ", {sine: {time: " << sine.time << ", amplitude: " << sine.amplitude << ", frequency: " << sine.frequency
        << ", duration: " << sine.duration << "}}, {move: {time: " << move.time << ", distance: " << move.distance
        << ", max_velocity: " << move.max_velocity << ", max_acceleration: " << move.max_acceleration << "}}";
    }
    y << "]";
    try
    {
      c->profile = std::make_shared<const CommandProfile>(c->command, segments);
      c->profile->requireTakenBy(d.sampled(), c->params.hasDryFriction());
      c->profile_yaml = y.str();
    }
    catch (const InvalidParameterError&)
    {
      c->profile.reset();  // a draw the profile rules refuse (e.g. a move of zero distance): none
    }
  }
}

/// Case number `index` of the sequence `seed` (any case can be replayed alone).
inline Case makeCase(std::uint64_t seed, std::uint64_t index)
{
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + index);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto logu = [&](double lo, double hi) { return lo * std::pow(hi / lo, u(rng)); };
  auto pick = [&](std::initializer_list<double> v) { return *(v.begin() + static_cast<int>(u(rng) * v.size())); };
  Case c;
  for (;;)  // draw until the point lies inside the validated envelope (the edges are drawn on purpose)
  {
    c = Case();  // nothing of a refused draw carries over
    const double omega_n = logu(NATURAL_FREQUENCY_MIN, NATURAL_FREQUENCY_MAX);
    const double zeta = u(rng) < 0.05 ? 0.0 : (u(rng) < 0.05 ? pick({5.0, 10.0}) : logu(1e-9, 3.0));
    const double ratio =
        u(rng) < 0.1 ? pick({INERTIA_RATIO_MIN, INERTIA_RATIO_MAX}) : logu(INERTIA_RATIO_MIN, INERTIA_RATIO_MAX);
    const double fr = u(rng) < 0.1 ? 0.0 : (u(rng) < 0.1 ? 1.0 : u(rng));
    const double total = logu(1e-4, 1e4);
    const double rho = u(rng) < 0.3 ? 1.0 : logu(1e-3, 1e3);
    ChartParams ch;
    ch.zeta = zeta;
    ch.natural_frequency = omega_n;
    ch.total_inertia = total;
    ch.inertia_ratio = ratio;
    ch.friction_ratio = fr;
    ch.gear_ratio = rho;
    ch.backlash = u(rng) < 0.1 ? 0.0 : logu(1e-6, 10.0);
    ch.restitution = u(rng) < 0.6 ? pick({0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0}) : u(rng);
    try
    {
      c.params = ch.toServoParams();
    }
    catch (const InvalidParameterError&)
    {
      continue;
    }
    const double delta = c.params.backlash;
    const double scale = delta > 0.0 ? delta : 1.0;
    c.command = (u(rng) < 0.5 ? -1.0 : 1.0) * scale * logu(1e-3, 1e6);
    const GearMesh mesh(c.params);
    const double kind = u(rng);
    c.start.contact =
        kind < 0.4 ? Contact::Forward : (kind < 0.6 && delta > 0.0 ? Contact::Backward : Contact::Forward);
    c.start.load_position = u(rng) < 0.5 ? 0.0 : (u(rng) - 0.5) * 4.0 * std::fabs(c.command);
    const double v_scale = omega_n * std::fabs(c.command) * pick({0.0, 1e-6, 0.1, 1.0, 10.0});
    c.start.load_velocity = (u(rng) - 0.5) * 2.0 * v_scale;
    if (kind >= 0.6 && delta > 0.0)
    {
      // Floating, anywhere in the gap (walls included), velocities into or out of the walls.
      c.start.contact = Contact::Apart;
      const double g = pick({0.0, 1.0, u(rng)}) * delta;
      c.start.motor_position = mesh.motorPosition(c.start.load_position, g);
      c.start.motor_velocity = (c.start.load_velocity + (u(rng) - 0.5) * 2.0 * v_scale) / rho;
    }
    else
    {
      c.start.motor_position = mesh.motorPositionOnWall(c.start.load_position, c.start.contact);
      c.start.motor_velocity = mesh.motorVelocityInContact(c.start.load_velocity);
    }
    c.duration = 20.0 * 2.0 * 3.14159265358979 / omega_n * pick({0.05, 1.0});
    // Part 2: a load torque (up to twice the torque the P law exerts at the step) and a digital drive.
    if (u(rng) < 0.3)
    {
      c.params.load_torque = (u(rng) - 0.5) * 4.0 * c.params.gain * std::fabs(c.command) / rho;
    }
    // (Sampled drives at any command the envelope allows: the limit |θ_R| ≤ 1e3 Δ they had, for energy residuals of
    // 3e-9 … 1e-8 measured beyond it, went with the apart mode's energy quadrature.)
    if (u(rng) < 0.3)
    {
      DriveParams& d = c.drive;
      d.controller_rate = omega_n / (2.0 * 3.14159265358979) * logu(10.0, 1000.0);
      d.controller_delay = u(rng) < 0.3 ? 1.0 : 0.0;
      const double law = u(rng);
      d.control_law = law < 0.4 ? "proportional" : (law < 0.8 ? "pid" : "cascade");
      d.feedback = u(rng) < 0.3 ? "motor" : "load";
      d.integral_gain = c.params.gain * omega_n * logu(1e-3, 0.5);
      d.derivative_gain = c.params.gain / omega_n * logu(1e-3, 1.0);
      d.position_loop_gain = omega_n * logu(0.1, 2.0);
      d.velocity_loop_gain = total / rho * omega_n * logu(0.1, 2.0);
      d.velocity_loop_integral_gain = d.velocity_loop_gain * omega_n * logu(0.01, 1.0);
      d.motor_encoder_resolution = u(rng) < 0.3 ? std::floor(logu(64.0, 1e6)) : 0.0;
      d.load_encoder_resolution = u(rng) < 0.3 ? std::floor(logu(64.0, 1e6)) : 0.0;
      d.torque_limit = u(rng) < 0.3 ? c.params.gain * std::fabs(c.command) * logu(0.05, 2.0) : 0.0;
    }
    else if (u(rng) < 0.15)
    {
      // The continuous law saturated: switches located where K|θ_R − θ_c| = T_max (Δ = 0 included: the rigid mesh's
      // flank flip-flop at Q ≈ 0 among them).
      c.drive.torque_limit = c.params.gain * std::fabs(c.command) * logu(0.05, 2.0);
    }
    // Dry friction and stiction, up to about the torque the P law exerts at the step (stick–slip, stuck off the
    // command, held bodies hit by the other).
    if (u(rng) < 0.3)
    {
      const double torque = c.params.gain * std::max(std::fabs(c.command), scale);
      c.params.motor_coulomb_friction = u(rng) < 0.3 ? 0.0 : torque * logu(1e-4, 0.5);
      c.params.motor_static_friction = c.params.motor_coulomb_friction * pick({1.0, 1.5, 3.0});
      c.params.load_coulomb_friction = u(rng) < 0.3 ? 0.0 : torque / rho * logu(1e-4, 0.5);
      c.params.load_static_friction = c.params.load_coulomb_friction * pick({1.0, 1.5, 3.0});
    }
    try
    {
      c.params.validate();
      c.drive.validate();
    }
    catch (const InvalidParameterError&)
    {
      continue;
    }
    drawWorkbench(&c, seed, index);
    return c;
  }
}

/// The mesh's reduced inertia μ at the load shaft [kg·m²]: the motor's J_m/ρ² against the output side of the mesh
/// (the gear J_g behind a torsional shaft, else the load).
inline double meshReducedInertia(const ServoParams& p)
{
  const double jm = p.motor_inertia / (p.gear_ratio * p.gear_ratio);
  const double jo = p.torsionalShaft() ? p.gear_inertia : p.load_inertia;
  return jm * jo / (jm + jo);
}

/// Case number `index` of the sequence `seed` with a compliant joint: the case's servo, command, start and drive, the
/// rigid teeth replaced by a mesh drawn across the envelope from a stream of its own — the contact frequency √(c/μ)
/// from ω_n to 1e4 ω_n, the contact damping ratio from 0 to 1, either mesh law, a torsional shaft in a third of the
/// cases (J_g/J_L and its frequency across the envelope) — and the case's dry friction kept; runs of two periods of
/// ω_n at most.
inline Case makeCompliantCase(std::uint64_t seed, std::uint64_t index)
{
  for (std::uint64_t attempt = 0;; ++attempt)
  {
    Case c = makeCase(seed, index + attempt * 0x100000000ull);
    std::mt19937_64 rng(seed * 0xA24BAED4963EE407ull + index * 7919 + attempt + 3);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    auto logu = [&](double lo, double hi) { return lo * std::pow(hi / lo, u(rng)); };
    ServoParams& p = c.params;
    const double omega_n = p.naturalFrequency();
    const bool shaft = u(rng) < 0.3;
    if (shaft)
    {
      // Split the load: the output gear J_g and the load J_L behind the shaft.
      const double split = logu(1e-2, 1e2);  // J_g / J_L
      const double total = p.load_inertia;
      p.load_inertia = total / (1.0 + split);
      p.gear_inertia = total - p.load_inertia;
      const double mu_s = p.gear_inertia * p.load_inertia / total;
      p.shaft_stiffness = mu_s * std::pow(omega_n * logu(1.0, 1e3), 2);
      p.shaft_damping = u(rng) < 0.3 ? 0.0 : 2.0 * logu(1e-3, 1.0) * std::sqrt(p.shaft_stiffness * mu_s);
    }
    const double mu = meshReducedInertia(p);
    p.mesh_stiffness = mu * std::pow(omega_n * logu(1.0, 1e4), 2);
    p.mesh_damping = u(rng) < 0.2 ? 0.0 : 2.0 * logu(1e-3, 1.0) * std::sqrt(p.mesh_stiffness * mu);
    p.mesh_law = u(rng) < 0.3 ? "msl_elastobacklash" : "spring_damper";
    // Two periods of ω_n at most: a stiff mesh makes every contact a train of fast oscillations.
    c.duration = std::min(c.duration, 4.0 * 3.14159265358979 / omega_n);
    try
    {
      p.validate();
      return c;
    }
    catch (const InvalidParameterError&)
    {
      // outside the envelope (an inertia split or frequency at its edge): draw again
    }
  }
}

/**
 * A compliant case of makeCompliantCase(seed, index) with its contact (and shaft) damping redrawn over the whole
 * envelope: damping ratios log-uniform from 0.01 up to where the damping rate reaches the envelope's edge
 * (COMPLIANT_DAMPING_RATE_RATIO_MAX ω_n) — overdamped contacts whose fast decay is over in a few of its time scales,
 * and contacts near their critical ratio (no modal form) — within the parameters' range. The rest of the case is
 * makeCompliantCase's.
 */
inline Case makeDampedCompliantCase(std::uint64_t seed, std::uint64_t index)
{
  constexpr double MESH_DAMPING_RANGE_MAX = 1e9;  // [N·m·s/rad] the parameters' own range (mesh and shaft)
  Case c = makeCompliantCase(seed, index);
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + index * 104729 + 11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ServoParams& p = c.params;
  const double edge = COMPLIANT_DAMPING_RATE_RATIO_MAX * p.naturalFrequency() * 0.999;  // [1/s]
  // ζ from 0.01 to the ratio whose rate 2ζ√(k/μ) is the edge: d = 2ζ√(kμ).
  const auto damping = [&](double stiffness, double mu) {
    const double top = std::max(0.02, edge / (2.0 * std::sqrt(stiffness / mu)));
    return std::min(MESH_DAMPING_RANGE_MAX, 2.0 * 0.01 * std::pow(top / 0.01, u(rng)) * std::sqrt(stiffness * mu));
  };
  p.mesh_damping = damping(p.mesh_stiffness, meshReducedInertia(p));
  if (p.torsionalShaft())
  {
    p.shaft_damping = damping(p.shaft_stiffness, p.gear_inertia * p.load_inertia / (p.gear_inertia + p.load_inertia));
  }
  return c;
}

/// Records the worst excursion of the gap out of [0, Δ] over every event.
struct GapWatch : EventSink
{
  GearMesh mesh;
  double command = 0.0;                           ///< θ_R [rad] (when no profile)
  std::shared_ptr<const CommandProfile> profile;  ///< θ_R(t), or null
  double worst = 0.0;                             // relative to the rounding scale
  void onEvent(const Event& e) override
  {
    const State& s = e.state;
    const double g = mesh.gap(s.load_position, s.motor_position);
    // Rounding scale: the positions and the set-point θ_R(t) — the law's closed forms are written about it, and a
    // ramp runs in a frame moving with it, so positions passing through zero at speed carry the rounding of |θ_R|
    // (e.g. θ_c = −4e-4 rad crossing zero at 26 rad/s during a ramp to −9.3 rad, gap 1.7e-15 rad out).
    const double set_point = std::fabs(profile ? profile->at(s.time) : command);
    const double tol =
        1e-12 * (std::fabs(s.load_position) + mesh.ratio * std::fabs(s.motor_position) + mesh.backlash + set_point);
    worst = std::max({worst, -g / tol, (g - mesh.backlash) / tol});
  }
};

/**
 * The compliant mesh's torque Q on the output gear [N·m] as its law gives it from a state (docs/model.md, Part 3),
 * written here independently of the simulator: y the penetration of a flank, ẏ its rate, τ_c = c·y, τ_d = d·ẏ;
 * spring_damper P = τ_c + τ_d, msl_elastobacklash P = τ_c + min(τ_c, τ_d) where τ_c + τ_d > 0; a flank with y > 0
 * transmits max(0, P) (a released flank re-engages exactly where P turns positive, so Q is a function of the state).
 * *scale receives what rounding of the angles and speeds can make of it (1e-9 of c·angles + d·speeds).
 */
inline double meshLawTorque(const ServoParams& p, const State& s, double* scale)
{
  const double rho = p.gear_ratio, c = p.mesh_stiffness, d = p.mesh_damping;
  const double g = s.load_position + s.shaft_twist - rho * s.motor_position;        // θ_o − ρθ_m [rad]
  const double gd = s.load_velocity + s.shaft_twist_rate - rho * s.motor_velocity;  // [rad/s]
  *scale =
      1e-9 *
      (c * (std::fabs(s.load_position) + std::fabs(s.shaft_twist) + rho * std::fabs(s.motor_position) + p.backlash) +
       d * (std::fabs(s.load_velocity) + std::fabs(s.shaft_twist_rate) + rho * std::fabs(s.motor_velocity)));
  double q = 0.0;
  for (int sigma : {1, -1})
  {
    const double y = sigma > 0 ? -g : g - p.backlash, yd = sigma > 0 ? -gd : gd;
    if (y <= 0.0)
    {
      continue;
    }
    const double tc = c * y, td = d * yd;
    const double push = tc + td <= 0.0 ? 0.0 : (p.mesh_law == "msl_elastobacklash" ? tc + std::min(tc, td) : tc + td);
    q += sigma * push;
  }
  return q;
}

/// Outcome class of one case: "ok", "budget" (stopped by the event budget: allowed), or a failure class.
struct Outcome
{
  std::string klass = "ok";
  std::string detail;
};

/// The case's joint, drive and profile as a simulator with the given event budget.
inline Simulator simulatorOf(const Case& c, std::uint64_t event_budget)
{
  Simulator sim(c.params, c.start, c.command);
  if (c.drive.sampled() || c.drive.torque_limit > 0.0 || c.drive.compensation != "none")  // not the plain P law
  {
    sim.setDrive(makePositionDrive(c.drive, c.params.gain, c.params.gear_ratio, c.command, c.start.time));
  }
  if (c.profile)
  {
    sim.setProfile(c.profile);
  }
  sim.setEventBudget(event_budget);
  return sim;
}

/// The largest figures seen at the probes of a run: kinetic energy [J], motor torque [N·m], angle [rad] and speed
/// [rad/s] of the bodies and the output gear, and the distance travelled [rad].
struct ProbeFigures
{
  double kinetic_max = 0.0, motor_torque_max = 0.0, angle_max = 0.0, speed_max = 0.0, travel = 0.0;
};

/**
 * A compliant joint's laws at one probe: the mesh transmits what its law says of the state (a flank pressed beyond
 * rounding but not in contact — a missed engagement — or a contact pulling shows here and nowhere else: no energy
 * flows through it), and a body with dry friction standing still is held by a torque within its static band (the
 * motor's T_m − ρQ, the load's Q + T_ext; S + T_ext behind a torsional shaft, S its spring–damper torque).
 */
inline Outcome compliantLaws(const Case& c, const Simulator& sim)
{
  double scale = 0.0;
  const double q = meshLawTorque(c.params, sim.state(), &scale);
  if (std::fabs(sim.meshTorque() - q) > scale + 1e-300)
  {
    std::ostringstream d;
    d << "mesh torque " << sim.meshTorque() << " N·m where its law gives " << q << " N·m at t = " << sim.state().time
      << " s";
    return {"mesh_law", d.str()};
  }
  const State& st = sim.state();
  const double shaft = c.params.shaft_stiffness * st.shaft_twist + c.params.shaft_damping * st.shaft_twist_rate;
  const double held[2] = {sim.motorTorque() - c.params.gear_ratio * q,
                          (c.params.torsionalShaft() ? shaft : q) + c.params.load_torque};
  const double band[2] = {c.params.motor_static_friction, c.params.load_static_friction};
  const double speed[2] = {st.motor_velocity, st.load_velocity};
  for (int b = 0; b < 2; ++b)
  {
    const double slack = 1e-9 * (band[b] + std::fabs(held[b])) + (b == 0 ? c.params.gear_ratio : 1.0) * scale;
    if (band[b] > 0.0 && speed[b] == 0.0 && std::fabs(held[b]) > band[b] + slack)
    {
      std::ostringstream d;
      d << (b == 0 ? "motor" : "load") << " stands under " << held[b] << " N·m beyond its static band " << band[b]
        << " N·m at t = " << st.time << " s";
      return {"stick_law", d.str()};
    }
  }
  return {};
}

/**
 * The run advanced in 1000 steps, watching the largest kinetic energy (the energy scale of fast, high-gain loops
 * whose energy swings between the probes) and, for the compliant mesh's and shaft's rounding, the angles, speeds and
 * distance travelled: their torques are computed from absolute angles and speeds, so c(ρθ_m − θ_o) carries ε·c·|θ|
 * of rounding however small the penetration, a force the state does not explain, whose work grows with the distance.
 */
inline Outcome probeRun(const Case& c, Simulator* sim, GapWatch* watch, ProbeFigures* figures)
{
  Simulator& whole = *sim;
  ProbeFigures& f = *figures;
  f.kinetic_max = whole.kineticEnergy();
  f.motor_torque_max = std::fabs(whole.motorTorque());
  State last = whole.state();
  const auto angles = [&](const State& st) {
    return std::max({std::fabs(st.load_position), std::fabs(st.load_position + st.shaft_twist),
                     c.params.gear_ratio * std::fabs(st.motor_position)});
  };
  const auto speeds = [&](const State& st) {
    return std::max({std::fabs(st.load_velocity), std::fabs(st.load_velocity + st.shaft_twist_rate),
                     c.params.gear_ratio * std::fabs(st.motor_velocity)});
  };
  f.angle_max = angles(last);
  f.speed_max = speeds(last);
  for (int i = 1; i <= 1000; ++i)
  {
    whole.advanceTo(i == 1000 ? c.start.time + c.duration : c.start.time + c.duration * i / 1000.0, watch);
    f.kinetic_max = std::max(f.kinetic_max, whole.kineticEnergy());
    f.motor_torque_max = std::max(f.motor_torque_max, std::fabs(whole.motorTorque()));
    const State& now = whole.state();
    f.angle_max = std::max(f.angle_max, angles(now));
    f.speed_max = std::max(f.speed_max, speeds(now));
    f.travel += std::fabs(now.load_position - last.load_position) +
                c.params.gear_ratio * std::fabs(now.motor_position - last.motor_position);
    last = now;
    if (c.params.compliant())
    {
      Outcome laws = compliantLaws(c, whole);
      if (laws.klass != "ok")
      {
        return laws;
      }
    }
  }
  return {};
}

/**
 * The energy ledger balances. The scale of the energies exchanged: the ledger's terms (the motor's work counted in
 * magnitude per segment: a sampled loop may pump energy in and out), the largest kinetic energy seen at the probes,
 * the energy stored in the P law's "spring" K(θ_R − θ_c)²/(2ρ) at both ends, and the work scale of the torques: every
 * work term is a torque times a displacement of angles known to rounding relative to the position scale, so the
 * largest torque (motor torque seen at the probes, static frictions, load torque) times that scale bounds what
 * rounding can make of them (a joint held by a 5 000 N·m stiction moving 1e-7 rad exchanges ~1e-7 J, but its angles
 * carry 1e-16 rad of rounding each). The compliant mesh's and shaft's rounding work is added with a margin of 8 ulps
 * (the worst case measured drifts by a quarter of one). A ramp of the continuous law runs in its moving frame, where
 * the ledger is the frame's: not checked then.
 */
inline Outcome energyBalance(const Case& c, const Simulator& whole, const ProbeFigures& f)
{
  const State& s = whole.state();
  const EnergyLedger& e = whole.energy();
  const MotorInput law = whole.plant().law();
  auto spring = [&](double x) {
    return law.stiffness > 0.0 ? law.torque(x) * law.torque(x) / (2.0 * law.stiffness * c.params.gear_ratio) : 0.0;
  };
  const double position_scale =
      std::max({std::fabs(c.start.load_position), std::fabs(s.load_position), std::fabs(c.command), c.params.backlash});
  const double work_scale =
      std::max(f.motor_torque_max, c.params.motor_static_friction) * position_scale / c.params.gear_ratio +
      std::max(std::fabs(c.params.load_torque), c.params.load_static_friction) * position_scale;
  const double energy_scale = std::max({std::fabs(e.input), e.input_magnitude, f.kinetic_max, std::fabs(e.load_work),
                                        e.motor_friction + e.load_friction + e.impact_loss + e.motor_dry_friction +
                                            e.load_dry_friction + e.mesh_loss + e.shaft_loss,
                                        e.initial_kinetic, e.initial_potential, e.potential, whole.kineticEnergy(),
                                        spring(c.start.load_position), spring(s.load_position), work_scale, 1e-300});
  const ServoParams& q = c.params;
  const double mesh_rounding = 8.0 * std::numeric_limits<double>::epsilon() *
                               ((q.mesh_stiffness + q.shaft_stiffness) * (f.angle_max + q.backlash) +
                                (q.mesh_damping + q.shaft_damping) * f.speed_max) *
                               f.travel;
  if (whole.energyValid() && std::fabs(whole.energyBalanceError()) > 1e-9 * energy_scale + mesh_rounding)
  {
    std::ostringstream d;
    d << "energy balance " << whole.energyBalanceError() << " J of " << energy_scale << " J (the stiff mesh's "
      << "rounding " << mesh_rounding << " J)";
    return {"energy", d.str()};
  }
  return {};
}

/// The same run cut into pieces (as output sampling or a node does) ends in the same state s, to 1e-9 of the scales.
inline Outcome sameInPieces(const Case& c, const State& s, const State& p)
{
  const double x_scale = std::max({std::fabs(s.load_position), std::fabs(c.command), c.params.backlash, 1e-300});
  const double v_scale = std::max(x_scale * c.params.naturalFrequency(), std::fabs(s.load_velocity));
  const double dx = std::max(std::fabs(p.load_position - s.load_position),
                             c.params.gear_ratio * std::fabs(p.motor_position - s.motor_position)) /
                    x_scale;
  const double dv = std::max(std::fabs(p.load_velocity - s.load_velocity),
                             c.params.gear_ratio * std::fabs(p.motor_velocity - s.motor_velocity)) /
                    v_scale;
  if (dx > 1e-9 || dv > 1e-9)
  {
    std::ostringstream d;
    d << "chunked run differs: position " << dx << ", velocity " << dv << " (relative)";
    return {"chunking", d.str()};
  }
  return {};
}

/// One case run and checked: its laws at 1000 probes, a finite end, the gap within [0, Δ] (rigid), the energy
/// ledger, and the same end when run in 17 pieces.
inline Outcome check(const Case& c, std::uint64_t event_budget = 100000)
{
  try
  {
    Simulator whole = simulatorOf(c, event_budget);
    GapWatch watch;
    watch.mesh = GearMesh(c.params);
    watch.command = c.command;
    watch.profile = c.profile;
    ProbeFigures figures;
    const Outcome probed = probeRun(c, &whole, &watch, &figures);
    if (probed.klass != "ok")
    {
      return probed;
    }
    const State& s = whole.state();
    if (!std::isfinite(s.load_position) || !std::isfinite(s.motor_position) || !std::isfinite(s.load_velocity) ||
        !std::isfinite(s.motor_velocity))
    {
      // An unstable digital loop may run off to infinity within the run: allowed, counted; elsewhere a failure.
      return {c.drive.sampled() ? "diverged" : "nonfinite", "final state not finite"};
    }
    if (!c.params.compliant() && watch.worst > 1.0)  // (a compliant mesh penetrates: its gap leaves [0, Δ])
    {
      return {"gap", "gap left [0, backlash] by " + std::to_string(watch.worst) + " x 1e-12 of the position scale"};
    }
    Simulator pieces = simulatorOf(c, event_budget);
    for (int i = 1; i <= 17; ++i)
    {
      pieces.advanceTo(i == 17 ? c.start.time + c.duration : c.start.time + c.duration * i / 17.0);
    }
    const Outcome energy = energyBalance(c, whole, figures);
    if (energy.klass != "ok")
    {
      return energy;
    }
    return sameInPieces(c, s, pieces.state());
  }
  catch (const EventBudgetExceeded& e)
  {
    return {"budget", e.what()};
  }
  catch (const MotionDiverged& e)
  {
    // An unstable digital loop (large integral gains, delay), or a load torque beyond what the law and the friction
    // can hold (the load falls for ever), stopped where it left the closed forms' bounds: allowed. Otherwise the
    // continuous law on a joint with friction cannot run away: there it is a failure.
    // With a compliant mesh or shaft the continuous law can be unstable too: feedback from the load through an
    // undamped compliance (non-collocated) grows the two-mass mode beyond a critical gain.
    return {c.drive.sampled() || c.params.load_torque != 0.0 || c.params.compliant() ? "diverged" : "exception",
            e.what()};
  }
  catch (const std::exception& e)
  {
    const std::string what = e.what();
    if (c.drive.sampled() && what.find("overflowed") != std::string::npos)
    {
      return {"diverged", what};  // an unstable digital loop (large integral gains, delay): a clear stop, allowed
    }
    return {what.find("no progress") != std::string::npos ? "no_progress" : "exception", what};
  }
}

}  // namespace fuzz
