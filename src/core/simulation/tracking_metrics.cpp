#include "backlash_servo/simulation/tracking_metrics.h"

#include <algorithm>

namespace backlash_servo
{
TrackingMetrics::TrackingMetrics(double band, double reference_end, double final_reference, double direction)
    : band_(band), reference_end_(reference_end), final_reference_(final_reference), direction_(direction)
{}

void TrackingMetrics::add(double time, double reference, double load_position, double motor_torque)
{
  const double e = reference - load_position;
  sum_e2_ += e * e;
  sum_t2_ += motor_torque * motor_torque;
  peak_torque_ = std::max(peak_torque_, std::fabs(motor_torque));
  ++count_;
  if (time >= reference_end_)
  {
    max_after_ = std::max(max_after_, std::fabs(e));
    overshoot_ = std::max(overshoot_, direction_ * (load_position - final_reference_));
    if (std::fabs(e) > band_)
    {
      last_outside_ = time;
      since_sum_ = 0.0;
      since_count_ = 0;
    }
    since_sum_ += e * e;
    ++since_count_;
    if (std::isnan(first_after_))
    {
      first_after_ = time;
    }
    last_time_ = time;
    if (!after_.empty() && after_.back().count < entry_size_)
    {
      after_.back().sum += e * e;
      ++after_.back().count;
    }
    else
    {
      if (after_.size() == MAX_ENTRIES)
      {
        for (std::size_t i = 0; i < MAX_ENTRIES / 2; ++i)
        {
          const Entry& a = after_[2 * i];
          const Entry& b = after_[2 * i + 1];
          after_[i] = {a.time, a.sum + b.sum, a.count + b.count};
        }
        after_.resize(MAX_ENTRIES / 2);
        entry_size_ *= 2;
      }
      after_.push_back({time, e * e, 1});
    }
  }
}

TrackingFigures TrackingMetrics::figures(double end_time, double dt, bool leaves_band) const
{
  TrackingFigures f;
  f.band = band_;
  if (count_ > 0)
  {
    f.rms_error = std::sqrt(sum_e2_ / count_);
    f.rms_torque = std::sqrt(sum_t2_ / count_);
    f.peak_torque = peak_torque_;
    f.max_error = max_after_;
    f.overshoot = overshoot_;
  }
  // Settled: inside the band from some time on (never left it at the end of the run).
  f.settling_time = std::isnan(last_outside_) ? reference_end_ : last_outside_;
  if (!std::isnan(last_outside_) && (leaves_band || last_outside_ >= end_time - 1.5 * dt))
  {
    f.settling_time = NAN;  // still outside at the end
  }
  if (!std::isnan(f.settling_time))
  {
    f.steady_rms_error = since_count_ > 0 ? std::sqrt(since_sum_ / since_count_) : NAN;
  }
  else if (!after_.empty())
  {
    const double from = first_after_ + 0.5 * (last_time_ - first_after_);
    double sum = 0.0;
    long k = 0;
    for (const Entry& x : after_)
    {
      if (x.time >= from)
      {
        sum += x.sum;
        k += x.count;
      }
    }
    f.steady_rms_error = k > 0 ? std::sqrt(sum / k) : NAN;
  }
  return f;
}

}  // namespace backlash_servo
