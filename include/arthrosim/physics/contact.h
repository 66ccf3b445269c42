#pragma once
// Contact terms handed from collision to the solvers for one step. A contact keeps a point of
// a deformable (a weighted sum of up to four nodes of one soft body or thread) on the outer
// side of a plane fixed for this step: normal . p >= offset. The solver adds the one-sided
// penalty energy 0.5 * k * max(0, offset - normal . p)^2, linearised inside the implicit
// step (so it is stable at dt = 20 ms), and reports the force it applied.
#include <array>
#include <cstdint>
#include <vector>

#include "arthrosim/core/types.h"

namespace arthrosim::physics {

struct PointContact {
  enum class Target : std::uint8_t { kSoftBody, kThread };
  Target target = Target::kSoftBody;
  std::int32_t index = -1;  ///< soft body or thread index in the Model
  std::array<std::int32_t, 4> nodes{-1, -1, -1, -1};
  std::array<double, 4> weights{0, 0, 0, 0};  ///< barycentric weights (sum 1), unused = 0
  Vec3 normal = Vec3::UnitZ();                ///< unit, out of the obstacle
  double offset_mm = 0;                       ///< plane: normal . p >= offset
  double stiffness_n_per_mm = 1.0;            ///< penalty stiffness, N/mm
  std::int32_t tool_slot = -1;                ///< tool slot that caused it, -1 = none (bone, ...)
  std::int32_t obstacle_id = -1;  ///< bone / soft body / thread index of the obstacle, or -1
  // Filled by the solver after the step:
  double force_n = 0;  ///< normal force magnitude applied, N (>= 0)
};

using ContactSet = std::vector<PointContact>;

/// A zero-or-positive-rest-length spring from a point of a deformable (weighted nodes, as in
/// PointContact) to an anchor point held fixed for this step (a tool point, a world point, or
/// the other side's point frozen at its position at the start of the step). The sim layer turns
/// each State::SpringConstraint into one PointSpring per deformable side (staggered coupling).
struct PointSpring {
  PointContact::Target target = PointContact::Target::kSoftBody;
  std::int32_t index = -1;
  std::array<std::int32_t, 4> nodes{-1, -1, -1, -1};
  std::array<double, 4> weights{0, 0, 0, 0};
  Vec3 anchor_mm = Vec3::Zero();    ///< other end, fixed during the step
  double stiffness_n_per_mm = 1.0;  ///< N/mm
  double rest_length_mm = 0.0;
  std::int64_t constraint_id = -1;  ///< State::SpringConstraint id it comes from (-1 = none)
  // Filled by the solver after the step:
  Vec3 force_n = Vec3::Zero();  ///< force the spring applied to the deformable point, N
};

using SpringSet = std::vector<PointSpring>;

}  // namespace arthrosim::physics
