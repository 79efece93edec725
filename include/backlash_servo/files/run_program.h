// Running a helper program without a shell, and private temporary directories that are cleaned up exactly.
#pragma once

#include <string>
#include <vector>

namespace backlash_servo
{
/**
 * Runs argv[0] with the arguments argv[1…] (posix_spawn: no shell, nothing is quoted or interpreted), its standard
 * output sent to this process's standard error. Returns its exit status; throws std::runtime_error when it could not
 * be started or was killed by a signal.
 */
int runProgram(const std::vector<std::string>& argv);

/**
 * Draws a chart: runs `/usr/bin/python3 script dir out` (runProgram: no shell) on the data the caller wrote to `dir`.
 * Throws std::runtime_error naming --png and the script when it fails.
 */
void runChartScript(const std::string& script, const std::string& dir, const std::string& out);

/**
 * The path of a helper file installed beside this executable (the package's bin directory, in the devel space and
 * after install). Throws std::runtime_error naming the expected path when it is not there.
 */
std::string helperBesideExecutable(const std::string& name);

/// Whether `path` names a PNG chart: it ends in ".png" after at least one character.
bool isPngPath(const std::string& path);

/**
 * A fresh private directory (mkdtemp under $TMPDIR or /tmp). The destructor removes the files that were named
 * through file() and then the directory itself — nothing else: a directory that still holds other files is left.
 */
class TemporaryDirectory
{
 public:
  /// Throws ConfigError when the directory cannot be created (never falls back to a shared directory).
  explicit TemporaryDirectory(const std::string& prefix);
  ~TemporaryDirectory();
  TemporaryDirectory(const TemporaryDirectory&) = delete;
  TemporaryDirectory& operator=(const TemporaryDirectory&) = delete;

  const std::string& path() const { return path_; }
  /// The path of `name` inside the directory, remembered for removal.
  std::string file(const std::string& name);

 private:
  std::string path_;
  std::vector<std::string> files_;
};

}  // namespace backlash_servo
