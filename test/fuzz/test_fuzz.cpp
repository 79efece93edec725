// Property fuzzing in CI: 2000 deterministic cases over the validated envelope and its edges
// (test/fuzz/fuzz_cases.h), including load torques and digital drives. Every case: no crash, exception or
// "no progress", the gap in [0, Δ] to rounding at every event, the same final state when the run is cut into 17
// pieces instead of 1000, a finite state, and the energy balance closing to 1e-9 of the energy scale. An impact
// storm may end at the event budget, an unstable digital loop may diverge with a clear error (both counted,
// allowed). No failure class is tolerated: the last one, energy residuals of 1e-9 … 2e-8 of the energy scale in ~1
// case in 10 000 (the apart closed form's product integrals cancelling), went with the quadrature of
// BasicFreeMotion::energy. Long runs: bash scripts/fuzz_long.sh.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <map>

#include "fuzz_cases.h"

namespace
{
/// Checks cases 0 … n − 1 drawn by `make`: each keeps every property or ends as an allowed outcome (the event budget,
/// a divergence). Prints and returns the counts per outcome class; `timed` is given each case's wall time [s].
std::map<std::string, int> checkSample(const std::function<fuzz::Case(std::uint64_t)>& make, int n, const char* label,
                                       const std::function<void(const fuzz::Case&, double)>& timed = nullptr)
{
  std::map<std::string, int> counts;
  for (int i = 0; i < n; ++i)
  {
    const fuzz::Case c = make(static_cast<std::uint64_t>(i));
    const auto start = std::chrono::steady_clock::now();
    const fuzz::Outcome o = fuzz::check(c);
    if (timed)
    {
      timed(c, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    ++counts[o.klass];
    EXPECT_TRUE(o.klass == "ok" || o.klass == "budget" || o.klass == "diverged")
        << o.klass << " in " << label << " case " << i << ": " << o.detail << "\n  backlash_sim " << c.describe();
  }
  for (const auto& kv : counts)
  {
    std::printf("fuzz (%s): %-10s %d\n", label, kv.first.c_str(), kv.second);
  }
  return counts;
}

TEST(Fuzz, TwoThousandCasesKeepEveryProperty)
{
  const int n = 2000;
  std::map<std::string, int> counts = checkSample([](std::uint64_t i) { return fuzz::makeCase(2, i); }, n, "rigid");
  // The sample covers the drive's additions too: compensators and command profiles.
  int compensated = 0, profiled = 0;
  for (int i = 0; i < n; ++i)
  {
    const fuzz::Case c = fuzz::makeCase(2, static_cast<std::uint64_t>(i));
    compensated += c.drive.compensation != "none";
    profiled += c.profile != nullptr;
  }
  EXPECT_GT(compensated, 100);
  EXPECT_GT(profiled, 200);
  EXPECT_GT(counts["ok"], n * 9 / 10);
}

// The same properties over compliant joints (fuzz::makeCompliantCase: the mesh across the envelope, both laws, a
// torsional shaft in a third of the cases, no dry friction): the energy balance — spring energies, damper losses,
// the mesh's jumps at releases and re-engagements — closing to 1e-9 of the energy scale, the same final state however
// the run is cut. The first 40 cases of a seed (a few stiff meshes take seconds each); more with
// `bash scripts/fuzz_long.sh N SEED --compliant`.
TEST(Fuzz, CompliantJointsKeepEveryProperty)
{
  const int n = 40;
  int shafts = 0, msl = 0, dry = 0;
  std::map<std::string, int> counts = checkSample(
      [&](std::uint64_t i) {
        fuzz::Case c = fuzz::makeCompliantCase(2, i);
        EXPECT_TRUE(c.params.compliant());
        shafts += c.params.torsionalShaft();
        dry += c.params.hasDryFriction();
        msl += c.params.mesh_law == "msl_elastobacklash";
        return c;
      },
      n, "compliant");
  EXPECT_GT(shafts, 5);
  EXPECT_GT(msl, 5);
  EXPECT_GT(dry, 5);
  EXPECT_GT(counts["ok"], n * 8 / 10);
}

// Compliant joints damped across the whole envelope (fuzz::makeDampedCompliantCase: contact damping ratios from 0.01
// to the damping rate's edge, 1e5 ω_n): the same properties, and each case answered within PER_CASE_SECONDS of wall
// time (the slowest measured takes 5 s; the bound is for a crawl, not a speed target).
TEST(Fuzz, DampedCompliantJointsKeepEveryPropertyInBoundedTime)
{
  constexpr double PER_CASE_SECONDS = 90.0;
  const int n = 30;
  int overdamped = 0;
  double slowest = 0.0;
  std::map<std::string, int> counts = checkSample(
      [&](std::uint64_t i) {
        fuzz::Case c = fuzz::makeDampedCompliantCase(3, i);
        const backlash_servo::ServoParams& p = c.params;
        overdamped += p.mesh_damping > 2.0 * std::sqrt(p.mesh_stiffness * fuzz::meshReducedInertia(p));
        return c;
      },
      n, "damped compliant",
      [&](const fuzz::Case& c, double seconds) {
        slowest = std::max(slowest, seconds);
        EXPECT_LT(seconds, PER_CASE_SECONDS) << "backlash_sim " << c.describe();
      });
  std::printf("fuzz (damped compliant): %d of %d overdamped contacts, slowest case %.2f s\n", overdamped, n, slowest);
  EXPECT_GT(overdamped, n / 5);
  EXPECT_GT(counts["ok"], n * 7 / 10);
}

// A compliant joint under the continuous law following a ramp runs in the ramp's moving frame, whose load torque
// carries the load's viscous friction at the ramp's speed, −f_L v (here f_L = 1.5e7 N·m·s/rad
// at 169 rad/s: 2.6e9 N·m), which must not be refused as if the user had set load_torque beyond its range. The frame's
// torques are derived, not inputs: the run keeps every property.
TEST(Fuzz, ACompliantRampsFrameTorqueIsNotAUserInput)
{
  const fuzz::Case c = fuzz::makeCompliantCase(1, 210);
  ASSERT_TRUE(c.profile != nullptr);
  ASSERT_FALSE(c.drive.sampled());
  EXPECT_GT(c.params.load_friction * 417.0 / 2.47, 1e9);  // the ramp's friction bias, beyond load_torque's range
  const fuzz::Outcome o = fuzz::check(c);
  EXPECT_EQ(o.klass, "ok") << o.detail;
}

// A motor viscous friction ~1e-6 of the compliant mesh's frequency (1.1e-11 N·m·s/rad on
// 1.1e-5 kg·m², a soft mesh and shaft, a cascade loop sampled every 60 s): in contact the joint's common drift decays
// at ~1e-9 of the mesh's frequency beside the zero eigenvalue of its common angle. Taken as nilpotent, that drift would
// be resolved to 1e-7 and the energy balance miss by 8e-9 of its scale; the run keeps every property.
TEST(Fuzz, ASlowFrictionDriftBesideTheMeshKeepsTheEnergyBalance)
{
  const fuzz::Case c = fuzz::makeCompliantCase(1, 749);
  ASSERT_TRUE(c.params.compliant() && c.params.torsionalShaft());
  EXPECT_LT(c.params.motor_friction / c.params.motor_inertia,
            1e-5 * std::sqrt(c.params.mesh_stiffness / c.params.motor_inertia));
  const fuzz::Outcome o = fuzz::check(c);
  EXPECT_EQ(o.klass, "ok") << o.detail;
}

// A load floating in the free play behind a torsional shaft, read by the P law, its viscous friction slow (the
// drift decays at 8e-6 of the shaft's frequency, the motor's at 4e-5; and a stiff mesh and shaft with dry
// friction): such slow modes must not be taken for a chain of the zero eigenvalue and cut off as a polynomial (the
// motor would drift 7e-7 of its travel off in 0.09 s, the energy balance miss by 4e-9 and 2e-8 of its scale).
TEST(Fuzz, SlowModesBesideTheZeroEigenvalueKeepTheEnergyBalance)
{
  for (std::uint64_t index : {202u, 10u})
  {
    const fuzz::Outcome o = fuzz::check(fuzz::makeCompliantCase(5, index));
    EXPECT_EQ(o.klass, "ok") << "seed 5 #" << index << ": " << o.detail;
  }
}

// A contact touched at the start (a backward contact, P = −3e-11 N·m within its rounding of
// 2e-8) whose P rises at 1.7 N·m/s while a stiff shaft (1.7e8 N·m/rad) bends it back at −1e12 N·m/s²: P peaks 1e-12
// above its start, inside the band, and falls. Judged by its rate, the contact would be kept and the release, a
// crossing from ≥ 0, never come: the mesh would pull until the load's turning point 1.65 µs later. It releases at the
// start: the side it leaves the rounding band on decides.
TEST(Fuzz, AContactTouchedAtTheStartThatLeavesItsRoundingDownwardsReleasesThere)
{
  const fuzz::Outcome o = fuzz::check(fuzz::makeCompliantCase(9, 289));
  EXPECT_EQ(o.klass, "ok") << o.detail;
}

// An engagement found within the rounding of a start whose teeth part at once (a backward
// flank touching at rest, a 1.4e6 N·m drive torque pulling the motor off, P = −0.15 N·m at the engagement; #4469, the
// same with P = −4e-24 N·m on a 7e-6 N·m/rad mesh): kept because it had just begun, such a contact's release output
// never crosses zero from above, and its torque, clipped at zero, hides the gear crossing the free play into the
// other flank (5.4e7 N·m of law unapplied at 7.9 µs in the first). A contact begun at this instant with P below its
// rounding releases at once.
TEST(Fuzz, AnEngagementWhoseTeethPartAtOnceReleasesThere)
{
  for (const int index : {1056, 4469})
  {
    const fuzz::Outcome o = fuzz::check(fuzz::makeCompliantCase(14, index));
    EXPECT_EQ(o.klass, "ok") << "case " << index << ": " << o.detail;
  }
}

// Teeth without backlash (Δ = 0, undamped, c = 6e3 N·m/rad) pressing with ~1e-13 N·m, inside the 7e-13 N·m rounding
// of their torque, swap flanks at a sample: the backward contact released there, the
// forward one engaged at once with P below zero within its rounding, and the new drive torque pulled the motor back —
// P fell from below zero and never crossed it, so the mesh must not stay in the forward contact with its torque
// clipped at zero while the teeth press the backward flank. A contact kept with its release output below zero within
// the rounding releases where it falls past the rounding.
TEST(Fuzz, TeethWithoutBacklashSwappingFlanksAtRoundingReleaseWhenPulledApart)
{
  const fuzz::Outcome o = fuzz::check(fuzz::makeCompliantCase(14, 5582));
  EXPECT_EQ(o.klass, "ok") << o.detail;
}

// msl_elastobacklash entering K2 (2c·y while d·ẏ > c·y) at a grazing engagement (d·ẏ and c·y both within the 2e-7 N·m
// rounding of angles of 270 rad): K2's switch output c·y − d·ẏ began at +2e-9, inside the band, so its crossing from ≤
// 0 would never come and the mesh press with 2c·y — twice its law. It switches to KD at the engagement: the output
// leaves its rounding band upwards.
TEST(Fuzz, AGrazingEngagementIntoK2LeavesItWhereTheSwitchOutputLeavesItsRoundingUpwards)
{
  const fuzz::Outcome o = fuzz::check(fuzz::makeCompliantCase(9, 3543));
  EXPECT_EQ(o.klass, "ok") << o.detail;
}

// The gap property's rounding scale includes the set-point θ_R(t) (a ramp runs in a frame moving with it):
// positions crossing zero at 26 rad/s during a ramp to −9.3 rad, the gap 1.7e-15 rad below 0 — rounding of
// the frame's ~9 rad. A gap out by far more than rounding (a missed impact) is still flagged, with or without a
// profile.
TEST(Fuzz, GapPropertyCountsTheSetPointsRoundingOnly)
{
  const fuzz::Case c = fuzz::makeCase(7, 52681);
  ASSERT_TRUE(c.profile != nullptr);
  EXPECT_EQ(fuzz::check(c).klass, "ok");
  fuzz::GapWatch watch;
  watch.mesh = backlash_servo::GearMesh(c.params);
  watch.profile = c.profile;
  backlash_servo::Event e;
  e.state.time = 1.43457985891;  // on the ramp, θ_R ≈ −8 rad
  e.state.motor_position = -0.0086665826434568771;
  e.state.load_position = c.params.gear_ratio * e.state.motor_position - 1.7e-15;
  watch.onEvent(e);
  EXPECT_LT(watch.worst, 1.0);
  e.state.load_position = c.params.gear_ratio * e.state.motor_position - 1e-10;  // beyond rounding: flagged
  watch.onEvent(e);
  EXPECT_GT(watch.worst, 1.0);
  fuzz::GapWatch constant;  // constant command 1 rad at positions ~1 rad: 1e-10 rad out is flagged too
  constant.mesh = backlash_servo::GearMesh(c.params);
  constant.command = 1.0;
  e.state.motor_position = 1.0 / c.params.gear_ratio;
  e.state.load_position = 1.0 - 1e-10;
  constant.onEvent(e);
  EXPECT_GT(constant.worst, 1.0);
}
}  // namespace
