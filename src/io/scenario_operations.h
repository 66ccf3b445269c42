#pragma once
// The scenario's optional `operations:` section (thresholds of the instruments' operations,
// docs/scenario-format.md and docs/operations.md): one reader per operation.
#include "arthrosim/core/model.h"
#include "arthrosim/core/yaml_fields.h"

namespace arthrosim::io {

/// Reads root's `operations:` map (if present) into m->operations; keys missing keep their
/// defaults. Call after the bodies are read (operations name them). Throws InputError naming file,
/// line and field for unknown keys or bad values.
void ReadOperations(const YamlSection& root, Model* m);

}  // namespace arthrosim::io
