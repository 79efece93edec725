#include "output_file.h"

#include <sys/stat.h>

#include <cstdio>
#include <iostream>
#include <stdexcept>

#include "backlash_servo/config/key_values.h"

namespace backlash_servo
{
void requireRegularTarget(const std::string& flag, const std::string& path)
{
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
  {
    throw ConfigError(flag + ": '" + path + "' is not a regular file (a device, FIFO or directory is never replaced)");
  }
}

OutputFile::OutputFile(const std::string& flag, const std::string& path) : flag_(flag), path_(path), tmp_(path + ".tmp")
{
  requireRegularTarget(flag, path);
  requireRegularTarget(flag, tmp_);
  out_.open(tmp_, std::ios::trunc);
  if (!out_)
  {
    throw ConfigError(flag + ": cannot write '" + tmp_ + "'");
  }
}

OutputFile::~OutputFile()
{
  if (!committed_)
  {
    out_.close();
    std::remove(tmp_.c_str());
  }
}

void OutputFile::commit()
{
  out_.flush();
  out_.close();
  if (!out_)
  {
    throw std::runtime_error(flag_ + ": writing '" + tmp_ + "' failed (disk full?); '" + path_ + "' was not written");
  }
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0)
  {
    throw std::runtime_error(flag_ + ": cannot rename '" + tmp_ + "' to '" + path_ + "'");
  }
  committed_ = true;
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
