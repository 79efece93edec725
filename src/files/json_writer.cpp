#include "backlash_servo/files/json_writer.h"

#include <cmath>
#include <cstdio>

namespace backlash_servo
{
std::string jsonQuote(const std::string& s)
{
  std::string q = "\"";
  for (char c : s)
  {
    if (c == '"' || c == '\\')
    {
      q += '\\';
      q += c;
    }
    else if (static_cast<unsigned char>(c) < 0x20)
    {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      q += buf;
    }
    else
    {
      q += c;
    }
  }
  return q + "\"";
}

void JsonWriter::prefix(const char* key)
{
  if (!first_.back())
  {
    out_ << ',';
  }
  first_.back() = false;
  if (key != nullptr)
  {
    out_ << jsonQuote(key) << ':';
  }
}

JsonWriter& JsonWriter::beginObject(const char* key)
{
  prefix(key);
  out_ << '{';
  first_.push_back(true);
  return *this;
}

JsonWriter& JsonWriter::endObject()
{
  first_.pop_back();
  out_ << '}';
  return *this;
}

JsonWriter& JsonWriter::beginArray(const char* key)
{
  prefix(key);
  out_ << '[';
  first_.push_back(true);
  return *this;
}

JsonWriter& JsonWriter::endArray()
{
  first_.pop_back();
  out_ << ']';
  return *this;
}

JsonWriter& JsonWriter::field(const char* key, double value)
{
  prefix(key);
  if (!std::isfinite(value))
  {
    out_ << "null";
    return *this;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", value);
  out_ << buf;
  return *this;
}

JsonWriter& JsonWriter::field(const char* key, long long value)
{
  prefix(key);
  out_ << value;
  return *this;
}

JsonWriter& JsonWriter::field(const char* key, bool value)
{
  prefix(key);
  out_ << (value ? "true" : "false");
  return *this;
}

JsonWriter& JsonWriter::field(const char* key, const std::string& value)
{
  prefix(key);
  out_ << jsonQuote(value);
  return *this;
}

JsonWriter& JsonWriter::null(const char* key)
{
  prefix(key);
  out_ << "null";
  return *this;
}

}  // namespace backlash_servo
