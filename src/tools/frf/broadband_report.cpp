#include "broadband_report.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/files/part_files.h"

namespace backlash_servo
{
namespace
{
std::string number(double v)
{
  return csvNumber(v);
}
}  // namespace

void writeBroadbandCsv(std::ostream& out, const std::vector<BroadbandEstimate>& estimates, bool linear)
{
  out << "amplitude,frequency,gain,phase,coherence,input_power" << (linear ? ",linear_gain,linear_phase" : "") << "\n";
  for (const BroadbandEstimate& e : estimates)
  {
    for (std::size_t i = 0; i < e.response.lines.size(); ++i)
    {
      const BroadbandLine& l = e.response.lines[i];
      out << number(e.amplitude) << "," << number(l.frequency) << "," << number(std::abs(l.h1)) << ","
          << number(std::arg(l.h1)) << "," << number(l.coherence) << "," << number(l.input_power);
      if (linear)
      {
        const bool has = e.has_linear && i < e.linear.lines.size();
        out << "," << (has ? number(std::abs(e.linear.lines[i].h1)) : "") << ","
            << (has ? number(std::arg(e.linear.lines[i].h1)) : "");
      }
      out << "\n";
    }
  }
}

void writeBroadbandJson(std::ostream& out, const std::string& channel, const std::string& excitation, double offset,
                        const std::vector<BroadbandEstimate>& estimates)
{
  std::ostringstream text;
  JsonWriter w(text);
  w.beginObject();
  w.field("channel", channel);
  w.field("excitation", excitation);
  w.field("offset", offset);
  w.field("sample_rate", estimates.empty() ? NAN : estimates.front().response.sample_rate);
  w.field("samples_per_period",
          estimates.empty() ? NAN : static_cast<double>(estimates.front().response.samples_per_period));
  w.field("settle_periods", estimates.empty() ? NAN : static_cast<double>(estimates.front().response.settle_periods));
  w.beginArray("estimates");
  for (const BroadbandEstimate& e : estimates)
  {
    w.beginObject();
    w.field("amplitude", e.amplitude);
    w.beginArray("lines");
    for (std::size_t i = 0; i < e.response.lines.size(); ++i)
    {
      const BroadbandLine& l = e.response.lines[i];
      w.beginObject();
      w.field("frequency", l.frequency);
      w.field("gain", std::abs(l.h1));
      w.field("phase", std::arg(l.h1));
      w.field("coherence", l.coherence);
      w.field("input_power", l.input_power);
      if (e.has_linear && i < e.linear.lines.size())
      {
        w.field("linear_gain", std::abs(e.linear.lines[i].h1));
        w.field("linear_phase", std::arg(e.linear.lines[i].h1));
      }
      w.endObject();
    }
    w.endArray();
    w.endObject();
  }
  w.endArray();
  w.endObject();
  out << text.str() << "\n";
}

void writeBroadbandText(std::ostream& out, const std::string& channel, const std::string& excitation,
                        const std::vector<BroadbandEstimate>& estimates, int rows)
{
  char buf[200];
  for (const BroadbandEstimate& e : estimates)
  {
    const std::vector<BroadbandLine>& lines = e.response.lines;
    std::snprintf(buf, sizeof buf,
                  "%s, %s of amplitude %g: %zu lines (%d samples a period at %g Hz, recorded after %d periods), H1 "
                  "and coherence\n",
                  channel.c_str(), excitation.c_str(), e.amplitude, lines.size(), e.response.samples_per_period,
                  e.response.sample_rate, e.response.settle_periods);
    out << buf;
    std::snprintf(buf, sizeof buf, "%12s %12s %12s %10s%s\n", "w [rad/s]", "gain", "phase", "coherence",
                  e.has_linear ? "  linear gain / phase" : "");
    out << buf;
    if (lines.empty())
    {
      continue;
    }
    // Rows spread evenly in log frequency (each line at most once).
    const double lo = std::log(lines.front().frequency), hi = std::log(lines.back().frequency);
    std::size_t last = lines.size();
    for (int r = 0; r < rows; ++r)
    {
      const double target = rows == 1 ? lo : lo + (hi - lo) * r / (rows - 1);
      std::size_t best = 0;
      for (std::size_t i = 1; i < lines.size(); ++i)
      {
        if (std::fabs(std::log(lines[i].frequency) - target) < std::fabs(std::log(lines[best].frequency) - target))
        {
          best = i;
        }
      }
      if (best == last)
      {
        continue;
      }
      last = best;
      const BroadbandLine& l = lines[best];
      std::snprintf(buf, sizeof buf, "%12.6g %12.6g %12.6g %10.4f", l.frequency, std::abs(l.h1), std::arg(l.h1),
                    l.coherence);
      out << buf;
      if (e.has_linear && best < e.linear.lines.size())
      {
        std::snprintf(buf, sizeof buf, "  %12.6g %12.6g", std::abs(e.linear.lines[best].h1),
                      std::arg(e.linear.lines[best].h1));
        out << buf;
      }
      out << "\n";
    }
  }
}

}  // namespace backlash_servo
