// Every tool's outputs and helper programs: no shell, no clobbering, no partial files. Each test works in its own
// private directory (never the real /tmp): planted links, outputs equal to inputs, devices, full disks (a file-size
// limit, as a full disk answers EFBIG/ENOSPC), signals and concurrent writers.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "backlash_servo/files/safe_output.h"
#include "test_helpers.h"

namespace
{
using test_helpers::readFile;
using test_helpers::runCapture;

const std::string SIM = BACKLASH_SIM_EXE;
const std::string SWEEP = BACKLASH_SWEEP_EXE;
const std::string COMPARE = BACKLASH_COMPARE_EXE;
const std::string RECORD = BACKLASH_RECORD_EXE;
const std::string PARAMS = BACKLASH_PARAMS_EXE;
const std::string DF = BACKLASH_DF_EXE;
const std::string SRC = SOURCE_DIR;

/// A shell word that stays one word whatever it holds.
std::string q(const std::string& s)
{
  std::string out = "'";
  for (char c : s)
  {
    out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  }
  return out + "'";
}

/// A private directory for one test, removed with everything in it afterwards.
class Sandbox : public ::testing::Test
{
 protected:
  void SetUp() override
  {
    char tmpl[] = "/tmp/backlash_file_safety.XXXXXX";
    ASSERT_NE(mkdtemp(tmpl), nullptr);
    dir = tmpl;
    config = dir + "/c.yaml";
    write(config, readFile(SRC + "/config/thesis_limit_cycle.yaml"));
  }
  void TearDown() override { runCapture("rm -rf " + q(dir)); }

  static void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }
  static bool exists(const std::string& path)
  {
    struct stat st;
    return ::lstat(path.c_str(), &st) == 0;
  }
  static bool isSymlink(const std::string& path)
  {
    struct stat st;
    return ::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode);
  }
  /// Names in the sandbox (sorted, one per line; hidden ones too).
  std::string listing() const { return runCapture("ls -A " + q(dir)); }
  /// Runs `cmd` in the sandbox; stdout+stderr captured, *code its exit status.
  std::string run(const std::string& cmd, int* code) const
  {
    return runCapture("cd " + q(dir) + " && { " + cmd + "; } 2>&1", code);
  }

  std::string dir, config;
};

using ChartSafety = Sandbox;
using OutputSafety = Sandbox;
using FullDisk = Sandbox;

TEST_F(ChartSafety, APngPathWithQuotesAndSemicolonsIsOnlyAFileName)
{
  const std::string png = "x'; touch PWNED; echo '.png";
  int code = -1;
  const std::string out = run(
      q(COMPARE) + " --config " + q(SRC + "/config/compare_example.yaml") + " --png " + q(png) + " --jobs 2", &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_FALSE(exists(dir + "/PWNED")) << "the path was run as a command";
  const std::string chart = readFile(dir + "/" + png);
  ASSERT_GT(chart.size(), 1000u);
  EXPECT_EQ(chart.substr(1, 3), "PNG");
  EXPECT_NE(readFile(dir + "/x'; touch PWNED; echo '.svg").find("<svg"), std::string::npos);
}

TEST_F(ChartSafety, AnUnusableTemporaryDirectoryIsAnErrorThatDeletesNothing)
{
  // TMPDIR names a file: mkdtemp fails. Nothing may fall back to a shared directory and clean it up.
  const std::string victim_dir = dir + "/shared_tmp";
  ASSERT_EQ(::mkdir(victim_dir.c_str(), 0700), 0);
  write(victim_dir + "/someone_elses_file", "keep me");
  write(dir + "/not_a_dir", "");
  int code = -1;
  const auto start = std::chrono::steady_clock::now();
  const std::string out = run("TMPDIR=" + q(dir + "/not_a_dir") + " " + q(COMPARE) + " --config " +
                                  q(SRC + "/config/compare_example.yaml") + " --png " + q(dir + "/c.png"),
                              &code);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("cannot create a temporary directory"), std::string::npos) << out;
  EXPECT_EQ(readFile(victim_dir + "/someone_elses_file"), "keep me");
  EXPECT_FALSE(exists(dir + "/c.png"));
  EXPECT_EQ(listing(), "c.yaml\nnot_a_dir\nshared_tmp\n") << "no temporary left behind";
  EXPECT_LT(seconds, 30.0);  // refused before the strategies run (they take a few seconds); generous for CI
}

TEST_F(ChartSafety, TheTemporaryDirectoryIsRemovedExactlyAndNothingElse)
{
  const std::string tmp = dir + "/tmpdir";
  ASSERT_EQ(::mkdir(tmp.c_str(), 0700), 0);
  write(tmp + "/someone_elses_file", "keep me");
  int code = -1;
  const std::string out = run("TMPDIR=" + q(tmp) + " " + q(COMPARE) + " --config " +
                                  q(SRC + "/config/compare_example.yaml") + " --png out.png --csv out.csv --jobs 2",
                              &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_EQ(runCapture("ls -A " + q(tmp)), "someone_elses_file\n");
  EXPECT_EQ(listing(), "c.yaml\nout.csv\nout.png\nout.svg\ntmpdir\n");
}

TEST_F(OutputSafety, APlantedTemporaryLinkIsNeitherFollowedNorRemoved)
{
  write(dir + "/victim", "victim\n");
  ASSERT_EQ(::symlink("victim", (dir + "/out.csv.tmp").c_str()), 0);
  write(dir + "/mine.csv.tmp", "the user's own file\n");
  int code = -1;
  std::string out = run(q(SIM) + " --config c.yaml --csv out.csv", &code);
  ASSERT_EQ(code, 0) << out;
  out = run(q(SIM) + " --config c.yaml --csv mine.csv", &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_EQ(readFile(dir + "/victim"), "victim\n");
  EXPECT_TRUE(isSymlink(dir + "/out.csv.tmp"));
  EXPECT_FALSE(isSymlink(dir + "/out.csv"));
  EXPECT_EQ(readFile(dir + "/mine.csv.tmp"), "the user's own file\n");
  EXPECT_EQ(readFile(dir + "/out.csv"), readFile(dir + "/mine.csv"));
  EXPECT_EQ(readFile(dir + "/out.csv").substr(0, 5), "time,");
}

TEST_F(OutputSafety, AnOutputThatIsAnInputIsRefusedAndTheInputKept)
{
  const std::string original = readFile(config);
  ASSERT_EQ(::link(config.c_str(), (dir + "/hardlink.yaml").c_str()), 0);
  ASSERT_EQ(::symlink("c.yaml", (dir + "/softlink.yaml").c_str()), 0);
  const std::string compare_cfg = dir + "/cmp.yaml";
  write(compare_cfg, readFile(SRC + "/config/compare_example.yaml"));
  const std::string compare_original = readFile(compare_cfg);
  const std::vector<std::string> cmds = {
      q(SIM) + " --config c.yaml --csv c.yaml",         q(SIM) + " --config c.yaml --csv ./hardlink.yaml",
      q(SIM) + " --config softlink.yaml --csv c.yaml",  q(SWEEP) + " --merge c.yaml --output c.yaml",
      q(COMPARE) + " --config cmp.yaml --csv cmp.yaml",
  };
  for (const std::string& cmd : cmds)
  {
    int code = -1;
    const std::string out = run(cmd, &code);
    EXPECT_EQ(code, 2) << cmd << "\n" << out;
    EXPECT_NE(out.find("also this run's input"), std::string::npos) << cmd << "\n" << out;
  }
  EXPECT_EQ(readFile(config), original);
  EXPECT_EQ(readFile(compare_cfg), compare_original);
  EXPECT_EQ(listing(), "c.yaml\ncmp.yaml\nhardlink.yaml\nsoftlink.yaml\n");
}

TEST_F(OutputSafety, LinksDevicesAndDirectoriesAreRefusedWithOneLine)
{
  write(dir + "/victim", "victim\n");
  ASSERT_EQ(::symlink("victim", (dir + "/link.csv").c_str()), 0);
  ASSERT_EQ(::symlink("victim", (dir + "/link.png").c_str()), 0);
  ASSERT_EQ(::mkdir((dir + "/adir").c_str(), 0700), 0);
  struct Case
  {
    std::string cmd, says;
  };
  const std::vector<Case> cases = {
      {q(SIM) + " --config c.yaml --csv link.csv", "is a symbolic link"},
      {q(SIM) + " --config c.yaml --csv /dev/null", "is a device"},
      {q(SIM) + " --config c.yaml --csv adir", "is a directory"},
      {q(SIM) + " --config c.yaml --csv nowhere/x.csv", "does not exist"},
      {q(SWEEP) + " --zeta 0.3,0.5 --output link.csv", "is a symbolic link"},
      {q(COMPARE) + " --config " + q(SRC + "/config/compare_example.yaml") + " --png link.png", "is a symbolic link"},
      {q(COMPARE) + " --config " + q(SRC + "/config/compare_example.yaml") + " --png chart", "must end in .png"},
      {q(COMPARE) + " --config " + q(SRC + "/config/compare_example.yaml") + " --csv /dev/null", "is a device"},
      {q(RECORD) + " /dev/null /topic", "is a device"},
      {q(RECORD) + " adir /topic", "is a directory"},
  };
  for (const Case& c : cases)
  {
    int code = -1;
    const std::string out = run(c.cmd, &code);
    EXPECT_EQ(code, 2) << c.cmd << "\n" << out;
    EXPECT_NE(out.find(c.says), std::string::npos) << c.cmd << "\n" << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << c.cmd << "\n" << out;
  }
  EXPECT_EQ(readFile(dir + "/victim"), "victim\n");
  EXPECT_TRUE(isSymlink(dir + "/link.csv"));
  EXPECT_EQ(listing(), "adir\nc.yaml\nlink.csv\nlink.png\nvictim\n");
}

TEST_F(OutputSafety, ARecordingLeftByAnInterruptedRunIsNeverOverwritten)
{
  write(dir + "/x.bag.active", "an interrupted recording\n");
  int code = -1;
  const std::string out = run(q(RECORD) + " x.bag /topic", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("rosbag reindex"), std::string::npos) << out;
  EXPECT_EQ(readFile(dir + "/x.bag.active"), "an interrupted recording\n");
}

TEST_F(OutputSafety, TwoWritersOfOneFileNeverMixAndTheLoserFails)
{
  // The class itself, deterministically: both writers started, both finish; the second to commit loses.
  for (const bool existed : {false, true})
  {
    const std::string path = dir + (existed ? "/existing.csv" : "/new.csv");
    if (existed)
    {
      write(path, "old\n");
    }
    backlash_servo::SafeOutput a("--csv", path), b("--csv", path);
    a.stream() << "run A\n";
    b.stream() << "run B\n";
    a.commit();
    EXPECT_THROW(b.commit(), std::runtime_error);
    EXPECT_EQ(readFile(path), "run A\n");
  }
  // The tool, racing for real: whichever finishes first, the file is one whole run (equal to a lone run's file),
  // and a run that did not write it says so and fails.
  int code = -1;
  ASSERT_EQ((run(q(SIM) + " --config c.yaml --csv alone.csv --sample-rate 2000", &code), code), 0);
  const std::string out = run("(" + q(SIM) + " --config c.yaml --csv same.csv --sample-rate 2000; echo rc=$?) & (" +
                                  q(SIM) + " --config c.yaml --csv same.csv --sample-rate 2000; echo rc=$?); wait",
                              &code);
  EXPECT_NE(out.find("rc=0"), std::string::npos) << out;
  const bool one_failed = out.find("rc=1") != std::string::npos;
  if (one_failed)
  {
    EXPECT_NE(out.find("another writer while this run computed; '"), std::string::npos) << out;
  }
  EXPECT_EQ(readFile(dir + "/same.csv"), readFile(dir + "/alone.csv"));
  EXPECT_EQ(listing(), "alone.csv\nc.yaml\nexisting.csv\nnew.csv\nsame.csv\n");
}

TEST_F(OutputSafety, AnInterruptedRunLeavesNoTemporary)
{
  for (const int sig : {SIGINT, SIGTERM})
  {
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0)
    {
      if (::chdir(dir.c_str()) != 0)
      {
        ::_exit(99);
      }
      ::execl(SIM.c_str(), SIM.c_str(), "--config", "c.yaml", "--csv", "big.csv", "--sample-rate", "100000",
              "--duration", "100000", static_cast<char*>(nullptr));
      ::_exit(98);
    }
    // Wait (up to 60 s) until the run has created its temporary, then interrupt it.
    bool seen = false;
    for (int i = 0; i < 600 && !seen; ++i)
    {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      seen = listing().find(".big.csv.") != std::string::npos;
    }
    ASSERT_TRUE(seen) << listing();
    ::kill(pid, sig);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << status;
    EXPECT_EQ(listing(), "c.yaml\n") << "signal " << sig;
  }
}

// A tool drawing its chart (a helper program writing into a work directory under $TMPDIR, the output's temporary
// beside the target) and interrupted then: the helper is ended, the work directory and the temporary removed.
TEST_F(OutputSafety, AnInterruptedChartLeavesNoWorkDirectoryNorTemporary)
{
  const std::string tmp = dir + "/tmpdir";
  ASSERT_EQ(::mkdir(tmp.c_str(), 0700), 0);
  for (const int sig : {SIGTERM, SIGINT, SIGHUP})
  {
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0)
    {
      if (::chdir(dir.c_str()) != 0 || ::setenv("TMPDIR", tmp.c_str(), 1) != 0)
      {
        ::_exit(99);
      }
      ::execl(DF.c_str(), DF.c_str(), "--zeta", "0.1", "--inertia-ratio", "1", "--friction-ratio", "0.4",
              "--restitution", "0", "--backlash", "0.3", "--png", "df.png", static_cast<char*>(nullptr));
      ::_exit(98);
    }
    // Wait (up to 60 s) until the chart's work directory exists, then interrupt the tool.
    bool seen = false;
    for (int i = 0; i < 6000 && !seen; ++i)
    {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      seen = runCapture("ls -A " + q(tmp)).find("backlash_df.") != std::string::npos;
    }
    ASSERT_TRUE(seen) << "signal " << sig;
    ::kill(pid, sig);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << status;
    EXPECT_EQ(runCapture("ls -A " + q(tmp)), "") << "signal " << sig;
    EXPECT_EQ(listing(), "c.yaml\ntmpdir\n") << "signal " << sig;
  }
}

TEST_F(FullDisk, ASweepStopsReportsTheTrueCountAndLeavesTheTargetAsItWas)
{
  write(dir + "/sweep.csv", "an earlier file\n");
  int code = -1;
  // 4 KiB file-size limit: the 1st KiB of rows fits, the rest fails as on a full disk.
  const std::string out = run(
      "trap '' XFSZ; ulimit -f 4; " + q(SWEEP) + " --zeta 0.1:0.9:40 --restitution 0,0.5,1 --output sweep.csv", &code);
  EXPECT_EQ(code, 1) << out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex("failed after ([0-9]+) of 120 rows"))) << out;
  EXPECT_LT(std::stoi(m[1]), 120);
  EXPECT_NE(out.find("is as before"), std::string::npos) << out;
  EXPECT_EQ(readFile(dir + "/sweep.csv"), "an earlier file\n");
  EXPECT_EQ(listing(), "c.yaml\nsweep.csv\n");
}

TEST_F(FullDisk, NoToolLeavesAPartialOrEmptyFile)
{
  const std::vector<std::string> cmds = {
      q(SIM) + " --config c.yaml --csv out.csv --sample-rate 1000",
      q(COMPARE) + " --config " + q(SRC + "/config/compare_example.yaml") + " --png out.png --jobs 2",
      q(COMPARE) + " --config " + q(SRC + "/config/compare_example.yaml") + " --csv out.csv --jobs 2",
  };
  for (const std::string& cmd : cmds)
  {
    int code = -1;
    const std::string out = run("trap '' XFSZ; ulimit -f 1; TMPDIR=" + q(dir) + " " + cmd, &code);
    EXPECT_EQ(code, 1) << cmd << "\n" << out;
    EXPECT_NE(out.find("failed"), std::string::npos) << cmd << "\n" << out;
    EXPECT_EQ(listing(), "c.yaml\n") << cmd << "\n" << out;
  }
}

}  // namespace

namespace
{
using SweepInputs = Sandbox;

/// `row` with its cell `index` (0-based) replaced by `value`.
std::string withCell(const std::string& row, std::size_t index, const std::string& value)
{
  std::vector<std::string> cells;
  std::stringstream ss(row);
  for (std::string c; std::getline(ss, c, ',');)
  {
    cells.push_back(c);
  }
  if (!row.empty() && row.back() == ',')
  {
    cells.push_back("");  // the empty last cell getline does not return
  }
  cells.at(index) = value;
  std::string out;
  for (std::size_t i = 0; i < cells.size(); ++i)
  {
    out += (i ? "," : "") + cells[i];
  }
  return out;
}

/// Replaces the first occurrence of `from` in the file by `to`.
void edit(const std::string& path, const std::string& from, const std::string& to)
{
  std::string text = readFile(path);
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  std::ofstream(path) << text;
}

TEST_F(SweepInputs, DamagedForgedOrForeignPartsAreRefusedWithOneLine)
{
  const std::string grid = " --zeta 0.3,0.5,0.7 --restitution 0,1";
  int code = -1;
  for (const std::string k : {"1", "2"})
  {
    ASSERT_EQ((run(q(SWEEP) + grid + " --shard " + k + "/2 --output p" + k + ".csv", &code), code), 0);
  }
  ASSERT_EQ((run(q(SWEEP) + grid + " --output whole.csv", &code), code), 0);
  ASSERT_EQ((run(q(SWEEP) + " --merge p1.csv p2.csv --output merged.csv", &code), code), 0);
  ASSERT_EQ(readFile(dir + "/merged.csv"), readFile(dir + "/whole.csv"));
  const std::string good1 = readFile(dir + "/p1.csv"), good2 = readFile(dir + "/p2.csv");
  const std::string p1_line = good1.substr(0, good1.find('\n'));
  const std::string header =
      good1.substr(good1.find('\n') + 1, good1.find('\n', good1.find('\n') + 1) - good1.find('\n') - 1);
  const std::string row1 =
      good1.substr(p1_line.size() + header.size() + 2,
                   good1.find('\n', p1_line.size() + header.size() + 2) - p1_line.size() - header.size() - 2);
  // The verdict's column: the number of commas before it in the header.
  const std::size_t v = static_cast<std::size_t>(
      std::count(header.begin(), header.begin() + static_cast<std::ptrdiff_t>(header.find("verdict")), ','));
  struct Case
  {
    std::string name, from, to, says;
  };
  const std::vector<Case> cases = {
      {"index 2^64-1", "points [0, 3)", "points [0, 18446744073709551615)", "damaged part line"},
      {"part count 1e12", "part 1/2", "part 1/1000000000000", "no valid part line"},
      {"total 1e12", "of 6,", "of 1000000000000,", "damaged part line"},
      {"garbage verdict", row1, withCell(row1, v, "garbage"), "unknown verdict"},
      {"extra column", row1, row1 + ",7", "columns, the header has"},
      {"not a number", row1, withCell(row1, 0, "x"), "is not a number"},
      {"flag not 0/1", row1, withCell(row1, v + 1, "2"), "is not 0 or 1"},
      {"short header, numeric row", header + "\n" + row1, "zeta,verdict,limit_cycle,x\n0.3,1,2,3",
       "no sweep CSV header"},
  };
  for (const Case& c : cases)
  {
    std::ofstream(dir + "/p1.csv") << good1;
    edit(dir + "/p1.csv", c.from, c.to);
    const std::string out = run(q(SWEEP) + " --merge p1.csv p2.csv --output bad.csv", &code);
    EXPECT_EQ(code, 2) << c.name << "\n" << out;
    EXPECT_NE(out.find(c.says), std::string::npos) << c.name << "\n" << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << c.name << "\n" << out;
    EXPECT_FALSE(exists(dir + "/bad.csv")) << c.name;
  }
  // Two rows swapped inside a part: both rows well formed, the grid order is not.
  {
    std::vector<std::string> lines;
    std::stringstream ss(good1);
    for (std::string l; std::getline(ss, l);)
    {
      lines.push_back(l);
    }
    std::swap(lines[2], lines[3]);
    std::ofstream f(dir + "/p1.csv");
    for (const std::string& l : lines)
    {
      f << l << "\n";
    }
  }
  std::string out = run(q(SWEEP) + " --merge p1.csv p2.csv --output bad.csv", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("rows swapped or altered"), std::string::npos) << out;
  std::ofstream(dir + "/p1.csv") << good1;
  // A part computed with another run-length cap belongs to another sweep.
  ASSERT_EQ((run(q(SWEEP) + grid + " --max-duration 500 --shard 2/2 --output p2.csv", &code), code), 0);
  out = run(q(SWEEP) + " --merge p1.csv p2.csv --output bad.csv", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("belongs to another sweep"), std::string::npos) << out;
  std::ofstream(dir + "/p2.csv") << good2;
  // Special files: one line each, and nothing read for ever.
  ASSERT_EQ(::mkdir((dir + "/adir").c_str(), 0700), 0);
  for (const char* part : {"/dev/zero", "adir"})
  {
    out = run(q(SWEEP) + " --merge p1.csv " + std::string(part) + " --output bad.csv", &code);
    EXPECT_EQ(code, 2) << part << "\n" << out;
    EXPECT_NE(out.find("give a file"), std::string::npos) << part << "\n" << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  }
  out = run(q(SWEEP) + grid + " --resume --output /dev/zero", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_EQ(listing(), "adir\nc.yaml\nmerged.csv\np1.csv\np2.csv\nwhole.csv\n");
}
}  // namespace

namespace
{
using BoundedWork = Sandbox;

TEST_F(BoundedWork, AChartOfManySamplesKeepsABoundedTrajectory)
{
  // 2e6 samples per strategy: every one enters the metrics, at most 20001 the chart (all of them would be ~80 MB
  // of samples and ~150 MB of chart data per strategy).
  write(dir + "/many.yaml",
        "motor_inertia: 0.1\nload_inertia: 0.9\nmotor_friction: 0.48\nload_friction: 0.32\ngain: 1\n"
        "backlash: 0.3\nrestitution: 1\nduration: 20\nsample_rate: 100000\n"
        "profile:\n  - step: {time: 0, target: 1}\nstrategies:\n  - name: P\n    control_law: proportional\n");
  const std::string tmp = dir + "/tmpdir";
  ASSERT_EQ(::mkdir(tmp.c_str(), 0700), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0)
  {
    ::setenv("TMPDIR", tmp.c_str(), 1);
    const std::string png = dir + "/many.png", cfg = dir + "/many.yaml";
    ::execl(COMPARE.c_str(), COMPARE.c_str(), "--config", cfg.c_str(), "--png", png.c_str(), "--json",
            static_cast<char*>(nullptr));
    ::_exit(98);
  }
  int status = 0;
  struct rusage usage;
  ASSERT_EQ(::wait4(pid, &status, 0, &usage), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  // The largest of the tool and its chart script (matplotlib alone: ~90 MB); 2e6 rows would be ~400 MB in Python.
  EXPECT_LT(usage.ru_maxrss, 150 * 1024) << "peak resident set [KiB] of backlash_compare or its chart script";
  EXPECT_GT(readFile(dir + "/many.png").size(), 1000u);
  EXPECT_EQ(runCapture("ls -A " + q(tmp)), "");
}

TEST_F(BoundedWork, RatesAndSectionsThatCannotBeHonouredAreRefused)
{
  int code = -1;
  std::string out = run(q(SIM) + " --config c.yaml --sample-rate 1e308 --csv out.csv", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--sample-rate must be in (0, 1e6]"), std::string::npos) << out;
  out = run(q(PARAMS) + " --format markdown --sections servo,bogus", &code);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("unknown section 'bogus'"), std::string::npos) << out;
  EXPECT_EQ(listing(), "c.yaml\n");
}
}  // namespace
