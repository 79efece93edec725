// backlash_sweep: every row against a single backlash_sim run; axes, profiles, resume, shards and the Slurm array.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>
#include "tools/tools_test.h"

using namespace tools_test;

TEST(Sweep, EveryRowEqualsASingleBacklashSimRun)
{
  int code = 0;
  const std::string csv = runCapture(SWEEP + GRID + " --jobs 2 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const auto rows = csvRows(csv);
  ASSERT_EQ(rows.size(), 12u);
  int cycles = 0;
  for (const auto& r : rows)
  {
    ASSERT_EQ(r.size(), 18u);  // (steady_error: empty unless converged; maxima_per_period; the cycle's shape)
    const std::string json = runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio " + r[1] +
                                        " --friction-ratio " + r[2] + " --restitution " + r[3] + " --backlash " + r[4]);
    EXPECT_EQ(r[5], jsonText(json, "verdict")) << r[0] << " " << r[1] << " " << r[3];
    EXPECT_EQ(std::stod(r[7]), jsonNumber(json, "limit_cycle_error"));
    EXPECT_EQ(std::stoull(r[9]), static_cast<unsigned long long>(jsonNumber(json, "impacts")));
    EXPECT_EQ(std::stoi(r[13]), r[6] == "1" ? static_cast<int>(jsonNumber(json, "maxima_per_period")) : 0);
    if (r[6] == "1")
    {
      EXPECT_EQ(std::stod(r[14]), jsonNumber(json, "peak_to_peak"));
      EXPECT_EQ(std::stod(r[15]), jsonNumber(json, "cycle_centre"));
    }
    else
    {
      EXPECT_EQ(r[14], "");
      EXPECT_EQ(r[15], "");
    }
    EXPECT_EQ(r[16], "");  // (the continuous law reads an ideal sensor: no counts)
    EXPECT_EQ(r[17], "");
    cycles += r[6] == "1";
  }
  EXPECT_GT(cycles, 0);
  EXPECT_LT(cycles, 12);
}

// --tracking adds the tracking figures: each equals backlash_sim's (the same replay) — a number, or empty where the
// JSON has null — and the sharded parts of such a sweep merge into exactly the unsharded CSV.
TEST(Sweep, TrackingColumnsEqualBacklashSimsFigures)
{
  const std::string grid = " --zeta 0.3,0.6 --inertia-ratio 1,9 --friction-ratio 0.4 --restitution 0,1 --tracking";
  int code = 0;
  const std::string csv = runCapture(SWEEP + grid + " --jobs 2 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  EXPECT_NE(
      csv.find("cycle_centre,peak_to_peak_counts,below_resolution,settling_band,settling_time,steady_rms_error\n"),
      std::string::npos);
  const auto rows = csvRows(csv);
  ASSERT_EQ(rows.size(), 8u);
  int settled = 0;
  for (const auto& r : rows)
  {
    ASSERT_EQ(r.size(), 21u);
    const std::string json = runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio " + r[1] +
                                        " --friction-ratio " + r[2] + " --restitution " + r[3]);
    EXPECT_EQ(std::stod(r[18]), jsonNumber(json, "settling_band"));
    if (json.find("\"settling_time\":null") != std::string::npos)
    {
      EXPECT_EQ(r[19], "");
    }
    else
    {
      EXPECT_EQ(std::stod(r[19]), jsonNumber(json, "settling_time"));
      ++settled;
    }
    EXPECT_EQ(std::stod(r[20]), jsonNumber(json, "steady_rms_error"));
  }
  EXPECT_GT(settled, 0);
  // Shards of the tracking sweep merge into the same bytes.
  char tmpl[] = "/tmp/backlash_tracking_XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  const std::string dir = tmpl;
  for (int k = 1; k <= 3; ++k)
  {
    ASSERT_EQ(std::system((SWEEP + grid + " --shard " + std::to_string(k) + "/3 --output " + dir + "/p" +
                           std::to_string(k) + ".csv 2>/dev/null")
                              .c_str()),
              0);
  }
  ASSERT_EQ(std::system((SWEEP + " --merge " + dir + "/p2.csv " + dir + "/p1.csv " + dir + "/p3.csv --output " + dir +
                         "/m.csv 2>/dev/null")
                            .c_str()),
            0);
  EXPECT_EQ(readFile(dir + "/m.csv"), csv);
  std::system(("rm -rf " + dir).c_str());
}

// A command profile is a setting every point shares: each row equals backlash_sim with the same profile (a digital
// drive sampling a ramp and a reversal), and differs from the plain step.
TEST(Sweep, AProfileIsSharedByEveryPoint)
{
  const std::string profile = "/tmp/backlash_sweep_profile.yaml";
  std::ofstream(profile) << "- ramp: {time: 0, target: 1, duration: 3}\n- move: {time: 40, distance: -0.4, "
                            "max_velocity: 0.2, max_acceleration: 0.1}\n";
  const std::string shared = " --controller-rate 200 --profile " + profile;
  int code = 0;
  const std::string csv = runCapture(SWEEP + " --zeta 0.3,0.5" + shared + " 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const auto rows = csvRows(csv);
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& r : rows)
  {
    const std::string json =
        runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio 9 --friction-ratio 0.4" + shared);
    EXPECT_EQ(r[5], jsonText(json, "verdict"));
    EXPECT_EQ(std::stod(r[10]), jsonNumber(json, "simulated_time"));
    EXPECT_GE(std::stod(r[10]), 40.0 + 2.0 * 2.0 + 0.0);  // a run until settled lasts past the profile's end
    const std::string step =
        runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio 9 --friction-ratio 0.4 --controller-rate 200");
    EXPECT_NE(jsonNumber(step, "simulated_time"), jsonNumber(json, "simulated_time"));
  }
}

// Any numeric parameter is an axis, in either form, with fixed settings (a digital drive) shared by every point:
// each row is exactly the backlash_sim run of the same flags.
TEST(Sweep, AnyParameterIsAnAxisInEitherForm)
{
  struct Grid
  {
    std::string flags;   // the sweep's fixed settings and axes
    std::string header;  // its axis columns
  };
  const Grid grids[] = {
      {" --zeta 0.4 --load-coulomb-friction 0,0.02 --load-static-friction 0.05 --controller-rate 0,200",
       "zeta,inertia_ratio,friction_ratio,restitution,backlash,load_coulomb_friction,controller_rate,"},
      {" --motor-inertia 0.1 --load-inertia 0.9 --motor-friction 0.48 --load-friction 0.32 --backlash 0.05"
       " --restitution 0.5 --gain 0.5:1.5:2 --control-law pid --controller-rate 100 --integral-gain 0,0.2"
       " --derivative-gain 0.1",
       "restitution,backlash,gain,integral_gain,"},
      // The compliant keys in the chart form (the impacts column counts a compliant mesh's contact phases).
      {" --zeta 0.4 --mesh-stiffness 1e3,1e4 --mesh-damping 1,3",
       "zeta,inertia_ratio,friction_ratio,restitution,backlash,mesh_stiffness,mesh_damping,"}};
  for (const Grid& g : grids)
  {
    int code = 0;
    const std::string csv = runCapture(SWEEP + g.flags + " --jobs 2 2>/dev/null", &code);
    ASSERT_EQ(code, 0) << g.flags;
    EXPECT_EQ(csv.substr(0, g.header.size()), g.header);
    const auto rows = csvRows(csv);
    ASSERT_EQ(rows.size(), 4u);
    const int axes = static_cast<int>(std::count(g.header.begin(), g.header.end(), ','));
    std::vector<std::string> keys;
    std::stringstream hs(g.header);
    for (std::string k; std::getline(hs, k, ',');)
    {
      keys.push_back(k);
    }
    for (const auto& r : rows)
    {
      std::string flags = g.flags;
      for (int i = 0; i < axes; ++i)
      {
        std::string flag = "--" + keys[i];
        std::replace(flag.begin(), flag.end(), '_', '-');
        flags += " " + flag + " " + r[i];  // the last occurrence of a flag wins over the grid's list
      }
      // The sweep's own list values stand before: give backlash_sim only the point.
      std::string point;
      std::stringstream fs(flags);
      std::vector<std::string> words;
      for (std::string w; fs >> w;)
      {
        words.push_back(w);
      }
      for (std::size_t i = 0; i + 1 < words.size(); i += 2)
      {
        if (words[i + 1].find(',') == std::string::npos && words[i + 1].find(':') == std::string::npos)
        {
          point += " " + words[i] + " " + words[i + 1];
        }
      }
      const std::string json = runCapture(SIM + " --json" + point);
      EXPECT_EQ(r[axes], jsonText(json, "verdict")) << point;
      EXPECT_EQ(std::stod(r[axes + 2]), jsonNumber(json, "limit_cycle_error")) << point;
      const bool compliant = json.find("\"contact_phases\"") != std::string::npos;  // (only compliant runs have it)
      EXPECT_EQ(std::stod(r[axes + 4]), jsonNumber(json, compliant ? "contact_phases" : "impacts")) << point;
      if (r[axes] == "converged")
      {
        EXPECT_EQ(std::stod(r[axes + 7]), jsonNumber(json, "steady_error")) << point;
      }
    }
  }
  // Mixing the two forms is one clear error.
  int code = 0;
  const std::string err = runCapture(SWEEP + " --gain 1,2 --zeta 0.3,0.4 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("not both"), std::string::npos) << err;
}

TEST(Sweep, ResumeAfterAnInterruptionGivesTheSameCsv)
{
  const std::string full = "/tmp/backlash_sweep_full.csv", part = "/tmp/backlash_sweep_part.csv";
  int code = 0;
  runCapture(SWEEP + GRID + " --output " + full + " 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const std::string expected = readFile(full);
  // A torn file: header, the first three rows and half of the fourth.
  std::stringstream ss(expected);
  std::string line, torn;
  for (int i = 0; i < 4 && std::getline(ss, line); ++i)
  {
    torn += line + "\n";
  }
  std::getline(ss, line);
  torn += line.substr(0, line.size() / 2);
  std::ofstream(part) << torn;
  runCapture(SWEEP + GRID + " --output " + part + " --resume 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(readFile(part), expected);
  // A real interruption (SIGINT) leaves a valid prefix; --resume completes it identically.
  std::remove(part.c_str());
  const pid_t pid = fork();
  if (pid == 0)
  {
    const std::string args = SWEEP + GRID + " --jobs 1 --output " + part;
    execl("/bin/sh", "sh", "-c", ("exec " + args + " 2>/dev/null").c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  usleep(20000);
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  const int rc = WEXITSTATUS(status);
  EXPECT_TRUE(rc == 130 || rc == 0) << rc;
  EXPECT_EQ(expected.rfind(readFile(part), 0), 0u) << "interrupted output is not a prefix";
  runCapture(SWEEP + GRID + " --output " + part + " --resume 2>/dev/null", &code);
  EXPECT_EQ(readFile(part), expected);
}

TEST(Sweep, BadAxesAreOneLineErrors)
{
  int code = 0;
  const std::string err = runCapture(SWEEP + " --zeta 1:2 2>&1 >/dev/null", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("--zeta"), std::string::npos) << err;
  runCapture(SWEEP + " --friction-ratio 1.5 2>/dev/null", &code);
  EXPECT_EQ(code, 2);
}

// A real single-node Slurm (slurmctld, slurmd, munge started and stopped by the script): scripts/slurm_sweep.sh's
// and scripts/slurm_frf.sh's array jobs and dependent merge jobs write exactly the CSV of an unsharded run.
TEST(Slurm, ArrayJobPlusMergeEqualsTheUnshardedSweep)
{
  int code = 0;
  const std::string log =
      runCapture("timeout 300 bash " + std::string(SOURCE_DIR) + "/test/slurm/local_slurm_sweep.sh 4 2>&1", &code);
  EXPECT_EQ(code, 0) << log;
  EXPECT_NE(log.find("4-part array job + merge job = the unsharded CSV"), std::string::npos) << log;
  EXPECT_NE(log.find("3-part backlash_frf array job + merge job = the unsharded CSV"), std::string::npos) << log;
  EXPECT_NE(log.find("3-part tolerance study array job + merge job = the unsharded CSV"), std::string::npos) << log;
}

TEST(SweepOutput, RefusesDevicesAndGridsItDidNotWrite)
{
  int code = 0;
  const std::string err = runCapture(std::string(BACKLASH_SWEEP_EXE) + " --output /dev/null 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("not a regular file"), std::string::npos) << err;
  // --resume with a file from a different grid is refused, and the file is left as it was.
  const std::string part = ::testing::TempDir() + "sweep_other_grid.csv";
  runCapture(std::string(BACKLASH_SWEEP_EXE) + " --zeta 0.3,0.4 --output " + part + " 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const std::string before = readFile(part);
  const std::string refused =
      runCapture(std::string(BACKLASH_SWEEP_EXE) + " --zeta 0.5,0.6 --output " + part + " --resume 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(refused.find("different grid"), std::string::npos) << refused;
  EXPECT_EQ(readFile(part), before);
  // A grid too large to hold is refused before anything is allocated.
  runCapture(
      std::string(BACKLASH_SWEEP_EXE) + " --zeta 0:1:10000 --inertia-ratio 1:2:10000 --friction-ratio 0:1:10000 2>&1",
      &code);
  EXPECT_EQ(code, 2);
}

TEST(SweepShards, PartsInAnyOrderMergeIntoExactlyTheUnshardedCsv)
{
  const std::string dir = ::testing::TempDir();
  const std::string grid = " --zeta 0.1,0.3,0.5 --inertia-ratio 0.25,9 --friction-ratio 0,0.5 --restitution 0.6,1";
  const std::string sweep = std::string(BACKLASH_SWEEP_EXE) + grid;
  int code = 0;
  runCapture(sweep + " --output " + dir + "shard_whole.csv 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  for (int k : {4, 2, 1, 3})
  {
    runCapture(sweep + " --shard " + std::to_string(k) + "/4 --output " + dir + "shard_" + std::to_string(k) +
                   ".csv 2>/dev/null",
               &code);
    ASSERT_EQ(code, 0) << k;
  }
  const std::string merge = std::string(BACKLASH_SWEEP_EXE) + " --merge ";
  runCapture(merge + dir + "shard_3.csv " + dir + "shard_1.csv " + dir + "shard_4.csv " + dir +
                 "shard_2.csv --output " + dir + "shard_merged.csv 2>/dev/null",
             &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(readFile(dir + "shard_merged.csv"), readFile(dir + "shard_whole.csv"));
  // Missing, twice, another grid, incomplete: refused, nothing written.
  const std::string out = " --output " + dir + "shard_bad.csv 2>&1";
  std::remove((dir + "shard_bad.csv").c_str());
  std::string err = runCapture(merge + dir + "shard_1.csv " + dir + "shard_2.csv " + dir + "shard_3.csv" + out, &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("missing part(s) 4"), std::string::npos) << err;
  err = runCapture(merge + dir + "shard_1.csv " + dir + "shard_1.csv " + dir + "shard_2.csv " + dir + "shard_3.csv " +
                       dir + "shard_4.csv" + out,
                   &code);
  EXPECT_NE(err.find("given twice"), std::string::npos) << err;
  runCapture(std::string(BACKLASH_SWEEP_EXE) + " --zeta 0.2,0.4 --shard 4/4 --output " + dir + "shard_other.csv 2>&1",
             &code);
  err = runCapture(
      merge + dir + "shard_1.csv " + dir + "shard_2.csv " + dir + "shard_3.csv " + dir + "shard_other.csv" + out,
      &code);
  EXPECT_NE(err.find("another sweep"), std::string::npos) << err;
  const std::string part = readFile(dir + "shard_2.csv");
  std::ofstream(dir + "shard_torn.csv") << part.substr(0, part.size() - 20);
  err = runCapture(
      merge + dir + "shard_1.csv " + dir + "shard_torn.csv " + dir + "shard_3.csv " + dir + "shard_4.csv" + out, &code);
  EXPECT_NE(err.find("finish it with --resume"), std::string::npos) << err;
  EXPECT_FALSE(std::ifstream(dir + "shard_bad.csv").good());
  // A torn part is finished by --resume into the same part.
  runCapture(sweep + " --shard 2/4 --resume --output " + dir + "shard_torn.csv 2>/dev/null", &code);
  EXPECT_EQ(code, 0);
  EXPECT_EQ(readFile(dir + "shard_torn.csv"), part);
}

// --monte-carlo: N joints with the drawn keys as columns (each row equals backlash_sim at its drawn values), the
// same draws for the same seed in any shard (parts merge into the unsharded CSV) and other draws for another seed;
// the summary's verdict counts are the CSV's; bad requests are one line, exit 2.
TEST(Sweep, MonteCarloDrawsABatchAndSummarisesIt)
{
  const std::string dir = "/tmp/backlash_sweep_mc/";
  std::system(("rm -rf " + dir + " && mkdir -p " + dir).c_str());
  const std::string study =
      SWEEP + " --monte-carlo 24 --seed 5 --backlash 'uniform(0.05,0.5)' --vary 'zeta=normal(0.35,0.1)'";
  int code = 0;
  const std::string summary = runCapture(study + " --output " + dir + "all.csv 2>/dev/null", &code);
  ASSERT_EQ(code, 0) << summary;
  const std::string csv = readFile(dir + "all.csv");
  EXPECT_EQ(csv.rfind("zeta,inertia_ratio,friction_ratio,restitution,backlash,verdict,", 0), 0u) << csv;
  const auto rows = csvRows(csv);
  ASSERT_EQ(rows.size(), 24u);
  std::map<std::string, int> verdicts;
  std::vector<std::string> distinct;
  for (std::size_t i = 0; i < rows.size(); ++i)
  {
    const auto& r = rows[i];
    const double backlash = std::stod(r[4]);
    EXPECT_TRUE(backlash >= 0.05 && backlash <= 0.5) << r[4];
    ++verdicts[r[5]];
    distinct.push_back(r[0] + r[4]);
    if (i < 4)  // a few rows against single runs at the drawn values
    {
      const std::string json =
          runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio " + r[1] + " --friction-ratio " + r[2] +
                     " --restitution " + r[3] + " --backlash " + r[4]);
      EXPECT_EQ(r[5], jsonText(json, "verdict")) << r[0] << " " << r[4];
    }
  }
  std::sort(distinct.begin(), distinct.end());
  EXPECT_EQ(std::unique(distinct.begin(), distinct.end()), distinct.end());  // every joint drawn anew
  EXPECT_NE(summary.find("batch of 24 joints"), std::string::npos) << summary;
  for (const auto& v : verdicts)
  {
    EXPECT_TRUE(std::regex_search(summary, std::regex("  " + v.first + " +" + std::to_string(v.second) + " ")))
        << v.first << " " << v.second << "\n"
        << summary;
  }
  EXPECT_NE(summary.find("what separates hunting from settling"), std::string::npos) << summary;
  // Shards of the same study merge into exactly its CSV; another seed draws other joints.
  for (int k = 1; k <= 3; ++k)
  {
    runCapture(
        study + " --shard " + std::to_string(k) + "/3 --output " + dir + "p" + std::to_string(k) + ".csv 2>/dev/null",
        &code);
    ASSERT_EQ(code, 0);
  }
  runCapture(SWEEP + " --merge " + dir + "p3.csv " + dir + "p1.csv " + dir + "p2.csv --output " + dir +
                 "merged.csv 2>/dev/null",
             &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(readFile(dir + "merged.csv"), csv);
  // --resume of a torn study finishes it with the same draws.
  std::ofstream(dir + "torn.csv") << csv.substr(0, csv.size() / 2);
  runCapture(study + " --resume --output " + dir + "torn.csv >/dev/null 2>&1", &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(readFile(dir + "torn.csv"), csv);
  // --png: the chart beside the CSV (a PNG and its SVG), drawn from the same study.
  runCapture(study + " --output " + dir + "charted.csv --png " + dir + "batch.png >/dev/null 2>&1", &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(readFile(dir + "charted.csv"), csv);
  EXPECT_EQ(readFile(dir + "batch.png").substr(1, 3), "PNG");
  EXPECT_NE(readFile(dir + "batch.svg").find("<svg"), std::string::npos);
  const std::string other = runCapture(std::regex_replace(study, std::regex("--seed 5"), "--seed 6") + " 2>/dev/null");
  EXPECT_NE(csvRows(other)[0][4], rows[0][4]);
  for (const char* bad :
       {" --monte-carlo 10", " --backlash 'uniform(0.1,0.2)'",
        " --monte-carlo 10 --backlash "
        "'uniform(0.1,0.2)' --zeta 0.2,0.4",
        " --monte-carlo 10 --backlash 'uniform(-1,1)'", " --monte-carlo 10 --vary 'backlsh=uniform(0.1,0.2)'",
        " --monte-carlo 0 --backlash "
        "'uniform(0.1,0.2)'",
        " --seed 3",
        " --monte-carlo 10 --backlash 0.2 --vary "
        "'backlash=uniform(0.1,0.2)'",
        " --png /tmp/backlash_sweep_mc/x.png",
        " --monte-carlo 10 --backlash 'uniform(0.1,0.2)' --shard 1/2 --png /tmp/backlash_sweep_mc/x.png",
        " --monte-carlo 10 --backlash 'uniform(0.1,0.2)' --png /tmp/backlash_sweep_mc/x.jpg"})
  {
    const std::string err = runCapture(SWEEP + bad + " 2>&1 >/dev/null", &code);
    EXPECT_EQ(code, 2) << bad << ": " << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << bad << ": " << err;
  }
}
