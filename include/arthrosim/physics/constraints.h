#pragma once
// Runtime spring constraints (grasps, stitches, knots, anchors) kept in State::constraints,
// sorted by id. Instruments create and remove them; the sim step turns each into one PointSpring
// per deformable side (staggered coupling: the other side is frozen at its start-of-step
// position) with BuildPointSprings, and the solvers fill the PointSpring forces.
#include <cstdint>
#include <string>
#include <vector>

#include "arthrosim/core/state.h"
#include "arthrosim/physics/contact.h"

namespace arthrosim::physics {

/// Stores c with id = state->next_constraint_id (then increments it); returns the id.
/// Throws std::invalid_argument for a negative stiffness or rest length.
std::int64_t AddConstraint(State* state, SpringConstraint c);

/// Removes the constraint with this id; false if there is none.
bool RemoveConstraint(State* state, std::int64_t id);

/// The constraint with this id, or nullptr.
const SpringConstraint* FindConstraint(const State& state, std::int64_t id);

/// Ids (ascending) of the constraints with this tag.
std::vector<std::int64_t> FindConstraintsByTag(const State& state, const std::string& tag);

/// Ids (ascending) of the constraints with an end of this kind on body/tool `index`; with
/// node >= 0 only ends that weight that node (non-zero weight).
std::vector<std::int64_t> FindConstraintsByEnd(const State& state, ConstraintEnd::Kind kind,
                                               std::int32_t index, std::int32_t node = -1);

/// World position (mm) of a constraint end in this state: weighted nodes of a soft body or
/// thread, the tool-frame point through State::tools[index].pose, or the world/bone point.
/// Throws std::invalid_argument for an index or node out of range.
Vec3 EndPosition(const State& state, const ConstraintEnd& end);

/// One PointSpring per deformable end (soft body or thread) of every constraint, in id order
/// (side a before side b), anchored at the other end's current position.
SpringSet BuildPointSprings(const State& state);
/// The same into *springs (cleared first; its capacity is reused, so a step need not allocate).
void BuildPointSprings(const State& state, SpringSet* springs);

/// A thread end at arc parameter s along thread `thread`: s = i + f lies between nodes i and
/// i + 1 at fraction f in [0, 1) (weights 1 - f and f); an integer s is node s alone. Throws
/// std::invalid_argument for a negative thread index or s < 0.
ConstraintEnd ThreadPointEnd(std::int32_t thread, double s);

/// The arc parameter s of a thread end made by ThreadPointEnd (or one holding a single node):
/// nodes[0] + weights[1]. Throws std::invalid_argument if the end is not of that form.
double ThreadEndParameter(const ConstraintEnd& end);

/// The sliding end of c (its thread end, a if both are threads), or nullptr if c does not slide
/// (slide_friction_n < 0 or no thread end).
const ConstraintEnd* SlidingEnd(const SpringConstraint& c);

/// Coulomb friction of sliding ends (one step, after the solvers): for every constraint with
/// slide_friction_n >= 0, the spring's pull on its thread end, projected on the thread tangent,
/// that exceeds the friction moves the end along the chain (the thread runs through the stitch,
/// knot or hook) by (|f_t| - friction) / stiffness mm, walking segment by segment, so the pull
/// left along the thread equals the friction; the end stops at a dead node or the chain's last
/// node (the thread end does not pass through). Sliding only lowers the spring energy. Returns
/// how many ends moved.
int SlideConstraintEnds(State* state);

/// Removes constraints with an end on a dead thread node (after a cut); returns how many.
int RemoveConstraintsOnDeadThreadNodes(State* state);

}  // namespace arthrosim::physics
