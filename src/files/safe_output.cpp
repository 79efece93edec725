#include "backlash_servo/files/safe_output.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <stdexcept>

#include "backlash_servo/config/key_values.h"

namespace backlash_servo
{
namespace
{
// ---- temporaries removed on a signal (async-signal-safe: fixed storage, unlink only) ---------------------------
constexpr int kSlots = 64;
constexpr int kPathMax = 4096;
char g_tmp_paths[kSlots][kPathMax];
std::atomic<bool> g_tmp_used[kSlots];
std::atomic<pid_t> g_child{0};  // a helper program running (watchChild): ended first, it may still be writing

int registerTemporary(const std::string& path)
{
  if (path.size() >= kPathMax)
  {
    return -1;
  }
  for (int i = 0; i < kSlots; ++i)
  {
    if (!g_tmp_used[i].load())
    {
      std::memcpy(g_tmp_paths[i], path.c_str(), path.size() + 1);
      g_tmp_used[i].store(true);
      return i;
    }
  }
  return -1;
}

void unregisterTemporary(const std::string& path)
{
  for (int i = 0; i < kSlots; ++i)
  {
    if (g_tmp_used[i].load() && path == g_tmp_paths[i])
    {
      g_tmp_used[i].store(false);
      return;
    }
  }
}

extern "C" void removeTemporariesAndDie(int sig)
{
  const pid_t child = g_child.load();
  if (child > 0)
  {
    ::kill(child, SIGTERM);
    ::waitpid(child, nullptr, 0);
  }
  // Files first, then the (then empty) temporary directories: unlink fails on a directory, rmdir on a file.
  for (int i = 0; i < kSlots; ++i)
  {
    if (g_tmp_used[i].load())
    {
      ::unlink(g_tmp_paths[i]);
    }
  }
  for (int i = kSlots - 1; i >= 0; --i)
  {
    if (g_tmp_used[i].load())
    {
      ::rmdir(g_tmp_paths[i]);
    }
  }
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

std::string directoryOf(const std::string& path)
{
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos)
  {
    return ".";
  }
  return slash == 0 ? "/" : path.substr(0, slash);
}

std::string baseNameOf(const std::string& path)
{
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

long long mtimeNs(const struct stat& st)
{
  return static_cast<long long>(st.st_mtim.tv_sec) * 1000000000LL + st.st_mtim.tv_nsec;
}

std::string kindOf(mode_t mode)
{
  if (S_ISDIR(mode))
  {
    return "a directory";
  }
  if (S_ISCHR(mode) || S_ISBLK(mode))
  {
    return "a device";
  }
  if (S_ISFIFO(mode))
  {
    return "a FIFO";
  }
  if (S_ISSOCK(mode))
  {
    return "a socket";
  }
  return "a special file";
}
}  // namespace

bool sameFile(const std::string& a, const std::string& b)
{
  struct stat sa, sb;
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

void checkOutputTarget(const std::string& flag, const std::string& path, const std::vector<std::string>& inputs)
{
  if (path.empty())
  {
    throw ConfigError(flag + ": an empty file name");
  }
  if (path.back() == '/')
  {
    throw ConfigError(flag + ": '" + path + "' names a directory, not a file");
  }
  struct stat st;
  if (::lstat(path.c_str(), &st) == 0)
  {
    if (S_ISLNK(st.st_mode))
    {
      char target[kPathMax];
      const ssize_t n = ::readlink(path.c_str(), target, sizeof target - 1);
      target[n > 0 ? n : 0] = '\0';
      throw ConfigError(flag + ": '" + path + "' is a symbolic link (to '" + target +
                        "'); it is neither written through nor replaced: name the file itself");
    }
    if (!S_ISREG(st.st_mode))
    {
      throw ConfigError(flag + ": '" + path + "' is " + kindOf(st.st_mode) +
                        ", not a regular file (only a regular file is ever replaced)");
    }
    for (const std::string& input : inputs)
    {
      if (!input.empty() && sameFile(path, input))
      {
        throw ConfigError(flag + ": '" + path + "' is also this run's input ('" + input +
                          "'); choose another output file");
      }
    }
    return;
  }
  if (errno != ENOENT)
  {
    throw ConfigError(flag + ": cannot use '" + path + "': " + std::strerror(errno));
  }
  const std::string dir = directoryOf(path);
  if (::stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
  {
    throw ConfigError(flag + ": directory '" + dir + "' of '" + path + "' does not exist");
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
  {
    throw ConfigError(flag + ": directory '" + dir + "' is not writable");
  }
}

SafeOutput::SafeOutput(const std::string& flag, const std::string& path, const std::vector<std::string>& inputs)
    : flag_(flag), path_(path)
{
  checkOutputTarget(flag, path, inputs);
  struct stat st;
  if (::lstat(path.c_str(), &st) == 0)
  {
    existed_ = true;
    dev_ = st.st_dev;
    ino_ = st.st_ino;
    mtime_ns_ = mtimeNs(st);
    size_ = static_cast<long long>(st.st_size);
  }
  std::string tmpl = directoryOf(path) + "/." + baseNameOf(path) + ".XXXXXX";
  fd_ = ::mkostemp(&tmpl[0], O_CLOEXEC);  // O_CREAT | O_EXCL: never follows or reuses an existing name
  if (fd_ < 0)
  {
    throw ConfigError(flag + ": cannot create a file in '" + directoryOf(path) + "': " + std::strerror(errno));
  }
  tmp_ = tmpl;
  registerTemporary(tmp_);
  // The file gets the permissions the target has, or those a new file gets.
  mode_t mode;
  if (existed_)
  {
    mode = st.st_mode & 07777;
  }
  else
  {
    const mode_t mask = ::umask(022);
    ::umask(mask);
    mode = 0666 & ~mask;
  }
  ::fchmod(fd_, mode);
  buf_ = std::make_unique<__gnu_cxx::stdio_filebuf<char>>(fd_, std::ios::out, 1 << 16);
  stream_ = std::make_unique<std::ostream>(buf_.get());
}

SafeOutput::~SafeOutput()
{
  if (!done_)
  {
    discard();
  }
}

bool SafeOutput::flush()
{
  stream_->flush();
  return good();
}

void SafeOutput::discard()
{
  if (done_)
  {
    return;
  }
  done_ = true;
  if (buf_)
  {
    buf_->close();
  }
  ::unlink(tmp_.c_str());
  unregisterTemporary(tmp_);
}

void SafeOutput::commit()
{
  auto fail = [&](const std::string& why) {
    discard();
    throw std::runtime_error(flag_ + ": " + why + "; '" + path_ + "' was not written");
  };
  if (done_)
  {
    throw std::logic_error("SafeOutput::commit called twice");
  }
  stream_->flush();
  if (!good())
  {
    fail(std::string("writing failed (") + (errno ? std::strerror(errno) : "write error") + ")");
  }
  if (::fsync(fd_) != 0)
  {
    fail(std::string("writing failed (") + std::strerror(errno) + ")");
  }
  if (buf_->close() == nullptr)
  {
    fail("closing the file failed");
  }
  struct stat st;
  const bool exists = ::lstat(path_.c_str(), &st) == 0;
  if (existed_)
  {
    if (!exists || !S_ISREG(st.st_mode) || st.st_dev != dev_ || st.st_ino != ino_ || mtimeNs(st) != mtime_ns_ ||
        static_cast<long long>(st.st_size) != size_)
    {
      fail("the file was changed or replaced by another writer while this run computed");
    }
    if (::rename(tmp_.c_str(), path_.c_str()) != 0)
    {
      fail(std::string("cannot rename the finished file into place: ") + std::strerror(errno));
    }
  }
  else
  {
    if (exists)
    {
      fail("the file was created by another writer while this run computed");
    }
    // Never replaces an existing name: two runs racing for a new file cannot both win (link() where the file
    // system has no RENAME_NOREPLACE).
    int rc = ::renameat2(AT_FDCWD, tmp_.c_str(), AT_FDCWD, path_.c_str(), RENAME_NOREPLACE);
    if (rc != 0 && (errno == EINVAL || errno == ENOSYS))
    {
      rc = ::link(tmp_.c_str(), path_.c_str());
      if (rc == 0)
      {
        ::unlink(tmp_.c_str());
      }
    }
    if (rc != 0)
    {
      fail(errno == EEXIST ? std::string("the file was created by another writer while this run computed")
                           : std::string("cannot move the finished file into place: ") + std::strerror(errno));
    }
  }
  unregisterTemporary(tmp_);
  done_ = true;
  const int dir = ::open(directoryOf(path_).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0)
  {
    ::fsync(dir);
    ::close(dir);
  }
}

std::string claimActiveFile(const std::string& flag, const std::string& path)
{
  checkOutputTarget(flag, path);
  const std::string active = path + ".active";
  const int fd = ::open(active.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
  if (fd < 0)
  {
    if (errno == EEXIST)
    {
      throw ConfigError(flag + ": '" + active +
                        "' exists (left by an interrupted recording? recover it with 'rosbag reindex' or remove it)");
    }
    throw ConfigError(flag + ": cannot create '" + active + "': " + std::strerror(errno));
  }
  ::close(fd);
  return active;
}

void publishActiveFile(const std::string& flag, const std::string& path)
{
  const std::string active = path + ".active";
  try
  {
    checkOutputTarget(flag, path);
  }
  catch (const ConfigError& e)
  {
    throw std::runtime_error(std::string(e.what()) + "; the recording is kept as '" + active + "'");
  }
  if (::rename(active.c_str(), path.c_str()) != 0)
  {
    throw std::runtime_error(flag + ": cannot rename '" + active + "' to '" + path + "': " + std::strerror(errno) +
                             "; the recording is kept as '" + active + "'");
  }
}

void watchTemporary(const std::string& path)
{
  registerTemporary(path);
}

void unwatchTemporary(const std::string& path)
{
  unregisterTemporary(path);
}

void watchChild(pid_t pid)
{
  g_child.store(pid);
}

void removeTemporariesOnSignals()
{
  for (int sig : {SIGINT, SIGTERM, SIGHUP})
  {
    struct sigaction sa;
    std::memset(&sa, 0, sizeof sa);
    sa.sa_handler = removeTemporariesAndDie;
    sigemptyset(&sa.sa_mask);
    ::sigaction(sig, &sa, nullptr);
  }
}

void copyFileInto(const std::string& from, SafeOutput& to)
{
  std::ifstream in(from, std::ios::binary);
  if (!in)
  {
    throw std::runtime_error(to.flag() + ": the chart script wrote no '" + from + "'");
  }
  to.stream() << in.rdbuf();
  to.commit();
}

void flushStdout()
{
  std::cout.flush();
  if (!std::cout)
  {
    throw std::runtime_error("writing the result to standard output failed");
  }
}

}  // namespace backlash_servo
