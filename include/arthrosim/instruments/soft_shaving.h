#pragma once
// Shaving soft tissue with the shaver and the electrocautery (Choi et al. 2020, section III.2):
// while button 1 is held, the surface vertices the working tip touches move inward (material
// removed), their surface neighbours follow part of the way (smoothing, no step edge), and the
// rest state of the elements they belong to is recomputed (the paper's re-calculation of the
// FEM force field: the removal is plastic, so the tissue does not spring back). Elements that
// become too thin are removed, never left inverted. The electrocautery also marks the touched
// nodes as cauterised. Depth is a rate times dt, so removal integrates over simulated time.
// docs/operations.md gives the choices; thresholds: scenario `operations.shaver`,
// `operations.electrocautery`.
#include <cstdint>
#include <vector>

#include "arthrosim/instruments/instruments.h"

namespace arthrosim::instruments {

/// What one shaving step did to one body.
struct ShaveResult {
  int moved_nodes = 0;            ///< touched surface vertices moved inward
  int smoothed_nodes = 0;         ///< their surface neighbours moved part of the way
  int removed_tets = 0;           ///< elements that became too thin
  double volume_mm3 = 0;          ///< rest volume removed (thinned elements + removed elements)
  Vec3 centre_mm = Vec3::Zero();  ///< mean of the touched vertices (current positions)
};

/// One shaving step of tool slot `slot` on soft body `body` with the working primitive at
/// (core, radius_mm) in world coordinates: the free surface vertices of the body's collision
/// surface that this step's contacts of the slot name and that lie within radius_mm +
/// opt.reach_mm of the core move inward by opt.rate_mm_s * dt along the surface normal, both in
/// the current and in the rest configuration. Does nothing (returns zeros) if none is touched.
/// Marks touched nodes in SoftBodyState::cauterized when `cauterize`.
ShaveResult ShaveBody(const Model& model, int slot, int body, const collision::Simplex& core,
                      double radius_mm, const SoftShavingOptions& opt, bool cauterize,
                      const StepContext& context, State* state, InstrumentScratch* scratch);

/// The shaver operation (button 1 held): ShaveBody on every soft body with the shaver's tip; one
/// `shave` event per body touched ("nodes=N smoothed=M removed_tets=K volume_mm3=V"), at the
/// centre of the touched vertices.
void ShaverShave(const Model& model, int slot, const StepContext& context, State* state,
                 InstrumentScratch* scratch);

/// The electrocautery operation: as the shaver with the cautery tip and
/// operations.electrocautery, and the touched nodes marked; `cauterize` events.
void CauteryShave(const Model& model, int slot, const StepContext& context, State* state,
                  InstrumentScratch* scratch);

}  // namespace arthrosim::instruments
