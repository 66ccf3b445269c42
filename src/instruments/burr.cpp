// Burr (Choi et al. 2020, section III.2): while button 1 is held and the burr head touches a
// bone, the bone within the burr radius is removed at a rate set by the bone's hardness and the
// burr speed, integrated over simulated time; the rim of the crater is then smoothed.
#include <algorithm>
#include <cstdio>
#include <string>

#include "arthrosim/collision/instrument_shape.h"
#include "arthrosim/mesh/surface_tissue.h"
#include "arthrosim/physics/bone_surface.h"
#include "bone_contact.h"
#include "operations.h"

namespace arthrosim::instruments {
namespace {

// The burr head of the tool in slot `slot` in world coordinates: centre and radius, mm.
bool BurrHead(const Model& model, const ToolState& tool, Vec3* center, double* radius_mm) {
  const InstrumentParts parts =
      InstrumentPartsLocal(model.instruments[static_cast<std::size_t>(tool.instrument)], tool.jaw);
  for (int i = 0; i < parts.count; ++i) {
    const InstrumentPart& p = parts.parts[static_cast<std::size_t>(i)];
    if (p.part != ToolPart::kBurr) continue;
    *center = tool.pose.Apply(p.v[0]);
    *radius_mm = p.radius_mm;
    return true;
  }
  return false;
}

// Books `removed_mm3` to every region of `bone` whose box holds `at`, or to "elsewhere" (the
// last entry) when none does.
void BookByRegion(const Model& model, int bone, const Vec3& at, double removed_mm3,
                  BoneState* state) {
  state->removed_by_region_mm3.resize(model.regions.size() + 1, 0.0);  // restored old files
  bool booked = false;
  for (std::size_t r = 0; r < model.regions.size(); ++r) {
    const Region& reg = model.regions[r];
    if (reg.body != model.bones[static_cast<std::size_t>(bone)].name) continue;
    if ((at.array() < reg.box_min_mm.array()).any() || (at.array() > reg.box_max_mm.array()).any())
      continue;
    state->removed_by_region_mm3[r] += removed_mm3;
    booked = true;
  }
  if (!booked) state->removed_by_region_mm3.back() += removed_mm3;
}

std::string Detail(double volume_mm3, double depth_mm, int vertices_hit) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "volume_mm3=%.6g depth_mm=%.6g triangles=%d", volume_mm3, depth_mm,
                vertices_hit);
  return buf;
}

}  // namespace

void BurrOperation(const Model& model, int slot, const StepContext& /*context*/, State* state,
                   InstrumentScratch* /*scratch*/) {
  const ToolState& tool = state->tools[static_cast<std::size_t>(slot)];
  if (!Button1(tool)) return;
  Vec3 center;
  double radius = 0;
  if (!BurrHead(model, tool, &center, &radius)) return;
  const BurrOptions& opt = model.operations.burr;
  // The proxy holds the head at the bone surface (a contact gap away); the hand's press carries
  // it across that gap and as deep as this step removes.
  const Vec3 press = PressMm(tool);
  const double press_mm = press.norm();
  const double gap_mm = model.contact.contact_distance_mm;
  for (std::size_t b = 0; b < model.bones.size(); ++b) {
    BoneState& bone = state->bones[b];
    // Surface recession this step: rate x speed / hardness, integrated over the step.
    const double depth_mm =
        opt.depth_rate_mm_s * opt.speed / model.bones[b].hardness * model.options.dt_s;
    const Vec3 at = press_mm > 0
                        ? Vec3(center + press * (std::min(press_mm, gap_mm + depth_mm) / press_mm))
                        : center;
    const BoneTouch touch = TouchBone(bone.surface, at, at, radius);
    if (touch.triangles == 0) continue;
    physics::BoneCarveOptions carve;
    carve.max_edge_mm = opt.max_edge_mm;
    double removed = physics::CarveSphere(&bone, at, radius, depth_mm, carve);
    removed += physics::SmoothRim(&bone, at, radius, radius + opt.smoothing_ring_mm);
    if (removed <= 0) continue;
    BookByRegion(model, static_cast<int>(b), touch.center_mm, removed, &bone);
    // On a tissue of the bone's own (articular cartilage, labrum): collateral damage, named in
    // the event (plans protect it with `protected: [{tissue: ...}]`, docs/plan-format.md).
    std::string detail = Detail(removed, depth_mm, touch.triangles);
    const BoneModel& bm = model.bones[b];
    const std::int8_t tissue = mesh::TissueNear(bm.surface, bm.tri_tissue, touch.center_mm);
    if (tissue != mesh::kBoneTissue)
      detail += " tissue=" + bm.tissues[static_cast<std::size_t>(tissue)];
    RecordEvent(model, slot, "burr", bm.name, detail, touch.center_mm, state);
  }
}

}  // namespace arthrosim::instruments
