#include "backlash_servo/config/safe_input.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "backlash_servo/config/key_values.h"

namespace backlash_servo
{
std::string readRegularFile(const std::string& flag, const std::string& path, std::size_t max_bytes)
{
  // Opened without blocking (a FIFO would wait for a writer) and checked on the descriptor that is read.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0)
  {
    throw ConfigError(flag + ": cannot read '" + path + "': " + std::strerror(errno));
  }
  struct stat st;
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))
  {
    const bool dir = S_ISDIR(st.st_mode);
    ::close(fd);
    throw ConfigError(flag + ": '" + path + "' is " + (dir ? "a directory" : "not a regular file (a device or FIFO)") +
                      "; give a file");
  }
  if (static_cast<std::size_t>(st.st_size) > max_bytes)
  {
    ::close(fd);
    throw ConfigError(flag + ": '" + path + "' is " + std::to_string(st.st_size) + " bytes, more than the " +
                      std::to_string(max_bytes) + " such a file can hold");
  }
  std::string content;
  char buf[65536];
  for (;;)
  {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR)
    {
      continue;
    }
    if (n < 0)
    {
      const int err = errno;
      ::close(fd);
      throw ConfigError(flag + ": reading '" + path + "' failed: " + std::strerror(err));
    }
    if (n == 0)
    {
      break;
    }
    content.append(buf, static_cast<std::size_t>(n));
    if (content.size() > max_bytes)  // grew while being read
    {
      ::close(fd);
      throw ConfigError(flag + ": '" + path + "' is larger than the " + std::to_string(max_bytes) +
                        " bytes such a file can hold");
    }
  }
  ::close(fd);
  return content;
}

std::vector<std::string> splitCsvCells(const std::string& line)
{
  std::vector<std::string> cells;
  std::size_t start = 0;
  for (;;)
  {
    const std::size_t comma = line.find(',', start);
    cells.push_back(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos)
    {
      return cells;
    }
    start = comma + 1;
  }
}

}  // namespace backlash_servo
