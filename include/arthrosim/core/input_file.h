#pragma once
// Reading a whole input file (scenario, plan, script, session) into memory, with the InputError
// every loader gives for a file it cannot open. Header-only, like error.h.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>

#include "arthrosim/core/error.h"

namespace arthrosim {

/// The bytes of the file at `path`. @throws InputError(path, 0, field, cannot_open) if it cannot
/// be opened, and InputError(path, 0, field, cannot_open + ": not a regular file ...") if it
/// names a directory, a device (/dev/zero never ends) or a FIFO (opening one waits for a
/// writer): those are refused before they are opened.
inline std::string ReadInputFile(const std::string& path, const std::string& field,
                                 const std::string& cannot_open) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (!ec && std::filesystem::exists(st) && !std::filesystem::is_regular_file(st)) {
    throw InputError(path, 0, field,
                     cannot_open + ": not a regular file (a directory, a device or a FIFO)");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, field, cannot_open);
  std::ostringstream text;
  text << in.rdbuf();
  return std::move(text).str();
}

}  // namespace arthrosim
