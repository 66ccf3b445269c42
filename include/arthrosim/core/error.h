#pragma once
// Errors for bad input. Every message names where the problem is (file, line, field) and what
// was expected, so a user can fix the input without reading code. Header-only so that the
// bottom layers (mesh) can throw it without linking core.
#include <stdexcept>
#include <string>

namespace arthrosim {

/// Bad user input (scenario, mesh, trajectory, command line). The CLI maps it to exit code 2.
class InputError : public std::runtime_error {
 public:
  /// line is 1-based; 0 means unknown. field may be empty.
  InputError(std::string file, int line, std::string field, const std::string& message)
      : std::runtime_error(Format(file, line, field, message)),
        file_(std::move(file)),
        line_(line),
        field_(std::move(field)) {}

  const std::string& file() const { return file_; }
  int line() const { return line_; }
  const std::string& field() const { return field_; }

 private:
  static std::string Format(const std::string& file, int line, const std::string& field,
                            const std::string& message) {
    // Appended piecewise: GCC 12 warns (-Wrestrict, falsely) on "literal" + std::string here.
    std::string s = file.empty() ? std::string("<input>") : file;
    if (line > 0) {
      s += ':';
      s += std::to_string(line);
    }
    if (!field.empty()) {
      s += ": field '";
      s += field;
      s += '\'';
    }
    s += ": ";
    s += message;
    return s;
  }
  std::string file_;
  int line_ = 0;
  std::string field_;
};

}  // namespace arthrosim
