#include "backlash_servo/frequency/driven_mesh.h"

#include <cmath>
#include <complex>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "backlash_servo/model/constants.h"
#include "frequency/driven_periods.h"
#include "numerics/gauss_legendre.h"
#include "numerics/linear_mode.h"

namespace backlash_servo
{
namespace
{
/// What a watched output's crossing means.
enum class Kind
{
  Engage,    ///< contact on flank σ begins (y rising through 0, or P rising through 0 inside the flank)
  Release,   ///< the teeth would pull (P falling through 0), or — in msl's 2c·y sub-mode — y falling through 0
  Leave,     ///< y falling through 0 while free: back in the free play (the watches change)
  Switch,    ///< msl_elastobacklash's sub-mode changes: d·ẏ − c·y crossing 0
  Stop,      ///< dry friction: a sliding load's velocity reaching 0 (the rest rule decides)
  Breakaway  ///< dry friction: a stuck load's holding torque leaving [−T_s, T_s]
};

struct Watch
{
  ModeVector w;
  double w0;
  int direction;
  Kind kind;
  int sigma;
};

/// The load behind the compliant mesh, its tooth moving as A sin ωt (see the file comment). State (θ_c, θ̇_c, cos ωt,
/// sin ωt).
class MeshElement
{
 public:
  MeshElement(const ServoParams& p, double amplitude, double omega)
      : j_(p.load_inertia),
        f_(p.load_friction),
        c_(p.mesh_stiffness),
        d_(p.mesh_damping),
        half_(0.5 * p.backlash),
        a_(amplitude),
        w_(omega),
        msl_(p.mesh_law == "msl_elastobacklash"),
        tc_(p.load_coulomb_friction),
        ts_(std::max(p.load_static_friction, p.load_coulomb_friction)),
        dry_(tc_ > 0.0 || ts_ > 0.0),
        x_(4)
  {
    x_ << 0.0, 0.0, 1.0, 0.0;
    Eigen::MatrixXd free = Eigen::MatrixXd::Zero(4, 4);
    free(0, 1) = 1.0;
    free(1, 1) = -f_ / j_;
    free(2, 3) = -w_;  // d/dt cos ωt = −ω sin ωt
    free(3, 2) = w_;   // d/dt sin ωt = ω cos ωt
    Eigen::MatrixXd contact = free;
    // J_L θ̈_c = −f_L θ̇_c + c(A sin ωt − θ_c) + d(Aω cos ωt − θ̇_c) − σcΔ/2.
    contact(1, 0) = -c_ / j_;
    contact(1, 1) = -(f_ + d_) / j_;
    contact(1, 2) = d_ * a_ * w_ / j_;
    contact(1, 3) = c_ * a_ / j_;
    // msl's 2c·y sub-mode: J_L θ̈_c = −f_L θ̇_c + 2c(A sin ωt − θ_c) − σ2cΔ/2.
    Eigen::MatrixXd doubled = free;
    doubled(1, 0) = -2.0 * c_ / j_;
    doubled(1, 3) = 2.0 * c_ * a_ / j_;
    const Eigen::MatrixXd* a[3] = {&free, &contact, &doubled};
    for (int k = 0; k < 3; ++k)
    {
      basis_[k][0] = std::make_shared<const ModeBasis>(*a[k]);
      Eigen::MatrixXd stuck = *a[k];
      stuck.topRows(2).setZero();  // the load held: θ_c and θ̇_c = 0 stay
      basis_[k][1] = std::make_shared<const ModeBasis>(stuck);
    }
  }

  double position() const { return x_(0); }
  double velocity() const { return x_(1); }
  /// 0 free, ±1 on the forward / backward flank (±2 there in msl's 2c·y sub-mode), times 3, plus the load's slide
  /// (0 stuck, ±1 sliding; 0 without dry friction).
  int phase() const { return 3 * (doubled_mode_ ? 2 * phase_ : phase_) + slide_; }
  /// From now on, ∫ F e^{−jωt} dt over [from, to] is summed: F the load's dry friction torque (T_c·slide while it
  /// slides, the holding torque while stuck) [N·m·s].
  void recordFriction(double from, double to)
  {
    record_from_ = from;
    record_to_ = to;
    friction_line_ = 0.0;
  }
  std::complex<double> frictionLine() const { return friction_line_; }

  /// The motion to t [s] ≥ now, exactly.
  void advanceTo(double t)
  {
    while (t_ < t)
    {
      x_(2) = std::cos(w_ * t_);  // the sine's phase from the time (no drift over many periods)
      x_(3) = std::sin(w_ * t_);
      settlePhase();
      settleSlide();
      ModeVector u = ModeVector::Zero(4);
      const bool stuck = dry_ && slide_ == 0;
      if (phase_ != 0 && !stuck)
      {
        u(1) = -phase_ * (doubled_mode_ ? 2.0 : 1.0) * c_ * half_ / j_;
      }
      if (dry_ && !stuck)
      {
        u(1) -= slide_ * tc_ / j_;
      }
      const LinearMode m(basis_[phase_ == 0 ? 0 : doubled_mode_ ? 2 : 1][stuck ? 1 : 0], u, x_);
      const std::vector<Watch> watches = watchesNow();
      const double horizon = t - t_;
      const double skip = LinearMode::FLOOR_FRACTION / std::max(m.norm(), 1e-300);
      double best = INF;
      int hit = -1;
      for (std::size_t i = 0; i < watches.size(); ++i)
      {
        const Watch& wa = watches[i];
        // The crossing that began this segment is not searched for again at its start.
        // (Nor a velocity's zero at the start of a slide begun at rest.)
        const bool again = t_ == last_time_ && ((static_cast<int>(wa.kind) == last_kind_ && wa.sigma == last_sigma_) ||
                                                wa.kind == Kind::Stop);
        const double tau =
            m.firstCrossing(wa.w, wa.w0, wa.direction, std::min(horizon, best), again ? skip : 0.0, again);
        if (tau < best)
        {
          best = tau;
          hit = static_cast<int>(i);
        }
      }
      if (hit < 0 || !(best <= horizon))
      {
        recordSegment(m, horizon);
        x_ = m.state(horizon);
        t_ = t;
        return;
      }
      recordSegment(m, best);
      x_ = m.state(best);
      t_ += best;
      const Watch& e = watches[static_cast<std::size_t>(hit)];
      last_time_ = t_;
      last_kind_ = static_cast<int>(e.kind);
      last_sigma_ = e.sigma;
      if (e.kind == Kind::Engage)
      {
        phase_ = e.sigma;
        // msl: a contact begun at the flank (y = 0, ẏ > 0: d·ẏ > c·y) is in its 2c·y sub-mode; one begun inside it
        // where P rises through 0 (d·ẏ = −c·y < c·y) in its c·y + d·ẏ sub-mode.
        ModeVector w;
        double w0;
        balance(phase_, &w, &w0);
        doubled_mode_ = msl_ && w.dot(x_) + w0 > 0.0;
      }
      else if (e.kind == Kind::Release)
      {
        phase_ = 0;
        doubled_mode_ = false;
      }
      else if (e.kind == Kind::Switch)
      {
        doubled_mode_ = !doubled_mode_;
      }
      else if (e.kind == Kind::Stop)
      {
        x_(1) = 0.0;  // at rest: the rest rule decides (settleSlide)
        slide_ = 0;
      }
      else if (e.kind == Kind::Breakaway)
      {
        slide_ = e.sigma;
      }
      if (++events_ > 10000000)
      {
        throw InvalidParameterError("mesh_stiffness", "the driven compliant element made more than 1e7 contacts");
      }
    }
  }

 private:
  /// At a segment's start: a free flank penetrated (or touching within rounding) whose torque pushes engages now —
  /// a watch for P rising through 0 cannot see a P that starts above it —, a contact whose torque pulls beyond
  /// rounding releases now (its crossing lay within the rounding of an earlier event); not the flank that changed at
  /// this very instant. msl's sub-mode is the one the state is in beyond rounding (else it stays).
  void settlePhase()
  {
    const double y_band = 1e-12 * (a_ + 2.0 * half_), p_band = 1e-12 * (c_ * (a_ + 2.0 * half_) + d_ * a_ * w_);
    ModeVector w;
    double w0;
    const bool just = t_ == last_time_;
    if (phase_ == 0)
    {
      for (int sigma : {1, -1})
      {
        penetration(sigma, &w, &w0);
        const double y = w.dot(x_) + w0;
        torque(sigma, &w, &w0);
        if (y > -y_band && w.dot(x_) + w0 > 0.0 && !(just && last_sigma_ == sigma))
        {
          phase_ = sigma;
          subModeFromState(p_band, false);
          return;
        }
      }
      return;
    }
    subModeFromState(p_band, just && last_kind_ == static_cast<int>(Kind::Switch));
    doubled_mode_ ? penetration(phase_, &w, &w0) : torque(phase_, &w, &w0);
    if (w.dot(x_) + w0 < -(doubled_mode_ ? y_band : p_band) && !(just && last_kind_ == static_cast<int>(Kind::Engage)))
    {
      phase_ = 0;
      doubled_mode_ = false;
    }
  }

  /// The load's holding torque H = w·state + w₀ [N·m]: the mesh torque on it (σP on flank σ, 0 in the free play).
  void holding(ModeVector* w, double* w0) const
  {
    if (phase_ == 0)
    {
      *w = ModeVector::Zero(4);
      *w0 = 0.0;
      return;
    }
    doubled_mode_ ? penetration(phase_, w, w0) : torque(phase_, w, w0);
    const double k = doubled_mode_ ? 2.0 * c_ : 1.0;  // (msl's 2c·y: twice the spring on y)
    *w *= phase_ * k;
    *w0 *= phase_ * k;
  }

  /// Dry friction's rest rule at a segment's start: a load at rest stays stuck while |H| ≤ T_s, else slides in the
  /// direction of H (beyond rounding).
  void settleSlide()
  {
    if (!dry_ || slide_ != 0)
    {
      return;
    }
    ModeVector w;
    double w0;
    holding(&w, &w0);
    const double h = w.dot(x_) + w0, band = 1e-12 * (c_ * (a_ + 2.0 * half_) + d_ * a_ * w_ + ts_);
    if (std::fabs(h) > ts_ + band)
    {
      slide_ = h > 0.0 ? 1 : -1;
    }
  }

  /// Adds ∫ F e^{−jωt} over the part of [t_, t_ + tau] inside the recorded window (see recordFriction).
  void recordSegment(const LinearMode& m, double tau)
  {
    if (!dry_)
    {
      return;
    }
    const double a = std::max(t_, record_from_), b = std::min(t_ + tau, record_to_);
    if (!(b > a))
    {
      return;
    }
    const std::complex<double> jw(0.0, w_);
    if (slide_ != 0)
    {
      friction_line_ += slide_ * tc_ * (std::exp(-jw * b) - std::exp(-jw * a)) / (-jw);
      return;
    }
    // Stuck: F = H(t), smooth — 8-point Gauss–Legendre over pieces of at most 1/64 of a period (exact to rounding).
    ModeVector w;
    double w0;
    holding(&w, &w0);
    const int pieces = std::max(1, static_cast<int>(std::ceil((b - a) * w_ * 64.0 / (2.0 * PI))));
    const double h = (b - a) / pieces;
    for (int k = 0; k < pieces; ++k)
    {
      const double mid = a + (k + 0.5) * h;
      for (int i = 0; i < 8; ++i)
      {
        const double t = mid + 0.5 * h * GAUSS_NODE[i];
        friction_line_ += 0.5 * h * GAUSS_WEIGHT[i] * (w.dot(m.state(t - t_)) + w0) * std::exp(-jw * t);
      }
    }
  }

  /// msl: in contact, the 2c·y sub-mode where d·ẏ − c·y > band, the other where it is < −band (unless it switched at
  /// this very instant).
  void subModeFromState(double band, bool just_switched)
  {
    if (!msl_ || just_switched)
    {
      return;
    }
    ModeVector w;
    double w0;
    balance(phase_, &w, &w0);
    const double s = w.dot(x_) + w0;
    if (s > band)
    {
      doubled_mode_ = true;
    }
    else if (s < -band)
    {
      doubled_mode_ = false;
    }
  }

  /// y_σ = σ(x − θ_c) − Δ/2, P_σ = c y_σ + d ẏ_σ and (msl) d ẏ_σ − c y_σ as outputs w·state + w₀.
  void penetration(int sigma, ModeVector* w, double* w0) const
  {
    *w = ModeVector(4);
    *w << -sigma, 0.0, 0.0, sigma * a_;
    *w0 = -half_;
  }
  void torque(int sigma, ModeVector* w, double* w0) const
  {
    *w = ModeVector(4);
    *w << -sigma * c_, -sigma * d_, sigma * d_ * a_ * w_, sigma * c_ * a_;
    *w0 = -c_ * half_;
  }
  void balance(int sigma, ModeVector* w, double* w0) const
  {
    *w = ModeVector(4);
    *w << sigma * c_, -sigma * d_, sigma * d_ * a_ * w_, -sigma * c_ * a_;
    *w0 = c_ * half_;
  }

  std::vector<Watch> watchesNow() const
  {
    std::vector<Watch> out;
    ModeVector w;
    double w0;
    if (dry_ && slide_ != 0)
    {
      w = ModeVector::Zero(4);
      w(1) = 1.0;
      out.push_back({w, 0.0, -slide_, Kind::Stop, slide_});
    }
    else if (dry_ && phase_ != 0)
    {
      holding(&w, &w0);
      out.push_back({w, w0 - ts_, +1, Kind::Breakaway, 1});
      out.push_back({w, w0 + ts_, -1, Kind::Breakaway, -1});
    }
    if (phase_ != 0)
    {
      if (doubled_mode_)
      {
        penetration(phase_, &w, &w0);
        out.push_back({w, w0, -1, Kind::Release, phase_});
        balance(phase_, &w, &w0);
        out.push_back({w, w0, -1, Kind::Switch, phase_});
        return out;
      }
      torque(phase_, &w, &w0);
      out.push_back({w, w0, -1, Kind::Release, phase_});
      if (msl_)
      {
        balance(phase_, &w, &w0);
        out.push_back({w, w0, +1, Kind::Switch, phase_});
      }
      return out;
    }
    for (int sigma : {1, -1})
    {
      penetration(sigma, &w, &w0);
      if (w.dot(x_) + w0 > 0.0)
      {
        out.push_back({w, w0, -1, Kind::Leave, sigma});
        torque(sigma, &w, &w0);
        out.push_back({w, w0, +1, Kind::Engage, sigma});
      }
      else
      {
        out.push_back({w, w0, +1, Kind::Engage, sigma});
      }
    }
    return out;
  }

  double j_, f_, c_, d_, half_, a_, w_;
  bool msl_;
  double tc_, ts_;  // the load's Coulomb and static friction [N·m]
  bool dry_;
  int slide_ = 0;  // dry friction: 0 stuck, ±1 sliding
  double record_from_ = INF, record_to_ = -INF;
  std::complex<double> friction_line_ = 0.0;
  ModeVector x_;
  double t_ = 0.0;
  int phase_ = 0;              // 0 free, +1 forward flank, −1 backward flank
  bool doubled_mode_ = false;  // msl_elastobacklash's 2c·y sub-mode (while d·ẏ > c·y)
  double last_time_ = -1.0;
  int last_kind_ = -1, last_sigma_ = 0;
  long events_ = 0;
  std::shared_ptr<const ModeBasis> basis_[3][2];  // free, contact, msl's 2c·y; moving or the load stuck
};

}  // namespace

void requireDrivableMesh(const ServoParams& params)
{
  requireThat(std::isfinite(params.mesh_stiffness) && params.mesh_stiffness > 0.0, "mesh_stiffness",
              "must be > 0 N·m/rad: the compliant element is the mesh");
  requireThat(std::isfinite(params.mesh_damping) && params.mesh_damping >= 0.0, "mesh_damping",
              "must be >= 0 N·m·s/rad");
  requireThat(std::isfinite(params.load_inertia) && params.load_inertia > 0.0, "load_inertia", "must be > 0 kg·m²");
  requireThat(std::isfinite(params.load_friction) && params.load_friction >= 0.0, "load_friction",
              "must be >= 0 N·m·s/rad");
  requireThat(std::isfinite(params.load_coulomb_friction) && params.load_coulomb_friction >= 0.0,
              "load_coulomb_friction", "must be >= 0 N·m");
  requireThat(std::isfinite(params.load_static_friction) && params.load_static_friction >= 0.0, "load_static_friction",
              "must be >= 0 N·m");
  requireThat(params.load_torque == 0.0, "load_torque",
              "must be 0: with a load torque the element's cycle is not symmetric about its centre");
  requireThat(params.shaft_stiffness == 0.0, "shaft_stiffness",
              "must be 0: the driven compliant element has a rigid shaft");
  requireThat(std::isfinite(params.backlash) && params.backlash >= 0.0, "backlash", "must be >= 0 rad");
}

DrivenBacklash drivenCompliantMesh(const ServoParams& params, double amplitude, double omega, double tolerance,
                                   int max_periods)
{
  requireDrivableMesh(params);
  requireThat(std::isfinite(amplitude) && amplitude > 0.0, "amplitude", "must be > 0 rad");
  requireThat(std::isfinite(omega) && omega > 0.0, "frequency", "must be > 0 rad/s");
  requireThat(max_periods >= 1 && tolerance > 0.0, "tolerance", "must be > 0, with at least one period");
  const double period = 2.0 * PI / omega;
  MeshElement element(params, amplitude, omega);
  DrivenBacklash out;
  double last_position = NAN, last_speed = NAN;
  int last_phase = 2;
  const double scale = std::max(params.backlash, amplitude);
  out.periods = settlePeriods(
      element, period, max_periods,
      [&](double) {
        if (std::fabs(element.position() - last_position) <= tolerance * scale &&
            std::fabs(element.velocity() - last_speed) <= tolerance * amplitude * omega &&
            element.phase() == last_phase)
        {
          return true;
        }
        last_position = element.position();
        last_speed = element.velocity();
        last_phase = element.phase();
        return false;
      },
      &out.periodic);
  std::complex<double> position(0.0, 0.0);
  element.recordFriction(out.periods * period, (out.periods + analysedPeriods(out.periodic)) * period);
  const int analysed = samplePeriods(element, period, out.periods, out.periodic,
                                     [&](std::complex<double> rotor) { position += element.position() * rotor; });
  element.advanceTo((out.periods + analysed) * period);  // (the friction's integral to the window's end)
  const std::complex<double> j(0.0, 1.0);
  out.position = j * (2.0 / (static_cast<double>(DRIVEN_SAMPLES) * analysed)) * position / amplitude;
  // The teeth's torque Q = J_L θ̈_c + f_L θ̇_c + F: its fundamental (−ω²J_L + jωf_L)Θ₁ + F₁.
  const std::complex<double> friction = j * (2.0 / (period * analysed)) * element.frictionLine() / amplitude;
  out.torque = std::complex<double>(-omega * omega * params.load_inertia, omega * params.load_friction) * out.position +
               friction;
  return out;
}

void requireDrivable(const ServoParams& params)
{
  if (params.mesh_stiffness > 0.0)
  {
    requireDrivableMesh(params);
  }
  else
  {
    requireDrivableBacklash(params);
  }
}

DrivenBacklash drivenElement(const ServoParams& params, double amplitude, double omega)
{
  return params.mesh_stiffness > 0.0 ? drivenCompliantMesh(params, amplitude, omega)
                                     : drivenBacklash(params, amplitude, omega);
}

}  // namespace backlash_servo
