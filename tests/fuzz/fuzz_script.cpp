// Fuzz target: the trajectory script parser (input::ScriptSource), resolved against the rotator
// cuff scenario, with its noise block at full strength; a script that parses is then played for
// its first second (50 frames), as a run would.
#include <string>

#include "arthrosim/core/input_frame.h"
#include "arthrosim/input/script_source.h"
#include "fuzz_model.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const arthrosim::Model& model = arthrosim::fuzz::RotatorCuffModel();
  const std::string text = arthrosim::fuzz::Bytes(data, size);
  arthrosim::fuzz::ExpectOnlyInputErrors([&] {
    arthrosim::input::ScriptOptions options;
    options.noise_scale = 1.0;
    arthrosim::input::ScriptSource script(text, "fuzz_script.yaml", model, options);
    arthrosim::InputFrame frame;
    for (int step = 0; step < 50; ++step) script.Frame(step, step * options.dt_s, &frame);
  });
  return 0;
}
