// What the tools' CSV output shares: the sharded tools' (backlash_sweep, backlash_frf) `--merge PART... FLAG FILE`
// command line, and the number format of the rows (also backlash_compare's).
#pragma once

#include <string>
#include <vector>

namespace backlash_servo
{
/// Reads `--merge PART... <output_flag> FILE` from argv into *parts and *output. On any other flag prints
/// "<tool>: error: ..." on stderr and returns false.
bool readMergeArguments(int argc, char** argv, const std::string& tool, const std::string& output_flag,
                        std::vector<std::string>* parts, std::string* output);

/// A CSV number: %.10g, empty for NaN and ±inf.
std::string csvNumber(double v);

}  // namespace backlash_servo
