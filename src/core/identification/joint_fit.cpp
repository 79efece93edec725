#include "backlash_servo/identification/joint_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <variant>

#include "backlash_servo/identification/replay_windows.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
namespace
{
/// How a fitted key lives in the fit: its member and its bounds, both from the parameter table (param_table.h).
struct KeyInfo
{
  const char* key;
  double ServoParams::*member;
  enum Kind
  {
    Positive,  // inertias, the backlash, the mesh stiffness: > 0
    Level,     // friction coefficients and levels, the mesh damping: ≥ 0
    Free,      // the load torque
    Unit       // the restitution: [0, 1]
  } kind;
};

const std::vector<KeyInfo>& table()
{
  static const std::vector<KeyInfo> t = [] {
    std::vector<KeyInfo> out;
    for (const char* key :
         {"backlash", "motor_inertia", "load_inertia", "motor_friction", "load_friction", "motor_coulomb_friction",
          "load_coulomb_friction", "load_torque", "restitution", "mesh_stiffness", "mesh_damping"})
    {
      const ParamSpec* spec = findParam(key);
      const ParamRange& r = spec->range;
      const std::string k = key;
      KeyInfo info{key, std::get<double ServoParams::*>(spec->field), KeyInfo::Free};
      if (r.lower == 0.0 && r.upper == 1.0)
      {
        info.kind = KeyInfo::Unit;
      }
      else if (r.lower == 0.0)
      {
        // (Δ > 0: a fit needs the free play it measured; c > 0: c = 0 is rigid teeth, another model)
        info.kind = r.lower_open || k == "backlash" || k == "mesh_stiffness" || k.find("inertia") != std::string::npos
                        ? KeyInfo::Positive
                        : KeyInfo::Level;
      }
      out.push_back(info);
    }
    return out;
  }();
  return t;
}

double rmsOf(const std::vector<double>& v)
{
  double s = 0.0;
  for (double x : v)
  {
    s += x * x;
  }
  return std::sqrt(s / static_cast<double>(std::max<std::size_t>(1, v.size())));
}

/// The fit's coordinates: x_i = p_i / scale_i, each scale the start's size — for a level or the load torque at least
/// the data's typical size (5 % of the torques applied, per the typical motor speed for a viscous coefficient).
class Coordinates
{
 public:
  Coordinates(const ServoParams& start, const std::vector<const KeyInfo*>& keys, double torque_scale,
              double speed_scale)
      : start_(start), keys_(keys)
  {
    const double big = std::numeric_limits<double>::max() / 4.0;
    for (const KeyInfo* k : keys_)
    {
      const double q = start.*(k->member);
      const std::string key = k->key;
      // The data's typical size of a level: 5 % of the torques applied (per the typical motor speed for a viscous
      // coefficient).
      const double typical = key == "motor_friction" || key == "load_friction" || key == "mesh_damping"
                                 ? 0.05 * torque_scale / speed_scale
                                 : 0.05 * torque_scale;
      double scale = std::fabs(q);
      if (k->kind == KeyInfo::Level || k->kind == KeyInfo::Free)
      {
        scale = std::max(scale, typical);  // (a start near 0 says nothing of the size: a load torque of 1e-9 N·m)
      }
      else if (!(scale > 0.0))
      {
        scale = 1.0;  // (the restitution)
      }
      scale_.push_back(scale);
      switch (k->kind)
      {
        case KeyInfo::Positive:
          lower_.push_back(1e-6 * q / scale);
          upper_.push_back(1e6 * q / scale);
          break;
        case KeyInfo::Level:
          lower_.push_back(0.0);
          upper_.push_back(big);
          break;
        case KeyInfo::Free:
          lower_.push_back(-big);
          upper_.push_back(big);
          break;
        case KeyInfo::Unit:
          lower_.push_back(0.0);
          upper_.push_back(1.0 / scale);
          break;
      }
    }
  }

  std::vector<double> start() const
  {
    std::vector<double> x;
    for (std::size_t i = 0; i < keys_.size(); ++i)
    {
      x.push_back(std::min(std::max(start_.*(keys_[i]->member) / scale_[i], lower_[i]), upper_[i]));
    }
    return x;
  }

  /// The joint at x; the static friction levels (held) at least the Coulomb levels.
  ServoParams params(const double* x) const
  {
    ServoParams p = start_;
    for (std::size_t i = 0; i < keys_.size(); ++i)
    {
      p.*(keys_[i]->member) = x[i] * scale_[i];
    }
    return withEstimates(p, {});  // (static friction at least the Coulomb level)
  }

  const std::vector<double>& lower() const { return lower_; }
  const std::vector<double>& upper() const { return upper_; }
  const std::vector<double>& scale() const { return scale_; }

 private:
  ServoParams start_;
  std::vector<const KeyInfo*> keys_;
  std::vector<double> scale_, lower_, upper_;
};

/// The least-squares problem: x = (the m parameters, scaled; then ReplayWindows::CORRECTIONS anchor velocity
/// corrections per window, scaled by the typical speed). Residuals are laid out
/// window by window, 2·length each, so a correction's Jacobian column is non-zero in its own window only and costs
/// one window's replay.
class Shooting
{
 public:
  static constexpr std::size_t C = ReplayWindows::CORRECTIONS;

  Shooting(const ReplayWindows& replay, const Coordinates& coordinates, std::size_t m, double speed_scale,
           const JointFitSettings& settings, int evaluations)
      : replay_(replay),
        coordinates_(coordinates),
        m_(m),
        speed_scale_(speed_scale),
        settings_(settings),
        evaluations_(evaluations)
  {}

  std::size_t size() const { return m_ + C * replay_.starts().size(); }
  std::size_t parameters() const { return m_; }
  int evaluations() const { return evaluations_; }

  ServoParams params(const std::vector<double>& x) const { return coordinates_.params(x.data()); }
  std::vector<double> corrections(const std::vector<double>& x) const
  {
    std::vector<double> c(x.begin() + static_cast<long>(m_), x.end());
    for (double& v : c)
    {
      v *= speed_scale_;
    }
    return c;
  }

  /// The residuals at x [rad]; returns their sum of squares.
  double residuals(const std::vector<double>& x, Eigen::VectorXd* r)
  {
    const std::vector<double> c = corrections(x);
    replay_.residuals(params(x), &buffer_, false, &c);
    count(1);
    *r = Eigen::Map<const Eigen::VectorXd>(buffer_.data(), static_cast<Eigen::Index>(buffer_.size()));
    return r->squaredNorm();
  }

  /// The Jacobian at x (residuals r there) by differences with steps `relative`·max(|x_i|, 1): forward (inwards at an
  /// upper bound) or, `central`, central (one-sided at a bound).
  void jacobian(const std::vector<double>& x, const Eigen::VectorXd& r, double relative, bool central,
                Eigen::MatrixXd* jac)
  {
    const std::vector<double>& lower = coordinates_.lower();
    const std::vector<double>& upper = coordinates_.upper();
    jac->setZero(r.size(), static_cast<Eigen::Index>(size()));
    Eigen::VectorXd rp, rm;
    for (std::size_t i = 0; i < m_; ++i)
    {
      const double step = relative * std::max(std::fabs(x[i]), 1.0);
      std::vector<double> xp = x, xm = x;
      xp[i] = std::min(x[i] + step, upper[i]);
      xm[i] = central ? std::max(x[i] - step, lower[i]) : x[i];
      if (!central && xp[i] == x[i])
      {
        xp[i] = x[i] - step;
      }
      residuals(xp, &rp);
      if (central)
      {
        residuals(xm, &rm);
      }
      jac->col(static_cast<Eigen::Index>(i)) = ((central ? rp - rm : rp - r) / (xp[i] - xm[i]));
    }
    const std::size_t per = 2 * replay_.length();
    const ServoParams p = params(x);
    const std::vector<double> c = corrections(x);
    std::vector<double> minus;
    for (std::size_t w = 0; w < replay_.starts().size(); ++w)
    {
      const Eigen::Index rows = static_cast<Eigen::Index>(w * per), n = static_cast<Eigen::Index>(per);
      for (std::size_t j = 0; j < C; ++j)
      {
        const std::size_t i = m_ + C * w + j;
        const double step = relative * std::max(std::fabs(x[i]), 1.0);
        const auto window = [&](double dx, std::vector<double>* out) {
          double cw[C];
          std::copy(c.begin() + static_cast<long>(C * w), c.begin() + static_cast<long>(C * (w + 1)), cw);
          cw[j] += dx * speed_scale_;
          replay_.windowResiduals(p, w, cw, out);
        };
        window(step, &buffer_);
        const Eigen::Map<const Eigen::VectorXd> plus(buffer_.data(), n);
        if (central)
        {
          window(-step, &minus);
          jac->block(rows, static_cast<Eigen::Index>(i), n, 1) =
              (plus - Eigen::Map<const Eigen::VectorXd>(minus.data(), n)) / (2.0 * step);
        }
        else
        {
          jac->block(rows, static_cast<Eigen::Index>(i), n, 1) = (plus - r.segment(rows, n)) / step;
        }
      }
    }
    count(static_cast<int>(central ? 2 * C : C));  // (each correction: one window's replay)
  }

  /// x clamped into the bounds (the corrections have none).
  double clamp(std::size_t i, double v) const
  {
    return i < m_ ? std::min(std::max(v, coordinates_.lower()[i]), coordinates_.upper()[i]) : v;
  }

 private:
  void count(int n)
  {
    evaluations_ += n;
    if (settings_.progress)
    {
      settings_.progress(std::min(evaluations_, settings_.max_evaluations), settings_.max_evaluations);
    }
  }

  const ReplayWindows& replay_;
  const Coordinates& coordinates_;
  std::size_t m_;
  double speed_scale_;
  const JointFitSettings& settings_;
  std::vector<double> buffer_;
  int evaluations_;
};

/// Levenberg–Marquardt (Marquardt's scaling by diag JᵀJ; forward-difference Jacobian, steps 1e-4 of each
/// coordinate's size; bounds kept by clamping the step). Stops when a step improves the sum of squares by less than
/// 1e-8 of it or brings it below `floor`, or moves no coordinate by more than `tolerance`, when no damping finds a
/// better point, or when the budget of evaluations (whole replays) is spent — then returns true.
bool levenbergMarquardt(Shooting& f, std::vector<double>& x, int budget, double tolerance, double floor)
{
  const std::size_t n = x.size();
  Eigen::VectorXd r, rn;
  double cost = f.residuals(x, &r);
  double lambda = 1e-3;
  Eigen::MatrixXd jac;
  const int jacobian_cost = static_cast<int>(f.parameters() + Shooting::C);
  while (f.evaluations() + jacobian_cost <= budget)
  {
    f.jacobian(x, r, 1e-4, false, &jac);
    const Eigen::MatrixXd jtj = jac.transpose() * jac;
    const Eigen::VectorXd g = jac.transpose() * r;
    const Eigen::VectorXd d = jtj.diagonal().cwiseMax(1e-12 * std::max(jtj.diagonal().maxCoeff(), 1e-300));
    bool improved = false;
    while (f.evaluations() < budget && lambda < 1e12)
    {
      Eigen::MatrixXd a = jtj;
      a.diagonal() += lambda * d;
      const Eigen::VectorXd dx = a.ldlt().solve(-g);
      std::vector<double> xn = x;
      double moved = 0.0;
      for (std::size_t i = 0; i < n; ++i)
      {
        xn[i] = f.clamp(i, x[i] + dx(static_cast<Eigen::Index>(i)));
        moved = std::max(moved, std::fabs(xn[i] - x[i]));
      }
      if (moved <= tolerance)
      {
        return false;
      }
      const double next = f.residuals(xn, &rn);
      if (next < cost)
      {
        const bool small = cost - next <= 1e-8 * cost || next <= floor;
        x = xn;
        cost = next;
        r = rn;
        lambda = std::max(lambda / 3.0, 1e-9);
        improved = true;
        if (small)
        {
          return false;
        }
        break;
      }
      lambda *= 4.0;
    }
    if (!improved)
    {
      return f.evaluations() >= budget;
    }
  }
  return true;
}

}  // namespace

const std::vector<std::string>& jointFitKeys()
{
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const KeyInfo& i : table())
    {
      k.push_back(i.key);
    }
    return k;
  }();
  return keys;
}

std::vector<std::string> jointFitKeysFor(const ServoParams& joint)
{
  std::vector<std::string> keys;
  for (const std::string& key : jointFitKeys())
  {
    const bool mesh = key.rfind("mesh_", 0) == 0;
    if (key == "restitution" ? !joint.compliant() : !mesh || joint.compliant())
    {
      keys.push_back(key);
    }
  }
  return keys;
}

namespace
{
/// The keys to fit, each checked against the start (a key of the table, meaningful for this mesh, a positive one
/// starting > 0), with the settings.
std::vector<const KeyInfo*> fittedKeys(const ServoParams& start, const JointFitSettings& settings)
{
  if (start.torsionalShaft())
  {
    throw InvalidParameterError("shaft_stiffness",
                                "the joint fit replays from the measured motor and load; a torsional shaft's gear "
                                "is not measured (fit the joint without the shaft: shaft_stiffness 0)");
  }
  if (settings.keys.empty())
  {
    throw InvalidParameterError("fit", "names no parameter to fit");
  }
  if (!(settings.window > 0.0) || settings.windows < 1 || settings.max_evaluations < 1)
  {
    throw InvalidParameterError("window", "the windows (length > 0 s, at least one) and the budget must be positive");
  }
  start.validate();
  std::vector<const KeyInfo*> keys;
  for (const std::string& key : settings.keys)
  {
    const auto it = std::find_if(table().begin(), table().end(), [&key](const KeyInfo& k) { return key == k.key; });
    if (it == table().end())
    {
      throw InvalidParameterError("fit", "'" + key + "' is not a parameter the joint fit estimates");
    }
    const std::vector<std::string> meaningful = jointFitKeysFor(start);
    if (std::find(meaningful.begin(), meaningful.end(), key) == meaningful.end())
    {
      throw InvalidParameterError(key, start.compliant() ? "has no meaning for a compliant mesh (its damping sets the "
                                                           "losses of a contact)"
                                                         : "is fitted for a compliant mesh only (a start with "
                                                           "mesh_stiffness > 0)");
    }
    if (it->kind == KeyInfo::Positive && !(start.*(it->member) > 0.0))
    {
      throw InvalidParameterError(key, "must start > 0 to be fitted");
    }
    keys.push_back(&*it);
  }
  return keys;
}

/// The windows kept: those whose residual stays within TRIM times the median window's (an anchor read across an
/// impact, or on the wrong side of a flank within the band, would pull every parameter), with their unknowns in
/// `kept_x` (the parameters first).
std::vector<std::size_t> windowsWithinTrim(const Eigen::VectorXd& r0, const std::vector<std::size_t>& starts,
                                           std::size_t length, const std::vector<double>& x, std::size_t m,
                                           double residual_floor, std::vector<double>* kept_x)
{
  constexpr double TRIM = 5.0;
  const std::size_t per = 2 * length;
  std::vector<double> window_rms(starts.size());
  for (std::size_t w = 0; w < starts.size(); ++w)
  {
    window_rms[w] = r0.segment(static_cast<Eigen::Index>(w * per), static_cast<Eigen::Index>(per)).norm();
  }
  std::vector<double> sorted = window_rms;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
  const double limit = std::max(TRIM * sorted[sorted.size() / 2], residual_floor * std::sqrt(static_cast<double>(per)));
  std::vector<std::size_t> kept_starts;
  kept_x->assign(x.begin(), x.begin() + static_cast<long>(m));
  for (std::size_t w = 0; w < starts.size(); ++w)
  {
    if (window_rms[w] <= limit)
    {
      kept_starts.push_back(starts[w]);
      for (std::size_t j = 0; j < Shooting::C; ++j)
      {
        kept_x->push_back(x[m + Shooting::C * w + j]);
      }
    }
  }
  return kept_starts;
}

/// The cluster-robust covariance of everything fitted (windows as clusters, `per` residuals each); the parameters'
/// block, in the table's units, allows for the velocity corrections fitted with them. NaN where not informed.
Eigen::MatrixXd parameterCovariance(const Eigen::MatrixXd& jac, const Eigen::VectorXd& r0,
                                    const std::vector<Eigen::Index>& informed, const std::vector<Eigen::Index>& kept,
                                    std::size_t windows, Eigen::Index per, const Coordinates& coordinates,
                                    Eigen::Index cols, double* condition)
{
  Eigen::MatrixXd cov = Eigen::MatrixXd::Constant(cols, cols, NAN);
  if (!informed.empty())
  {
    const Eigen::MatrixXd jp = jac(Eigen::all, informed);
    const Eigen::VectorXd colnorm = jp.colwise().norm().transpose();
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(jp * colnorm.cwiseInverse().asDiagonal());
    const Eigen::VectorXd sv = svd.singularValues();
    *condition = sv(sv.size() - 1) > 0.0 ? sv(0) / sv(sv.size() - 1) : INFINITY;
    const Eigen::MatrixXd jk = jac(Eigen::all, kept);
    const Eigen::MatrixXd bread = (jk.transpose() * jk).completeOrthogonalDecomposition().pseudoInverse();
    Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(jk.cols(), jk.cols());
    for (Eigen::Index w = 0; w < static_cast<Eigen::Index>(windows); ++w)
    {
      const Eigen::VectorXd g = jk.middleRows(w * per, per).transpose() * r0.segment(w * per, per);
      meat += g * g.transpose();
    }
    Eigen::MatrixXd c = bread * meat * bread;
    c = 0.5 * (c + c.transpose()).eval();
    for (std::size_t a = 0; a < informed.size(); ++a)
    {
      for (std::size_t b = 0; b < informed.size(); ++b)
      {
        const std::size_t ia = static_cast<std::size_t>(informed[a]), ib = static_cast<std::size_t>(informed[b]);
        cov(informed[a], informed[b]) = c(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) *
                                        coordinates.scale()[ia] * coordinates.scale()[ib];
      }
    }
  }
  return cov;
}

/// Each fitted parameter with its standard error, and the correlations between the informed ones.
void reportParameters(const std::vector<const KeyInfo*>& keys, const ServoParams& start,
                      const std::vector<Eigen::Index>& informed, const Eigen::MatrixXd& cov, JointFit* fit)
{
  JointFit& out = *fit;
  const std::size_t m = keys.size();
  const Eigen::Index cols = static_cast<Eigen::Index>(m);
  out.correlation = Eigen::MatrixXd::Constant(cols, cols, NAN);
  for (std::size_t i = 0; i < m; ++i)
  {
    const Eigen::Index ii = static_cast<Eigen::Index>(i);
    FittedParameter f;
    f.key = keys[i]->key;
    f.start = start.*(keys[i]->member);
    f.value = out.params.*(keys[i]->member);
    f.informed = std::find(informed.begin(), informed.end(), ii) != informed.end();
    f.standard_error = f.informed ? std::sqrt(std::max(0.0, cov(ii, ii))) : NAN;
    out.parameters.push_back(f);
  }
  for (Eigen::Index i : informed)
  {
    FittedParameter& f = out.parameters[static_cast<std::size_t>(i)];
    for (Eigen::Index j : informed)
    {
      const double d = std::sqrt(cov(i, i) * cov(j, j));
      const double c = d > 0.0 ? cov(i, j) / d : (i == j ? 1.0 : 0.0);
      out.correlation(i, j) = c;
      if (i != j && std::fabs(c) > f.largest_correlation)
      {
        f.largest_correlation = std::fabs(c);
        f.most_correlated_with = out.parameters[static_cast<std::size_t>(j)].key;
      }
    }
  }
}
}  // namespace

JointFit fitJoint(const Recording& data, const IdentificationSettings& identification, double zero_offset,
                  const ServoParams& start, const JointFitSettings& settings)
{
  const std::vector<const KeyInfo*> keys = fittedKeys(start, settings);
  const std::size_t n = data.time.size();
  if (n < 50)
  {
    throw InvalidParameterError("data", "needs at least 50 samples");
  }
  const double h = (data.time.back() - data.time.front()) / static_cast<double>(n - 1);
  if (!(settings.window >= 2.0 * h))
  {
    // (a window of a sample or two replays nothing of the dynamics: its anchors, read from the angles, set the fit)
    throw InvalidParameterError("window", "must be at least two sample periods (2 × " + formatNumber(h) + " s); got " +
                                              formatNumber(settings.window) + " s");
  }
  const std::size_t length = std::max<std::size_t>(2, static_cast<std::size_t>(std::ceil(settings.window / h)));
  std::vector<std::size_t> starts = ReplayWindows::spread(n, length, static_cast<std::size_t>(settings.windows));
  auto replay = std::make_unique<ReplayWindows>(data, identification, zero_offset, starts, length);
  // Typical torque and motor speed (the scales of parameters that start at 0).
  std::vector<double> speed(n - 2);
  for (std::size_t k = 1; k + 1 < n; ++k)
  {
    speed[k - 1] = (data.motor_position[k + 1] - data.motor_position[k - 1]) / (2.0 * h);
  }
  const double torque_scale = std::max(rmsOf(data.motor_torque), 1e-300), speed_scale = std::max(rmsOf(speed), 1e-300);
  const Coordinates coordinates(start, keys, torque_scale, speed_scale);
  const std::size_t m = keys.size();

  auto shooting = std::make_unique<Shooting>(*replay, coordinates, m, speed_scale, settings, 0);
  std::vector<double> x = coordinates.start();
  x.resize(shooting->size(), 0.0);  // (the velocity corrections start at 0)
  JointFit out;
  Eigen::VectorXd r0;
  out.start_rms = std::sqrt(shooting->residuals(x, &r0) / static_cast<double>(r0.size()));
  const auto fit = [&](int budget) {
    return levenbergMarquardt(*shooting, x, budget, settings.tolerance,
                              std::pow(settings.residual_floor, 2) * static_cast<double>(r0.size()));
  };
  out.budget_exhausted = fit(settings.max_evaluations / 2);
  // Windows far beyond the median window's residual: fitted again without them.
  shooting->residuals(x, &r0);
  std::vector<double> kept_x;
  const std::vector<std::size_t> kept_starts =
      windowsWithinTrim(r0, starts, length, x, m, settings.residual_floor, &kept_x);
  if (kept_starts.size() < starts.size() && 2 * kept_starts.size() >= starts.size())
  {
    out.windows_dropped = starts.size() - kept_starts.size();
    starts = kept_starts;
    x = kept_x;
    const int spent = shooting->evaluations();
    replay = std::make_unique<ReplayWindows>(data, identification, zero_offset, starts, length);
    shooting = std::make_unique<Shooting>(*replay, coordinates, m, speed_scale, settings, spent);
    shooting->residuals(x, &r0);
  }
  out.budget_exhausted = fit(settings.max_evaluations);
  out.evaluations = shooting->evaluations();
  out.windows = starts.size();
  out.window_starts = starts;
  out.window_length = length;

  // The Jacobian at the fit by central differences (one-sided at a bound), in scaled coordinates.
  shooting->residuals(x, &r0);
  Eigen::MatrixXd jac;
  shooting->jacobian(x, r0, 1e-3, true, &jac);
  const Eigen::Index rows = r0.size(), cols = static_cast<Eigen::Index>(m);
  // Informed: a parameter's column not negligible beside the largest parameter column. One that is not keeps its
  // start (the search may have wandered along it freely).
  const Eigen::VectorXd norms = jac.leftCols(cols).colwise().norm().transpose();
  const double largest = norms.maxCoeff();
  std::vector<Eigen::Index> informed, kept;  // (kept: informed parameters, then every velocity correction)
  const std::vector<double> x0 = coordinates.start();
  for (Eigen::Index i = 0; i < cols; ++i)
  {
    if (norms(i) > 1e-9 * largest && norms(i) > 0.0)
    {
      informed.push_back(i);
    }
    else
    {
      x[static_cast<std::size_t>(i)] = x0[static_cast<std::size_t>(i)];
    }
  }
  kept = informed;
  for (Eigen::Index i = cols; i < jac.cols(); ++i)
  {
    kept.push_back(i);
  }
  out.params = shooting->params(x);
  out.anchor_corrections = shooting->corrections(x);
  shooting->residuals(x, &r0);
  out.residuals = static_cast<std::size_t>(rows);
  out.rms = std::sqrt(r0.squaredNorm() / static_cast<double>(rows));
  const Eigen::MatrixXd cov =
      parameterCovariance(jac, r0, informed, kept, out.windows, static_cast<Eigen::Index>(2 * replay->length()),
                          coordinates, cols, &out.condition);
  reportParameters(keys, start, informed, cov, &out);
  return out;
}

}  // namespace backlash_servo
