// Fuzz target: the Gmsh MSH 2.2 ASCII, 4.1 ASCII and 4.1 binary reader (mesh::ParseMesh on
// "fuzz.msh").
#include "fuzz_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  arthrosim::fuzz::FuzzMesh("fuzz.msh", data, size);
  return 0;
}
