// The manifest's JSON reader (json.hpp).
#include "json.hpp"

#include <cmath>

namespace rocks {

class JsonParser {
 public:
  JsonParser(const std::string& text, const std::string& what) : s_(text), what_(what) {}

  Json document() {
    Json v = value(what_);
    space();
    if (i_ != s_.size()) fail("text after the end of the document");
    return v;
  }

 private:
  const std::string& s_;
  std::string what_;
  size_t i_ = 0;
  int depth_ = 0;

  [[noreturn]] void fail(const std::string& why) const {
    throw Error(ROCKS_ERROR_MODULE, what_ + ": not valid JSON at byte " + std::to_string(i_) + ": " + why);
  }
  void space() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\r' || s_[i_] == '\t')) i_++;
  }
  bool take(const char* word) {
    size_t n = std::char_traits<char>::length(word);
    if (s_.compare(i_, n, word) == 0) {
      i_ += n;
      return true;
    }
    return false;
  }

  Json value(const std::string& path) {
    if (++depth_ > 64) fail("nested too deeply");
    space();
    if (i_ >= s_.size()) fail("unexpected end");
    Json v;
    v.path_ = path;
    char c = s_[i_];
    if (c == '{') {
      v.kind_ = Json::Object;
      i_++;
      space();
      if (i_ < s_.size() && s_[i_] == '}') {
        i_++;
      } else {
        for (;;) {
          space();
          if (i_ >= s_.size() || s_[i_] != '"') fail("expected a key");
          std::string key = str();
          space();
          if (i_ >= s_.size() || s_[i_] != ':') fail("expected ':'");
          i_++;
          v.object_[key] = value(path == what_ ? what_ + ": " + key : path + "." + key);
          space();
          if (i_ < s_.size() && s_[i_] == ',') { i_++; continue; }
          if (i_ < s_.size() && s_[i_] == '}') { i_++; break; }
          fail("expected ',' or '}'");
        }
      }
    } else if (c == '[') {
      v.kind_ = Json::Array;
      i_++;
      space();
      if (i_ < s_.size() && s_[i_] == ']') {
        i_++;
      } else {
        for (;;) {
          v.array_.push_back(value(path + "[" + std::to_string(v.array_.size()) + "]"));
          space();
          if (i_ < s_.size() && s_[i_] == ',') { i_++; continue; }
          if (i_ < s_.size() && s_[i_] == ']') { i_++; break; }
          fail("expected ',' or ']'");
        }
      }
    } else if (c == '"') {
      v.kind_ = Json::String;
      v.string_ = str();
    } else if (take("true")) {
      v.kind_ = Json::Bool;
      v.bool_ = true;
    } else if (take("false")) {
      v.kind_ = Json::Bool;
    } else if (take("null")) {
      v.kind_ = Json::Null;
    } else {
      v.kind_ = Json::Number;
      size_t start = i_;
      while (i_ < s_.size() && (std::isdigit(static_cast<unsigned char>(s_[i_])) || s_[i_] == '-' ||
                                s_[i_] == '+' || s_[i_] == '.' || s_[i_] == 'e' || s_[i_] == 'E'))
        i_++;
      const char* first = s_.data() + start;
      const char* last = s_.data() + i_;
      if (first != last && *first == '+') fail("a number may not start with '+'");
      auto r = std::from_chars(first, last, v.number_);  // exact, locale-free
      if (r.ec != std::errc() || r.ptr != last) fail("not a number");
    }
    depth_--;
    return v;
  }

  std::string str() {
    std::string out;
    i_++;  // the opening quote
    while (i_ < s_.size() && s_[i_] != '"') {
      char c = s_[i_++];
      if (c != '\\') {
        out += c;
        continue;
      }
      if (i_ >= s_.size()) break;
      char e = s_[i_++];
      switch (e) {
        case '"': out += '"'; break;
        case '\\': out += '\\'; break;
        case '/': out += '/'; break;
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          if (i_ + 4 > s_.size()) fail("a short \\u escape");
          unsigned cp = 0;
          auto r = std::from_chars(s_.data() + i_, s_.data() + i_ + 4, cp, 16);
          if (r.ec != std::errc() || r.ptr != s_.data() + i_ + 4) fail("a bad \\u escape");
          i_ += 4;
          if (cp >= 0xD800 && cp < 0xDC00 && i_ + 6 <= s_.size() && s_[i_] == '\\' && s_[i_ + 1] == 'u') {
            unsigned lo = 0;
            auto r2 = std::from_chars(s_.data() + i_ + 2, s_.data() + i_ + 6, lo, 16);
            if (r2.ec == std::errc() && lo >= 0xDC00 && lo < 0xE000) {
              cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
              i_ += 6;
            }
          }
          if (cp < 0x80) {
            out += static_cast<char>(cp);
          } else if (cp < 0x800) {
            out += static_cast<char>(0xC0 | (cp >> 6));
            out += static_cast<char>(0x80 | (cp & 0x3F));
          } else if (cp < 0x10000) {
            out += static_cast<char>(0xE0 | (cp >> 12));
            out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
            out += static_cast<char>(0x80 | (cp & 0x3F));
          } else {
            out += static_cast<char>(0xF0 | (cp >> 18));
            out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
            out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
            out += static_cast<char>(0x80 | (cp & 0x3F));
          }
          break;
        }
        default: fail("a bad escape");
      }
    }
    if (i_ >= s_.size()) fail("an unterminated string");
    i_++;  // the closing quote
    return out;
  }
};

Json Json::parse(const std::string& text, const std::string& what) { return JsonParser(text, what).document(); }

void Json::wrong(const char* want) const {
  static const char* names[] = {"null", "a boolean", "a number", "a string", "an array", "an object"};
  throw Error(ROCKS_ERROR_MODULE, path_ + ": expected " + want + ", got " + names[kind_]);
}

const Json& Json::operator[](const std::string& key) const {
  if (kind_ != Object) wrong("an object");
  auto it = object_.find(key);
  if (it == object_.end()) throw Error(ROCKS_ERROR_MODULE, path_ + ": no key \"" + key + "\"");
  return it->second;
}

const Json& Json::operator[](size_t i) const {
  if (kind_ != Array) wrong("an array");
  if (i >= array_.size())
    throw Error(ROCKS_ERROR_MODULE, path_ + ": no element " + std::to_string(i) + " (it has " +
                                        std::to_string(array_.size()) + ")");
  return array_[i];
}

size_t Json::size() const {
  if (kind_ == Array) return array_.size();
  if (kind_ == Object) return object_.size();
  wrong("an array or an object");
}

double Json::number() const {
  if (kind_ != Number) wrong("a number");
  return number_;
}

int64_t Json::integer() const {
  double v = number();
  if (!(std::fabs(v) <= 9007199254740992.0) || std::floor(v) != v) wrong("a whole number");
  return static_cast<int64_t>(v);
}

bool Json::boolean() const {
  if (kind_ != Bool) wrong("true or false");
  return bool_;
}

const std::string& Json::string() const {
  if (kind_ != String) wrong("a string");
  return string_;
}

std::vector<double> Json::numbers() const {
  std::vector<double> out;
  for (size_t i = 0; i < size(); i++) out.push_back((*this)[i].number());
  return out;
}

const std::map<std::string, Json>& Json::members() const {
  if (kind_ != Object) wrong("an object");
  return object_;
}

}  // namespace rocks
