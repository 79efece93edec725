// Shared by the tools' tests: where the built tools are, and reading their CSV and JSON.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "test_helpers.h"

namespace tools_test
{
using test_helpers::readFile;
using test_helpers::runCapture;

inline std::vector<std::vector<std::string>> csvRows(const std::string& text)
{
  std::vector<std::vector<std::string>> rows;
  std::stringstream ss(text);
  std::string line;
  std::getline(ss, line);  // header
  while (std::getline(ss, line))
  {
    std::vector<std::string> cells;
    std::stringstream ls(line);
    std::string cell;
    while (std::getline(ls, cell, ','))
    {
      cells.push_back(cell);
    }
    if (!line.empty() && line.back() == ',')
    {
      cells.emplace_back();  // a trailing empty cell
    }
    rows.push_back(cells);
  }
  return rows;
}

inline double jsonNumber(const std::string& json, const std::string& key)
{
  std::smatch m;
  if (!std::regex_search(json, m, std::regex("\"" + key + "\":(-?[0-9.eE+-]+)")))
  {
    ADD_FAILURE() << "no " << key << " in " << json.substr(0, 300);
    return NAN;
  }
  return std::stod(m[1]);
}

inline std::string jsonText(const std::string& json, const std::string& key)
{
  std::smatch m;
  if (!std::regex_search(json, m, std::regex("\"" + key + "\":\"([a-z_]+)\"")))
  {
    return "";
  }
  return m[1];
}

inline const std::string SWEEP = BACKLASH_SWEEP_EXE;
inline const std::string SIM = BACKLASH_SIM_EXE;
inline const std::string DESIGN = BACKLASH_DESIGN_EXE;
inline const std::string COMPARE = BACKLASH_COMPARE_EXE;
inline const std::string DF = BACKLASH_DF_EXE;
inline const std::string FRF = BACKLASH_FRF_EXE;
inline const std::string IDENTIFY = BACKLASH_IDENTIFY_EXE;
inline const std::string GRID = " --zeta 0.3,0.6 --inertia-ratio 1,9 --friction-ratio 0.4 --restitution 0,0.6,1";

/// A 100:1 robot joint under gravity with dry friction, a 1 kHz PID on a 17-bit load encoder and a 0.5 N·m torque
/// limit (gains given by each test).
inline const std::string ROBOT_JOINT =
    " --motor-inertia 3e-5 --load-inertia 0.12 --motor-friction 5e-5 --load-friction 0.05 --gear-ratio 0.01"
    " --backlash 0.002618 --restitution 0.3 --load-torque -3.5 --motor-coulomb-friction 0.005"
    " --load-coulomb-friction 0.2 --control-law pid --controller-rate 1000 --load-encoder-resolution 131072"
    " --derivative-gain 0.3 --torque-limit 0.5 --command 0.5";
}  // namespace tools_test
