// Awl (Choi et al. 2020, section III.3): the pilot hole for an anchor. Method 2 (default)
// compares the tool direction with the deformation direction (from the rounded tip to the centre
// of its contact points); when they agree within operations.awl.max_angle_deg a hole is opened on
// the tool axis and the surface within the awl radius is pushed along it by a ratio falling with
// the distance from the axis (a concave hole) as deep as the tip is pushed past the entry (the
// mallet). Method 1 displaces the contact vertex and its neighbours together.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "arthrosim/core/instrument_geometry.h"
#include "arthrosim/core/units.h"
#include "arthrosim/physics/bone_surface.h"
#include "bone_contact.h"
#include "operations.h"

namespace arthrosim::instruments {
namespace {

struct AwlFrame {
  Vec3 tip = Vec3::Zero();     // tool tip (the proxy, held at the bone surface), mm
  Vec3 driven = Vec3::Zero();  // tip driven on along its axis by the hand's press (the mallet)
  Vec3 axis = Vec3::UnitZ();   // tool direction (into the bone), unit
  double radius_mm = 0;        // awl body radius: the hole radius
};

AwlFrame Frame(const Model& model, const ToolState& tool) {
  AwlFrame f;
  f.tip = tool.pose.position_mm;
  f.axis = (tool.pose.orientation * Vec3::UnitZ()).normalized();
  f.driven = f.tip + std::max(0.0, PressMm(tool).dot(f.axis)) * f.axis;
  const InstrumentParts parts =
      InstrumentPartsLocal(model.instruments[static_cast<std::size_t>(tool.instrument)], tool.jaw);
  for (int i = 0; i < parts.count; ++i) {
    if (parts.parts[static_cast<std::size_t>(i)].part == ToolPart::kAwlBody)
      f.radius_mm = parts.parts[static_cast<std::size_t>(i)].radius_mm;
  }
  return f;
}

int OpenHole(const State& state, int slot) {
  for (std::size_t h = 0; h < state.holes.size(); ++h) {
    if (state.holes[h].open && state.holes[h].tool_slot == slot) return static_cast<int>(h);
  }
  return -1;
}

// Starts a hole where the rounded tip (a sphere of the awl radius one radius behind the tip)
// touches a bone and the deformation direction agrees with the tool direction; -1 if none.
int StartHole(const Model& model, int slot, const AwlFrame& f, State* state) {
  for (const BoneHole& h : state->holes) {  // the tip is still in an earlier hole
    const Vec3 d = f.tip - h.entry_mm;
    const double s = std::clamp(d.dot(h.axis), 0.0, h.depth_mm);
    if ((d - s * h.axis).norm() < 0.5 * h.diameter_mm + f.radius_mm) return -1;
  }
  const Vec3 back = f.tip - f.radius_mm * f.axis;
  for (std::size_t b = 0; b < model.bones.size(); ++b) {
    // Within the contact gap the proxy keeps from bone: the proxy's tip touches.
    const BoneTouch touch = TouchBone(state->bones[b].surface, back, back,
                                      f.radius_mm + model.contact.contact_distance_mm);
    if (touch.triangles == 0) continue;
    const Vec3 d = touch.center_mm - back;
    // The rounded tip must still be outside the surface by at least half a radius: nearer, the
    // contact centre lies almost beside it and the direction to it says nothing (a tool
    // sliding along the surface would open a hole along it).
    if (!(-d.dot(touch.normal) >= 0.5 * f.radius_mm)) continue;
    const double cos_dev = std::clamp(f.axis.dot(d.normalized()), -1.0, 1.0);
    if (std::acos(cos_dev) > model.operations.awl.max_angle_deg * units::kDegToRad) continue;
    // The surface plane at the entry: the normal over the hole's footprint (the triangles within
    // the awl diameter of the contact centre), not the one or two facets under the tip, which
    // on a faceted humeral head tilt it by several degrees.
    const BoneTouch patch =
        TouchBone(state->bones[b].surface, touch.center_mm, touch.center_mm, 2 * f.radius_mm);
    const Vec3 normal = patch.triangles > 0 ? patch.normal : touch.normal;
    const double un = f.axis.dot(normal);
    if (!(un < 0)) continue;  // the axis must point into the bone
    BoneHole h;
    h.bone = static_cast<std::int32_t>(b);
    h.tool_slot = slot;
    // The axis meets the local surface plane (contact centre, normal) at the entry.
    h.entry_mm = back + ((touch.center_mm - back).dot(normal) / un) * f.axis;
    h.axis = f.axis;
    h.diameter_mm = 2 * f.radius_mm;
    h.angle_deg = std::asin(std::min(1.0, -un)) / units::kDegToRad;
    h.open = 1;
    state->holes.push_back(h);
    return static_cast<int>(state->holes.size()) - 1;
  }
  return -1;
}

// Method 1: the surface vertex nearest to the axis at the entry and its neighbours move
// together along the axis to the commanded depth (their moves are kept only if no triangle
// around them turns over).
double DisplaceVertexAndNeighbours(BoneState* bone, const BoneHole& h, double depth_mm) {
  mesh::TriMesh& m = bone->surface;
  int nearest = -1;
  double best = 1e300;
  for (int i = 0; i < static_cast<int>(m.nodes.cols()); ++i) {
    const Vec3 d = m.nodes.col(i) - h.entry_mm;
    const double rho = (d - d.dot(h.axis) * h.axis).norm();
    if (rho < best && d.dot(h.axis) > -h.diameter_mm) {
      best = rho;
      nearest = i;
    }
  }
  if (nearest < 0) return 0.0;
  std::vector<int> group{nearest};
  std::vector<int> tris;
  for (int t = 0; t < static_cast<int>(m.tris.size()); ++t) {
    const mesh::Tri& tr = m.tris[t];
    if (tr[0] != nearest && tr[1] != nearest && tr[2] != nearest) continue;
    for (int k = 0; k < 3; ++k) group.push_back(tr[k]);
  }
  std::sort(group.begin(), group.end());
  group.erase(std::unique(group.begin(), group.end()), group.end());
  const double s = (m.nodes.col(nearest) - h.entry_mm).dot(h.axis);
  const double move = depth_mm - s;
  if (!(move > 0)) return 0.0;
  for (int t = 0; t < static_cast<int>(m.tris.size()); ++t) {
    const mesh::Tri& tr = m.tris[t];
    for (int k = 0; k < 3; ++k) {
      if (std::binary_search(group.begin(), group.end(), tr[k])) {
        tris.push_back(t);
        break;
      }
    }
  }
  const double v_before = physics::EnclosedVolume(m);
  const Points old = m.nodes;
  for (int i : group) m.nodes.col(i) += move * h.axis;
  for (int t : tris) {
    const mesh::Tri& tr = m.tris[t];
    const Vec3 n0 = (old.col(tr[1]) - old.col(tr[0])).cross(old.col(tr[2]) - old.col(tr[0]));
    const Vec3 n1 =
        (m.nodes.col(tr[1]) - m.nodes.col(tr[0])).cross(m.nodes.col(tr[2]) - m.nodes.col(tr[0]));
    if (!(n0.dot(n1) > 0)) {
      m.nodes = old;
      return 0.0;
    }
  }
  ++bone->revision;
  const double removed = v_before - physics::EnclosedVolume(m);
  bone->removed_volume_mm3 += removed;
  return removed;
}

std::string HoleDetail(int index, const BoneHole& h) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "hole=%d depth_mm=%.6g diameter_mm=%.6g angle_deg=%.6g axis=%.6g,%.6g,%.6g", index,
                h.depth_mm, h.diameter_mm, h.angle_deg, h.axis.x(), h.axis.y(), h.axis.z());
  return buf;
}

// Ends the hole the awl leaves: recorded by a `hole` event once deep enough. A hole that never
// got that deep (the tip only touched, or slid off) is forgotten when it is the last record,
// which it is unless another slot opened one since (anchors refer to holes by index).
void CloseHole(const Model& model, int slot, int index, State* state) {
  BoneHole& h = state->holes[static_cast<std::size_t>(index)];
  h.open = 0;
  if (h.depth_mm < model.operations.awl.min_depth_mm) {
    if (static_cast<std::size_t>(index) + 1 == state->holes.size()) state->holes.pop_back();
    return;
  }
  RecordEvent(model, slot, "hole", model.bones[static_cast<std::size_t>(h.bone)].name,
              HoleDetail(index, h), h.entry_mm, state);
}

}  // namespace

void AwlOperation(const Model& model, int slot, const StepContext& /*context*/, State* state,
                  InstrumentScratch* /*scratch*/) {
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  const AwlFrame f = Frame(model, tool);
  if (!(f.radius_mm > 0)) return;
  int index = OpenHole(*state, slot);
  if (Button2(tool)) {  // seat an anchor in the hole at the tip, if there is one
    const int hole = HoleForAnchor(model, f.driven, *state);
    if (hole >= 0) {
      if (hole == index) CloseHole(model, slot, index, state);
      if (static_cast<std::size_t>(hole) < state->holes.size())
        SeatAnchor(model, slot, hole, state);
      return;
    }
  }
  if (index < 0) {
    index = StartHole(model, slot, f, state);
    if (index < 0) return;
  }
  BoneHole& h = state->holes[static_cast<std::size_t>(index)];
  const Vec3 d = f.driven - h.entry_mm;
  const double push_mm = d.dot(h.axis);  // how far the mallet drove the tip past the entry
  const double off_axis_mm = (d - push_mm * h.axis).norm();
  if (push_mm < -f.radius_mm || off_axis_mm > f.radius_mm) {  // the awl has left the hole
    CloseHole(model, slot, index, state);
    return;
  }
  if (push_mm > h.depth_mm) {
    BoneState& bone = state->bones[static_cast<std::size_t>(h.bone)];
    if (model.operations.awl.method == 1) {
      DisplaceVertexAndNeighbours(&bone, h, push_mm);
    } else {
      physics::BoneCarveOptions carve;
      carve.max_edge_mm = model.operations.awl.max_edge_mm;
      physics::PushAlong(&bone, h.entry_mm, h.axis, 0.5 * h.diameter_mm, push_mm, carve);
    }
    h.depth_mm = push_mm;
  }
}

}  // namespace arthrosim::instruments
