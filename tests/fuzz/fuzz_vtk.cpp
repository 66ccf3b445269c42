// Fuzz target: the legacy VTK UNSTRUCTURED_GRID (ASCII, 2.0-5.1) reader (mesh::ParseMesh on
// "fuzz.vtk").
#include "fuzz_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  arthrosim::fuzz::FuzzMesh("fuzz.vtk", data, size);
  return 0;
}
