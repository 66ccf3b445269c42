#pragma once
// Internal: a bounds-checked reader over a whole file held in memory. Text access is token
// based with 1-based line tracking; binary access reads little-endian values and reports byte
// offsets. Every failure throws arthrosim::InputError, so parsers never read past the end.
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "arthrosim/core/error.h"

namespace arthrosim::mesh::detail {

class Cursor {
 public:
  Cursor(std::string file, std::string_view bytes) : file_(std::move(file)), buf_(bytes) {}

  const std::string& file() const { return file_; }
  std::size_t pos() const { return pos_; }
  std::size_t size() const { return buf_.size(); }
  std::size_t remaining() const { return buf_.size() - pos_; }
  int line() const { return token_line_; }
  bool AtEnd() const { return pos_ >= buf_.size(); }
  std::string_view bytes() const { return buf_; }

  /// Throws at the line of the last token read.
  [[noreturn]] void Fail(const std::string& field, const std::string& message) const {
    if (binary_mode_) FailAt(token_start_, field, message);
    throw InputError(file_, token_line_, field, message);
  }
  /// In binary mode line numbers mean nothing: Fail() cites the byte offset instead.
  void SetBinaryMode(bool on) { binary_mode_ = on; }
  /// Throws citing the current byte offset (for binary data).
  [[noreturn]] void FailAt(std::size_t offset, const std::string& field,
                           const std::string& message) const {
    throw InputError(file_, 0, field, "at byte offset " + std::to_string(offset) + ": " + message);
  }

  /// Skips spaces, tabs, CR and newlines; returns false at end of file.
  bool SkipSpace() {
    while (pos_ < buf_.size()) {
      const char c = buf_[pos_];
      if (c == '\n') {
        ++line_;
      } else if (c != ' ' && c != '\t' && c != '\r' && c != '\f' && c != '\v') {
        break;
      }
      ++pos_;
    }
    token_line_ = line_;
    token_start_ = pos_;
    return pos_ < buf_.size();
  }

  /// Next whitespace-delimited token, or InputError naming `field` at end of file.
  std::string_view Token(const std::string& field) {
    if (!SkipSpace()) Fail(field, "unexpected end of file (truncated?) while reading " + field);
    const std::size_t start = pos_;
    while (pos_ < buf_.size() && !IsSpace(buf_[pos_])) ++pos_;
    return buf_.substr(start, pos_ - start);
  }

  /// Next token if any (empty at end of file); never throws.
  std::string_view TryToken() {
    if (!SkipSpace()) return {};
    const std::size_t start = pos_;
    while (pos_ < buf_.size() && !IsSpace(buf_[pos_])) ++pos_;
    return buf_.substr(start, pos_ - start);
  }

  /// The rest of the current line (without CR/LF), advancing past its newline.
  std::string_view RestOfLine() {
    token_line_ = line_;
    const std::size_t start = pos_;
    while (pos_ < buf_.size() && buf_[pos_] != '\n') ++pos_;
    std::size_t end = pos_;
    if (pos_ < buf_.size()) {
      ++pos_;
      ++line_;
    }
    while (end > start && buf_[end - 1] == '\r') --end;
    return buf_.substr(start, end - start);
  }

  /// Requires the next token to equal `expected`.
  void Expect(std::string_view expected, const std::string& field) {
    const std::string_view t = Token(field);
    if (t != expected) {
      Fail(field, "expected '" + std::string(expected) + "' but found '" + Shorten(t) + "'");
    }
  }

  /// Integer token (optional sign, decimal digits only).
  std::int64_t Int(const std::string& field) {
    const std::string_view t = Token(field);
    std::int64_t v = 0;
    if (!ParseInt(t, &v)) Fail(field, "expected an integer but found '" + Shorten(t) + "'");
    return v;
  }

  /// Integer token within [lo, hi].
  std::int64_t IntIn(const std::string& field, std::int64_t lo, std::int64_t hi) {
    const std::int64_t v = Int(field);
    if (v < lo || v > hi) {
      Fail(field, "value " + std::to_string(v) + " out of range [" + std::to_string(lo) + ", " +
                      std::to_string(hi) + "]");
    }
    return v;
  }

  /// A declared element count; rejects counts the rest of the file cannot possibly hold,
  /// given that each item needs at least `min_bytes_per_item` bytes.
  std::int64_t Count(const std::string& field, std::size_t min_bytes_per_item) {
    const std::int64_t n = Int(field);
    CheckCount(n, min_bytes_per_item, field);
    return n;
  }
  void CheckCount(std::int64_t n, std::size_t min_bytes_per_item, const std::string& field) const {
    if (n < 0) Fail(field, "expected a non-negative count but found " + std::to_string(n));
    if (min_bytes_per_item > 0 &&
        static_cast<std::uint64_t>(n) > remaining() / min_bytes_per_item + 1) {
      Fail(field, "declared count " + std::to_string(n) + " exceeds what the remaining " +
                      std::to_string(remaining()) + " bytes of the file can hold (truncated?)");
    }
  }

  /// Floating-point token; accepts what strtod accepts in the C locale except hex.
  double Real(const std::string& field) {
    const std::string_view t = Token(field);
    double v = 0;
    if (!ParseReal(t, &v)) Fail(field, "expected a number but found '" + Shorten(t) + "'");
    return v;
  }

  /// Finite floating-point token (a coordinate).
  double Finite(const std::string& field) {
    const double v = Real(field);
    if (!(v - v == 0.0)) Fail(field, "non-finite coordinate '" + std::to_string(v) + "'");
    return v;
  }

  /// Reads a little-endian binary value of type T.
  template <class T>
  T Bin(const std::string& field) {
    if (remaining() < sizeof(T)) {
      FailAt(pos_, field,
             "unexpected end of file (truncated?) reading " + std::to_string(sizeof(T)) +
                 "-byte binary " + field);
    }
    T v;
    std::memcpy(&v, buf_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  void SkipBytes(std::size_t n, const std::string& field) {
    if (remaining() < n) FailAt(pos_, field, "unexpected end of file (truncated?)");
    pos_ += n;
  }
  /// A saved position (with its line count) for one-token look-ahead.
  struct Mark {
    std::size_t pos;
    int line;
  };
  Mark Save() const { return {pos_, line_}; }
  void Restore(Mark m) {
    pos_ = m.pos;
    line_ = m.line;
    token_line_ = m.line;
  }
  /// Moves forward to byte `p`, counting the newlines passed (keeps line numbers right).
  void AdvanceTo(std::size_t p) {
    for (; pos_ < p && pos_ < buf_.size(); ++pos_) {
      if (buf_[pos_] == '\n') ++line_;
    }
    token_line_ = line_;
  }

  static bool IsSpace(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
  }
  static bool ParseInt(std::string_view t, std::int64_t* out);
  static bool ParseReal(std::string_view t, double* out);
  /// A token clipped for messages (garbage may be long or binary).
  static std::string Shorten(std::string_view t);

 private:
  std::string file_;
  std::string_view buf_;
  std::size_t pos_ = 0;
  int line_ = 1;
  int token_line_ = 1;
  std::size_t token_start_ = 0;
  bool binary_mode_ = false;
};

/// Reads a whole file; InputError if it cannot be opened or is not a regular file.
std::string ReadFileBytes(const std::string& path);

/// Lower-case extension without the dot ("" if none).
std::string LowerExtension(const std::string& path);

}  // namespace arthrosim::mesh::detail
