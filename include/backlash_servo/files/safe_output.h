// The one way every tool writes a file: checked before any work, written to a private temporary file in the
// target's directory, synced and renamed over the target only when complete.
//
// Rules (the same for CSV, JSON, YAML, PNG/SVG and the checks made for bags):
//  * the target must be absent or a regular file: a device, FIFO, socket or directory is refused, and so is a
//    symbolic link (it is neither written through nor replaced: name the file itself);
//  * an output that is one of the run's inputs (same file, also through a hard or symbolic link) is refused;
//  * the temporary file is created with O_CREAT|O_EXCL|O_NOFOLLOW under a random name ".NAME.XXXXXX" in the
//    target's directory, so it never follows a planted link and never touches a user's own files; creating it is
//    also the up-front proof that the directory exists and is writable;
//  * commit() flushes, fsyncs and renames; a failed write (disk full) removes the temporary and the target is left
//    as it was; a target that another writer replaced or created while this run computed is not overwritten (this
//    run fails with a message, the other run's file stays whole);
//  * the temporary is removed by the destructor, by discard(), and on SIGINT/SIGTERM/SIGHUP when the program calls
//    removeTemporariesOnSignals().
#pragma once

#include <sys/types.h>

#include <ext/stdio_filebuf.h>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

namespace backlash_servo
{
/**
 * Checks an output path before any work is done; throws ConfigError naming `flag` and the path when the target is
 * a device, FIFO, socket, directory or symbolic link, when it is the same file as one of `inputs`, or when its
 * directory does not exist. Does not create anything.
 */
void checkOutputTarget(const std::string& flag, const std::string& path, const std::vector<std::string>& inputs = {});

/// True when `a` and `b` name the same existing file (device and inode; links followed).
bool sameFile(const std::string& a, const std::string& b);

class SafeOutput
{
 public:
  /// Checks the target (checkOutputTarget) and creates the temporary file; throws ConfigError naming `flag`.
  SafeOutput(const std::string& flag, const std::string& path, const std::vector<std::string>& inputs = {});
  /// Removes the temporary unless commit() succeeded.
  ~SafeOutput();
  SafeOutput(const SafeOutput&) = delete;
  SafeOutput& operator=(const SafeOutput&) = delete;

  std::ostream& stream() { return *stream_; }
  /// False once any write to stream() failed (disk full).
  bool good() const { return static_cast<bool>(*stream_); }
  /// Flushes the stream; false when a write failed.
  bool flush();
  /// Flushes, fsyncs, closes and renames over the target. Throws std::runtime_error (and removes the temporary)
  /// when a write failed or another writer replaced the target meanwhile.
  void commit();
  /// Removes the temporary; the target is untouched.
  void discard();
  const std::string& path() const { return path_; }
  const std::string& temporaryPath() const { return tmp_; }
  /// The flag it was opened for (for messages).
  const std::string& flag() const { return flag_; }

 private:
  std::string flag_;
  std::string path_;
  std::string tmp_;
  int fd_ = -1;
  std::unique_ptr<__gnu_cxx::stdio_filebuf<char>> buf_;
  std::unique_ptr<std::ostream> stream_;
  // What the target was when the run started, to notice another writer at commit().
  bool existed_ = false;
  dev_t dev_ = 0;
  ino_t ino_ = 0;
  long long mtime_ns_ = 0;
  long long size_ = 0;
  bool done_ = false;
};

/**
 * For writers that can only open a file by name (rosbag): checks `path` like SafeOutput, then creates
 * "PATH.active" exclusively (O_EXCL | O_NOFOLLOW) and returns its name. An existing PATH.active is refused — it is
 * what an interrupted recording left (`rosbag reindex` recovers it) and is never overwritten.
 */
std::string claimActiveFile(const std::string& flag, const std::string& path);

/// Renames PATH.active over PATH once written, after checking again that PATH is absent or a regular file.
/// Throws std::runtime_error (PATH.active is then kept, with its data) when that is no longer so.
void publishActiveFile(const std::string& flag, const std::string& path);

/**
 * Installs handlers for SIGINT, SIGTERM and SIGHUP that remove every SafeOutput temporary still open and then end
 * the program as the signal would have (exit status 128 + signal). For tools whose work cannot stop early.
 */
void removeTemporariesOnSignals();
/// A temporary file or directory of the program's own, removed on those signals too (a directory once the files
/// watched in it are gone); unwatchTemporary() when it is removed or kept.
void watchTemporary(const std::string& path);
void unwatchTemporary(const std::string& path);
/// A helper program this process waits for (0: none): on those signals it is ended, and waited for, before the
/// temporaries it may be writing are removed.
void watchChild(pid_t pid);

/// Flushes stdout; throws std::runtime_error when writing it failed (closed pipe, /dev/full).
void flushStdout();

/// Copies a finished file (a chart a helper script drew in a private directory) into `to` and commits it. Throws
/// std::runtime_error naming `to`'s flag when `from` is missing or the write fails.
void copyFileInto(const std::string& from, SafeOutput& to);

}  // namespace backlash_servo
