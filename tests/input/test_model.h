#pragma once
// A small hand-built Model for the input tests: the three portals, the eleven instruments named
// after their kinds and the eleven landmarks of the rotator-cuff scenario, at made-up positions.
#include <string>

#include "arthrosim/core/model.h"

namespace arthrosim::input::testing {

/// The hand-built model.
Model MakeTestModel();

/// Portals, instruments, landmarks and camera of a scenario YAML (no meshes), for validating
/// trajectories against the real scenario without the io layer.
Model LoadScenarioSubset(const std::string& path);

/// The message of the InputError that building a ScriptSource from `yaml` throws (file name
/// "t.yaml", the hand-built model, dt 0.01 s); "" if it builds.
std::string ScriptErrorOf(const std::string& yaml);

/// A unique temporary file path under the build tree.
std::string TempPath(const std::string& name);

}  // namespace arthrosim::input::testing
