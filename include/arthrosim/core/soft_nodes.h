#pragma once
// Which nodes of a soft body still belong to its tissue.

#include <cstdint>
#include <vector>

#include "arthrosim/core/state.h"

namespace arthrosim {

/// Per node of `body` (x.cols() entries): 1 if at least one alive element (tet_alive) uses it,
/// 0 for a node that cutting or shaving left without elements. Such a node is debris: no force
/// acts on it any more, it stays where it was cut, so measures of where the tissue is (region
/// centroids, gaps) must skip it.
std::vector<std::uint8_t> NodesInAliveTets(const SoftBodyState& body);

}  // namespace arthrosim
