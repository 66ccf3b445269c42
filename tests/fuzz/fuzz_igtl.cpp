// Fuzz target: the OpenIGTLink stream framing and message decoders of the live server
// (src/input/igtl_wire.h). The bytes are a TCP stream, fed whole and then in 7-byte pieces;
// every framed message goes through the decoder for its type.
#include <cstdio>
#include <string>
#include <vector>

#include "fuzz_util.h"
#include "igtl_wire.h"

namespace {

namespace wire = arthrosim::input::igtl_wire;

// Frames everything `parser` holds and decodes each message; false once the stream is lost.
bool Drain(wire::StreamParser* parser) {
  wire::Message m;
  std::string why;
  for (;;) {
    switch (parser->Next(&m, &why)) {
      case wire::StreamParser::Result::kNeedMore:
        return true;
      case wire::StreamParser::Result::kFatal:
        return false;
      case wire::StreamParser::Result::kDropped:
        continue;
      case wire::StreamParser::Result::kMessage:
        break;
    }
    why.clear();
    bool ok = false;
    if (m.type == "TRANSFORM") ok = wire::DecodeTransform(m, &why).has_value();
    if (m.type == "STRING") ok = wire::DecodeString(m, &why).has_value();
    if (m.type == "SENSOR") ok = wire::DecodeSensor(m, &why).has_value();
    if (arthrosim::fuzz::Verbose()) {
      std::fprintf(stderr, "%s '%s': %s\n", m.type.c_str(), m.device.c_str(),
                   ok ? "decoded" : why.c_str());
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  constexpr std::size_t kMaxBody = 4096;  // the server's default is 64 KiB; smaller skips more
  wire::StreamParser whole(kMaxBody);
  whole.Append(data, size);
  Drain(&whole);
  wire::StreamParser pieces(kMaxBody);
  for (std::size_t at = 0; at < size; at += 7) {
    pieces.Append(data + at, std::min<std::size_t>(7, size - at));
    if (!Drain(&pieces)) break;
  }
  return 0;
}
