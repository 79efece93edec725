// Tolerance studies: parameters drawn from distributions (a batch of gearboxes), and what the batch does.
// A draw is a pure function of (seed, point index, key): any shard, resume or rerun of point i draws the same joint.
// Values are truncated to the key's range (parameter table) by redrawing. SI units as the keys'.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace backlash_servo
{
/// A key's distribution: uniform(a, b) on [a, b]; normal(μ, σ); lognormal(μ, σ) of the logarithm (the median is
/// e^μ); each truncated to the key's range.
struct Distribution
{
  enum class Kind
  {
    Uniform,
    Normal,
    LogNormal
  };
  std::string key;
  Kind kind = Kind::Uniform;
  double a = 0.0, b = 0.0;  ///< uniform: the ends; normal and lognormal: μ and σ

  /// "uniform(0.002,0.006)" as written.
  std::string text() const;
};

/// Whether `text` is a distribution ("uniform(…)", "normal(…)", "lognormal(…)") rather than a value or an axis.
bool isDistributionText(const std::string& text);
/// The distribution `text` of `key`; ConfigError naming the key and the text when it is malformed, its parameters are
/// not finite (σ ≤ 0, b < a) or a uniform reaches outside the key's range.
Distribution parseDistribution(const std::string& key, const std::string& text);

/// Point `index`'s value of d under `seed` (counter-based: independent of every other point and key). ConfigError
/// when 1000 draws in a row fall outside the key's range (a distribution mostly outside it).
double drawValue(const Distribution& d, std::uint64_t seed, std::size_t index);

/// One drawn key against the verdict: how well it tells hunting joints from settling ones.
struct KeyInfluence
{
  std::string key;
  /// Spearman's rank correlation of the key with "hunts" (1 for a limit cycle or an irregular oscillation, else 0)
  /// [-1, 1]; NaN when either is constant.
  double rank_correlation = 0.0;
  /// The best one-split rule "hunts when key > threshold" (or "<", `above` false): its threshold [the key's unit]
  /// and the fraction of joints it classifies right.
  double threshold = 0.0;
  bool above = true;
  double accuracy = 0.0;
};

/// What a batch does: the fraction of joints per verdict with a 95 % interval, the hunting joints' cycle sizes and
/// periods as quantiles, and which drawn key separates hunting from settling.
struct MonteCarloSummary
{
  std::size_t joints = 0;
  struct Share
  {
    std::string verdict;
    std::size_t count = 0;
    double fraction = 0.0, low = 0.0, high = 0.0;  ///< count / joints and its Wilson 95 % interval
  };
  std::vector<Share> verdicts;
  std::size_t hunting = 0;              ///< limit cycles and irregular oscillations
  std::size_t below_resolution = 0;     ///< hunting joints whose cycle spans less than one count of the loop's encoder
  std::vector<double> quantile_levels;  ///< 0.05, 0.25, 0.5, 0.75, 0.95
  std::vector<double> peak_to_peak_quantiles;  ///< of the hunting joints' peak to peak [rad]
  std::vector<double> period_quantiles;        ///< of their period [s]
  std::vector<KeyInfluence> influences;        ///< one per drawn key, strongest |rank correlation| first
};

/// The largest study whose rows are kept for its summary (about 200 bytes a row).
constexpr std::size_t MAX_SUMMARY_JOINTS = 1000000;

/// The summary of a sweep CSV's rows (header included) whose columns `drawn` were drawn.
MonteCarloSummary summarizeBatch(const std::string& csv, const std::vector<std::string>& drawn);
/// The summary as text, a line per figure.
std::string summaryText(const MonteCarloSummary& s);

}  // namespace backlash_servo
