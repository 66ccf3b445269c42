// Fuzz target: the Wavefront OBJ reader (mesh::ParseMesh on "fuzz.obj").
#include "fuzz_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  arthrosim::fuzz::FuzzMesh("fuzz.obj", data, size);
  return 0;
}
