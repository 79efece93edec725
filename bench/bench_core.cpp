// Speed and accuracy of the exact core against what users would write instead (bench/baselines.h; scipy in
// bench/scipy_baseline.py). Prints a table and ratios; exits 1 if the accuracy comparison does not hold.
// usage: bench_core [--quick] [--reference-out FILE] | bench_core --tracking (the tracking figures' cost alone)
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "backlash_servo/model/gear_mesh.h"
#include "backlash_servo/rigid/impact.h"
#include "backlash_servo/rigid/short_flight.h"
#include "backlash_servo/simulation/step_response.h"
#include "baselines.h"

using namespace backlash_servo;

namespace
{
struct Case
{
  std::string name;
  ServoParams params;
  double duration;
};

struct Row
{
  std::string method;
  double wall = 0.0;  // s per run
  long events = 0;
  std::vector<bench::Max> maxima;
};

ServoParams chart(double zeta, double ir, double fr, double e, double omega_n = 1.0)
{
  ChartParams c;
  c.zeta = zeta;
  c.inertia_ratio = ir;
  c.friction_ratio = fr;
  c.restitution = e;
  c.natural_frequency = omega_n;
  return c.toServoParams();
}

/// Wall time per run [s]: repeats fast methods until 0.2 s have passed.
double timeIt(const std::function<void()>& run)
{
  int n = 0;
  const auto start = std::chrono::steady_clock::now();
  double elapsed = 0.0;
  do
  {
    run();
    ++n;
    elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  } while (elapsed < 0.2 && n < 1000);
  return elapsed / n;
}

struct Counter : EventSink
{
  long events = 0;
  std::vector<bench::Max> maxima;
  double command = 1.0;
  void onEvent(const Event& e) override
  {
    if (e.type == EventType::Impact || e.type == EventType::Separation || e.type == EventType::Maximum)
    {
      ++events;
    }
    if (e.type == EventType::Maximum && e.state.load_position > command)
    {
      maxima.push_back({e.state.time, e.state.load_position});
    }
  }
};

Row ours(const Case& c)
{
  Row r;
  r.method = "ours (exact)";
  Counter counter;
  r.wall = timeIt([&]() {
    counter = Counter();
    Simulator sim(c.params, State(), 1.0);
    sim.setEnergyTracking(false);
    sim.advanceTo(c.duration, &counter);
  });
  r.events = counter.events;
  r.maxima = counter.maxima;
  return r;
}

/// The real joint (docs/model.md Part 2): digital drives, encoders, dry friction. Figures only (their accuracy is
/// checked by the tests against test/joint_cases/reference_cases.json and closed forms).
struct JointCase
{
  std::string name;
  ServoParams params;
  DriveParams drive;
  double command;
  double duration;
};

/// A robot joint: J_m 1e-4 kg·m², ρ 0.01, J_L 0.5 kg·m², Δ 0.005 rad, dry friction on both shafts.
JointCase robotJoint(double duration)
{
  JointCase c;
  c.name = "robot_pid_1kHz";
  c.params.motor_inertia = 1e-4;
  c.params.load_inertia = 0.5;
  c.params.motor_friction = 1e-4;
  c.params.load_friction = 0.5;
  c.params.gain = 6.0;
  c.params.gear_ratio = 0.01;
  c.params.backlash = 0.005;
  c.params.restitution = 0.5;
  c.params.motor_coulomb_friction = 0.005;
  c.params.motor_static_friction = 0.008;
  c.params.load_coulomb_friction = 1.0;
  c.params.load_static_friction = 1.5;
  c.drive.control_law = "pid";
  c.drive.controller_rate = 1000.0;
  c.drive.integral_gain = 30.0;
  c.drive.derivative_gain = 0.4;
  c.command = 0.5;
  c.duration = duration;
  return c;
}

void jointBenchmarks(double scale)
{
  std::printf("\n== the real joint: digital drives (energy ledger off)\n");
  std::printf("%-22s %9s %11s %10s %9s %9s %8s %8s\n", "case", "sim [s]", "wall [ms]", "samples", "ns/sample",
              "impacts", "rests", "held %");
  JointCase d1;
  d1.name = "d1_p_1kHz";
  d1.drive.controller_rate = 1000.0;
  d1.command = 1.0;
  d1.duration = 1000.0 * scale;
  for (const JointCase& c : {robotJoint(1000.0 * scale), d1})
  {
    long impacts = 0, rests = 0;
    double held = 0.0;  // samples taken in blocks through stick phases
    struct Count : EventSink
    {
      long* impacts;
      long* rests;
      void onEvent(const Event& e) override
      {
        *impacts += e.type == EventType::Impact;
        *rests += e.type == EventType::Rest;
      }
    } count;
    count.impacts = &impacts;
    count.rests = &rests;
    const double wall = timeIt([&]() {
      impacts = rests = 0;
      Simulator sim(c.params, State(), c.command);
      sim.setDrive(makePositionDrive(c.drive, c.params.gain, c.params.gear_ratio, c.command, 0.0));
      sim.setEnergyTracking(false);
      sim.advanceTo(c.duration, &count);
      held = static_cast<double>(sim.heldSamples());
    });
    const double samples = c.duration * c.drive.controller_rate;
    std::printf("%-22s %9.0f %11.3f %10.0f %9.0f %9ld %8ld %8.1f\n", c.name.c_str(), c.duration, wall * 1e3, samples,
                wall * 1e9 / samples, impacts, rests, 100.0 * held / samples);
  }
}

/// The thesis grid's costliest points (elastic chatter of a light load: ρ²J_L/J_m = 0.04, e = 1), run as the sweep
/// runs them (until the verdict settles, ledger off) with the chatter fast path off (the closed form for every
/// flight: the code before it) and on. Returns false if a verdict or a limit-cycle amplitude (1e-6 rad) differs.
/// What a backlash_sim run costs beyond its simulation: the tracking figures gathered in the run's own pass
/// (RunConfig::tracking) against the replay they used to need (runResponse + replayTracking), the D1 servo as
/// `backlash_sim --duration T` runs it (energy ledger on). Best of three of each (the machine's speed drifts).
void trackingBenchmarks(double scale)
{
  std::printf("\n== tracking figures: in the run's own pass vs a replay (thesis D1, energy ledger on, best of 3)\n");
  std::printf("%-12s %10s %12s %12s %12s %10s %10s %s\n", "sim [s]", "samples", "alone [ms]", "replay [ms]",
              "in pass [ms]", "replay/x", "in pass/x", "figures");
  for (const double duration : {1e4 * scale, 1e5 * scale})
  {
    RunConfig c;
    c.duration = duration;
    auto best = [](const std::function<void()>& run) {
      double b = INFINITY;
      for (int k = 0; k < 3; ++k)
      {
        const auto start = std::chrono::steady_clock::now();
        run();
        b = std::min(b, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      }
      return b;
    };
    RunSummary alone_run;
    const double alone = best([&]() { alone_run = runResponse(c); });
    TrackingFigures replayed;
    double rate = 0.0;
    const double replay = best([&]() {
      const RunSummary r = runResponse(c);
      replayed = replayTracking(c, r, &rate);
    });
    RunConfig tracked = c;
    tracked.tracking = true;
    RunSummary in_pass_run;
    const double in_pass = best([&]() { in_pass_run = runResponse(tracked); });
    const TrackingFigures& f = in_pass_run.tracking;
    const bool same = f.settling_time == replayed.settling_time && f.rms_error == replayed.rms_error &&
                      f.steady_rms_error == replayed.steady_rms_error && f.max_error == replayed.max_error &&
                      f.overshoot == replayed.overshoot && f.rms_torque == replayed.rms_torque;
    std::printf("%-12.0f %10.0f %12.1f %12.1f %12.1f %10.2f %10.2f %s\n", duration, duration * rate, alone * 1e3,
                replay * 1e3, in_pass * 1e3, replay / alone, in_pass / alone, same ? "bit-identical" : "DIFFER");
  }
}

bool chatterBenchmarks(bool quick)
{
  std::printf("\n== elastic chatter: the thesis grid's costliest points, until settled (closed form vs fast path)\n");
  std::printf("%-16s %11s %11s %10s %10s %8s %9s %9s %s\n", "zeta/fr", "closed [ms]", "fast [ms]", "impacts", "impacts",
              "ratio", "ns/imp", "amp diff", "verdict");
  const std::vector<std::pair<double, double>> points =
      quick ? std::vector<std::pair<double, double>>{{0.8, 0.6}}
            : std::vector<std::pair<double, double>>{{0.3, 1.0}, {0.4, 1.0}, {0.5, 1.0}, {0.6, 1.0},
                                                     {0.8, 1.0}, {0.5, 0.8}, {0.6, 0.8}, {0.8, 0.8}};
  bool ok = true;
  double closed_total = 0.0, fast_total = 0.0;
  for (const auto& [zeta, fr] : points)
  {
    RunConfig config;
    config.params = chart(zeta, 0.04, fr, 1.0);
    config.track_energy = false;
    RunSummary with, without;
    config.short_flights = false;
    const double closed = timeIt([&]() { without = runResponse(config, nullptr); });
    config.short_flights = true;
    const double fast = timeIt([&]() { with = runResponse(config, nullptr); });
    closed_total += closed;
    fast_total += fast;
    const double amp_diff = std::fabs(with.status.error - without.status.error);
    const bool same = with.status.verdict == without.status.verdict && amp_diff <= 1e-6;
    ok = ok && same;
    char name[32];
    std::snprintf(name, sizeof name, "%.1f/%.1f", zeta, fr);
    std::printf("%-16s %11.1f %11.1f %10llu %10llu %7.1fx %9.0f %9.1e %s%s\n", name, closed * 1e3, fast * 1e3,
                static_cast<unsigned long long>(without.impacts), static_cast<unsigned long long>(with.impacts),
                closed / fast, fast * 1e9 / std::max<double>(1.0, static_cast<double>(with.impacts)), amp_diff,
                toString(with.status.verdict), same ? "" : " (DIFFERS)");
  }
  std::printf("%-16s %11.1f %11.1f %10s %10s %7.1fx\n", "total", closed_total * 1e3, fast_total * 1e3, "", "",
              closed_total / fast_total);
  return ok;
}

/// One chain of elastic micro-chatter outside the Plant: the certified short flight to the next impact, the motor
/// snapped onto the wall hit, the elastic impact map — the work of each impact of Plant::chatter without its
/// bookkeeping (floor rule, budget, divergence check). Restarts from its first state if a flight is refused.
struct ChatterChain
{
  State start, state;
  long impacts = 0, restarts = 0;

  void step(const ShortFlight::Model& model, const GearMesh& mesh, const ImpactMap& map)
  {
    ShortFlight f;
    const double t0 = state.time;
    if (!f.flyToImpact(model, state, 1.0, &state))
    {
      state = start;
      ++restarts;
      return;
    }
    state.time = t0 + f.impactTime();
    state.motor_position = mesh.motorPositionOnWall(state.load_position, f.wall());
    const ImpactOutcome o = map(state.load_velocity, state.motor_velocity);
    state.load_velocity = o.load_velocity;
    state.motor_velocity = o.motor_velocity;
    ++impacts;
  }
};

/// Captures the state just after the first impact past `after` [s] whose closing speed is below `speed` [rad/s],
/// and the states after the impacts that follow it (up to `follow`).
struct MicroChatterStart : EventSink
{
  double after = 0.0, speed = 0.0;
  std::size_t follow = 1000;
  bool found = false;
  State state;
  std::vector<State> next;
  void onEvent(const Event& e) override
  {
    if (e.type != EventType::Impact)
    {
      return;
    }
    if (found && next.size() < follow)
    {
      next.push_back(e.state);
    }
    if (!found && e.state.time > after && e.impact.approach_speed < speed)
    {
      found = true;
      state = e.state;
    }
  }
};

/**
 * Headroom of a scheduler that would run two chatter points interleaved on one core (not built): the
 * chain of dependent operations from one impact to the next leaves much of the core idle, so two independent
 * chains, stepped alternately, overlap in the out-of-order window. Both chains start from micro-chatter of the
 * thesis grid's costliest point (ζ 0.8, ρ²J_L/J_m 0.04, ρ²f_L/F_T 1, e 1), the second from a load velocity 1e-7
 * higher. Prints ns per impact for one chain and for two stepped alternately, and their ratio. Returns false if the
 * probe's chain does not repeat the simulation's impacts bit for bit, or its flights are refused (over 1 % restarts).
 */
bool interleavingProbe(bool quick)
{
  const ServoParams p = chart(0.8, 0.04, 1.0, 1.0);
  MicroChatterStart capture;
  capture.after = 30.0;
  capture.speed = 1e-5;
  Simulator sim(p, State(), 1.0);
  sim.setEnergyTracking(false);
  sim.advanceTo(40.0, &capture);
  std::printf(
      "\n== elastic micro-chatter, one chain vs two interleaved on one core (headroom of a paired scheduler)\n");
  if (!capture.found)
  {
    std::printf("no micro-chatter found in 30..40 s\n");
    return false;
  }
  const ShortFlight::Model model(p, sim.drive().law());  // the law in force: T_m = K(θ_R − θ_c)
  const GearMesh mesh(p);
  const ImpactMap map(p, p.restitution);
  // The probe's chain is the Plant's chatter: its first impacts are the simulation's, bit for bit.
  ChatterChain a{capture.state, capture.state}, b = a;
  std::size_t same = 0;
  for (; same < capture.next.size(); ++same)
  {
    a.step(model, mesh, map);
    const State& x = a.state;
    const State& y = capture.next[same];
    if (!(x.time == y.time && x.load_position == y.load_position && x.load_velocity == y.load_velocity &&
          x.motor_position == y.motor_position && x.motor_velocity == y.motor_velocity))
    {
      break;
    }
  }
  std::printf("the probe's chain repeats the simulation's next %zu impacts bit for bit (of %zu)\n", same,
              capture.next.size());
  a = ChatterChain{capture.state, capture.state};
  b.start.load_velocity *= 1.0 + 1e-7;
  b.state = b.start;
  const long n = quick ? 200000 : 2000000;
  auto perImpact = [&](auto&& run) {
    const auto t0 = std::chrono::steady_clock::now();
    run();
    return std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() / n;
  };
  double one = INFINITY, two = INFINITY;
  for (int rep = 0; rep < 3; ++rep)  // the best of three: the figures are compared, not added
  {
    one = std::min(one, perImpact([&]() {
                     for (long i = 0; i < n; ++i)
                     {
                       a.step(model, mesh, map);
                     }
                   }));
    two = std::min(two, perImpact([&]() {
                     for (long i = 0; i < n / 2; ++i)
                     {
                       a.step(model, mesh, map);
                       b.step(model, mesh, map);
                     }
                   }));
  }
  std::printf("one chain %.1f ns/impact, two interleaved %.1f ns/impact: %.2fx (restarts %ld of %ld impacts)\n", one,
              two, one / two, a.restarts + b.restarts, a.impacts + b.impacts);
  return same == capture.next.size() && capture.next.size() == capture.follow &&
         100 * (a.restarts + b.restarts) <= a.impacts + b.impacts;
}

}  // namespace

int main(int argc, char** argv)
{
  bool quick = false;
  std::string reference_out;
  for (int i = 1; i < argc; ++i)
  {
    if (!std::strcmp(argv[i], "--quick"))
    {
      quick = true;
    }
    else if (!std::strcmp(argv[i], "--tracking"))
    {
      trackingBenchmarks(1.0);  // that table alone
      return 0;
    }
    else if (!std::strcmp(argv[i], "--reference-out") && i + 1 < argc)
    {
      reference_out = argv[++i];
    }
    else
    {
      std::fprintf(stderr, "usage: bench_core [--quick] [--reference-out FILE] | bench_core --tracking\n");
      return 2;
    }
  }
  const double scale = quick ? 0.05 : 1.0;
  std::vector<Case> cases = {
      {"thesis_d1", ServoParams(), 1000.0 * scale},
      {"plastic_e0", chart(0.2, 4.0, 0.4, 0.0), 1000.0 * scale},
      {"zeno_e0.8", chart(0.4, 9.0, 0.4, 0.8), 1000.0 * scale},
      {"high_freq_wn50", chart(0.4, 9.0, 0.4, 1.0, 50.0), 100.0 * scale},
  };
  std::vector<double> rk4_steps = quick ? std::vector<double>{1e-2, 1e-3} : std::vector<double>{1e-2, 1e-3, 1e-4};
  std::ofstream ref_file;
  if (!reference_out.empty())
  {
    ref_file.open(reference_out);
  }
  bool ok = true;
  std::printf("%-15s %-22s %11s %12s %10s %8s %7s %11s %9s\n", "case", "method", "wall [ms]", "sim s/wall s",
              "ns/event", "events", "maxima", "max err", "ours is");
  for (const Case& c : cases)
  {
    // High-accuracy reference: odeint Dopri5 at tolerance 1e-13 with bisected events.
    const bench::Outcome ref = bench::odeintDense(c.params, 1.0, c.duration, 1e-13);
    std::vector<Row> rows;
    rows.push_back(ours(c));
    // One timed row per baseline run.
    auto baseline = [&](const char* format, double setting, const std::function<bench::Outcome()>& run) {
      Row r;
      char name[40];
      std::snprintf(name, sizeof name, format, setting);
      r.method = name;
      bench::Outcome o;
      r.wall = timeIt([&]() { o = run(); });
      r.events = o.events;
      r.maxima = o.maxima;
      rows.push_back(r);
    };
    for (double dt : rk4_steps)
    {
      baseline("RK4 fixed dt=%g", dt, [&]() { return bench::fixedStepRk4(c.params, 1.0, c.duration, dt); });
    }
    for (double tol : {1e-6, 1e-10})
    {
      baseline("odeint dopri5 tol=%g", tol, [&]() { return bench::odeintDense(c.params, 1.0, c.duration, tol); });
    }
    const double ours_wall = rows[0].wall;
    double ours_err = 0.0, rk4_coarse_err = 0.0;
    for (std::size_t k = 0; k < rows.size(); ++k)
    {
      const Row& r = rows[k];
      std::size_t n = 0;
      const double err = bench::maxError(r.maxima, ref.maxima, &n);
      if (k == 0)
      {
        ours_err = err;
      }
      if (k == 1)
      {
        rk4_coarse_err = err;
      }
      char ratio[32] = "-";
      if (k > 0)
      {
        std::snprintf(ratio, sizeof ratio, "%.0fx faster", r.wall / ours_wall);
      }
      std::printf("%-15s %-22s %11.4f %12.4g %10.0f %8ld %7zu %11.2e %9s\n", c.name.c_str(), r.method.c_str(),
                  r.wall * 1e3, c.duration / r.wall, r.events ? r.wall * 1e9 / r.events : 0.0, r.events,
                  r.maxima.size(), err, ratio);
    }
    std::printf("%-15s %-22s %11s %12s %10s %8ld %7zu %11s\n", c.name.c_str(), "(reference dopri5 1e-13)", "-", "-",
                "-", ref.events, ref.maxima.size(), "0");
    if (!(ours_err <= 1e-9) || !(rk4_coarse_err > ours_err))
    {
      std::printf("ACCURACY CHECK FAILED for %s: ours %.3g rad, RK4 dt=1e-2 %.3g rad\n", c.name.c_str(), ours_err,
                  rk4_coarse_err);
      ok = false;
    }
    if (ref_file)
    {
      ref_file << c.name << " " << c.duration << " " << ours_wall << " " << c.params.motor_inertia << " "
               << c.params.load_inertia << " " << c.params.motor_friction << " " << c.params.load_friction << " "
               << c.params.gain << " " << c.params.gear_ratio << " " << c.params.backlash << " "
               << c.params.restitution;
      for (const bench::Max& m : ref.maxima)
      {
        ref_file << " " << m.position;
      }
      ref_file << "\n";
    }
  }
  jointBenchmarks(scale);
  trackingBenchmarks(scale);
  if (!chatterBenchmarks(quick))
  {
    std::printf("CHATTER CHECK FAILED: the fast path changed a verdict or an amplitude\n");
    ok = false;
  }
  if (!interleavingProbe(quick))
  {
    std::printf("PROBE CHECK FAILED: the interleaving probe does not repeat the simulation's chatter\n");
    ok = false;
  }
  rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  std::printf("peak memory (whole benchmark process): %.1f MB\n", usage.ru_maxrss / 1024.0);
  std::printf("accuracy check: %s\n",
              ok ? "ours agrees with the reference to 1e-9 rad and beats RK4 dt=1e-2" : "FAILED");
  return ok ? 0 : 1;
}
