// Opening a run file for reading, shared by RunReader and RunCheckpoints.
#pragma once

#include <filesystem>
#include <string>

#include "arthrosim/core/error.h"
#include "arthrosim/io/hdf5.h"

namespace arthrosim::io::detail {

/// Opens `path` read-only (SWMR: a run still being written can be read) into *file and calls
/// read(), translating every HDF5 fault, including those of read(), into an InputError naming
/// the file. A missing path or one that is not a regular file is refused in one line first.
template <class Read>
void ReadRunFile(const std::string& path, h5::File* file, Read read) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(path, 0, "", "run file not found");
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(path, 0, "", "not a regular file (expected an HDF5 run file)");
  }
  try {
    *file = h5::File::OpenReadOnly(path, true);
    read();
  } catch (const h5::Error& e) {
    throw InputError(path, 0, "", std::string("cannot read run file: ") + e.what());
  }
}

}  // namespace arthrosim::io::detail
