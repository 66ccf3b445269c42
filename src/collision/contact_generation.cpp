// The collision stage (Detect) as named stages, as the sim step is: sync the world, shared
// per-step data, the independent pair tasks, their merge in task order, and the sort that makes
// the contact list independent of creation order. The pair tests live in contact_tool.cpp,
// contact_thread.cpp and contact_tissue.cpp.
#include "arthrosim/collision/contact_generation.h"

#include <algorithm>
#include <cstdint>

#include "arthrosim/core/parallel.h"
#include "contact_internal.h"

namespace arthrosim::collision {
namespace {

using internal::ContactBuilder;
using Kind = ConstraintEnd::Kind;
using physics::PointContact;

// The detection tasks, in the order their contacts would be created one after the other: tool
// slots, threads (against tissue and bone), soft bodies (against bones), soft bodies (against
// other soft bodies).
struct TaskRanges {
  std::size_t threads = 0, soft = 0, tissue_tissue = 0;
  std::size_t Count() const { return kToolSlots + threads + soft + tissue_tissue; }
};

TaskRanges MakeTaskRanges(const State& state, const CollisionWorld& world,
                          const CollisionParams& params) {
  TaskRanges r;
  r.threads = state.threads.size();
  r.soft = world.soft.size();
  r.tissue_tissue = params.tissue_tissue_contacts ? r.soft : 0;
  return r;
}

// Thread segment boxes for the tool tests, shared by both slots (made only when a tool is in).
void PrepareThreadBoxes(const Model& model, const State& state, DetectScratch* scratch) {
  if (scratch->thread_boxes.size() < state.threads.size()) {
    scratch->thread_boxes.resize(state.threads.size());
  }
  bool tool_in = false;
  for (const ToolState& t : state.tools) tool_in = tool_in || t.instrument >= 0;
  if (!tool_in) return;
  for (std::size_t t = 0; t < state.threads.size(); ++t) {
    internal::MakeThreadBoxes(model, state, static_cast<int>(t), &scratch->thread_boxes[t]);
  }
}

// One task: writes only its own scratch and world data no other task reads or writes (its
// slot's sweeps and bone force, its thread's caches, its body's caches).
void RunTask(const Model& model, const State& state,
             const std::array<ToolState, kToolSlots>& prev_tools, const CollisionParams& params,
             const TaskRanges& ranges, std::size_t task, CollisionWorld* world,
             CollisionOutput* out) {
  ContactTaskScratch& scratch = world->scratch.tasks[task];
  scratch.contacts.clear();
  scratch.kinds.clear();
  scratch.touches.clear();
  ContactBuilder cb{model, state, params, scratch};
  if (task < static_cast<std::size_t>(kToolSlots)) {
    internal::DetectToolSlot(&cb, static_cast<int>(task), prev_tools, world,
                             world->scratch.thread_boxes, out);
    return;
  }
  task -= kToolSlots;
  if (task < ranges.threads) {
    internal::DetectThread(&cb, static_cast<int>(task), world);
    return;
  }
  task -= ranges.threads;
  if (task < ranges.soft) {
    internal::DetectTissueBones(&cb, static_cast<int>(task), world);
    return;
  }
  task -= ranges.soft;
  internal::DetectTissueTissue(&cb, static_cast<int>(task), world);
}

// Every task, possibly concurrently: each writes its own lists, so the merged lists are the same
// for any thread count and any order of completion.
void RunTasks(const Model& model, const State& state,
              const std::array<ToolState, kToolSlots>& prev_tools, const CollisionParams& params,
              const TaskRanges& ranges, CollisionWorld* world, CollisionOutput* out) {
  const std::size_t ntasks = ranges.Count();
  if (world->scratch.tasks.size() < ntasks) world->scratch.tasks.resize(ntasks);
  ParallelFor(static_cast<std::int64_t>(ntasks), 1, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t t = begin; t < end; ++t) {
      RunTask(model, state, prev_tools, params, ranges, static_cast<std::size_t>(t), world, out);
    }
  });
}

// The tasks' contacts and touches concatenated in task order (lists kept across steps: no heap
// allocation in a steady state).
void MergeTasks(std::size_t ntasks, DetectScratch* scratch, CollisionOutput* out) {
  scratch->merged.clear();
  scratch->merged_kinds.clear();
  for (std::size_t t = 0; t < ntasks; ++t) {
    const ContactTaskScratch& to = scratch->tasks[t];
    scratch->merged.insert(scratch->merged.end(), to.contacts.begin(), to.contacts.end());
    scratch->merged_kinds.insert(scratch->merged_kinds.end(), to.kinds.begin(), to.kinds.end());
    out->bone_touches.insert(out->bone_touches.end(), to.touches.begin(), to.touches.end());
  }
}

// Lexicographic on (tool, target, body, obstacle kind, obstacle, nodes, weights, offset,
// normal, creation index), stopping at the first difference.
bool ContactLess(const std::vector<PointContact>& contacts, const std::vector<Kind>& kinds,
                 std::size_t i, std::size_t j) {
  const PointContact &a = contacts[i], &b = contacts[j];
  if (a.tool_slot != b.tool_slot) return a.tool_slot < b.tool_slot;
  if (a.target != b.target) return a.target < b.target;
  if (a.index != b.index) return a.index < b.index;
  if (kinds[i] != kinds[j]) return kinds[i] < kinds[j];
  if (a.obstacle_id != b.obstacle_id) return a.obstacle_id < b.obstacle_id;
  // Element by element (std::array's operators go through memcmp and a lexicographic compare).
  for (int k = 0; k < 4; ++k) {
    if (a.nodes[k] != b.nodes[k]) return a.nodes[k] < b.nodes[k];
  }
  for (int k = 0; k < 4; ++k) {
    if (a.weights[k] != b.weights[k]) return a.weights[k] < b.weights[k];
  }
  if (a.offset_mm != b.offset_mm) return a.offset_mm < b.offset_mm;
  for (int k = 0; k < 3; ++k) {
    if (a.normal[k] != b.normal[k]) return a.normal[k] < b.normal[k];
  }
  return i < j;  // creation order last: a total order, so an unstable sort is stable
}

// The leading fields (tool, target, body, obstacle kind, obstacle, first node) packed into one
// integer whose order is theirs, so most comparisons are one integer compare; equal keys fall
// back to the full comparison (same total order, so the same sorted list). False (keys unused)
// unless every field fits its bits.
bool PackSortKeys(const std::vector<PointContact>& contacts, const std::vector<Kind>& kinds,
                  std::vector<std::uint64_t>* key) {
  key->resize(contacts.size());
  bool packed = true;
  for (std::size_t i = 0; i < contacts.size() && packed; ++i) {
    const PointContact& c = contacts[i];
    const std::uint64_t slot = static_cast<std::uint64_t>(c.tool_slot + 1);
    const std::uint64_t body = static_cast<std::uint64_t>(c.index);
    const std::uint64_t kind = static_cast<std::uint64_t>(kinds[i]);
    const std::uint64_t obst = static_cast<std::uint64_t>(c.obstacle_id + 1);
    const std::uint64_t node = static_cast<std::uint64_t>(c.nodes[0] + 1);
    packed = c.tool_slot >= -1 && slot < 4 && c.index >= 0 && body < 1024 && kind < 8 &&
             c.obstacle_id >= -1 && obst < 1024 && c.nodes[0] >= -1 && node < (1u << 21);
    (*key)[i] = slot << 62 | static_cast<std::uint64_t>(c.target) << 61 | body << 51 | kind << 48 |
                obst << 38 | node << 17;
  }
  return packed;
}

// Creation order never matters: out->contacts are the merged contacts sorted by (tool, target,
// body, obstacle, feature) and, for completeness, by the remaining values.
void SortContacts(DetectScratch* scratch, CollisionOutput* out) {
  const std::vector<PointContact>& contacts = scratch->merged;
  const std::vector<Kind>& kinds = scratch->merged_kinds;
  std::vector<std::size_t>& order = scratch->order;
  order.resize(contacts.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  auto less = [&](std::size_t i, std::size_t j) { return ContactLess(contacts, kinds, i, j); };
  const std::vector<std::uint64_t>& key = scratch->key;
  const bool packed = PackSortKeys(contacts, kinds, &scratch->key);
  auto keyed_less = [&](std::size_t i, std::size_t j) {
    if (key[i] != key[j]) return key[i] < key[j];
    return less(i, j);
  };
  // Contacts are mostly created in order already: sort only when needed.
  if (packed) {
    if (!std::is_sorted(order.begin(), order.end(), keyed_less)) {
      std::sort(order.begin(), order.end(), keyed_less);  // in place: no buffer
    }
  } else if (!std::is_sorted(order.begin(), order.end(), less)) {
    std::sort(order.begin(), order.end(), less);
  }
  out->contacts.clear();
  out->obstacle_kind.clear();
  for (std::size_t i : order) {
    out->contacts.push_back(contacts[i]);
    out->obstacle_kind.push_back(kinds[i]);
  }
}

}  // namespace

void Detect(const Model& model, const State& state,
            const std::array<ToolState, kToolSlots>& prev_tools, const CollisionParams& params,
            CollisionWorld* world, CollisionOutput* out) {
  SyncWorld(model, state, world);
  out->bone_force_n.fill(Vec3::Zero());
  out->bone_touches.clear();
  PrepareThreadBoxes(model, state, &world->scratch);
  const TaskRanges ranges = MakeTaskRanges(state, *world, params);
  RunTasks(model, state, prev_tools, params, ranges, world, out);
  MergeTasks(ranges.Count(), &world->scratch, out);
  SortContacts(&world->scratch, out);
}

CollisionParams ParamsFromModel(const ContactOptions& c) { return c; }

std::array<Vec3, kToolSlots> ToolForces(const CollisionOutput& out) {
  std::array<Vec3, kToolSlots> f = out.bone_force_n;
  for (const PointContact& c : out.contacts) {
    if (c.tool_slot >= 0 && c.tool_slot < kToolSlots) f[c.tool_slot] -= c.force_n * c.normal;
  }
  return f;
}

}  // namespace arthrosim::collision
