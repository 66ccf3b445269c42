#pragma once
// Reading a whole input file (scenario, plan, script, session) into memory, with the InputError
// every loader gives for a file it cannot open. Header-only, like error.h.
#include <fstream>
#include <sstream>
#include <string>

#include "arthrosim/core/error.h"

namespace arthrosim {

/// The bytes of the file at `path`. @throws InputError(path, 0, field, cannot_open) if it cannot
/// be opened.
inline std::string ReadInputFile(const std::string& path, const std::string& field,
                                 const std::string& cannot_open) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, field, cannot_open);
  std::ostringstream text;
  text << in.rdbuf();
  return std::move(text).str();
}

}  // namespace arthrosim
