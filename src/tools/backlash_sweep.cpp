// backlash_sweep: the thesis' parameter study (and finer ones) in parallel, one CSV row per point, resumable.
// See README, "backlash_sweep".
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>
#include <vector>

#include "sim_options.h"

using namespace backlash_servo;

namespace
{
const char* USAGE = R"(usage: backlash_sweep [axes] [--preset thesis] [--output FILE|-] [--jobs N] [--resume]
Runs every combination of the axes (chart form, w_n = 1 rad/s, J = 1 kg·m², rho = 1, unit step from rest in
forward contact), each until its limit-cycle verdict is settled, and writes one CSV row per point in a fixed order.

axes (a list "0.1,0.2,0.5", a range "start:stop:count", or "log:start:stop:count"):
  --zeta Z (0.4)  --inertia-ratio rho^2 J_L/J_m (9)  --friction-ratio rho^2 f_L/F_T (0.4)
  --restitution e (1)  --backlash D [rad] (0.3)
options:
  --preset thesis   the 1961 grid: zeta {.1,.2,.3,.4,.5,.6,.8,1}, friction {0,.2,.4,.6,.8,1},
                    inertia {0.04,0.1,1/9,0.25,1,4,9}, e {0,.6,.8,1}, backlash 0.3 (1344 points)
  --max-duration s  cap per point when the verdict does not settle (0 = 2000 s)
  --output FILE     CSV file, '-' = stdout (default)
  --jobs N          worker threads (default: all cores)
  --resume          keep the rows already in FILE and compute only the missing points
  --help
)";

const char* HEADER =
    "zeta,inertia_ratio,friction_ratio,restitution,backlash,verdict,limit_cycle,limit_cycle_error,period,impacts,"
    "simulated_time,settled";
constexpr int PARAM_COLUMNS = 5;
constexpr int COLUMNS = 12;

std::atomic<bool> g_interrupted{false};
void onSignal(int)
{
  g_interrupted = true;
}

std::vector<double> parseAxis(const std::string& flag, const std::string& text)
{
  KeyValues kv;
  auto num = [&](const std::string& s) {
    kv.set(flag, s);
    return kv.number(flag);
  };
  std::vector<std::string> parts;
  std::stringstream ss(text);
  std::string item;
  const char sep = text.find(':') != std::string::npos ? ':' : ',';
  while (std::getline(ss, item, sep))
  {
    parts.push_back(item);
  }
  std::vector<double> values;
  if (sep == ':')
  {
    const bool log = !parts.empty() && parts[0] == "log";
    if (log)
    {
      parts.erase(parts.begin());
    }
    if (parts.size() != 3)
    {
      throw UsageError("--" + flag + ": a range is start:stop:count or log:start:stop:count");
    }
    const double a = num(parts[0]), b = num(parts[1]), n = num(parts[2]);
    if (n < 1 || n != std::floor(n) || n > 1e6)
    {
      throw UsageError("--" + flag + ": count must be a whole number >= 1");
    }
    if (log && !(a > 0 && b > 0))
    {
      throw UsageError("--" + flag + ": log ranges need positive ends");
    }
    for (int i = 0; i < static_cast<int>(n); ++i)
    {
      const double f = n == 1 ? 0.0 : i / (n - 1);
      values.push_back(log ? a * std::pow(b / a, f) : a + (b - a) * f);
    }
  }
  else
  {
    for (const std::string& p : parts)
    {
      values.push_back(num(p));
    }
  }
  if (values.empty())
  {
    throw UsageError("--" + flag + ": no values");
  }
  return values;
}

struct Point
{
  double zeta, inertia_ratio, friction_ratio, restitution, backlash;
};

std::string key(const Point& p)
{
  char buf[160];
  std::snprintf(buf, sizeof buf, "%.10g,%.10g,%.10g,%.10g,%.10g", p.zeta, p.inertia_ratio, p.friction_ratio,
                p.restitution, p.backlash);
  return buf;
}

/// Physical parameters of a point (chart form, ω_n = 1 rad/s, J = 1 kg·m², ρ = 1); throws InvalidParameterError.
ServoParams paramsOf(const Point& p)
{
  ChartParams ch;
  ch.zeta = p.zeta;
  ch.inertia_ratio = p.inertia_ratio;
  ch.friction_ratio = p.friction_ratio;
  ch.restitution = p.restitution;
  ch.backlash = p.backlash;
  return ch.toServoParams();
}

std::string evaluate(const Point& p, double max_duration)
{
  RunConfig c;
  c.params = paramsOf(p);
  c.max_duration = max_duration;
  c.track_energy = false;  // verdicts only
  const RunSummary r = runResponse(c);
  const bool lc = r.status.verdict == Verdict::LimitCycle || r.status.verdict == Verdict::Irregular;
  char buf[400];
  std::snprintf(buf, sizeof buf, "%s,%s,%d,%.17g,%.17g,%llu,%.17g,%d", key(p).c_str(), toString(r.status.verdict),
                lc ? 1 : 0, lc ? r.status.error : 0.0, lc ? r.status.period : 0.0,
                static_cast<unsigned long long>(r.impacts), r.simulated, r.settled ? 1 : 0);
  return buf;
}

void progress(std::size_t done, std::size_t total, double elapsed)
{
  const int width = 30;
  const double f = total ? static_cast<double>(done) / total : 1.0;
  const int fill = static_cast<int>(f * width);
  const double eta = done ? elapsed / done * (total - done) : 0.0;
  std::fprintf(stderr, "\r[%s%s] %5.1f%% %zu/%zu  %.1f s elapsed, ETA %.1f s ", std::string(fill, '#').c_str(),
               std::string(width - fill, '-').c_str(), 100.0 * f, done, total, elapsed, eta);
  std::fflush(stderr);
}
}  // namespace

int main(int argc, char** argv)
{
  std::vector<double> axes[5] = {{0.4}, {9.0}, {0.4}, {1.0}, {0.3}};
  const char* names[5] = {"zeta", "inertia-ratio", "friction-ratio", "restitution", "backlash"};
  std::string output = "-";
  int jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  bool resume = false;
  double max_duration = 0.0;
  try
  {
    for (int i = 1; i < argc; ++i)
    {
      const std::string arg = argv[i];
      if (arg == "--help" || arg == "-h")
      {
        std::cout << USAGE;
        return 0;
      }
      if (arg == "--resume")
      {
        resume = true;
        continue;
      }
      if (arg == "--preset")
      {
        if (i + 1 >= argc || std::string(argv[i + 1]) != "thesis")
        {
          throw UsageError("--preset: the only preset is 'thesis'");
        }
        ++i;
        axes[0] = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0};
        axes[1] = {0.04, 0.1, 1.0 / 9.0, 0.25, 1.0, 4.0, 9.0};
        axes[2] = {0.0, 0.2, 0.4, 0.6, 0.8, 1.0};
        axes[3] = {0.0, 0.6, 0.8, 1.0};
        axes[4] = {0.3};
        continue;
      }
      if (arg.rfind("--", 0) != 0 || i + 1 >= argc)
      {
        throw UsageError("unexpected argument '" + arg + "' (see --help)");
      }
      const std::string value = argv[++i];
      const std::string flag = arg.substr(2);
      const auto axis = std::find(names, names + 5, flag);
      if (axis != names + 5)
      {
        axes[axis - names] = parseAxis(flag, value);
      }
      else if (flag == "output")
      {
        output = value;
      }
      else if (flag == "jobs")
      {
        jobs = static_cast<int>(parseAxis(flag, value).front());
        if (jobs < 1)
        {
          throw UsageError("--jobs must be >= 1");
        }
      }
      else if (flag == "max-duration")
      {
        max_duration = parseAxis(flag, value).front();
      }
      else
      {
        throw UsageError("unknown option " + arg + " (see --help)");
      }
    }
    if (resume && output == "-")
    {
      throw UsageError("--resume needs --output FILE");
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_sweep: error: " << e.what() << "\n";
    return 2;
  }

  std::vector<Point> points;
  for (double z : axes[0])
    for (double ir : axes[1])
      for (double fr : axes[2])
        for (double e : axes[3])
          for (double d : axes[4])
          {
            points.push_back({z, ir, fr, e, d});
          }
  // Validate every point before any output (one clear line on the first bad one).
  for (const Point& p : points)
  {
    try
    {
      paramsOf(p);
    }
    catch (const std::exception& e)
    {
      std::cerr << "backlash_sweep: error: " << e.what() << "\n";
      return 2;
    }
  }

  // Resume: keep complete rows (the file is always an in-order prefix), drop a torn last line.
  std::set<std::string> done_keys;
  std::vector<std::string> kept;
  if (resume)
  {
    std::ifstream in(output);
    std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::stringstream ss(content);
    std::string line;
    bool first = true;
    while (std::getline(ss, line))
    {
      const bool complete = ss.good() || (!content.empty() && content.back() == '\n');
      if (first)
      {
        first = false;
        if (line != HEADER)
        {
          std::cerr << "backlash_sweep: error: '" << output << "' is not a backlash_sweep CSV (header differs)\n";
          return 2;
        }
        continue;
      }
      if (!complete || std::count(line.begin(), line.end(), ',') != COLUMNS - 1)
      {
        break;
      }
      std::string k = line;
      std::size_t pos = 0;
      for (int c = 0; c < PARAM_COLUMNS; ++c)
      {
        pos = k.find(',', pos) + 1;
      }
      done_keys.insert(k.substr(0, pos - 1));
      kept.push_back(line);
    }
  }
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < points.size(); ++i)
  {
    if (!done_keys.count(key(points[i])))
    {
      todo.push_back(i);
    }
  }

  std::ofstream file;
  std::ostream* out = &std::cout;
  if (output != "-")
  {
    file.open(output, std::ios::trunc);
    if (!file)
    {
      std::cerr << "backlash_sweep: error: cannot write '" << output << "'\n";
      return 2;
    }
    out = &file;
  }
  *out << HEADER << "\n";
  for (const std::string& line : kept)
  {
    *out << line << "\n";
  }
  out->flush();

  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  const bool show_progress = isatty(2) && output != "-";
  std::vector<std::string> rows(todo.size());
  std::vector<char> ready(todo.size(), 0);
  std::atomic<std::size_t> next{0};
  std::mutex mutex;
  std::size_t written = 0, finished = 0;
  std::string failure;
  const auto start = std::chrono::steady_clock::now();
  auto worker = [&]() {
    for (;;)
    {
      const std::size_t i = next++;
      if (i >= todo.size() || g_interrupted)
      {
        return;
      }
      std::string row;
      try
      {
        row = evaluate(points[todo[i]], max_duration);
      }
      catch (const std::exception& e)
      {
        std::lock_guard<std::mutex> lock(mutex);
        failure = key(points[todo[i]]) + ": " + e.what();
        g_interrupted = true;
        return;
      }
      std::lock_guard<std::mutex> lock(mutex);
      rows[i] = std::move(row);
      ready[i] = 1;
      ++finished;
      // Deterministic order: write the completed prefix.
      while (written < todo.size() && ready[written])
      {
        *out << rows[written] << "\n";
        rows[written].clear();
        ++written;
      }
      out->flush();
      if (show_progress)
      {
        progress(kept.size() + finished, points.size(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      }
    }
  };
  std::vector<std::thread> threads;
  for (int j = 0; j < std::min<int>(jobs, std::max<std::size_t>(1, todo.size())); ++j)
  {
    threads.emplace_back(worker);
  }
  for (auto& t : threads)
  {
    t.join();
  }
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (show_progress)
  {
    std::fprintf(stderr, "\n");
  }
  if (!failure.empty())
  {
    std::cerr << "backlash_sweep: error at point " << failure << "\n";
    return 1;
  }
  if (g_interrupted)
  {
    std::cerr << "backlash_sweep: interrupted: " << kept.size() + written << " of " << points.size()
              << " points written; rerun with --resume to finish\n";
    return 130;
  }
  std::fprintf(stderr, "backlash_sweep: %zu points (%zu computed) in %.3f s wall with %d jobs\n", points.size(),
               todo.size(), elapsed, jobs);
  return 0;
}
