#include "arthrosim/core/yaml_fields.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "arthrosim/core/error.h"

namespace arthrosim {

int YamlLine(const YAML::Node& n) {
  if (!n.IsDefined() || n.Mark().is_null() || n.Mark().line < 0) return 0;
  return n.Mark().line + 1;
}

std::string FieldPath(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

std::string IndexedField(const std::string& field, std::size_t i) {
  return field + "[" + std::to_string(i) + "]";
}

YAML::Node ParseYaml(const std::string& text, const std::string& file) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0, "",
                     "YAML syntax error: " + e.msg);
  }
}

void YamlReader::Fail(const YAML::Node& n, const std::string& field,
                      const std::string& message) const {
  throw InputError(file_, YamlLine(n), field, message);
}

void YamlReader::Warn(const YAML::Node& n, const std::string& field,
                      const std::string& message) const {
  warnings_.push_back(InputError(file_, YamlLine(n), field, message).what());
}

void YamlReader::CheckKeys(const YAML::Node& map, const std::string& field,
                           const std::vector<const char*>& allowed) const {
  if (!map.IsMap()) Fail(map, field, "expected a map");
  for (const auto& kv : map) {
    const std::string key = Scalar(kv.first, field);
    if (std::any_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; }))
      continue;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    Fail(kv.first, FieldPath(field, key), "unknown key '" + key + "'; allowed: " + list);
  }
}

double YamlReader::Number(const YAML::Node& n, const std::string& field) const {
  if (!n.IsScalar()) Fail(n, field, "expected a number");
  double v = 0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    Fail(n, field, "expected a number, found '" + n.Scalar() + "'");
  }
  if (!std::isfinite(v)) Fail(n, field, "expected a finite number");
  return v;
}

std::int64_t YamlReader::Integer(const YAML::Node& n, const std::string& field,
                                 std::int64_t min_value, std::int64_t max_value) const {
  std::int64_t v = 0;
  try {
    if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "");
    v = n.as<std::int64_t>();
  } catch (const YAML::Exception&) {
    Fail(n, field, "expected an integer");
  }
  if (v < min_value) Fail(n, field, "must be >= " + std::to_string(min_value));
  if (v > max_value) Fail(n, field, "must be <= " + std::to_string(max_value));
  return v;
}

std::string YamlReader::Scalar(const YAML::Node& n, const std::string& field) const {
  if (!n.IsScalar()) Fail(n, field, "expected a string");
  return n.Scalar();
}

bool YamlReader::Bool(const YAML::Node& n, const std::string& field) const {
  try {
    if (n.IsScalar()) return n.as<bool>();
  } catch (const YAML::Exception&) {
  }
  Fail(n, field, "expected true or false");
}

Vec3 YamlReader::Vector(const YAML::Node& n, const std::string& field) const {
  if (!n.IsSequence() || n.size() != 3) Fail(n, field, "expected [x, y, z]");
  return Vec3(Number(n[0], field), Number(n[1], field), Number(n[2], field));
}

YamlSection::YamlSection(const YamlReader& reader, const YAML::Node& node, std::string field,
                         std::initializer_list<const char*> allowed)
    : YamlSection(reader, node, std::move(field), std::vector<const char*>(allowed)) {}

YamlSection::YamlSection(const YamlReader& reader, const YAML::Node& node, std::string field,
                         const std::vector<const char*>& allowed)
    : reader_(reader), node_(node), field_(std::move(field)) {
  reader_.CheckKeys(node_, field_, allowed);
}

void YamlSection::Fail(const char* key, const std::string& message) const {
  reader_.Fail(Has(key) ? Get(key) : node_, Field(key), message);
}

YAML::Node YamlSection::Required(const char* key) const {
  YAML::Node n = node_[key];
  if (!n) reader_.Fail(node_, Field(key), "required field is missing");
  return n;
}

double YamlSection::Number(const char* key, std::optional<double> fallback) const {
  if (!Has(key) && fallback) return *fallback;
  return reader_.Number(Required(key), Field(key));
}

double YamlSection::Positive(const char* key, std::optional<double> fallback) const {
  const double v = Number(key, fallback);
  if (!(v > 0)) Fail(key, "must be > 0");
  return v;
}

double YamlSection::NonNegative(const char* key, std::optional<double> fallback) const {
  const double v = Number(key, fallback);
  if (v < 0) Fail(key, "must be >= 0");
  return v;
}

double YamlSection::Quantity(const char* key, const QuantityRange& range,
                             std::optional<double> fallback) const {
  const double v = Number(key, fallback);
  if (!Has(key)) return v;
  const bool below = range.min_exclusive ? !(v > range.min) : !(v >= range.min);
  if (below || v > range.max) {
    Fail(key, fmt::format("must be in {}{:g}, {:g}] {}, got {:g}", range.min_exclusive ? "(" : "[",
                          range.min, range.max, range.unit, v));
  }
  if (v < range.usual_min || v > range.usual_max) {
    reader_.Warn(Get(key), Field(key),
                 fmt::format("{:g} {} is outside the usual range [{:g}, {:g}] {}: check the unit",
                             v, range.unit, range.usual_min, range.usual_max, range.unit));
  }
  return v;
}

std::int64_t YamlSection::Integer(const char* key, std::int64_t fallback, std::int64_t min_value,
                                  std::int64_t max_value) const {
  if (!Has(key)) return fallback;
  return reader_.Integer(Get(key), Field(key), min_value, max_value);
}

std::string YamlSection::String(const char* key, std::optional<std::string> fallback) const {
  if (!Has(key) && fallback) return *fallback;
  const YAML::Node n = Required(key);
  if (!n.IsScalar() || n.Scalar().empty())
    reader_.Fail(n, Field(key), "expected a non-empty string");
  return n.Scalar();
}

bool YamlSection::Bool(const char* key, bool fallback) const {
  return Has(key) ? reader_.Bool(Get(key), Field(key)) : fallback;
}

Vec3 YamlSection::Vector(const char* key, std::optional<Vec3> fallback) const {
  if (!Has(key) && fallback) return *fallback;
  return reader_.Vector(Required(key), Field(key));
}

YAML::Node YamlSection::Sequence(const char* key, bool required) const {
  if (!Has(key)) {
    if (required) Required(key);
    return YAML::Node(YAML::NodeType::Sequence);
  }
  YAML::Node n = Get(key);
  if (!n.IsSequence()) reader_.Fail(n, Field(key), "expected a list");
  return n;
}

}  // namespace arthrosim
