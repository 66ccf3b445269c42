#include "arthrosim/core/state_fields.h"

#include <gtest/gtest.h>

#include <cstddef>
#include <set>
#include <string>

namespace arthrosim {
namespace {

// Converts to any member type: T{AnyMember{}, ...} compiles for as many initialisers as T has
// members (C++20 aggregate initialisation), which counts an aggregate's members.
struct AnyMember {
  template <class T>
  operator T() const;  // NOLINT(google-explicit-constructor): only named in unevaluated contexts
};

template <class T, class... A>
constexpr std::size_t MemberCount() {
  if constexpr (requires { T{A{}..., AnyMember{}}; }) {
    return MemberCount<T, A..., AnyMember>();
  } else {
    return sizeof...(A);
  }
}

/// Names the members a struct's visitor reports, and how many.
template <class T>
std::vector<std::string> VisitedNames() {
  T value{};
  std::vector<std::string> names;
  VisitFields(value, [&](auto&, const FieldInfo& info) { names.emplace_back(info.name); });
  return names;
}

template <class T>
void ExpectEveryMemberVisitedOnce(const char* type) {
  const std::vector<std::string> names = VisitedNames<T>();
  EXPECT_EQ(names.size(), MemberCount<T>())
      << type << ": its VisitFields (core/state_fields.h) must name every member exactly once";
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size())
      << type << ": two members share a name";
}

TEST(StateFields, TheCounterCountsMembers) {
  struct Three {
    int a;
    std::string b;
    Points c;
  };
  EXPECT_EQ(MemberCount<Three>(), 3u);
  EXPECT_EQ(MemberCount<ConstraintEnd>(), 5u);  // an enum and two std::arrays among them
}

TEST(StateFields, EveryStateStructNamesEveryMember) {
  ExpectEveryMemberVisitedOnce<State>("State");
  ExpectEveryMemberVisitedOnce<SoftBodyState>("SoftBodyState");
  ExpectEveryMemberVisitedOnce<BoneState>("BoneState");
  ExpectEveryMemberVisitedOnce<mesh::TriMesh>("mesh::TriMesh");
  ExpectEveryMemberVisitedOnce<ThreadState>("ThreadState");
  ExpectEveryMemberVisitedOnce<ToolState>("ToolState");
  ExpectEveryMemberVisitedOnce<CameraState>("CameraState");
  ExpectEveryMemberVisitedOnce<SpringConstraint>("SpringConstraint");
  ExpectEveryMemberVisitedOnce<ConstraintEnd>("ConstraintEnd");
  ExpectEveryMemberVisitedOnce<Event>("Event");
  ExpectEveryMemberVisitedOnce<ToolContact>("ToolContact");
  ExpectEveryMemberVisitedOnce<BoneHole>("BoneHole");
  ExpectEveryMemberVisitedOnce<AnchorState>("AnchorState");
}

}  // namespace
}  // namespace arthrosim
