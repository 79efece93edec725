#include "backlash_servo/frequency/limit_cycle_prediction.h"

#include <algorithm>
#include <cmath>

#include "backlash_servo/frequency/driven_backlash.h"
#include "backlash_servo/frequency/driven_mesh.h"
#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/simulation/simulator.h"

namespace backlash_servo
{
namespace
{
constexpr int CYCLE_SAMPLES = 4096;
}  // namespace

double LimitCyclePrediction::amplitudeError(const HarmonicBalance& h) const
{
  const bool cycle = simulated.verdict == Verdict::LimitCycle && std::isfinite(simulated.amplitude);
  return cycle && h.stable ? h.amplitude / simulated.amplitude - 1.0 : NAN;
}

double LimitCyclePrediction::frequencyError(const HarmonicBalance& h) const
{
  const bool cycle = simulated.verdict == Verdict::LimitCycle && std::isfinite(simulated.amplitude);
  return cycle && h.stable ? h.frequency / simulated.frequency - 1.0 : NAN;
}

std::complex<double> thesisLoop(const ServoParams& p, double w)
{
  const double wn = p.naturalFrequency(), zeta = p.dampingRatio();
  return wn * wn / std::complex<double>(-w * w, 2.0 * zeta * wn * w);
}

double lawStiffness(const ServoParams& p, const DriveParams& d)
{
  return d.sampled() && d.control_law == "cascade" ? d.velocity_loop_gain * d.position_loop_gain : p.gain;
}

double loopNaturalFrequency(const ServoParams& p, const DriveParams& d)
{
  return std::sqrt(p.gear_ratio * lawStiffness(p, d) / p.totalInertia());
}

LawResponse lawResponse(const ServoParams& p, const DriveParams& d, double w)
{
  LawResponse r;
  if (!d.sampled())
  {
    r.load = p.gain;
    return r;
  }
  const double t = 1.0 / d.controller_rate;
  const std::complex<double> back = 1.0 - std::exp(std::complex<double>(0.0, -w * t));  // 1 − z⁻¹ at z = e^{jωT}
  std::complex<double> hold = back / std::complex<double>(0.0, w * t);                  // the hold's fundamental
  if (d.controller_delay > 0.0)
  {
    hold *= std::exp(std::complex<double>(0.0, -w * t));
  }
  if (d.control_law == "cascade")
  {
    // u = C_v(z) (K_p e − ŵ), ŵ = (1 − z⁻¹)/T · ρθ_m (the motor encoder's backward difference).
    const std::complex<double> cv = d.velocity_loop_gain + d.velocity_loop_integral_gain * t / back;
    const std::complex<double> speed = back / t;
    (d.feedback == "motor" ? r.motor : r.load) = cv * d.position_loop_gain * hold;
    r.motor += cv * speed * hold;
    return r;
  }
  std::complex<double> c = p.gain;
  if (d.control_law == "pid")
  {
    c += d.integral_gain * t / back + d.derivative_gain * back / t;
  }
  (d.feedback == "motor" ? r.motor : r.load) = c * hold;
  return r;
}

namespace
{
/// The two bodies of a loop at ω (a compliant mesh's, or the load's reaction on a motor loop): M = −ω²J_m + jωf_m, L =
/// −ω²J_L + jωf_L, the law's K(jω), and the deflection's response to the mesh torque, G = ρ(ρ + K_θ/L)/(M + ρK_x) + 1/L
/// (X = −G T).
struct TwoBodies
{
  std::complex<double> m, l, g;
  LawResponse k;
};
TwoBodies twoBodies(const ServoParams& p, const DriveParams& d, double w)
{
  TwoBodies b;
  b.m = {-w * w * p.motor_inertia, w * p.motor_friction};
  b.l = {-w * w * p.load_inertia, w * p.load_friction};
  b.k = lawResponse(p, d, w);
  const double rho = p.gear_ratio;
  b.g = rho * (rho + b.k.load / b.l) / (b.m + rho * b.k.motor) + 1.0 / b.l;
  return b;
}
}  // namespace

std::complex<double> loopResponse(const ServoParams& p, const DriveParams& d, double w)
{
  const TwoBodies b = twoBodies(p, d, w);
  const LawResponse& k = b.k;
  const double rho = p.gear_ratio;
  if (k.motor == 0.0)
  {
    return thesisLoop(p, w) * (k.load / p.gain);  // the thesis' loop: the load lumped into the motor
  }
  const std::complex<double> s(0.0, w);
  if (k.load != 0.0)
  {
    return rho * k.load / (s * s * p.totalInertia() + s * p.totalFriction() + rho * k.motor);
  }
  // The loop reads the motor alone: lumped, nothing would pass the backlash; the load's reaction through it does.
  return rho * rho * b.l / (b.m + rho * k.motor);
}

std::complex<double> compliantLoop(const ServoParams& p, const DriveParams& d, double w)
{
  return std::complex<double>(p.mesh_stiffness, w * p.mesh_damping) * twoBodies(p, d, w).g;
}

double compliantMotorAmplitude(const ServoParams& p, const DriveParams& d, double w)
{
  // ρΘ_m = ρ(K_θ/L + ρ) X / (G (M + ρK_x)).
  const TwoBodies b = twoBodies(p, d, w);
  const double rho = p.gear_ratio;
  return std::abs(rho * (b.k.load / b.l + rho) / (b.g * (b.m + rho * b.k.motor)));
}

std::complex<double> elementBalance(const ServoParams& p, double a, double w, const DriveParams& drive)
{
  const DrivenBacklash d = drivenElement(p, a, w);
  const double rho = p.gear_ratio;
  const LawResponse k = lawResponse(p, drive, w);
  return std::complex<double>(-w * w * p.motor_inertia, w * p.motor_friction) / rho +
         std::complex<double>(0.0, 4.0 * p.motor_coulomb_friction / (PI * a)) + k.load * d.position + k.motor +
         rho * d.torque;
}

bool numericalHarmonicBalance(const ServoParams& p, const HarmonicBalance& start, HarmonicBalance* out,
                              const DriveParams& drive)
{
  // Newton in (u, v) = (ln A, ln ω) on (Re E, Im E) / K.
  double u = std::log(start.amplitude), v = std::log(start.frequency);
  const double scale = lawStiffness(p, drive), wn = loopNaturalFrequency(p, drive);
  const auto e = [&p, &drive, scale](double uu, double vv) {
    return elementBalance(p, std::exp(uu), std::exp(vv), drive) / scale;
  };
  try
  {
    constexpr double STEP = 1e-4;
    const auto jacobian = [&](double uu, double vv, double m[2][2]) {
      const std::complex<double> du = (e(uu + STEP, vv) - e(uu - STEP, vv)) / (2.0 * STEP),
                                 dv = (e(uu, vv + STEP) - e(uu, vv - STEP)) / (2.0 * STEP);
      m[0][0] = du.real();
      m[0][1] = dv.real();
      m[1][0] = du.imag();
      m[1][1] = dv.imag();
    };
    for (int iteration = 0; iteration < 20; ++iteration)
    {
      const std::complex<double> f = e(u, v);
      double m[2][2];
      jacobian(u, v, m);
      const double det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
      if (!(std::fabs(det) > 0.0) || !std::isfinite(det))
      {
        return false;
      }
      double du = -(m[1][1] * f.real() - m[0][1] * f.imag()) / det,
             dv = -(-m[1][0] * f.real() + m[0][0] * f.imag()) / det;
      // Converged: the step is below 1e-7 in ln A and ln ω (the DFs' Fourier sums leave a floor near 1e-8 in E).
      if (std::max(std::fabs(du), std::fabs(dv)) < 1e-7 && std::abs(f) < 1e-5)
      {
        out->amplitude = std::exp(u + du);
        out->frequency = std::exp(v + dv);
        out->stable = det > 0.0;  // Loeb: ∂U/∂A ∂V/∂ω − ∂U/∂ω ∂V/∂A > 0 (A, ω > 0 scale it by Aω)
        return true;
      }
      const double longest = std::max(std::fabs(du), std::fabs(dv));
      if (longest > 0.5)  // (a damped step: at most a factor e^0.5 in A or ω)
      {
        du *= 0.5 / longest;
        dv *= 0.5 / longest;
      }
      u += du;
      v += dv;
      // Within the classical search's band of frequencies, and beyond the half-backlash (a sine-driven element from
      // rest never reaches the load below it).
      if (!std::isfinite(u) || !std::isfinite(v) || std::exp(u) <= 0.5 * p.backlash * (1.0 + 1e-9) ||
          std::fabs(v - std::log(wn)) > std::log(1e4))
      {
        return false;
      }
    }
  }
  catch (const InvalidParameterError&)
  {
    return false;  // the element chattered beyond its budget on the way: no prediction from this start
  }
  return false;
}

SimulatedCycle simulateCycle(const RunConfig& config)
{
  SimulatedCycle c;
  RunConfig run = config;
  run.track_energy = false;
  const RunSummary r = runResponse(run);
  c.verdict = r.status.verdict;
  c.simulated = r.simulated;
  if (r.status.verdict != Verdict::LimitCycle || !(r.status.period > 0.0))
  {
    return c;
  }
  // One more period from the settled state, sampled evenly: the continuous law's state is the plant's; a digital
  // drive's (its integral, the torque it holds) is not, so that run is repeated up to there (it is deterministic).
  const double period = r.status.period, rho = config.params.gear_ratio;
  const double t0 = r.final_state.time;
  Simulator sim = config.drive.sampled() ? makeSimulator(run) : Simulator(config.params, r.final_state, config.command);
  sim.advanceTo(t0);
  std::vector<double> x(CYCLE_SAMPLES);
  for (int k = 0; k < CYCLE_SAMPLES; ++k)
  {
    sim.advanceTo(t0 + period * k / CYCLE_SAMPLES);
    x[static_cast<std::size_t>(k)] = rho * sim.state().motor_position;
  }
  // The fundamental: the strongest of the period's first four harmonics (a digital loop's cycle repeats to rounding
  // only after a few of its swings when they do not span whole samples: the monitor's period is then that multiple).
  double mean = 0.0;
  for (double v : x)
  {
    mean += v;
  }
  c.centre = mean / CYCLE_SAMPLES;
  int harmonic = 1;
  c.amplitude = 0.0;
  for (int m = 1; m <= 4; ++m)
  {
    double a1 = 0.0, b1 = 0.0;
    for (int k = 0; k < CYCLE_SAMPLES; ++k)
    {
      const double theta = 2.0 * PI * m * k / CYCLE_SAMPLES, v = x[static_cast<std::size_t>(k)];
      b1 += v * std::sin(theta);
      a1 += v * std::cos(theta);
    }
    const double amplitude = 2.0 / CYCLE_SAMPLES * std::hypot(a1, b1);
    if (amplitude > c.amplitude)
    {
      c.amplitude = amplitude;
      harmonic = m;
    }
  }
  c.peak = 0.0;
  for (double v : x)
  {
    c.peak = std::max(c.peak, std::fabs(v - c.centre));
  }
  c.frequency = 2.0 * PI * harmonic / period;
  return c;
}

void requireDescribable(const RunConfig& config)
{
  const DriveParams& d = config.drive;
  const auto refuse = [](const char* key, const std::string& why) {
    throw InvalidParameterError(key,
                                "the describing-function analysis takes a linear loop around the backlash: " + why);
  };
  if (config.profile)
  {
    refuse("profile", "a constant command, not a profile");
  }
  if (d.torque_limit != 0.0)
  {
    refuse("torque_limit", "no torque limit (a saturation is a second non-linearity)");
  }
  if (d.compensation != "none")
  {
    refuse("compensation", "no compensator");
  }
  if (d.sampled())
  {
    if (d.feedback == "load" && d.load_encoder_resolution > 0.0)
    {
      refuse("load_encoder_resolution", "an ideal load encoder (counts are a second non-linearity)");
    }
    if ((d.feedback == "motor" || d.control_law == "cascade") && d.motor_encoder_resolution > 0.0)
    {
      refuse("motor_encoder_resolution", "an ideal motor encoder (counts are a second non-linearity)");
    }
  }
  if (!(config.params.backlash > 0.0))
  {
    throw InvalidParameterError("backlash", "must be > 0: without backlash there is no describing function to balance");
  }
  if (config.params.shaft_stiffness > 0.0)
  {
    refuse("shaft_stiffness", "a rigid shaft (the compliant mesh's dead zone alone)");
  }
  if (d.sampled() && d.control_law == "cascade" && !(d.velocity_loop_gain > 0.0 && d.position_loop_gain > 0.0))
  {
    refuse(d.velocity_loop_gain > 0.0 ? "position_loop_gain" : "velocity_loop_gain",
           "a cascade whose position and velocity loops both act: set position_loop_gain > 0 [1/s] and "
           "velocity_loop_gain > 0 [N·m·s/rad] (without them its loop stiffness K_v·K_p is 0)");
  }
}

LimitCyclePrediction predictLimitCycle(const RunConfig& config)
{
  requireDescribable(config);
  const ServoParams& p = config.params;
  const DriveParams& drive = config.drive;
  LimitCyclePrediction out;
  out.natural_frequency = loopNaturalFrequency(p, drive);
  out.zeta = p.totalFriction() / (2.0 * out.natural_frequency * p.totalInertia());
  const double wn = out.natural_frequency;
  // (A sampled loop's fundamental is its own only below the Nyquist frequency π f_s.)
  const double top = drive.sampled() ? std::min(1e4 * wn, PI * drive.controller_rate) : 1e4 * wn;
  // The classical predictions, and where the real element's balance starts from (or why it is not solved).
  std::vector<HarmonicBalance> starts;
  const auto rigid = [&]() {
    return backlashHarmonicBalance([&](double w) { return loopResponse(p, drive, w); }, p.backlash, 1e-4 * wn, top);
  };
  if (p.mesh_stiffness > 0.0)
  {
    // A compliant mesh: the dead zone of its penetration, the deflection's amplitude turned into ρθ_m's.
    out.predictions =
        deadZoneHarmonicBalance([&](double w) { return compliantLoop(p, drive, w); }, 0.5 * p.backlash, 1e-4 * wn, top);
    for (HarmonicBalance& h : out.predictions)
    {
      h.amplitude *= compliantMotorAmplitude(p, drive, h.frequency);
    }
    // (A dead zone's prediction often lies below the half-backlash, where a sine-driven element from rest never
    // reaches the load: the rigid teeth's predictions are starts too.)
    starts = out.predictions;
    for (const HarmonicBalance& h : rigid())
    {
      starts.push_back(h);
    }
  }
  else
  {
    out.predictions = rigid();
    starts = out.predictions;
  }
  try
  {
    requireDrivable(p);  // (what the joint's element takes: its refusal, key named, is the note)
  }
  catch (const InvalidParameterError& e)
  {
    out.numerical_note = std::string("no numerical DF: ") + e.what();
  }
  if (out.numerical_note.empty())
  {
    for (const HarmonicBalance& h : starts)
    {
      HarmonicBalance n;
      if (h.amplitude > 0.5 * p.backlash && numericalHarmonicBalance(p, h, &n, drive))
      {
        bool seen = false;  // (two starts may reach one solution, to the balance's floor near 1e-5)
        for (const HarmonicBalance& o : out.numerical)
        {
          seen = seen || (std::fabs(o.amplitude / n.amplitude - 1.0) < 1e-4 &&
                          std::fabs(o.frequency / n.frequency - 1.0) < 1e-4);
        }
        if (!seen)
        {
          out.numerical.push_back(n);
        }
      }
    }
    if (out.numerical.empty() && !out.predictions.empty())
    {
      out.numerical_note =
          "no numerical DF: the real element's balance did not converge from the classical predictions";
    }
  }
  out.simulated = simulateCycle(config);
  return out;
}

}  // namespace backlash_servo
