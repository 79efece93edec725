#include "backlash_servo/model/drive_params.h"

#include "backlash_servo/model/params.h"

namespace backlash_servo
{
void DriveParams::validate(ControlMode mode) const
{
  if (control_law != "proportional" && control_law != "pid" && control_law != "cascade")
  {
    throw InvalidParameterError("control_law", "must be proportional, pid or cascade (got '" + control_law + "')");
  }
  if (feedback != "load" && feedback != "motor")
  {
    throw InvalidParameterError("feedback", "must be load or motor (got '" + feedback + "')");
  }
  if (sampled() && controller_rate < MIN_CONTROLLER_RATE)
  {
    // A sample every 1e300 s is no drive: it would hold its first torque for ever (and run away unchecked).
    throw InvalidParameterError("controller_rate", "must be 0 (the continuous law) or at least " +
                                                       formatNumber(MIN_CONTROLLER_RATE) + " Hz (got " +
                                                       formatNumber(controller_rate) + ")");
  }
  if (!sampled())
  {
    if (control_law != "proportional")
    {
      throw InvalidParameterError("control_law",
                                  control_law + " is a sampled law: it needs controller_rate > 0 Hz (got 0)");
    }
    if (feedback != "load")
    {
      throw InvalidParameterError("feedback",
                                  "the continuous law feeds back the load position (motor feedback needs "
                                  "controller_rate > 0 Hz)");
    }
    const bool drive_encoders =
        mode == ControlMode::Position && (motor_encoder_resolution > 0.0 || load_encoder_resolution > 0.0);
    if (drive_encoders || controller_delay > 0.0)
    {
      throw InvalidParameterError("controller_rate",
                                  "encoders and delay belong to a sampled drive: set controller_rate > 0 Hz");
    }
  }
  if (controller_delay != 0.0 && controller_delay != 1.0)
  {
    throw InvalidParameterError("controller_delay",
                                "must be 0 or 1 sample (got " + formatNumber(controller_delay) + ")");
  }
  const bool known = compensation == "none" || compensation == "inverse" || compensation == "dual_loop" ||
                     compensation == "friction_feedforward" || compensation == "dither";
  if (!known)
  {
    throw InvalidParameterError("compensation",
                                "must be none, inverse, dual_loop, friction_feedforward or dither "
                                "(got '" +
                                    compensation + "')");
  }
  if (dither_shape != "square" && dither_shape != "sine")
  {
    throw InvalidParameterError("dither_shape", "must be square or sine (got '" + dither_shape + "')");
  }
  if (!sampled() && (compensation == "inverse" || compensation == "dual_loop"))
  {
    throw InvalidParameterError("compensation", compensation +
                                                    " corrects a loop on the motor encoder: it needs a digital drive "
                                                    "(controller_rate > 0 Hz, feedback: motor)");
  }
  if (!sampled() && compensation == "dither" && dither_shape == "sine")
  {
    throw InvalidParameterError("dither_shape",
                                "the continuous law takes a square dither (piecewise-constant torque, exact); a sine "
                                "dither needs a digital drive (controller_rate > 0 Hz) that samples it");
  }
  if (!sampled() && compensation == "friction_feedforward" && !(compensation_width > 0.0))
  {
    throw InvalidParameterError("compensation_width",
                                "the continuous law's friction feed-forward needs a dead band w > 0 rad: a relay "
                                "switching at e = 0 chatters infinitely often near the set-point (a digital drive "
                                "switches at most once per sample)");
  }
  if ((compensation == "inverse" || compensation == "dual_loop") && feedback != "motor")
  {
    throw InvalidParameterError("compensation", compensation +
                                                    " corrects a loop on the motor encoder: set feedback: motor (a "
                                                    "load loop sees the backlash itself)");
  }
  if (compensation == "dither" && sampled() && dither_frequency > 0.5 * controller_rate)
  {
    throw InvalidParameterError("dither_frequency",
                                "must be <= controller_rate / 2 = " + formatNumber(0.5 * controller_rate) +
                                    " Hz (the drive samples the dither; got " + formatNumber(dither_frequency) + ")");
  }
  for (double n : {motor_encoder_resolution, load_encoder_resolution})
  {
    if (n != std::floor(n))
    {
      throw InvalidParameterError(
          n == motor_encoder_resolution ? "motor_encoder_resolution" : "load_encoder_resolution",
          "must be a whole number of counts per revolution (got " + formatNumber(n) + ")");
    }
  }
}
}  // namespace backlash_servo
