// Output files that never lie: streamed to "<path>.tmp" next to the target, every write checked, renamed over the
// target only when complete — and only when the target is absent or a regular file (never a device or a FIFO).
#pragma once

#include <fstream>
#include <string>

namespace backlash_servo
{
/// Throws ConfigError when path exists and is not a regular file ("--csv: '/dev/null' is a device …").
void requireRegularTarget(const std::string& flag, const std::string& path);

class OutputFile
{
 public:
  /// Opens "<path>.tmp"; throws ConfigError naming the flag when that fails or the target is not a regular file.
  OutputFile(const std::string& flag, const std::string& path);
  /// Removes the temporary unless commit() succeeded.
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  std::ofstream& stream() { return out_; }
  /// Flushes, closes and renames over the target; throws std::runtime_error when a write failed (disk full).
  void commit();

 private:
  std::string flag_;
  std::string path_;
  std::string tmp_;
  std::ofstream out_;
  bool committed_ = false;
};

/// Flushes stdout; throws std::runtime_error when writing it failed (closed pipe, /dev/full).
void flushStdout();

}  // namespace backlash_servo
