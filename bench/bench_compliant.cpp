// The compliant joint against SUNDIALS CVODE, the solver general-purpose tools (Modelica, Simscape's variable-step
// solvers) put behind a hybrid model: the same servo (App. D1 with a spring–damper mesh, docs/model.md Part 3)
// integrated by CVODE (BDF with Newton and a dense solver, and Adams) with rootfinding for the mesh's events, at
// several tolerances; its positive load maxima against ours, its wall time (the best of three runs) against ours (the
// best of three before and three after).
// Then the robot joint's 1 kHz PID on a compliant mesh (ours only). Prints figures and ratios; instructions per event
// where the kernel lets a process count its own (perf_event_open), "n/a" otherwise.
// usage: bench_compliant [--quick]
#include <cvode/cvode.h>
#include <linux/perf_event.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sys/ioctl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "backlash_servo/drive/drive.h"
#include "backlash_servo/simulation/simulator.h"
#include "maxima.h"

using namespace backlash_servo;

namespace
{
/// Counts this process's user-space instructions while alive (−1 when the kernel does not allow it).
class InstructionCounter
{
 public:
  InstructionCounter()
  {
    perf_event_attr attr;
    std::memset(&attr, 0, sizeof attr);
    attr.size = sizeof attr;
    attr.type = PERF_TYPE_HARDWARE;
    attr.config = PERF_COUNT_HW_INSTRUCTIONS;
    attr.disabled = 1;
    attr.exclude_kernel = 1;
    attr.exclude_hv = 1;
    fd_ = static_cast<int>(syscall(SYS_perf_event_open, &attr, 0, -1, -1, 0));
  }
  ~InstructionCounter()
  {
    if (fd_ >= 0)
    {
      close(fd_);
    }
  }
  void start()
  {
    if (fd_ >= 0)
    {
      ioctl(fd_, PERF_EVENT_IOC_RESET, 0);
      ioctl(fd_, PERF_EVENT_IOC_ENABLE, 0);
    }
  }
  long long stop()
  {
    long long n = -1;
    if (fd_ >= 0)
    {
      ioctl(fd_, PERF_EVENT_IOC_DISABLE, 0);
      if (read(fd_, &n, sizeof n) != static_cast<ssize_t>(sizeof n))
      {
        n = -1;
      }
    }
    return n;
  }

 private:
  int fd_ = -1;
};

/// The shortest wall time [s] of three runs (each run starts its results afresh): on a shared machine the other runs
/// measure the neighbours.
double seconds(const std::function<void()>& run)
{
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i)
  {
    const auto start = std::chrono::steady_clock::now();
    run();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return best;
}

/// App. D1 with resilient teeth (config/compliant_d1.yaml).
ServoParams compliantD1()
{
  ServoParams p;  // App. D1: J_m 0.1, J_L 0.9, f_m 0.48, f_L 0.32, K 1, ρ 1, Δ 0.3
  p.mesh_stiffness = 1e4;
  p.mesh_damping = 4.4613;
  return p;
}

struct Ours
{
  std::vector<bench::Max> maxima;
  long events = 0;
  double wall = 0.0;
  long long instructions = -1;
};

Ours runOurs(const ServoParams& p, double command, double duration)
{
  Ours o;
  struct Sink : EventSink
  {
    Ours* o;
    void onEvent(const Event& e) override
    {
      ++o->events;
      if (e.type == EventType::Maximum && e.state.load_position > 0.0)
      {
        o->maxima.push_back({e.state.time, e.state.load_position});
      }
    }
  } sink;
  sink.o = &o;
  InstructionCounter count;
  o.wall = seconds([&]() {
    o.maxima.clear();
    o.events = 0;
    Simulator sim(p, State(), command);
    sim.setEnergyTracking(false);
    count.start();
    sim.advanceTo(duration, &sink);
    o.instructions = count.stop();
  });
  return o;
}

/// The same joint for CVODE: x = (θ_m, ω_m, θ_c, ω_c), the P law T_m = K(θ_R − θ_c), the mesh torque of the flank in
/// contact (Q = c y + d ẏ forward, −(c y + d ẏ) backward, y the flank's penetration), free play otherwise.
struct Model
{
  ServoParams p;
  double command = 1.0;
  int flank = 1;             // +1 forward, −1 backward, 0 apart
  bool penetrating = false;  // apart after a release with y > 0 (a re-engagement is possible)
  int last_flank = 1;        // the flank released last
  double y(const double* x, int s) const
  {
    return s > 0 ? p.gear_ratio * x[0] - x[2] : -(p.gear_ratio * x[0] - x[2]) - p.backlash;
  }
  double ydot(const double* x, int s) const { return s * (p.gear_ratio * x[1] - x[3]); }
  double meshForce(const double* x, int s) const { return p.mesh_stiffness * y(x, s) + p.mesh_damping * ydot(x, s); }
};

int rhs(sunrealtype, N_Vector xv, N_Vector dv, void* data)
{
  const Model& m = *static_cast<const Model*>(data);
  const double* x = N_VGetArrayPointer(xv);
  double* d = N_VGetArrayPointer(dv);
  const double q = m.flank != 0 ? m.flank * m.meshForce(x, m.flank) : 0.0;
  const double tm = m.p.gain * (m.command - x[2]);
  d[0] = x[1];
  d[1] = (tm - m.p.motor_friction * x[1] - m.p.gear_ratio * q) / m.p.motor_inertia;
  d[2] = x[3];
  d[3] = (q - m.p.load_friction * x[3]) / m.p.load_inertia;
  return 0;
}

// Roots: [0] the load velocity (maxima: + to −); in contact [1] the flank's force P ↓ 0 (release); apart [1], [2] the
// flanks' penetrations ↑ 0 (engagements) — or, penetrating after a release, [1] y ↓ 0 and [2] P ↑ 0 (re-engagement).
int roots(sunrealtype, N_Vector xv, sunrealtype* g, void* data)
{
  const Model& m = *static_cast<const Model*>(data);
  const double* x = N_VGetArrayPointer(xv);
  g[0] = x[3];
  if (m.flank != 0)
  {
    g[1] = m.meshForce(x, m.flank);
    g[2] = 1.0;
  }
  else if (m.penetrating)
  {
    g[1] = m.y(x, m.last_flank);
    g[2] = m.meshForce(x, m.last_flank);
  }
  else
  {
    g[1] = m.y(x, 1);
    g[2] = m.y(x, -1);
  }
  return 0;
}

struct CvodeRun
{
  std::vector<bench::Max> maxima;
  long events = 0, steps = 0;
  double wall = 0.0;
  bool ok = true;
};

CvodeRun runCvode(const ServoParams& p, double command, double duration, double rtol, int method)
{
  CvodeRun r;
  r.wall = seconds([&]() {
    r = CvodeRun();
    SUNContext ctx;
    SUNContext_Create(nullptr, &ctx);
    Model m;
    m.p = p;
    m.command = command;
    N_Vector x = N_VNew_Serial(4, ctx);
    N_VConst(0.0, x);
    void* mem = CVodeCreate(method, ctx);
    CVodeInit(mem, rhs, 0.0, x);
    // Absolute tolerances at the scale of each state (angles ~1 rad, speeds ~1 rad/s).
    CVodeSStolerances(mem, rtol, rtol);
    CVodeSetUserData(mem, &m);
    CVodeSetMaxNumSteps(mem, 100000000);
    SUNMatrix a = SUNDenseMatrix(4, 4, ctx);
    SUNLinearSolver ls = SUNLinSol_Dense(x, a, ctx);
    CVodeSetLinearSolver(mem, ls, a);
    CVodeRootInit(mem, 3, roots);
    int dirs[3] = {-1, 0, 0};
    const auto setDirections = [&]() {
      if (m.flank != 0)
      {
        dirs[1] = -1;
        dirs[2] = 0;
      }
      else if (m.penetrating)
      {
        dirs[1] = -1;
        dirs[2] = +1;
      }
      else
      {
        dirs[1] = +1;
        dirs[2] = +1;
      }
      CVodeSetRootDirection(mem, dirs);
    };
    setDirections();
    double t = 0.0;
    while (t < duration)
    {
      const int flag = CVode(mem, duration, x, &t, CV_NORMAL);
      if (flag < 0)
      {
        r.ok = false;
        break;
      }
      if (flag != CV_ROOT_RETURN)
      {
        continue;
      }
      if (r.events > 1000000)
      {
        r.ok = false;  // a storm of roots at one mode switch: CVODE's root isolation lost the sign
        break;
      }
      int found[3] = {0, 0, 0};
      CVodeGetRootInfo(mem, found);
      const double* s = N_VGetArrayPointer(x);
      ++r.events;
      if (found[0] != 0)
      {
        if (s[2] > 0.0)
        {
          r.maxima.push_back({t, s[2]});
        }
        if (found[1] == 0 && found[2] == 0)
        {
          continue;  // no mode change: the integration goes on
        }
      }
      if (m.flank != 0 && found[1] != 0)
      {
        m.last_flank = m.flank;
        m.penetrating = m.y(s, m.flank) > 0.0;
        m.flank = 0;
      }
      else if (m.flank == 0 && m.penetrating)
      {
        if (found[2] != 0)
        {
          m.flank = m.last_flank;
        }
        m.penetrating = false;
      }
      else if (m.flank == 0)
      {
        m.flank = found[1] != 0 ? 1 : -1;
      }
      setDirections();
      long steps = 0;
      CVodeGetNumSteps(mem, &steps);
      r.steps += steps;
      CVodeReInit(mem, t, x);
    }
    long steps = 0;
    CVodeGetNumSteps(mem, &steps);
    r.steps += steps;
    SUNLinSolFree(ls);
    SUNMatDestroy(a);
    N_VDestroy(x);
    CVodeFree(&mem);
    SUNContext_Free(&ctx);
  });
  return r;
}

}  // namespace

int main(int argc, char** argv)
{
  bool quick = false;
  for (int i = 1; i < argc; ++i)
  {
    if (!std::strcmp(argv[i], "--quick"))
    {
      quick = true;
    }
    else
    {
      std::fprintf(stderr, "usage: bench_compliant [--quick]\n");
      return 2;
    }
  }
  const double duration = quick ? 100.0 : 1000.0;
  const ServoParams p = compliantD1();
  std::printf("== compliant D1 (c = 1e4 N·m/rad, d = 4.4613 N·m·s/rad), unit step, %.0f s\n", duration);
  Ours ours = runOurs(p, 1.0, duration);
  struct Setting
  {
    const char* name;
    int method;
    double rtol;
  };
  const std::vector<Setting> settings = {
      {"CVODE BDF rtol 1e-8", CV_BDF, 1e-8},       {"CVODE BDF rtol 1e-10", CV_BDF, 1e-10},
      {"CVODE BDF rtol 1e-12", CV_BDF, 1e-12},     {"CVODE BDF rtol 1e-13", CV_BDF, 1e-13},
      {"CVODE BDF rtol 1e-14", CV_BDF, 1e-14},     {"CVODE BDF rtol 1e-15", CV_BDF, 1e-15},
      {"CVODE Adams rtol 1e-8", CV_ADAMS, 1e-8},   {"CVODE Adams rtol 1e-10", CV_ADAMS, 1e-10},
      {"CVODE Adams rtol 1e-12", CV_ADAMS, 1e-12}, {"CVODE Adams rtol 1e-13", CV_ADAMS, 1e-13},
      {"CVODE Adams rtol 1e-14", CV_ADAMS, 1e-14}, {"CVODE Adams rtol 1e-15", CV_ADAMS, 1e-15}};
  std::vector<CvodeRun> runs;
  for (const Setting& s : settings)
  {
    std::fprintf(stderr, "%s …\n", s.name);
    runs.push_back(runCvode(p, 1.0, duration, s.rtol, s.method));
  }
  // Ours timed again after the CVODE runs, the better of the two kept: this machine's speed changes for seconds at a
  // time, which a run of 15 ms sees whole and the CVODE runs of seconds each see in part.
  ours.wall = std::min(ours.wall, runOurs(p, 1.0, duration).wall);
  std::printf("%-24s %10s %9s %9s %10s %12s %9s %9s %9s\n", "method", "wall [ms]", "events", "steps", "ns/event",
              "instr/event", "maxima", "max err", "max dt");
  std::printf("%-24s %10.1f %9ld %9s %10.0f %12s %9zu %9s\n", "exact (this package)", ours.wall * 1e3, ours.events, "-",
              ours.wall * 1e9 / std::max(1L, ours.events),
              ours.instructions >= 0 ? std::to_string(ours.instructions / std::max(1L, ours.events)).c_str() : "n/a",
              ours.maxima.size(), "-");
  for (std::size_t k = 0; k < settings.size(); ++k)
  {
    const Setting& s = settings[k];
    const CvodeRun& r = runs[k];
    std::size_t compared = 0;
    const double err = bench::maxError(ours.maxima, r.maxima, &compared);
    double drift = 0.0;  // (the maxima's times: where a limit cycle's phase drifts, CVODE's event times do)
    for (std::size_t i = 0; i < compared; ++i)
    {
      drift = std::max(drift, std::fabs(ours.maxima[i].time - r.maxima[i].time));
    }
    std::printf("%-24s %10.1f %9ld %9ld %10.0f %12s %9zu %9.1e %9.1e   %.0fx ours%s\n", s.name, r.wall * 1e3, r.events,
                r.steps, r.wall * 1e9 / std::max(1L, r.events), "", r.maxima.size(), err, drift, r.wall / ours.wall,
                r.ok ? "" : " (CVODE stopped: failed or a root storm)");
  }
  std::printf(
      "(max err, max dt: the largest difference of the positive load maxima [rad] and of their times [s], the "
      "first %s of each list; ours: the best of three runs before the CVODE runs and three after)\n",
      "min(count)");

  std::printf(
      "\n== robot joint with a compliant mesh: ρ = 0.01, J_m 1e-4, J_L 0.5 kg·m², Δ 5 mrad, c = 8.6e4 N·m/rad, "
      "1 kHz PID, %.0f s\n",
      duration);
  ServoParams r;
  r.motor_inertia = 1e-4;
  r.load_inertia = 0.5;
  r.motor_friction = 1e-4;
  r.load_friction = 0.5;
  r.gain = 6.0;
  r.gear_ratio = 0.01;
  r.backlash = 0.005;
  r.mesh_stiffness = 8.6e4;
  r.mesh_damping = 20.0;
  DriveParams d;
  d.control_law = "pid";
  d.controller_rate = 1000.0;
  d.integral_gain = 30.0;
  d.derivative_gain = 0.4;
  struct Count : EventSink
  {
    long n = 0;
    void onEvent(const Event&) override { ++n; }
  };
  // The same joint ringing in its limit cycle, and holding a load against gravity (the mesh stays engaged).
  for (const double load_torque : {0.0, 20.0})
  {
    r.load_torque = load_torque;
    long events = 0;
    const double wall = seconds([&]() {
      Count count;
      Simulator sim(r, State(), 0.5);
      sim.setDrive(makePositionDrive(d, r.gain, r.gear_ratio, 0.5, 0.0));
      sim.setEnergyTracking(false);
      sim.advanceTo(duration, &count);
      events = count.n;
    });
    const double samples = duration * d.controller_rate;
    std::printf("load torque %4.1f N·m: wall %.1f ms (%.0f ns per sample, %ld events; target 100 ms per 1000 s)\n",
                load_torque, wall * 1e3, wall * 1e9 / samples, events);
  }
  return 0;
}
