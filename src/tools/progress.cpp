#include "progress.h"

#include <cstdio>
#include <string>

namespace backlash_servo
{
Progress::Progress(bool enabled, double delay)
    : enabled_(enabled), delay_(delay), start_(std::chrono::steady_clock::now()), last_draw_(start_)
{}

double Progress::elapsed() const
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::update(std::size_t done, std::size_t total)
{
  char counts[64];
  std::snprintf(counts, sizeof counts, " %zu/%zu", done, total);
  draw(total ? static_cast<double>(done) / total : 1.0, counts);
}

void Progress::update(double fraction)
{
  draw(fraction, "");
}

void Progress::draw(double f, const char* counts)
{
  if (!enabled_)
  {
    return;
  }
  const auto now = std::chrono::steady_clock::now();
  const double t = elapsed();
  // Quiet for short runs; at most 10 redraws a second.
  if (t < delay_ || (shown_ && std::chrono::duration<double>(now - last_draw_).count() < 0.1 && f < 1.0))
  {
    return;
  }
  last_draw_ = now;
  const int width = 30;
  f = f < 0.0 ? 0.0 : (f > 1.0 ? 1.0 : f);
  const int fill = static_cast<int>(f * width);
  const double eta = f > 0.0 ? t / f * (1.0 - f) : 0.0;
  std::fprintf(stderr, "\r[%s%s] %5.1f%%%s  %.1f s elapsed, ETA %.1f s ", std::string(fill, '#').c_str(),
               std::string(width - fill, '-').c_str(), 100.0 * f, counts, t, eta);
  std::fflush(stderr);
  shown_ = true;
}

void Progress::finish()
{
  if (shown_)
  {
    std::fprintf(stderr, "\n");
  }
}

}  // namespace backlash_servo
