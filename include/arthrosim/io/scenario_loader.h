#pragma once
// Scenario YAML -> Model. Strict: unknown keys, missing required fields, wrong types and
// non-physical values are InputErrors naming file, line and field (docs/scenario-format.md).
#include <string>
#include <vector>

#include "arthrosim/core/model.h"

namespace arthrosim::io {

/// Loads and validates a scenario file, reading its meshes (paths relative to the file).
/// Physical quantities are checked against their plausible ranges (src/io/scenario_ranges.h):
/// outside is an InputError; possible but unusual values ("file:line: field 'f': ...") are
/// appended to `warnings`, or printed to stderr as "warning: ..." when it is null.
/// @throws InputError on any problem with the file or a mesh it names (a mesh fault names the
///   scenario line and field that referenced the mesh, then the mesh's own file and line).
Model LoadScenario(const std::string& path, std::vector<std::string>* warnings = nullptr);

/// Same, from YAML text; `path` is used for messages and to resolve relative mesh paths.
Model LoadScenarioFromText(const std::string& text, const std::string& path,
                           std::vector<std::string>* warnings = nullptr);

}  // namespace arthrosim::io
