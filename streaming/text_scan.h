// Small text-scanning helpers shared by the ASCII readers (PLY, STL, OBJ):
// physical-line cursor over a mapped file, whitespace tokenizer, and number
// parsing with std::from_chars (locale-independent, no allocation).
#pragma once

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string_view>

namespace raylod::text {

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// Iterates physical lines of `text` from `offset`, stripping "\n" / "\r\n".
// Text in classic Mac OS's convention ends its lines with "\r" alone: one
// whose first 64 KiB (from `offset`) hold a "\r" and no "\n" is split at
// "\r" instead.
class LineCursor {
 public:
  LineCursor() = default;
  LineCursor(std::string_view text, size_t offset = 0, uint64_t first_line = 1)
      : text_(text), pos_(offset), next_line_(first_line) {
    if (pos_ < text_.size()) {
      const size_t window = std::min<size_t>(text_.size() - pos_, size_t(1) << 16);
      if (!std::memchr(text_.data() + pos_, '\n', window) && std::memchr(text_.data() + pos_, '\r', window))
        end_ = '\r';
    }
  }
  // False at the end of the text.
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const char* begin = text_.data() + pos_;
    const void* nl = std::memchr(begin, end_, text_.size() - pos_);
    size_t len = nl ? size_t(static_cast<const char*>(nl) - begin) : text_.size() - pos_;
    pos_ += len + (nl ? 1 : 0);
    if (len > 0 && begin[len - 1] == '\r') --len;
    line = std::string_view(begin, len);
    line_ = next_line_++;
    return true;
  }
  uint64_t line_number() const { return line_; }  // of the line last returned
  size_t offset() const { return pos_; }           // just past the line last returned
  bool at_end() const { return pos_ >= text_.size(); }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  uint64_t next_line_ = 1, line_ = 0;
  char end_ = '\n';  // the line terminator
};

// Whitespace-separated tokens of one line.
struct Tokens {
  std::string_view rest;
  explicit Tokens(std::string_view line) : rest(line) {}
  bool next(std::string_view& tok) {
    size_t i = 0;
    while (i < rest.size() && is_space(rest[i])) ++i;
    if (i == rest.size()) { rest = {}; return false; }
    size_t j = i;
    while (j < rest.size() && !is_space(rest[j])) ++j;
    tok = rest.substr(i, j - i);
    rest.remove_prefix(j);
    return true;
  }
  // True if only whitespace is left.
  bool done() {
    while (!rest.empty() && is_space(rest.front())) rest.remove_prefix(1);
    return rest.empty();
  }
};

// Whole-token parses; "+1.5" is accepted, "1.5x" is not. NaN/Inf parse (the
// callers report them as non-finite with the line number).
inline bool parse_number(std::string_view tok, double& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size();
}
inline bool parse_number(std::string_view tok, float& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size();
}
inline bool parse_number(std::string_view tok, int64_t& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size();
}

// Whether a number token that from_chars rejected as out of range overflowed
// (its decimal exponent is positive, "1e400") rather than underflowed ("1e-400").
inline bool overflows(std::string_view tok) {
  size_t i = 0;
  if (i < tok.size() && (tok[i] == '+' || tok[i] == '-')) ++i;
  int64_t int_digits = 0, point_zeros = 0;  // significant digits before the point; zeros after it before any
  bool point = false, significant = false;
  for (; i < tok.size(); ++i) {
    const char c = tok[i];
    if (c == '.') { point = true; continue; }
    if (c < '0' || c > '9') break;
    if (!significant && c == '0') { point_zeros += point; continue; }
    significant = true;
    int_digits += !point;
  }
  int64_t exponent = 0;
  if (i + 1 < tok.size() && (tok[i] == 'e' || tok[i] == 'E')) {
    std::string_view e = tok.substr(i + 1);
    const bool negative = e.front() == '-';
    if (e.front() == '+' || negative) e.remove_prefix(1);
    // An exponent past int64 decides on its own.
    if (std::from_chars(e.data(), e.data() + e.size(), exponent).ec != std::errc()) return !negative;
    if (negative) exponent = -exponent;
  }
  const int64_t magnitude = int_digits > 0 ? int_digits - 1 : -(point_zeros + 1);
  return magnitude + exponent > 0;
}

// FarFromOrigin: the value is a float, but not its difference from the
// mesh's local origin (parse_coordinate): the mesh spans more than floats hold.
enum class FloatParse { Ok, NotANumber, OutOfRange, FarFromOrigin };

// A float coordinate or normal component. A value that rounds beyond the
// float range (|x| >= 2^128 - 2^103, about 3.4e38, e.g. "1e39") is
// OutOfRange, not "not a number": it is a number no float holds. Tiny values
// round to a subnormal or zero like any float parse. "nan" and "inf" are Ok
// (the callers report them as non-finite).
inline FloatParse parse_float(std::string_view tok, float& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return FloatParse::NotANumber;
  const char* end = tok.data() + tok.size();
  auto r = std::from_chars(tok.data(), end, out);
  if (r.ptr != end) return FloatParse::NotANumber;
  if (r.ec == std::errc()) return FloatParse::Ok;
  if (r.ec != std::errc::result_out_of_range) return FloatParse::NotANumber;
  // Over- or underflow of float: a double tells which (and rounds underflow).
  double d = 0;
  if (std::from_chars(tok.data(), end, d).ec == std::errc()) {
    if (!(std::fabs(d) < 0x1.ffffffp+127)) return FloatParse::OutOfRange;
    out = float(d);
    return FloatParse::Ok;
  }
  if (overflows(tok)) return FloatParse::OutOfRange;
  out = tok.front() == '-' ? -0.0f : 0.0f;
  return FloatParse::Ok;
}

// Bytes of a UTF-8 byte order mark at the start of a text file (3), or 0.
// Editors on Windows write one; the readers skip it rather than read it as
// part of the first keyword.
inline size_t utf8_bom_bytes(std::string_view text) {
  return text.size() >= 3 && text[0] == '\xEF' && text[1] == '\xBB' && text[2] == '\xBF' ? 3 : 0;
}

inline bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    char x = a[i], y = b[i];
    if (x >= 'A' && x <= 'Z') x = char(x - 'A' + 'a');
    if (y >= 'A' && y <= 'Z') y = char(y - 'A' + 'a');
    if (x != y) return false;
  }
  return true;
}

// Shortens a token for an error message.
inline std::string_view clip(std::string_view s, size_t n = 40) { return s.size() > n ? s.substr(0, n) : s; }

// A number as double (the first vertex of a text mesh, which decides the
// mesh's local origin). False if the token is not a number or not finite.
inline bool parse_double(std::string_view tok, double& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  const char* end = tok.data() + tok.size();
  auto r = std::from_chars(tok.data(), end, out);
  return !tok.empty() && r.ptr == end && r.ec == std::errc() && std::isfinite(out);
}

// A vertex coordinate relative to the mesh's local origin along its axis
// (MeshHeader::origin): exactly parse_float when the origin is 0; otherwise
// the double value minus the origin, rounded to float once. The value
// itself must lie in the float range, as for parse_float.
inline FloatParse parse_coordinate(std::string_view tok, double origin, float& out) {
  if (origin == 0) return parse_float(tok, out);
  const FloatParse range = parse_float(tok, out);
  if (range != FloatParse::Ok) return range;
  double d = 0;
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  // In range for parse_float, so out of range for a double means underflow.
  if (std::from_chars(tok.data(), tok.data() + tok.size(), d).ec == std::errc::result_out_of_range) d = 0;
  out = float(d - origin);
  return std::isfinite(out) ? FloatParse::Ok : FloatParse::FarFromOrigin;
}

}  // namespace raylod::text
