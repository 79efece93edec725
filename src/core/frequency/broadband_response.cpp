#include "backlash_servo/frequency/broadband_response.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/model/constants.h"
#include "numerics/dft.h"

namespace backlash_servo
{
namespace
{
/// Lines whose input power is below this fraction of the largest carry no excitation and are not reported.
constexpr double LINE_POWER_FLOOR = 1e-4;

/// Feedback taps of a maximal-length Fibonacci LFSR of each order 3 … 20 (bit positions counted from 1; the primitive
/// polynomials of the standard tables, e.g. Xilinx XAPP052).
const std::vector<std::vector<int>>& taps()
{
  static const std::vector<std::vector<int>> t = {
      {3, 2},   {4, 3},          {5, 3},   {6, 5},        {7, 6},        {8, 6, 5, 4},
      {9, 5},   {10, 7},         {11, 9},  {12, 6, 4, 1}, {13, 4, 3, 1}, {14, 5, 3, 1},
      {15, 14}, {16, 15, 13, 4}, {17, 14}, {18, 11},      {19, 6, 2, 1}, {20, 17}};
  return t;
}

}  // namespace

std::vector<int> maximumLengthSequence(int order)
{
  if (order < 3 || order > 20)
  {
    throw InvalidParameterError("prbs_order", "must be in [3, 20] (got " + std::to_string(order) + ")");
  }
  const std::vector<int>& t = taps()[static_cast<std::size_t>(order - 3)];
  const std::size_t length = (std::size_t{1} << order) - 1;
  std::vector<int> out(length);
  std::uint32_t state = 1;
  for (std::size_t i = 0; i < length; ++i)
  {
    out[i] = (state & 1u) != 0 ? 1 : -1;
    std::uint32_t bit = 0;
    for (int tap : t)
    {
      bit ^= (state >> (order - tap)) & 1u;
    }
    state = (state >> 1) | (bit << (order - 1));
  }
  return out;
}

namespace
{
void checkBroadband(const BroadbandSettings& s, double amplitude)
{
  if (!(std::isfinite(amplitude) && amplitude > 0.0))
  {
    throw InvalidParameterError("amplitude", "must be finite and > 0 (got " + std::to_string(amplitude) + ")");
  }
  if (!std::isfinite(s.offset))
  {
    throw InvalidParameterError("offset", "must be finite");
  }
  if (s.settle_periods < 0 || s.periods < 1 || s.settle_periods + s.periods > 100000)
  {
    throw InvalidParameterError("periods",
                                "needs settle_periods ≥ 0 (0: automatic), periods ≥ 1 (together at most 100000)");
  }
  if (loadTorqueInput(s.channel))
  {
    throw InvalidParameterError("channel", std::string(toString(s.channel)) +
                                               ": a disturbance on the load is measured by stepped sines (the sine "
                                               "itself, exact); broadband takes the command, the motor torque and "
                                               "the set-point");
  }
}

/// One period of the excitation's shape s_k: the PRBS's bits, each held prbs_hold samples, or the chirp's sine
/// sweeping whole DFT lines from chirp_low to chirp_high [rad/s] at `rate` [Hz].
std::vector<double> excitationShape(const BroadbandSettings& s, double rate)
{
  std::vector<double> shape;
  if (s.kind == BroadbandKind::Prbs)
  {
    if (s.prbs_hold < 1 || s.prbs_hold > 1000)
    {
      throw InvalidParameterError("prbs_hold",
                                  "must be in [1, 1000] samples (got " + std::to_string(s.prbs_hold) + ")");
    }
    for (int bit : maximumLengthSequence(s.prbs_order))
    {
      shape.insert(shape.end(), static_cast<std::size_t>(s.prbs_hold), static_cast<double>(bit));
    }
  }
  else
  {
    const int n = s.chirp_samples;
    if (n < 16 || n > (1 << 20))
    {
      throw InvalidParameterError("chirp_samples", "must be in [16, 2^20] (got " + std::to_string(n) + ")");
    }
    const double line = 2.0 * PI * rate / n;  // [rad/s] per DFT line
    if (!(s.chirp_low > 0.0 && s.chirp_high > s.chirp_low && s.chirp_high <= 2.0 * PI * rate / 4.0))
    {
      throw InvalidParameterError("chirp", "needs 0 < low < high <= a quarter of the sample rate (" +
                                               std::to_string(2.0 * PI * rate / 4.0) + " rad/s)");
    }
    long k0 = std::max(1L, std::lround(s.chirp_low / line)), k1 = std::lround(s.chirp_high / line);
    if ((k1 - k0) % 2 != 0)
    {
      ++k1;  // an even sweep closes its phase on a whole turn
    }
    if (k1 <= k0)
    {
      throw InvalidParameterError("chirp", "the sweep spans no DFT line: lengthen the period (chirp_samples)");
    }
    for (int k = 0; k < n; ++k)
    {
      const double x = static_cast<double>(k) / n;
      const double turns = static_cast<double>(k0) * x + static_cast<double>(k1 - k0) * x * x / 2.0;
      shape.push_back(std::sin(2.0 * PI * (turns - std::floor(turns))));
    }
  }
  return shape;
}

/// The simulator with the excitation on the channel's input: set-points held from each sample (the command), the
/// shape injected at the drive's samples (the set-point channels); a torque is set sample by sample by the caller.
Simulator excitedSimulator(const RunConfig& config, const BroadbandSettings& s, const std::vector<double>& shape,
                           double amplitude, double rate, long total)
{
  const std::size_t n = shape.size();
  const double t0 = config.initial.time;
  const auto sampleTime = [&](long k) { return t0 + static_cast<double>(k) / rate; };
  const auto inputAt = [&](long k) { return s.offset + amplitude * shape[static_cast<std::size_t>(k) % n]; };
  RunConfig run = config;
  run.track_energy = false;
  run.duration = 0.0;
  const bool torque = torqueInput(s.channel), setpoint = setpointInput(s.channel);
  if (setpoint)
  {
    // The loops closed on the command (held, or turning at the offset speed), the shape injected at their samples.
    run.profile = speedOffsetProfile(config, s.offset, static_cast<double>(total + 2) / rate);
  }
  else if (!torque)
  {
    // The command as set-points held from each sample instant (the drive reads each at its own sample).
    ProfileSegment points;
    points.kind = ProfileSegment::Kind::Points;
    points.time = t0;
    for (long k = 0; k < total; ++k)
    {
      points.points.emplace_back(sampleTime(k), inputAt(k));
    }
    run.profile = std::make_shared<const CommandProfile>(inputAt(0), std::vector<ProfileSegment>{points});
  }
  Simulator sim = makeSimulator(run);
  if (setpoint)
  {
    sim.sampledDrive()->setInjection(amplitude, std::make_shared<const std::vector<double>>(shape));  // (from t₀)
  }
  return sim;
}

/// H1 = S_yu/S_uu and the coherence at every DFT line the excitation reaches (above LINE_POWER_FLOOR of the
/// strongest; not the Nyquist line).
std::vector<BroadbandLine> estimateLines(const std::vector<std::complex<double>>& cross, const std::vector<double>& uu,
                                         const std::vector<double>& yy, std::size_t n, double rate, bool setpoint,
                                         int periods)
{
  const std::size_t lines = cross.size();
  std::vector<BroadbandLine> out;
  double largest = 0.0;
  for (std::size_t k = 1; k < lines; ++k)
  {
    largest = std::max(largest, uu[k]);
  }
  for (std::size_t k = 1; k < lines; ++k)
  {
    if (!(uu[k] > LINE_POWER_FLOOR * largest) || 2 * k >= n)
    {
      continue;  // no excitation there, or the Nyquist line (real only)
    }
    BroadbandLine l;
    l.frequency = 2.0 * PI * rate * static_cast<double>(k) / static_cast<double>(n);
    l.h1 = cross[k] / uu[k];
    if (setpoint)
    {
      l.h1 *= std::polar(1.0, -l.frequency / rate);  // u recorded one sample late: U = z·(what was recorded)
    }
    l.coherence = yy[k] > 0.0 ? std::norm(cross[k]) / (uu[k] * yy[k]) : 0.0;
    l.input_power = uu[k] / periods;
    out.push_back(l);
  }
  return out;
}
}  // namespace

namespace
{
/// The most samples one broadband measurement simulates: about half an hour at the ~2 µs a sample of a quiet joint.
constexpr double MAX_SAMPLES = 1e9;
/// The most samples an automatic settling runs (a few seconds).
constexpr double AUTO_SETTLING_SAMPLES = 5e6;

/// Refuses, before any work, a measurement of more than MAX_SAMPLES samples (n a period, settle + periods periods, at
/// rate [Hz]), naming the figures and the keys that shorten it.
void checkWork(std::size_t n, int settle, int periods, double rate)
{
  const double samples = static_cast<double>(n) * (settle + periods);
  if (samples <= MAX_SAMPLES)
  {
    return;
  }
  char text[400];
  std::snprintf(
      text, sizeof text,
      "%zu samples a period × (%d settling + %d recorded periods) = %.3g samples (%.3g s simulated) exceed the "
      "%.0e one measurement simulates: fewer periods (periods, settle_periods) or a shorter period "
      "(prbs_order, prbs_hold, chirp_samples)",
      n, settle, periods, samples, samples / rate, MAX_SAMPLES);
  throw InvalidParameterError("periods", text);
}
}  // namespace

BroadbandResponse measureBroadband(const RunConfig& config, const BroadbandSettings& s, double amplitude,
                                   const std::function<void(double)>& progress)
{
  checkBroadband(s, amplitude);
  const double rate = excitationRate(config, s.channel, s.injection_rate);
  const std::vector<double> shape = excitationShape(s, rate);
  const std::size_t n = shape.size();
  int settle = s.settle_periods;
  if (settle == 0)
  {
    // 40 of the slowest time constant, at least 2 periods, and no more than AUTO_SETTLING_SAMPLES in all (a very slow
    // joint's transient then lingers in the estimate: the report says how many periods settled it).
    const double period = static_cast<double>(n) / rate;
    const double budget = std::floor(AUTO_SETTLING_SAMPLES / static_cast<double>(n));
    settle = static_cast<int>(
        std::max(2.0, std::min({100000.0 - s.periods, budget,
                                std::ceil(AUTO_SETTLING_SCALES * slowestTimeScale(config, s.channel) / period)})));
  }
  const long total = static_cast<long>(n) * (settle + s.periods);
  checkWork(n, settle, s.periods, rate);
  const double t0 = config.initial.time;
  const auto sampleTime = [&](long k) { return t0 + static_cast<double>(k) / rate; };
  const auto inputAt = [&](long k) { return s.offset + amplitude * shape[static_cast<std::size_t>(k) % n]; };

  const bool torque = torqueInput(s.channel), setpoint = setpointInput(s.channel);
  Simulator sim = excitedSimulator(config, s, shape, amplitude, rate, total);
  const Dft dft(n);
  const std::size_t lines = n / 2 + 1;
  std::vector<std::complex<double>> cross(lines, 0.0);
  std::vector<double> uu(lines, 0.0), yy(lines, 0.0);
  std::vector<double> u(n), y(n);
  for (long p = 0; p < settle + s.periods; ++p)
  {
    for (std::size_t j = 0; j < n; ++j)
    {
      const long k = p * static_cast<long>(n) + static_cast<long>(j);
      sim.advanceTo(sampleTime(k));
      y[j] = frfOutput(s.channel, sim.state());
      // (Set-point: the torque the drive applied over the last sample, [t_{k−1}, t_k) — its sample at t_k is taken
      // when the run goes on; the one-sample shift is undone on the estimate.)
      u[j] = setpoint ? sim.plant().motorTorque() : inputAt(k);
      if (torque)
      {
        sim.setMotorTorque(u[j]);
        sim.setInputHorizon(sampleTime(k + 1));
      }
    }
    if (p >= settle)
    {
      const std::vector<std::complex<double>> uf = dft.realLines(u), yf = dft.realLines(y);
      for (std::size_t k = 0; k < lines; ++k)
      {
        cross[k] += yf[k] * std::conj(uf[k]);
        uu[k] += std::norm(uf[k]);
        yy[k] += std::norm(yf[k]);
      }
    }
    if (progress)
    {
      progress(static_cast<double>(p + 1) / (settle + s.periods));
    }
  }
  BroadbandResponse out;
  out.samples_per_period = static_cast<int>(n);
  out.sample_rate = rate;
  out.settle_periods = settle;
  out.lines = estimateLines(cross, uu, yy, n, rate, setpoint, s.periods);
  return out;
}

}  // namespace backlash_servo
