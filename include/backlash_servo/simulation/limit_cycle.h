/**
 * @file limit_cycle.h
 * @brief Limit cycle or convergence? Decided on the Poincaré map of successive positive maxima of θ_c.
 *
 * Let \f$ x_n = \theta_{c,\max,n} - \theta_R > 0 \f$ be the successive positive errors. The map \f$ x_n \mapsto
 * x_{n+k} \f$ (k = 1, or the cycle's multiplicity when a cycle has several maxima) either has a fixed point
 * \f$ x^* > 0 \f$ (a limit cycle) or drives \f$ x_n \f$ to 0 (convergence). Aitken's Δ² extrapolation of the last
 * four same-phase maxima estimates \f$ x^* \f$ and the contraction ratio \f$ r = d_n/d_{n-1} \f$; the verdict is
 * settled only when the estimate is self-consistent (see docs/validation.md, "How the limit-cycle verdict is made"). No
 * ROS dependency.
 */
#pragma once

#include <cmath>
#include <vector>

namespace backlash_servo
{
/// A positive maximum of the load position.
struct Maximum
{
  double time = 0.0;      ///< [s]
  double position = 0.0;  ///< θ_c at the maximum [rad]
  double velocity = 0.0;  ///< ω_c just after the maximum [rad/s] (0, or negative after an impact)
};

enum class Verdict
{
  Undecided,   ///< not enough evidence yet
  LimitCycle,  ///< maxima settled to a fixed point above the command
  Irregular,   ///< sustained oscillation whose maxima never settle (quasi-periodic or chaotic), no decay
  Converged,   ///< maxima decay to the command (or stopped, with the servo at rest)
  Diverged     ///< the motion ran away (an unstable loop): set by runResponse when the plant stops it
};

const char* toString(Verdict v);

struct LimitCycleReport
{
  Verdict verdict = Verdict::Undecided;
  double error = 0.0;         ///< limit-cycle error: largest positive error θ_c,max − θ_R of the settled cycle
                              ///< (Aitken fixed point of each phase) [rad]; 0 if none
                              ///< (Irregular: largest error of the last IRREGULAR_WINDOW maxima)
  double period = 0.0;        ///< limit-cycle period [s]; 0 if none (Irregular: mean time between maxima)
  int multiplicity = 0;       ///< maxima per period of the cycle
  double extrapolated = 0.0;  ///< Aitken estimate of the fixed point x* [rad] (latest)
  /// LimitCycle of a sampled, quantised or stick–slip loop whose maxima wander in a narrow settled band instead of
  /// repeating (docs/model.md Part 2): error = the band's top, period = mean time between maxima.
  bool quasi_periodic = false;
  double band_low = 0.0;   ///< quasi-periodic: lowest error of the settled band [rad]
  double band_high = 0.0;  ///< quasi-periodic: highest error of the settled band [rad]
};

class LimitCycleDetector
{
 public:
  /**
   * @param command θ_R [rad]: reported errors are θ_c,max − θ_R (the thesis' limit-cycle error)
   * @param scale size [rad] below which errors count as zero (use max(Δ, |step|)); thresholds are fractions of it
   * @param centre the equilibrium [rad] the maxima are judged against (a load torque shifts it off θ_R); NaN: θ_R
   */
  LimitCycleDetector(double command, double scale, double centre = NAN);

  /// Records a maximum: kept for the verdict when above the centre, reported when above θ_R. Updates the status.
  void addMaximum(const Maximum& m);
  /// Tells the detector the servo is at rest on its command: settles a Converged verdict.
  void markAtRest();
  /// Tells the detector the joint can never move again (held by stiction under a constant torque): Converged,
  /// replacing any earlier verdict (maxima that looked periodic before it stuck were not a sustained oscillation).
  void markStuck();
  /// Whether a settled narrow band of maxima counts as a (quasi-periodic) limit cycle: on for sampled drives and dry
  /// friction (docs/model.md Part 2), off for the continuous thesis servo, whose wandering maxima stay Irregular.
  void allowBands(bool on) { bands_ = on; }
  /// Whether a steady geometric decay of the maxima onto the equilibrium settles a Converged verdict (the Poincaré
  /// map of a loop linear in each mode); off under dry friction, where a decay can stall into stick–slip hunting and
  /// only the state (markAtRest, markStuck) settles convergence.
  void extrapolateDecay(bool on) { extrapolate_decay_ = on; }
  /// Maxima closer than this [s] to the previous one are one hump (a load settling against a flank or by stiction
  /// under micro-bounces makes maxima 1e-7 s apart); the higher is kept. 0 (default): every maximum counts.
  void setMinimumSpacing(double seconds) { min_spacing_ = seconds; }

  /// The positive maxima θ_c,max > θ_R (what is reported: the thesis' maxima).
  const std::vector<Maximum>& maxima() const { return centre_ == command_ ? maxima_ : reported_; }
  /// The maxima above the centre, on which the verdict is judged (the same list when the centre is θ_R).
  const std::vector<Maximum>& judged() const { return maxima_; }
  const LimitCycleReport& status() const { return status_; }
  bool settled() const { return status_.verdict != Verdict::Undecided; }
  double command() const { return command_; }

  /// Relative precision to which a limit cycle's fixed point must be pinned before it is declared.
  static constexpr double FIXED_POINT_TOLERANCE = 1e-6;
  /// Fraction of the scale below which a maximum or a fixed point counts as zero.
  static constexpr double ZERO_FRACTION = 1e-7;
  /// Largest cycle multiplicity (maxima per period) looked for.
  static constexpr int MAX_MULTIPLICITY = 8;
  /// Quasi-periodic: two consecutive windows of this many maxima ...
  static constexpr int BAND_WINDOW = 10;
  /// ... each within this fraction of its mean error, the later one not shrinking (range ≥ half the earlier) and
  /// not monotone: a settled band, not a slow approach to a fixed point.
  static constexpr double BAND_FRACTION = 2e-2;
  /// Irregular: two consecutive windows of this many maxima show no decay.
  static constexpr int IRREGULAR_WINDOW = 30;

  /// True for verdicts that mean a sustained oscillation (LimitCycle, Irregular).
  bool oscillating() const;

 private:
  /// The verdict from the maxima so far, tried in turn: a pinned cycle, a geometric decay, a band, irregular.
  void update();
  // Each rule on the n maxima: true when it decided the verdict (reported errors are from θ_R: + offset [rad]).
  bool pinnedCycle(int n, double offset);
  bool geometricDecay(int n);
  bool quasiPeriodic(int n, double offset);
  void irregular(int n, double offset);
  /// Maximum i above the centre [rad].
  double deviation(int i) const;
  bool bands_ = false;
  bool extrapolate_decay_ = true;
  double min_spacing_ = 0.0;  // [s]

  double command_;
  double centre_;  // the equilibrium the maxima are judged against [rad]
  double scale_;
  std::vector<Maximum> maxima_;    // above the centre: judged
  std::vector<Maximum> reported_;  // above θ_R, when the centre differs
  LimitCycleReport status_;
  int decay_votes_ = 0;
};

}  // namespace backlash_servo
