#include "arthrosim/physics/thread_cut.h"

#include <stdexcept>
#include <string>

namespace arthrosim::physics {

namespace {

int KillRange(ThreadState* state, int begin, int end) {
  int killed = 0;
  for (int i = begin; i < end; ++i) {
    if (state->node_alive[i]) ++killed;
    state->node_alive[i] = 0;
    state->v.col(i).setZero();
  }
  return killed;
}

}  // namespace

int CutThreadFrom(ThreadState* state, int first_node) {
  const int n = static_cast<int>(state->x.cols());
  if (first_node < 0 || first_node >= n)
    throw std::invalid_argument("CutThreadFrom: node " + std::to_string(first_node) +
                                " outside [0, " + std::to_string(n) + ")");
  return KillRange(state, first_node, n);
}

int CutThreadAtSegment(const ThreadModel& model, ThreadState* state, int segment) {
  const int n = static_cast<int>(state->x.cols());
  if (segment < 0 || segment + 1 >= n)
    throw std::invalid_argument("CutThreadAtSegment: segment " + std::to_string(segment) +
                                " outside [0, " + std::to_string(n - 1) + ")");
  bool fixed_before = false, fixed_after = false;
  for (std::int32_t f : model.fixed_nodes) {
    if (f <= segment) fixed_before = true;
    if (f > segment && f < n) fixed_after = true;
  }
  if (fixed_after && !fixed_before) return KillRange(state, 0, segment + 1);
  return KillRange(state, segment + 1, n);
}

}  // namespace arthrosim::physics
