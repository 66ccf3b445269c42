// Fuzz target: the plan loader (scoring::LoadPlanFromText), once checked against the rotator cuff
// scenario's names and once without a Model (as `arthrosim score` before it opens the run).
#include <string>

#include "arthrosim/scoring/plan.h"
#include "fuzz_model.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const arthrosim::Model& model = arthrosim::fuzz::RotatorCuffModel();
  const std::string text = arthrosim::fuzz::Bytes(data, size);
  arthrosim::fuzz::ExpectOnlyInputErrors(
      [&] { arthrosim::scoring::LoadPlanFromText(text, "fuzz_plan.yaml", &model); });
  arthrosim::fuzz::ExpectOnlyInputErrors(
      [&] { arthrosim::scoring::LoadPlanFromText(text, "fuzz_plan.yaml", nullptr); });
  return 0;
}
