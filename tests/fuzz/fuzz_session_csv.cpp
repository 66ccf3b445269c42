// Fuzz target: the session CSV reader (input::ParseSessionCsv), with the default options and
// with the gap-holding repair policy and a time offset.
#include <string>

#include "arthrosim/input/session.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = arthrosim::fuzz::Bytes(data, size);
  arthrosim::fuzz::ExpectOnlyInputErrors(
      [&] { arthrosim::input::ParseSessionCsv(text, "fuzz.csv"); });
  arthrosim::input::SessionOptions hold;
  hold.gap_policy = arthrosim::input::GapPolicy::kHold;
  hold.time_offset_s = 1.5;
  arthrosim::fuzz::ExpectOnlyInputErrors(
      [&] { arthrosim::input::ParseSessionCsv(text, "fuzz.csv", hold); });
  return 0;
}
