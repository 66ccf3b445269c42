// Fuzz target: the STL, ASCII and binary reader (mesh::ParseMesh on "fuzz.stl").
#include "fuzz_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  arthrosim::fuzz::FuzzMesh("fuzz.stl", data, size);
  return 0;
}
