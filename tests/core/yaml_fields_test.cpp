#include "arthrosim/core/yaml_fields.h"

#include <gtest/gtest.h>

#include <string>

#include "arthrosim/core/error.h"

namespace arthrosim {
namespace {

/// The message of the InputError that f throws ("" and a test failure if none).
template <class F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an InputError";
  return "";
}

const char* kText =
    "top:\n"
    "  length: 2.5\n"
    "  count: 3\n"
    "  name: knot\n"
    "  on: true\n"
    "  at: [1, 2, 3]\n"
    "  list: [4, 5]\n"
    "bad:\n"
    "  length: abc\n"
    "  nan: .nan\n"
    "  count: 1.5\n"
    "  at: [1, 2]\n"
    "  on: maybe\n"
    "  list: 7\n";

class YamlFieldsTest : public ::testing::Test {
 protected:
  YamlReader reader_{"f.yaml"};
  YAML::Node doc_ = ParseYaml(kText, "f.yaml");
  std::vector<const char*> keys_ = {"length", "count", "name", "on", "at", "list", "nan"};
};

TEST_F(YamlFieldsTest, ReadsTypedValuesAndFallbacks) {
  const YamlSection s(reader_, doc_["top"], "top", keys_);
  EXPECT_EQ(s.Number("length"), 2.5);
  EXPECT_EQ(s.Positive("length"), 2.5);
  EXPECT_EQ(s.Integer("count", 0, 1), 3);
  EXPECT_EQ(s.String("name"), "knot");
  EXPECT_TRUE(s.Bool("on", false));
  EXPECT_EQ(s.Vector("at"), Vec3(1, 2, 3));
  EXPECT_EQ(s.Sequence("list", true).size(), 2u);
  EXPECT_EQ(s.Number("nan", 7.0), 7.0);  // absent: the fallback
  EXPECT_EQ(s.Integer("nan", -4, -10), -4);
  EXPECT_EQ(s.Sequence("nan", false).size(), 0u);
  EXPECT_EQ(s.Field("length"), "top.length");
  EXPECT_EQ(FieldPath("", "name"), "name");
  EXPECT_EQ(IndexedField("bodies", 2), "bodies[2]");
}

TEST_F(YamlFieldsTest, UnknownKeyNamesFileLineFieldAndTheAllowedKeys) {
  const std::string msg = ErrorOf([&] { YamlSection(reader_, doc_["top"], "top", {"length"}); });
  EXPECT_EQ(msg, "f.yaml:3: field 'top.count': unknown key 'count'; allowed: length");
  EXPECT_EQ(ErrorOf([&] { YamlSection(reader_, doc_["top"]["length"], "top.length", {}); }),
            "f.yaml:2: field 'top.length': expected a map");
}

TEST_F(YamlFieldsTest, WrongValuesNameTheirLineAndWhatWasExpected) {
  const YamlSection s(reader_, doc_["bad"], "bad", keys_);
  EXPECT_EQ(ErrorOf([&] { s.Number("length"); }),
            "f.yaml:9: field 'bad.length': expected a number, found 'abc'");
  EXPECT_EQ(ErrorOf([&] { s.Number("nan"); }),
            "f.yaml:10: field 'bad.nan': expected a finite number");
  EXPECT_EQ(ErrorOf([&] { s.Integer("count", 0, 0); }),
            "f.yaml:11: field 'bad.count': expected an integer");
  EXPECT_EQ(ErrorOf([&] { s.Vector("at"); }), "f.yaml:12: field 'bad.at': expected [x, y, z]");
  EXPECT_EQ(ErrorOf([&] { s.Bool("on", false); }),
            "f.yaml:13: field 'bad.on': expected true or false");
  EXPECT_EQ(ErrorOf([&] { s.Sequence("list", false); }),
            "f.yaml:14: field 'bad.list': expected a list");
}

TEST_F(YamlFieldsTest, RangeAndPresenceChecks) {
  const YamlSection s(reader_, doc_["top"], "top", keys_);
  EXPECT_EQ(ErrorOf([&] { s.Integer("count", 0, 4); }),
            "f.yaml:3: field 'top.count': must be >= 4");
  // A missing required key points at its map.
  EXPECT_EQ(ErrorOf([&] { s.Number("nan"); }),
            "f.yaml:2: field 'top.nan': required field is missing");
  EXPECT_EQ(ErrorOf([&] { s.Positive("nan", -1.0); }), "f.yaml:2: field 'top.nan': must be > 0");
  EXPECT_EQ(ErrorOf([&] { s.NonNegative("nan", -1.0); }),
            "f.yaml:2: field 'top.nan': must be >= 0");
  EXPECT_EQ(YamlLine(doc_["top"]["missing"]), 0);
}

TEST_F(YamlFieldsTest, SyntaxErrorNamesItsLine) {
  EXPECT_EQ(
      ErrorOf([] { ParseYaml("a: 1\nb: [\n", "s.yaml"); }).rfind("s.yaml:3: YAML syntax error", 0),
      0u);
}

}  // namespace
}  // namespace arthrosim
