// docs/hdf5-layout.md stays true: every field of the State field table is named there.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "arthrosim/core/state_fields.h"

namespace arthrosim {
namespace {

struct Named {
  std::string name;
  FieldStore store;
  bool in_record;  ///< a member of a compound record (documented inline, not as a table row)
};

template <class T>
concept HasFields = requires(const T& t) {
  VisitFields(t, [](const auto&, const FieldInfo&) {});
};

/// Every field of s and, recursively, of its nested structs and lists of structs.
template <class S>
void Collect(const S& s, bool in_record, std::vector<Named>* out) {
  VisitFields(s, [&](const auto& value, const FieldInfo& info) {
    using T = std::decay_t<decltype(value)>;
    out->push_back({info.name, info.store, in_record});
    const bool record = in_record || info.store == FieldStore::kRecords ||
                        info.store == FieldStore::kEvents || info.store == FieldStore::kNested;
    if constexpr (HasFields<T>) {
      Collect(value, record && !std::is_same_v<T, mesh::TriMesh>, out);
    } else if constexpr (requires { typename T::value_type; }) {
      if constexpr (HasFields<typename T::value_type>)
        Collect(typename T::value_type{}, record, out);
    }
  });
}

std::string ReadDoc() {
  std::ifstream in(std::string(ARTHROSIM_SOURCE_DIR) + "/docs/hdf5-layout.md");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(RunLayoutDoc, EveryStateFieldIsDocumented) {
  const std::string doc = ReadDoc();
  ASSERT_FALSE(doc.empty());
  const std::size_t not_stored = doc.find("## State fields not in the run file");
  ASSERT_NE(not_stored, std::string::npos);
  std::vector<Named> fields;
  Collect(State{}, false, &fields);
  ASSERT_GT(fields.size(), 40u);
  for (const Named& f : fields) {
    const std::string quoted = "`" + f.name + "`";
    if (f.store == FieldStore::kNested) continue;  // its fields are checked one by one
    if (f.store == FieldStore::kGroup || f.store == FieldStore::kRecords) {
      EXPECT_NE(doc.find("`/" + f.name), std::string::npos) << "group /" << f.name;
    } else if (f.store == FieldStore::kNone || f.store == FieldStore::kDerived) {
      EXPECT_NE(doc.find(quoted, not_stored), std::string::npos)
          << quoted << " is not stored: list it under 'State fields not in the run file'";
    } else if (!f.in_record) {  // a dataset: a row of a table
      EXPECT_NE(doc.find("| " + quoted), std::string::npos)
          << quoted << " (a State field of core/state_fields.h) has no row in docs/hdf5-layout.md";
    } else {
      EXPECT_NE(doc.find(quoted), std::string::npos)
          << quoted
          << " (a State field of core/state_fields.h) is missing from docs/hdf5-layout.md";
    }
  }
}

}  // namespace
}  // namespace arthrosim
