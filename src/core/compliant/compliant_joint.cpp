#include "compliant/compliant_joint.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/gear_mesh.h"
#include "compliant/compliant_joint_detail.h"
#include "numerics/linear_mode.h"
#include "numerics/mode_products.h"

namespace backlash_servo
{
using compliant_detail::isForward;
using compliant_detail::isK2;
using compliant_detail::roundingOf;

namespace
{
// A segment's event search windows, in units of its fastest time scale 1/‖Â‖₂: the first FIRST_WINDOW_SCALE long,
// each next one twice the one before, up to WINDOW_SCALE.
constexpr double FIRST_WINDOW_SCALE = 4.0;
constexpr double WINDOW_SCALE = 256.0;
// A segment without events is re-anchored at its state after this many of the longest windows (4096 fast time
// scales): the closed form's phases (ωτ) stay below ~4000 rad, whose rounding would otherwise grow with the segment's
// length (a joint gliding in contact for minutes drifted its energy balance by 2e-10 of its energy per second).
constexpr double REANCHOR_WINDOWS = 16.0;

/// The modes' order — the joint's size and two states per sine, the law's and the load's — within MAX_MODE_ORDER.
void requireOrder(int size, const Waveform& wave, const Waveform& load_wave, const char* key)
{
  const int count = wave.count + load_wave.count;
  if (size + 2 * count > MAX_MODE_ORDER)
  {
    throw InvalidParameterError(key, std::to_string(count) +
                                         " sines (the motor's and the load's together): a joint with a torsional "
                                         "shaft takes one exactly, with a rigid shaft two (a digital drive samples "
                                         "more)");
  }
}

}  // namespace

CompliantJoint::CompliantJoint(const ServoParams& params, const MotorInput& law)
    : s_(params),
      law_(law),
      torsional_(params.torsionalShaft()),
      msl_(params.mesh_law == "msl_elastobacklash"),
      rigid_(!params.compliant())
{
  s_.validate();
  if (rigid_)
  {
    requireExactWave(s_, "a sine");
  }
  requireOrder(size(), law_.wave, load_wave_, "wave");
  setState(Eigen::VectorXd::Zero(size()));
}

void CompliantJoint::setParams(const ServoParams& params, bool frame)
{
  if (!frame)
  {
    params.validate();
  }
  if (params.compliant() == rigid_ || params.torsionalShaft() != torsional_)
  {
    throw InvalidParameterError(params.compliant() ? "shaft_stiffness" : "mesh_stiffness",
                                "cannot switch between a rigid and a compliant " +
                                    std::string(params.compliant() ? "shaft" : "mesh") + " during a run");
  }
  // A parameter change is not a physical process: the ledger is kept and its reference re-based by the jump of the
  // stored and kinetic energy.
  const double before = kineticEnergy() + potentialEnergy();
  const CompliantEnergy kept = energy_;
  const double initial_kinetic = initial_kinetic_, initial_potential = initial_potential_;
  const std::uint64_t contacts = contacts_, reengagements = reengagements_;
  if (rigid_)
  {
    requireExactWave(params, "a sine");
  }
  const std::uint64_t impacts = impacts_;
  s_ = params;
  msl_ = params.mesh_law == "msl_elastobacklash";
  setState(state(), time_);
  impacts_ = impacts;
  energy_ = kept;
  contacts_ = contacts;
  reengagements_ = reengagements;
  initial_potential_ = initial_potential;
  initial_kinetic_ = initial_kinetic + (kineticEnergy() + potentialEnergy() - before);
}

void CompliantJoint::setLoadWave(const Waveform& wave)
{
  requireOrder(size(), law_.wave, wave, "load_wave");
  const Eigen::VectorXd phys = x_.head(size());
  load_wave_ = wave;
  setModeState(phys);
  segment_.reset();
}

void CompliantJoint::setLaw(const MotorInput& law)
{
  requireOrder(size(), law.wave, load_wave_, "wave");
  const Eigen::VectorXd phys = x_.head(size());
  law_ = law;
  setModeState(phys);
  segment_.reset();
  if (fresh_)
  {
    // Teeth touching at relative rest at the start engage as the law in force at the start pushes them.
    mode_ = chooseMode(false, false);
    contacts_ = mode_ == MeshMode::Free ? 0 : 1;
  }
}

void CompliantJoint::setWatch(double lo, double hi)
{
  if (lo == watch_lo_ && hi == watch_hi_)
  {
    return;
  }
  watch_lo_ = lo;
  watch_hi_ = hi;
  segment_.reset();
}

void CompliantJoint::setModeState(const Eigen::VectorXd& phys)
{
  const int n = size();
  x_.resize(dim());
  x_.head(n) = phys;
  int z = n;
  for (const Waveform* wave : {&law_.wave, &load_wave_})
  {
    for (int i = 0; i < wave->count; ++i, z += 2)
    {
      const double angle = wave->tones[static_cast<std::size_t>(i)].angle(time_);
      x_(z) = std::cos(angle);
      x_(z + 1) = std::sin(angle);
    }
  }
}

void CompliantJoint::setState(const Eigen::VectorXd& x, double t)
{
  if (x.size() != size() || !x.allFinite() || !std::isfinite(t))
  {
    throw std::invalid_argument("CompliantJoint::setState: expected " + std::to_string(size()) + " finite entries");
  }
  time_ = t;
  setModeState(x);
  for (int b = 0; b < 2; ++b)
  {
    // A body with dry friction at rest starts stuck: the segment's start applies the rest rule (it breaks away when
    // its holding torque is beyond the static band).
    dry_[b] = staticOf(b) > 0.0;
    const double v = x_(angleIndex(b) + 1);
    slide_[b] = !dry_[b] ? 1 : v > 0.0 ? 1 : v < 0.0 ? -1 : 0;
    stuck_at_[b] = x_(angleIndex(b));
    slide_began_[b] = -INFINITY;
  }
  mode_ = chooseMode(false, false);
  contacts_ = mode_ == MeshMode::Free ? 0 : 1;
  reengagements_ = 0;
  impacts_ = 0;
  last_kind_ = -1;
  release_time_[0] = release_time_[1] = -INFINITY;
  fresh_ = true;
  segment_.reset();
  energy_ = CompliantEnergy();
  initial_kinetic_ = kineticEnergy();
  initial_potential_ = potentialEnergy();
}

Eigen::VectorXcd CompliantJoint::eigenvalues() const
{
  ModeMatrix a;
  ModeVector u;
  modeMatrices(mode_, slide_, &a, &u);
  return a.topLeftCorner(size(), size()).eigenvalues();  // (not the wave's oscillator, ±jω)
}

double CompliantJoint::inertiaOf(int body) const
{
  return body == 0 ? s_.motor_inertia : torsional_ ? s_.load_inertia : s_.load_inertia + s_.gear_inertia;
}

double CompliantJoint::meshTorque() const
{
  if (mode_ == MeshMode::Free)
  {
    return 0.0;
  }
  const int sigma = isForward(mode_) ? 1 : -1;
  const bool k2 = isK2(mode_);
  ModeVector w;
  double w0;
  if (rigid_)
  {
    rigidMeshTorque(&w, &w0);
    return sigma * std::max(0.0, sigma * (w.dot(x_) + w0));
  }
  flankTorque(sigma, (k2 ? 2.0 : 1.0) * s_.mesh_stiffness, k2 ? 0.0 : s_.mesh_damping, &w, &w0);
  return sigma * std::max(0.0, w.dot(x_) + w0);
}

void CompliantJoint::penetration(int sigma, ModeVector* w, double* w0) const
{
  // y = σ(ρθ_m − θ_o) − δ, δ = 0 forward, Δ backward.
  *w = ModeVector::Zero(dim());
  (*w)(0) = sigma * s_.gear_ratio;
  (*w)(out()) = -sigma;
  *w0 = sigma > 0 ? 0.0 : -s_.backlash;
}

void CompliantJoint::flankTorque(int sigma, double ky, double kv, ModeVector* w, double* w0) const
{
  // ky y + kv ẏ with ẏ = σ(ρω_m − ω_o).
  *w = ModeVector::Zero(dim());
  (*w)(0) = sigma * ky * s_.gear_ratio;
  (*w)(out()) = -sigma * ky;
  (*w)(1) = sigma * kv * s_.gear_ratio;
  (*w)(out() + 1) = -sigma * kv;
  *w0 = sigma > 0 ? 0.0 : -ky * s_.backlash;
}

void CompliantJoint::modeMatrices(MeshMode m, const std::array<int, 2>& slide, ModeMatrix* a, ModeVector* u) const
{
  if (rigid_ && m != MeshMode::Free)
  {
    rigidContact(a, u);  // (either flank: the flank enters through the mesh torque's sign)
    return;
  }
  const int k = dim(), o = out(), l = loadIndex();
  *a = ModeMatrix::Zero(k, k);
  *u = ModeVector::Zero(k);
  const double rho = s_.gear_ratio, jm = s_.motor_inertia;
  const double j_out = torsional_ ? s_.gear_inertia : s_.load_inertia + s_.gear_inertia;
  ModeMatrix& A = *a;
  ModeVector& U = *u;
  A(0, 1) = 1.0;
  A(o, o + 1) = 1.0;
  // Motor: J_m ω̇_m = a − kθ_c − f_m ω_m − ρQ.
  A(1, 1) = -s_.motor_friction / jm;
  A(1, l) = -law_.stiffness / jm;
  U(1) = law_.offset / jm;
  addOscillators(law_.wave, size(), 1.0 / jm, 1, a);  // the sines on the motor
  if (m != MeshMode::Free)
  {
    // Q = k(ρθ_m − θ_o) + k_d(ρω_m − ω_o) − σ k δ_σ (δ = 0 forward, Δ backward).
    const int sigma = isForward(m) ? 1 : -1;
    const double kq = isK2(m) ? 2.0 * s_.mesh_stiffness : s_.mesh_stiffness;
    const double kd = isK2(m) ? 0.0 : s_.mesh_damping;
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
    const double ks = s_.shaft_stiffness, ds = s_.shaft_damping, jl = s_.load_inertia;
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
    addOscillators(load_wave_, loadWaveIndex(), 1.0 / jl, l + 1, a);  // the load's sines
  }
  else
  {
    A(o + 1, o + 1) += -s_.load_friction / j_out;
    U(o + 1) += s_.load_torque / j_out;
    addOscillators(load_wave_, loadWaveIndex(), 1.0 / j_out, o + 1, a);
  }
  for (int b = 0; b < 2; ++b)
  {
    const int i = angleIndex(b);
    if (slide[b] == 0)
    {
      // Stuck: angle and velocity stay (θ̇ = 0 too, so that the zero eigenvalue keeps a full eigenspace).
      A.row(i).setZero();
      A.row(i + 1).setZero();
      U(i) = U(i + 1) = 0.0;
    }
    else
    {
      U(i + 1) -= slide[b] * coulombOf(b) / inertiaOf(b);
    }
  }
}

void CompliantJoint::addOscillators(const Waveform& wave, int first, double gain, int row, ModeMatrix* a) const
{
  // Each sine's oscillator z = (cos, sin) of its angle, and A sin on the row.
  ModeMatrix& A = *a;
  for (int i = 0; i < wave.count; ++i)
  {
    const Sinusoid& s = wave.tones[static_cast<std::size_t>(i)];
    const int z = first + 2 * i;
    A(z, z + 1) = -s.frequency;
    A(z + 1, z) = s.frequency;
    A(row, z + 1) = gain * s.amplitude;
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
    ModeVector w;
    double w0;
    penetration(sigma, &w, &w0);
    double y = w.dot(x_) + w0;
    // A penetration within the rounding of the angles it is the difference of counts as touching.
    if (std::fabs(y) <= roundingOf(w, w0, x_))
    {
      y = 0.0;
    }
    flankTorque(sigma, 0.0, 1.0, &w, &w0);
    double ydot = w.dot(x_) + w0;
    // Touching, the rate too is judged against the rounding of the speeds it is the difference of.
    if (y == 0.0 && std::fabs(ydot) <= roundingOf(w, w0, x_))
    {
      ydot = 0.0;
    }
    if (rigid_ && (y != 0.0 || ydot != 0.0))
    {
      continue;  // rigid teeth: apart, or reaching the flank — an impact decides (a located event)
    }
    const double tc = s_.mesh_stiffness * y, td = s_.mesh_damping * ydot;
    if (y == 0.0 && ydot == 0.0)
    {
      // Touching at relative rest (the start): engaged when the free motion would push the teeth together.
      ModeMatrix a;
      ModeVector u;
      modeMatrices(MeshMode::Free, slide_, &a, &u);
      flankTorque(sigma, 0.0, 1.0, &w, &w0);
      // ÿ = w·ẋ; where it vanishes (a sine passing through zero at the start) its first derivative that does not
      // decides: w·A^j ẋ, j = 1, 2.
      ModeVector d = a * x_ + u;
      double press = w.dot(d);
      for (int j = 1; j <= 2 && std::fabs(press) <= roundingOf(w, 0.0, d); ++j)
      {
        d = a * d;
        press = w.dot(d);
      }
      if (press > 0.0)
      {
        // (msl_elastobacklash enters in K2, dẏ > cy = 0, unless the teeth are undamped — as at an engagement.)
        if (msl_ && s_.mesh_damping > 0.0)
        {
          return sigma > 0 ? MeshMode::ForwardK2 : MeshMode::BackwardK2;
        }
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

std::shared_ptr<const ModeBasis> CompliantJoint::basisFor(const ModeMatrix& a)
{
  // Bounded: a drive whose law stiffness keeps changing would otherwise grow it without end.
  constexpr std::size_t KEPT = 16;
  for (auto it = bases_.rbegin(); it != bases_.rend(); ++it)
  {
    const ModeMatrix& m = (*it)->matrix();
    if (m.rows() == a.rows() && m.cols() == a.cols() && m == a)  // (a wave adds two states: sizes differ)
    {
      std::shared_ptr<const ModeBasis> found = *it;
      if (it != bases_.rbegin())
      {
        bases_.erase(std::next(it).base());
        bases_.push_back(found);
      }
      return found;
    }
  }
  if (bases_.size() >= KEPT)
  {
    bases_.erase(bases_.begin());
  }
  bases_.push_back(std::make_shared<const ModeBasis>(a));
  return bases_.back();
}

std::vector<CompliantJoint::Watch> CompliantJoint::watchList() const
{
  const double c = s_.mesh_stiffness, d = s_.mesh_damping;
  const int l = loadIndex();
  std::vector<Watch> watches;
  watches.reserve(12);
  ModeVector w;
  double w0;
  if (mode_ == MeshMode::Free)
  {
    for (int sigma : {1, -1})
    {
      penetration(sigma, &w, &w0);
      const double y = w.dot(x_) + w0, band = roundingOf(w, w0, x_);
      if (y > band && !rigid_)
      {
        watches.push_back({w, w0, -1, MeshEvent::LeavePenetration, sigma});
        flankTorque(sigma, c, d, &w, &w0);  // P = cy + dẏ (msl: τc + τd, KD on re-engaging)
        watches.push_back({w, w0, +1, MeshEvent::Reengage, sigma});
      }
      else
      {
        // Penetrating within rounding (released there) is touching: the flank engages where y rises past that
        // rounding — watching P or y itself from a start whose sign is rounding could miss it for good. Not rigid
        // teeth, which an impact put exactly on the flank (moving off it, or the start's rule has engaged them): a
        // rebound's return found that late would gain the speed √(2ÿ·band) each time, and a chatter never end.
        watches.push_back({w, y > 0.0 && !rigid_ ? w0 - band : w0, +1, MeshEvent::Engage, sigma});
      }
    }
  }
  else
  {
    const int sigma = isForward(mode_) ? 1 : -1;
    if (rigid_)
    {
      rigidMeshTorque(&w, &w0);
      watches.push_back({sigma * w, sigma * w0, -1, MeshEvent::Release, sigma});  // σQ ↓ 0
    }
    else if (isK2(mode_))
    {
      flankTorque(sigma, c, -d, &w, &w0);  // c y − d ẏ ↑ 0
      watches.push_back({w, w0, +1, MeshEvent::SubMode, sigma});
      penetration(sigma, &w, &w0);
      watches.push_back({w, w0, -1, MeshEvent::Release, sigma});
    }
    else
    {
      flankTorque(sigma, c, d, &w, &w0);
      watches.push_back({w, w0, -1, MeshEvent::Release, sigma});
      if (msl_ && d > 0.0)  // (undamped, ElastoBacklash is the plain spring: no K2, whose switch would be the release)
      {
        flankTorque(sigma, -c, d, &w, &w0);  // d ẏ − c y ↑ 0
        watches.push_back({w, w0, +1, MeshEvent::SubMode, sigma});
      }
    }
  }
  for (int b = 0; b < 2; ++b)
  {
    if (!dry_[b])
    {
      continue;
    }
    if (slide_[b] == 0)
    {
      // Stuck: its holding torque H leaving ±T_s.
      holdingTorque(b, mode_, &w, &w0);
      watches.push_back({w, w0 - staticOf(b), +1, MeshEvent::Breakaway, b});
      watches.push_back({w, w0 + staticOf(b), -1, MeshEvent::Breakaway, b});
    }
    else
    {
      w = ModeVector::Zero(dim());
      w(angleIndex(b) + 1) = slide_[b];  // slide·ω falling through 0
      watches.push_back({w, 0.0, -1, MeshEvent::Stop, b});
    }
  }
  if (slide_[1] != 0)  // (a stuck load has no turning points and cannot leave the watched interval)
  {
    if (!dry_[1])  // (with dry friction its stop, watched above, is its turning point)
    {
      w = ModeVector::Zero(dim());
      w(l + 1) = 1.0;
      // Its turning points, both in one search (direction 0): the load's velocity just after tells a maximum from a
      // minimum (the watch stands for both).
      watches.push_back({w, 0.0, 0, MeshEvent::Maximum, 0});
    }
    w = ModeVector::Zero(dim());
    w(l) = 1.0;
    if (std::isfinite(watch_hi_))
    {
      watches.push_back({w, -watch_hi_, +1, MeshEvent::WatchExit, 1});
    }
    if (std::isfinite(watch_lo_))
    {
      watches.push_back({w, -watch_lo_, -1, MeshEvent::WatchExit, -1});
    }
  }
  return watches;
}

void CompliantJoint::beginSegment()
{
  if (forced())
  {
    setModeState(state());  // the oscillator exact at the segment's start (a function of time alone)
  }
  ModeMatrix a;
  ModeVector u;
  modeMatrices(mode_, slide_, &a, &u);
  std::shared_ptr<const ModeBasis> basis = basisFor(a);
  const double norm = std::max(basis->norm(), 1e-300);  // ‖Â‖₂ [1/s]
  // Windows of a fixed length from the anchor: long enough for many of the mode's fastest oscillations, short enough
  // that a window's search stays cheap.
  double window = WINDOW_SCALE / norm;
  if (horizon_ > time_ && horizon_ - time_ < window)
  {
    window = horizon_ - time_;
  }
  const double piece = 0.5 / norm;
  const double first_window = std::min(window, FIRST_WINDOW_SCALE / norm);
  segment_.emplace(std::move(basis), u, x_, time_, window, first_window, watchList(), energy_, slide_, piece);
  checkStart(a, u);
}

void CompliantJoint::resumeSegment(double tau)
{
  // The same motion on: only what is watched changed (a flank's penetration ended in the free play, a turning
  // point). Its watches are set up afresh from the state at tau, searched from there in short windows again.
  Segment& seg = *segment_;
  ModeMatrix a;
  ModeVector u;
  modeMatrices(mode_, slide_, &a, &u);
  seg.watches = watchList();
  seg.resumed = tau;
  seg.searched = tau;
  seg.event = INF;
  seg.hit = -1;
  seg.next_window = std::min(seg.window, FIRST_WINDOW_SCALE / std::max(seg.motion.norm(), 1e-300));
  checkStart(a, u);
}

void CompliantJoint::checkStart(const ModeMatrix& a, const ModeVector& u)
{
  // The watch `matches` picks becomes the event at the watches' start.
  Segment& seg = *segment_;
  const ModeVector x = x_, xd = mode_detail::affine(a, x, u);  // the state there, and ẋ: which way the outputs move
  const auto startWith = [&seg](const auto& matches) {
    for (std::size_t i = 0; i < seg.watches.size() && seg.event != seg.resumed; ++i)
    {
      if (matches(seg.watches[i]))
      {
        seg.event = seg.resumed;
        seg.hit = static_cast<int>(i);
        return;
      }
    }
  };
  // Where an output starts within its rounding band ±noise of zero: the side it leaves the band on first (+1 above,
  // −1 below, 0 neither within the segment's window).
  const auto leavesBand = [&seg](const Watch& o, double noise) {
    const double horizon = seg.resumed + seg.window;
    const double up = seg.motion.firstCrossing(o.w, o.w0 - noise, +1, horizon, seg.resumed);
    const double down = seg.motion.firstCrossing(o.w, o.w0 + noise, -1, std::min(up, horizon), seg.resumed);
    return down < up ? -1 : up < INFINITY ? 1 : 0;
  };
  if (mode_ != MeshMode::Free)
  {
    // A contact whose release output (P, or in K2 the penetration) starts below zero beyond rounding, or within it
    // and leaving it downwards, releases here, as the segment's first event: its crossing lay within the rounding of
    // this start (the end of the previous segment, a sample, evaluated again). Within the rounding, the rate alone
    // does not tell which way the output leaves: a contact touched at the start and pulled off by a stiff shaft may
    // rise by ṡ²/2|s̈|, far below the rounding, before it falls, and would pull all the while — the side on which it
    // leaves the band decides. A contact begun at this very instant releases only where its output starts below the
    // rounding: an engagement found within the rounding of a start (teeth touching at rest) whose teeth part at once
    // — the drive pulling the motor off — would otherwise keep a contact whose release output began below zero and
    // never crosses it, while its torque, clipped at zero, hides the missed release and the flank it crosses to.
    // (Within the band its rate and side are not asked: at a new contact they are rounding, and an output hovering
    // there — teeth without backlash chattering at rounding level — would be searched down to the floor.)
    const int sigma = isForward(mode_) ? 1 : -1;
    const bool just_engaged =
        last_time_ == time_ && last_sigma_ == sigma &&
        (last_kind_ == static_cast<int>(MeshEvent::Engage) || last_kind_ == static_cast<int>(MeshEvent::Reengage));
    startWith([&](Watch& r) {
      if (r.kind != MeshEvent::Release)
      {
        return false;
      }
      const double out = r.w.dot(x) + r.w0, noise = roundingOf(r.w, r.w0, x);
      if (out < -noise || (!just_engaged && std::fabs(out) <= noise &&
                           (r.w.dot(xd) < -roundingOf(r.w, 0.0, xd) || leavesBand(r, noise) < 0)))
      {
        return true;
      }
      // Kept with its output below zero within the rounding: it releases where the output falls past that rounding —
      // from a start whose sign is rounding, a crossing of zero itself may never come (the output already below it)
      // while the teeth part, as an engagement's watch waits for y to rise past its rounding.
      if (out < 0.0)
      {
        r.w0 += noise;
      }
      return false;
    });
    // msl_elastobacklash's sub-mode output (K2: cy − dẏ, KD: dẏ − cy) likewise: past its switch beyond rounding, or
    // within the rounding and leaving it upwards, switches here — also at an engagement: teeth entering K2 at a
    // grazing engagement, dẏ and cy both within the rounding of the angles, leave it at once as cy grows. (Leaving
    // upwards in one sub-mode is leaving downwards in the other: no switching back and forth.)
    startWith([&](const Watch& m) {
      if (m.kind != MeshEvent::SubMode)
      {
        return false;
      }
      const double out = m.w.dot(x) + m.w0, noise = roundingOf(m.w, m.w0, x);
      return out > noise || (std::fabs(out) <= noise && leavesBand(m, noise) > 0);
    });
  }
  else
  {
    // A flank the state presses (within rounding of touching and closing, or penetrating with P > 0) engages here,
    // as the segment's first event: its crossing lay within the rounding of an earlier start (a sample, a
    // re-anchoring) and had no sign to search for. Not a flank released at this very instant.
    const MeshMode pressing = chooseMode(release_time_[0] == time_, release_time_[1] == time_);
    if (pressing != MeshMode::Free)
    {
      const int sigma = isForward(pressing) ? 1 : -1;
      startWith([sigma](const Watch& e) {
        return e.sigma == sigma && (e.kind == MeshEvent::Engage || e.kind == MeshEvent::Reengage);
      });
    }
  }
  // Dry friction, likewise: a stuck body whose holding torque is beyond its static band (or at its edge and
  // leaving it) breaks away here; a sliding body whose velocity is against its slide (or zero and turning against
  // it) stops here — not one that began to slide at this very instant.
  for (int b = 0; b < 2 && seg.event != seg.resumed; ++b)
  {
    if (!dry_[b])
    {
      continue;
    }
    if (slide_[b] == 0)
    {
      startWith([&](const Watch& e) {
        if (e.kind != MeshEvent::Breakaway || e.sigma != b)
        {
          return false;
        }
        // H ∓ T_s in its direction: beyond the band, or at its edge and rising (H̊ from the moving bodies' rates).
        const double out = e.direction * (e.w.dot(x) + e.w0), noise = roundingOf(e.w, e.w0, x);
        return out > noise || (out >= -noise && e.direction * e.w.dot(xd) > roundingOf(e.w, 0.0, xd));
      });
    }
    else if (slide_began_[b] != time_)
    {
      const int v = angleIndex(b) + 1;
      const double along = slide_[b] * x_(v), accel = slide_[b] * xd(v);
      if (along < 0.0 || (along == 0.0 && accel < 0.0))
      {
        startWith([b](const Watch& e) { return e.kind == MeshEvent::Stop && e.sigma == b; });
      }
    }
  }
}

void CompliantJoint::searchNextWindow()
{
  Segment& seg = *segment_;
  // (The windows end where the segment is re-anchored: at REANCHOR_WINDOWS longest windows.)
  const double from = seg.searched, to = std::min(seg.searched + seg.next_window, REANCHOR_WINDOWS * seg.window);
  seg.next_window = std::min(2.0 * seg.next_window, seg.window);
  // The event that began this segment (or set up its watches again) lies at their start: its own crossing is not
  // searched for again within the search floor (1e-9 of the fastest time scale).
  const double skip = LinearMode::FLOOR_FRACTION / std::max(seg.motion.norm(), 1e-300);
  const double began = seg.start + seg.resumed;
  for (std::size_t i = 0; i < seg.watches.size(); ++i)
  {
    const Watch& watch = seg.watches[i];
    // (A body that began to slide from rest here: its velocity's zero at the start began the motion.)
    const bool again =
        from == seg.resumed &&
        ((static_cast<int>(watch.kind) == last_kind_ && watch.sigma == last_sigma_ && began == last_time_) ||
         (watch.kind == MeshEvent::Stop && slide_began_[watch.sigma] == began));
    const double tau = seg.motion.firstCrossing(watch.w, watch.w0, watch.direction, std::min(to, seg.event),
                                                again ? seg.resumed + skip : from, again);
    if (tau < seg.event)
    {
      seg.event = tau;
      seg.hit = static_cast<int>(i);
    }
  }
  seg.searched = to;
}

bool CompliantJoint::advanceTo(double t_end, const Observer& observer)
{
  double last_time = time_;
  long stalled = 0;  // events in a row at one instant
  while (true)
  {
    if (time_ != last_time)
    {
      last_time = time_;
      stalled = 0;
    }
    else if (++stalled > 1000000)
    {
      throw std::logic_error("CompliantJoint: no progress at t = " + std::to_string(time_) +
                             " s (internal error; please report with the parameters)");
    }
    if (!segment_)
    {
      beginSegment();
    }
    Segment& seg = *segment_;
    const double local_end = t_end - seg.start;
    const double anchor_end = REANCHOR_WINDOWS * seg.window;
    while (!std::isfinite(seg.event) && seg.searched < std::min(local_end, anchor_end))
    {
      searchNextWindow();
    }
    if (!std::isfinite(seg.event) && local_end > seg.searched && seg.searched >= anchor_end)
    {
      // No event over the segment's re-anchoring span: a new segment from its state there (not an event).
      moveTo(seg.searched, seg.start + seg.searched);
      segment_.reset();
      last_kind_ = -1;
      continue;
    }
    if (!(seg.event <= local_end))
    {
      moveTo(local_end, t_end);
      return false;
    }
    const double tau = seg.event;
    moveTo(tau, seg.start + tau);
    Watch watch = seg.watches[static_cast<std::size_t>(seg.hit)];
    const MeshEvent watched = watch.kind;  // (`again` compares the kind watched)
    // (The load's velocity just before a turning point: only those need it.)
    const double before = watched == MeshEvent::Maximum ? seg.motion.state(tau * (1.0 - 1e-6))(loadIndex() + 1) : 0.0;
    if (watch.kind == MeshEvent::Maximum && seg.motion.state(tau)(loadIndex() + 1) > 0.0)
    {
      watch.kind = MeshEvent::Minimum;  // (the turning points' watch: its velocity crossed upwards)
    }
    last_kind_ = static_cast<int>(watched);
    last_sigma_ = watch.sigma;
    last_time_ = time_;
    const MeshMode mode = mode_;
    const std::array<int, 2> slide = slide_;
    const double mesh_loss = energy_.mesh_loss;
    bool stop = false;
    // (A turning point only where the load moved that way just before — not a load at rest pushed off.)
    if (!(watch.kind == MeshEvent::Maximum && !(before > 0.0)) &&
        !(watch.kind == MeshEvent::Minimum && !(before < 0.0)))
    {
      stop = handle(watch, observer);
    }
    // An event that changed only what is watched (a turning point; a released flank's penetration ended in the free
    // play) goes on with the same motion; any other begins a new segment from the state now. (The observer may have
    // ended the segment already: a new law.)
    const bool watches_only = watched == MeshEvent::Maximum || watched == MeshEvent::LeavePenetration;
    if (segment_ && watches_only && mode_ == mode && slide_ == slide)
    {
      segment_->at_start.mesh_loss += energy_.mesh_loss - mesh_loss;  // (the ledger is placed from the segment's)
      resumeSegment(tau);
    }
    else
    {
      segment_.reset();
    }
    if (stop)
    {
      return true;
    }
  }
}

void CompliantJoint::moveTo(double tau, double t)
{
  fresh_ = fresh_ && tau == 0.0;
  x_ = segment_->motion.state(tau);
  for (int b = 0; b < 2; ++b)
  {
    if (segment_->slide[b] == 0)
    {
      // A stuck body stands exactly (the closed form's rounding would move it by a few ulps).
      x_(angleIndex(b)) = stuck_at_[b];
      x_(angleIndex(b) + 1) = 0.0;
    }
  }
  if (rigid_ && mode_ != MeshMode::Free)
  {
    // The meshed pair: the motor exactly where the flank puts it (the closed form keeps the gap to rounding).
    const int o = out();
    const GearMesh mesh(s_);
    x_(0) = mesh.motorPositionOnWall(x_(o), isForward(mode_) ? Contact::Forward : Contact::Backward);
    x_(1) = mesh.motorVelocityInContact(x_(o + 1));
  }
  time_ = t;
  if (track_energy_)
  {
    placeEnergy(tau);
  }
}

bool CompliantJoint::handle(const Watch& watch, const Observer& observer)
{
  // The mesh's stored energy may jump where its law changes (a release with y > 0, a re-engagement, K2 ↔ KD).
  fresh_ = false;
  const double stored = potentialEnergy();
  const int load_slide = slide_[1];
  const std::uint64_t impacts = impacts_;
  const bool other_flank = applyEvent(watch);
  if (rigid_ && watch.kind == MeshEvent::Engage && impacts_ == impacts)
  {
    return false;  // rigid teeth touching without closing: no impact, nothing to report
  }
  if (track_energy_)
  {
    energy_.mesh_loss += stored - potentialEnergy();
  }
  if (observer)
  {
    if (watch.kind == MeshEvent::Stop && watch.sigma == static_cast<int>(Body::Load))
    {
      // The load coming to rest is a turning point of θ_c as well (its velocity's zero is the same crossing).
      observer(load_slide > 0 ? MeshEvent::Maximum : MeshEvent::Minimum, 0);
    }
    if (other_flank)
    {
      if (watch.kind == MeshEvent::Release)
      {
        observer(MeshEvent::Release, watch.sigma);
      }
      if (!rigid_)  // (rigid teeth change flank without an impact)
      {
        observer(MeshEvent::Engage, -watch.sigma);
      }
    }
    else
    {
      const bool kinematic =
          watch.kind == MeshEvent::Maximum || watch.kind == MeshEvent::Minimum || watch.kind == MeshEvent::WatchExit;
      // (Stop and Breakaway report the body in sigma.)
      observer(watch.kind, kinematic ? 0 : watch.sigma);
      if (rigid_ && watch.kind == MeshEvent::Engage)
      {
        // An impact that reverses the load is a turning point of θ_c.
        const double before = last_impact_.load_velocity_before, after = x_(out() + 1);
        if (before > 0.0 && after <= 0.0)
        {
          observer(MeshEvent::Maximum, 0);
        }
        else if (before < 0.0 && after >= 0.0)
        {
          observer(MeshEvent::Minimum, 0);
        }
      }
    }
  }
  return !other_flank && watch.kind == MeshEvent::WatchExit;
}

bool CompliantJoint::applyEvent(const Watch& watch)
{
  const double d = s_.mesh_damping;
  switch (watch.kind)
  {
    case MeshEvent::Maximum:
    case MeshEvent::Minimum:
    case MeshEvent::WatchExit:
      break;
    case MeshEvent::Stop: {
      // At rest exactly: the rest rule decides whether it sticks or slides on in the direction of its torque.
      const int b = watch.sigma, i = angleIndex(b);
      x_(i + 1) = 0.0;
      slide_[b] = restSlide(b);
      stuck_at_[b] = x_(i);
      if (slide_[b] != 0)
      {
        slide_began_[b] = time_;
      }
      break;
    }
    case MeshEvent::Breakaway:
      slide_[watch.sigma] = watch.direction;
      slide_began_[watch.sigma] = time_;
      break;
    case MeshEvent::Engage:
      if (rigid_)
      {
        impact(watch.sigma);
        contacts_ += mode_ != MeshMode::Free ? 1 : 0;
        break;
      }
      ++contacts_;
      // msl_elastobacklash enters in K2 (dẏ > cy = 0) unless the teeth are undamped.
      mode_ = msl_ && d > 0.0 ? (watch.sigma > 0 ? MeshMode::ForwardK2 : MeshMode::BackwardK2)
                              : (watch.sigma > 0 ? MeshMode::Forward : MeshMode::Backward);
      break;
    case MeshEvent::Reengage: {
      ++contacts_;
      ++reengagements_;
      // At its crossing P = 0 (KD); found pressing at a segment's start, msl_elastobacklash may be in K2 (dẏ > cy).
      const bool forward = watch.sigma > 0;
      const MeshMode m = chooseMode(!forward, forward);  // this flank only
      mode_ = m != MeshMode::Free ? m : (watch.sigma > 0 ? MeshMode::Forward : MeshMode::Backward);
      break;
    }
    case MeshEvent::Release:
      release_time_[watch.sigma > 0 ? 0 : 1] = time_;
      if (rigid_ && s_.backlash == 0.0)
      {
        // Rigid teeth without backlash: the pair's torque passes through zero onto the other flank, at relative rest.
        mode_ = watch.sigma > 0 ? MeshMode::Backward : MeshMode::Forward;
        ++contacts_;
        last_kind_ = static_cast<int>(MeshEvent::Engage);
        last_sigma_ = -watch.sigma;
        return true;
      }
      [[fallthrough]];
    case MeshEvent::LeavePenetration:
      // Now in the free play — or, with Δ = 0, on the other flank at once (an undamped mesh's torque passes through
      // zero exactly where the penetration does).
      mode_ = chooseMode(watch.sigma > 0, watch.sigma < 0);
      if (mode_ != MeshMode::Free)
      {
        ++contacts_;
        last_kind_ = static_cast<int>(MeshEvent::Engage);
        last_sigma_ = -watch.sigma;
        return true;
      }
      break;
    case MeshEvent::SubMode:
      mode_ = isK2(mode_) ? (watch.sigma > 0 ? MeshMode::Forward : MeshMode::Backward)
                          : (watch.sigma > 0 ? MeshMode::ForwardK2 : MeshMode::BackwardK2);
      break;
  }
  return false;
}

}  // namespace backlash_servo
