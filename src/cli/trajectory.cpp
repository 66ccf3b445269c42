#include "trajectory.h"

#include <filesystem>

#include "arthrosim/core/error.h"
#include "arthrosim/input/recorded_source.h"

namespace arthrosim::cli {

std::unique_ptr<input::InputSource> OpenTrajectory(const Model& model, const std::string& path) {
  if (path.empty()) return std::make_unique<input::IdleSource>(model);
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".csv" || ext == ".h5" || ext == ".hdf5") {
    return input::RecordedSource::Open(path, model, model.options.dt_s);
  }
  throw InputError(path, 0, "--trajectory",
                   "unknown trajectory extension '" + ext + "' (expected .csv, .h5 or .yaml)");
}

}  // namespace arthrosim::cli
