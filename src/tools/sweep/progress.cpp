#include "progress.h"

#include <cstdio>
#include <string>

namespace backlash_servo
{
Progress::Progress(bool enabled) : enabled_(enabled), start_(std::chrono::steady_clock::now()) {}

double Progress::elapsed() const
{
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::update(std::size_t done, std::size_t total)
{
  if (!enabled_)
  {
    return;
  }
  const int width = 30;
  const double f = total ? static_cast<double>(done) / total : 1.0;
  const int fill = static_cast<int>(f * width);
  const double t = elapsed();
  const double eta = done ? t / done * (total - done) : 0.0;
  std::fprintf(stderr, "\r[%s%s] %5.1f%% %zu/%zu  %.1f s elapsed, ETA %.1f s ", std::string(fill, '#').c_str(),
               std::string(width - fill, '-').c_str(), 100.0 * f, done, total, t, eta);
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
