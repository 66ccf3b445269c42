// Contact start/end events: compare this step's touching (tool, body) pairs with last step's.
#include <algorithm>
#include <string>
#include <tuple>

#include "arthrosim/collision/contact_generation.h"

namespace arthrosim::collision {
namespace {

using Kind = ConstraintEnd::Kind;

auto PairKey(const ToolContact& c) {
  return std::make_tuple(c.tool_slot, static_cast<int>(c.body_kind), c.body);
}

const std::string& BodyName(const Model& model, Kind kind, int index) {
  static const std::string kNone;
  switch (kind) {
    case Kind::kSoftBody:
      return index >= 0 && index < static_cast<int>(model.soft_bodies.size())
                 ? model.soft_bodies[index].name
                 : kNone;
    case Kind::kThread:
      return index >= 0 && index < static_cast<int>(model.threads.size())
                 ? model.threads[index].name
                 : kNone;
    case Kind::kBone:
      return index >= 0 && index < static_cast<int>(model.bones.size()) ? model.bones[index].name
                                                                        : kNone;
    default:
      return kNone;
  }
}

std::string ToolName(const Model& model, const State& state, int slot) {
  const int i = state.tools[slot].instrument;
  if (i >= 0 && i < static_cast<int>(model.instruments.size())) return model.instruments[i].name;
  return "slot" + std::to_string(slot);
}

std::string RegionDetail(const Model& model, const std::string& body, const Vec3& p) {
  for (const Region& r : model.regions) {
    if (r.body == body && (p.array() >= r.box_min_mm.array()).all() &&
        (p.array() <= r.box_max_mm.array()).all()) {
      return "region=" + r.name;
    }
  }
  return "";
}

Vec3 ContactPoint(const State& state, const physics::PointContact& c) {
  const Points& x = c.target == physics::PointContact::Target::kSoftBody
                        ? state.soft_bodies[c.index].x
                        : state.threads[c.index].x;
  Vec3 p = Vec3::Zero();
  for (int k = 0; k < 4; ++k) {
    if (c.nodes[k] >= 0) p += c.weights[k] * x.col(c.nodes[k]);
  }
  return p;
}

}  // namespace

void UpdateContactEvents(const Model& model, const State& state, const CollisionOutput& out,
                         std::vector<ToolContact>* touching, std::vector<Event>* events,
                         ContactEventScratch* scratch) {
  ContactEventScratch local;
  ContactEventScratch& w = scratch ? *scratch : local;
  std::vector<ToolContact>& now = w.now;
  now.clear();
  w.weight.clear();
  // This step's pairs: force-weighted mean point of the solved contacts of each (tool, body).
  for (const physics::PointContact& c : out.contacts) {  // sorted: one run per pair
    if (c.tool_slot < 0 || !(c.force_n > 0)) continue;
    const Kind kind =
        c.target == physics::PointContact::Target::kSoftBody ? Kind::kSoftBody : Kind::kThread;
    if (now.empty() || now.back().tool_slot != c.tool_slot || now.back().body_kind != kind ||
        now.back().body != c.index) {
      now.push_back(ToolContact{c.tool_slot, kind, c.index, Vec3::Zero()});
      w.weight.push_back(0);
    }
    now.back().position_mm += c.force_n * ContactPoint(state, c);
    w.weight.back() += c.force_n;
  }
  for (std::size_t k = 0; k < now.size(); ++k) now[k].position_mm /= w.weight[k];
  now.insert(now.end(), out.bone_touches.begin(), out.bone_touches.end());
  // Stable insertion sort by pair (a handful of pairs; no temporary buffer).
  for (std::size_t k = 1; k < now.size(); ++k) {
    const ToolContact c = now[k];
    std::size_t m = k;
    for (; m > 0 && PairKey(c) < PairKey(now[m - 1]); --m) now[m] = now[m - 1];
    now[m] = c;
  }
  // Merge the two sorted lists.
  auto emit = [&](const char* kind, const ToolContact& c) {
    Event e;
    e.step = state.step;
    e.time_s = state.time_s;
    e.kind = kind;
    e.tool = ToolName(model, state, c.tool_slot);
    e.body = BodyName(model, c.body_kind, c.body);
    e.detail = RegionDetail(model, e.body, c.position_mm);
    e.position_mm = c.position_mm;
    events->push_back(std::move(e));
  };
  std::size_t i = 0, j = 0;
  const std::vector<ToolContact>& before = *touching;
  while (i < before.size() || j < now.size()) {
    if (j == now.size() || (i < before.size() && PairKey(before[i]) < PairKey(now[j]))) {
      emit("contact_end", before[i++]);
    } else if (i == before.size() || PairKey(now[j]) < PairKey(before[i])) {
      emit("contact_start", now[j++]);
    } else {
      ++i;
      ++j;
    }
  }
  touching->assign(now.begin(), now.end());
}

}  // namespace arthrosim::collision
