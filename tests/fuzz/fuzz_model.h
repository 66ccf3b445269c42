#pragma once
// The Model the plan and script targets check names against: the shipped rotator cuff
// scenario (the one the seed plans and scripts are written for), loaded once.
#include "arthrosim/core/model.h"
#include "arthrosim/io/scenario_loader.h"

namespace arthrosim::fuzz {

inline const Model& RotatorCuffModel() {
  static const Model model = [] {
    std::vector<std::string> warnings;
    return io::LoadScenario(ARTHROSIM_SOURCE_DIR "/scenarios/rotator_cuff_repair.yaml", &warnings);
  }();
  return model;
}

}  // namespace arthrosim::fuzz
