#include "arthrosim/core/soft_nodes.h"

namespace arthrosim {

std::vector<std::uint8_t> NodesInAliveTets(const SoftBodyState& body) {
  std::vector<std::uint8_t> in(static_cast<std::size_t>(body.x.cols()), 0);
  for (std::size_t t = 0; t < body.tets.size(); ++t) {
    if (t < body.tet_alive.size() && !body.tet_alive[t]) continue;
    for (const std::int32_t n : body.tets[t]) {
      if (n >= 0 && static_cast<std::size_t>(n) < in.size()) in[static_cast<std::size_t>(n)] = 1;
    }
  }
  return in;
}

}  // namespace arthrosim
