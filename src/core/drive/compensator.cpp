#include "backlash_servo/drive/compensator.h"

#include <algorithm>
#include <cmath>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/drive_params.h"

namespace backlash_servo
{
Compensator::Compensator(const DriveParams& d)
    : backlash_(d.compensation_backlash),
      width_(d.compensation_width),
      outer_gain_(d.outer_loop_gain),
      friction_(d.compensation_friction),
      amplitude_(d.dither_amplitude),
      frequency_(d.dither_frequency),
      square_(d.dither_shape != "sine")
{
  const std::string& c = d.compensation;
  kind_ = c == "inverse"                ? Kind::Inverse
          : c == "dual_loop"            ? Kind::DualLoop
          : c == "friction_feedforward" ? Kind::FrictionFeedforward
          : c == "dither"               ? Kind::Dither
                                        : Kind::None;
}

bool Compensator::retune(const DriveParams& drive)
{
  Compensator next(drive);
  if (next.kind_ != kind_)
  {
    return false;
  }
  next.started_ = started_;
  next.direction_ = direction_;
  next.last_reference_ = last_reference_;
  next.offset_ = offset_;
  *this = next;
  return true;
}

double Compensator::reference(double reference, double load_reading, double period)
{
  if (kind_ == Kind::DualLoop)
  {
    offset_ += outer_gain_ * period * (reference - load_reading);
    return reference + offset_;
  }
  if (kind_ != Kind::Inverse)
  {
    return reference;
  }
  if (!started_)
  {
    // The first commanded motion is from where the load stands towards the reference.
    direction_ = reference >= load_reading ? 1 : -1;
    offset_ = direction_ < 0 ? -backlash_ : 0.0;
  }
  else if (reference != last_reference_)
  {
    direction_ = reference > last_reference_ ? 1 : -1;
  }
  const double target = direction_ < 0 ? -backlash_ : 0.0;
  if (started_ && width_ > 0.0)
  {
    const double step = backlash_ * std::fabs(reference - last_reference_) / width_;
    offset_ += std::min(std::max(target - offset_, -step), step);
  }
  else
  {
    offset_ = target;
  }
  started_ = true;
  last_reference_ = reference;
  return reference + offset_;
}

double Compensator::torque(double torque, double error, double time) const
{
  if (kind_ == Kind::FrictionFeedforward)
  {
    if (std::fabs(error) <= width_ || error == 0.0)
    {
      return torque;
    }
    return torque + (error > 0.0 ? friction_ : -friction_);
  }
  if (kind_ == Kind::Dither)
  {
    const double s = std::sin(TWO_PI * frequency_ * time);
    return torque + amplitude_ * (square_ ? (s >= 0.0 ? 1.0 : -1.0) : s);
  }
  return torque;
}

}  // namespace backlash_servo
