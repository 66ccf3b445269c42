#pragma once
// Scenario YAML -> Model. Strict: unknown keys, missing required fields, wrong types and
// non-physical values are InputErrors naming file, line and field (docs/scenario-format.md).
#include <string>

#include "arthrosim/core/model.h"

namespace arthrosim::io {

/// Loads and validates a scenario file, reading its meshes (paths relative to the file).
/// @throws InputError on any problem with the file or a mesh it names.
Model LoadScenario(const std::string& path);

/// Same, from YAML text; `path` is used for messages and to resolve relative mesh paths.
Model LoadScenarioFromText(const std::string& text, const std::string& path);

}  // namespace arthrosim::io
