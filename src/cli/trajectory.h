#pragma once
// Picks the input source for `run` from the trajectory file's extension.
#include <memory>
#include <string>

#include "arthrosim/core/model.h"
#include "arthrosim/input/input_source.h"

namespace arthrosim::cli {

/// "" -> idle; .csv/.h5 -> recorded session; .yaml/.yml -> synthetic script.
/// @throws InputError for an unknown extension or a bad file.
std::unique_ptr<input::InputSource> OpenTrajectory(const Model& model, const std::string& path);

}  // namespace arthrosim::cli
