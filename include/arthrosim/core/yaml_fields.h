#pragma once
// Strict YAML field readers shared by every YAML input (scenarios, scripts, plans): each
// failure throws InputError naming the file, the line, the field path ("bodies[2].mesh") and
// what was expected. They sit in the core layer (library arthrosim_yaml_fields, which links
// yaml-cpp) because the scenario loader (io) and the script parser (input) are siblings that
// may not include each other; physics and sim do not link it.
#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim {

/// 1-based line of a node in its file; 0 when it has none (a missing key, a node built in code).
int YamlLine(const YAML::Node& n);

/// "parent.key", or "key" when parent is empty (the top level).
std::string FieldPath(const std::string& parent, const std::string& key);

/// "field[i]".
std::string IndexedField(const std::string& field, std::size_t i);

/// Parses YAML text; a syntax error throws InputError(file, line, "", "YAML syntax error: ...").
YAML::Node ParseYaml(const std::string& text, const std::string& file);

/// A physical quantity's plausible values: outside [min, max] (min itself excluded when
/// min_exclusive) no material, tool or clock has it, and reading it is an InputError; inside
/// that but outside [usual_min, usual_max] it is possible but unusual (a 1 Pa tissue, a 0.5 s
/// time step), and reading it records a warning. `unit` is how the file writes it.
struct QuantityRange {
  double min = 0;
  bool min_exclusive = true;
  double max = 0;
  double usual_min = 0;
  double usual_max = 0;
  const char* unit = "";
};

/// Reads the values of one YAML file strictly. Every failure throws InputError.
class YamlReader {
 public:
  explicit YamlReader(std::string file) : file_(std::move(file)) {}

  const std::string& file() const { return file_; }

  /// Throws InputError(file, line of n, field, message).
  [[noreturn]] void Fail(const YAML::Node& n, const std::string& field,
                         const std::string& message) const;
  /// Records "file:line: field 'f': message" in warnings() (the input is still accepted).
  void Warn(const YAML::Node& n, const std::string& field, const std::string& message) const;
  /// The warnings recorded so far, in reading order.
  const std::vector<std::string>& warnings() const { return warnings_; }
  /// Throws unless map is a map whose every key is in allowed ("unknown key 'x'; allowed: ...").
  void CheckKeys(const YAML::Node& map, const std::string& field,
                 const std::vector<const char*>& allowed) const;
  /// A finite number ("expected a number, found 'abc'").
  double Number(const YAML::Node& n, const std::string& field) const;
  /// A whole number in [min_value, max_value].
  std::int64_t Integer(const YAML::Node& n, const std::string& field, std::int64_t min_value,
                       std::int64_t max_value = std::numeric_limits<std::int64_t>::max()) const;
  /// A scalar as written (may be empty).
  std::string Scalar(const YAML::Node& n, const std::string& field) const;
  /// true or false.
  bool Bool(const YAML::Node& n, const std::string& field) const;
  /// [x, y, z] of finite numbers.
  Vec3 Vector(const YAML::Node& n, const std::string& field) const;

 private:
  std::string file_;
  mutable std::vector<std::string> warnings_;  // reading records warnings; it never changes input
};

/// A YAML map whose keys are checked against an allowed list on construction (so a typo is an
/// error), with typed getters: a getter without a fallback makes its key required.
class YamlSection {
 public:
  /// Throws unless node is a map with allowed keys only. reader must outlive the section.
  YamlSection(const YamlReader& reader, const YAML::Node& node, std::string field,
              std::initializer_list<const char*> allowed);
  YamlSection(const YamlReader& reader, const YAML::Node& node, std::string field,
              const std::vector<const char*>& allowed);

  bool Has(const char* key) const { return static_cast<bool>(node_[key]); }
  YAML::Node Get(const char* key) const { return node_[key]; }
  /// The field path of key ("materials.muscle.density").
  std::string Field(const char* key) const { return FieldPath(field_, key); }
  const std::string& field() const { return field_; }
  const YAML::Node& node() const { return node_; }
  const YamlReader& reader() const { return reader_; }

  /// Throws InputError naming key's field (at key's line, or the map's when absent).
  [[noreturn]] void Fail(const char* key, const std::string& message) const;
  /// node[key]; throws "required field is missing" when absent.
  YAML::Node Required(const char* key) const;
  /// A finite number; the fallback when absent (required without one).
  double Number(const char* key, std::optional<double> fallback = std::nullopt) const;
  /// A number > 0.
  double Positive(const char* key, std::optional<double> fallback = std::nullopt) const;
  /// A number >= 0.
  double NonNegative(const char* key, std::optional<double> fallback = std::nullopt) const;
  /// A number within range (outside it: InputError naming the range and unit); a warning when
  /// outside the usual part of it. A fallback is returned unchecked.
  double Quantity(const char* key, const QuantityRange& range,
                  std::optional<double> fallback = std::nullopt) const;
  /// A whole number in [min_value, max_value]; the fallback when absent. Counts that size
  /// memory or loops take a max_value, so an absurd one is an error, not an allocation failure
  /// or a hang.
  std::int64_t Integer(const char* key, std::int64_t fallback, std::int64_t min_value,
                       std::int64_t max_value = std::numeric_limits<std::int64_t>::max()) const;
  /// A non-empty string; the fallback when absent (required without one).
  std::string String(const char* key, std::optional<std::string> fallback = std::nullopt) const;
  /// true or false; the fallback when absent.
  bool Bool(const char* key, bool fallback) const;
  /// [x, y, z]; the fallback when absent (required without one).
  Vec3 Vector(const char* key, std::optional<Vec3> fallback = std::nullopt) const;
  /// A list (empty when absent and not required).
  YAML::Node Sequence(const char* key, bool required) const;

 private:
  const YamlReader& reader_;
  YAML::Node node_;
  std::string field_;
};

}  // namespace arthrosim
