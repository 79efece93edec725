#include "backlash_servo/identification/experiment_design.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "backlash_servo/identification/identification.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
namespace
{
/// The most samples the check simulates and holds (640 MB).
constexpr double MAX_CHECKED_SAMPLES = 2e7;

/// The travels tried when growing: 3Δ doubled up to the largest allowed (at most 48Δ unless given).
std::vector<double> travelsToTry(const ServoParams& params, const ExperimentRequest& request)
{
  if (request.travel > 0.0)
  {
    return {request.travel};
  }
  const double largest =
      std::min(request.max_travel > 0.0 ? request.max_travel : 48.0 * params.backlash, param("command").range.upper);
  std::vector<double> out;
  for (double travel = 3.0 * params.backlash; travel <= largest * (1.0 + 1e-12); travel *= 2.0)
  {
    out.push_back(travel);
  }
  return out.empty() ? std::vector<double>{3.0 * params.backlash} : out;
}

/// The experiment run on the prior's joint, recorded as the identification reads it: at the drive's rate (1 kHz for
/// the continuous law) the torque applied from each sample to the next and both angles exactly.
Recording simulatedRecording(const RunConfig& prior, const std::vector<ProfileSegment>& segments, double duration,
                             std::uint64_t* impacts)
{
  RunConfig config = prior;
  config.profile = std::make_shared<CommandProfile>(prior.initial.load_position, segments);
  Simulator sim = makeSimulator(config);
  const double rate = prior.drive.sampled() ? prior.drive.controller_rate : 1000.0;
  // (the check holds the run in memory: 32 bytes a sample)
  requireThat(duration * rate <= MAX_CHECKED_SAMPLES, "duration",
              formatNumber(duration) + " s at " + formatNumber(rate) + " Hz is " + formatNumber(duration * rate) +
                  " samples; the check on the prior's joint simulates at most " + formatNumber(MAX_CHECKED_SAMPLES) +
                  " (give a shorter --duration)");
  const auto n = static_cast<std::size_t>(std::floor(duration * rate)) + 1;
  Recording out;
  for (std::size_t k = 0; k < n; ++k)
  {
    const double t = prior.initial.time + static_cast<double>(k) / rate;
    sim.advanceTo(t);
    sim.takeSampleDue();  // (the torque applied from t on, as a drive logs it)
    const State s = sim.state();
    out.time.push_back(t);
    out.motor_torque.push_back(sim.motorTorque());
    out.motor_position.push_back(s.motor_position);
    out.load_position.push_back(s.load_position);
  }
  *impacts = sim.impactCount();
  return out;
}

/// How far each body parameter the run gives back lies from the prior's value (relative; a level relative to the
/// larger of itself and 1 % of the peak torque on its shaft); keys not within `tolerance` into `uninformed`.
void compareWithPrior(const ServoParams& p, const InitialEstimates& e, double peak_torque, double tolerance,
                      CheckedExperiment* out)
{
  const std::map<std::string, Estimate> estimates = e.byKey();
  const double rho = p.gear_ratio;
  const std::vector<std::pair<std::string, double>> checked = {{"backlash", p.backlash},
                                                               {"motor_inertia", p.motor_inertia},
                                                               {"load_inertia", p.load_inertia},
                                                               {"motor_friction", p.motor_friction},
                                                               {"load_friction", p.load_friction},
                                                               {"motor_coulomb_friction", p.motor_coulomb_friction},
                                                               {"load_coulomb_friction", p.load_coulomb_friction},
                                                               {"load_torque", p.load_torque}};
  for (const auto& [key, truth] : checked)
  {
    const bool level = key.find("coulomb") != std::string::npos || key == "load_torque";
    if (!level && truth == 0.0)
    {
      continue;  // (nothing to give back)
    }
    const double shaft_peak = key.rfind("load", 0) == 0 ? peak_torque / rho : peak_torque;
    const double scale = level ? std::max(std::fabs(truth), 0.01 * shaft_peak) : std::fabs(truth);
    const auto x = estimates.find(key);
    const double value = x == estimates.end() ? NAN : x->second.value;
    const double error = std::fabs(value - truth) / scale;
    out->errors[key] = error;
    if (e.not_identifiable.count(key))
    {
      out->uninformed[key] = e.not_identifiable.at(key);
    }
    else if (!(error <= tolerance))
    {
      out->uninformed[key] = "given back as " + formatNumber(value) + " for " + formatNumber(truth);
    }
  }
}

/// One travel: the experiment, its run on the prior's joint and what that run gives back.
CheckedExperiment checkTravel(const RunConfig& prior, const ExperimentRequest& request, double travel)
{
  CheckedExperiment out;
  out.travel = travel;
  out.segments = identificationExperiment(prior.params, request.duration, travel, request.dither_amplitude,
                                          request.dither_frequency);
  const Recording run = simulatedRecording(prior, out.segments, request.duration, &out.impacts);
  double peak = 0.0;
  for (double u : run.motor_torque)
  {
    peak = std::max(peak, std::fabs(u));
  }
  IdentificationSettings settings;
  settings.gear_ratio = prior.params.gear_ratio;
  settings.load_torque_fallback = prior.params.load_torque;
  try
  {
    compareWithPrior(prior.params, estimateInitial(run, settings), peak, request.tolerance, &out);
  }
  catch (const InvalidParameterError& none)
  {
    out.uninformed["backlash"] = std::string("nothing estimated: ") + none.what();
  }
  return out;
}

}  // namespace

CheckedExperiment designExperiment(const RunConfig& prior, const ExperimentRequest& request,
                                   const std::function<void(const std::string&)>& progress)
{
  // (the request's own checks first: a rigid-teeth prior, a duration or dither out of range)
  identificationExperiment(prior.params, request.duration,
                           request.travel > 0.0 ? request.travel : 3.0 * prior.params.backlash,
                           request.dither_amplitude, request.dither_frequency);
  CheckedExperiment best;
  bool first = true;
  std::vector<double> tried;
  for (double travel : travelsToTry(prior.params, request))
  {
    CheckedExperiment c = checkTravel(prior, request, travel);
    tried.push_back(travel);
    if (progress)
    {
      char figure[32];
      std::snprintf(figure, sizeof figure, "%.6g", travel);
      std::string line = "travel " + std::string(figure) + " rad: " + std::to_string(c.impacts) + " impacts, ";
      const std::size_t missed = c.uninformed.size();
      line += missed == 0 ? "every key given back"
                          : std::to_string(missed) + (missed == 1 ? " key" : " keys") + " not given back";
      progress(line);
    }
    // (the first that informs every key; else the one that leaves the fewest uninformed, the larger travel on a tie)
    if (first || c.uninformed.size() <= best.uninformed.size())
    {
      best = c;
      first = false;
    }
    if (c.uninformed.empty())
    {
      break;
    }
  }
  best.travels_tried = tried;
  return best;
}

}  // namespace backlash_servo
