#include "backlash_servo/identification/identify_joint.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <variant>

#include "backlash_servo/identification/measured_angles.h"
#include "backlash_servo/identification/replay_windows.h"
#include "backlash_servo/model/param_table.h"
#include "identification/identify_mesh.h"

namespace backlash_servo
{
namespace
{
/// Measured angles: the restitution's largest standard error for it to be reported [-].
constexpr double LOOSEST_RESTITUTION = 0.05;

/// The estimate of a parameter the replays need in `e` (backlash, motor_inertia … load_torque).
Estimate* bodyField(InitialEstimates* e, const std::string& key)
{
  return key == "backlash"                 ? &e->backlash
         : key == "motor_inertia"          ? &e->motor_inertia
         : key == "load_inertia"           ? &e->load_inertia
         : key == "motor_friction"         ? &e->motor_friction
         : key == "load_friction"          ? &e->load_friction
         : key == "motor_coulomb_friction" ? &e->motor_coulomb_friction
         : key == "load_coulomb_friction"  ? &e->load_coulomb_friction
                                           : &e->load_torque;
}

/// Why the recording does not inform `key` (empty: it does).
std::string notInformedReason(const std::string& key, const InitialEstimates& e, const std::string& restitution_note)
{
  if (const auto it = e.not_identifiable.find(key); it != e.not_identifiable.end())
  {
    return it->second;
  }
  if (key == "restitution" && !restitution_note.empty())
  {
    return restitution_note;
  }
  if (key == "load_torque" && e.load_torque_given)
  {
    return "the contact motion went one way only: the load torque is not told from the Coulomb friction";
  }
  if (key.find("static_friction") != std::string::npos)
  {
    const Estimate& x = key == "motor_static_friction" ? e.motor_static_friction : e.load_static_friction;
    if (!std::isfinite(x.value))
    {
      return key == "motor_static_friction" ? "the motor never rested with the teeth apart"
                                            : "the pair never rested on a flank (or the motor's level is unknown)";
    }
  }
  return "";
}

}  // namespace

const std::vector<std::string>& identifiedKeys()
{
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k = jointFitKeys();
    k.insert(k.begin() + 7, {"motor_static_friction", "load_static_friction"});
    return k;
  }();
  return keys;
}

std::vector<std::string> identifiedKeysFor(const ServoParams& joint)
{
  const std::vector<std::string> fittable = jointFitKeysFor(joint);
  std::vector<std::string> keys;
  for (const std::string& key : identifiedKeys())
  {
    if (key.find("static_friction") != std::string::npos ||
        std::find(fittable.begin(), fittable.end(), key) != fittable.end())
    {
      keys.push_back(key);
    }
  }
  return keys;
}

namespace
{
/// Whether the user's prior gives the key (every key when no statement is tracked).
bool statedInPrior(const IdentifyOptions& options, const std::string& key)
{
  return !options.stated || options.stated->count(key) != 0;
}

/// The prior's value of a key of the table [its unit].
double priorValue(const ServoParams& prior, const std::string& key)
{
  return prior.*std::get<double ServoParams::*>(findParam(key)->field);
}

/// The keys to identify: those asked for (all that describe the prior's joint when none), each checked.
std::set<std::string> keysToIdentify(const ServoParams& prior, const IdentifyOptions& options)
{
  const std::vector<std::string> meaningful = identifiedKeysFor(prior);
  std::set<std::string> keys = options.keys;
  if (keys.empty())
  {
    keys.insert(meaningful.begin(), meaningful.end());
  }
  for (const std::string& key : keys)
  {
    if (std::find(identifiedKeys().begin(), identifiedKeys().end(), key) == identifiedKeys().end())
    {
      throw InvalidParameterError("fit", "'" + key + "' is not estimated here");
    }
    if (std::find(meaningful.begin(), meaningful.end(), key) == meaningful.end())
    {
      throw InvalidParameterError("fit", "'" + key + "' does not describe this joint: " +
                                             (prior.compliant() ? "a compliant mesh has no restitution (its damping "
                                                                  "sets the losses of a contact)"
                                                                : "the mesh is fitted when the prior's mesh_stiffness "
                                                                  "is > 0 (a compliant mesh)"));
    }
  }
  return keys;
}

/// The bodies as the replays need them: estimated, or stated in the prior; the keys that are neither are named in
/// `unknown_bodies` (nothing to replay then: no restitution, no joint fit).
InitialEstimates replayedBodies(const InitialEstimates& e, const ServoParams& prior, const IdentifyOptions& options,
                                std::string* unknown_bodies_out)
{
  InitialEstimates bodies = e;
  std::string& unknown_bodies = *unknown_bodies_out;
  for (const char* key : {"backlash", "motor_inertia", "load_inertia", "motor_friction", "load_friction",
                          "motor_coulomb_friction", "load_coulomb_friction", "load_torque"})
  {
    Estimate& x = *bodyField(&bodies, key);
    if (std::isfinite(x.value) && e.not_identifiable.count(key) == 0)
    {
      continue;
    }
    if (statedInPrior(options, key))
    {
      x = {priorValue(prior, key), NAN};
      continue;
    }
    unknown_bodies += (unknown_bodies.empty() ? "" : ", ") + std::string(key);
  }
  return bodies;
}

/// Each key asked for: its initial estimate where the recording informs it (into `estimated` and `chosen`), or why
/// not with the prior's value if stated (into `unknown`).
void chooseEstimates(const std::set<std::string>& keys, const std::map<std::string, Estimate>& initial,
                     const InitialEstimates& e, const std::string& restitution_note, const ServoParams& prior,
                     const IdentifyOptions& options, std::vector<IdentifiedParameter>* estimated,
                     std::map<std::string, Estimate>* chosen, std::vector<IdentifiedParameter>* unknown)
{
  for (const std::string& key : identifiedKeys())
  {
    if (keys.count(key) == 0)
    {
      continue;
    }
    const auto x = initial.find(key);
    IdentifiedParameter p;
    p.key = key;
    std::string why = notInformedReason(key, e, restitution_note);
    if (why.empty() && x != initial.end() && std::isfinite(x->second.value))
    {
      // An estimate outside its key's range (a level below zero is zero within its scatter, see withEstimates) is
      // not what the data say of it.
      const ParamSpec& spec = *findParam(key);
      const double v = spec.range.lower == 0.0 ? std::max(0.0, x->second.value) : x->second.value;
      try
      {
        spec.check(v);
      }
      catch (const InvalidParameterError& outside)
      {
        why = "the estimate " + formatNumber(x->second.value) +
              " lies outside the key's range: the recording does "
              "not determine it";
      }
    }
    if (x == initial.end() || !std::isfinite(x->second.value) || !why.empty())
    {
      p.identifiable = false;
      p.reason = why.empty() ? "the recording does not inform it" : why;
      p.initial = p.value = Estimate{statedInPrior(options, key) ? priorValue(prior, key) : NAN, NAN};
      unknown->push_back(p);
      continue;
    }
    (*chosen)[key] = x->second;
    p.initial = p.value = x->second;
    estimated->push_back(p);
  }
}

/// The joint fit's keys (the static levels stay as the rests gave them). Auto: on measured angles only the impact
/// parameters — the replayed windows' anchors, read from the angles, would set the smooth ones more than the data.
JointFitSettings jointFitSettings(const IdentifyOptions& options, const IdentificationSettings& s,
                                  std::vector<IdentifiedParameter>* parameters,
                                  std::vector<IdentifiedParameter*>* fitted)
{
  const bool measured = s.contact_band > 0.0;
  JointFitSettings settings = options.fit;
  settings.keys.clear();
  for (IdentifiedParameter& p : *parameters)
  {
    const bool fittable = std::find(jointFitKeys().begin(), jointFitKeys().end(), p.key) != jointFitKeys().end();
    // (integrated equations: the backlash from where the gap dwells on each flank, which the replays' noisy
    // anchors would only blur)
    const bool impact =
        (p.key == "backlash" && !s.integrated) || p.key == "restitution" || p.key.rfind("mesh_", 0) == 0;
    if (fittable &&
        (options.joint == JointFitMode::On || (options.joint == JointFitMode::Auto && (!measured || impact))))
    {
      settings.keys.push_back(p.key);
      fitted->push_back(&p);
    }
  }
  return settings;
}

/// Measured angles: a restitution the replays pin down no better than ±LOOSEST_RESTITUTION is not a model.
void judgeRestitution(const IdentificationSettings& s, const ServoParams& prior, const IdentifyOptions& options,
                      std::vector<IdentifiedParameter>* parameters)
{
  for (IdentifiedParameter& p : *parameters)
  {
    if (p.key == "restitution" && s.integrated && !(p.value.standard_error <= LOOSEST_RESTITUTION))
    {
      p.identifiable = false;
      p.reason = "the replays around the impacts give " + formatNumber(p.value.value) + " ± " +
                 formatNumber(p.value.standard_error) + ", not within ±" + formatNumber(LOOSEST_RESTITUTION);
      p.value = {statedInPrior(options, p.key) ? prior.restitution : NAN, NAN};
    }
  }
}

/// Every key asked for, in the table's order: the unknown ones beside the estimated.
void inTableOrder(const std::vector<IdentifiedParameter>& unknown, std::vector<IdentifiedParameter>* parameters)
{
  parameters->insert(parameters->end(), unknown.begin(), unknown.end());
  const auto order = [](const IdentifiedParameter& p) {
    return std::find(identifiedKeys().begin(), identifiedKeys().end(), p.key) - identifiedKeys().begin();
  };
  std::stable_sort(
      parameters->begin(), parameters->end(),
      [&order](const IdentifiedParameter& a, const IdentifiedParameter& b) { return order(a) < order(b); });
}

}  // namespace

JointIdentification identifyJoint(const Recording& data, const IdentificationSettings& given, const ServoParams& prior,
                                  const IdentifyOptions& options)
{
  const std::set<std::string> keys = keysToIdentify(prior, options);
  if (prior.torsionalShaft())
  {
    throw InvalidParameterError("shaft_stiffness",
                                "a torsional shaft is not identified (its gear's angle is not "
                                "measured): give a prior without one (shaft_stiffness 0)");
  }
  JointIdentification out;
  // The angles as measured: the smoothing and the contact band from the data unless given.
  out.measurement = recogniseMeasurement(data, given);
  IdentificationSettings s = given;
  s.smoothing = out.measurement.smoothing;
  s.contact_band = out.measurement.contact_band;
  s.integrated = out.measurement.integrated;
  // An inertia stated in the prior and not fitted is known: it holds its column of the bodies' equations.
  for (const auto& [key, field, value] : {std::make_tuple("motor_inertia", &s.known_motor_inertia, prior.motor_inertia),
                                          std::make_tuple("load_inertia", &s.known_load_inertia, prior.load_inertia)})
  {
    if (statedInPrior(options, key) && keys.count(key) == 0)
    {
      *field = value;
    }
  }
  out.settings = s;
  const InitialEstimates& e = out.initial =
      prior.compliant() ? estimateCompliantInitial(data, s) : estimateInitial(data, s);
  std::map<std::string, Estimate> initial = e.byKey();
  // The bodies as the replays need them: estimated, or stated in the prior; a body's parameter that is neither leaves
  // nothing to replay (no restitution, no joint fit).
  std::string unknown_bodies;
  const InitialEstimates bodies = replayedBodies(e, prior, options, &unknown_bodies);
  // The restitution of rigid teeth: the simulator replayed over windows around impacts (none: not estimated, the
  // prior's kept).
  if (keys.count("restitution") && !unknown_bodies.empty())
  {
    out.restitution_note = "the replays around the impacts need the backlash and the bodies' parameters, and " +
                           unknown_bodies + (unknown_bodies.find(',') == std::string::npos ? " is" : " are") +
                           " not identified (nor given in the prior)";
  }
  else if (keys.count("restitution"))
  {
    try
    {
      initial["restitution"] = fitRestitution(data, s, bodies);
    }
    catch (const InvalidParameterError& none)
    {
      out.restitution_note = none.what();
    }
  }
  // The start: the prior with the initial estimates of the keys chosen (a static level without rests, a restitution
  // without impacts, a load torque the data could not tell from friction: the prior's).
  std::map<std::string, Estimate> chosen;
  std::vector<IdentifiedParameter> unknown;
  chooseEstimates(keys, initial, e, out.restitution_note, prior, options, &out.parameters, &chosen, &unknown);
  ServoParams start = withEstimates(prior, chosen);
  start.validateValues();
  if (options.stated && options.stated->count("gain") == 0)
  {
    start.gain = replayGain(start);
  }
  std::vector<IdentifiedParameter*> fitted;
  const JointFitSettings settings = jointFitSettings(options, s, &out.parameters, &fitted);
  out.model = start;
  // A model outside the validated envelope is reported, not refused; the simulator is not run on it (no joint fit).
  bool inside = true;
  try
  {
    // (only a model whose inertias are known: estimated or stated)
    if (unknown_bodies.find("inertia") == std::string::npos)
    {
      start.validateEnvelope(false);
    }
  }
  catch (const InvalidParameterError& outside)
  {
    out.warnings.push_back(std::string("the identified joint: ") + outside.what() +
                           (settings.keys.empty() ? "" : " — the joint fit (the simulator) was not run on it"));
    inside = false;
  }
  out.joint_fit = inside && unknown_bodies.empty() && !settings.keys.empty();
  if (out.joint_fit && s.integrated)
  {
    // Measured angles: a joint fit the simulator refuses (the model outside its envelope) leaves the estimates as
    // they are, with the reason.
    try
    {
      out.fit = fitJoint(data, s, e.zero_offset, start, settings);
    }
    catch (const InvalidParameterError& refused)
    {
      out.warnings.push_back(std::string("the joint fit did not run: ") + refused.what());
      out.joint_fit = false;
    }
  }
  else if (out.joint_fit)
  {
    out.fit = fitJoint(data, s, e.zero_offset, start, settings);
  }
  if (out.joint_fit)
  {
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
  judgeRestitution(s, prior, options, &out.parameters);
  inTableOrder(unknown, &out.parameters);
  return out;
}

}  // namespace backlash_servo
