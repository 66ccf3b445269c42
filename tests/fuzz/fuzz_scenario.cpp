// Fuzz target: the scenario loader (io::LoadScenarioFromText), YAML text from the fuzz bytes.
// Its bodies' mesh paths resolve against tests/fuzz/meshes (a few small meshes); an input
// naming a mesh by a path with a directory part is rejected unread, so the fuzzer never opens
// files outside that folder (the loader itself refuses devices and FIFOs: bad-input corpus).
#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "arthrosim/io/scenario_loader.h"
#include "fuzz_util.h"

namespace {

// True if some bodies[i].mesh (what the loader reads) names a path outside the mesh folder, or
// if that cannot be told (then the input is skipped too).
bool NamesOutsideMesh(const std::string& text) {
  YAML::Node parsed;
  try {
    parsed = YAML::Load(text);
  } catch (const YAML::Exception&) {
    return false;  // the loader stops at the syntax error, before any mesh
  }
  try {
    const YAML::Node& doc = parsed;
    if (!doc.IsMap() || !doc["bodies"] || !doc["bodies"].IsSequence()) return false;
    for (const YAML::Node& body : doc["bodies"]) {
      if (!body.IsMap() || !body["mesh"]) continue;
      const YAML::Node mesh = body["mesh"];
      if (mesh.IsScalar() && mesh.Scalar().find('/') != std::string::npos) return true;
    }
    return false;
  } catch (const YAML::Exception&) {
    return true;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = arthrosim::fuzz::Bytes(data, size);
  if (NamesOutsideMesh(text)) return -1;  // not added to the corpus
  std::vector<std::string> warnings;
  arthrosim::fuzz::ExpectOnlyInputErrors([&] {
    arthrosim::io::LoadScenarioFromText(text, ARTHROSIM_SOURCE_DIR "/tests/fuzz/meshes/fuzz.yaml",
                                        &warnings);
  });
  return 0;
}
