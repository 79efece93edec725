// Parameter validation and the chart-form conversion.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "backlash_servo/model/params.h"

using namespace backlash_servo;

namespace
{
std::string failingField(const ServoParams& p)
{
  try
  {
    p.validate();
  }
  catch (const InvalidParameterError& e)
  {
    return e.field();
  }
  return "";
}
}  // namespace

TEST(Params, DefaultsAreTheThesisLimitCycleCaseAndValid)
{
  ServoParams p;
  EXPECT_NO_THROW(p.validate());
  EXPECT_NEAR(p.dampingRatio(), 0.4, 1e-12);
  EXPECT_NEAR(p.inertiaRatio(), 9.0, 1e-12);
  EXPECT_NEAR(p.frictionRatio(), 0.4, 1e-12);
}

TEST(Params, EachBadFieldIsNamed)
{
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Case
  {
    double ServoParams::*field;
    double value;
    const char* name;
  };
  const Case cases[] = {
      {&ServoParams::motor_inertia, 0.0, "motor_inertia"}, {&ServoParams::motor_inertia, -1.0, "motor_inertia"},
      {&ServoParams::load_inertia, nan, "load_inertia"},   {&ServoParams::motor_friction, -0.1, "motor_friction"},
      {&ServoParams::load_friction, inf, "load_friction"}, {&ServoParams::gain, 0.0, "gain"},
      {&ServoParams::gear_ratio, -2.0, "gear_ratio"},      {&ServoParams::backlash, -1e-3, "backlash"},
      {&ServoParams::restitution, 1.01, "restitution"},    {&ServoParams::restitution, -0.01, "restitution"}};
  for (const Case& c : cases)
  {
    ServoParams p;
    p.*(c.field) = c.value;
    EXPECT_EQ(failingField(p), c.name) << c.name << " = " << c.value;
  }
  ServoParams rigid;
  rigid.backlash = 0.0;  // Δ = 0 is legal: the linear servo
  EXPECT_NO_THROW(rigid.validate());
}

TEST(Params, MessageGivesTheRange)
{
  ServoParams p;
  p.restitution = 2.0;
  try
  {
    p.validate();
    FAIL() << "no throw";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("[0, 1]"), std::string::npos) << e.what();
  }
}

TEST(Params, ChartFormRoundTrips)
{
  ChartParams ch;
  ch.zeta = 0.3;
  ch.natural_frequency = 7.0;
  ch.total_inertia = 2.5;
  ch.inertia_ratio = 4.0;
  ch.friction_ratio = 0.6;
  ch.gear_ratio = 3.0;
  const ServoParams p = ch.toServoParams();
  EXPECT_NEAR(p.dampingRatio(), 0.3, 1e-12);
  EXPECT_NEAR(p.naturalFrequency(), 7.0, 1e-12);
  EXPECT_NEAR(p.totalInertia(), 2.5, 1e-12);
  EXPECT_NEAR(p.inertiaRatio(), 4.0, 1e-12);
  EXPECT_NEAR(p.frictionRatio(), 0.6, 1e-12);
  EXPECT_DOUBLE_EQ(p.gear_ratio, 3.0);
  // Thesis App. D1 in chart form gives the published physical values.
  ChartParams d1;
  d1.zeta = 0.4;
  d1.inertia_ratio = 9.0;
  d1.friction_ratio = 0.4;
  const ServoParams q = d1.toServoParams();
  EXPECT_NEAR(q.motor_inertia, 0.1, 1e-12);
  EXPECT_NEAR(q.load_inertia, 0.9, 1e-12);
  EXPECT_NEAR(q.motor_friction, 0.48, 1e-12);
  EXPECT_NEAR(q.load_friction, 0.32, 1e-12);
  ChartParams bad = d1;
  bad.friction_ratio = 1.5;
  EXPECT_THROW(bad.toServoParams(), InvalidParameterError);
}

TEST(Params, ACompliantJointsDampingRatesStayWithinTheEnvelope)
{
  // D1 with resilient teeth: ω_n = 1 rad/s, μ = J_m J_L/(J_m + ρ²J_L) = 0.09 kg·m², so the contact's damping rate
  // d/μ reaches 1e5 ω_n at d = 9000 N·m·s/rad; a shaft between J_g = 0.1 and J_L = 0.9 kg·m² at d_s = 9000 too.
  ServoParams p;
  p.mesh_stiffness = 1e4;
  p.mesh_damping = 8000.0;
  EXPECT_NO_THROW(p.validate());
  p.mesh_damping = 1e6;  // a mistyped exponent: a contact damping ratio of 5e4
  EXPECT_EQ(failingField(p), "contact damping rate ratio (d/μ)/ω_n");
  try
  {
    p.validate();
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("mesh_damping 1000000"), std::string::npos) << e.what();
  }
  p.mesh_damping = 1.0;
  p.gear_inertia = 0.1;
  p.shaft_stiffness = 100.0;
  p.shaft_damping = 8000.0;
  EXPECT_NO_THROW(p.validate());
  p.shaft_damping = 1e5;
  EXPECT_EQ(failingField(p), "shaft damping rate ratio (d_s(J_g + J_L)/(J_g J_L))/ω_n");
}
