#include "backlash_servo/files/run_program.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/files/safe_output.h"

extern char** environ;

namespace backlash_servo
{
int runProgram(const std::vector<std::string>& argv)
{
  if (argv.empty())
  {
    throw std::invalid_argument("runProgram: no program");
  }
  std::vector<char*> args;
  for (const std::string& a : argv)
  {
    args.push_back(const_cast<char*>(a.c_str()));
  }
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, STDERR_FILENO, STDOUT_FILENO);
  pid_t pid = 0;
  const int rc = ::posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0)
  {
    throw std::runtime_error("cannot run '" + argv[0] + "': " + std::strerror(rc));
  }
  watchChild(pid);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0)
  {
    if (errno != EINTR)
    {
      watchChild(0);
      throw std::runtime_error("waiting for '" + argv[0] + "' failed: " + std::strerror(errno));
    }
  }
  watchChild(0);
  if (WIFSIGNALED(status))
  {
    throw std::runtime_error("'" + argv[0] + "' was killed by signal " + std::to_string(WTERMSIG(status)));
  }
  return WEXITSTATUS(status);
}

void runChartScript(const std::string& script, const std::string& dir, const std::string& out)
{
  const int status = runProgram({"/usr/bin/python3", script, dir, out});
  if (status != 0)
  {
    throw std::runtime_error("--png: the chart script " + script + " failed (exit status " + std::to_string(status) +
                             ")");
  }
}

bool isPngPath(const std::string& path)
{
  return path.size() >= 5 && path.compare(path.size() - 4, 4, ".png") == 0;
}

std::string helperBesideExecutable(const std::string& name)
{
  char exe[4096];
  const ssize_t n = ::readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n <= 0)
  {
    throw std::runtime_error("cannot locate this executable (/proc/self/exe) to find '" + name + "'");
  }
  exe[n] = '\0';
  std::string dir(exe);
  dir = dir.substr(0, dir.find_last_of('/'));
  const std::string path = dir + "/" + name;
  if (::access(path.c_str(), R_OK) != 0)
  {
    throw std::runtime_error("helper '" + path + "' is missing (rebuild or reinstall the package)");
  }
  return path;
}

TemporaryDirectory::TemporaryDirectory(const std::string& prefix)
{
  const char* env = std::getenv("TMPDIR");
  std::string base = env && *env ? env : "/tmp";
  std::string tmpl = base + "/" + prefix + ".XXXXXX";
  if (::mkdtemp(&tmpl[0]) == nullptr)
  {
    throw ConfigError("cannot create a temporary directory in '" + base + "' (TMPDIR): " + std::strerror(errno));
  }
  path_ = tmpl;
  watchTemporary(path_);
}

TemporaryDirectory::~TemporaryDirectory()
{
  for (const std::string& f : files_)
  {
    ::unlink(f.c_str());
    unwatchTemporary(f);
  }
  ::rmdir(path_.c_str());
  unwatchTemporary(path_);
}

std::string TemporaryDirectory::file(const std::string& name)
{
  files_.push_back(path_ + "/" + name);
  watchTemporary(files_.back());
  return files_.back();
}

}  // namespace backlash_servo
