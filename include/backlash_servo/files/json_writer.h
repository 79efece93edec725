/**
 * @file json_writer.h
 * @brief Minimal streaming JSON writer for the command-line tools (numbers round-trip exactly, %.17g).
 */
#pragma once

#include <ostream>
#include <string>
#include <vector>

namespace backlash_servo
{
class JsonWriter
{
 public:
  explicit JsonWriter(std::ostream& out) : out_(out) {}
  JsonWriter& beginObject(const char* key = nullptr);
  JsonWriter& endObject();
  JsonWriter& beginArray(const char* key = nullptr);
  JsonWriter& endArray();
  JsonWriter& field(const char* key, double value);  ///< non-finite values are written as null
  JsonWriter& field(const char* key, long long value);
  JsonWriter& field(const char* key, bool value);
  JsonWriter& field(const char* key, const std::string& value);
  JsonWriter& null(const char* key);

 private:
  void prefix(const char* key);
  std::ostream& out_;
  std::vector<bool> first_{true};
};

/// JSON string literal with escapes.
std::string jsonQuote(const std::string& s);

}  // namespace backlash_servo
