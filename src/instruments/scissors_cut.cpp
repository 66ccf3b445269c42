// Scissors: the tets between the closing blades are cut (Choi et al. 2020, section III.1).
#include <cmath>
#include <cstdio>
#include <string>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/instruments/cutting.h"

namespace arthrosim::instruments {
namespace {

// True if this step's contacts include one of tool slot `slot` on soft body `body`.
bool BladesTouch(const StepContext& context, int slot, int body) {
  if (context.contacts == nullptr) return false;
  for (const physics::PointContact& c : context.contacts->contacts) {
    if (c.tool_slot == slot && c.target == physics::PointContact::Target::kSoftBody &&
        c.index == body) {
      return true;
    }
  }
  return false;
}

std::string Number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string IdList(const std::vector<std::int32_t>& ids) {
  std::string s;
  for (std::int32_t id : ids) {
    if (!s.empty()) s += ',';
    s += std::to_string(id);
  }
  return s;
}

}  // namespace

bool BladeTriangle(const Model& model, const ToolState& tool, std::array<Vec3, 3>* tri) {
  if (tool.instrument < 0) return false;
  // The parts of the one instrument geometry (fixed capacity: nothing allocated per step).
  const InstrumentParts parts =
      InstrumentPartsLocal(model.instruments[static_cast<std::size_t>(tool.instrument)], tool.jaw);
  const InstrumentPart* blade[2] = {nullptr, nullptr};
  for (int i = 0; i < parts.count; ++i) {
    const InstrumentPart& p = parts.parts[static_cast<std::size_t>(i)];
    if (p.part == ToolPart::kBlade && p.side >= 0 && p.side < 2) blade[p.side] = &p;
  }
  if (blade[0] == nullptr || blade[1] == nullptr) return false;
  // Blade core: v0 = hinge, v1 = tip (cutting edge v0-v1); both blades share the hinge.
  *tri = {tool.pose.Apply(blade[0]->v[0]), tool.pose.Apply(blade[0]->v[1]),
          tool.pose.Apply(blade[1]->v[1])};
  return true;
}

bool JawClosing(const ToolState& now, const ToolState& prev, double min_step) {
  return now.instrument >= 0 && now.instrument == prev.instrument && now.jaw - prev.jaw > min_step;
}

double TetRestVolume(const SoftBodyState& body, std::int32_t t) {
  const mesh::Tet& e = body.tets[static_cast<std::size_t>(t)];
  const Vec3 p0 = body.x_rest.col(e[0]);
  Mat3 d;
  d.col(0) = body.x_rest.col(e[1]) - p0;
  d.col(1) = body.x_rest.col(e[2]) - p0;
  d.col(2) = body.x_rest.col(e[3]) - p0;
  return std::abs(d.determinant()) / 6.0;
}

void TetsCrossedByTriangle(const State& state, int body, const std::array<Vec3, 3>& tri,
                           collision::TetTree* tree, std::vector<std::int32_t>* out) {
  const SoftBodyState& sb = state.soft_bodies[static_cast<std::size_t>(body)];
  if (!tree->BuiltFor(sb.tets.size())) {
    tree->Build(sb.x, sb.tets);
  } else {
    tree->Refit(sb.x, sb.tets);
  }
  tree->QueryTriangle(sb.x, sb.tets, sb.tet_alive, tri[0], tri[1], tri[2], out);
}

void ScissorsCut(const Model& model, int slot, const StepContext& context, State* state,
                 InstrumentScratch* scratch) {
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  if (context.prev_tools == nullptr || context.soft == nullptr) return;
  const ScissorsOptions& opt = model.operations.scissors;
  if (!JawClosing(tool, (*context.prev_tools)[static_cast<std::size_t>(slot)], opt.min_jaw_step)) {
    return;
  }
  std::array<Vec3, 3> tri;
  if (!BladeTriangle(model, tool, &tri)) return;
  scratch->tet_trees.resize(state->soft_bodies.size());
  // Table 1: scissors cut muscle and tendon, i.e. the soft bodies; bone and suture only touch.
  for (std::size_t b = 0; b < state->soft_bodies.size(); ++b) {
    const int body = static_cast<int>(b);
    if (!BladesTouch(context, slot, body)) continue;
    TetsCrossedByTriangle(*state, body, tri, &scratch->tet_trees[b], &scratch->tets);
    if (scratch->tets.empty()) continue;
    SoftBodyState& sb = state->soft_bodies[b];
    // Where the cut is: the centroid of the tets the blade triangle crosses (before the cut).
    Vec3 centroid = Vec3::Zero();
    for (std::int32_t t : scratch->tets)
      for (std::int32_t n : sb.tets[static_cast<std::size_t>(t)]) centroid += sb.x.col(n);
    centroid /= 4.0 * static_cast<double>(scratch->tets.size());
    if (opt.mode == CutMode::kSplit) {
      // The blades lie in the tool's x-z plane: its normal is the tool's y axis.
      const Vec3 normal = tool.pose.orientation * Vec3::UnitY();
      const SplitResult r =
          SplitTetsByPlane(model, body, scratch->tets, tri[0], normal, opt.snap_fraction,
                           &scratch->tet_trees[b], context.soft, state);
      if (r.split_tets == 0) continue;
      RecordEvent(
          model, slot, "cut", model.soft_bodies[b].name,
          "tets=" + std::to_string(r.split_tets) + " new_nodes=" + std::to_string(r.new_nodes) +
              " new_tets=" + std::to_string(r.new_tets) + " volume_mm3=" + Number(r.volume_mm3) +
              " min_quality=" + Number(r.min_quality) + " mode=split",
          centroid, state);
      continue;
    }
    double volume = 0;
    for (std::int32_t t : scratch->tets) volume += TetRestVolume(sb, t);
    context.soft->RemoveTets(body, scratch->tets, state);
    sb.removed_volume_mm3 += volume;
    RecordEvent(model, slot, "cut", model.soft_bodies[b].name,
                "tets=" + std::to_string(scratch->tets.size()) + " ids=" + IdList(scratch->tets) +
                    " volume_mm3=" + Number(volume) + " mode=remove",
                centroid, state);
  }
}

}  // namespace arthrosim::instruments
