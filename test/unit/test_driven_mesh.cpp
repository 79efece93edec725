// The compliant mesh's element driven by an exact sine (driven_mesh.h) against independent truth: without backlash
// and damping it is a linear spring on the load, whose response is written here; refusals name the key.
#include <gtest/gtest.h>

#include <complex>
#include <string>

#include "backlash_servo/driven_mesh.h"
#include "backlash_servo/params.h"

using namespace backlash_servo;

// Δ = 0, d = 0: the teeth pass c(x − θ_c) at all times (one flank or the other), so N_θ = c/(−ω²J_L + jωf_L + c) —
// below, near and above the load's resonance √(c/J_L), soft and stiff — and N_T = (−ω²J_L + jωf_L) N_θ.
TEST(DrivenMesh, WithoutBacklashAndDampingItIsTheLinearSpring)
{
  ServoParams p;
  p.load_inertia = 0.5;
  p.load_friction = 0.08;
  p.backlash = 0.0;
  p.mesh_damping = 0.0;
  for (double c : {3.0, 1000.0})
  {
    p.mesh_stiffness = c;
    for (double w : {0.7, 2.0, 3.0})
    {
      const DrivenBacklash d = drivenCompliantMesh(p, 0.2, w);
      const std::complex<double> l(-w * w * p.load_inertia, w * p.load_friction);
      const std::complex<double> expected = c / (l + c);
      ASSERT_TRUE(d.periodic) << c << " " << w;
      EXPECT_LT(std::abs(d.position - expected), 1e-9 * std::abs(expected)) << c << " " << w;
      EXPECT_LT(std::abs(d.torque - l * expected), 1e-9 * std::abs(l * expected)) << c << " " << w;
    }
  }
}

// With backlash the element passes less than the spring would (N_θ below the linear one at small amplitudes, the
// free play crossed without torque) and tends to it as A/Δ grows.
TEST(DrivenMesh, ItTendsToTheLinearSpringAtLargeAmplitude)
{
  ServoParams p;
  p.load_inertia = 0.5;
  p.load_friction = 0.08;
  p.mesh_stiffness = 50.0;
  p.mesh_damping = 0.0;
  p.backlash = 0.01;
  const double w = 2.0;
  const std::complex<double> l(-w * w * p.load_inertia, w * p.load_friction);
  const std::complex<double> linear = p.mesh_stiffness / (l + p.mesh_stiffness);
  double previous = INFINITY;
  for (double a : {0.02, 0.1, 1.0})
  {
    const double off = std::abs(drivenCompliantMesh(p, a, w).position - linear) / std::abs(linear);
    EXPECT_LT(off, previous) << a;
    previous = off;
  }
  EXPECT_LT(previous, 0.01);
}

TEST(DrivenMesh, WhatItDoesNotTakeIsNamed)
{
  const auto refusal = [](const ServoParams& p) {
    try
    {
      drivenCompliantMesh(p, 0.5, 1.0);
    }
    catch (const InvalidParameterError& e)
    {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  ServoParams p;
  p.mesh_stiffness = 100.0;
  EXPECT_EQ(refusal(p), "accepted");
  ServoParams q = p;
  q.mesh_stiffness = 0.0;
  EXPECT_NE(refusal(q).find("mesh_stiffness"), std::string::npos);
  q = p;
  q.mesh_law = "msl_elastobacklash";
  EXPECT_NE(refusal(q).find("mesh_law"), std::string::npos);
  q = p;
  q.load_coulomb_friction = 0.1;
  EXPECT_NE(refusal(q).find("load_coulomb_friction"), std::string::npos);
  q = p;
  q.load_torque = 0.1;
  EXPECT_NE(refusal(q).find("load_torque"), std::string::npos);
}
