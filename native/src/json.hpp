// A small JSON reader for the module's manifest (RFC 8259: objects, arrays, strings, numbers, true, false, null).
// Numbers are read with std::from_chars, which is exact and ignores the C locale: the manifest's floats are
// Python's repr, the shortest text that reads back to the same float64. Errors throw rocks::Error naming the
// byte offset.
#pragma once

#include <charconv>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "error.hpp"

namespace rocks {

class Json {
 public:
  enum Kind { Null, Bool, Number, String, Array, Object };

  Json() = default;
  static Json parse(const std::string& text, const std::string& what);

  Kind kind() const { return kind_; }
  bool has(const std::string& key) const { return kind_ == Object && object_.count(key) != 0; }
  // member or element access: a missing key, a wrong kind or an index out of range throws Error naming `path_`
  const Json& operator[](const std::string& key) const;
  const Json& operator[](size_t i) const;
  size_t size() const;
  double number() const;
  int64_t integer() const;  // a number that is a whole int64
  bool boolean() const;
  const std::string& string() const;
  std::vector<double> numbers() const;  // an array of numbers
  const std::map<std::string, Json>& members() const;
  const std::string& path() const { return path_; }

 private:
  Kind kind_ = Null;
  bool bool_ = false;
  double number_ = 0.0;
  std::string string_;
  std::vector<Json> array_;
  std::map<std::string, Json> object_;
  std::string path_;  // where this value is, for messages ("manifest.json: host.table.size")

  friend class JsonParser;
  [[noreturn]] void wrong(const char* want) const;
};

}  // namespace rocks
