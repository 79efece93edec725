#include "backlash_servo/identify_joint.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <variant>

#include "backlash_servo/param_table.h"

namespace backlash_servo
{
const std::vector<std::string>& identifiedKeys()
{
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k = jointFitKeys();
    k.insert(k.begin() + 7, {"motor_static_friction", "load_static_friction"});
    return k;
  }();
  return keys;
}

JointIdentification identifyJoint(const Recording& data, const IdentificationSettings& s, const ServoParams& prior,
                                  const IdentifyOptions& options)
{
  std::set<std::string> keys = options.keys;
  if (keys.empty())
  {
    keys.insert(identifiedKeys().begin(), identifiedKeys().end());
  }
  for (const std::string& key : keys)
  {
    if (std::find(identifiedKeys().begin(), identifiedKeys().end(), key) == identifiedKeys().end())
    {
      throw InvalidParameterError("fit", "'" + key + "' is not estimated here");
    }
  }
  JointIdentification out;
  const InitialEstimates& e = out.initial = estimateInitial(data, s);
  // The restitution: the simulator replayed over windows around impacts (none: not estimated, the prior's kept).
  Estimate restitution{NAN, NAN};
  if (keys.count("restitution"))
  {
    try
    {
      restitution = fitRestitution(data, s, e);
    }
    catch (const InvalidParameterError& none)
    {
      out.restitution_note = none.what();
    }
  }
  const std::map<std::string, Estimate> initial = {{"backlash", e.backlash},
                                                   {"motor_inertia", e.motor_inertia},
                                                   {"load_inertia", e.load_inertia},
                                                   {"motor_friction", e.motor_friction},
                                                   {"load_friction", e.load_friction},
                                                   {"motor_coulomb_friction", e.motor_coulomb_friction},
                                                   {"load_coulomb_friction", e.load_coulomb_friction},
                                                   {"motor_static_friction", e.motor_static_friction},
                                                   {"load_static_friction", e.load_static_friction},
                                                   {"load_torque", e.load_torque},
                                                   {"restitution", restitution}};
  const auto member = [](const std::string& key) { return std::get<double ServoParams::*>(findParam(key)->field); };
  // The start: the prior with the initial estimates of the keys chosen (friction levels below zero are zero within
  // their scatter; static friction at least the Coulomb level).
  ServoParams start = prior;
  for (const std::string& key : identifiedKeys())
  {
    const Estimate& x = initial.at(key);
    if (keys.count(key) == 0 || (key == "load_torque" && e.load_torque_given) || !std::isfinite(x.value))
    {
      continue;  // the prior's value stays (a static level without rests, a restitution without impacts)
    }
    const bool level = key.find("friction") != std::string::npos;
    start.*member(key) = level ? std::max(0.0, x.value) : x.value;
    IdentifiedParameter p;
    p.key = key;
    p.initial = p.value = x;
    out.parameters.push_back(p);
  }
  start.motor_static_friction = std::max(start.motor_static_friction, start.motor_coulomb_friction);
  start.load_static_friction = std::max(start.load_static_friction, start.load_coulomb_friction);
  start.validate();
  // The joint fit (the static levels stay as the rests gave them). Auto: on measured angles only the impact
  // parameters — the replayed windows' anchors, read from the angles, would set the smooth ones more than the data.
  const bool measured = s.contact_band > 0.0;
  JointFitSettings settings = options.fit;
  settings.keys.clear();
  std::vector<IdentifiedParameter*> fitted;
  for (IdentifiedParameter& p : out.parameters)
  {
    const bool fittable = std::find(jointFitKeys().begin(), jointFitKeys().end(), p.key) != jointFitKeys().end();
    const bool impact = p.key == "backlash" || p.key == "restitution";
    if (fittable &&
        (options.joint == JointFitMode::On || (options.joint == JointFitMode::Auto && (!measured || impact))))
    {
      settings.keys.push_back(p.key);
      fitted.push_back(&p);
    }
  }
  out.model = start;
  out.joint_fit = !settings.keys.empty();
  if (out.joint_fit)
  {
    out.fit = fitJoint(data, s, e.zero_offset, start, settings);
    out.model = out.fit.params;
    for (std::size_t i = 0; i < fitted.size(); ++i)
    {
      const FittedParameter& f = out.fit.parameters[i];
      fitted[i]->value = {f.value, f.standard_error};
      fitted[i]->in_joint_fit = true;
      fitted[i]->informed = f.informed;
      fitted[i]->largest_correlation = f.largest_correlation;
      fitted[i]->most_correlated_with = f.most_correlated_with;
    }
  }
  return out;
}

}  // namespace backlash_servo
