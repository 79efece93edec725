#include "backlash_servo/files/part_files.h"

#include <cmath>
#include <cstdio>
#include <iostream>

namespace backlash_servo
{
bool readMergeArguments(int argc, char** argv, const std::string& tool, const std::string& output_flag,
                        std::vector<std::string>* parts, std::string* output)
{
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    if (arg == "--merge")
    {
      continue;
    }
    if (arg == output_flag && i + 1 < argc)
    {
      *output = argv[++i];
    }
    else if (arg.rfind("--", 0) == 0)
    {
      std::cerr << tool << ": error: --merge takes only part files and " << output_flag << " FILE (got " << arg
                << ")\n";
      return false;
    }
    else
    {
      parts->push_back(arg);
    }
  }
  return true;
}

std::string csvNumber(double v)
{
  if (!std::isfinite(v))
  {
    return "";
  }
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace backlash_servo
