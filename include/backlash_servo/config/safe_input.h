// Reading an input file the way every tool should: a regular file only, and bounded; and its CSV lines.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace backlash_servo
{
/**
 * The whole content of `path`. Throws ConfigError naming `flag` (one line) when the path is missing, is a
 * directory, device, FIFO or socket (a FIFO or /dev/zero would be read for ever), or is larger than `max_bytes`.
 */
std::string readRegularFile(const std::string& flag, const std::string& path, std::size_t max_bytes);

/// The comma-separated cells of one CSV line, empty cells kept ("a,,b," → a, "", b, "").
std::vector<std::string> splitCsvCells(const std::string& line);

}  // namespace backlash_servo
