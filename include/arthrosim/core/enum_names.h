#pragma once
// The names of an enum's values kept in one table per enum: the table gives a value its name and
// a name its value, so the two directions (a writer and a parser) cannot drift apart.
#include <cstddef>
#include <optional>
#include <string_view>

namespace arthrosim {

/// One row of an enum's name table.
template <class E>
struct EnumName {
  E value;
  const char* name;
};

/// The name `table` gives `value`, or `fallback` if no row holds that value.
template <class E, std::size_t N>
constexpr const char* NameIn(const EnumName<E> (&table)[N], E value, const char* fallback) {
  for (const EnumName<E>& row : table) {
    if (row.value == value) return row.name;
  }
  return fallback;
}

/// The value `table` names `name`, or nullopt if no row has that name.
template <class E, std::size_t N>
constexpr std::optional<E> ValueIn(const EnumName<E> (&table)[N], std::string_view name) {
  for (const EnumName<E>& row : table) {
    if (name == row.name) return row.value;
  }
  return std::nullopt;
}

}  // namespace arthrosim
