#include "arthrosim/core/model.h"

#include <array>

namespace arthrosim {
namespace {

template <class T>
int FindByName(const std::vector<T>& items, const std::string& name) {
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (items[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

constexpr std::array<const char*, kInstrumentKindCount> kKindNames = {
    "scissors", "cutter",          "burr",        "shaver", "electrocautery", "awl", "retriever",
    "grasper",  "scorpion_needle", "knot_pusher", "hook"};

}  // namespace

int Model::FindSoftBody(const std::string& n) const { return FindByName(soft_bodies, n); }
int Model::FindBone(const std::string& n) const { return FindByName(bones, n); }
int Model::FindThread(const std::string& n) const { return FindByName(threads, n); }
int Model::FindInstrument(const std::string& n) const { return FindByName(instruments, n); }
int Model::FindLandmark(const std::string& n) const { return FindByName(landmarks, n); }
int Model::FindRegion(const std::string& n) const { return FindByName(regions, n); }
int Model::FindPortal(const std::string& n) const { return FindByName(portals, n); }

const char* InstrumentKindName(InstrumentKind kind) {
  return kKindNames[static_cast<std::size_t>(kind)];
}

std::optional<InstrumentKind> ParseInstrumentKind(const std::string& name) {
  for (std::size_t i = 0; i < kKindNames.size(); ++i) {
    if (name == kKindNames[i]) return static_cast<InstrumentKind>(i);
  }
  return std::nullopt;
}

}  // namespace arthrosim
