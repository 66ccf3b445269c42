#pragma once
// Shared by the fuzz targets: the bytes as a string, and the one exception a parser may throw.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "arthrosim/core/error.h"

namespace arthrosim::fuzz {

/// The fuzz input as a std::string (may hold any byte, including NUL).
inline std::string Bytes(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

/// True when ARTHROSIM_FUZZ_VERBOSE is set: targets then print what each input gave (for
/// checking that seeds parse).
inline bool Verbose() {
  static const bool verbose = std::getenv("ARTHROSIM_FUZZ_VERBOSE") != nullptr;
  return verbose;
}

/// Runs `parse`; an InputError is the expected answer to bad input and is swallowed. Anything
/// else (another exception, a crash, a sanitizer report) escapes and is a finding.
template <class F>
void ExpectOnlyInputErrors(const F& parse) {
  try {
    parse();
    if (Verbose()) std::fprintf(stderr, "parsed\n");
  } catch (const InputError& e) {
    if (Verbose()) std::fprintf(stderr, "InputError: %s\n", e.what());
  }
}

}  // namespace arthrosim::fuzz
